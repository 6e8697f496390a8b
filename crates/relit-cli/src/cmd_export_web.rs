//! `relit export-web`: the viewer and a file's data as a static web folder.

use crate::shared::refuse_overwriting_inputs;
use relit::fsutil::Output;
use relit::storage::Precision;
use relit_viewer::{export_web, BundleOptions, PRECISIONS};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable EXR written by `relit fit`.
    pub file: PathBuf,
    /// Output folder (created; an earlier export there is replaced).
    pub dir: PathBuf,
    /// Precision of the coefficient layers: u8 (8-bit PNG, scale/offset per plane) or
    /// f16 (half floats).
    #[arg(long, default_value = "u8")]
    pub storage: Precision,
    /// Lat-long environment maps (.hdr/.exr) offered as environment lights. Repeatable.
    #[arg(long = "env")]
    pub envs: Vec<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    args.storage
        .require(&PRECISIONS, "--storage (the viewer)")?;
    // An earlier export in the folder is replaced whole, so nothing it holds may be read.
    let mut inputs = vec![args.file.clone()];
    inputs.extend(args.envs.iter().cloned());
    refuse_overwriting_inputs(&inputs, &[Output::folder(&args.dir)])?;
    let options = BundleOptions {
        precision: args.storage,
        environments: args.envs.clone(),
        source_name: String::new(),
    };
    let summary = export_web(&args.file, &args.dir, &options)?;
    println!(
        "wrote {} ({} files, {:.1} MiB); host it with any static web server",
        args.dir.display(),
        summary.files,
        summary.bytes as f64 / (1024.0 * 1024.0)
    );
    Ok(())
}
