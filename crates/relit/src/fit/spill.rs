//! The strip-major spill file of the perceptual fit.
//!
//! The reference images arrive one at a time, but per-pixel normal equations need all
//! samples of a pixel at once. Like the seed's rebinning (seed 000, figure 2), each image
//! is cut into strips of rows and each strip written where it belongs in an unlinked
//! temporary file: strip `s` holds that strip of image 0, then of image 1, and so on. A
//! strip of every image is then one contiguous read. Memory stays one image per decoder
//! thread while writing and one strip of all images while solving.

use crate::{Error, ErrorKind, Result};
use std::fs::File;

pub struct Spill {
    file: File,
    width: usize,
    height: usize,
    images: usize,
    rows_per_strip: usize,
}

impl Spill {
    /// A spill file for `images` images of `width×height`, with strips of at most
    /// `strip_bytes` bytes (at least one row).
    pub fn create(width: usize, height: usize, images: usize, strip_bytes: usize) -> Result<Spill> {
        let row_bytes = width * 3 * 4 * images;
        let rows_per_strip = (strip_bytes / row_bytes.max(1)).clamp(1, height.max(1));
        let file = tempfile::tempfile().map_err(|e| {
            Error::new(
                ErrorKind::Io,
                "cannot create the fit's temporary spill file",
            )
            .with_source(e)
        })?;
        Ok(Spill {
            file,
            width,
            height,
            images,
            rows_per_strip,
        })
    }

    pub fn strips(&self) -> usize {
        self.height.div_ceil(self.rows_per_strip)
    }

    pub fn bytes(&self) -> u64 {
        (self.width * self.height * 3 * 4 * self.images) as u64
    }

    fn strip_rows(&self, s: usize) -> (usize, usize) {
        let r0 = s * self.rows_per_strip;
        (r0, (r0 + self.rows_per_strip).min(self.height))
    }

    /// Byte offset of strip `s` of image `j`.
    fn offset(&self, s: usize, j: usize) -> u64 {
        let (r0, r1) = self.strip_rows(s);
        let before = r0 * self.width * 3 * 4 * self.images;
        let strip_len = (r1 - r0) * self.width * 3 * 4;
        (before + j * strip_len) as u64
    }

    /// Store image `j` (interleaved linear RGB of the full frame).
    pub fn write_image(&self, j: usize, data: &[f32]) -> Result<()> {
        let mut rows = self.image_rows(j);
        for row in data.chunks_exact(3 * self.width.max(1)) {
            rows.push(row)?;
        }
        rows.finish()
    }

    /// A writer of image `j`'s rows, from the first down: each strip goes to the file
    /// once its rows are in, so an image read row by row is held one strip at a time.
    pub fn image_rows(&self, j: usize) -> ImageRows<'_> {
        ImageRows {
            spill: self,
            image: j,
            bytes: Vec::new(),
            rows: 0,
        }
    }

    /// Read strip `s` of every image into `buffer` as `[image][pixel][channel]`; returns
    /// the strip's first pixel index and pixel count.
    pub fn read_strip(&self, s: usize, buffer: &mut Vec<f32>) -> Result<(usize, usize)> {
        let (r0, r1) = self.strip_rows(s);
        let count = (r1 - r0) * self.width;
        // One image's part at a time, so that the bytes read add one image's strip to
        // the floats, not a second strip.
        let mut bytes = vec![0u8; count * 3 * 4];
        buffer.clear();
        buffer.reserve_exact(count * 3 * self.images);
        for j in 0..self.images {
            read_at(&self.file, &mut bytes, self.offset(s, j))?;
            buffer.extend(
                bytes
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            );
        }
        Ok((r0 * self.width, count))
    }
}

/// See [`Spill::image_rows`].
pub struct ImageRows<'a> {
    spill: &'a Spill,
    image: usize,
    bytes: Vec<u8>,
    rows: usize,
}

impl ImageRows<'_> {
    /// The next row (`3·width` values).
    pub fn push(&mut self, row: &[f32]) -> Result<()> {
        let spill = self.spill;
        if row.len() != 3 * spill.width || self.rows == spill.height {
            return Err(Error::invalid(
                "a row that does not belong to the spill file",
            ));
        }
        self.bytes.extend(row.iter().flat_map(|v| v.to_le_bytes()));
        self.rows += 1;
        let strip = (self.rows - 1) / spill.rows_per_strip;
        if self.rows == spill.strip_rows(strip).1 {
            write_at(&spill.file, &self.bytes, spill.offset(strip, self.image))?;
            self.bytes.clear();
        }
        Ok(())
    }

    /// Every row is in.
    pub fn finish(self) -> Result<()> {
        if self.rows != self.spill.height {
            return Err(Error::invalid(format!(
                "{} of the spill file's {} rows were written",
                self.rows, self.spill.height
            )));
        }
        Ok(())
    }
}

fn spill_error(e: std::io::Error) -> Error {
    Error::new(
        ErrorKind::Io,
        format!(
            "the fit's temporary spill file in {} failed (is that folder full? TMPDIR names another)",
            std::env::temp_dir().display()
        ),
    )
    .with_source(e)
}

#[cfg(unix)]
fn write_at(file: &File, bytes: &[u8], offset: u64) -> Result<()> {
    use std::os::unix::fs::FileExt;
    file.write_all_at(bytes, offset).map_err(spill_error)
}

#[cfg(unix)]
fn read_at(file: &File, bytes: &mut [u8], offset: u64) -> Result<()> {
    use std::os::unix::fs::FileExt;
    file.read_exact_at(bytes, offset).map_err(spill_error)
}

#[cfg(windows)]
fn write_at(file: &File, mut bytes: &[u8], mut offset: u64) -> Result<()> {
    use std::os::windows::fs::FileExt;
    while !bytes.is_empty() {
        let n = file.seek_write(bytes, offset).map_err(spill_error)?;
        bytes = &bytes[n..];
        offset += n as u64;
    }
    Ok(())
}

#[cfg(windows)]
fn read_at(file: &File, mut bytes: &mut [u8], mut offset: u64) -> Result<()> {
    use std::os::windows::fs::FileExt;
    while !bytes.is_empty() {
        let n = file.seek_read(bytes, offset).map_err(spill_error)?;
        if n == 0 {
            return Err(spill_error(std::io::ErrorKind::UnexpectedEof.into()));
        }
        bytes = &mut bytes[n..];
        offset += n as u64;
    }
    Ok(())
}
