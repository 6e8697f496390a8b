//! `relit view`: serve the interactive relighting viewer for one file.

use relit::storage::Precision;
use relit_viewer::{serve, BundleOptions, Tiling, WebBundle};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable EXR written by `relit fit`.
    pub file: PathBuf,
    /// Port to listen on (0 or absent: an ephemeral port).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Open the viewer in the default browser.
    #[arg(long)]
    pub open: bool,
    /// How coefficient planes are sent: f16 (half floats) or u8 (quantised 8-bit PNG).
    #[arg(long, default_value = "f16")]
    pub storage: Precision,
    /// Whole coefficient layers (`off`), tiles of N pixels with a mip pyramid, sent at
    /// the level and region the view needs (64 to 1024; a relit EXR or a `.rlz` file of
    /// planes, read from its own mip levels where it has them; half floats),
    /// or `auto`: tiles of 256 when whole layers would pass 512 MiB.
    #[arg(long, default_value = "auto")]
    pub tiles: Tiling,
    /// With tiles: the MiB the overview (the coarse level always held, drawn where a
    /// tile has not arrived) may take; the finest level within them is used.
    #[arg(long, default_value_t = (relit_viewer::tiles::OVERVIEW_BYTES >> 20) as f64)]
    pub overview_mib: f64,
    /// Lat-long environment maps (.hdr/.exr) offered as environment lights. Repeatable.
    #[arg(long = "env")]
    pub envs: Vec<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    args.storage
        .require(&relit_viewer::PRECISIONS, "--storage (the viewer)")?;
    let options = BundleOptions {
        precision: args.storage,
        environments: args.envs.clone(),
        source_name: args
            .file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        tiling: args.tiles,
        overview_bytes: (args.overview_mib.max(0.0) * 1048576.0) as usize,
    };
    let bundle = WebBundle::read(&args.file, &options)?;
    let bytes = bundle.bytes();
    let tiles = bundle.tiles.as_ref().map(|t| match t.overview_level() {
        0 => ", the whole image: no tiles needed".to_string(),
        l => format!(
            " for level {l}, and {}-pixel tiles of levels 0 to {} read from the file as the view asks",
            t.side(),
            l - 1
        ),
    });
    let server = serve(bundle, &args.host, args.port)?;
    let url = server.url();
    println!("{url}");
    eprintln!(
        "relit view: serving {} ({:.1} MiB of {} planes{}) at {url}; Ctrl-C stops",
        args.file.display(),
        bytes as f64 / (1024.0 * 1024.0),
        args.storage.name(),
        tiles.unwrap_or_default()
    );
    use std::io::Write;
    let _ = std::io::stdout().flush();
    if args.open {
        let opener = if cfg!(target_os = "macos") {
            "open"
        } else if cfg!(windows) {
            "explorer"
        } else {
            "xdg-open"
        };
        if let Err(e) = std::process::Command::new(opener).arg(&url).spawn() {
            eprintln!("relit view: could not open a browser ({opener}: {e}); open {url} yourself");
        }
    }
    server.wait();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Args;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    #[test]
    fn listens_on_loopback_unless_told_otherwise() {
        let cli = Cli::try_parse_from(["view", "scene.exr"]).unwrap();
        assert_eq!(cli.args.host, "127.0.0.1");
        assert_eq!(cli.args.port, 0);
        let cli = Cli::try_parse_from(["view", "scene.exr", "--host", "0.0.0.0", "--port", "8080"])
            .unwrap();
        assert_eq!((cli.args.host.as_str(), cli.args.port), ("0.0.0.0", 8080));
    }
}
