//! The compressed relightable file (`.rlz`): the output of [`crate::compress::pack`] in
//! one file, every part checksummed, readable tile by tile. The layout is in
//! `docs/format.md`:
//!
//! ```text
//! magic      8 bytes  89 52 4C 5A 0D 0A 1A 0A   ("\x89RLZ\r\n\x1a\n")
//! version    u32      1
//! H          u32      header bytes
//! crc        u32      CRC-32 of the header bytes
//! header     H bytes  zstd of the JSON header (compress::Header)
//! S          u32      sections (must equal what the header implies)
//! index      S × 20   per section: u64 offset, u64 length, u32 CRC-32
//! crc        u32      CRC-32 of the index
//! sections   …        tiles of each plane in raster order, plane after plane, then depth's
//! ```
//!
//! All integers little-endian. A reader checks every length against the file's real
//! size before it allocates anything from it, and every checksum before it decodes.

use crate::compress::{self, Packed};
use crate::fsutil::write_atomically;
use crate::maps::RelightableImage;
use crate::{Error, ErrorKind, Result};
use std::io::{Read, Write};
use std::path::Path;

pub use crate::compress::container::{from_bytes, to_bytes, MAGIC, VERSION};

/// Whether the file at `path` starts with [`MAGIC`].
pub fn is_packed(path: &Path) -> Result<bool> {
    let mut f = std::fs::File::open(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            Error::new(ErrorKind::Io, format!("{} does not exist", path.display()))
        } else {
            Error::new(
                ErrorKind::Io,
                format!("cannot open {}: {e}", path.display()),
            )
        }
    })?;
    let mut head = [0u8; 8];
    let mut got = 0;
    while got < 8 {
        match f.read(&mut head[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) => {
                return Err(Error::new(
                    ErrorKind::Io,
                    format!("cannot read {}: {e}", path.display()),
                ))
            }
        }
    }
    Ok(got == 8 && head == MAGIC)
}

/// Read the sections of a compressed file that `wanted` names (the others left empty)
/// straight from the file, with the bytes read and the file's size.
fn read_sections(
    path: &Path,
    wanted: &dyn Fn(&compress::Header, usize) -> bool,
) -> Result<(Packed, u64, u64)> {
    let cannot = |e: std::io::Error| {
        Error::new(
            ErrorKind::Io,
            format!("cannot read {}: {e}", path.display()),
        )
    };
    let file = std::fs::File::open(path).map_err(cannot)?;
    let len = file.metadata().map_err(cannot)?.len();
    let name = path.display().to_string();
    let (packed, read) =
        compress::container::read_from(&mut std::io::BufReader::new(file), len, &name, wanted)?;
    Ok((packed, read, len))
}

/// Read a compressed file into its packed form.
pub fn read_packed(path: &Path) -> Result<Packed> {
    read_sections(path, &|_, _| true).map(|(packed, _, _)| packed)
}

/// The header of a compressed file, reading no section (lengths and the header's and
/// index's checksums are still checked).
pub fn read_header(path: &Path) -> Result<compress::Header> {
    read_sections(path, &|_, _| false).map(|(packed, _, _)| packed.header)
}

/// Read a compressed file as ordinary maps (in its projected basis): level 0, its
/// finer levels' sections left unread.
pub fn read(path: &Path) -> Result<RelightableImage> {
    let (packed, _, _) = read_sections(path, &|h, s| h.section_level(s).0 == 0)?;
    compress::unpack(&packed).map_err(|e| Error::new(e.kind(), format!("{}: {e}", path.display())))
}

/// The region `(x, y, w, h)` of a compressed file's maps, reading only the sections
/// of the tiles it touches ([`compress::unpack_region`]: no camera or depth, for lights
/// that are the same at every pixel). Also returns the bytes read and the file's size.
pub fn read_region(
    path: &Path,
    region: (usize, usize, usize, usize),
) -> Result<(RelightableImage, u64, u64)> {
    read_region_with(path, region, false)
}

/// [`read_region`], and with `depth` the region's depth too where the file has one
/// (its depth sections the region touches, in the same pass): what a tiled viewer
/// needs, as `exr::read_region_with` gives it.
pub fn read_region_with(
    path: &Path,
    region: (usize, usize, usize, usize),
    depth: bool,
) -> Result<(RelightableImage, u64, u64)> {
    read_level_region(path, 0, region, depth)
}

/// [`read_region_with`] of mip level `level` (`region` in its pixels), reading only
/// that level's sections the region touches ([`compress::Header::levels`]).
pub fn read_level_region(
    path: &Path,
    level: usize,
    region: (usize, usize, usize, usize),
    depth: bool,
) -> Result<(RelightableImage, u64, u64)> {
    // The level's header, made once for all the sections asked about.
    let at = std::cell::OnceCell::new();
    let (packed, read, len) = read_sections(path, &|h, s| {
        let (l, own) = h.section_level(s);
        let at = at.get_or_init(|| h.at_level(level));
        l == level
            && (compress::section_needed(at, own, region)
                || (depth && compress::depth_section_in(at, own, region)))
    })?;
    let in_file = |e: Error| Error::new(e.kind(), format!("{}: {e}", path.display()));
    let packed = packed.level(level).map_err(in_file)?;
    let mut image = compress::unpack_region(&packed, region).map_err(in_file)?;
    if depth {
        image.depth = compress::unpack_depth_region(&packed, region).map_err(in_file)?;
    }
    Ok((image, read, len))
}

/// Write `packed` to `path` (atomically: a temporary file renamed into place).
pub fn write_packed(path: &Path, packed: &Packed) -> Result<()> {
    let bytes = to_bytes(packed)?;
    write_atomically(path, |out| {
        out.write_all(&bytes).map_err(|e| {
            Error::new(
                ErrorKind::Io,
                format!("cannot write {}: {e}", path.display()),
            )
        })
    })
}

/// Compress `image` with `settings` and write it; returns the packed form.
pub fn write(
    path: &Path,
    image: &RelightableImage,
    settings: &compress::Settings,
) -> Result<Packed> {
    let packed = compress::pack(image, settings)?;
    write_packed(path, &packed)?;
    Ok(packed)
}
