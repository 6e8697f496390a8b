//! `relit info`: what a relightable file holds.

use relit::codec::{self, exr, FileForm};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable file (EXR or compressed .rlz).
    pub file: PathBuf,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
}

/// What `info` shows of a file: its metadata, size, coefficients and whether it has
/// depth. A relit EXR or a `.rlz` file is read no further than its header, so that a file of gigabytes answers at once; the RTI tools' files and web
/// folders are read whole.
struct Summary {
    meta: relit::maps::Metadata,
    width: usize,
    height: usize,
    k: usize,
    depth: bool,
}

fn summary(path: &std::path::Path) -> anyhow::Result<Summary> {
    Ok(match FileForm::of(path)? {
        FileForm::Exr => {
            let shape = exr::read_shape(path)?;
            Summary {
                k: shape.k,
                depth: shape.depth,
                meta: shape.meta,
                width: shape.width,
                height: shape.height,
            }
        }
        FileForm::Compressed => {
            let header = codec::packed::read_header(path)?;
            Summary {
                k: header.meta.basis.build()?.len(),
                depth: header.depth,
                width: header.width,
                height: header.height,
                meta: header.meta,
            }
        }
        _ => {
            let image = codec::read(path)?;
            Summary {
                width: image.width(),
                height: image.height(),
                k: image.maps.k,
                depth: image.depth.is_some(),
                meta: image.meta,
            }
        }
    })
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let image = summary(&args.file)?;
    let meta = &image.meta;
    let bytes = crate::shared::size_on_disk(&args.file)?;
    let storage = match FileForm::of(&args.file)? {
        FileForm::Web => codec::web::describe(&args.file)?,
        FileForm::Exr => {
            let precision = exr::read_metadata_summary(&args.file)?
                .into_iter()
                .find(|(k, _)| k == "relit.storage")
                .map(|(_, v)| v)
                .unwrap_or_default();
            format!(
                "OpenEXR {precision} in {}",
                exr::describe_layout(&args.file)?
            )
        }
        FileForm::Ptm => codec::ptm::describe(&args.file)?,
        FileForm::Rti => "HSH .rti (8-bit codes)".to_string(),
        FileForm::Compressed => {
            let header = codec::packed::read_header(&args.file)?;
            let functions = header.layout.channels().0;
            let counts: Vec<String> = functions
                .iter()
                .map(|f| {
                    header
                        .planes
                        .iter()
                        .filter(|p| p.channel == *f)
                        .count()
                        .to_string()
                })
                .collect();
            let levels = header
                .planes
                .iter()
                .map(|p| p.quantizer.levels)
                .max()
                .unwrap_or(0);
            let pixels = match header.codebook {
                Some(entries) if !header.indexed_pixels() => format!(
                    "{} planes of ≤ {levels} levels, {} tiles of {}², and components {}–{} of each function from a codebook of {entries} entries (the PCA residual, zstd index tiles)",
                    header.planes.len(),
                    header.codec.name(),
                    header.tile,
                    header.residual[0].index + 1,
                    header.residual[0].index + header.residual.len() / counts.len(),
                ),
                Some(entries) => format!(
                    "a codebook of {entries} entries ({} values each, ≤ {levels} levels), {} index tiles of {}²",
                    header.planes.len(),
                    header.codec.name(),
                    header.tile
                ),
                None => format!(
                    "{} planes of ≤ {levels} levels, {} tiles of {}²{}",
                    header.planes.len(),
                    header.codec.name(),
                    header.tile,
                    if header.levels > 1 {
                        format!(", {} mip levels", header.levels)
                    } else {
                        String::new()
                    }
                ),
            };
            let gain = if header.gain {
                ", divided by a perceptual gain"
            } else {
                ""
            };
            let blocks = match header.pca_block {
                Some(b) => {
                    let (across, down) = header.pca_blocks();
                    format!(" per block of {b}² ({across}×{down} blocks)")
                }
                None => String::new(),
            };
            format!(
                "compressed: {} layout, {} components{blocks}{gain}, {pixels}",
                header.layout.name(),
                counts.join("/"),
            )
        }
    };
    if args.json {
        let value = serde_json::json!({
            "file": args.file.display().to_string(),
            "width": image.width,
            "height": image.height,
            "format_version": meta.format_version,
            "basis": meta.basis,
            "coefficients": image.k,
            "color_space": meta.color_space,
            "light_frame": meta.light_frame,
            "projection": meta.projection,
            "storage": storage,
            "depth": image.depth,
            "fit": meta.fit,
            "bake": meta.bake,
            "file_bytes": bytes,
            "bytes_per_pixel": bytes as f64 / (image.width * image.height) as f64,
            "bits_per_pixel": 8.0 * bytes as f64 / (image.width * image.height) as f64,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    println!("{}", args.file.display());
    println!("  size          {}×{}", image.width, image.height);
    println!(
        "  basis         {} ({} coefficients × RGB)",
        meta.basis.build()?.name(),
        image.k
    );
    println!("  color space   {}", meta.color_space.name());
    println!(
        "  storage       {storage}, {} ({:.1} bits/pixel)",
        relit::memory::mib(bytes),
        8.0 * bytes as f64 / (image.width * image.height) as f64
    );
    println!("  light frame   {}", meta.light_frame);
    println!(
        "  projection    {}",
        serde_json::to_string(&meta.projection)?
    );
    println!("  depth         {}", if image.depth { "yes" } else { "no" });
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
        if let Some(shard) = fit.shard {
            println!("  shard         {shard} (join the parts with `relit merge`)");
        }
    }
    if let Some(bake) = &meta.bake {
        let bounces = if bake.indirect > 0 {
            format!(
                ", {} bounce rays × {} directions",
                bake.indirect, bake.bounce_samples
            )
        } else {
            String::new()
        };
        println!(
            "  baked         {} transfer, {} directions per sample{bounces}, {}×{} samples per pixel, {} window, noise {:.2} %, {:.2} s",
            bake.transfer,
            bake.samples,
            bake.supersample,
            bake.supersample,
            bake.window,
            100.0 * bake.noise,
            bake.seconds
        );
    }
    Ok(())
}
