//! `relit compare A B`: how far one image is from another, by the same definitions
//! every relit figure uses (`relit::metrics`).

use crate::shared::refuse_overwriting_inputs;
use anyhow::{bail, Context};
use relit::fsutil::Output;
use relit::image::ImageRgb;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The image under test (PNG/JPEG/TIFF as 8-bit or 16-bit sRGB, EXR/HDR linear).
    pub test: PathBuf,
    /// The reference image, the same size.
    pub reference: PathBuf,
    /// Score only the pixels where this single-channel image is above one half.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Write a false-colour picture of the per-pixel difference (8-bit sRGB codes,
    /// the largest of the three channels; black none, through blue, green and yellow,
    /// to red at the scale printed).
    #[arg(long)]
    pub diff: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Report {
    test: String,
    reference: String,
    width: usize,
    height: usize,
    /// Pixels scored (all, or inside the mask).
    pixels: usize,
    masked: bool,
    psnr_linear: f64,
    psnr_srgb8: f64,
    ssim: f64,
    /// Largest and mean absolute difference of linear samples.
    max_abs_error: f64,
    mean_abs_error: f64,
    /// The difference picture and the 8-bit difference its red stands for.
    #[serde(skip_serializing_if = "Option::is_none")]
    diff: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    diff_scale: Option<u8>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut inputs = vec![args.test.clone(), args.reference.clone()];
    inputs.extend(args.mask.iter().cloned());
    refuse_overwriting_inputs(
        &inputs,
        &args.diff.iter().map(Output::file).collect::<Vec<_>>(),
    )?;
    let test = relit::image::load_linear(&args.test, None)?;
    let reference = relit::image::load_linear(&args.reference, None)?;
    if (test.width, test.height) != (reference.width, reference.height) {
        bail!(
            "{} is {}×{} but {} is {}×{}: compare images of one size",
            args.test.display(),
            test.width,
            test.height,
            args.reference.display(),
            reference.width,
            reference.height
        );
    }
    let (w, h) = (test.width, test.height);
    let mask = match &args.mask {
        Some(path) => {
            let (mw, mh, values) = relit::image::load_scalar(path)?;
            if (mw, mh) != (w, h) {
                bail!(
                    "the mask {} is {mw}×{mh}, the images {w}×{h}",
                    path.display()
                );
            }
            Some(values)
        }
        None => None,
    };
    let mask = mask.as_deref();
    let inside = |p: usize| mask.is_none_or(|m| m[p] > 0.5);
    let pixels = (0..w * h).filter(|&p| inside(p)).count();
    if pixels == 0 {
        bail!("the mask selects no pixel");
    }
    let psnr = relit::metrics::compare(&test.data, &reference.data, mask);
    let ssim = relit::metrics::ssim(&test.data, &reference.data, w, h, mask);
    let (mut max_abs, mut sum_abs) = (0.0f64, 0.0f64);
    for p in (0..w * h).filter(|&p| inside(p)) {
        for c in 0..3 {
            let d = (test.data[3 * p + c] as f64 - reference.data[3 * p + c] as f64).abs();
            let d = if d.is_finite() { d } else { f64::INFINITY };
            max_abs = max_abs.max(d);
            sum_abs += d;
        }
    }
    let (mut diff, mut diff_scale) = (None, None);
    if let Some(path) = &args.diff {
        let scale = write_difference(path, &test, &reference, mask)?;
        diff = Some(path.display().to_string());
        diff_scale = Some(scale);
    }
    let report = Report {
        test: args.test.display().to_string(),
        reference: args.reference.display().to_string(),
        width: w,
        height: h,
        pixels,
        masked: mask.is_some(),
        psnr_linear: psnr.psnr_linear,
        psnr_srgb8: psnr.psnr_srgb8,
        ssim,
        max_abs_error: max_abs,
        mean_abs_error: sum_abs / (3 * pixels) as f64,
        diff,
        diff_scale,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{} against {} ({w}×{h}, {} pixels{})",
        report.test,
        report.reference,
        pixels,
        if report.masked { " in the mask" } else { "" }
    );
    println!(
        "  PSNR {:.2} dB linear (peak 1), {:.2} dB 8-bit sRGB; SSIM {:.4}",
        report.psnr_linear, report.psnr_srgb8, report.ssim
    );
    println!(
        "  absolute error (linear): max {:.4}, mean {:.5}",
        report.max_abs_error, report.mean_abs_error
    );
    if let (Some(path), Some(scale)) = (&report.diff, report.diff_scale) {
        println!("  wrote {path} (red = a difference of {scale} in 8-bit sRGB codes or more)");
    }
    Ok(())
}

/// The false-colour difference picture; returns the 8-bit difference shown as red (the
/// 99.9th percentile of the scored pixels' differences, at least 1). Pixels outside the
/// mask are dark grey.
fn write_difference(
    path: &Path,
    test: &ImageRgb,
    reference: &ImageRgb,
    mask: Option<&[f32]>,
) -> anyhow::Result<u8> {
    let n = test.width * test.height;
    let code = relit::color::linear_to_srgb8;
    let difference: Vec<u8> = (0..n)
        .map(|p| {
            (0..3)
                .map(|c| code(test.data[3 * p + c]).abs_diff(code(reference.data[3 * p + c])))
                .max()
                .unwrap_or(0)
        })
        .collect();
    let inside = |p: usize| mask.is_none_or(|m| m[p] > 0.5);
    let mut scored: Vec<u8> = (0..n)
        .filter(|&p| inside(p))
        .map(|p| difference[p])
        .collect();
    scored.sort_unstable();
    let scale = scored
        .get(((scored.len() as f64 - 1.0) * 0.999) as usize)
        .copied()
        .unwrap_or(1)
        .max(1);
    // Black → blue → green → yellow → red.
    let stops: [[f64; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [0.0, 0.2, 1.0],
        [0.0, 0.9, 0.2],
        [1.0, 0.9, 0.0],
        [1.0, 0.0, 0.0],
    ];
    let colour = |t: f64| -> [u8; 3] {
        let x = t.clamp(0.0, 1.0) * 4.0;
        let i = (x.floor() as usize).min(3);
        let f = x - i as f64;
        std::array::from_fn(|c| {
            ((stops[i][c] * (1.0 - f) + stops[i + 1][c] * f) * 255.0).round() as u8
        })
    };
    let bytes: Vec<u8> = (0..n)
        .flat_map(|p| {
            if inside(p) {
                colour(difference[p] as f64 / scale as f64)
            } else {
                [40, 40, 40]
            }
        })
        .collect();
    relit::image::save_srgb8_png(path, test.width, test.height, bytes)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(scale)
}
