//! Files that hold relightable images.
//!
//! * OpenEXR ([`exr`]) is the native, lossless form: maps stored in a
//!   [`crate::storage::Precision`] (f32 or f16), readable by any EXR tool.
//! * The compressed form ([`packed`], `.rlz`): principal components, quantised planes,
//!   zstd or JPEG tiles ([`crate::compress`]).
//!
//! * The RTI tools' interchange files: HP's `.ptm` ([`ptm`]) and HSH `.rti` ([`rti`]),
//!   display-referred and 8-bit, each with its one basis.
//! * The relight/OpenLIME web format ([`web`]): a folder with `info.json` and 8-bit
//!   plane images, what museums publish RTIs in.
//!
//! [`read`] opens any of them (a folder holding `info.json` is the web format, a file is
//! told by its first bytes, not its name), so every command that reads a relightable
//! file reads all of them.

pub mod exr;
mod legacy;
pub mod packed;
pub mod ptm;
mod reexpress;
pub mod rti;

pub use reexpress::reexpress;
pub mod web;

use crate::maps::RelightableImage;
use crate::storage::{CompactPlanes, Precision};
use crate::Result;
use std::path::Path;

/// The forms of relightable file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileForm {
    Exr,
    Compressed,
    /// HP's polynomial texture map (`.ptm`).
    Ptm,
    /// An HSH `.rti` file.
    Rti,
    /// The relight/OpenLIME web format (a folder).
    Web,
}

impl FileForm {
    /// The form of the file at `path`, from its first bytes.
    pub fn of(path: &Path) -> Result<FileForm> {
        use std::io::Read;
        if web::is_web(path) {
            return Ok(FileForm::Web);
        }
        // A missing or unreadable file gets its clear message here.
        if packed::is_packed(path)? {
            return Ok(FileForm::Compressed);
        }
        let mut prefix = [0u8; 8];
        let read = std::fs::File::open(path)
            .and_then(|mut f| f.read(&mut prefix))
            .map_err(|e| crate::Error::io(path, "read", e))?;
        let prefix = &prefix[..read];
        Ok(if ptm::is_ptm(prefix) {
            FileForm::Ptm
        } else if rti::is_rti(prefix) {
            FileForm::Rti
        } else {
            FileForm::Exr
        })
    }

    /// The form an output path asks for: a folder (an existing one, or a path ending in
    /// `/`) is the web format, `.rlz` compressed, `.ptm` and `.rti` (or `.hsh`) the RTI
    /// tools' files,
    /// anything else EXR.
    pub fn for_output(path: &Path) -> FileForm {
        if path.is_dir() || path.as_os_str().to_string_lossy().ends_with(['/', '\\']) {
            return FileForm::Web;
        }
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("rlz") => FileForm::Compressed,
            Some(e) if e.eq_ignore_ascii_case("ptm") => FileForm::Ptm,
            Some(e) if e.eq_ignore_ascii_case("rti") || e.eq_ignore_ascii_case("hsh") => {
                FileForm::Rti
            }
            _ => FileForm::Exr,
        }
    }
}

/// How [`write`] stores a relightable image, per form (each form reads its part).
#[derive(Clone, Debug)]
pub struct WriteOptions {
    /// OpenEXR: the maps' precision (f32 or f16).
    pub storage: Precision,
    /// `.rlz`: the compression settings.
    pub compress: crate::compress::Settings,
    /// `.ptm`: RGB or LRGB.
    pub ptm_format: ptm::PtmFormat,
    /// Web folders.
    pub web: web::WriteOptions,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            storage: Precision::F16,
            compress: Default::default(),
            ptm_format: ptm::PtmFormat::Lrgb,
            web: Default::default(),
        }
    }
}

/// Write `image` to `path` in the form its name asks for ([`FileForm::for_output`]).
pub fn write(path: &Path, image: &RelightableImage, options: &WriteOptions) -> Result<()> {
    match FileForm::for_output(path) {
        FileForm::Exr => exr::write(path, image, options.storage),
        FileForm::Compressed => packed::write(path, image, &options.compress).map(|_| ()),
        form @ (FileForm::Ptm | FileForm::Rti) => {
            write_interchange(path, image, form, options.ptm_format).map(|_| ())
        }
        FileForm::Web => web::write(path, image, &options.web).map(|_| ()),
    }
}

/// Write `image` as one of the RTI tools' files (`form` [`FileForm::Ptm`] or
/// [`FileForm::Rti`]; a `.ptm` in `ptm_format`), re-expressed in that file's basis.
/// Returns a short description of what was written.
pub fn write_interchange(
    path: &Path,
    image: &RelightableImage,
    form: FileForm,
    ptm_format: ptm::PtmFormat,
) -> Result<String> {
    match form {
        FileForm::Ptm => {
            ptm::write(path, image, ptm_format)?;
            Ok(format!("PTM 1.2, {}", ptm_format.describe()))
        }
        FileForm::Rti => {
            rti::write(path, image)?;
            Ok("HSH .rti".into())
        }
        FileForm::Exr | FileForm::Compressed | FileForm::Web => Err(crate::Error::invalid(
            "write_interchange writes .ptm and .rti files only",
        )),
    }
}

/// Read a relightable file of any form.
pub fn read(path: &Path) -> Result<RelightableImage> {
    match FileForm::of(path)? {
        FileForm::Exr => exr::read(path),
        FileForm::Compressed => packed::read(path),
        FileForm::Ptm => ptm::read(path),
        FileForm::Rti => rti::read(path),
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
        FileForm::Compressed => packed::read_compact(path, precision),
        FileForm::Ptm | FileForm::Rti | FileForm::Web => {
            let mut image = read(path)?;
            let planes = CompactPlanes::from_maps(&image.maps, precision)?;
            image.maps.data = Vec::new();
            Ok((image, planes))
        }
    }
}
