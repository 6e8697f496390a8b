//! `relit convert`: between the lossless OpenEXR file, the compressed `.rlz` file, the
//! RTI tools' `.ptm` and `.rti` files and the relight/OpenLIME web folder.

use crate::shared::{refuse_overwriting_inputs, CompressArgs};
use anyhow::Context;
use relit::codec::{self, FileForm};
use relit::fsutil::Output;
use relit::storage::Precision;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable file (EXR, .rlz, .ptm, .rti or a web folder).
    pub input: PathBuf,
    /// The file to write: `.rlz` compresses, `.ptm` and `.rti` write the RTI tools'
    /// files (re-expressed in their basis), a folder (an existing one, or a name ending
    /// in `/`) the relight/OpenLIME web format, any other name OpenEXR.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub web: crate::shared::WebArgs,
    #[command(flatten)]
    pub compress: CompressArgs,
    /// The colour layout of a `.ptm` output: lrgb (one luminance polynomial × RGB, as
    /// PTMfitter writes) or rgb (a polynomial per channel), raw or as HP's JPEG variants
    /// jpeg-lrgb[:Q] and jpeg-rgb[:Q] (each plane a grayscale JPEG of quality Q, default
    /// 90: about a fifth of the bytes).
    #[arg(long, default_value = "lrgb", value_parser = |s: &str| relit::codec::ptm::PtmFormat::parse(s).map_err(|e| e.to_string()))]
    pub ptm_format: relit::codec::ptm::PtmFormat,
    /// What an input `.ptm`/`.rti` file's values are: srgb (the formats' convention,
    /// the default) or linear (what relight-cli writes by default).
    #[arg(long, value_enum)]
    pub file_space: Option<crate::shared::SpaceArg>,
    /// Precision of an EXR output's maps: f16 or f32.
    #[arg(long, default_value = "f16")]
    pub storage: Precision,
    /// Write an EXR output tiled (tiles of this side, default 256) with mip levels, so
    /// that `relit relight --roi/--level` and the viewer read only the tiles a view
    /// needs; a `.rlz` output in tiles of this side with mip levels (`--mip`).
    #[arg(long, num_args = 0..=1, default_missing_value = "256")]
    pub mip_tiles: Option<usize>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let form = FileForm::for_output(&args.output);
    anyhow::ensure!(
        args.mip_tiles.is_none() || matches!(form, FileForm::Exr | FileForm::Compressed),
        "--mip-tiles is for EXR and .rlz outputs"
    );
    let output = if form == FileForm::Web {
        Output::folder(&args.output)
    } else {
        Output::file(&args.output)
    };
    refuse_overwriting_inputs(std::slice::from_ref(&args.input), &[output])?;
    let start = std::time::Instant::now();
    // EXR to tiled EXR with mip levels (a tile at a time) or to .rlz (a band of rows at
    // a time, where the settings need no whole-image step): the maps never held whole.
    let settings = args.compress.settings_with_mip_tiles(args.mip_tiles);
    let from_exr = args.file_space.is_none() && FileForm::of(&args.input)? == FileForm::Exr;
    let streamed = from_exr
        && match form {
            FileForm::Exr => args.mip_tiles.is_some(),
            FileForm::Compressed => {
                let shape = codec::exr::read_shape(&args.input)?;
                crate::shared::pack_in_bands(&settings, (shape.width, shape.height, shape.k))
            }
            _ => false,
        };
    let mut image = if streamed {
        // Only the metadata and one pixel: the summary's size and basis.
        codec::exr::read_region(&args.input, 0, (0, 0, 1, 1))?.image
    } else {
        codec::read(&args.input)?
    };
    crate::shared::apply_file_space(&args.input, &mut image, args.file_space)?;
    let (w, h) = if streamed {
        let shape = codec::exr::read_shape(&args.input)?;
        (shape.width, shape.height)
    } else {
        (image.width(), image.height())
    };
    let description = match form {
        FileForm::Web => {
            let summary = codec::web::write(&args.output, &image, &args.web.options())
                .with_context(|| format!("writing {}", args.output.display()))?;
            format!(
                "web folder, {} {} with {} planes",
                summary.kind, summary.colorspace, summary.planes
            )
        }
        FileForm::Compressed => {
            if streamed {
                let bars = crate::shared::Bars::new(args.json);
                codec::packed::write_in_bands(&args.input, &args.output, &settings, &bars)
                    .map(|_| ())
            } else {
                codec::packed::write(&args.output, &image, &settings).map(|_| ())
            }
            .with_context(|| format!("writing {}", args.output.display()))?;
            settings.describe()
        }
        form @ (FileForm::Ptm | FileForm::Rti) => {
            codec::write_interchange(&args.output, &image, form, args.ptm_format)
                .with_context(|| format!("writing {}", args.output.display()))?
        }
        FileForm::Exr => {
            args.storage
                .require(&[Precision::F32, Precision::F16], "--storage (OpenEXR)")?;
            match args.mip_tiles {
                Some(tile) => {
                    if streamed {
                        codec::exr::write_tiled_from(&args.input, &args.output, args.storage, tile)
                    } else {
                        codec::exr::write_tiled(&args.output, &image, args.storage, tile)
                    }
                    .with_context(|| format!("writing {}", args.output.display()))?;
                    let levels = codec::exr::mip_sizes(w, h).len();
                    format!(
                        "OpenEXR {}, {tile}-pixel tiles, {levels} mip levels",
                        args.storage
                    )
                }
                None => {
                    codec::exr::write(&args.output, &image, args.storage)
                        .with_context(|| format!("writing {}", args.output.display()))?;
                    format!("OpenEXR {}", args.storage)
                }
            }
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    let bytes_in = crate::shared::size_on_disk(&args.input)?;
    let bytes_out = crate::shared::size_on_disk(&args.output)?;
    // What was written, read back: from its header alone when it was streamed or is
    // compressed (decoding a large .rlz whole would hold all its maps again).
    let compressed = args.output.is_file() && codec::packed::is_packed(&args.output)?;
    let (written_basis, written_k) = if streamed && form == FileForm::Exr {
        let shape = codec::exr::read_shape(&args.output)?;
        (shape.meta.basis, shape.k)
    } else if compressed {
        let basis = codec::packed::read_header(&args.output)?.meta.basis;
        let k = basis.build()?.len();
        (basis, k)
    } else {
        let written = codec::read(&args.output)?;
        (written.meta.basis, written.maps.k)
    };
    let basis = written_basis.build()?;
    let bits_per_pixel = |b: u64| 8.0 * b as f64 / (w * h) as f64;
    if args.json {
        let value = serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.output.display().to_string(),
            "settings": description,
            "basis": basis.name(),
            "coefficients": written_k,
            "input_bytes": bytes_in,
            "output_bytes": bytes_out,
            "input_bits_per_pixel": bits_per_pixel(bytes_in),
            "output_bits_per_pixel": bits_per_pixel(bytes_out),
            "ratio": bytes_in as f64 / bytes_out.max(1) as f64,
            "seconds": seconds,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!(
            "wrote {} ({description}, basis {}): {} → {} bytes, {:.1} → {:.1} bits/pixel ({:.1}×), {:.2} s",
            args.output.display(),
            basis.name(),
            bytes_in,
            bytes_out,
            bits_per_pixel(bytes_in),
            bits_per_pixel(bytes_out),
            bytes_in as f64 / bytes_out.max(1) as f64,
            seconds
        );
    }
    Ok(())
}
