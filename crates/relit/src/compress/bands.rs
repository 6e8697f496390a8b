//! Packing a file a band of rows at a time, so that compressing an image of any size
//! holds a few bands of its maps instead of all of them (and their projection).
//!
//! Three passes over level 0's rows, each a band of one tile row at a time: the
//! principal components' pixels; each plane's range and quantile subsample; then every
//! tile coded as it comes, each finer mip level made from the rows above it as they
//! come (a 2×2 block needs two rows) and coded a tile row at a time too. With a
//! perceptual gain ([`super::gain`]) a first pass finds level 0's gain (kept, one value
//! a pixel) and the gain plane's quantiser, and the second codes level 0's gain tiles
//! as it goes and keeps in the gain's place what a reader will decode (what the later
//! passes divide by); a finer level's gain tiles are coded with its tile rows (a tile's
//! gain depends on its own pixels alone). With principal components a block, each
//! band's blocks (which lie inside it) are found while its planes are measured and kept
//! for the coding pass. With a codebook, the statistics pass also gathers the vectors
//! k-means trains on (every few pixels', as [`vq::train`] takes them), the residual's
//! ranges and the sums that weigh `lrgb`'s albedo; the codebook is trained before the
//! coding pass, which gives each pixel of a tile its nearest entry. Every value is found
//! from the same pixels, in the same order and arithmetic, as [`super::pack`] finds it
//! from the whole image, so the file is the same byte for byte.
//!
//! Peak memory: two to three bands of `tile × width` pixels of `3K` f32 coefficients
//! (the band read, what its source decodes it from, and the finer levels' pending rows,
//! which together hold less than one band), a tile's projection a thread, and the
//! sections of one tile row; with a gain, its plane (one f32 a pixel of level 0); with
//! blocks, each block's components (`K × K′` f64 twice a projection group); with a
//! codebook, its training vectors (64 an entry, 2¹⁶ to 2¹⁹, or up to twice that where
//! the stride rounds down; of its values each).

use super::{
    albedo_at, chunks_of_planes, codebook_bytes, codebook_weights, coded_gain, encode_floats, gain,
    gain_quantizer, plane_entries, projection, projection_groups, residual_entry, squared,
    stored_basis, undivided, undivided_all, vq, Counts, Header, Layout, PlaneEntry, PlaneStats,
    Quantizer, Settings, BLOCK_PCA_PIXELS, PCA_PIXELS,
};
use crate::basis::Basis;
use crate::maps::{CoefficientMaps, Metadata, RelightableImage};
use crate::progress::Progress;
use crate::sphere::Vec3;
use crate::storage::FiniteRange;
use crate::{Error, Result};
use rayon::prelude::*;
use std::ops::Range;

/// Pixels (whole rows, at least one) projected at a time while the planes are measured.
const STATS_SPAN: usize = 1 << 16;

/// Level 0 of an image, read a band of whole rows at a time.
pub trait BandSource: Sync {
    /// The image's metadata (its basis, space, camera…).
    fn meta(&self) -> &Metadata;
    /// Width, height and coefficients per channel.
    fn shape(&self) -> (usize, usize, usize);
    /// Whether the image has depth.
    fn has_depth(&self) -> bool;
    /// Rows `rows`, the whole width: the maps, and the depth where the image has one.
    fn band(&self, rows: Range<usize>) -> Result<RelightableImage>;
}

impl BandSource for RelightableImage {
    fn meta(&self) -> &Metadata {
        &self.meta
    }

    fn shape(&self) -> (usize, usize, usize) {
        (self.width(), self.height(), self.maps.k)
    }

    fn has_depth(&self) -> bool {
        self.depth.is_some()
    }

    fn band(&self, rows: Range<usize>) -> Result<RelightableImage> {
        Ok(rows_of(self, rows))
    }
}

/// Where [`pack_in_bands`] puts each section as it is made (in no particular order):
/// its number in the file, and its bytes.
pub trait SectionSink {
    fn put(&mut self, section: usize, bytes: Vec<u8>) -> Result<()>;
}

/// Whether files of `settings` can be packed a band at a time: not with what
/// [`super::pack`] refuses (mip levels with blocks or a codebook; a codebook with blocks
/// or the gain), which is left to it to say. Blocks of principal components that cross
/// tile rows are packed in bands too: their components are found first, from bands of
/// whole block rows.
pub fn packs_in_bands(settings: &Settings) -> bool {
    let blocks_fit = settings
        .pca_block
        .is_none_or(|side| side > 0 && !settings.mip_levels);
    let codebook_fits = settings.codebook.is_none()
        || (!settings.mip_levels && !settings.gain && settings.pca_block.is_none());
    codebook_fits && blocks_fit
}

/// Maps (f32, all three channels) above which writers pack a band at a time by default:
/// below it the image held whole costs little memory and is packed faster (one read, one
/// projection; the band packer reads its source three times, and a fit first writes its
/// maps to a temporary file). Measured on item1's fit (64 MiB of maps): 2.8–2.9 s and
/// 163 MiB whole, 3.7–4.0 s and 229 MiB in bands; on item1 repeated to 4096×1024
/// (768 MiB): 35.2 s and 1.75 GiB whole, 36.6 s and 0.84 GiB in bands.
pub const BANDS_ABOVE_BYTES: u64 = 256 << 20;

/// Whether to pack an image of `width × height` pixels with at most `k` coefficients a
/// channel a band at a time: its settings allow it ([`packs_in_bands`]) and its maps take
/// more than `above` bytes (by default [`BANDS_ABOVE_BYTES`]).
pub fn worth_packing_in_bands(
    settings: &Settings,
    (width, height, k): (usize, usize, usize),
    above: u64,
) -> bool {
    packs_in_bands(settings) && 12 * (k as u64) * (width as u64) * (height as u64) > above
}

/// Pack the image `source` reads with `settings` ([`packs_in_bands`]), a band of rows
/// at a time, every section into `sink`; returns the file's header.
pub fn pack_in_bands(
    source: &dyn BandSource,
    settings: &Settings,
    sink: &mut dyn SectionSink,
    progress: &dyn Progress,
) -> Result<Header> {
    if !packs_in_bands(settings) {
        return Err(Error::invalid(
            "blocks of principal components take no mip levels, and a codebook takes \
             neither mip levels, blocks nor the gain: such a file is packed whole",
        ));
    }
    let (width, height, k) = source.shape();
    let meta = source.meta();
    let basis = meta.basis.build()?;
    if basis.len() != k {
        return Err(Error::invalid("the maps and their basis disagree on K"));
    }
    let counts = Counts::checked(settings, k)?;
    let (components, extra) = (counts.components, counts.extra);
    if settings.codebook.is_some() && extra == 0 && !settings.codec.lossless() {
        return Err(Error::invalid(
            "a codebook's indices need the lossless codec (zstd), not an image codec",
        ));
    }
    let layout = settings.layout;
    let counts = counts.per_function(layout);
    let gram = projection::gram(basis.as_ref(), settings.directions.as_deref());
    let n = width * height;
    let bands: Vec<Range<usize>> = (0..height)
        .step_by(settings.tile)
        .map(|y| y..(y + settings.tile).min(height))
        .collect();

    // Level 0's gain and the gain plane's quantiser, from every pixel's gain as `pack`
    // finds them. The gain is replaced by what a reader decodes as its tiles are coded
    // while the principal components' pixels are read.
    let (gain, mut divisor) = match settings.gain {
        false => (None, None),
        true => {
            let directions = settings.directions.as_deref();
            let mut stats = PlaneStats::empty(settings.codec);
            let mut values = Vec::with_capacity(n);
            progress.begin("measuring the gain", bands.len() as u64);
            for rows in &bands {
                let band = band_of(source, rows.clone())?;
                let first = rows.start * width;
                values.extend(gain::perceptual(&band.maps, basis.as_ref(), directions));
                for (p, &v) in values.iter().enumerate().skip(first) {
                    stats.see(p, n, v);
                }
                progress.advance(1);
            }
            progress.end();
            let coder = GainCoder {
                basis: basis.as_ref(),
                directions,
                quantizer: gain_quantizer(&stats, settings.codec),
                settings,
            };
            (Some(coder), Some(values))
        }
    };
    // Level 0's gain tiles: the last plane's, after every other plane's.
    let across = width.div_ceil(settings.tile);
    let gain_sections = planes_of(layout, &counts) * across * height.div_ceil(settings.tile);

    // The principal components of each projection group, from every `step`-th pixel as
    // `pack` takes them.
    let groups = projection_groups(layout, settings.pca_block.is_some());
    let step = (n / PCA_PIXELS).max(1);
    let mut vectors: Vec<Vec<f64>> = vec![Vec::new(); groups.len()];
    progress.begin("finding principal components", bands.len() as u64);
    for rows in &bands {
        let band = band_of(source, rows.clone())?;
        let first = rows.start * width;
        if let (Some(g), Some(plane)) = (&gain, &mut divisor) {
            let values = &mut plane[first..rows.end * width];
            let (sections, decoded) = g.code_values(values, width, rows.len())?;
            for (tx, bytes) in sections.into_iter().enumerate() {
                let index = rows.start / settings.tile * across + tx;
                sink.put(gain_sections + index, bytes)?;
            }
            values.copy_from_slice(&decoded);
        }
        let band_divisor = divisor.as_deref().map(|d| &d[first..]);
        let mut all = vec![0.0f32; counts.len() * k];
        for p in (first.next_multiple_of(step)..rows.end * width).step_by(step) {
            undivided_all(layout, &band.maps, p - first, &mut all);
            for (channels, vectors) in groups.iter().zip(&mut vectors) {
                for &f in channels {
                    vectors.extend(
                        all[f * k..(f + 1) * k]
                            .iter()
                            .map(|&v| divided(v, band_divisor, p - first) as f64),
                    );
                }
            }
        }
        progress.advance(1);
    }
    progress.end();
    let whole: Vec<projection::Principal> = groups
        .iter()
        .zip(vectors)
        .map(|(channels, vectors)| {
            // A codebook of the residual holds the next `extra` components of each.
            projection::principal(&gram, &vectors, k, counts[channels[0]] + extra)
        })
        .collect::<Result<_>>()?;
    // With principal components a block, each block's (found while its band is measured).
    let mut principals: Vec<Vec<projection::Principal>> = match settings.pca_block {
        None => vec![whole.clone()],
        Some(_) => Vec::new(),
    };
    let projection = Projection {
        layout,
        counts: &counts,
        group_of: (0..counts.len())
            .map(|f| super::group_of(&groups, f))
            .collect(),
        groups,
        gram: &gram,
        block: settings.pca_block,
        across: settings.pca_block.map_or(0, |side| width.div_ceil(side)),
        residual: (components, extra),
    };

    // Each plane's statistics, then its quantiser; with a codebook, the vectors it is
    // trained on (as [`vq::train`] takes them from every pixel's), the residual's
    // ranges and the sums of squares that weigh `lrgb`'s albedo, as `pack` finds them.
    let planes = planes_of(layout, &counts);
    let mut stats = vec![PlaneStats::empty(settings.codec); planes];
    let fcount = counts.len();
    let mut book = settings.codebook.map(|entries| {
        let values = match extra {
            0 => 0..planes,
            _ => planes..planes + fcount * extra,
        };
        let functions = match extra {
            0 => counts.iter().sum(),
            _ => values.len(),
        };
        // `lrgb`'s albedo among the values weighs by the first function's energy.
        let weighed = values.len() > functions;
        BookStats {
            entries,
            stride: vq::training_stride(n, entries),
            n,
            training: Vec::new(),
            ranges: vec![FiniteRange::EMPTY; fcount * extra],
            squares: vec![0.0; if weighed { counts[0] } else { 0 }],
            values,
            functions,
        }
    });
    // Blocks that cross tile rows: every block's components first, from bands of whole
    // block rows at least a tile high (a band then holds at most a tile and a block's
    // rows); blocks inside the tile rows are found with their band below.
    let crossing = settings
        .pca_block
        .filter(|&side| !settings.tile.is_multiple_of(side));
    if let Some(side) = crossing {
        let high = settings.tile.div_ceil(side) * side;
        let block_bands: Vec<Range<usize>> = (0..height)
            .step_by(high)
            .map(|y| y..(y + high).min(height))
            .collect();
        progress.begin("finding each block's components", block_bands.len() as u64);
        for rows in block_bands {
            let band = band_of(source, rows.clone())?;
            let found =
                projection.blocks_of(&band, rows.start, height, &whole, divisor.as_deref())?;
            principals.extend(found);
            progress.advance(1);
        }
        progress.end();
    }
    progress.begin("measuring the planes", bands.len() as u64);
    for rows in &bands {
        let band = band_of(source, rows.clone())?;
        let band_divisor = divisor.as_deref().map(|d| &d[rows.start * width..]);
        if projection.block.is_some() && crossing.is_none() {
            let found =
                projection.blocks_of(&band, rows.start, height, &whole, divisor.as_deref())?;
            principals.extend(found);
        }
        let projector = projection.with(&principals);
        // A few rows' projection at a time: the band is the only large thing held.
        let pixels = band.maps.pixels();
        let span = (STATS_SPAN / width.max(1)).max(1) * width;
        for start in (0..pixels).step_by(span) {
            let at = start..(start + span).min(pixels);
            let first = rows.start * width + start;
            let projected = projector.project(&band.maps, at, band_divisor, (0, rows.start));
            stats
                .par_iter_mut()
                .zip(&projected)
                .for_each(|(stats, plane)| {
                    for (local, &v) in plane.iter().enumerate() {
                        stats.see(first + local, n, v);
                    }
                });
            if let Some(book) = &mut book {
                book.see(&projected, planes, first);
            }
        }
        progress.advance(1);
    }
    progress.end();
    let albedo = planes - counts.iter().sum::<usize>();
    let mut entries = plane_entries(settings, &counts, albedo, None, &|i| stats[i].clone())?;
    drop(stats);
    let residual: Vec<PlaneEntry> = match &book {
        Some(book) => (book.ranges.iter().enumerate())
            .map(|(i, &range)| residual_entry(layout, components, extra, i, range))
            .collect(),
        None => Vec::new(),
    };
    let indexer = book.map(BookStats::train).transpose()?;
    // The gain plane, the last.
    if let Some(g) = &gain {
        entries.push(PlaneEntry {
            channel: gain::CHANNEL.to_string(),
            index: 0,
            quantizer: g.quantizer,
        });
    }

    let levels = if settings.mip_levels {
        crate::maps::mip_sizes(width, height)
    } else {
        vec![(width, height)]
    };
    let header = Header {
        meta: Metadata {
            format_version: crate::maps::FORMAT_VERSION,
            basis: match settings.pca_block {
                // Blocks' planes decode into the input basis, each by its own map.
                Some(_) => meta.basis.clone(),
                None => stored_basis(&meta.basis, &whole[0], components + extra)?,
            },
            ..meta.clone()
        },
        width,
        height,
        tile: settings.tile,
        layout,
        codec: settings.codec,
        planes: entries,
        codebook: indexer.as_ref().map(|(book, _)| book.entries()),
        residual,
        gain: gain.is_some(),
        pca_block: settings.pca_block,
        depth: source.has_depth(),
        levels: levels.len(),
    };

    // Every level's tiles, level 0's as its bands come and each finer level's as the
    // rows above it do.
    let mut pyramid: Vec<Level> = levels
        .iter()
        .enumerate()
        .map(|(l, &size)| Level {
            size,
            first_section: if l == 0 {
                0
            } else {
                header.level_sections(l).start
            },
            pending: None,
            coded_rows: 0,
            unhalved: None,
            halved_rows: 0,
        })
        .collect();
    if let (Some((book, _)), Some(section)) = (&indexer, header.codebook_section()) {
        sink.put(section, codebook_bytes(&header, book)?)?;
    }
    let projector = projection.with(&principals);
    let coder = Coder {
        header: &header,
        projector: &projector,
        gain: gain.as_ref(),
        level0_divisor: divisor.as_deref(),
        indexer: indexer.as_ref().map(|(_, indexer)| indexer),
    };
    progress.begin("coding tiles", bands.len() as u64);
    for rows in &bands {
        let band = band_of(source, rows.clone())?;
        feed(&mut pyramid, 0, band, &coder, sink)?;
        progress.advance(1);
    }
    progress.end();
    if let Some(l) = pyramid
        .iter()
        .position(|level| level.coded_rows != level.size.1)
    {
        return Err(Error::invalid(format!(
            "level {l} was left incomplete: the source gave other rows than it has"
        )));
    }
    if settings.pca_block.is_some() {
        // Each block's P as the reader uses it (f32), the last section, as `pack` makes it.
        let bytes = principals
            .iter()
            .flatten()
            .flat_map(|p| p.basis_map.iter().map(|&v| v as f32))
            .flat_map(f32::to_le_bytes)
            .collect();
        sink.put(header.sections() - 1, bytes)?;
    }
    Ok(header)
}

/// Rows `rows` of `source`, checked to be what was asked for (a source that gives
/// another shape is refused, not indexed out of bounds).
fn band_of(source: &dyn BandSource, rows: Range<usize>) -> Result<RelightableImage> {
    let (width, _, k) = source.shape();
    let band = source.band(rows.clone())?;
    let maps = &band.maps;
    let pixels = width * rows.len();
    if maps.width != width
        || maps.height != rows.len()
        || maps.k != k
        || maps.data.len() != 3 * k * pixels
        || band.depth.as_ref().is_some_and(|d| d.len() != pixels)
    {
        return Err(Error::invalid(format!(
            "rows {}..{} of the image came back in another shape",
            rows.start, rows.end
        )));
    }
    Ok(band)
}

/// The planes a file of `layout` with `counts` components a function holds before the
/// gain: the functions' components, then `lrgb`'s albedo.
fn planes_of(layout: Layout, counts: &[usize]) -> usize {
    counts.iter().sum::<usize>() + 3 * (layout == Layout::Lrgb) as usize
}

/// `v`, a function's coefficient at pixel `p`, divided by the pixel's gain where there
/// is one (as `pack` divides it: the albedo of `lrgb` is not).
fn divided(v: f32, divisor: Option<&[f32]>, p: usize) -> f32 {
    match divisor {
        Some(d) => v / d[p],
        None => v,
    }
}

/// Codes a tile row's perceptual gain plane as `pack` does, which also gives the gain a
/// reader will decode: what the function planes are divided by.
struct GainCoder<'a> {
    basis: &'a dyn Basis,
    directions: Option<&'a [Vec3]>,
    /// Level 0's, for every level.
    quantizer: Quantizer,
    settings: &'a Settings,
}

impl GainCoder<'_> {
    /// The sections of the gain tiles of `maps` (rows of at most one tile, the whole
    /// width), in order, and the decoded gain of every pixel.
    fn code(&self, maps: &CoefficientMaps) -> Result<(Vec<Vec<u8>>, Vec<f32>)> {
        let values = gain::perceptual(maps, self.basis, self.directions);
        self.code_values(&values, maps.width, maps.height)
    }

    /// [`GainCoder::code`] of the gain `values` of `width × height` pixels.
    fn code_values(
        &self,
        values: &[f32],
        width: usize,
        height: usize,
    ) -> Result<(Vec<Vec<u8>>, Vec<f32>)> {
        coded_gain(values, &self.quantizer, width, height, self.settings)
    }
}

/// What a codebook is found from, gathered in pixel order while the planes are measured.
struct BookStats {
    /// Entries asked for.
    entries: usize,
    /// The projected planes the codebook holds (every plane's, or the residual's), and
    /// how many of them are functions' (the rest, `lrgb`'s albedo, are weighed).
    values: Range<usize>,
    functions: usize,
    /// Every `stride`-th pixel's values, unweighed, of the image's `n`.
    stride: usize,
    n: usize,
    training: Vec<f32>,
    /// The residual's planes' ranges.
    ranges: Vec<FiniteRange>,
    /// The sums of squares of the first function's planes, where the albedo is weighed.
    squares: Vec<f64>,
}

impl BookStats {
    /// `projected`'s pixels, the first of them pixel `first` of the image (`planes`: the
    /// planes before the residual's).
    fn see(&mut self, projected: &[Vec<f32>], planes: usize, first: usize) {
        let pixels = projected.first().map_or(0, Vec::len);
        let values = &projected[self.values.clone()];
        for p in (first.next_multiple_of(self.stride)..first + pixels).step_by(self.stride) {
            self.training
                .extend(values.iter().map(|plane| plane[p - first]));
        }
        for (range, plane) in self.ranges.iter_mut().zip(&projected[planes..]) {
            *range = plane.iter().fold(*range, |r, &v| r.with(v));
        }
        for (sum, plane) in self.squares.iter_mut().zip(projected) {
            *sum = plane.iter().fold(*sum, |s, &v| s + squared(v));
        }
    }

    /// The codebook, in the planes' units, and what assigns a pixel its entry.
    fn train(self) -> Result<(vq::Codebook, Indexer)> {
        let dims = self.values.len();
        if dims == 0 {
            return Err(Error::invalid("vector quantisation of no values"));
        }
        let weights = codebook_weights(dims, self.functions, self.squares.into_iter(), self.n);
        let mut training = self.training;
        for vector in training.chunks_exact_mut(dims) {
            for (x, w) in vector.iter_mut().zip(&weights) {
                *x *= w;
            }
        }
        let mut book = vq::train_on(training, dims, self.entries)?;
        let assigner = vq::Assigner::new(&book);
        for entry in book.values.chunks_exact_mut(dims) {
            for (x, w) in entry.iter_mut().zip(&weights) {
                *x /= w;
            }
        }
        let indexer = Indexer {
            assigner,
            values: self.values,
            weights,
        };
        Ok((book, indexer))
    }
}

/// Assigns each pixel its codebook entry from its projected planes.
struct Indexer {
    assigner: vq::Assigner,
    values: Range<usize>,
    weights: Vec<f32>,
}

impl Indexer {
    /// The entry of every pixel of `projected`.
    fn indices(&self, projected: &[Vec<f32>]) -> Vec<u16> {
        let values = &projected[self.values.clone()];
        let pixels = values.first().map_or(0, Vec::len);
        let mut vectors = Vec::with_capacity(pixels * values.len());
        for p in 0..pixels {
            vectors.extend(
                values
                    .iter()
                    .zip(&self.weights)
                    .map(|(plane, &w)| plane[p] * w),
            );
        }
        self.assigner.assign(&vectors)
    }
}

/// How the file's planes are made from the coefficients, but for the principal
/// components themselves (the file's, or each block's as they are found).
struct Projection<'a> {
    layout: Layout,
    counts: &'a [usize],
    /// The projection groups (with blocks, ycc's chroma has its own), and each function
    /// channel's.
    groups: Vec<Vec<usize>>,
    group_of: Vec<usize>,
    gram: &'a [f64],
    /// The blocks' side, where each has its own components, and how many lie across.
    block: Option<usize>,
    across: usize,
    /// With a codebook of the residual, the components a function keeps as planes and
    /// the residual's that follow them (0 without).
    residual: (usize, usize),
}

impl Projection<'_> {
    /// Projecting with `principals`: the file's per projection group, or each block's.
    fn with<'b>(&'b self, principals: &'b [Vec<projection::Principal>]) -> Projector<'b> {
        Projector {
            projection: self,
            principals,
        }
    }

    /// The principal components of each block whose rows begin in `band` (rows from
    /// `row0`, the whole width, of an image `height` rows high), block by block in the
    /// file's order: each group's from up to `BLOCK_PCA_PIXELS` of the block's pixels
    /// (divided by the image's `divisor` where there is one), turned like the file's
    /// (`whole`), as `pack` finds them.
    fn blocks_of(
        &self,
        band: &RelightableImage,
        row0: usize,
        height: usize,
        whole: &[projection::Principal],
        divisor: Option<&[f32]>,
    ) -> Result<Vec<Vec<projection::Principal>>> {
        let Some(side) = self.block else {
            return Ok(Vec::new());
        };
        let (width, k) = (band.width(), band.maps.k);
        let divisor = divisor.map(|d| &d[row0 * width..]);
        let first_row = row0.div_ceil(side);
        let last_row = (row0 + band.height())
            .div_ceil(side)
            .min(height.div_ceil(side));
        (first_row * self.across..last_row * self.across)
            .into_par_iter()
            .map(|block| {
                let (x0, y0, w, h) = super::tile_rect(width, height, side, block);
                if y0 < row0 || y0 + h > row0 + band.height() {
                    return Err(Error::invalid("a block lies across two bands"));
                }
                let pixels: Vec<usize> = (y0 - row0..y0 - row0 + h)
                    .flat_map(|y| y * width + x0..y * width + x0 + w)
                    .collect();
                let step = (pixels.len() / BLOCK_PCA_PIXELS).max(1);
                self.groups
                    .iter()
                    .zip(whole)
                    .map(|(channels, file)| {
                        let vectors: Vec<f64> = pixels
                            .iter()
                            .step_by(step)
                            .flat_map(|&p| {
                                channels.iter().flat_map(move |&f| {
                                    (0..k).map(move |i| {
                                        let v = undivided(self.layout, &band.maps, i, f, p);
                                        divided(v, divisor, p) as f64
                                    })
                                })
                            })
                            .collect();
                        let components = self.counts[channels[0]];
                        let mut own = projection::principal(self.gram, &vectors, k, components)?;
                        own.orient_like(file);
                        Ok(own)
                    })
                    .collect()
            })
            .collect()
    }
}

/// Projects a band's coefficients onto the file's planes: each function channel's
/// components, then `lrgb`'s albedo.
struct Projector<'a> {
    projection: &'a Projection<'a>,
    /// The file's principal components per projection group, or each block's.
    principals: &'a [Vec<projection::Principal>],
}

impl Projector<'_> {
    /// The planes of the file's tiles: the functions' components, then `lrgb`'s albedo.
    fn coded_planes(&self) -> usize {
        planes_of(self.projection.layout, self.projection.counts)
    }

    /// Every plane [`Projector::project`] gives: the coded ones, then the residual's
    /// components (each function channel's in turn).
    fn planes(&self) -> usize {
        let (_, extra) = self.projection.residual;
        self.coded_planes() + self.projection.counts.len() * extra
    }

    /// The principal components of function channel `f` at pixel `p` of maps `width`
    /// pixels wide whose first pixel is pixel `origin` (x, y) of the image.
    fn principal_at(
        &self,
        width: usize,
        (x0, y0): (usize, usize),
        p: usize,
        f: usize,
    ) -> &projection::Principal {
        let projection = self.projection;
        let block = match projection.block {
            None => 0,
            Some(side) => {
                let (x, y) = (x0 + p % width, y0 + p / width);
                (y / side) * projection.across + x / side
            }
        };
        &self.principals[block][projection.group_of[f]]
    }

    /// Every plane's values ([`Projector::planes`]) at the pixels `span` of `maps` (whose
    /// first pixel is pixel `origin` of the image), the functions divided by `divisor`
    /// (one value a pixel of `maps`) where there is one.
    fn project(
        &self,
        maps: &CoefficientMaps,
        span: Range<usize>,
        divisor: Option<&[f32]>,
        origin: (usize, usize),
    ) -> Vec<Vec<f32>> {
        const CHUNK: usize = 4096;
        let (pixels, k) = (span.len(), maps.k);
        let Projection {
            layout,
            counts,
            gram,
            residual: (components, extra),
            ..
        } = *self.projection;
        // With a residual, every function's components and the residual's, as `pack`
        // applies them (a row's value does not depend on how many are applied).
        let rows = |count: usize| if extra > 0 { components + extra } else { count };
        let most = counts.iter().map(|&c| rows(c)).max().unwrap_or(0);
        let residual = self.coded_planes();
        let mut planes: Vec<Vec<f32>> = (0..self.planes()).map(|_| vec![0.0; pixels]).collect();
        // Each chunk of pixels writes its part of every plane.
        chunks_of_planes(&mut planes, CHUNK)
            .into_par_iter()
            .enumerate()
            .for_each(|(chunk, mut outs)| {
                let (mut all, mut y) = (vec![0.0f32; counts.len() * k], vec![0.0f32; most]);
                let mut scratch = (vec![0.0f64; k], vec![0.0f64; k]);
                for local in 0..outs[0].len() {
                    let p = span.start + chunk * CHUNK + local;
                    undivided_all(layout, maps, p, &mut all);
                    all.iter_mut().for_each(|v| *v = divided(*v, divisor, p));
                    let mut plane = 0;
                    for (f, &count) in counts.iter().enumerate() {
                        let c = &all[f * k..(f + 1) * k];
                        self.principal_at(maps.width, origin, p, f)
                            .apply(c, &mut y[..rows(count)]);
                        for &v in &y[..count] {
                            outs[plane][local] = v;
                            plane += 1;
                        }
                        for r in 0..extra {
                            outs[residual + f * extra + r][local] = y[components + r];
                        }
                    }
                    if layout == Layout::Lrgb {
                        for v in albedo_at(maps, gram, p, &mut scratch) {
                            outs[plane][local] = v;
                            plane += 1;
                        }
                    }
                }
            });
        planes
    }
}

/// Codes a level's tiles into their sections.
struct Coder<'a> {
    header: &'a Header,
    projector: &'a Projector<'a>,
    gain: Option<&'a GainCoder<'a>>,
    /// Level 0's decoded gain, its tiles coded already.
    level0_divisor: Option<&'a [f32]>,
    /// With a codebook: each pixel's entry.
    indexer: Option<&'a Indexer>,
}

impl Coder<'_> {
    /// The tiles of `rows` (one tile row of `level`, whose rows start at `y0`), every
    /// plane's and the depth's, into `sink`.
    fn code_tile_row(
        &self,
        l: usize,
        level: &Level,
        y0: usize,
        rows: &RelightableImage,
        sink: &mut dyn SectionSink,
    ) -> Result<()> {
        let header = self.header;
        let (w, h) = level.size;
        let t = header.tile;
        let across = w.div_ceil(t);
        let tiles = across * h.div_ceil(t);
        let planes = header.planes.len();
        let row = y0 / t;
        // The gain the planes are divided by: level 0's as kept, a finer level's from its
        // gain tiles (the last plane's), coded here.
        let divisor: Option<std::borrow::Cow<[f32]>> = match (self.gain, self.level0_divisor) {
            (Some(_), Some(kept)) if l == 0 => Some(kept[y0 * w..][..rows.maps.pixels()].into()),
            (Some(g), _) => {
                let (sections, divisor) = g.code(&rows.maps)?;
                for (tx, bytes) in sections.into_iter().enumerate() {
                    sink.put(
                        level.first_section + (planes - 1) * tiles + row * across + tx,
                        bytes,
                    )?;
                }
                Some(divisor.into())
            }
            (None, _) => None,
        };
        let made: Vec<Vec<(usize, Vec<u8>)>> = (0..across)
            .into_par_iter()
            .map(|tx| {
                let (x0, tw) = (tx * t, t.min(w - tx * t));
                let tile = columns_of(rows, x0..x0 + tw);
                if tile.depth.is_some() != header.depth {
                    return Err(Error::invalid("the source's depth comes and goes"));
                }
                let index = row * across + tx;
                let tile_divisor: Option<Vec<f32>> = divisor.as_ref().map(|d| {
                    d.chunks_exact(w)
                        .flat_map(|line| line[x0..x0 + tw].iter().copied())
                        .collect()
                });
                let projected = self.projector.project(
                    &tile.maps,
                    0..tile.maps.pixels(),
                    tile_divisor.as_deref(),
                    (x0, y0),
                );
                // A codebook's pixels without planes are only indices.
                let coded = match header.indexed_pixels() {
                    true => 0,
                    false => self.projector.coded_planes(),
                };
                let mut sections: Vec<(usize, Vec<u8>)> = projected[..coded]
                    .par_iter()
                    .zip(&header.planes)
                    .enumerate()
                    .map(|(p, (plane, entry))| {
                        let q = &entry.quantizer;
                        let codes: Vec<u16> = plane.iter().map(|&v| q.code(v)).collect();
                        let bytes = super::planes::encode_tile(
                            &codes,
                            tw,
                            tile.height(),
                            q.width(),
                            header.codec,
                        )?;
                        Ok((level.first_section + p * tiles + index, bytes))
                    })
                    .collect::<Result<_>>()?;
                if let (Some(indexer), Some(book)) = (self.indexer, header.codebook_section()) {
                    let codes = indexer.indices(&projected);
                    let (width, codec) = (header.index_width(), header.index_codec());
                    let bytes =
                        super::planes::encode_tile(&codes, tw, tile.height(), width, codec)?;
                    sections.push((book + 1 + index, bytes));
                }
                if let Some(depth) = &tile.depth {
                    // Level 0's depth follows its planes' (or its codebook's) sections.
                    let before = match l {
                        0 => header.plane_sections(),
                        _ => planes * tiles,
                    };
                    let s = level.first_section + before + index;
                    sections.push((s, encode_floats(depth)?));
                }
                Ok(sections)
            })
            .collect::<Result<_>>()?;
        for (s, bytes) in made.into_iter().flatten() {
            sink.put(s, bytes)?;
        }
        Ok(())
    }
}

/// One mip level being made: its rows not yet coded (less than a tile row), and the
/// row not yet halved into the next level (a 2×2 block needs two).
struct Level {
    size: (usize, usize),
    first_section: usize,
    pending: Option<RelightableImage>,
    coded_rows: usize,
    unhalved: Option<RelightableImage>,
    /// Rows of the next level made so far.
    halved_rows: usize,
}

/// The next rows of level `l` (`band`, whole width): coded where they complete a tile
/// row, and halved into level `l + 1`'s rows where there is one.
fn feed(
    pyramid: &mut [Level],
    l: usize,
    band: RelightableImage,
    coder: &Coder,
    sink: &mut dyn SectionSink,
) -> Result<()> {
    let t = coder.header.tile;
    let next = pyramid.get(l + 1).map(|level| level.size);
    let level = &mut pyramid[l];
    let (_, h) = level.size;
    // The next level's rows: the 2×2 means of this level's row pairs (a level of one
    // row halves that row alone; an odd last row is left out).
    let mut finer = None;
    if let Some((next_w, next_h)) = next {
        let rows = match level.unhalved.take() {
            Some(above) => std::borrow::Cow::Owned(stack(above, &band)),
            None => std::borrow::Cow::Borrowed(&band),
        };
        let wanted = next_h - level.halved_rows;
        let pairs = if h == 1 {
            rows.height().min(wanted)
        } else {
            (rows.height() / 2).min(wanted)
        };
        if pairs > 0 {
            let used = if h == 1 { pairs } else { 2 * pairs };
            // The rows halved, copied out only where some are left over.
            let halves = if used == rows.height() {
                crate::maps::halved(&rows, (next_w, pairs))
            } else {
                crate::maps::halved(&rows_of(&rows, 0..used), (next_w, pairs))
            };
            level.halved_rows += pairs;
            finer = Some(halves);
            if level.halved_rows < next_h && used < rows.height() {
                level.unhalved = Some(rows_of(&rows, used..rows.height()));
            }
        } else if level.halved_rows < next_h {
            level.unhalved = Some(rows.into_owned());
        }
    }
    // This level's tile rows.
    let mut rows = match level.pending.take() {
        Some(above) => stack(above, &band),
        None => band,
    };
    while rows.height() > 0 {
        let y0 = level.coded_rows;
        if y0 >= h {
            return Err(Error::invalid(format!(
                "level {l} was given more than its {h} rows"
            )));
        }
        let whole = t.min(h - y0);
        if rows.height() < whole {
            level.pending = Some(rows);
            break;
        }
        let rest = rows_of(&rows, whole..rows.height());
        let row = if rest.height() > 0 {
            rows_of(&rows, 0..whole)
        } else {
            rows
        };
        coder.code_tile_row(l, level, y0, &row, sink)?;
        level.coded_rows += whole;
        rows = rest;
    }
    if let Some(halves) = finer {
        feed(pyramid, l + 1, halves, coder, sink)?;
    }
    Ok(())
}

/// Rows `rows` of `image`, the whole width.
fn rows_of(image: &RelightableImage, rows: Range<usize>) -> RelightableImage {
    let w = image.width();
    let pixels = rows.start * w..rows.end * w;
    let maps = &image.maps;
    let mut data = Vec::with_capacity(3 * maps.k * pixels.len());
    for plane in maps.data.chunks_exact(maps.pixels().max(1)) {
        data.extend_from_slice(&plane[pixels.clone()]);
    }
    RelightableImage {
        meta: image.meta.clone(),
        maps: CoefficientMaps {
            width: w,
            height: rows.len(),
            k: maps.k,
            data,
        },
        depth: image.depth.as_ref().map(|d| d[pixels].to_vec()),
    }
}

/// Columns `columns` of `image`, every row.
fn columns_of(image: &RelightableImage, columns: Range<usize>) -> RelightableImage {
    let w = image.width();
    // Every line of every plane (the planes are whole lines one after another).
    let crop = |lines: &[f32]| -> Vec<f32> {
        let mut out = Vec::with_capacity(lines.len() / w.max(1) * columns.len());
        for line in lines.chunks_exact(w.max(1)) {
            out.extend_from_slice(&line[columns.clone()]);
        }
        out
    };
    let maps = &image.maps;
    RelightableImage {
        meta: image.meta.clone(),
        maps: CoefficientMaps {
            width: columns.len(),
            height: image.height(),
            k: maps.k,
            data: crop(&maps.data),
        },
        depth: image.depth.as_deref().map(crop),
    }
}

/// `above`'s rows, then `below`'s (both the same width).
fn stack(above: RelightableImage, below: &RelightableImage) -> RelightableImage {
    if above.height() == 0 {
        return rows_of(below, 0..below.height());
    }
    let (w, k) = (below.width(), below.maps.k);
    let height = above.height() + below.height();
    let mut data = Vec::with_capacity(3 * k * w * height);
    let upper = above.maps.data.chunks_exact(above.maps.pixels().max(1));
    for (upper, lower) in upper.zip(below.maps.data.chunks_exact(below.maps.pixels().max(1))) {
        data.extend_from_slice(upper);
        data.extend_from_slice(lower);
    }
    let depth = match (&above.depth, &below.depth) {
        (Some(a), Some(b)) => Some([a.as_slice(), b.as_slice()].concat()),
        _ => None,
    };
    RelightableImage {
        meta: below.meta.clone(),
        maps: CoefficientMaps {
            width: w,
            height,
            k,
            data,
        },
        depth,
    }
}
