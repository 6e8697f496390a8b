//! `relit eval`: fidelity against held-out captured lights.

use crate::cmd_fit::StorageArg;
use crate::shared::{mib, Bars, FitArgs};
use relit::capture::Capture;
use relit::codec::Storage;
use relit::eval::{evaluate, EvalOptions, Holdout};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The capture: an RTI `.lp` file or a relit manifest `.json`.
    pub capture: PathBuf,
    /// Images to hold out: `every:N`, `spread:N` (N evenly spread; `spread:5` is the
    /// RTI peer-baseline protocol) or indices in capture order like `0,12,24,35,47`.
    #[arg(long, default_value = "spread:5")]
    pub holdout: String,
    /// Fit once without all held-out images (default: one fit per held-out image).
    #[arg(long)]
    pub joint: bool,
    /// Mask image (> 0.5 inside) restricting the linear PSNR.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Precision the maps are stored (and scored) at.
    #[arg(long, value_enum, default_value_t = StorageArg::Half)]
    pub storage: StorageArg,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let capture = Capture::open(&args.capture)?;
    let holdout: Holdout = args.holdout.parse()?;
    let mask = match &args.mask {
        Some(path) => {
            let (w, h, values) = relit::image::load_scalar(path)?;
            anyhow::ensure!(
                (w, h) == (capture.width, capture.height),
                "mask {} is {w}×{h} but the capture is {}×{}",
                path.display(),
                capture.width,
                capture.height
            );
            Some(values)
        }
        None => None,
    };
    let options = EvalOptions {
        holdout,
        fit: args.fit.to_options()?,
        storage: match args.storage {
            StorageArg::Half => Storage::Half,
            StorageArg::Float => Storage::Float,
        },
        joint: args.joint,
        mask,
    };
    let bars = Bars::new(args.quiet || args.json);
    let report = evaluate(&capture, &options, &bars)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}: {} images of {}×{}, {} ({} coefficients), {} objective, {} maps, {}",
        report.capture,
        report.images,
        report.width,
        report.height,
        report.basis,
        report.coefficients,
        report.objective,
        report.storage,
        report.protocol
    );
    println!(
        "{:>6}  {:<24} {:>12} {:>12} {:>8} {:>8}",
        "index", "image", "sRGB8 dB", "linear dB", "λ", "fit s"
    );
    for h in &report.holdouts {
        println!(
            "{:>6}  {:<24} {:>12.2} {:>12.2} {:>8.0e} {:>8.2}",
            h.index, h.image, h.psnr_srgb8, h.psnr_linear, h.lambda, h.fit_seconds
        );
    }
    println!(
        "mean    {:<24} {:>12.2} {:>12.2}",
        if report.masked {
            "(linear inside mask)"
        } else {
            ""
        },
        report.psnr_srgb8_mean,
        report.psnr_linear_mean
    );
    println!(
        "stored maps: {:.1} bytes/pixel; fit {:.2} s each; peak memory {}",
        report.bytes_per_pixel,
        report.fit_seconds,
        mib(report.peak_rss_bytes)
    );
    Ok(())
}
