//! What the two RTI interchange files (`.ptm`, `.rti`) share: a short text header of
//! whitespace-separated fields followed by binary data, and one 8-bit quantiser per
//! coefficient over the whole image.

use crate::{Error, Result};
use std::path::Path;

/// The longest text header accepted: real headers are under 200 bytes, and a file
/// without line breaks must not be scanned whole.
const MAX_HEADER: usize = 4096;

/// The first `fields` whitespace-separated fields of `bytes`' text header, skipping
/// lines that start with `#` when `comments`, and the offset where the binary data
/// starts: just after the line break that ends the line holding the last field.
/// Trailing spaces and `\r\n` line ends are accepted.
pub(crate) fn text_header(
    path: &Path,
    bytes: &[u8],
    fields: usize,
    comments: bool,
) -> Result<(Vec<String>, usize)> {
    let mut found = Vec::with_capacity(fields);
    let mut start = 0;
    while found.len() < fields {
        if start >= bytes.len().min(MAX_HEADER) {
            return Err(Error::parse(format!(
                "{}: the header ends after {} of its {fields} fields",
                path.display(),
                found.len()
            )));
        }
        let end = bytes[start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| start + i);
        if end - start > MAX_HEADER {
            return Err(Error::parse(format!(
                "{}: header line {} is not text",
                path.display(),
                found.len() + 1
            )));
        }
        let line = std::str::from_utf8(&bytes[start..end]).map_err(|_| {
            Error::parse(format!(
                "{}: the header is not text (after field {})",
                path.display(),
                found.len()
            ))
        })?;
        if !(comments && line.starts_with('#')) {
            for field in line.split_ascii_whitespace() {
                found.push(field.to_string());
            }
        }
        start = end + 1;
    }
    if found.len() > fields {
        return Err(Error::parse(format!(
            "{}: the header line of field {fields} has {} extra fields",
            path.display(),
            found.len() - fields
        )));
    }
    Ok((found, start.min(bytes.len())))
}

/// Parse header field `name` (`value`) as a number.
pub(crate) fn field<T: std::str::FromStr>(path: &Path, name: &str, value: &str) -> Result<T> {
    value.parse().map_err(|_| {
        Error::parse(format!(
            "{}: header field `{name}` is `{value}`, not a number of the expected kind",
            path.display()
        ))
    })
}

/// Check an image size from a header against the data the file really holds:
/// `bytes_per_pixel × width × height` bytes after `offset`.
pub(crate) fn check_payload(
    path: &Path,
    len: usize,
    offset: usize,
    width: usize,
    height: usize,
    bytes_per_pixel: usize,
) -> Result<usize> {
    if width == 0 || height == 0 || width > 1 << 16 || height > 1 << 16 {
        return Err(Error::parse(format!(
            "{}: an image of {width}×{height} pixels (each side must be 1 to 65536)",
            path.display()
        )));
    }
    let needed = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(bytes_per_pixel))
        .ok_or_else(|| Error::parse(format!("{}: the image size overflows", path.display())))?;
    let available = len.saturating_sub(offset);
    if available < needed {
        return Err(Error::parse(format!(
            "{}: truncated: {width}×{height} pixels need {needed} bytes of data, the file has {available}",
            path.display()
        )));
    }
    Ok(needed)
}

/// The range of one coefficient over the whole image, for an 8-bit code per value.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Range {
    pub min: f32,
    pub max: f32,
}

impl Range {
    /// The range of the finite values among `values`.
    pub fn of(values: impl Iterator<Item = f32>) -> Range {
        let (min, max) = values
            .filter(|v| v.is_finite())
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        if min > max {
            Range { min: 0.0, max: 0.0 }
        } else {
            Range { min, max }
        }
    }

    /// The step of one code (never zero, so a constant coefficient still decodes).
    pub fn step(&self) -> f32 {
        let span = self.max - self.min;
        if span > 0.0 {
            span / 255.0
        } else {
            self.min.abs().max(1e-6) / 255.0
        }
    }
}
