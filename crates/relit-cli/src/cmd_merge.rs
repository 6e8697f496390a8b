//! `relit merge`: join the parts of a sharded fit (`relit fit --tile I/N`) into one file.

use crate::shared::{refuse_overwriting_inputs, CompressArgs};
use anyhow::Context;
use relit::codec::{self, FileForm};
use relit::fsutil::Output;
use relit::storage::Precision;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Every part's EXR, in any order (`shard_*.exr`).
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// The joined file: OpenEXR, or compressed when it ends in `.rlz`.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub compress: CompressArgs,
    /// Precision of an EXR output: f16 or f32; default the parts' own (f32 if any part
    /// holds f32, so that nothing is rounded on the way).
    #[arg(long)]
    pub storage: Option<Precision>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The precision an EXR part stores its maps at, from its header.
fn stored_precision(path: &std::path::Path) -> Option<Precision> {
    let summary = codec::exr::read_metadata_summary(path).ok()?;
    let (_, value) = summary.iter().find(|(k, _)| k == "relit.storage")?;
    value.parse().ok()
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let form = FileForm::for_output(&args.output);
    anyhow::ensure!(
        matches!(form, FileForm::Exr | FileForm::Compressed),
        "relit merge writes OpenEXR or a compressed `.rlz`: name the output `*.exr` or `*.rlz`"
    );
    refuse_overwriting_inputs(&args.parts, &[Output::file(&args.output)])?;
    let start = std::time::Instant::now();
    let storage = args.storage.unwrap_or_else(|| {
        if args
            .parts
            .iter()
            .any(|p| stored_precision(p) == Some(Precision::F32))
        {
            Precision::F32
        } else {
            Precision::F16
        }
    });
    if form == FileForm::Exr {
        // A band of rows at a time from every part's file: the maps are never held
        // whole (the depth map is, when the parts have one).
        storage.require(&[Precision::F32, Precision::F16], "--storage (OpenEXR)")?;
        let (meta, (width, height)) =
            relit::shard::merge_exr_files(&args.parts, &args.output, storage)
                .with_context(|| format!("writing {}", args.output.display()))?;
        let summary = Summary {
            description: format!("OpenEXR {storage}"),
            basis: meta.basis.build()?.name(),
            width,
            height,
            fit_seconds: meta.fit.as_ref().map(|f| f.seconds),
        };
        return report(&args, &summary, start);
    }
    let settings = args.compress.settings();
    let exr_parts = args
        .parts
        .iter()
        .all(|p| matches!(FileForm::of(p), Ok(FileForm::Exr)));
    // The whole image's shape: the parts' widths and coefficients, their rows together.
    let shape = || -> anyhow::Result<(usize, usize, usize)> {
        let mut whole = (0, 0, 0);
        for part in &args.parts {
            let s = codec::exr::read_shape(part)?;
            whole = (s.width.max(whole.0), whole.1 + s.height, s.k.max(whole.2));
        }
        Ok(whole)
    };
    if exr_parts && crate::shared::pack_in_bands(&settings, shape()?) {
        // The parts merged a band at a time into a lossless file (f32: the parts' values
        // as they read), then packed a band at a time from it.
        let whole = crate::shared::temporary_beside(&args.output, ".relit-merge-", ".exr")?;
        let (meta, (width, height)) =
            relit::shard::merge_exr_files(&args.parts, &whole, Precision::F32)
                .with_context(|| format!("writing {}", whole.display()))?;
        let bars = crate::shared::Bars::new(args.json);
        codec::packed::write_in_bands(&whole, &args.output, &settings, &bars)
            .with_context(|| format!("writing {}", args.output.display()))?;
        let summary = Summary {
            description: settings.describe(),
            basis: meta.basis.build()?.name(),
            width,
            height,
            fit_seconds: meta.fit.as_ref().map(|f| f.seconds),
        };
        return report(&args, &summary, start);
    }
    // One part in memory at a time beside the whole image's maps: a file whose settings
    // need every pixel at once.
    let read =
        |p: &std::path::PathBuf| codec::read(p).with_context(|| format!("reading {}", p.display()));
    let count = args.parts.len();
    let mut merger = relit::shard::Merger::new(
        read(&args.parts[0])?,
        &args.parts[0].display().to_string(),
        count,
    )?;
    for path in &args.parts[1..] {
        merger.add(read(path)?, &path.display().to_string())?;
    }
    let image = merger.finish()?;
    codec::packed::write(&args.output, &image, &settings)
        .with_context(|| format!("writing {}", args.output.display()))?;
    let summary = Summary {
        description: settings.describe(),
        basis: image.meta.basis.build()?.name(),
        width: image.width(),
        height: image.height(),
        fit_seconds: image.meta.fit.as_ref().map(|f| f.seconds),
    };
    report(&args, &summary, start)
}

/// What a merge wrote.
struct Summary {
    description: String,
    basis: String,
    width: usize,
    height: usize,
    fit_seconds: Option<f64>,
}

/// Print what was written (JSON with `--json`).
fn report(args: &Args, s: &Summary, start: std::time::Instant) -> anyhow::Result<()> {
    let bytes = crate::shared::size_on_disk(&args.output)?;
    let seconds = start.elapsed().as_secs_f64();
    let count = args.parts.len();
    if args.json {
        let value = serde_json::json!({
            "output": args.output.display().to_string(),
            "parts": count,
            "width": s.width,
            "height": s.height,
            "basis": s.basis,
            "settings": s.description,
            "bytes": bytes,
            "fit_seconds": s.fit_seconds,
            "seconds": seconds,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!(
            "wrote {} ({}, basis {}, {}×{}) from {count} parts: {} bytes, {:.2} s",
            args.output.display(),
            s.description,
            s.basis,
            s.width,
            s.height,
            bytes,
            seconds
        );
    }
    Ok(())
}
