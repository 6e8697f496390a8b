//! `relit info`: what a relightable file holds.

use relit::codec::exr;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable EXR written by `relit fit`.
    pub file: PathBuf,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let image = exr::read(&args.file)?;
    let meta = &image.meta;
    let bytes = std::fs::metadata(&args.file)?.len();
    let attributes = exr::read_metadata_summary(&args.file)?;
    let storage = attributes
        .iter()
        .find(|(k, _)| k == "relit.storage")
        .map(|(_, v)| v.clone())
        .unwrap_or_default();
    if args.json {
        let value = serde_json::json!({
            "file": args.file.display().to_string(),
            "width": image.width(),
            "height": image.height(),
            "format_version": meta.format_version,
            "basis": meta.basis,
            "coefficients": image.maps.k,
            "color_space": meta.color_space,
            "light_frame": meta.light_frame,
            "projection": meta.projection,
            "storage": storage,
            "depth": image.depth.is_some(),
            "fit": meta.fit,
            "file_bytes": bytes,
            "bytes_per_pixel": bytes as f64 / (image.width() * image.height()) as f64,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    println!("{}", args.file.display());
    println!("  size          {}×{}", image.width(), image.height());
    println!(
        "  basis         {} ({} coefficients × RGB)",
        meta.basis.build()?.name(),
        image.maps.k
    );
    println!("  color space   {}", meta.color_space.name());
    println!(
        "  storage       {storage}, {} ({:.1} bytes/pixel)",
        relit::memory::mib(bytes),
        bytes as f64 / (image.width() * image.height()) as f64
    );
    println!("  light frame   {}", meta.light_frame);
    println!(
        "  projection    {}",
        serde_json::to_string(&meta.projection)?
    );
    println!(
        "  depth         {}",
        if image.depth.is_some() { "yes" } else { "no" }
    );
    println!("  format        relit {}", meta.format_version);
    if let Some(fit) = &meta.fit {
        println!(
            "  fit           {} objective, {} regulariser, λ = {:.0e} ({}), {} images, {:.2} s",
            fit.objective, fit.regularizer, fit.lambda, fit.lambda_choice, fit.images, fit.seconds
        );
        println!(
            "  residual      RMSE (linear) R {:.4} G {:.4} B {:.4}; training 8-bit sRGB PSNR {:.2} dB",
            fit.rmse_linear[0], fit.rmse_linear[1], fit.rmse_linear[2], fit.psnr_srgb8
        );
    }
    Ok(())
}
