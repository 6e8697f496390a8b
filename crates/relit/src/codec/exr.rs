//! The native file: one OpenEXR part whose channels are the coefficient planes.
//!
//! Layout and attribute names are fixed in the [conventions](crate): channels
//! `cNN.R|G|B` (coefficient NN) and optional `Z` (depth); metadata in `relit.*`
//! attributes, structured values as ASCII JSON so any EXR tool can show them.

use crate::basis::BasisSpec;
use crate::fit::Piece;
use crate::fsutil::write_atomically;
use crate::maps::{
    BakeInfo, CoefficientMaps, FitInfo, MapSpace, Metadata, RelightableImage, FORMAT_VERSION,
};
use crate::storage::{CompactPlanes, FiniteRange, PlaneCoding, Precision};
use crate::{Error, ErrorKind, Result};
use exr::math::RoundingMode;
use exr::meta::attribute::LevelMode;
use exr::prelude::*;
use std::path::Path;

const CHANNEL_NAMES: [&str; 3] = ["R", "G", "B"];

fn channel_name(i: usize, c: usize) -> String {
    format!("c{i:02}.{}", CHANNEL_NAMES[c])
}

fn exr_error(path: &Path, action: &str, e: exr::error::Error) -> Error {
    Error::new(
        ErrorKind::Io,
        format!("cannot {action} {}: {e}", path.display()),
    )
}

/// JSON with every non-ASCII character escaped, as EXR text attributes hold bytes.
fn ascii_json<T: serde::Serialize>(value: &T) -> String {
    let json = serde_json::to_string(value).expect("metadata serialises");
    let mut out = String::with_capacity(json.len());
    for ch in json.chars() {
        if ch.is_ascii() {
            out.push(ch);
        } else {
            let mut buf = [0u16; 2];
            for unit in ch.encode_utf16(&mut buf) {
                out.push_str(&format!("\\u{unit:04x}"));
            }
        }
    }
    out
}

fn text(s: &str) -> AttributeValue {
    AttributeValue::Text(Text::new_or_panic(s))
}

/// Write a relightable image. Maps are stored in `precision` (f32 or f16); depth
/// always as 32-bit float.
pub fn write(path: &Path, image: &RelightableImage, precision: Precision) -> Result<()> {
    use exr::block::writer::ChunksWriter;
    let precision = precision.require(&[Precision::F32, Precision::F16], "OpenEXR")?;
    let maps = &image.maps;
    let (w, h) = (maps.width, maps.height);
    // The header is inferred from channels without samples; each block's bytes are made
    // from the maps as it goes to the compressor, so the writer never holds a second copy
    // of the maps (item1's fit peaked 20 MiB lower, item11's 45).
    let headers = native_headers(
        w,
        h,
        maps.k,
        precision,
        image.depth.is_some(),
        &attributes(&image.meta, precision),
    );
    let half = precision == Precision::F16;
    // The sources in the header's channel order (sorted by name).
    let order: Vec<(&[f32], bool)> = headers[0]
        .channels
        .list
        .iter()
        .map(|ch| match parse_channel_name(&ch.name.to_string()) {
            Some((i, c)) => (maps.plane(i, c), half),
            None => (
                image.depth.as_deref().expect("a Z channel only with depth"),
                false,
            ),
        })
        .collect();
    write_atomically(path, |out| {
        exr::block::write(out, headers, true, |meta, chunk_writer| {
            let blocks = meta.collect_ordered_block_data(|index| {
                let (x0, y0) = (index.pixel_position.0, index.pixel_position.1);
                let (bw, bh) = (index.pixel_size.0, index.pixel_size.1);
                let mut data = Vec::with_capacity(bw * bh * 4 * order.len());
                let mut bits = vec![0u16; bw];
                for y in y0..y0 + bh {
                    for &(samples, half) in &order {
                        let row = &samples[y * w + x0..y * w + x0 + bw];
                        push_samples(&mut data, row, half, &mut bits);
                    }
                }
                data
            });
            // A batch of blocks a few per thread, compressed side by side
            // (`zip::compress`), then written in order.
            use rayon::prelude::*;
            let mut blocks = blocks;
            let batch = 2 * rayon::current_num_threads().max(1);
            loop {
                let made: Vec<_> = blocks.by_ref().take(batch).collect();
                if made.is_empty() {
                    return Ok(());
                }
                let chunks = made
                    .into_par_iter()
                    .map(|(i, block)| Ok((i, zip::compress(&meta.headers, block)?)))
                    .collect::<exr::error::Result<Vec<_>>>()?;
                for (i, chunk) in chunks {
                    chunk_writer.write_chunk(i, chunk)?;
                }
            }
        })
        .map_err(|e| exr_error(path, "write", e))
    })
}

/// The `relit.*` attributes of a file of `meta` stored in `precision`.
/// A file written from pieces as they are made (a fit's strips of rows, or parts of
/// tiles), so that the maps are never held whole: each block (16 scan lines, or a tile,
/// as [`write`] makes them) is compressed as soon as its pixels have arrived and its
/// bytes go to a temporary file until [`ExrStream::finish`] writes the file with the
/// final metadata (the header, which holds the fit's results, comes first in the file).
/// It reads back as [`write`]'s file of the same maps and metadata does, bit for bit,
/// and has its size.
///
/// Memory: the pieces of a block a thread and of the blocks still incomplete, beside
/// what the caller passes; pieces must come in the order of the blocks
/// ([`ExrStream::tiles`]).
pub struct ExrStream {
    width: usize,
    height: usize,
    k: usize,
    precision: Precision,
    depth: Option<Vec<f32>>,
    /// Headers made with empty metadata: compression depends only on the channels and
    /// the blocks, which the final headers share.
    headers: exr::meta::Headers,
    /// The channels in the header's order: `Some((i, c))` a coefficient plane, `None`
    /// depth.
    order: Vec<Option<(usize, usize)>>,
    /// Pieces whose pixels are in a block not yet compressed, each with the last block
    /// it touches.
    pending: Vec<(Piece, CoefficientMaps, usize)>,
    /// Every block of the file, in the order it is written, and its rows arrived so far
    /// (pieces fill a block from its top).
    blocks: Vec<exr::block::BlockIndex>,
    filled: Vec<usize>,
    /// The blocks compressed so far, in order, each with the length of its bytes, which
    /// are moved to `spill` one after another.
    chunks: Vec<(exr::block::chunk::Chunk, usize)>,
    spill: std::fs::File,
}

impl ExrStream {
    /// A file of `width × height` pixels with `k` coefficients per channel, in
    /// `precision` (f32 or f16), with `depth` when given (`width × height` values).
    pub fn new(
        width: usize,
        height: usize,
        k: usize,
        precision: Precision,
        depth: Option<Vec<f32>>,
    ) -> Result<ExrStream> {
        let precision = precision.require(&[Precision::F32, Precision::F16], "OpenEXR")?;
        if depth.as_ref().is_some_and(|d| d.len() != width * height) {
            return Err(Error::invalid("the depth map does not match the image"));
        }
        let headers = native_headers(
            width,
            height,
            k,
            precision,
            depth.is_some(),
            &LayerAttributes::default(),
        );
        let order = headers[0]
            .channels
            .list
            .iter()
            .map(|ch| parse_channel_name(&ch.name.to_string()))
            .collect();
        let blocks: Vec<exr::block::BlockIndex> =
            exr::block::enumerate_ordered_header_block_indices(&headers)
                .enumerate()
                .map(|(at, (index, block))| {
                    debug_assert_eq!(at, index);
                    block
                })
                .collect();
        let filled = vec![0; blocks.len()];
        Ok(ExrStream {
            width,
            height,
            k,
            precision,
            depth,
            headers,
            order,
            pending: Vec::new(),
            blocks,
            filled,
            chunks: Vec::new(),
            spill: tempfile::tempfile().map_err(|e| {
                Error::new(
                    ErrorKind::Io,
                    "cannot create a temporary file for the blocks",
                )
                .with_source(e)
            })?,
        })
    }

    /// The tiles of the file of an image of `width × height` pixels with `k`
    /// coefficients per channel, in `precision` (with a depth channel when `depth`), or
    /// `None` when it is stored in scan lines: pieces for [`ExrStream::piece`] must stay
    /// inside its tiles.
    pub fn tiles(
        width: usize,
        k: usize,
        precision: Precision,
        depth: bool,
    ) -> Option<(usize, usize)> {
        match native_blocks(width, k, precision, depth).1 {
            Blocks::ScanLines => None,
            Blocks::Tiles(size) => Some((size.0, size.1)),
        }
    }

    /// The coefficients `maps` of `piece` of the image. Pieces come in the order of the
    /// file's blocks: strips of rows from the top, or, in a tiled file, tile by tile
    /// (rows of tiles from the top, each from the left), each tile's pieces from its top.
    pub fn piece(&mut self, piece: Piece, maps: CoefficientMaps) -> Result<()> {
        use rayon::prelude::*;
        if maps.width != piece.width
            || maps.height != piece.height
            || maps.k != self.k
            || piece.pixels() == 0
            || piece.x0 + piece.width > self.width
            || piece.y0 + piece.height > self.height
        {
            return Err(Error::invalid("a piece that does not belong to this image"));
        }
        // The blocks the piece falls in (blocks go down the image, a row of tiles or
        // one block of lines at a time): each must be the piece's across its width and
        // continue it from its next row down.
        let first = self
            .blocks
            .partition_point(|b| b.pixel_position.1 + b.pixel_size.1 <= piece.y0);
        let mut touched = Vec::new();
        for (b, block) in self.blocks.iter().enumerate().skip(first) {
            let (Vec2(bx, by), Vec2(bw, bh)) = (block.pixel_position, block.pixel_size);
            if by >= piece.y0 + piece.height {
                break;
            }
            if bx + bw <= piece.x0 || bx >= piece.x0 + piece.width {
                continue;
            }
            if bx < piece.x0 || bx + bw > piece.x0 + piece.width {
                return Err(Error::invalid("a piece that cuts the file's tiles"));
            }
            if piece.y0.max(by) != by + self.filled[b] {
                return Err(Error::invalid(
                    "pixels out of the order of the file's blocks, or twice",
                ));
            }
            touched.push((b, (by + bh).min(piece.y0 + piece.height) - by));
        }
        let Some(&(last, _)) = touched.last() else {
            return Err(Error::invalid("a piece that does not belong to this image"));
        };
        for (b, filled) in touched {
            self.filled[b] = filled;
        }
        self.pending.push((piece, maps, last));
        // The blocks whose pixels have all arrived, compressed in parallel, in order.
        let done = self.chunks.len();
        let ready = self.blocks[done..]
            .iter()
            .zip(&self.filled[done..])
            .take_while(|(b, &filled)| filled == b.pixel_size.1)
            .count();
        let complete = done + ready == self.blocks.len();
        // A block a thread at least, so that compressing is never one thread's work
        // while the others wait (a strip of a small image completes about one block).
        if ready == 0 || (ready < rayon::current_num_threads() && !complete) {
            return Ok(());
        }
        let this = &*self;
        let chunks: Vec<exr::block::chunk::Chunk> = self.blocks[done..done + ready]
            .par_iter()
            .map(|b| this.block(b))
            .collect::<Result<_>>()?;
        for mut chunk in chunks {
            let bytes = std::mem::take(chunk_bytes(&mut chunk));
            std::io::Write::write_all(&mut self.spill, &bytes).map_err(|e| {
                Error::new(ErrorKind::Io, "cannot write the temporary file of blocks")
                    .with_source(e)
            })?;
            self.chunks.push((chunk, bytes.len()));
        }
        // Pieces whose every block is compressed are no longer needed.
        let compressed = self.chunks.len();
        self.pending.retain(|&(_, _, last)| last >= compressed);
        Ok(())
    }

    /// One block (all its pixels pending), compressed.
    fn block(&self, block: &exr::block::BlockIndex) -> Result<exr::block::chunk::Chunk> {
        let w = self.width;
        let (x0, y0) = (block.pixel_position.0, block.pixel_position.1);
        let (bw, bh) = (block.pixel_size.0, block.pixel_size.1);
        let half = self.precision == Precision::F16;
        let mut data = Vec::with_capacity(bw * bh * 4 * self.order.len());
        let mut bits = vec![0u16; bw];
        for y in y0..y0 + bh {
            let (piece, maps, _) = self
                .pending
                .iter()
                .find(|(p, _, _)| p.local(x0, y).is_some())
                .expect("a complete block's pixels are pending");
            let at = piece.local(x0, y).expect("the row is in the piece");
            for source in &self.order {
                match *source {
                    Some((i, c)) => {
                        let row = &maps.plane(i, c)[at..at + bw];
                        push_samples(&mut data, row, half, &mut bits);
                    }
                    None => {
                        let depth = self.depth.as_ref().expect("a Z channel only with depth");
                        push_samples(
                            &mut data,
                            &depth[y * w + x0..y * w + x0 + bw],
                            false,
                            &mut bits,
                        );
                    }
                }
            }
        }
        zip::compress(
            &self.headers,
            exr::block::UncompressedBlock {
                index: *block,
                data,
            },
        )
        .map_err(|e| Error::new(ErrorKind::Io, format!("cannot compress a block: {e}")))
    }

    /// Write the file with its metadata, once every pixel has arrived; the file appears
    /// whole or not at all.
    pub fn finish(self, path: &Path, meta: &Metadata) -> Result<()> {
        use exr::block::writer::ChunksWriter;
        if self.chunks.len() != self.blocks.len() {
            let made: usize = self
                .blocks
                .iter()
                .zip(&self.filled)
                .map(|(b, rows)| b.pixel_size.0 * rows)
                .sum();
            return Err(Error::invalid(format!(
                "{made} of {} pixels were made: the file is not written",
                self.width * self.height
            )));
        }
        let headers = native_headers(
            self.width,
            self.height,
            self.k,
            self.precision,
            self.depth.is_some(),
            &attributes(meta, self.precision),
        );
        let (chunks, mut spill) = (self.chunks, self.spill);
        std::io::Seek::rewind(&mut spill).map_err(|e| {
            Error::new(ErrorKind::Io, "cannot read the temporary file of blocks").with_source(e)
        })?;
        let mut spill = std::io::BufReader::new(spill);
        write_atomically(path, |out| {
            exr::block::write(out, headers, true, |_, chunk_writer| {
                for (index, (mut chunk, length)) in chunks.into_iter().enumerate() {
                    let bytes = chunk_bytes(&mut chunk);
                    bytes.resize(length, 0);
                    std::io::Read::read_exact(&mut spill, bytes)?;
                    chunk_writer.write_chunk(index, chunk)?;
                }
                Ok(())
            })
            .map_err(|e| exr_error(path, "write", e))
        })
    }
}

/// The compressed bytes of a block of a flat (not deep) file.
fn chunk_bytes(chunk: &mut exr::block::chunk::Chunk) -> &mut Vec<u8> {
    use exr::block::chunk::CompressedBlock;
    match &mut chunk.compressed_block {
        CompressedBlock::Tile(tile) => &mut tile.compressed_pixels_le,
        CompressedBlock::ScanLine(lines) => &mut lines.compressed_pixels_le,
        CompressedBlock::DeepScanLine(_) | CompressedBlock::DeepTile(_) => {
            unreachable!("relit writes no deep data")
        }
    }
}

/// A fit written to the OpenEXR file `path` (f16 or f32) as its pieces are solved
/// ([`crate::fit::fit_streamed`] into an [`ExrStream`]): the maps are never held whole.
/// The file reads back as [`crate::fit::fit`]'s image written with [`write`] does, bit
/// for bit (the fit's time in its metadata aside). Returns the metadata and the fit's
/// report, whose peak memory includes the writing.
pub fn fit_to_exr(
    capture: &crate::capture::Capture,
    options: &crate::fit::FitOptions,
    progress: &dyn crate::progress::Progress,
    path: &Path,
    precision: Precision,
) -> Result<(Metadata, crate::fit::FitReport)> {
    let mut sink = StreamSink {
        precision,
        depth: capture.depth.is_some(),
        stream: None,
    };
    let (meta, mut report) = crate::fit::fit_streamed(capture, options, progress, &mut sink)?;
    let started = std::time::Instant::now();
    sink.stream
        .ok_or_else(|| Error::invalid("the fit produced no pixels"))?
        .finish(path, &meta)?;
    // The report's time covers the writing (its stages sum to at most its time); the
    // metadata's, written in the file, ends where the maps were made.
    let writing = started.elapsed().as_secs_f64();
    report.stages.push(crate::fit::Stage {
        name: "write",
        seconds: writing,
    });
    report.seconds += writing;
    report.images_per_second = report.images as f64 / report.seconds.max(1e-9);
    report.peak_rss_bytes = crate::memory::peak_rss_bytes();
    Ok((meta, report))
}

/// An [`ExrStream`] made when the fit knows its size.
struct StreamSink {
    precision: Precision,
    /// Whether the file has a depth channel (the capture has a depth map).
    depth: bool,
    stream: Option<ExrStream>,
}

impl crate::fit::PieceSink for StreamSink {
    fn tiles(&self, width: usize, _height: usize, k: usize) -> Option<(usize, usize)> {
        ExrStream::tiles(width, k, self.precision, self.depth)
    }

    fn begin(
        &mut self,
        width: usize,
        height: usize,
        k: usize,
        depth: Option<Vec<f32>>,
    ) -> Result<()> {
        if depth.is_some() != self.depth {
            return Err(Error::invalid("the depth map came or went during the fit"));
        }
        self.stream = Some(ExrStream::new(width, height, k, self.precision, depth)?);
        Ok(())
    }

    fn piece(&mut self, piece: Piece, maps: CoefficientMaps) -> Result<()> {
        self.stream
            .as_mut()
            .ok_or_else(|| Error::invalid("pixels before the stream began"))?
            .piece(piece, maps)
    }
}

/// Append one row of a block's channel as the file stores it (native-endian, as the
/// exr crate's uncompressed blocks are): half floats, or f32. `bits` is scratch of the
/// row's length.
fn push_samples(data: &mut Vec<u8>, row: &[f32], half: bool, bits: &mut [u16]) {
    if half {
        crate::storage::to_f16_bits(row, bits);
        bits.iter()
            .for_each(|b| data.extend_from_slice(&b.to_ne_bytes()));
    } else {
        row.iter()
            .for_each(|v| data.extend_from_slice(&v.to_ne_bytes()));
    }
}

/// The most bytes a block may take, as stored: 16 scan lines up to this, else tiles of
/// 16 lines within it (at K = 25 in half floats, 16 lines up to 436 pixels wide, then
/// tiles 256 pixels wide). A streamed fit holds a block a thread waiting, in f32, so a
/// block's size bounds its memory however wide the image: with scan lines, a row of an
/// 8192-pixel panorama at K = 25 is 2.4 MB in f32.
const MAX_BLOCK_BYTES: usize = 1 << 20;

/// Lines of a block: a block of scan lines, or a tile's height.
const BLOCK_LINES: usize = 16;

/// The compression and blocks of the native file of an image `width` pixels wide with
/// `k` coefficients per channel in `precision` (and a depth channel when `depth`):
/// ZIP in blocks of 16 scan lines, or in tiles 16 lines high and a power of two from 16
/// to 256 pixels wide, the widest within [`MAX_BLOCK_BYTES`].
fn native_blocks(
    width: usize,
    k: usize,
    precision: Precision,
    depth: bool,
) -> (Compression, Blocks) {
    let half = precision == Precision::F16;
    let pixel_bytes = 3 * k * if half { 2 } else { 4 } + if depth { 4 } else { 0 };
    if BLOCK_LINES * width * pixel_bytes <= MAX_BLOCK_BYTES {
        return (Compression::ZIP16, Blocks::ScanLines);
    }
    let most = MAX_BLOCK_BYTES / (BLOCK_LINES * pixel_bytes);
    let tile_width = (16..=256)
        .rev()
        .filter(|w: &usize| w.is_power_of_two())
        .find(|&w| w <= most)
        .unwrap_or(16);
    (
        Compression::ZIP16,
        Blocks::Tiles(Vec2(tile_width, BLOCK_LINES)),
    )
}

/// The headers of the native file of coefficient planes (and depth), as [`write`] and
/// [`ExrStream`] make them.
fn native_headers(
    width: usize,
    height: usize,
    k: usize,
    precision: Precision,
    depth: bool,
    attrs: &LayerAttributes,
) -> exr::meta::Headers {
    let channels = empty_channels(k, precision, depth, |samples| samples);
    let (compression, blocks) = native_blocks(width, k, precision, depth);
    headers_of((width, height), attrs, compression, blocks, channels)
}

/// The headers of a one-layer file of `channels` (sorted by name), its blocks written in
/// increasing order, so that the same maps make the same bytes (unspecified would let
/// the writer put them down as its threads finish).
fn headers_of<S: for<'s> exr::image::write::samples::WritableSamples<'s>>(
    size: (usize, usize),
    attrs: &LayerAttributes,
    compression: Compression,
    blocks: Blocks,
    channels: Vec<AnyChannel<S>>,
) -> exr::meta::Headers {
    let encoding = Encoding {
        compression,
        blocks,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        size,
        attrs.clone(),
        encoding,
        AnyChannels::sort(channels.into()),
    );
    Image::from_layer(layer).write().infer_meta_data()
}

/// The channels of a file of `k` coefficients per colour (and depth), holding no
/// samples (`wrap` puts the empty samples of each into what the layer holds: the samples
/// themselves, or one level of them): what the headers are inferred from.
fn empty_channels<S: for<'s> exr::image::write::samples::WritableSamples<'s>>(
    k: usize,
    precision: Precision,
    depth: bool,
    wrap: impl Fn(FlatSamples) -> S,
) -> Vec<AnyChannel<S>> {
    let none = |precision: Precision| match precision {
        Precision::F16 => FlatSamples::F16(Vec::new()),
        _ => FlatSamples::F32(Vec::new()),
    };
    let mut channels: Vec<AnyChannel<S>> = (0..k)
        .flat_map(|i| (0..3).map(move |c| (i, c)))
        .map(|(i, c)| AnyChannel::new(channel_name(i, c).as_str(), wrap(none(precision))))
        .collect();
    if depth {
        channels.push(AnyChannel::new("Z", wrap(none(Precision::F32))));
    }
    channels
}

fn attributes(meta: &Metadata, precision: Precision) -> LayerAttributes {
    let mut attrs = LayerAttributes::default();
    let other = &mut attrs.other;
    other.insert(
        Text::new_or_panic("relit.formatVersion"),
        AttributeValue::I32(meta.format_version as i32),
    );
    other.insert(
        Text::new_or_panic("relit.basis"),
        text(&ascii_json(&meta.basis)),
    );
    other.insert(
        Text::new_or_panic("relit.colorSpace"),
        text(meta.color_space.name()),
    );
    other.insert(
        Text::new_or_panic("relit.lightFrame"),
        text(&ascii_json(&meta.light_frame)),
    );
    other.insert(
        Text::new_or_panic("relit.projection"),
        text(&ascii_json(&meta.projection)),
    );
    other.insert(Text::new_or_panic("relit.storage"), text(precision.name()));
    if let Some(fit) = &meta.fit {
        other.insert(Text::new_or_panic("relit.fit"), text(&ascii_json(fit)));
    }
    if let Some(bake) = &meta.bake {
        other.insert(Text::new_or_panic("relit.bake"), text(&ascii_json(bake)));
    }
    if let Some(camera) = &meta.camera {
        other.insert(
            Text::new_or_panic("relit.camera"),
            text(&ascii_json(camera)),
        );
    }
    attrs
}

/// A plane's samples in `precision` (f16 or f32).
fn flat_samples(precision: Precision, plane: &[f32]) -> FlatSamples {
    match precision {
        Precision::F16 => {
            let mut bits = vec![0u16; plane.len()];
            crate::storage::to_f16_bits(plane, &mut bits);
            FlatSamples::F16(bits.into_iter().map(f16::from_bits).collect())
        }
        _ => FlatSamples::F32(plane.to_vec()),
    }
}

/// Side of the tiles of a tiled file unless one is named.
pub const DEFAULT_TILE: usize = 256;

/// The tile sides a tiled file may have.
pub const TILE_SIDES: std::ops::RangeInclusive<usize> = 16..=4096;

use crate::maps::halve;
pub use crate::maps::{halved, mip_sizes};

/// Write `image` as a tiled OpenEXR file (`tile`-pixel tiles) with mip levels
/// (MIPMAP_LEVELS, rounding down): each level holds the 2×2 means of the level above —
/// relighting is linear in the coefficients, so a level relights to the 2×2 means of
/// the finer level's frame — and the depth the mean of the hit samples. A reader that
/// knows nothing of levels ([`read`]) reads level 0 as any relit file; [`read_region`]
/// reads the tiles of one region of one level.
pub fn write_tiled(
    path: &Path,
    image: &RelightableImage,
    precision: Precision,
    tile: usize,
) -> Result<()> {
    use rayon::prelude::*;
    let precision = precision.require(&[Precision::F32, Precision::F16], "OpenEXR")?;
    check_tile_side(tile)?;
    let maps = &image.maps;
    let sizes = mip_sizes(maps.width, maps.height);
    let levels = |plane: &[f32], precision: Precision, keep: fn(f32) -> bool| {
        let mut data = vec![flat_samples(precision, plane)];
        let mut current: Option<Vec<f32>> = None;
        for pair in sizes.windows(2) {
            let next = halve(current.as_deref().unwrap_or(plane), pair[0], pair[1], keep);
            data.push(flat_samples(precision, &next));
            current = Some(next);
        }
        Levels::Mip {
            rounding_mode: RoundingMode::Down,
            level_data: data,
        }
    };
    let mut channels: Vec<AnyChannel<Levels<FlatSamples>>> = (0..3 * maps.k)
        .into_par_iter()
        .map(|j| {
            let (i, c) = (j / 3, j % 3);
            let l = levels(maps.plane(i, c), precision, f32::is_finite);
            (channel_name(i, c), l)
        })
        .collect::<Vec<_>>()
        .into_iter()
        .map(|(name, l)| AnyChannel::new(name.as_str(), l))
        .collect();
    if let Some(depth) = &image.depth {
        let hit: fn(f32) -> bool = |d| d.is_finite() && d > 0.0;
        channels.push(AnyChannel::new("Z", levels(depth, Precision::F32, hit)));
    }
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::Tiles(Vec2(tile, tile)),
        // Increasing: the blocks in one order, so the same maps make the same bytes
        // (unspecified lets the writer put them down as its threads finish).
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        (maps.width, maps.height),
        attributes(&image.meta, precision),
        encoding,
        AnyChannels::sort(channels.into()),
    );
    let exr_image = Image::from_layer(layer);
    write_atomically(path, |out| {
        exr_image
            .write()
            .to_buffered(out)
            .map_err(|e| exr_error(path, "write", e))
    })
}

/// Refuse tile sides outside [`TILE_SIDES`].
fn check_tile_side(tile: usize) -> Result<()> {
    if !TILE_SIDES.contains(&tile) {
        return Err(Error::invalid(format!(
            "EXR tiles are {} to {} pixels a side, not {tile}",
            TILE_SIDES.start(),
            TILE_SIDES.end()
        )));
    }
    Ok(())
}

/// The level sizes of a tiled file with mip levels (level 0 first), or `None` for any
/// other relit file (scan lines, or tiles of one level).
pub fn tiled_levels(path: &Path) -> Result<Option<Vec<(usize, usize)>>> {
    Ok(header_levels(&first_header(path)?))
}

/// The level sizes of any relit EXR file: a tiled file's mip levels, or level 0 alone.
pub fn levels(path: &Path) -> Result<Vec<(usize, usize)>> {
    Ok(level_sizes(&first_header(path)?))
}

/// How the file's blocks are laid out, in words: `scan lines (16 a block)`, or
/// `tiles 256×16`, with its mip levels when it has them.
pub fn describe_layout(path: &Path) -> Result<String> {
    let header = first_header(path)?;
    Ok(match header.blocks {
        exr::meta::BlockDescription::ScanLines => format!(
            "scan lines ({} a block)",
            header.compression.scan_lines_per_block()
        ),
        exr::meta::BlockDescription::Tiles(tiles) => {
            let levels = level_sizes(&header);
            let (w, h) = levels[levels.len() - 1];
            let pyramid = match levels.len() {
                1 => String::new(),
                n => format!(", {n} mip levels down to {w}×{h}"),
            };
            format!("tiles {}×{}{pyramid}", tiles.tile_size.0, tiles.tile_size.1)
        }
    })
}

/// What a relit EXR's header says of it, read without any of its blocks.
#[derive(Clone, Debug)]
pub struct FileShape {
    pub meta: Metadata,
    /// Level 0's size.
    pub width: usize,
    pub height: usize,
    /// Coefficients per colour channel.
    pub k: usize,
    /// Whether it has a depth channel.
    pub depth: bool,
    /// Its level sizes: a tiled file's mip levels, or level 0 alone.
    pub levels: Vec<(usize, usize)>,
}

/// The metadata, size, coefficients, depth and levels of the relit EXR at `path`: what
/// `relit info`, the tiled viewer and the streaming writers need before they read the
/// pixels. Its header, offset table and first pixel are read, so that a truncated or
/// damaged file is refused here as any reader refuses it.
pub fn read_shape(path: &Path) -> Result<FileShape> {
    let probe = read_region_with(path, 0, (0, 0, 1, 1), true)?;
    let levels = probe.levels;
    let image = probe.image;
    Ok(FileShape {
        width: levels[0].0,
        height: levels[0].1,
        k: image.maps.k,
        depth: image.depth.is_some(),
        meta: image.meta,
        levels,
    })
}

/// The header of the file's first layer, read alone.
fn first_header(path: &Path) -> Result<exr::meta::header::Header> {
    let meta =
        exr::meta::MetaData::read_from_file(path, false).map_err(|e| exr_error(path, "read", e))?;
    meta.headers
        .into_iter()
        .next()
        .ok_or_else(|| Error::parse(format!("{}: the EXR file has no layer", path.display())))
}

/// The level sizes of a header: its mip levels, or level 0 alone.
fn level_sizes(header: &exr::meta::header::Header) -> Vec<(usize, usize)> {
    header_levels(header)
        .unwrap_or_else(|| vec![(header.layer_size.width(), header.layer_size.height())])
}

/// The level sizes of a header of tiles with mip levels rounding down, else `None`.
fn header_levels(header: &exr::meta::header::Header) -> Option<Vec<(usize, usize)>> {
    match header.blocks {
        exr::meta::BlockDescription::Tiles(TileDescription {
            level_mode: LevelMode::MipMap,
            rounding_mode: RoundingMode::Down,
            ..
        }) => Some(mip_sizes(
            header.layer_size.width(),
            header.layer_size.height(),
        )),
        _ => None,
    }
}

/// A region of one mip level of a tiled file ([`read_region`]) and what reading it took.
#[derive(Debug)]
pub struct RegionRead {
    /// The region's maps, and its depth when asked for ([`read_region_with`]).
    pub image: RelightableImage,
    /// The level's size, and every level's (level 0 first).
    pub level_size: (usize, usize),
    pub levels: Vec<(usize, usize)>,
    /// Bytes the read pulled from the file, and the file's size.
    pub bytes_read: u64,
    pub file_bytes: u64,
}

/// A reader that counts the bytes it reads.
struct Counted<R> {
    inner: R,
    read: u64,
}

impl<R: std::io::Read> std::io::Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        Ok(n)
    }
}

impl<R: std::io::Seek> std::io::Seek for Counted<R> {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        self.inner.seek(to)
    }
}

/// Read `rect` (`x, y, width, height` in the level's pixels) of mip level `level` of a
/// tiled relit file ([`write_tiled`]), or of level 0 of any relit file (a fit's scan
/// lines or tiles): only the header (once), the offset tables and the blocks the region
/// touches are read and decompressed.
pub fn read_region(
    path: &Path,
    level: usize,
    rect: (usize, usize, usize, usize),
) -> Result<RegionRead> {
    read_region_with(path, level, rect, false)
}

/// [`read_region`], and with `depth` the region's depth too where the file has one (as
/// stored, as [`read`] gives it): what a tiled viewer needs, which holds the depth whole
/// but the coefficients a tile at a time.
pub fn read_region_with(
    path: &Path,
    level: usize,
    rect: (usize, usize, usize, usize),
    depth: bool,
) -> Result<RegionRead> {
    use exr::block::reader::ChunksReader;
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, "read", e))?;
    let file_bytes = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut counted = std::io::BufReader::new(Counted {
        inner: file,
        read: 0,
    });
    let reader = exr::block::read(&mut counted, false).map_err(|e| exr_error(path, "read", e))?;
    let header =
        reader.headers().first().cloned().ok_or_else(|| {
            Error::parse(format!("{}: the EXR file has no layer", path.display()))
        })?;
    let sizes = level_sizes(&header);
    let &(lw, lh) = sizes.get(level).ok_or_else(|| {
        Error::invalid(if sizes.len() == 1 {
            format!(
                "{} has level 0 only, not {level} (write mip levels with `relit convert --mip-tiles`)",
                path.display()
            )
        } else {
            format!(
                "{} has levels 0 to {}, not {level}",
                path.display(),
                sizes.len() - 1
            )
        })
    })?;
    let (rx, ry, rw, rh) = rect;
    if rw == 0 || rh == 0 || rx + rw > lw || ry + rh > lh {
        return Err(Error::invalid(format!(
            "the region {rw}×{rh} at ({rx}, {ry}) is not inside level {level} ({lw}×{lh})"
        )));
    }
    let (meta, k) = parse_header(path, &header)?;
    let values = rw.checked_mul(rh).and_then(|n| n.checked_mul(3 * k));
    let mut maps = CoefficientMaps {
        width: rw,
        height: rh,
        k,
        data: try_zeroed(values, &format!("{}: the region's maps", path.display()))?,
    };
    let targets: Vec<Option<usize>> = header
        .channels
        .list
        .iter()
        .map(|c| parse_channel_name(&c.name.to_string()).map(|(i, c)| 3 * i + c))
        .collect();
    if let Some((i, c)) = (0..3 * k)
        .map(|j| (j / 3, j % 3))
        .find(|&(i, c)| !targets.contains(&Some(3 * i + c)))
    {
        return Err(Error::parse(format!(
            "{}: not a relit file (channel {} is missing)",
            path.display(),
            channel_name(i, c)
        )));
    }
    let n = rw * rh;
    let z = header
        .channels
        .list
        .iter()
        .position(|c| c.name.to_string() == "Z")
        .filter(|_| depth);
    let mut depth_values = match z {
        Some(_) => try_zeroed(Some(n), &format!("{}: the region's depth", path.display()))?,
        None => Vec::new(),
    };
    let mut samples: Vec<f32> = Vec::new();
    reader
        .filter_chunks(false, |_, _, block| {
            let (bx, by) = (block.pixel_position.x(), block.pixel_position.y());
            let (bw, bh) = (block.pixel_size.width(), block.pixel_size.height());
            block.layer == 0
                && block.level == exr::math::Vec2(level, level)
                && bx < rx + rw
                && rx < bx + bw
                && by < ry + rh
                && ry < by + bh
        })
        .map_err(|e| exr_error(path, "read", e))?
        .decompress_parallel(false, |meta, block| {
            let channels = &meta.headers[0].channels;
            for line in block.lines(channels) {
                let is_depth = Some(line.location.channel) == z;
                let Some(j) = targets[line.location.channel]
                    .filter(|&j| j < 3 * k)
                    .or(is_depth.then_some(0))
                else {
                    continue;
                };
                let (x0, y) = (line.location.position.x(), line.location.position.y());
                if y < ry || y >= ry + rh {
                    continue;
                }
                let (from, to) = (x0.max(rx), (x0 + line.location.sample_count).min(rx + rw));
                if from >= to {
                    continue;
                }
                line_samples(
                    &line,
                    channels.list[line.location.channel].sample_type,
                    &mut samples,
                )?;
                let (source, at) = (&samples[from - x0..to - x0], (y - ry) * rw + (from - rx));
                if is_depth {
                    depth_values[at..at + (to - from)].copy_from_slice(source);
                } else {
                    maps.data[j * n + at..j * n + at + (to - from)].copy_from_slice(source);
                }
            }
            Ok(())
        })
        .map_err(|e| exr_error(path, "read", e))?;
    let bytes_read = counted.get_ref().read;
    Ok(RegionRead {
        image: RelightableImage {
            meta,
            maps,
            depth: z.map(|_| depth_values),
        },
        level_size: (lw, lh),
        levels: sizes,
        bytes_read,
        file_bytes,
    })
}

fn text_attr(attrs: &LayerAttributes, name: &str) -> Option<String> {
    match attrs.other.get(&Text::new_or_panic(name))? {
        AttributeValue::Text(t) => Some(t.to_string()),
        _ => None,
    }
}

fn parse_json<T: serde::de::DeserializeOwned>(path: &Path, name: &str, s: &str) -> Result<T> {
    serde_json::from_str(s)
        .map_err(|e| Error::parse(format!("{}: attribute {name}: {e}", path.display())))
}

/// Read a relightable image written by [`write`].
pub fn read(path: &Path) -> Result<RelightableImage> {
    Ok(read_planes(path, Sink::F32)?.0)
}

/// Read a relightable file straight into compact planes (`precision` f16 or u8), for a
/// relighter that never holds the f32 maps: the returned image's `maps.data` is empty
/// (sizes, metadata and depth are there). f16 rounds each value to half (exact for
/// half-float files). u8 reads the file twice, first for each plane's range, then
/// decoding straight into 8 bits with that plane's coding: the same bytes as
/// quantising the f32 maps ([`CompactPlanes::from_maps`]). Peak memory: the compact
/// planes plus the blocks in flight.
pub fn read_compact(
    path: &Path,
    precision: Precision,
) -> Result<(RelightableImage, CompactPlanes)> {
    let precision = precision.require(&[Precision::F16, Precision::U8], "read_compact")?;
    let (image, sink) = match precision {
        Precision::F16 => read_planes(path, Sink::F16(Vec::new()))?,
        _ => {
            let ranges = match read_planes(path, Sink::Ranges(Vec::new()))?.1 {
                Sink::Ranges(r) => r,
                _ => unreachable!("a range scan returns ranges"),
            };
            let coding = ranges.into_iter().map(PlaneCoding::u8).collect();
            read_planes(
                path,
                Sink::U8 {
                    data: Vec::new(),
                    coding,
                },
            )?
        }
    };
    let (pixels, count) = (image.maps.pixels(), 3 * image.maps.k);
    let planes = match sink {
        Sink::F16(bits) => CompactPlanes::from_f16_bits(bits, pixels, count),
        Sink::U8 { data, coding } => CompactPlanes::from_u8(data, coding, pixels, count),
        _ => None,
    }
    .expect("the planes were sized from the header");
    Ok((image, planes))
}

/// Where the coefficient planes are decoded to.
enum Sink {
    /// The maps' f32 values (`RelightableImage::maps.data`).
    F32,
    /// Half-float bits (allocated by the reader).
    F16(Vec<u16>),
    /// Only each plane's finite range (allocated by the reader).
    Ranges(Vec<FiniteRange>),
    /// 8 bits in the given coding per plane (`data` allocated by the reader).
    U8 {
        data: Vec<u8>,
        coding: Vec<PlaneCoding>,
    },
}

/// A zeroed vector of `len` values, or an error naming what needed it when the memory
/// cannot be had: sizes come from a file's header, which must not abort the process.
pub(crate) fn try_zeroed<T: Copy + Default>(len: Option<usize>, what: &str) -> Result<Vec<T>> {
    let bytes = len.and_then(|n| n.checked_mul(std::mem::size_of::<T>()));
    let (Some(len), Some(bytes)) = (len, bytes) else {
        return Err(Error::invalid(format!("{what}: the size overflows")));
    };
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| {
        Error::new(
            ErrorKind::InvalidInput,
            format!(
                "{what} need {:.1} GiB, which could not be allocated",
                bytes as f64 / (1u64 << 30) as f64
            ),
        )
    })?;
    v.resize(len, T::default());
    Ok(v)
}

fn read_planes(path: &Path, mut sink: Sink) -> Result<(RelightableImage, Sink)> {
    if !path.is_file() {
        return Err(Error::new(
            ErrorKind::Io,
            format!("{} does not exist", path.display()),
        ));
    }
    // Block by block: each decompressed block goes straight into its planes, so reading
    // holds the maps once (plus the blocks in flight), not a second copy of every channel.
    use exr::block::reader::ChunksReader;
    let file = std::fs::File::open(path)
        .map_err(|e| Error::new(ErrorKind::Io, format!("{}: {e}", path.display())))?;
    let reader = exr::block::read(std::io::BufReader::new(file), false)
        .map_err(|e| exr_error(path, "read", e))?;
    let header =
        reader.headers().first().cloned().ok_or_else(|| {
            Error::parse(format!("{}: the EXR file has no layer", path.display()))
        })?;
    let (meta, k) = parse_header(path, &header)?;
    let bad = |what: &str| Error::parse(format!("{}: not a relit file ({what})", path.display()));
    let (w, h) = (header.layer_size.width(), header.layer_size.height());
    let values = w.checked_mul(h).and_then(|n| n.checked_mul(3 * k));
    let what = format!("{}: the {w}×{h} maps of {k} coefficients", path.display());
    let mut maps = CoefficientMaps {
        width: w,
        height: h,
        k,
        data: Vec::new(),
    };
    match &mut sink {
        Sink::F32 => maps.data = try_zeroed(values, &what)?,
        Sink::F16(bits) => *bits = try_zeroed(values, &what)?,
        Sink::Ranges(ranges) => *ranges = vec![FiniteRange::EMPTY; 3 * k],
        Sink::U8 { data, coding } => {
            if coding.len() != 3 * k {
                return Err(Error::invalid(format!(
                    "{}: the file changed between its two reads",
                    path.display()
                )));
            }
            *data = try_zeroed(values, &what)?;
        }
    }
    let mut found = vec![false; 3 * k];
    let mut depth: Option<Vec<f32>> = None;
    // Where each channel of the file goes: plane 3i + c, the depth map, or nowhere.
    #[derive(Clone, Copy)]
    enum Target {
        Plane(usize),
        Depth,
        Skip,
    }
    let mut targets = Vec::new();
    for channel in &header.channels.list {
        let name = channel.name.to_string();
        targets.push(if name == "Z" {
            depth = Some(try_zeroed(
                Some(w * h),
                &format!("{}: the depth map", path.display()),
            )?);
            Target::Depth
        } else if let Some((i, c)) = parse_channel_name(&name) {
            if i >= k {
                return Err(bad(&format!(
                    "channel {name} beyond the basis' {k} coefficients"
                )));
            }
            found[3 * i + c] = true;
            Target::Plane(3 * i + c)
        } else {
            Target::Skip
        });
    }
    let n = w * h;
    let mut samples: Vec<f32> = Vec::new();
    reader
        .all_chunks(false)
        .map_err(|e| exr_error(path, "read", e))?
        .decompress_parallel(false, |meta, block| {
            if block.index.layer != 0 || block.index.level != exr::math::Vec2(0, 0) {
                return Ok(());
            }
            let channels = &meta.headers[0].channels;
            for line in block.lines(channels) {
                let at = line.location.position;
                let start = at.y() * w + at.x();
                let target = targets[line.location.channel];
                if matches!(target, Target::Skip)
                    || (matches!(target, Target::Depth) && matches!(sink, Sink::Ranges(_)))
                {
                    continue;
                }
                line_samples(
                    &line,
                    channels.list[line.location.channel].sample_type,
                    &mut samples,
                )?;
                let span = start..start + samples.len();
                let j = match target {
                    Target::Depth => {
                        if let Some(d) = depth.as_mut() {
                            d[span].copy_from_slice(&samples);
                        }
                        continue;
                    }
                    Target::Plane(j) => j,
                    Target::Skip => continue,
                };
                let at = j * n + span.start..j * n + span.end;
                match &mut sink {
                    Sink::F32 => maps.data[at].copy_from_slice(&samples),
                    Sink::F16(bits) => {
                        crate::storage::to_f16_bits(&samples, &mut bits[at]);
                    }
                    Sink::Ranges(ranges) => {
                        ranges[j] = samples.iter().copied().fold(ranges[j], FiniteRange::with);
                    }
                    Sink::U8 { data, coding } => {
                        for (d, &v) in data[at].iter_mut().zip(&samples) {
                            *d = coding[j].quantize(v);
                        }
                    }
                }
            }
            Ok(())
        })
        .map_err(|e| exr_error(path, "read", e))?;
    if let Some(missing) = found.iter().position(|f| !f) {
        return Err(bad(&format!(
            "channel {} is missing",
            channel_name(missing / 3, missing % 3)
        )));
    }
    Ok((RelightableImage { meta, maps, depth }, sink))
}

/// The `relit.*` metadata of a file's header and the basis' coefficient count.
fn parse_header(path: &Path, header: &exr::meta::header::Header) -> Result<(Metadata, usize)> {
    let attrs = &header.own_attributes;
    let bad = |what: &str| Error::parse(format!("{}: not a relit file ({what})", path.display()));
    let version = match attrs.other.get(&Text::new_or_panic("relit.formatVersion")) {
        Some(AttributeValue::I32(v)) => *v as u32,
        _ => return Err(bad("no relit.formatVersion attribute")),
    };
    if version > FORMAT_VERSION {
        return Err(Error::parse(format!(
            "{}: written by a newer relit (format {version}; this build reads up to {FORMAT_VERSION})",
            path.display()
        )));
    }
    let basis: BasisSpec = parse_json(
        path,
        "relit.basis",
        &text_attr(attrs, "relit.basis").ok_or_else(|| bad("no relit.basis"))?,
    )?;
    basis
        .build()
        .map_err(|e| Error::parse(format!("{}: relit.basis: {e}", path.display())))?;
    let color_space = match text_attr(attrs, "relit.colorSpace").as_deref() {
        Some("linear") | None => MapSpace::Linear,
        Some("srgb") => MapSpace::Srgb,
        Some(other) => {
            return Err(Error::parse(format!(
                "{}: unknown relit.colorSpace `{other}`",
                path.display()
            )))
        }
    };
    let light_frame = match text_attr(attrs, "relit.lightFrame") {
        Some(s) => parse_json(path, "relit.lightFrame", &s)?,
        None => crate::maps::LIGHT_FRAME.to_string(),
    };
    let projection = match text_attr(attrs, "relit.projection") {
        Some(s) => parse_json(path, "relit.projection", &s)?,
        None => Default::default(),
    };
    let camera = match text_attr(attrs, "relit.camera") {
        Some(s) => Some(parse_json(path, "relit.camera", &s)?),
        None => None,
    };
    let fit: Option<FitInfo> = match text_attr(attrs, "relit.fit") {
        Some(s) => Some(parse_json(path, "relit.fit", &s)?),
        None => None,
    };
    let bake: Option<BakeInfo> = match text_attr(attrs, "relit.bake") {
        Some(s) => Some(parse_json(path, "relit.bake", &s)?),
        None => None,
    };
    let k = basis.build()?.len();
    Ok((
        Metadata {
            format_version: version,
            basis,
            color_space,
            light_frame,
            projection,
            camera,
            fit,
            bake,
        },
        k,
    ))
}

/// One line's samples as `f32`, into `out`.
fn line_samples(
    line: &exr::block::lines::LineRef,
    sample_type: SampleType,
    out: &mut Vec<f32>,
) -> exr::error::UnitResult {
    out.clear();
    match sample_type {
        SampleType::F16 => {
            for v in line.read_samples::<f16>() {
                out.push(v?.to_f32());
            }
        }
        SampleType::F32 => {
            out.resize(line.location.sample_count, 0.0);
            line.read_samples_into_slice(out)?;
        }
        SampleType::U32 => {
            for v in line.read_samples::<u32>() {
                out.push(v? as f32);
            }
        }
    }
    Ok(())
}

fn parse_channel_name(name: &str) -> Option<(usize, usize)> {
    let rest = name.strip_prefix('c')?;
    let (num, chan) = rest.split_once('.')?;
    let i: usize = num.parse().ok()?;
    let c = CHANNEL_NAMES.iter().position(|&n| n == chan)?;
    Some((i, c))
}

/// Read the header attributes only, for `relit info` on large files.
pub fn read_metadata_summary(path: &Path) -> Result<Vec<(String, String)>> {
    let meta =
        exr::meta::MetaData::read_from_file(path, false).map_err(|e| exr_error(path, "read", e))?;
    let mut out = Vec::new();
    for header in &meta.headers {
        out.push((
            "size".into(),
            format!(
                "{}×{}",
                header.layer_size.width(),
                header.layer_size.height()
            ),
        ));
        out.push(("channels".into(), header.channels.list.len().to_string()));
        out.push(("compression".into(), format!("{:?}", header.compression)));
        let mut names: Vec<_> = header.own_attributes.other.keys().collect();
        names.sort_by_key(|n| n.to_string());
        for name in names {
            let value = match &header.own_attributes.other[name] {
                AttributeValue::Text(t) => t.to_string(),
                other => format!("{other:?}"),
            };
            out.push((name.to_string(), value));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Projection;
    use crate::storage::{f16_bits, f16_value};

    #[test]
    fn a_file_written_from_pieces_equals_the_file_written_whole() {
        // 37 rows: blocks of 16 across strips of 1, 5, 16 and 20 rows, and a short last
        // block; 600 pixels at K = 25 are tiles (256 or 128 wide, 16 high), cut into
        // pieces of 1, 5 and 16 rows, and a narrower last column.
        let dir = tempfile::tempdir().unwrap();
        for (w, h, k) in [(9, 37, 4), (600, 37, 25)] {
            let mut image = sample_image(k);
            let mut maps = CoefficientMaps::zeros(w, h, k);
            for (i, v) in maps.data.iter_mut().enumerate() {
                *v = ((i * 7919) % 1000) as f32 / 137.0 - 3.0;
            }
            image.maps = maps;
            for depth in [
                None,
                Some((0..w * h).map(|p| 1.0 + p as f32).collect::<Vec<f32>>()),
            ] {
                image.depth = depth.clone();
                for precision in [Precision::F16, Precision::F32] {
                    let tiles = ExrStream::tiles(w, k, precision, depth.is_some());
                    assert_eq!(tiles.is_some(), w == 600, "{w} {precision:?}");
                    let whole = dir.path().join("whole.exr");
                    write(&whole, &image, precision).unwrap();
                    for rows in [1, 5, 16, 20] {
                        let mut stream = ExrStream::new(w, h, k, precision, depth.clone()).unwrap();
                        for piece in pieces(w, h, tiles, rows) {
                            let mut part = CoefficientMaps::zeros(piece.width, piece.height, k);
                            for plane in 0..3 * k {
                                let source = &image.maps.data[plane * w * h..][..w * h];
                                let values = &mut part.data[plane * piece.pixels()..];
                                for p in 0..piece.pixels() {
                                    values[p] = source[piece.band_pixel(p, w)];
                                }
                            }
                            stream.piece(piece, part).unwrap();
                        }
                        let streamed = dir.path().join("streamed.exr");
                        stream.finish(&streamed, &image.meta).unwrap();
                        // Blocks compressed in parallel may reach the file in another
                        // order (its line order is unspecified), so compare what a
                        // reader gets.
                        let (a, b) = (read(&whole).unwrap(), read(&streamed).unwrap());
                        let bits = |m: &CoefficientMaps| {
                            m.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                        };
                        let what = format!(
                            "{w}×{h}, {precision:?}, depth {}, pieces of {rows} rows",
                            depth.is_some()
                        );
                        assert!(
                            bits(&a.maps) == bits(&image_rounded(&image, precision)),
                            "{what}"
                        );
                        assert!(bits(&a.maps) == bits(&b.maps), "{what}");
                        assert_eq!(a.depth, b.depth, "{what}");
                        assert_eq!(a.meta, b.meta, "{what}");
                        assert_eq!(
                            std::fs::metadata(&whole).unwrap().len(),
                            std::fs::metadata(&streamed).unwrap().len(),
                            "{what}"
                        );
                    }
                }
            }
        }
    }

    /// The maps of `image` as `precision` stores them.
    fn image_rounded(image: &RelightableImage, precision: Precision) -> CoefficientMaps {
        let mut maps = image.maps.clone();
        if precision == Precision::F16 {
            for v in &mut maps.data {
                *v = half::f16::from_f32(*v).to_f32();
            }
        }
        maps
    }

    /// Pieces of a `w × h` image as a streamed fit makes them: strips of `rows` rows, or
    /// each of `tiles` cut into pieces of at most `rows` rows.
    fn pieces(w: usize, h: usize, tiles: Option<(usize, usize)>, rows: usize) -> Vec<Piece> {
        let (tw, th) = tiles.unwrap_or((w, rows));
        let mut out = Vec::new();
        for ty in (0..h).step_by(th) {
            for x0 in (0..w).step_by(tw) {
                let bottom = (ty + th).min(h);
                for y0 in (ty..bottom).step_by(rows) {
                    out.push(Piece {
                        x0,
                        y0,
                        width: tw.min(w - x0),
                        height: rows.min(bottom - y0),
                    });
                }
            }
        }
        out
    }

    #[test]
    fn a_fit_streamed_to_a_file_equals_the_fit_held_whole() {
        // Strips of one row (16-pixel tiles span several), both objectives, a shard, both
        // precisions, and a capture wide enough for a tiled file (pieces of one row of a
        // tile): the file streamed as the pieces are solved reads back as the whole maps
        // written at once, with the same metadata but the fit's time.
        let narrow = crate::synth::BumpyPlane {
            width: 70,
            height: 37,
        }
        .capture(&crate::sphere::hemisphere_fibonacci(30));
        let wide = crate::synth::BumpyPlane {
            width: 600,
            height: 20,
        }
        .capture(&crate::sphere::hemisphere_fibonacci(30));
        let dir = tempfile::tempdir().unwrap();
        let bits = |m: &CoefficientMaps| m.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        use crate::fit::Objective::{Linear, Perceptual};
        for (capture, basis, objective, shard, precision) in [
            (&narrow, "sh:9", Perceptual, None, Precision::F16),
            (&narrow, "sh:9", Linear, None, Precision::F32),
            (&narrow, "sh:9", Perceptual, Some((1, 3)), Precision::F32),
            (&wide, "sh:25", Perceptual, None, Precision::F16),
            (&wide, "sh:25", Linear, Some((0, 2)), Precision::F32),
        ] {
            let k = crate::basis::BasisSpec::named(basis)
                .unwrap()
                .build()
                .unwrap()
                .len();
            let tiled = ExrStream::tiles(capture.width, k, precision, false).is_some();
            assert_eq!(tiled, capture.width == 600);
            let mut opts = crate::fit::FitOptions {
                basis: crate::fit::BasisRequest::parse(basis).unwrap(),
                objective,
                lambda: crate::fit::Lambda::Fixed(1e-4),
                ..crate::fit::FitOptions::default()
            };
            opts.piece_bytes = 1;
            opts.shard = shard;
            let whole = crate::fit::fit(capture, &opts, &crate::progress::Silent).unwrap();
            let path = dir.path().join("streamed.exr");
            let (meta, report) =
                fit_to_exr(capture, &opts, &crate::progress::Silent, &path, precision).unwrap();
            let back = crate::codec::exr::read(&path).unwrap();
            let mut expected = whole.image.clone();
            expected.meta.fit.as_mut().unwrap().seconds = meta.fit.as_ref().unwrap().seconds;
            let reference = dir.path().join("whole.exr");
            crate::codec::exr::write(&reference, &expected, precision).unwrap();
            let want = crate::codec::exr::read(&reference).unwrap();
            let what = format!(
                "{} {basis} {objective:?} {shard:?} {precision:?}",
                capture.width
            );
            assert!(bits(&back.maps) == bits(&want.maps), "{what}");
            assert_eq!(back.depth, want.depth, "{what}");
            assert_eq!(back.meta, want.meta, "{what}");
            assert_eq!(report.psnr_srgb8, whole.report.psnr_srgb8, "{what}");
            assert_eq!(report.rmse_linear, whole.report.rmse_linear, "{what}");
            assert_eq!(report.objective, objective, "{what}");
        }
    }

    /// A synthetic capture written as JPEG photographs with an `.lp`, opened again.
    fn jpeg_capture(dir: &std::path::Path, width: usize, height: usize) -> crate::capture::Capture {
        let synthetic = crate::synth::BumpyPlane { width, height }
            .capture(&crate::sphere::hemisphere_fibonacci(30));
        let names: Vec<String> = (0..synthetic.len())
            .map(|j| {
                let name = format!("image{j:02}.jpg");
                let img = synthetic.load(j).unwrap();
                crate::image::save(&dir.join(&name), &img, 0.0).unwrap();
                name
            })
            .collect();
        let lp = dir.join("dirs.lp");
        std::fs::write(
            &lp,
            crate::capture::lp::format(&names, &synthetic.directions()),
        )
        .unwrap();
        crate::capture::Capture::open(&lp).unwrap()
    }

    #[test]
    fn photographs_read_once_fit_as_when_read_twice() {
        // A fit streamed to a file reads a JPEG capture's images once — the subsample
        // and the spill file of codes together — before it chooses anything; a fit held
        // whole reads the subsample first and the images after the choice, as values.
        // Both give the same maps bit for bit: narrow (scan lines for every K), wide with
        // candidates whose files differ (scan lines at K = 4 and 9, tiles at 16 and 25:
        // the spill file in tiles, a choice of scan lines solved in strips read across
        // them), shards, and a data-driven basis fixed.
        let dir = tempfile::tempdir().unwrap();
        let narrow_dir = dir.path().join("narrow");
        let wide_dir = dir.path().join("wide");
        std::fs::create_dir_all(&narrow_dir).unwrap();
        std::fs::create_dir_all(&wide_dir).unwrap();
        let narrow = jpeg_capture(&narrow_dir, 70, 37);
        let wide = jpeg_capture(&wide_dir, 600, 20);
        assert!(narrow.eight_bit_codes() && wide.eight_bit_codes());
        assert_ne!(
            ExrStream::tiles(600, 4, Precision::F16, false),
            ExrStream::tiles(600, 25, Precision::F16, false)
        );
        let bits = |m: &CoefficientMaps| m.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let candidates = |list: &[&str]| {
            list.iter()
                .map(|c| crate::basis::BasisChoice::parse(c).unwrap())
                .collect::<Vec<_>>()
        };
        let mut across = 0;
        for (capture, basis, list, shard) in [
            (&narrow, "auto", &["sh:9", "rbf:9", "hsh:16"][..], None),
            (&narrow, "rbf:9", &[][..], Some((1, 3))),
            (&wide, "auto", &["sh:4", "sg:25"][..], None),
            (&wide, "auto", &["sh:4", "ptm:6", "sh:9"][..], None),
            (&wide, "auto", &["sh:9", "sh:16"][..], Some((0, 2))),
        ] {
            let mut opts = crate::fit::FitOptions {
                basis: crate::fit::BasisRequest::parse(basis).unwrap(),
                candidates: candidates(list),
                ..crate::fit::FitOptions::default()
            };
            // Pieces of one row of every image (whole rows fit a piece).
            opts.piece_bytes = capture.width * 12 * capture.len();
            opts.shard = shard;
            let whole = crate::fit::fit(capture, &opts, &crate::progress::Silent).unwrap();
            let path = dir.path().join("streamed.exr");
            let (meta, report) = fit_to_exr(
                capture,
                &opts,
                &crate::progress::Silent,
                &path,
                Precision::F32,
            )
            .unwrap();
            let what = format!("{} {basis} {shard:?}", capture.width);
            let stages: Vec<&str> = report.stages.iter().map(|s| s.name).collect();
            assert_eq!(stages[0], "images", "{what}: read once, first ({stages:?})");
            assert!(!stages.contains(&"subsample"), "{what}");
            let rows = band_rows(capture.height, shard);
            let codes = capture.width * rows * 3 * capture.len();
            assert_eq!(report.spill_bytes, codes as u64, "{what}: codes");
            let back = crate::codec::exr::read(&path).unwrap();
            assert_eq!(
                back.meta.basis, whole.image.meta.basis,
                "{what}: the same choice"
            );
            assert_eq!(meta.basis, whole.image.meta.basis, "{what}");
            // Whether the pieces were read across the spill file's tiles: its tiles are
            // the narrowest of any candidate's file, the chosen one's may differ.
            let tiles_of = |k: usize| ExrStream::tiles(capture.width, k, Precision::F32, false);
            let spilled = opts.candidates.iter().filter_map(|c| tiles_of(c.k)).min();
            across += usize::from(!list.is_empty() && tiles_of(back.maps.k) != spilled);
            assert!(bits(&back.maps) == bits(&whole.image.maps), "{what}");
            assert_eq!(report.psnr_srgb8, whole.report.psnr_srgb8, "{what}");
        }
        assert!(
            across > 0,
            "a choice whose file's tiles are not the spill file's"
        );
    }

    #[test]
    fn a_photographs_codes_stand_for_the_values_it_is_read_as() {
        // What the spill file of codes turns back into values: bit for bit what
        // `read_parts` gives, for a light of unit and of coloured intensity, in linear
        // radiance and display values.
        let dir = tempfile::tempdir().unwrap();
        let mut capture = jpeg_capture(dir.path(), 23, 11);
        capture.lights[1].intensity = [2.5, 0.7, 1.3];
        let pixels = [0, 5, 100, 23 * 11 - 1];
        let srgb = crate::color::linear_to_srgb_tabulated as fn(f32) -> f32;
        for j in [0, 1] {
            for then in [None, Some(srgb)] {
                let mut rows = Vec::new();
                let picked = capture
                    .read_parts(j, 2..9, &pixels, then, &mut |_, v| {
                        rows.extend_from_slice(v);
                        Ok(())
                    })
                    .unwrap();
                let mut code_rows = Vec::new();
                let codes = capture
                    .read_code_parts(j, 2..9, &pixels, &mut |_, c| {
                        code_rows.extend_from_slice(c);
                        Ok(())
                    })
                    .unwrap();
                let values = capture.code_values(j, then);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                let decoded = |c: &[u8]| -> Vec<f32> {
                    c.iter()
                        .enumerate()
                        .map(|(i, &c)| values[256 * (i % 3) + c as usize])
                        .collect()
                };
                assert_eq!(bits(&decoded(&code_rows)), bits(&rows), "image {j}");
                assert_eq!(bits(&decoded(&codes)), bits(&picked), "image {j}");
            }
        }
    }

    /// Rows of a shard's band of an image `height` rows high.
    fn band_rows(height: usize, shard: Option<(usize, usize)>) -> usize {
        shard.map_or(height, |(i, n)| {
            crate::maps::ShardInfo::new(i, n, height)
                .unwrap()
                .rows()
                .len()
        })
    }

    #[test]
    fn a_stream_missing_pixels_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("short.exr");
        let mut stream = ExrStream::new(4, 20, 1, Precision::F16, None).unwrap();
        let strip = |y0, height| Piece {
            x0: 0,
            y0,
            width: 4,
            height,
        };
        stream
            .piece(strip(0, 17), CoefficientMaps::zeros(4, 17, 1))
            .unwrap();
        assert!(
            stream
                .piece(strip(17, 4), CoefficientMaps::zeros(4, 4, 1))
                .is_err(),
            "past the last row"
        );
        assert!(
            stream
                .piece(strip(16, 1), CoefficientMaps::zeros(4, 1, 1))
                .is_err(),
            "a row twice"
        );
        assert!(
            stream
                .piece(strip(17, 1), CoefficientMaps::zeros(5, 1, 1))
                .is_err(),
            "maps of another size"
        );
        let err = stream.finish(&path, &sample_image(1).meta).unwrap_err();
        assert!(err.to_string().contains("68 of 80 pixels"), "{err}");
        assert!(!path.exists());
        assert!(
            std::fs::read_dir(dir.path()).unwrap().next().is_none(),
            "no partial file"
        );
        // A tiled file takes no piece across its tiles.
        let (w, k) = (600, 25);
        let (tw, th) = ExrStream::tiles(w, k, Precision::F16, false).unwrap();
        assert_eq!((tw, th), (256, 16));
        let mut tiled = ExrStream::new(w, 20, k, Precision::F16, None).unwrap();
        let across = Piece {
            x0: 0,
            y0: 0,
            width: tw + 1,
            height: 1,
        };
        assert!(tiled
            .piece(across, CoefficientMaps::zeros(tw + 1, 1, k))
            .is_err());
        assert!(ExrStream::new(4, 20, 1, Precision::U8, None).is_err());
        assert!(ExrStream::new(4, 20, 1, Precision::F16, Some(vec![0.0; 3])).is_err());
    }

    fn sample_image(k: usize) -> RelightableImage {
        let mut maps = CoefficientMaps::zeros(5, 3, k);
        for (i, v) in maps.data.iter_mut().enumerate() {
            *v = ((i * 7919) % 1000) as f32 / 137.0 - 3.0 + 1e-7 * i as f32;
        }
        // SH of k coefficients where k is a square (sh:4 otherwise: a meta only).
        let basis = BasisSpec::named(&format!("sh:{k}"))
            .or_else(|_| BasisSpec::named("sh:4"))
            .unwrap();
        let mut meta = Metadata::new(
            basis,
            MapSpace::Linear,
            Projection::Cylindrical {
                fov_y_deg: Some(60.0),
            },
        );
        meta.fit = Some(FitInfo {
            objective: "perceptual".into(),
            regularizer: "roughness".into(),
            lambda: 1e-3,
            lambda_choice: "auto".into(),
            images: 60,
            rmse_linear: [0.01, 0.02, 0.03],
            psnr_srgb8: 35.5,
            seconds: 1.25,
            shard: Some(crate::maps::ShardInfo::new(1, 2, 6).unwrap()),
        });
        meta.camera = Some(crate::camera::CameraSpec {
            projection: Projection::Cylindrical {
                fov_y_deg: Some(60.0),
            },
            width: 5,
            height: 3,
            pose: crate::camera::Pose::at(crate::sphere::Vec3::new(0.0, 1.5, 0.0)),
            orthographic_height: None,
        });
        RelightableImage {
            meta,
            maps,
            depth: Some((0..15).map(|i| i as f32 * 0.5).collect()),
        }
    }

    #[test]
    fn float_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.exr");
        let img = sample_image(4);
        write(&path, &img, Precision::F32).unwrap();
        let back = read(&path).unwrap();
        assert_eq!(back, img);
    }

    #[test]
    fn half_round_trip_equals_half_rounding() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.exr");
        let img = sample_image(4);
        write(&path, &img, Precision::F16).unwrap();
        let back = read(&path).unwrap();
        for (a, b) in back.maps.data.iter().zip(&img.maps.data) {
            assert_eq!(*a, f16_value(f16_bits(*b)));
        }
        assert_eq!(back.meta, img.meta);
        assert_eq!(back.depth, img.depth, "depth is always stored as float");
    }

    #[test]
    fn foreign_and_broken_files_are_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain.exr");
        crate::image::save(&plain, &crate::image::ImageRgb::new(2, 2), 0.0).unwrap();
        assert!(read(&plain)
            .unwrap_err()
            .to_string()
            .contains("not a relit file"));
        let junk = dir.path().join("junk.exr");
        std::fs::write(&junk, b"v/1\x01 garbage").unwrap();
        assert!(read(&junk).is_err());
        assert!(read(&dir.path().join("absent.exr"))
            .unwrap_err()
            .to_string()
            .contains("does not exist"));
    }

    #[test]
    fn compact_reads_equal_compact_copies_of_the_maps() {
        // Decoding straight into f16 or u8 planes gives the planes and codings of the
        // compact copy made from the f32 maps, for half and float files, and holds no
        // f32 maps.
        let dir = tempfile::tempdir().unwrap();
        for in_file in [Precision::F16, Precision::F32] {
            let path = dir.path().join("m.exr");
            write(&path, &sample_image(4), in_file).unwrap();
            let full = read(&path).unwrap();
            for precision in [Precision::F16, Precision::U8] {
                let (image, planes) = read_compact(&path, precision).unwrap();
                assert!(image.maps.data.is_empty());
                assert_eq!(
                    (image.meta.clone(), image.depth.clone()),
                    (full.meta.clone(), full.depth.clone())
                );
                assert_eq!(planes.precision(), precision);
                let copied = CompactPlanes::from_maps(&full.maps, precision).unwrap();
                assert_eq!(planes.bytes(), copied.bytes());
                for j in 0..3 * full.maps.k {
                    assert_eq!(planes.coding(j), copied.coding(j), "{in_file} {precision}");
                    for p in 0..full.maps.pixels() {
                        assert_eq!(planes.value(j, p), copied.value(j, p));
                    }
                }
            }
        }
        assert!(read_compact(&dir.path().join("m.exr"), Precision::F32).is_err());
        assert!(write(&dir.path().join("u8.exr"), &sample_image(1), Precision::U8).is_err());
    }

    #[test]
    fn a_header_asking_for_more_memory_than_there_is_is_an_error() {
        // 128 TiB: more than any machine this runs on will hand out.
        let err = try_zeroed::<f32>(Some(1 << 45), "huge maps").unwrap_err();
        assert!(err.to_string().contains("could not be allocated"), "{err}");
        assert!(try_zeroed::<f32>(None, "overflowing maps")
            .unwrap_err()
            .to_string()
            .contains("overflows"));
        assert_eq!(try_zeroed::<u16>(Some(3), "small").unwrap(), vec![0; 3]);
    }
}

mod pyramid;
mod zip;
pub use pyramid::write_tiled_from;
