//! `relit export-web`: a relightable file as a static web folder, by default in the
//! relight/OpenLIME web format that museum RTI viewers read (`relit::codec::web`), or
//! with relit's own viewer.

use crate::shared::{refuse_overwriting_inputs, WebArgs};
use anyhow::{bail, Context};
use relit::fsutil::Output;
use relit::storage::Precision;
use relit_viewer::{export_web, BundleOptions, Tiling, WebBundle, PRECISIONS};
use std::path::PathBuf;

/// The viewer an export is for.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Viewer {
    /// The relight/OpenLIME web format: `info.json` and JPEG coefficient planes.
    Openlime,
    /// relit's own viewer, its page and assets beside the data.
    Relit,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable file (EXR, .rlz or a web folder).
    pub file: PathBuf,
    /// Output folder (created; files of an earlier export there are replaced).
    pub dir: PathBuf,
    /// Which viewer the folder is for.
    #[arg(long, value_enum, default_value = "openlime")]
    pub viewer: Viewer,
    #[command(flatten)]
    pub web: WebArgs,
    /// relit's viewer only: precision of the coefficient layers, u8 (8-bit PNG,
    /// scale/offset per plane) or f16 (half floats). Default u8 (f16 when tiled).
    #[arg(long)]
    pub storage: Option<Precision>,
    /// relit's viewer only: whole coefficient layers (`off`), tiles of N pixels with a
    /// mip pyramid, read at the level and region a view needs (64 to 1024, a relit EXR
    /// or a `.rlz` file of planes; half floats), or `auto`: tiles of 256 when whole
    /// layers would pass 512 MiB.
    #[arg(long, default_value = "auto")]
    pub tiles: Tiling,
    /// With tiles: the MiB the overview (the coarse level always held, drawn where a
    /// tile has not arrived) may take; the finest level within them is used.
    #[arg(long, default_value_t = (relit_viewer::tiles::OVERVIEW_BYTES >> 20) as f64)]
    pub overview_mib: f64,
    /// relit's viewer only: lat-long environment maps (.hdr/.exr) offered as
    /// environment lights. Repeatable.
    #[arg(long = "env")]
    pub envs: Vec<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut inputs = vec![args.file.clone()];
    inputs.extend(args.envs.iter().cloned());
    refuse_overwriting_inputs(&inputs, &[Output::folder(&args.dir)])?;
    if args.viewer == Viewer::Openlime {
        if args.storage.is_some() || !args.envs.is_empty() || args.tiles != Tiling::Auto {
            bail!("--storage, --tiles and --env are for relit's viewer: add --viewer relit");
        }
        let image = relit::codec::read(&args.file)?;
        let options = args.web.options();
        if options
            .chroma_planes
            .is_some_and(|c| 3 * c < options.planes)
        {
            eprintln!(
                "note: mycc with fewer chroma planes than plane images is relight's layout; \
                 OpenLIME 1.2.6 reads its luma-only images as (Y, C1, C2) triples and shows \
                 it wrong (relit and relight read it right). Plain --mycc avoids this."
            );
        }
        let summary = relit::codec::web::write(&args.dir, &image, &options)
            .with_context(|| format!("writing {}", args.dir.display()))?;
        println!(
            "wrote {} (relight/OpenLIME web format: {} {}, {} planes, {} files, {:.1} MiB); open it with OpenLIME's `rti` layer, layout `{}`",
            args.dir.display(),
            summary.kind,
            summary.colorspace,
            summary.planes,
            summary.files,
            summary.bytes as f64 / (1024.0 * 1024.0),
            args.web.layout().name()
        );
        return Ok(());
    }
    let mut options = BundleOptions {
        precision: args.storage.unwrap_or(Precision::F16),
        environments: args.envs.clone(),
        source_name: String::new(),
        tiling: args.tiles,
        overview_bytes: (args.overview_mib.max(0.0) * 1048576.0) as usize,
    };
    // 8-bit layers unless asked otherwise, but a tiled bundle is half floats.
    if args.storage.is_none() && WebBundle::tile_side(&args.file, &options)?.is_none() {
        options.precision = Precision::U8;
    }
    options
        .precision
        .require(&PRECISIONS, "--storage (the viewer)")?;
    let summary = export_web(&args.file, &args.dir, &options)?;
    println!(
        "wrote {} ({} files, {:.1} MiB); host it with any static web server",
        args.dir.display(),
        summary.files,
        summary.bytes as f64 / (1024.0 * 1024.0)
    );
    Ok(())
}
