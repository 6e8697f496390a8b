//! Tiled bundles: a big file reaches the browser a tile at a time, at the level the view
//! needs.
//!
//! A bundle of whole layers holds `width × height × layers × 8` bytes of half floats
//! (an 8192×2048 file of k = 25: 2.8 GB), more than a browser or a GPU should hold. A
//! tiled bundle ships instead:
//!
//! * an *overview*: the finest level of the file's mip pyramid whose layers take at most
//!   [`OVERVIEW_BYTES`], as the whole layers of an ordinary bundle (`info.json`
//!   `layers`, at `tiles.overview_size`); the viewer always holds it and draws from it
//!   where a tile has not arrived, and for views that shrink the image past it;
//! * tiles of every finer level, `data/tiles/L/X_Y.f16`: the `side × side` pixels (fewer
//!   at the right and bottom edges) from column `X·side`, row `Y·side` of level `L`, all
//!   layers of the bundle one after the other, each row-major RGBA half floats, the
//!   layout of a whole layer; then, where the file has depth, the tile's depth
//!   (row-major little-endian `f32`, 0 where nothing was hit). The server reads each
//!   from the file when it is asked for.
//!
//! Level `L` is the pyramid of `relit convert --mip-tiles` (OpenEXR's rounding down,
//! [`exr::mip_sizes`]): each pixel the mean of the `2^L × 2^L` pixels of level 0 it
//! covers (relighting is linear, so a level relights to the means of level 0's frame),
//! and its depth the mean of the hit ones among them, as the file's own levels hold it.
//! Levels the file holds are read as they are, by region; others are the means of
//! level 0's region, read in bands of rows, so a request never holds more than a band.
//! Depth travels the same way: the overview's depth (`data/depth.f32`, the overview's
//! size) stands in where a tile has not arrived, and no part of the bundle holds the
//! whole of level 0's depth (an 8192×2048 map alone is 64 MiB).

use crate::bundle::encode_layer;
use crate::{invalid, Result};
use relit::codec::exr;
use relit::maps::{CoefficientMaps, RelightableImage};
use relit::storage::Precision;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};

/// A turn to read a tile ([`TileSource::turn`]).
struct Turn<'a>(&'a (Mutex<usize>, Condvar));

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        let (count, freed) = self.0;
        *count.lock().unwrap_or_else(|e| e.into_inner()) -= 1;
        freed.notify_one();
    }
}

/// Side of a tile unless one is named: the tiles of `relit convert --mip-tiles`, so a
/// tile of a level the file holds is one block of it.
pub const DEFAULT_TILE_SIDE: usize = exr::DEFAULT_TILE;

/// The tile sides a bundle may have (a power of two, so that tiles of level `L` cover
/// whole tiles of level `L + 1`).
pub const TILE_SIDES: [usize; 5] = [64, 128, 256, 512, 1024];

/// Most bytes of the overview's layers unless told otherwise (the finest level within
/// them is the overview): a k = 25 overview of 1024×256, 8192×2048's level 3.
pub const OVERVIEW_BYTES: usize = 64 << 20;

/// Whole layers above this many bytes are tiled when the bundle chooses
/// ([`Tiling::Auto`]).
pub const WHOLE_BYTES: usize = 512 << 20;

/// Bytes of one texel of every layer: `layers` RGBA half floats.
fn texel_bytes(k: usize) -> usize {
    3 * crate::bundle::layers_per_channel(k) * 8
}

/// How a bundle sends the coefficient layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tiling {
    /// Whole layers while they take at most [`WHOLE_BYTES`] (half floats), tiles of
    /// [`DEFAULT_TILE_SIDE`] beyond, for files that can be read by region (relit EXR).
    Auto,
    /// Whole layers, however big.
    Whole,
    /// Tiles of this side (one of [`TILE_SIDES`]).
    Tiles(usize),
}

impl std::str::FromStr for Tiling {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(Tiling::Auto),
            "off" | "whole" => Ok(Tiling::Whole),
            n => match n.parse::<usize>() {
                Ok(side) if TILE_SIDES.contains(&side) => Ok(Tiling::Tiles(side)),
                _ => Err(format!(
                    "`{s}`: auto, off, or a tile side of {TILE_SIDES:?} pixels"
                )),
            },
        }
    }
}

/// The files tiles are read from by region.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Form {
    /// A relit EXR: any level it holds, by region.
    Exr,
    /// A compressed `.rlz` file of planes (not a codebook): any level it holds, by tile.
    Packed,
}

/// The tiles of one relit EXR or `.rlz` file, read from it as they are asked for.
#[derive(Debug)]
pub struct TileSource {
    path: PathBuf,
    form: Form,
    /// The block of level 0 read at once when a level is made from it (whole blocks of
    /// the file: 16 scan lines across the image, or a compressed file's tile).
    band: (usize, usize),
    side: usize,
    /// Level sizes from 0 to the overview's.
    sizes: Vec<(usize, usize)>,
    /// Levels the file holds (1: level 0 alone).
    file_levels: usize,
    k: usize,
    /// Whether the file has depth (each tile then carries its own).
    depth: bool,
    bytes_read: AtomicU64,
    tiles_read: AtomicU64,
    /// Tiles being read now, at most [`TileSource::readers`]: each holds a tile's maps
    /// (and a level's band), so clients asking for many at once wait rather than
    /// multiply the server's memory.
    reading: (Mutex<usize>, Condvar),
    /// The most tiles read at once so far.
    peak_readers: AtomicUsize,
}

/// What [`TileSource::open`] reads once: the overview's maps with the file's metadata,
/// and its depth (the overview's size) where the file has one.
pub struct Opened {
    pub source: TileSource,
    pub overview: RelightableImage,
}

impl TileSource {
    /// Open `path` (a relit EXR, or a `.rlz` file of planes) for tiles of `side`, its
    /// overview the finest level within `overview_bytes`; read the overview with its
    /// depth.
    pub fn open(path: &Path, side: usize, overview_bytes: usize) -> Result<Opened> {
        use relit::codec::{packed, FileForm};
        if !TILE_SIDES.contains(&side) {
            return Err(invalid(format!(
                "tiles are {TILE_SIDES:?} pixels a side, not {side}"
            )));
        }
        let (form, meta, k, has_depth, file_sizes, band) = match FileForm::of(path)? {
            FileForm::Exr => {
                let shape = exr::read_shape(path)?;
                let band = (shape.width, 16);
                (Form::Exr, shape.meta, shape.k, shape.depth, shape.levels, band)
            }
            FileForm::Compressed => {
                let header = packed::read_header(path)?;
                if header.indexed_pixels() {
                    return Err(invalid(format!(
                        "{}: a codebook file goes to the viewer as its entries and one index a pixel, not in tiles",
                        path.display()
                    )));
                }
                let k = header.meta.basis.build()?.len();
                let (_, _, tw, th) = header.tile_rect(0);
                let sizes = header.level_sizes();
                (Form::Packed, header.meta, k, header.depth, sizes, (tw, th))
            }
            _ => {
                return Err(invalid(format!(
                    "{}: tiles are read by region from a relit EXR or .rlz file; convert it first (`relit convert {} -o X.exr`)",
                    path.display(),
                    path.display()
                )))
            }
        };
        let (file_levels, (w, h)) = (file_sizes.len(), file_sizes[0]);
        let all = exr::mip_sizes(w, h);
        // The overview: the finest level within its bytes (the coarsest if none is).
        let overview = all
            .iter()
            .position(|&(lw, lh)| lw * lh * texel_bytes(k) <= overview_bytes)
            .unwrap_or(all.len() - 1);
        let source = TileSource {
            path: path.to_path_buf(),
            form,
            band,
            side,
            sizes: all[..=overview].to_vec(),
            file_levels,
            k,
            depth: has_depth,
            bytes_read: AtomicU64::new(0),
            tiles_read: AtomicU64::new(0),
            reading: (Mutex::new(0), Condvar::new()),
            peak_readers: AtomicUsize::new(0),
        };
        let (ow, oh) = all[overview];
        let (maps, depth) = source.read_level(overview, (0, 0, ow, oh))?;
        Ok(Opened {
            overview: RelightableImage { meta, maps, depth },
            source,
        })
    }

    /// The tile side.
    pub fn side(&self) -> usize {
        self.side
    }

    /// The level sizes from 0 to the overview's (the last).
    pub fn sizes(&self) -> &[(usize, usize)] {
        &self.sizes
    }

    /// The overview's level.
    pub fn overview_level(&self) -> usize {
        self.sizes.len() - 1
    }

    /// Tiles across and down level `level`.
    pub fn grid(&self, level: usize) -> (usize, usize) {
        let (w, h) = self.sizes[level];
        (w.div_ceil(self.side), h.div_ceil(self.side))
    }

    /// Every tile the bundle serves: `(level, x, y)` of the levels finer than the
    /// overview.
    pub fn tiles(&self) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        (0..self.overview_level()).flat_map(move |l| {
            let (c, r) = self.grid(l);
            (0..r).flat_map(move |y| (0..c).map(move |x| (l, x, y)))
        })
    }

    /// Bytes read from the file for tiles so far, and tiles served.
    pub fn counters(&self) -> (u64, u64) {
        (
            self.bytes_read.load(Ordering::Relaxed),
            self.tiles_read.load(Ordering::Relaxed),
        )
    }

    /// The bytes of tile `(level, x, y)` (of this source's, [`Self::parse_path`]).
    pub fn tile_bytes(&self, level: usize, x: usize, y: usize) -> usize {
        let (_, _, w, h) = self.tile_rect(level, x, y);
        w * h * (texel_bytes(self.k) + if self.depth { 4 } else { 0 })
    }

    /// The pixels of tile `(level, x, y)` in its level: `(x0, y0, width, height)`.
    fn tile_rect(&self, level: usize, x: usize, y: usize) -> (usize, usize, usize, usize) {
        let (w, h) = self.sizes[level];
        let (x0, y0) = (x * self.side, y * self.side);
        (x0, y0, self.side.min(w - x0), self.side.min(h - y0))
    }

    /// The bundle path of tile `(level, x, y)`.
    pub fn tile_path(level: usize, x: usize, y: usize) -> String {
        format!("data/tiles/{level}/{x}_{y}.f16")
    }

    /// The tile a bundle path names, if it names one of this source's.
    pub fn parse_path(&self, path: &str) -> Option<(usize, usize, usize)> {
        let rest = path.strip_prefix("data/tiles/")?.strip_suffix(".f16")?;
        let (level, xy) = rest.split_once('/')?;
        let (x, y) = xy.split_once('_')?;
        let number = |s: &str| {
            (!s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()) && s.len() < 10)
                .then(|| s.parse::<usize>().ok())
                .flatten()
        };
        let (level, x, y) = (number(level)?, number(x)?, number(y)?);
        let (c, r) = (level < self.overview_level()).then(|| self.grid(level))?;
        (x < c && y < r).then_some((level, x, y))
    }

    /// Tile `(level, x, y)`: its layers, each row-major RGBA half floats, one after the
    /// other (module docs).
    pub fn tile(&self, level: usize, x: usize, y: usize) -> Result<Vec<u8>> {
        if level >= self.overview_level() || x >= self.grid(level).0 || y >= self.grid(level).1 {
            return Err(invalid(format!("no tile {level}/{x}_{y}")));
        }
        let rect = self.tile_rect(level, x, y);
        let (maps, depth) = {
            let _turn = self.turn();
            self.read_level(level, rect)?
        };
        self.tiles_read.fetch_add(1, Ordering::Relaxed);
        let n = crate::bundle::layers_per_channel(self.k);
        let mut bytes = Vec::with_capacity(self.tile_bytes(level, x, y));
        for c in 0..3 {
            for j in 0..n {
                bytes.extend(encode_layer(&maps, c, j, Precision::F16)?);
            }
        }
        if let Some(depth) = depth {
            bytes.extend(crate::bundle::depth_bytes(&depth));
        }
        Ok(bytes)
    }

    /// The most tiles read at once so far (never more than [`Self::readers`]).
    pub fn peak_readers(&self) -> usize {
        self.peak_readers.load(Ordering::Relaxed)
    }

    /// Tiles read at once: one a core.
    pub fn readers() -> usize {
        std::thread::available_parallelism().map_or(2, |n| n.get())
    }

    /// Wait for a turn to read a tile; the turn ends when the guard drops.
    fn turn(&self) -> Turn<'_> {
        let (count, freed) = &self.reading;
        let mut n = count.lock().unwrap_or_else(|e| e.into_inner());
        while *n >= Self::readers() {
            n = freed.wait(n).unwrap_or_else(|e| e.into_inner());
        }
        *n += 1;
        self.peak_readers.fetch_max(*n, Ordering::Relaxed);
        Turn(&self.reading)
    }

    /// The maps of `rect` of `level`, with its depth where the file has one: read from
    /// the file where it holds the level, otherwise the means of level 0's pixels under
    /// each (the depth: of the hit ones), read in bands of rows.
    fn read_level(
        &self,
        level: usize,
        rect: (usize, usize, usize, usize),
    ) -> Result<(CoefficientMaps, Option<Vec<f32>>)> {
        if level < self.file_levels {
            return self.read(level, rect, self.depth);
        }
        // A level's pixel covers 2^e level-0 pixels along an axis, e stopping where the
        // side reached 1 (OpenEXR's rounding down keeps that side at 1).
        let (ex, ey) = self.shifts(level);
        let (rx, ry, rw, rh) = rect;
        let from = (rx << ex, ry << ey, rw << ex, rh << ey);
        let k = self.k;
        let n = rw * rh;
        let mut sums = vec![0.0f64; 3 * k * n];
        let mut hits = vec![(0.0f64, 0u32); if self.depth { n } else { 0 }];
        self.stream(level, from, self.depth, |(x0, y), band, band_depth| {
            let m = band.pixels();
            let column = |x: usize| ((x0 + x) >> ex) - rx;
            for j in 0..3 * k {
                let plane = &band.data[j * m..(j + 1) * m];
                let out = &mut sums[j * n..(j + 1) * n];
                for (row, line) in plane.chunks_exact(band.width).enumerate() {
                    let oy = ((y + row) >> ey) - ry;
                    let out = &mut out[oy * rw..(oy + 1) * rw];
                    for (x, &v) in line.iter().enumerate() {
                        out[column(x)] += v as f64;
                    }
                }
            }
            let band_depth = band_depth.unwrap_or(&[]);
            for (row, line) in band_depth.chunks_exact(band.width).enumerate() {
                let oy = ((y + row) >> ey) - ry;
                for (x, &d) in line.iter().enumerate() {
                    if d.is_finite() && d > 0.0 {
                        let hit = &mut hits[oy * rw + column(x)];
                        hit.0 += d as f64;
                        hit.1 += 1;
                    }
                }
            }
        })?;
        let scale = 1.0 / (1u64 << (ex + ey)) as f64;
        let maps = CoefficientMaps {
            width: rw,
            height: rh,
            k,
            data: sums.iter().map(|&s| (s * scale) as f32).collect(),
        };
        let depth = self.depth.then(|| {
            hits.iter()
                .map(|&(sum, count)| {
                    if count > 0 {
                        (sum / count as f64) as f32
                    } else {
                        0.0
                    }
                })
                .collect()
        });
        Ok((maps, depth))
    }

    /// How many times level `level` halved each side: a pixel of it covers `2^ex × 2^ey`
    /// pixels of level 0 (a side stops halving at 1, as OpenEXR's rounding down keeps it).
    fn shifts(&self, level: usize) -> (usize, usize) {
        let (w0, h0) = self.sizes[0];
        let shift = |side: usize| level.min((usize::BITS - 1 - side.leading_zeros()) as usize);
        (shift(w0), shift(h0))
    }

    /// `rect` of `level` (one the file holds) as stored, with its depth when asked for;
    /// counts the bytes read.
    fn read(
        &self,
        level: usize,
        rect: (usize, usize, usize, usize),
        depth: bool,
    ) -> Result<(CoefficientMaps, Option<Vec<f32>>)> {
        let (maps, depth, bytes) = match self.form {
            Form::Exr => {
                let read = exr::read_region_with(&self.path, level, rect, depth)?;
                (read.image.maps, read.image.depth, read.bytes_read)
            }
            Form::Packed => {
                let (image, bytes, _) =
                    relit::codec::packed::read_level_region(&self.path, level, rect, depth)?;
                (image.maps, image.depth, bytes)
            }
        };
        self.bytes_read.fetch_add(bytes, Ordering::Relaxed);
        Ok((maps, depth))
    }

    /// Read `rect` of level 0 a block of the file at a time (rows: at least `2^level`,
    /// so that an EXR band covers whole rows of `level`), handing each block's top-left
    /// corner, maps and depth (EXR, when asked for) to `f`. Blocks end on the file's
    /// block boundaries, so that none is decoded twice.
    fn stream(
        &self,
        level: usize,
        rect: (usize, usize, usize, usize),
        depth: bool,
        mut f: impl FnMut((usize, usize), &CoefficientMaps, Option<&[f32]>),
    ) -> Result<()> {
        let (x, y, w, h) = rect;
        let (across, down) = (self.band.0, self.band.1.max(1 << level.min(20)));
        let mut top = y;
        while top < y + h {
            let rows = (down - top % down).min(y + h - top);
            let mut left = x;
            while left < x + w {
                let columns = (across - left % across).min(x + w - left);
                let (maps, block_depth) = self.read(0, (left, top, columns, rows), depth)?;
                f((left, top), &maps, block_depth.as_deref());
                left += columns;
            }
            top += rows;
        }
        Ok(())
    }
}
