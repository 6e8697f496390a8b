//! Files that hold relightable images.
//!
//! * OpenEXR ([`exr`]) is the native, lossless form: maps stored in a
//!   [`crate::storage::Precision`] (f32 or f16), readable by any EXR tool.
//! * The compressed form ([`packed`], `.rlz`): principal components, quantised planes,
//!   zstd or JPEG tiles ([`crate::compress`]).
//!
//! [`read`] opens either (by the file's first bytes, not its name), so every command
//! that reads a relightable file reads both.

pub mod exr;
pub mod packed;

use crate::maps::RelightableImage;
use crate::storage::{CompactPlanes, Precision};
use crate::Result;
use std::path::Path;

/// The two forms of relightable file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileForm {
    Exr,
    Compressed,
}

impl FileForm {
    /// The form of the file at `path`, from its first bytes.
    pub fn of(path: &Path) -> Result<FileForm> {
        Ok(if packed::is_packed(path)? {
            FileForm::Compressed
        } else {
            FileForm::Exr
        })
    }

    /// The form an output path asks for: `.rlz` is compressed, anything else EXR.
    pub fn for_output(path: &Path) -> FileForm {
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
        FileForm::Compressed => {
            let mut image = packed::read(path)?;
            let planes = CompactPlanes::from_maps(&image.maps, precision)?;
            image.maps.data = Vec::new();
            Ok((image, planes))
        }
    }
}
