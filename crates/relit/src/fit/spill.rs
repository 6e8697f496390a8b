//! The piece-major spill file of the streamed fit.
//!
//! The reference images arrive one at a time, but per-pixel normal equations need all
//! samples of a pixel at once. Like the seed's rebinning (seed 000, figure 2), each image
//! is cut into pieces and each piece written where it belongs in an unlinked temporary
//! file: piece `s` holds that piece of image 0, then of image 1, and so on. A piece of
//! every image is then one contiguous read.
//!
//! A piece is a rectangle: the band is cut into tiles (`tile_w × tile_h`, the last
//! column and row of tiles smaller), each tile into pieces of at most `piece_h` rows,
//! ordered tile row by tile row, tile by tile, piece by piece. With tiles as wide as the
//! image, a piece is a strip of whole rows. Tiles narrower than the image keep a piece's
//! size independent of the image's width, so that a fit of a wide panorama holds no
//! more than a narrow one: the output file's tiles ([`crate::fit::RowSink::tiles`]) set
//! the tile size. Memory stays a few rows of one image per decoder thread while
//! writing and one piece of all images while solving.
//!
//! Photographs are spilled as their 8-bit codes ([`Samples::Codes`]), a quarter of the
//! floats' bytes, and turned into values as a piece is read, by each image's table of
//! what its codes stand for: the table can then be chosen after the images were read
//! (the maps' space is chosen on the subsample read in the same pass).

use crate::{Error, ErrorKind, Result};
use rayon::prelude::*;
use std::fs::File;

/// A rectangle of the band's pixels: columns `x0..x0 + width`, rows `y0..y0 + height`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Piece {
    pub x0: usize,
    pub y0: usize,
    pub width: usize,
    pub height: usize,
}

impl Piece {
    /// A piece of `width × height` pixels at the origin (a whole band, or a piece's own
    /// maps).
    pub fn sized(width: usize, height: usize) -> Piece {
        Piece {
            x0: 0,
            y0: 0,
            width,
            height,
        }
    }

    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// The band's pixel index of the piece's pixel `p` (row-major within the piece), in
    /// a band `band_width` pixels wide.
    pub fn band_pixel(&self, p: usize, band_width: usize) -> usize {
        (self.y0 + p / self.width) * band_width + self.x0 + p % self.width
    }

    /// The piece's pixel index of the band's pixel `(x, y)`, when it is in the piece.
    pub fn local(&self, x: usize, y: usize) -> Option<usize> {
        (x >= self.x0 && x < self.x0 + self.width && y >= self.y0 && y < self.y0 + self.height)
            .then(|| (y - self.y0) * self.width + x - self.x0)
    }
}

pub struct Spill {
    file: File,
    width: usize,
    height: usize,
    images: usize,
    tile_w: usize,
    tile_h: usize,
    piece_h: usize,
    samples: Samples,
    /// The budget of a piece of all images, in floats.
    piece_bytes: usize,
    /// The tiles asked for (`None`: strips of whole rows).
    tiles: Option<(usize, usize)>,
}

/// What the spill file holds of each sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Samples {
    /// The values the fit solves for, RGB in f32.
    Floats,
    /// A photograph's 8-bit RGB codes, turned into values when read.
    Codes,
}

impl Samples {
    /// Bytes of one pixel's sample of one image.
    fn pixel_bytes(self) -> usize {
        match self {
            Samples::Floats => 3 * 4,
            Samples::Codes => 3,
        }
    }
}

impl Spill {
    /// A spill file for `images` images of `width×height`, in pieces of at most
    /// `piece_bytes` bytes of all images as the solve holds them, in floats (at least
    /// one row of a tile). `tiles`: the tile size pieces must stay inside (the output's
    /// tiles), or `None` for strips of whole rows. `samples`: what the file keeps.
    pub fn create(
        width: usize,
        height: usize,
        images: usize,
        piece_bytes: usize,
        tiles: Option<(usize, usize)>,
        samples: Samples,
    ) -> Result<Spill> {
        let (tile_w, tile_h) = match tiles {
            Some((tw, th)) if tw > 0 && th > 0 => (tw.min(width.max(1)), th),
            Some(_) => return Err(Error::invalid("a spill file of empty tiles")),
            None => (width.max(1), height.max(1)),
        };
        let row_bytes = tile_w * Samples::Floats.pixel_bytes() * images;
        let piece_h = (piece_bytes / row_bytes.max(1)).clamp(1, tile_h.min(height.max(1)));
        // Strips of whole rows are tiles of one piece each.
        let tile_h = if tiles.is_none() { piece_h } else { tile_h };
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
            tile_w,
            tile_h,
            piece_h,
            samples,
            piece_bytes,
            tiles,
        })
    }

    /// The pieces of an output whose tiles are `tiles` (`None`: scan lines, read in
    /// strips of whole rows), in the output's order — tile rows from the top, tiles from
    /// the left, each tile's pieces from its top — each at most the file's piece budget
    /// and at least one row of a tile: the file's own pieces where its tiles are those,
    /// pieces read across its tiles ([`Spill::read_region`]) otherwise. A fit that
    /// spills its images before it knows its output's tiles solves in them so.
    pub fn pieces_for(&self, tiles: Option<(usize, usize)>) -> Vec<Piece> {
        if tiles == self.tiles || self.width == 0 || self.height == 0 {
            return (0..self.pieces()).map(|s| self.piece(s).0).collect();
        }
        let (tile_w, tile_h) = match tiles {
            Some((tw, th)) if tw > 0 && th > 0 => (tw.min(self.width), th),
            _ => (self.width, self.height),
        };
        let row_bytes = tile_w * Samples::Floats.pixel_bytes() * self.images;
        let piece_h = (self.piece_bytes / row_bytes.max(1)).clamp(1, tile_h.min(self.height));
        let mut pieces = Vec::new();
        for ty in (0..self.height).step_by(tile_h) {
            let rows = tile_h.min(self.height - ty);
            for x0 in (0..self.width).step_by(tile_w) {
                let width = tile_w.min(self.width - x0);
                for y0 in (ty..ty + rows).step_by(piece_h) {
                    pieces.push(Piece {
                        x0,
                        y0,
                        width,
                        height: piece_h.min(ty + rows - y0),
                    });
                }
            }
        }
        pieces
    }

    /// Read the rectangle `region` of every image into `buffer` as `[image][pixel][channel]`,
    /// the region's pixels row by row, from whichever of the file's pieces hold it: one
    /// read per image where it is one of them, one per image, tile and piece it crosses
    /// otherwise. A file of codes needs `values`: per image, what each code of each
    /// channel stands for (`256·channel + code`).
    pub fn read_region(
        &self,
        region: Piece,
        buffer: &mut Vec<f32>,
        values: Option<&[Vec<f32>]>,
    ) -> Result<()> {
        let tables = self.tables(values)?;
        self.read_region_as(region, buffer, |j, src, dst| {
            decode_samples(src, dst, tables.map(|t| t[j].as_slice()))
        })
    }

    /// [`Spill::read_region`] of a file of codes, the codes as the file stores them
    /// (`[image][pixel][channel]`): a reader that looks up more than the value of a code
    /// (the per-pixel solve also its encoding and weight) does so once, and holds a
    /// quarter of the floats' bytes.
    pub fn read_region_codes(&self, region: Piece, buffer: &mut Vec<u8>) -> Result<()> {
        if self.samples != Samples::Codes {
            return Err(Error::invalid(
                "a spill file of floats has no codes to read",
            ));
        }
        self.read_region_as(region, buffer, |_, src, dst| dst.copy_from_slice(src))
    }

    /// The rectangle `region` of every image into `buffer`, three values a pixel, each
    /// run of an image's samples turned into values by `decode(image, bytes, values)`.
    fn read_region_as<T: Copy + Default + Send>(
        &self,
        region: Piece,
        buffer: &mut Vec<T>,
        decode: impl Fn(usize, &[u8], &mut [T]) + Sync,
    ) -> Result<()> {
        if region.pixels() == 0
            || region.x0 + region.width > self.width
            || region.y0 + region.height > self.height
        {
            return Err(Error::invalid("a region outside the spill file"));
        }
        let (s, r) = self.piece_at(region.x0 / self.tile_w, region.y0);
        if r == 0 && self.piece(s).0 == region {
            return self.read_piece_as(s, buffer, decode).map(|_| ());
        }
        let count = region.pixels();
        let sample = self.samples.pixel_bytes();
        buffer.clear();
        buffer.resize(count * 3 * self.images, T::default());
        let first_column = region.x0 / self.tile_w;
        let last_column = (region.x0 + region.width - 1) / self.tile_w;
        buffer
            .par_chunks_mut(count * 3)
            .enumerate()
            .try_for_each_init(Vec::new, |bytes, (j, image)| -> Result<()> {
                for tx in first_column..=last_column {
                    let tile_x0 = tx * self.tile_w;
                    let tile_w = self.tile_w.min(self.width - tile_x0);
                    let from = region.x0.max(tile_x0);
                    let to = (region.x0 + region.width).min(tile_x0 + tile_w);
                    let mut y = region.y0;
                    while y < region.y0 + region.height {
                        // The rows of this piece of the tile column: contiguous in the file.
                        let (s, r) = self.piece_at(tx, y);
                        let (piece, _) = self.piece(s);
                        let run = (piece.y0 + piece.height).min(region.y0 + region.height) - y;
                        bytes.resize(run * tile_w * sample, 0);
                        let at = self.offset(s, j) + (r * tile_w * sample) as u64;
                        read_at(&self.file, bytes, at)?;
                        for i in 0..run {
                            let row = (y + i - region.y0) * region.width;
                            let src = &bytes[((i * tile_w) + from - tile_x0) * sample..]
                                [..(to - from) * sample];
                            let dst = &mut image[3 * (row + from - region.x0)..][..3 * (to - from)];
                            decode(j, src, dst);
                        }
                        y += run;
                    }
                }
                Ok(())
            })?;
        Ok(())
    }

    /// The per-image tables of a file of codes, checked; `None` for a file of floats.
    fn tables<'v>(&self, values: Option<&'v [Vec<f32>]>) -> Result<Option<&'v [Vec<f32>]>> {
        match (self.samples, values) {
            (Samples::Codes, Some(v))
                if v.len() == self.images && v.iter().all(|t| t.len() == 768) =>
            {
                Ok(Some(v))
            }
            (Samples::Codes, _) => Err(Error::invalid(
                "a spill file of codes is read with each image's values of its codes",
            )),
            (Samples::Floats, _) => Ok(None),
        }
    }

    /// What the file keeps of each sample.
    pub fn samples(&self) -> Samples {
        self.samples
    }

    fn tile_columns(&self) -> usize {
        self.width.div_ceil(self.tile_w)
    }

    /// Rows of tile row `ty`.
    fn tile_row_height(&self, ty: usize) -> usize {
        self.tile_h.min(self.height - ty * self.tile_h)
    }

    /// Pieces of a tile `rows` high.
    fn pieces_per_tile(&self, rows: usize) -> usize {
        rows.div_ceil(self.piece_h)
    }

    pub fn pieces(&self) -> usize {
        if self.width == 0 || self.height == 0 {
            return 0;
        }
        let full_rows = self.height / self.tile_h;
        let rest = self.height % self.tile_h;
        self.tile_columns()
            * (full_rows * self.pieces_per_tile(self.tile_h) + self.pieces_per_tile(rest))
    }

    pub fn bytes(&self) -> u64 {
        (self.width * self.height * self.samples.pixel_bytes() * self.images) as u64
    }

    /// Piece `s` and the band pixels of the pieces before it.
    fn piece(&self, s: usize) -> (Piece, usize) {
        let columns = self.tile_columns();
        let per_full_row = columns * self.pieces_per_tile(self.tile_h);
        let ty = s / per_full_row;
        let rows = self.tile_row_height(ty);
        let in_row = s - ty * per_full_row;
        let per_tile = self.pieces_per_tile(rows);
        let (tx, py) = (in_row / per_tile, in_row % per_tile);
        let x0 = tx * self.tile_w;
        let width = self.tile_w.min(self.width - x0);
        let y0 = ty * self.tile_h + py * self.piece_h;
        let height = self.piece_h.min(ty * self.tile_h + rows - y0);
        let before = ty * self.tile_h * self.width + x0 * rows + py * self.piece_h * width;
        (
            Piece {
                x0,
                y0,
                width,
                height,
            },
            before,
        )
    }

    /// The piece holding row `y`'s pixels of tile column `tx`, and that row's place in it.
    fn piece_at(&self, tx: usize, y: usize) -> (usize, usize) {
        let columns = self.tile_columns();
        let ty = y / self.tile_h;
        let per_tile = self.pieces_per_tile(self.tile_row_height(ty));
        let within = y - ty * self.tile_h;
        let s = ty * columns * self.pieces_per_tile(self.tile_h)
            + tx * per_tile
            + within / self.piece_h;
        (s, within % self.piece_h)
    }

    /// Byte offset of piece `s` of image `j`.
    fn offset(&self, s: usize, j: usize) -> u64 {
        let (piece, before) = self.piece(s);
        ((before * self.images + j * piece.pixels()) * self.samples.pixel_bytes()) as u64
    }

    /// Store image `j` (interleaved RGB values of the full frame) in a file of floats.
    pub fn write_image(&self, j: usize, data: &[f32]) -> Result<()> {
        let mut rows = self.image_rows(j);
        for row in data.chunks_exact(3 * self.width.max(1)) {
            rows.push(row)?;
        }
        rows.finish()
    }

    /// A writer of image `j`'s rows, from the first down: a few rows are held (at most
    /// 1 MiB, within a piece) and each tile column's part of them written at once.
    pub fn image_rows(&self, j: usize) -> ImageRows<'_> {
        ImageRows {
            spill: self,
            image: j,
            held: Vec::new(),
            held_from: 0,
            rows: 0,
            most: (HELD_BYTES / (self.width * self.samples.pixel_bytes()).max(1))
                .clamp(1, self.piece_h),
        }
    }

    /// Piece `s` of every image into `buffer` as `[image][pixel][channel]`, the piece's
    /// pixels row by row, each image's samples turned into values by
    /// `decode(image, bytes, values)`; returns the piece.
    fn read_piece_as<T: Copy + Default + Send>(
        &self,
        s: usize,
        buffer: &mut Vec<T>,
        decode: impl Fn(usize, &[u8], &mut [T]) + Sync,
    ) -> Result<Piece> {
        let (piece, _) = self.piece(s);
        let count = piece.pixels();
        let sample = self.samples.pixel_bytes();
        buffer.clear();
        buffer.resize(count * 3 * self.images, T::default());
        // The images' parts in parallel, each reading its bytes into a buffer of one
        // image's part (a thread's, reused), so that the bytes add a part a thread to
        // the floats, not a second piece.
        buffer
            .par_chunks_mut(count * 3)
            .enumerate()
            .try_for_each_init(
                || vec![0u8; count * sample],
                |bytes, (j, image)| -> Result<()> {
                    read_at(&self.file, bytes, self.offset(s, j))?;
                    decode(j, bytes, image);
                    Ok(())
                },
            )?;
        Ok(piece)
    }
}

/// A run of pixels' samples of one image as the file stores them (`src`), as their
/// values, three a pixel (`dst`). A file of codes looks each channel up in its own
/// 256-entry part of `table`, taken as a fixed-size array once a run, so that the
/// lookups need no bounds checks (a call a pixel, each lookup checked, cost about 3 %
/// of a 1024×768 fit's CPU time).
fn decode_samples(src: &[u8], dst: &mut [f32], table: Option<&[f32]>) {
    match table {
        None => {
            for (d, b) in dst.iter_mut().zip(src.chunks_exact(4)) {
                *d = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
        Some(t) => {
            let channel = |c: usize| -> &[f32; 256] {
                t[256 * c..256 * (c + 1)]
                    .try_into()
                    .expect("a table has 256 values a channel")
            };
            let (r, g, b) = (channel(0), channel(1), channel(2));
            for (d, code) in dst.chunks_exact_mut(3).zip(src.chunks_exact(3)) {
                d[0] = r[code[0] as usize];
                d[1] = g[code[1] as usize];
                d[2] = b[code[2] as usize];
            }
        }
    }
}

/// Bytes of rows an [`ImageRows`] holds at most before writing them (at least a row):
/// each row's part of a tile is one write when a piece is a row of the tile, and those
/// small writes made the images stage twice as slow (4096×1024: 2.6 → 5.4 s).
const HELD_BYTES: usize = 1 << 20;

/// See [`Spill::image_rows`].
pub struct ImageRows<'a> {
    spill: &'a Spill,
    image: usize,
    /// Rows `held_from..rows`, not yet written, as the file stores them; all in the
    /// same pieces.
    held: Vec<u8>,
    held_from: usize,
    rows: usize,
    /// The most rows held.
    most: usize,
}

impl ImageRows<'_> {
    /// The next row (`3·width` values) of a file of floats.
    pub fn push(&mut self, row: &[f32]) -> Result<()> {
        self.check(row.len(), Samples::Floats)?;
        self.held.extend(row.iter().flat_map(|v| v.to_le_bytes()));
        self.pushed()
    }

    /// The next row (`3·width` codes) of a file of codes.
    pub fn push_codes(&mut self, row: &[u8]) -> Result<()> {
        self.check(row.len(), Samples::Codes)?;
        self.held.extend_from_slice(row);
        self.pushed()
    }

    fn check(&self, samples: usize, kind: Samples) -> Result<()> {
        let spill = self.spill;
        if samples != 3 * spill.width || self.rows == spill.height || kind != spill.samples {
            return Err(Error::invalid(
                "a row that does not belong to the spill file",
            ));
        }
        Ok(())
    }

    /// A row is held: write the held rows where they end a piece or fill the buffer.
    fn pushed(&mut self) -> Result<()> {
        let spill = self.spill;
        let y = self.rows;
        self.rows += 1;
        // Held rows stay in one piece of each tile column: the rows of a piece of one
        // image are consecutive in the file, and the next image's part follows.
        let (s, r) = spill.piece_at(0, y);
        if self.rows - self.held_from == self.most || r + 1 == spill.piece(s).0.height {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<()> {
        let spill = self.spill;
        let rows = self.rows - self.held_from;
        if rows == 0 {
            return Ok(());
        }
        let sample = spill.samples.pixel_bytes();
        let row_bytes = spill.width * sample;
        let mut part = Vec::new();
        for tx in 0..spill.tile_columns() {
            let (s, r) = spill.piece_at(tx, self.held_from);
            let x0 = tx * spill.tile_w;
            let width = spill.tile_w.min(spill.width - x0);
            let at = spill.offset(s, self.image) + (r * width * sample) as u64;
            if width == spill.width {
                write_at(&spill.file, &self.held, at)?;
            } else {
                part.clear();
                for held_row in self.held.chunks_exact(row_bytes) {
                    part.extend_from_slice(&held_row[x0 * sample..(x0 + width) * sample]);
                }
                write_at(&spill.file, &part, at)?;
            }
        }
        self.held.clear();
        self.held_from = self.rows;
        Ok(())
    }

    /// Every row is in.
    pub fn finish(mut self) -> Result<()> {
        if self.rows != self.spill.height {
            return Err(Error::invalid(format!(
                "{} of the spill file's {} rows were written",
                self.rows, self.spill.height
            )));
        }
        self.flush()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_piece_reads_back_its_pixels_of_every_image() {
        let (w, h, n) = (37, 23, 3);
        // Codes, and what each image's codes stand for: a different table an image and
        // a channel, so that a code read with another image's table shows.
        let codes: Vec<Vec<u8>> = (0..n)
            .map(|j| {
                (0..w * h * 3)
                    .map(|v| ((v * 7 + j * 13) % 256) as u8)
                    .collect()
            })
            .collect();
        let tables: Vec<Vec<f32>> = (0..n)
            .map(|j| (0..768).map(|i| (i * 3 + j * 1000) as f32).collect())
            .collect();
        let value = |j: usize, v: usize| tables[j][256 * (v % 3) + codes[j][v] as usize];
        let images: Vec<Vec<f32>> = (0..n)
            .map(|j| (0..w * h * 3).map(|v| value(j, v)).collect())
            .collect();
        // Strips of whole rows (one, several, all), and tiles with narrower last
        // columns, shorter last rows and pieces of one, some or all of a tile's rows;
        // floats and codes.
        for samples in [Samples::Floats, Samples::Codes] {
            for (tiles, rows) in [
                (None, 1),
                (None, 5),
                (None, h),
                (Some((16, 8)), 1),
                (Some((16, 8)), 3),
                (Some((16, 8)), 8),
                (Some((64, 16)), 16),
            ] {
                let spill = Spill::create(
                    w,
                    h,
                    n,
                    rows * w.min(tiles.map_or(w, |t| t.0)) * 12 * n,
                    tiles,
                    samples,
                )
                .unwrap();
                for j in 0..n {
                    match samples {
                        Samples::Floats => spill.write_image(j, &images[j]).unwrap(),
                        Samples::Codes => {
                            let mut writer = spill.image_rows(j);
                            // A row of the other kind is refused.
                            assert!(writer.push(&images[j][..3 * w]).is_err());
                            for row in codes[j].chunks_exact(3 * w) {
                                writer.push_codes(row).unwrap();
                            }
                            writer.finish().unwrap();
                        }
                    }
                }
                let tables = (samples == Samples::Codes).then_some(tables.as_slice());
                let mut seen = vec![0; w * h];
                let mut buffer = Vec::new();
                let mut read_codes = Vec::new();
                for (s, &piece) in spill.pieces_for(tiles).iter().enumerate() {
                    spill.read_region(piece, &mut buffer, tables).unwrap();
                    if samples == Samples::Codes {
                        spill.read_region_codes(piece, &mut read_codes).unwrap();
                        for (j, image) in codes.iter().enumerate() {
                            for p in 0..piece.pixels() {
                                let q = piece.band_pixel(p, w);
                                let got = &read_codes[(j * piece.pixels() + p) * 3..][..3];
                                assert_eq!(got, &image[3 * q..3 * q + 3]);
                            }
                        }
                    } else {
                        assert!(spill.read_region_codes(piece, &mut read_codes).is_err());
                    }
                    let (tw, th) = tiles.unwrap_or((w, rows));
                    assert!(piece.height <= rows, "{tiles:?} {rows}");
                    assert_eq!(
                        piece.x0 / tw,
                        (piece.x0 + piece.width - 1) / tw,
                        "inside a tile"
                    );
                    assert_eq!(
                        piece.y0 / th,
                        (piece.y0 + piece.height - 1) / th,
                        "inside a tile"
                    );
                    assert_eq!(buffer.len(), piece.pixels() * 3 * n);
                    for (j, image) in images.iter().enumerate() {
                        for p in 0..piece.pixels() {
                            let q = piece.band_pixel(p, w);
                            let got = &buffer[(j * piece.pixels() + p) * 3..][..3];
                            assert_eq!(
                                got,
                                &image[3 * q..3 * q + 3],
                                "{samples:?} {tiles:?} {rows} piece {s}"
                            );
                            seen[q] += 1;
                        }
                    }
                }
                assert!(
                    seen.iter().all(|&c| c == n),
                    "every pixel once, {tiles:?} {rows}"
                );
                let bytes = if samples == Samples::Codes { 3 } else { 12 };
                assert_eq!(spill.bytes(), (w * h * bytes * n) as u64);
                if samples == Samples::Codes && spill.pieces() > 0 {
                    let first = spill.pieces_for(tiles)[0];
                    assert!(spill.read_region(first, &mut buffer, None).is_err());
                }
            }
        }
    }

    #[test]
    fn pieces_of_other_tiles_read_across_the_files_pieces() {
        // A file spilled in one layout, solved in another's pieces: strips of whole rows
        // from tiles, tiles twice as wide, and tiles from strips; floats and codes.
        let (w, h, n) = (70, 21, 3);
        let tables: Vec<Vec<f32>> = (0..n)
            .map(|j| (0..768).map(|i| (i * 5 + j * 7000) as f32).collect())
            .collect();
        let codes: Vec<Vec<u8>> = (0..n)
            .map(|j| (0..w * h * 3).map(|v| ((v * 11 + j) % 256) as u8).collect())
            .collect();
        let value = |j: usize, v: usize| tables[j][256 * (v % 3) + codes[j][v] as usize];
        for samples in [Samples::Floats, Samples::Codes] {
            for (spilled, solved, budget_rows) in [
                (Some((16, 8)), None, 2),
                (Some((16, 8)), Some((32, 8)), 3),
                (None, Some((16, 8)), 4),
                (Some((16, 8)), Some((16, 8)), 5),
            ] {
                let piece_bytes = budget_rows * 16 * 12 * n;
                let spill = Spill::create(w, h, n, piece_bytes, spilled, samples).unwrap();
                for (j, image_codes) in codes.iter().enumerate() {
                    let mut writer = spill.image_rows(j);
                    for y in 0..h {
                        match samples {
                            Samples::Floats => {
                                let row: Vec<f32> =
                                    (3 * w * y..3 * w * (y + 1)).map(|v| value(j, v)).collect();
                                writer.push(&row).unwrap();
                            }
                            Samples::Codes => writer
                                .push_codes(&image_codes[3 * w * y..3 * w * (y + 1)])
                                .unwrap(),
                        }
                    }
                    writer.finish().unwrap();
                }
                let tables = (samples == Samples::Codes).then_some(tables.as_slice());
                let pieces = spill.pieces_for(solved);
                let what = format!("{samples:?} {spilled:?} → {solved:?}");
                let mut seen = vec![0; w * h];
                let mut buffer = Vec::new();
                for piece in &pieces {
                    let (tw, th) = solved.unwrap_or((w, h));
                    assert_eq!(piece.x0 % tw, 0, "{what}: a piece starts a tile");
                    assert_eq!(
                        piece.width,
                        tw.min(w - piece.x0),
                        "{what}: the tile's width"
                    );
                    assert_eq!(piece.y0 / th, (piece.y0 + piece.height - 1) / th, "{what}");
                    spill.read_region(*piece, &mut buffer, tables).unwrap();
                    for j in 0..n {
                        for p in 0..piece.pixels() {
                            let q = piece.band_pixel(p, w);
                            for c in 0..3 {
                                let got = buffer[(j * piece.pixels() + p) * 3 + c];
                                assert_eq!(got, value(j, 3 * q + c), "{what} {piece:?}");
                            }
                        }
                    }
                    (0..piece.pixels()).for_each(|p| seen[piece.band_pixel(p, w)] += 1);
                }
                assert!(seen.iter().all(|&c| c == 1), "{what}: every pixel once");
                if spilled == solved {
                    assert_eq!(pieces.len(), spill.pieces(), "{what}: the file's own");
                }
            }
        }
        let spill = Spill::create(8, 4, 1, 1000, None, Samples::Floats).unwrap();
        let outside = Piece {
            x0: 4,
            y0: 0,
            width: 5,
            height: 1,
        };
        assert!(spill.read_region(outside, &mut Vec::new(), None).is_err());
    }
}
