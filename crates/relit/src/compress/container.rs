//! The bytes of a compressed file (layout in `codec::packed` and `docs/format.md`):
//! the header and sections of a [`Packed`] image, every part checksummed.

use super::{Header, Packed};
use crate::{Error, ErrorKind, Result};
use std::io::{Read, Seek, SeekFrom};

/// The first eight bytes of every compressed file.
pub const MAGIC: [u8; 8] = *b"\x89RLZ\r\n\x1a\n";

/// The newest layout version this build writes and reads. Version 2 added the codebook
/// (vector quantisation) and WebP tiles, version 3 the perceptual gain, version 4
/// principal components per block, version 5 a codebook of the residual beside the
/// planes, version 6 mip levels; a file is written with the oldest version that holds
/// it, so that older readers keep reading what they can.
pub const VERSION: u32 = 6;

/// The version a header needs.
fn version_of(header: &Header) -> u32 {
    let webp = matches!(header.codec, super::TileCodec::Webp { .. });
    if header.levels > 1 {
        6
    } else if !header.residual.is_empty() {
        5
    } else if header.pca_block.is_some() {
        4
    } else if header.gain {
        3
    } else if header.codebook.is_some() || webp {
        2
    } else {
        1
    }
}

/// The most bytes a header may decompress to.
const MAX_HEADER_JSON: u64 = 64 << 20;

/// Bytes of one index entry.
const ENTRY: usize = 20;

/// The file's bytes.
pub fn to_bytes(packed: &Packed) -> Result<Vec<u8>> {
    let sections: Vec<(u64, u32)> = packed
        .sections
        .iter()
        .map(|s| (s.len() as u64, crc32fast::hash(s)))
        .collect();
    let mut out = head(&packed.header, &sections)?;
    for section in &packed.sections {
        out.extend_from_slice(section);
    }
    Ok(out)
}

/// The bytes of a file before its sections, given each section's length and CRC-32 in
/// order: what a writer that holds the sections elsewhere writes first.
pub fn head(header: &Header, sections: &[(u64, u32)]) -> Result<Vec<u8>> {
    let json = serde_json::to_vec(header)
        .map_err(|e| Error::invalid(format!("header does not serialise: {e}")))?;
    let compressed = zstd::bulk::compress(&json, 19)
        .map_err(|e| Error::new(ErrorKind::Io, format!("zstd: {e}")))?;
    let s = sections.len();
    let index_start = 8 + 12 + compressed.len() + 4;
    let mut offset = (index_start + s * ENTRY + 4) as u64;
    let mut index = Vec::with_capacity(s * ENTRY);
    for &(len, crc) in sections {
        index.extend_from_slice(&offset.to_le_bytes());
        index.extend_from_slice(&len.to_le_bytes());
        index.extend_from_slice(&crc.to_le_bytes());
        offset += len;
    }
    let mut out = Vec::with_capacity(index_start + index.len() + 4);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&version_of(header).to_le_bytes());
    out.extend_from_slice(&(compressed.len() as u32).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&compressed).to_le_bytes());
    out.extend_from_slice(&compressed);
    out.extend_from_slice(&(s as u32).to_le_bytes());
    out.extend_from_slice(&index);
    out.extend_from_slice(&crc32fast::hash(&index).to_le_bytes());
    Ok(out)
}

/// Parse a file's bytes, checking every length and checksum.
pub fn from_bytes(bytes: &[u8], name: &str) -> Result<Packed> {
    let mut cursor = std::io::Cursor::new(bytes);
    read_from(&mut cursor, bytes.len() as u64, name, &|_, _| true).map(|(packed, _)| packed)
}

/// Parse a file of `file_len` bytes from `src`, reading only the sections `wanted`
/// names (given the header and the section's number; the others are left empty) and
/// checking every length and checksum of what it reads. Returns the file and the
/// bytes read. No length from the file is allocated before it is checked against
/// `file_len`.
pub fn read_from<R: Read + Seek>(
    src: &mut R,
    file_len: u64,
    name: &str,
    wanted: &dyn Fn(&Header, usize) -> bool,
) -> Result<(Packed, u64)> {
    let bad = |why: String| Error::parse(format!("{name}: {why}"));
    let mut file = Bounded {
        src,
        at: 0,
        read: 0,
        len: file_len,
    };
    let take = |file: &mut Bounded<R>, len: u64, what: &str| -> Result<Vec<u8>> {
        file.take(len)
            .map_err(|e| bad(format!("{e} in the {what} (file of {file_len} bytes)")))
    };
    let u32_at = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    if take(&mut file, 8, "magic")? != MAGIC {
        return Err(bad("not a compressed relit file (wrong magic)".into()));
    }
    let version = u32_at(&take(&mut file, 4, "version")?);
    if !(1..=VERSION).contains(&version) {
        return Err(bad(format!(
            "layout version {version}; this build reads versions 1 to {VERSION}"
        )));
    }
    let header_len = u32_at(&take(&mut file, 4, "header length")?) as u64;
    let header_crc = u32_at(&take(&mut file, 4, "header checksum")?);
    let header_bytes = take(&mut file, header_len, "header")?;
    if crc32fast::hash(&header_bytes) != header_crc {
        return Err(bad("the header's checksum does not match".into()));
    }
    let mut json = Vec::new();
    zstd::stream::read::Decoder::new(&header_bytes[..])
        .and_then(|d| d.take(MAX_HEADER_JSON).read_to_end(&mut json))
        .map_err(|e| bad(format!("the header does not decompress: {e}")))?;
    let header: Header = serde_json::from_slice(&json).map_err(|e| bad(format!("header: {e}")))?;
    if version < version_of(&header) {
        return Err(bad(format!(
            "a version {version} file cannot hold a codebook, WebP tiles (version 2 added them), a gain plane (version 3), principal components per block (version 4), a codebook of the residual (version 5) or mip levels (version 6)"
        )));
    }
    let sections = u32_at(&take(&mut file, 4, "section count")?) as usize;
    if sections != header.sections() {
        return Err(bad(format!(
            "{sections} sections, but the header implies {}",
            header.sections()
        )));
    }
    let index_len = (sections as u64)
        .checked_mul(ENTRY as u64)
        .ok_or_else(|| bad("section count overflows".into()))?;
    let index = take(&mut file, index_len, "section index")?;
    let index_crc = u32_at(&take(&mut file, 4, "index checksum")?);
    if crc32fast::hash(&index) != index_crc {
        return Err(bad("the section index's checksum does not match".into()));
    }
    let mut out = Vec::with_capacity(sections);
    let mut expected = file.at;
    for (s, entry) in index.chunks_exact(ENTRY).enumerate() {
        let offset = u64::from_le_bytes(entry[0..8].try_into().expect("8 bytes"));
        let len = u64::from_le_bytes(entry[8..16].try_into().expect("8 bytes"));
        let crc = u32_at(&entry[16..20]);
        if offset != expected {
            return Err(bad(format!("section {s} is out of order")));
        }
        if offset.checked_add(len).is_none_or(|e| e > file_len) {
            return Err(bad(format!(
                "truncated: section {s} ends past the file's {file_len} bytes"
            )));
        }
        if wanted(&header, s) {
            if file.at != offset {
                file.src
                    .seek(SeekFrom::Start(offset))
                    .map_err(|e| bad(format!("cannot seek to section {s}: {e}")))?;
                file.at = offset;
            }
            let section = take(&mut file, len, "sections")?;
            if crc32fast::hash(&section) != crc {
                return Err(bad(format!("section {s}'s checksum does not match")));
            }
            out.push(section);
        } else {
            out.push(Vec::new());
        }
        expected = offset + len;
    }
    if expected != file_len {
        return Err(bad(format!(
            "{} bytes after the last section",
            file_len - expected
        )));
    }
    Ok((
        Packed {
            header,
            sections: out,
        },
        file.read,
    ))
}

/// A source of known length, read forward; counts what it reads.
struct Bounded<'a, R> {
    src: &'a mut R,
    at: u64,
    read: u64,
    len: u64,
}

impl<R: Read> Bounded<'_, R> {
    /// The next `len` bytes, allocated only once they are known to be in the file.
    fn take(&mut self, len: u64) -> std::result::Result<Vec<u8>, String> {
        let end = self
            .at
            .checked_add(len)
            .filter(|&e| e <= self.len)
            .ok_or("truncated")?;
        let mut out = vec![0u8; len as usize];
        self.src
            .read_exact(&mut out)
            .map_err(|e| format!("cannot read ({e})"))?;
        self.at = end;
        self.read += len;
        Ok(out)
    }
}
