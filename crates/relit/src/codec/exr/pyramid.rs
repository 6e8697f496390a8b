//! [`write_tiled_from`]: the tiled file with mip levels of [`super::write_tiled`], made
//! from a relit EXR read a tile at a time, so that the maps are never held whole.
//!
//! Each tile of level `l > 0` holds the 2×2 means of level `l − 1`'s pixels under it,
//! and tile boundaries fall on even pixels, so the four pixels of every mean lie in one
//! tile of the finer level: a tile is made from its (up to) four children, each made
//! the same way and dropped once its quarter is taken, down to level 0's tiles, read
//! by region. The coarsest level is one tile, so one walk from it makes every tile that
//! has a parent; the last tile column or row of a level whose side is odd has none (the
//! coarser level leaves its pixels out) and is walked from separately. Every tile is
//! compressed when made and its bytes kept in a temporary file until the file is
//! written. Memory: a tile a level on the walk's path, however big the image.

use super::*;
use exr::block::writer::ChunksWriter;
use std::io::{Read, Seek, SeekFrom, Write};

/// Write the relit EXR at `input` as a tiled file with mip levels at `path`, reading a
/// tile of level 0 at a time: the file [`super::write_tiled`] writes from the image
/// [`super::read`] gives, its offsets and blocks byte for byte (the header's
/// attributes may come in another order: the exr crate keeps them in a hash map).
pub fn write_tiled_from(
    input: &Path,
    path: &Path,
    precision: Precision,
    tile: usize,
) -> Result<()> {
    let precision = precision.require(&[Precision::F32, Precision::F16], "OpenEXR")?;
    check_tile_side(tile)?;
    let FileShape {
        meta,
        width: w,
        height: h,
        k,
        depth,
        ..
    } = read_shape(input)?;
    let headers = tiled_headers(
        w,
        h,
        k,
        precision,
        depth,
        &attributes(&meta, precision),
        tile,
    );
    let order: Vec<Option<(usize, usize)>> = headers[0]
        .channels
        .list
        .iter()
        .map(|ch| parse_channel_name(&ch.name.to_string()))
        .collect();
    let mut walk = Walk {
        input,
        headers: &headers,
        order,
        tile,
        sizes: mip_sizes(w, h),
        depth,
        half: precision == Precision::F16,
        spill: tempfile::tempfile().map_err(|e| {
            Error::new(
                ErrorKind::Io,
                "cannot create a temporary file for the tiles",
            )
            .with_source(e)
        })?,
        written: 0,
        chunks: std::collections::HashMap::new(),
    };
    let top = walk.sizes.len() - 1;
    walk.make(top, 0, 0)?;
    for level in (0..top).rev() {
        let (cols, rows) = walk.grid(level);
        let (parent_cols, parent_rows) = walk.grid(level + 1);
        for ty in 0..rows {
            for tx in 0..cols {
                if tx >= 2 * parent_cols || ty >= 2 * parent_rows {
                    walk.make(level, tx, ty)?;
                }
            }
        }
    }
    let Walk {
        mut chunks,
        mut spill,
        ..
    } = walk;
    let blocks: Vec<(usize, exr::block::BlockIndex)> =
        exr::block::enumerate_ordered_header_block_indices(&headers).collect();
    let mut ordered = Vec::with_capacity(blocks.len());
    for (_, block) in &blocks {
        let key = (
            block.level.0,
            block.pixel_position.0 / tile,
            block.pixel_position.1 / tile,
        );
        let entry = chunks
            .remove(&key)
            .ok_or_else(|| Error::invalid(format!("tile {key:?} was not made")))?;
        ordered.push(entry);
    }
    write_atomically(path, |out| {
        exr::block::write(out, headers.clone(), true, |_, chunk_writer| {
            for (index, (mut chunk, at, length)) in ordered.into_iter().enumerate() {
                let bytes = chunk_bytes(&mut chunk);
                bytes.resize(length, 0);
                spill.seek(SeekFrom::Start(at))?;
                spill.read_exact(bytes)?;
                chunk_writer.write_chunk(index, chunk)?;
            }
            Ok(())
        })
        .map_err(|e| exr_error(path, "write", e))
    })
}

/// The headers of [`super::write_tiled`]'s file: ZIP in `tile`-pixel tiles with mip
/// levels rounding down, the channels sorted by name.
pub(super) fn tiled_headers(
    width: usize,
    height: usize,
    k: usize,
    precision: Precision,
    depth: bool,
    attrs: &LayerAttributes,
    tile: usize,
) -> exr::meta::Headers {
    let channels = empty_channels(k, precision, depth, |samples| Levels::Mip {
        rounding_mode: RoundingMode::Down,
        level_data: vec![samples],
    });
    headers_of(
        (width, height),
        attrs,
        Compression::ZIP16,
        Blocks::Tiles(Vec2(tile, tile)),
        channels,
    )
}

/// One tile of one level: a plane of `width × height` values for each channel of the
/// file, in the header's order.
struct LevelTile {
    width: usize,
    height: usize,
    planes: Vec<Vec<f32>>,
}

/// A tile's chunk, its bytes moved out.
struct Compressed {
    chunk: exr::block::chunk::Chunk,
    bytes: Vec<u8>,
}

/// The walk over the pyramid's tiles (module docs).
struct Walk<'a> {
    input: &'a Path,
    headers: &'a exr::meta::Headers,
    /// The file's channels in order: a coefficient plane `(i, c)`, or `None` the depth.
    order: Vec<Option<(usize, usize)>>,
    tile: usize,
    sizes: Vec<(usize, usize)>,
    depth: bool,
    half: bool,
    spill: std::fs::File,
    written: u64,
    /// Each tile made, `(level, x, y)`: its chunk (bytes moved out), where its bytes
    /// start in `spill` and their length.
    chunks:
        std::collections::HashMap<(usize, usize, usize), (exr::block::chunk::Chunk, u64, usize)>,
}

impl Walk<'_> {
    fn grid(&self, level: usize) -> (usize, usize) {
        let (w, h) = self.sizes[level];
        (w.div_ceil(self.tile), h.div_ceil(self.tile))
    }

    /// The size of tile `(x, y)` of `level`.
    fn tile_size(&self, level: usize, x: usize, y: usize) -> (usize, usize) {
        let (lw, lh) = self.sizes[level];
        (
            self.tile.min(lw - x * self.tile),
            self.tile.min(lh - y * self.tile),
        )
    }

    /// Make tile `(x, y)` of `level` (and every tile under it), store it, return it.
    /// The level-0 children of a level-1 tile are read and compressed side by side.
    fn make(&mut self, level: usize, x: usize, y: usize) -> Result<LevelTile> {
        use rayon::prelude::*;
        if level == 0 {
            let (made, chunk) = self.level0(x, y)?;
            self.store(0, x, y, chunk)?;
            return Ok(made);
        }
        let t = self.tile;
        let (tw, th) = self.tile_size(level, x, y);
        let mut made = LevelTile {
            width: tw,
            height: th,
            planes: vec![vec![0.0; tw * th]; self.order.len()],
        };
        let (cols, rows) = self.grid(level - 1);
        let finer = self.sizes[level - 1];
        let children: Vec<(usize, usize)> = (2 * y..(2 * y + 2).min(rows))
            .flat_map(|cy| (2 * x..(2 * x + 2).min(cols)).map(move |cx| (cx, cy)))
            .collect();
        if level == 1 {
            let this = &*self;
            let made_children: Vec<_> = children
                .par_iter()
                .map(|&(cx, cy)| this.level0(cx, cy))
                .collect::<Result<_>>()?;
            for (&(cx, cy), (child, chunk)) in children.iter().zip(made_children) {
                self.store(0, cx, cy, chunk)?;
                self.take_quarter(&mut made, (x * t, y * t), &child, (cx * t, cy * t), finer);
            }
        } else {
            for (cx, cy) in children {
                let child = self.make(level - 1, cx, cy)?;
                self.take_quarter(&mut made, (x * t, y * t), &child, (cx * t, cy * t), finer);
            }
        }
        let chunk = self.compress(level, x, y, &made)?;
        self.store(level, x, y, chunk)?;
        Ok(made)
    }

    /// Tile `(x, y)` of level 0, read from the input, and compressed.
    fn level0(&self, x: usize, y: usize) -> Result<(LevelTile, Compressed)> {
        let (tw, th) = self.tile_size(0, x, y);
        let rect = (x * self.tile, y * self.tile, tw, th);
        let read = read_region_with(self.input, 0, rect, self.depth)?;
        let RelightableImage { maps, depth, .. } = read.image;
        let planes = self
            .order
            .iter()
            .map(|source| match *source {
                Some((i, c)) => maps.plane(i, c).to_vec(),
                None => depth.clone().unwrap_or_default(),
            })
            .collect();
        let made = LevelTile {
            width: tw,
            height: th,
            planes,
        };
        let chunk = self.compress(0, x, y, &made)?;
        Ok((made, chunk))
    }

    /// The pixels of `parent` (at `origin` of its level) whose 2×2 blocks lie in
    /// `child` (at `child_origin` of the finer level, `finer` pixels in all): the means
    /// of the block's pixels inside the finer level that its channel keeps (finite
    /// coefficients; finite positive depth), 0 where none is, as `halve` makes them.
    fn take_quarter(
        &self,
        parent: &mut LevelTile,
        origin: (usize, usize),
        child: &LevelTile,
        child_origin: (usize, usize),
        finer: (usize, usize),
    ) {
        for (s, source) in self.order.iter().enumerate() {
            let keep: fn(f32) -> bool = match source {
                Some(_) => f32::is_finite,
                None => |d| d.is_finite() && d > 0.0,
            };
            let from = &child.planes[s];
            let to = &mut parent.planes[s];
            for py in 0..parent.height {
                let fy = 2 * (origin.1 + py);
                if fy < child_origin.1 || fy >= child_origin.1 + child.height {
                    continue;
                }
                for px in 0..parent.width {
                    let fx = 2 * (origin.0 + px);
                    if fx < child_origin.0 || fx >= child_origin.0 + child.width {
                        continue;
                    }
                    let (mut sum, mut n) = (0.0f64, 0u32);
                    for sy in (fy..fy + 2).filter(|&v| v < finer.1) {
                        for sx in (fx..fx + 2).filter(|&v| v < finer.0) {
                            let v =
                                from[(sy - child_origin.1) * child.width + (sx - child_origin.0)];
                            if keep(v) {
                                sum += v as f64;
                                n += 1;
                            }
                        }
                    }
                    if n > 0 {
                        to[py * parent.width + px] = (sum / n as f64) as f32;
                    }
                }
            }
        }
    }

    /// `made`, tile `(x, y)` of `level`, compressed.
    fn compress(&self, level: usize, x: usize, y: usize, made: &LevelTile) -> Result<Compressed> {
        let t = self.tile;
        let index = exr::block::BlockIndex {
            layer: 0,
            pixel_position: Vec2(x * t, y * t),
            pixel_size: Vec2(made.width, made.height),
            level: Vec2(level, level),
        };
        let mut data = Vec::with_capacity(made.width * made.height * 4 * self.order.len());
        let mut bits = vec![0u16; made.width];
        for row in 0..made.height {
            for (s, source) in self.order.iter().enumerate() {
                let line = &made.planes[s][row * made.width..(row + 1) * made.width];
                push_samples(&mut data, line, self.half && source.is_some(), &mut bits);
            }
        }
        let mut chunk = exr::block::UncompressedBlock { index, data }
            .compress_to_chunk(self.headers)
            .map_err(|e| Error::new(ErrorKind::Io, format!("cannot compress a tile: {e}")))?;
        let bytes = std::mem::take(chunk_bytes(&mut chunk));
        Ok(Compressed { chunk, bytes })
    }

    /// Keep tile `(x, y)` of `level`'s bytes in the spill file.
    fn store(&mut self, level: usize, x: usize, y: usize, compressed: Compressed) -> Result<()> {
        let Compressed { chunk, bytes } = compressed;
        self.spill.write_all(&bytes).map_err(|e| {
            Error::new(ErrorKind::Io, "cannot write the temporary file of tiles").with_source(e)
        })?;
        self.chunks
            .insert((level, x, y), (chunk, self.written, bytes.len()));
        self.written += bytes.len() as u64;
        Ok(())
    }
}
