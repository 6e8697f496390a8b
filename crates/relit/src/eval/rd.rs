//! The rate–distortion curve of a capture: held-out PSNR against the size on disk of
//! real files, for several bases and every compression setting `--budget` chooses from.
//!
//! The protocol is [`super::evaluate`]'s: the same hold-outs, one fit per hold-out by
//! default. Fits are the expensive part, so each basis is fitted once per hold-out and
//! that one fit is stored every way — the lossless EXR, then each setting of
//! [`crate::compress::budget::grid`] — each written to a temporary folder, read back
//! and relit at the held-out lights. A point's bits per pixel are its files' mean size
//! on disk; its PSNR the mean over the held-out images, as in [`super::evaluate`].
//!
//! A point is on the Pareto front when every point of as many bits or fewer scores
//! less: the best PSNR a file of that size reaches among the candidates.

use super::{for_training, relight_and_score, Holdout, Protocol, Scratch};
use crate::capture::Capture;
use crate::compress::{budget, Settings};
use crate::fit::{self, BasisRequest, FitOptions};
use crate::progress::Progress;
use crate::storage::Precision;
use crate::{Error, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The bases of a curve unless told otherwise, at 25 coefficients (what `--basis auto`
/// may use by default; smaller sizes are on the curve as fewer principal components):
/// global harmonics, and an interpolating family for captures with hard shadows, where
/// it gains several dB (docs/bases.md). Each basis costs a fit per hold-out and a pass
/// over the whole grid, so the default stays at two.
pub const DEFAULT_BASES: [&str; 2] = ["sh:25", "rbf:25"];

/// Options of [`curve`].
#[derive(Clone, Debug)]
pub struct RdOptions {
    pub holdout: Holdout,
    /// Fit once without all held-out images instead of once per held-out image.
    pub joint: bool,
    /// How every basis is fitted; its `basis` is replaced by each of `bases`.
    pub fit: FitOptions,
    pub bases: Vec<BasisRequest>,
    /// The precision of the lossless (EXR) point.
    pub lossless: Precision,
    /// At most this many compression settings per basis, spread evenly over the grid
    /// (`None`: all of it): a coarser curve for quick looks and tests.
    pub max_settings: Option<usize>,
    /// Mask (> 0.5 inside) for the linear PSNR; overrides the capture's own mask.
    pub mask: Option<Vec<f32>>,
}

impl Default for RdOptions {
    fn default() -> Self {
        RdOptions {
            holdout: Holdout::Spread(5),
            joint: false,
            fit: FitOptions::default(),
            bases: DEFAULT_BASES
                .iter()
                .map(|b| BasisRequest::parse(b).expect("the default bases parse"))
                .collect(),
            lossless: Precision::F16,
            max_settings: None,
            mask: None,
        }
    }
}

/// One point of the curve: one basis stored one way, over every fit of the protocol.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RdPoint {
    /// The basis asked for (`sh:25`, `auto`).
    pub basis: String,
    /// How the file holds the maps: `exr f16`, or the compression settings
    /// (`ycc k9 jpeg:90`, see [`Settings::describe`]).
    pub storage: String,
    /// Whether the file is the lossless EXR.
    pub lossless: bool,
    /// Mean over the fits' files of their size on disk, in bits per pixel.
    pub bits_per_pixel: f64,
    /// Each fit's file: its size on disk.
    pub file_bytes: Vec<u64>,
    /// Mean over the held-out images of the 8-bit sRGB PSNR (the peer's figure).
    pub psnr_srgb8: f64,
    /// Mean over the held-out images of the linear PSNR (inside the mask, if any).
    pub psnr_linear: f64,
    /// Each held-out image's 8-bit sRGB PSNR, in the order of [`RdReport::holdouts`].
    pub holdout_psnr_srgb8: Vec<f64>,
    /// On the Pareto front: every point of as many bits or fewer scores less.
    pub pareto: bool,
}

/// How one basis was fitted.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RdFit {
    /// The basis asked for.
    pub basis: String,
    /// The bases the fits chose (the one asked for, unless it was `auto`).
    pub fitted: Vec<String>,
    /// Coefficients per colour channel of the first fit.
    pub coefficients: usize,
    /// Mean wall time of one fit.
    pub fit_seconds: f64,
    /// Compression settings stored per fit.
    pub settings: usize,
}

/// The curve of a capture.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RdReport {
    pub capture: String,
    pub images: usize,
    pub width: usize,
    pub height: usize,
    pub protocol: String,
    /// The held-out images, in the order of every point's per-image figures.
    pub holdouts: Vec<usize>,
    pub masked: bool,
    pub fits: Vec<RdFit>,
    /// Every point, fewest bits first.
    pub points: Vec<RdPoint>,
    /// Wall time of the whole curve.
    pub seconds: f64,
}

impl RdReport {
    /// The Pareto front, fewest bits first (PSNR rises along it).
    pub fn pareto(&self) -> impl Iterator<Item = &RdPoint> {
        self.points.iter().filter(|p| p.pareto)
    }

    /// The best 8-bit sRGB PSNR among files of at most `bits_per_pixel`.
    pub fn best_within(&self, bits_per_pixel: f64) -> Option<&RdPoint> {
        self.pareto()
            .take_while(|p| p.bits_per_pixel <= bits_per_pixel)
            .last()
    }
}

/// How one fit is stored for one point.
enum Storage {
    Lossless(Precision),
    Compressed(Settings),
}

impl Storage {
    fn label(&self) -> String {
        match self {
            Storage::Lossless(precision) => format!("exr {}", precision.name()),
            Storage::Compressed(settings) => settings.describe(),
        }
    }
}

/// A point while the fits come in.
struct Pending {
    basis: usize,
    storage: String,
    lossless: bool,
    file_bytes: Vec<u64>,
    srgb8: Vec<f64>,
    linear: Vec<f64>,
}

/// Fit every basis once per hold-out and score every way of storing each fit.
pub fn curve(capture: &Capture, options: &RdOptions, progress: &dyn Progress) -> Result<RdReport> {
    if options.bases.is_empty() {
        return Err(Error::invalid(
            "a rate–distortion curve needs at least one basis",
        ));
    }
    if options.max_settings == Some(0) {
        return Err(Error::invalid(
            "at least one compression setting per basis is needed",
        ));
    }
    let start = std::time::Instant::now();
    let protocol = Protocol::new(capture, &options.holdout, options.joint, &options.mask)?;
    let scratch = Scratch::new()?;
    let labels: Vec<String> = options.bases.iter().map(BasisRequest::name).collect();
    let mut fits: Vec<RdFit> = labels
        .iter()
        .map(|basis| RdFit {
            basis: basis.clone(),
            fitted: Vec::new(),
            coefficients: 0,
            fit_seconds: 0.0,
            settings: 0,
        })
        .collect();
    let mut pending: Vec<Pending> = Vec::new();
    let groups = protocol.groups.len();
    for (g, group) in protocol.groups.iter().enumerate() {
        let training = capture.subset(&protocol.training(group));
        let references: Vec<_> = group
            .iter()
            .map(|&i| capture.load_raw(i))
            .collect::<Result<_>>()?;
        for (b, request) in options.bases.iter().enumerate() {
            let fit_options = FitOptions {
                basis: request.clone(),
                ..options.fit.clone()
            };
            let fitted = fit::fit(&training, &fit_options, progress)?;
            let record = &mut fits[b];
            if !record.fitted.contains(&fitted.report.basis) {
                record.fitted.push(fitted.report.basis.clone());
            }
            if g == 0 {
                record.coefficients = fitted.report.coefficients;
            }
            record.fit_seconds += fitted.report.seconds / groups as f64;
            let settings = spread(budget::grid(fitted.image.maps.k), options.max_settings);
            record.settings = settings.len();
            let storages: Vec<Storage> = std::iter::once(Storage::Lossless(options.lossless))
                .chain(settings.into_iter().map(Storage::Compressed))
                .collect();
            progress.begin(
                &format!("{} {}/{groups}", labels[b], g + 1),
                storages.len() as u64,
            );
            // The settings of one fit are independent: score them side by side.
            let scored: Vec<(u64, Vec<(f64, f64)>)> = storages
                .par_iter()
                .enumerate()
                .map(|(s, storage)| {
                    let stem = format!("point{s}");
                    let (image, bytes) = match storage {
                        Storage::Lossless(precision) => {
                            scratch.exr_round_trip(&fitted.image, *precision, &stem)?
                        }
                        Storage::Compressed(settings) => {
                            let settings = for_training(settings, &training);
                            scratch.compressed_round_trip(&fitted.image, &settings, &stem)?
                        }
                    };
                    let scores = group
                        .iter()
                        .zip(&references)
                        .map(|(&index, reference)| {
                            let (_, srgb8, linear) = relight_and_score(
                                &image,
                                capture,
                                index,
                                reference,
                                protocol.mask(),
                            )?;
                            Ok((srgb8, linear))
                        })
                        .collect::<Result<_>>()?;
                    progress.advance(1);
                    Ok((bytes, scores))
                })
                .collect::<Result<_>>()?;
            for (storage, (bytes, scores)) in storages.iter().zip(scored) {
                let label = storage.label();
                let at = match pending
                    .iter()
                    .position(|p| p.basis == b && p.storage == label)
                {
                    Some(at) => at,
                    None => {
                        pending.push(Pending {
                            basis: b,
                            storage: label,
                            lossless: matches!(storage, Storage::Lossless(_)),
                            file_bytes: Vec::new(),
                            srgb8: Vec::new(),
                            linear: Vec::new(),
                        });
                        pending.len() - 1
                    }
                };
                let point = &mut pending[at];
                point.file_bytes.push(bytes);
                for (srgb8, linear) in scores {
                    point.srgb8.push(srgb8);
                    point.linear.push(linear);
                }
            }
            progress.end();
        }
    }
    let pixels = (capture.width * capture.height) as f64;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    // `auto` may choose bases of different sizes for different hold-outs, and the grid
    // depends on the size: only settings every fit was stored with make a point.
    let mut points: Vec<RdPoint> = pending
        .into_iter()
        .filter(|p| p.file_bytes.len() == groups)
        .map(|p| RdPoint {
            basis: labels[p.basis].clone(),
            storage: p.storage,
            lossless: p.lossless,
            bits_per_pixel: 8.0 * p.file_bytes.iter().sum::<u64>() as f64 / groups as f64 / pixels,
            psnr_srgb8: mean(&p.srgb8),
            psnr_linear: mean(&p.linear),
            holdout_psnr_srgb8: p.srgb8,
            file_bytes: p.file_bytes,
            pareto: false,
        })
        .collect();
    mark_pareto(&mut points);
    Ok(RdReport {
        capture: capture.origin.clone(),
        images: capture.len(),
        width: capture.width,
        height: capture.height,
        protocol: protocol.name().into(),
        holdouts: protocol.groups.concat(),
        masked: protocol.mask.is_some(),
        fits,
        points,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// `count` items spread evenly over `all` (first and last included), or all of them.
fn spread<T>(all: Vec<T>, count: Option<usize>) -> Vec<T> {
    let n = all.len();
    match count {
        Some(count) if count < n => {
            let keep: Vec<usize> = if count == 1 {
                vec![0]
            } else {
                (0..count)
                    .map(|i| ((i * (n - 1)) as f64 / (count - 1) as f64).round() as usize)
                    .collect()
            };
            all.into_iter()
                .enumerate()
                .filter(|(i, _)| keep.contains(i))
                .map(|(_, t)| t)
                .collect()
        }
        _ => all,
    }
}

/// Sort fewest bits first and mark the Pareto front.
fn mark_pareto(points: &mut [RdPoint]) {
    // Of equal sizes the better first, so that only it can be on the front.
    points.sort_by(|a, b| {
        a.bits_per_pixel
            .total_cmp(&b.bits_per_pixel)
            .then(b.psnr_srgb8.total_cmp(&a.psnr_srgb8))
    });
    let mut best = f64::NEG_INFINITY;
    for point in points.iter_mut() {
        point.pareto = point.psnr_srgb8 > best;
        best = best.max(point.psnr_srgb8);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(bits: f64, psnr: f64) -> RdPoint {
        RdPoint {
            basis: "sh:4".into(),
            storage: String::new(),
            lossless: false,
            bits_per_pixel: bits,
            file_bytes: vec![],
            psnr_srgb8: psnr,
            psnr_linear: psnr,
            holdout_psnr_srgb8: vec![psnr],
            pareto: false,
        }
    }

    #[test]
    fn the_front_is_the_best_psnr_at_each_size() {
        let mut points = vec![
            point(10.0, 30.0),
            point(5.0, 31.0),
            point(20.0, 33.0),
            point(20.0, 34.0),
            point(8.0, 29.0),
            point(40.0, 33.5),
        ];
        mark_pareto(&mut points);
        let front: Vec<(f64, f64)> = points
            .iter()
            .filter(|p| p.pareto)
            .map(|p| (p.bits_per_pixel, p.psnr_srgb8))
            .collect();
        assert_eq!(front, vec![(5.0, 31.0), (20.0, 34.0)]);
        assert!(points
            .windows(2)
            .all(|w| w[0].bits_per_pixel <= w[1].bits_per_pixel));
        let report = RdReport {
            capture: String::new(),
            images: 0,
            width: 1,
            height: 1,
            protocol: String::new(),
            holdouts: vec![],
            masked: false,
            fits: vec![],
            points,
            seconds: 0.0,
        };
        assert_eq!(report.best_within(19.0).unwrap().psnr_srgb8, 31.0);
        assert_eq!(report.best_within(25.0).unwrap().psnr_srgb8, 34.0);
        assert!(report.best_within(4.0).is_none());
    }

    #[test]
    fn spread_keeps_the_ends() {
        let all: Vec<usize> = (0..72).collect();
        assert_eq!(spread(all.clone(), Some(3)), vec![0, 36, 71]);
        assert_eq!(spread(all.clone(), Some(1)), vec![0]);
        assert_eq!(spread(all.clone(), None).len(), 72);
        assert_eq!(spread(all, Some(100)).len(), 72);
    }

    #[test]
    fn every_point_is_a_real_file_scored_at_the_held_out_lights() {
        let dirs = crate::sphere::hemisphere_fibonacci(16);
        let capture = crate::synth::bumpy_plane(20, 12, &dirs);
        let options = RdOptions {
            holdout: Holdout::Spread(2),
            bases: vec![BasisRequest::parse("sh:4").unwrap()],
            fit: FitOptions {
                lambda: crate::fit::Lambda::Fixed(1e-3),
                ..FitOptions::default()
            },
            max_settings: Some(3),
            ..RdOptions::default()
        };
        let report = curve(&capture, &options, &crate::progress::Silent).unwrap();
        assert_eq!(report.holdouts, vec![0, 15]);
        assert_eq!(report.points.len(), 4, "the EXR and three settings");
        assert_eq!(report.points.iter().filter(|p| p.lossless).count(), 1);
        for p in &report.points {
            assert_eq!(p.file_bytes.len(), 2, "one file per fit");
            assert!(p.file_bytes.iter().all(|&b| b > 0));
            let bits = 8.0 * (p.file_bytes[0] + p.file_bytes[1]) as f64 / 2.0 / 240.0;
            assert!((p.bits_per_pixel - bits).abs() < 1e-9);
            assert!(p.psnr_srgb8.is_finite() && p.psnr_srgb8 > 15.0, "{p:?}");
        }
        assert!(report.points[0].pareto);
        assert_eq!(report.fits[0].fitted, vec!["sh:4".to_string()]);
        assert_eq!(report.fits[0].settings, 3);
    }
}
