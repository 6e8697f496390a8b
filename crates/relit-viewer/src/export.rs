//! `export_web`: the viewer and a bundle as a static folder any web server can host.

use crate::assets::ASSETS;
use crate::bundle::{BundleOptions, WebBundle};
use crate::tiles::TileSource;
use crate::{invalid, io_error};
use relit::fsutil::{check_outputs, Output};
use relit::{Error, ErrorKind, Result};
use std::path::Path;

/// What an export wrote.
#[derive(Clone, Debug)]
pub struct ExportSummary {
    pub files: usize,
    pub bytes: usize,
}

/// Write the viewer's assets and the bundle of the relightable EXR `input` into `dir`.
///
/// Everything goes to a temporary folder beside `dir` first, renamed onto `dir` when
/// complete; an existing `dir` must be empty or an earlier export (it then is replaced),
/// so a failure never leaves a half-written site and no unrelated folder is deleted.
/// A `dir` that holds `input` or an environment map is refused before anything is read.
pub fn export_web(input: &Path, dir: &Path, options: &BundleOptions) -> Result<ExportSummary> {
    let inputs: Vec<&Path> = std::iter::once(input)
        .chain(options.environments.iter().map(|p| p.as_path()))
        .collect();
    check_outputs(&inputs, &[Output::folder(dir)])?;
    let mut options = options.clone();
    if options.source_name.is_empty() {
        options.source_name = input
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
    }
    let bundle = WebBundle::read(input, &options)?;
    write_site(&bundle, dir)
}

/// Write the assets and `bundle` into `dir` atomically (see [`export_web`]).
pub fn write_site(bundle: &WebBundle, dir: &Path) -> Result<ExportSummary> {
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    if !parent.is_dir() {
        return Err(Error::new(
            ErrorKind::Io,
            format!("output folder's parent {} does not exist", parent.display()),
        ));
    }
    if dir.exists() {
        let is_export = dir.join("data").join("info.json").is_file();
        let empty = dir.is_dir()
            && std::fs::read_dir(dir)
                .map_err(|e| io_error(dir, "list", e))?
                .next()
                .is_none();
        if !dir.is_dir() || !(is_export || empty) {
            return Err(invalid(format!(
                "{} exists and is not an empty folder or an earlier export; refusing to replace it",
                dir.display()
            )));
        }
    }
    let tmp = tempfile::Builder::new()
        .prefix(".relit-web-")
        .tempdir_in(&parent)
        .map_err(|e| io_error(&parent, "create a temporary folder in", e))?;
    let mut files = 0;
    let mut bytes = 0;
    let mut put = |rel: &str, body: &[u8]| -> Result<()> {
        let path = tmp.path().join(rel);
        if let Some(p) = path.parent() {
            std::fs::create_dir_all(p).map_err(|e| io_error(p, "create", e))?;
        }
        std::fs::write(&path, body).map_err(|e| io_error(&path, "write", e))?;
        files += 1;
        bytes += body.len();
        Ok(())
    };
    for (rel, _, body) in ASSETS {
        put(rel, body.as_bytes())?;
    }
    for (rel, body) in &bundle.files {
        put(rel, body)?;
    }
    // A static host cannot read tiles on demand: every tile of every level goes in.
    if let Some(source) = &bundle.tiles {
        for (level, x, y) in source.tiles() {
            put(
                &TileSource::tile_path(level, x, y),
                &source.tile(level, x, y)?,
            )?;
        }
    }
    let staged = tmp.keep();
    let old = if dir.exists() {
        let old = parent.join(format!(
            ".relit-web-old-{}-{}",
            std::process::id(),
            dir.file_name()
                .map(|n| n.to_string_lossy())
                .unwrap_or_default()
        ));
        std::fs::rename(dir, &old).map_err(|e| io_error(dir, "move aside", e))?;
        Some(old)
    } else {
        None
    };
    if let Err(e) = std::fs::rename(&staged, dir) {
        if let Some(old) = &old {
            let _ = std::fs::rename(old, dir);
        }
        let _ = std::fs::remove_dir_all(&staged);
        return Err(io_error(dir, "rename the finished export to", e));
    }
    if let Some(old) = old {
        let _ = std::fs::remove_dir_all(old);
    }
    Ok(ExportSummary { files, bytes })
}
