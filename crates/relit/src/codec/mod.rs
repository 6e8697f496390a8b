//! Files that hold relightable images.
//!
//! * OpenEXR ([`exr`]) is the native, lossless form: maps stored in a
//!   [`crate::storage::Precision`] (f32 or f16), readable by any EXR tool.
//! * The compressed form ([`packed`], `.rlz`): principal components, quantised planes,
//!   zstd or JPEG tiles ([`crate::compress`]).
//!
//! * The relight/OpenLIME web format ([`web`]): a folder with `info.json` and 8-bit
//!   plane images, what museums publish RTIs in.
//!
//! [`read`] opens any of them (a folder holding `info.json` is the web format, a file is
//! told by its first bytes, not its name), so every command that reads a relightable
//! file reads all of them.

pub mod exr;
pub mod packed;
pub mod web;

use crate::maps::RelightableImage;
use crate::storage::{CompactPlanes, Precision};
use crate::Result;
use std::path::Path;

/// The two forms of relightable file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileForm {
    Exr,
    Compressed,
    Web,
}

impl FileForm {
    /// The form of the file at `path`, from its first bytes.
    pub fn of(path: &Path) -> Result<FileForm> {
        if web::is_web(path) {
            return Ok(FileForm::Web);
        }
        Ok(if packed::is_packed(path)? {
            FileForm::Compressed
        } else {
            FileForm::Exr
        })
    }

    /// The form an output path asks for: a folder (an existing one, or a path ending in
    /// `/`) is the web format, `.rlz` compressed, anything else EXR.
    pub fn for_output(path: &Path) -> FileForm {
        if path.is_dir() || path.as_os_str().to_string_lossy().ends_with(['/', '\\']) {
            return FileForm::Web;
        }
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("rlz") => FileForm::Compressed,
            _ => FileForm::Exr,
        }
    }
}

/// Read a relightable file of either form.
pub fn read(path: &Path) -> Result<RelightableImage> {
    match FileForm::of(path)? {
        FileForm::Exr => exr::read(path),
        FileForm::Compressed => packed::read(path),
        FileForm::Web => web::read(path),
    }
}

/// Read a relightable file of either form into compact planes (see
/// [`exr::read_compact`]): the returned image's `maps.data` is empty.
pub fn read_compact(
    path: &Path,
    precision: Precision,
) -> Result<(RelightableImage, CompactPlanes)> {
    match FileForm::of(path)? {
        FileForm::Exr => exr::read_compact(path, precision),
        FileForm::Compressed | FileForm::Web => {
            let mut image = read(path)?;
            let planes = CompactPlanes::from_maps(&image.maps, precision)?;
            image.maps.data = Vec::new();
            Ok((image, planes))
        }
    }
}
