//! The rate–distortion curve as an SVG plot: held-out PSNR against bits per pixel on a
//! log axis, one colour per basis, the lossless EXR points as squares, the Pareto front
//! as a line.
//!
//! Written by hand rather than with a plotting crate: one chart of points and a line
//! needs a few dozen lines of SVG, and a plotting crate would add its dependencies and
//! compile time to every build of the CLI for this one picture.

use relit::eval::rd::{RdPoint, RdReport};
use std::fmt::Write;

const WIDTH: f64 = 860.0;
const HEIGHT: f64 = 540.0;
const LEFT: f64 = 72.0;
const RIGHT: f64 = 200.0;
const TOP: f64 = 48.0;
const BOTTOM: f64 = 62.0;

/// Colours that stay apart for common colour-vision deficiencies (Okabe–Ito).
const PALETTE: [&str; 8] = [
    "#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#000000",
];

/// The plot of `report`.
pub fn svg(report: &RdReport) -> String {
    let points: Vec<&RdPoint> = report
        .points
        .iter()
        .filter(|p| p.bits_per_pixel > 0.0 && p.bits_per_pixel.is_finite())
        .filter(|p| p.psnr_srgb8.is_finite())
        .collect();
    let mut bases: Vec<&str> = Vec::new();
    for p in &points {
        if !bases.contains(&p.basis.as_str()) {
            bases.push(&p.basis);
        }
    }
    let fold = |f: fn(f64, f64) -> f64, init: f64, v: &dyn Fn(&RdPoint) -> f64| {
        points.iter().fold(init, |m, p| f(m, v(p)))
    };
    let (lo_bits, hi_bits) = (
        fold(f64::min, f64::INFINITY, &|p| p.bits_per_pixel),
        fold(f64::max, 0.0, &|p| p.bits_per_pixel),
    );
    let (lo_db, hi_db) = (
        fold(f64::min, f64::INFINITY, &|p| p.psnr_srgb8),
        fold(f64::max, f64::NEG_INFINITY, &|p| p.psnr_srgb8),
    );
    let x_axis = LogAxis::covering(lo_bits, hi_bits);
    let y_axis = LinearAxis::covering(lo_db, hi_db);
    let plot_w = WIDTH - LEFT - RIGHT;
    let plot_h = HEIGHT - TOP - BOTTOM;
    let x = |bits: f64| LEFT + plot_w * x_axis.fraction(bits);
    let y = |db: f64| TOP + plot_h * (1.0 - y_axis.fraction(db));

    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(
        s,
        r#"<rect width="{WIDTH}" height="{HEIGHT}" fill="white"/>"#
    );
    let name = std::path::Path::new(&report.capture)
        .parent()
        .and_then(|p| p.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| report.capture.clone());
    let _ = writeln!(
        s,
        r#"<text x="{LEFT}" y="22" font-size="15" font-weight="bold">{}</text>"#,
        escape(&format!(
            "{name}: held-out PSNR against file size ({}×{}, {} images, {} hold-outs, {})",
            report.width,
            report.height,
            report.images,
            report.holdouts.len(),
            report.protocol
        ))
    );

    // Grid, ticks and labels.
    let _ = writeln!(s, r##"<g stroke="#dddddd" stroke-width="1">"##);
    for &t in &x_axis.ticks {
        let _ = writeln!(
            s,
            r#"<line x1="{0:.1}" y1="{TOP}" x2="{0:.1}" y2="{1:.1}"/>"#,
            x(t),
            TOP + plot_h
        );
    }
    for &t in &y_axis.ticks {
        let _ = writeln!(
            s,
            r#"<line x1="{LEFT}" y1="{0:.1}" x2="{1:.1}" y2="{0:.1}"/>"#,
            y(t),
            LEFT + plot_w
        );
    }
    let _ = writeln!(s, "</g>");
    let _ = writeln!(
        s,
        r#"<rect x="{LEFT}" y="{TOP}" width="{plot_w}" height="{plot_h}" fill="none" stroke="black"/>"#
    );
    for &t in &x_axis.ticks {
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
            x(t),
            TOP + plot_h + 16.0,
            number(t)
        );
    }
    for &t in &y_axis.ticks {
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"#,
            LEFT - 6.0,
            y(t) + 4.0,
            number(t)
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">bits per pixel of the whole file (size on disk, log scale)</text>"#,
        LEFT + plot_w / 2.0,
        HEIGHT - 18.0
    );
    let _ = writeln!(
        s,
        r#"<text transform="translate(18 {:.1}) rotate(-90)" text-anchor="middle">held-out PSNR, 8-bit sRGB (dB)</text>"#,
        TOP + plot_h / 2.0
    );

    // The front first, so that the points stay visible on it.
    let front: Vec<String> = points
        .iter()
        .filter(|p| p.pareto)
        .map(|p| format!("{:.1},{:.1}", x(p.bits_per_pixel), y(p.psnr_srgb8)))
        .collect();
    let _ = writeln!(
        s,
        r#"<polyline class="pareto" points="{}" fill="none" stroke="black" stroke-width="1.5"/>"#,
        front.join(" ")
    );
    for (b, basis) in bases.iter().enumerate() {
        let colour = PALETTE[b % PALETTE.len()];
        let _ = writeln!(
            s,
            r#"<g class="series" data-basis="{}" fill="{colour}" fill-opacity="0.75">"#,
            escape(basis)
        );
        for p in points.iter().filter(|p| p.basis == *basis) {
            let (px, py) = (x(p.bits_per_pixel), y(p.psnr_srgb8));
            let tip = escape(&format!(
                "{} {}: {:.2} bits/px, {:.2} dB{}",
                p.basis,
                p.storage,
                p.bits_per_pixel,
                p.psnr_srgb8,
                if p.pareto { " (Pareto front)" } else { "" }
            ));
            if p.lossless {
                let _ = writeln!(
                    s,
                    r#"<rect x="{:.1}" y="{:.1}" width="8" height="8"><title>{tip}</title></rect>"#,
                    px - 4.0,
                    py - 4.0
                );
            } else {
                let _ = writeln!(
                    s,
                    r#"<circle cx="{px:.1}" cy="{py:.1}" r="3.5"><title>{tip}</title></circle>"#
                );
            }
        }
        let _ = writeln!(s, "</g>");
    }

    // Legend, right of the plot.
    let lx = LEFT + plot_w + 18.0;
    let mut ly = TOP + 10.0;
    for (b, basis) in bases.iter().enumerate() {
        let _ = writeln!(
            s,
            r#"<circle cx="{lx}" cy="{:.1}" r="4" fill="{}"/><text x="{}" y="{:.1}">{}</text>"#,
            ly,
            PALETTE[b % PALETTE.len()],
            lx + 12.0,
            ly + 4.0,
            escape(basis)
        );
        ly += 20.0;
    }
    let _ = writeln!(
        s,
        r#"<rect x="{}" y="{:.1}" width="8" height="8" fill="gray"/><text x="{}" y="{:.1}">lossless EXR</text>"#,
        lx - 4.0,
        ly - 4.0,
        lx + 12.0,
        ly + 4.0
    );
    ly += 20.0;
    let _ = writeln!(
        s,
        r#"<line x1="{}" y1="{ly:.1}" x2="{}" y2="{ly:.1}" stroke="black" stroke-width="1.5"/><text x="{}" y="{:.1}">Pareto front</text>"#,
        lx - 6.0,
        lx + 6.0,
        lx + 12.0,
        ly + 4.0
    );
    let _ = writeln!(s, "</svg>");
    s
}

/// A log₁₀ axis from the last of 1, 2, 5 × 10ⁿ below the data to the first above,
/// ticked at those values (at powers of ten only when they would crowd).
struct LogAxis {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
}

impl LogAxis {
    fn covering(lo: f64, hi: f64) -> LogAxis {
        let (lo, hi) = if lo.is_finite() && hi >= lo && lo > 0.0 {
            (lo, hi)
        } else {
            (1.0, 10.0)
        };
        let first = lo.log10().floor() as i32;
        let last = (hi.log10().ceil() as i32).max(first + 1);
        let all: Vec<f64> = (first..=last)
            .flat_map(|e| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(e)))
            .collect();
        let start = all
            .iter()
            .copied()
            .filter(|&t| t <= lo)
            .fold(all[0], f64::max);
        let end = all
            .iter()
            .copied()
            .find(|&t| t >= hi && t > start)
            .unwrap_or(10f64.powi(last));
        let mut ticks: Vec<f64> = all
            .into_iter()
            .filter(|&t| t >= start && t <= end)
            .collect();
        if ticks.len() > 12 {
            ticks.retain(|t| (t.log10().round() - t.log10()).abs() < 1e-9);
        }
        LogAxis {
            lo: start,
            hi: end,
            ticks,
        }
    }

    fn fraction(&self, v: f64) -> f64 {
        (v.log10() - self.lo.log10()) / (self.hi.log10() - self.lo.log10())
    }
}

/// A linear axis from whole decibels around the data, ticked every 1, 2 or 5 dB
/// (whichever gives at most a dozen ticks).
struct LinearAxis {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
}

impl LinearAxis {
    fn covering(lo: f64, hi: f64) -> LinearAxis {
        let (lo, hi) = if lo.is_finite() && hi.is_finite() && hi >= lo {
            (lo, hi)
        } else {
            (0.0, 1.0)
        };
        let span = (hi - lo).max(1.0);
        let step = [1.0, 2.0, 5.0, 10.0, 20.0]
            .into_iter()
            .find(|s| span / s <= 12.0)
            .unwrap_or(50.0);
        let lo = (lo / step).floor() * step;
        let hi = ((hi / step).ceil() * step).max(lo + step);
        let ticks = (0..=((hi - lo) / step).round() as usize)
            .map(|i| lo + i as f64 * step)
            .collect();
        LinearAxis { lo, hi, ticks }
    }

    fn fraction(&self, v: f64) -> f64 {
        (v - self.lo) / (self.hi - self.lo)
    }
}

/// A tick label: no trailing zeros.
fn number(v: f64) -> String {
    if v >= 1.0 && v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Text made safe inside SVG elements and attributes.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_cover_the_data_with_round_ticks() {
        let x = LogAxis::covering(13.0, 980.0);
        assert_eq!((x.lo, x.hi), (10.0, 1000.0));
        assert_eq!(x.ticks, vec![10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0]);
        assert!((x.fraction(100.0) - 0.5).abs() < 1e-12);
        let x = LogAxis::covering(8.2, 1016.0);
        assert_eq!((x.lo, x.hi), (5.0, 2000.0));
        assert_eq!(x.ticks[0], 5.0);
        let x = LogAxis::covering(0.3, 2e6);
        assert_eq!(x.ticks.first(), Some(&1.0));
        assert!(x.ticks.len() <= 8);
        let y = LinearAxis::covering(22.3, 37.9);
        assert_eq!((y.lo, y.hi), (22.0, 38.0));
        assert_eq!(y.ticks.len(), 9);
        assert_eq!(number(0.5), "0.5");
        assert_eq!(number(200.0), "200");
        assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
    }
}
