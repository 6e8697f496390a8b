//! Compression of relightable images: the stages between fitted maps and the bytes of
//! the compressed file (`.rlz`, [`container`]), each undone by any reader.
//!
//! 1. **Colour layout** ([`Layout`]): `rgb`, `ycc` (fewer chroma components) or
//!    `lrgb` (one luminance function × an RGB albedo).
//! 2. **Principal components across pixels** ([`projection`]): `K′` planes per
//!    function instead of `K`, found in the metric of the relit image. The stored
//!    basis becomes [`crate::basis::Projected`], so a frame costs `K′` multiply-adds a
//!    pixel and every engine reads the planes as they are.
//! 3. **Quantisation** ([`planes::Quantizer`]): one step for every function plane
//!    (their errors weigh the same after step 2), from `bits` over the first plane's
//!    range; the stored numbers mean `offset + scale · q` as everywhere in relit.
//! 4. **Vector quantisation** ([`vq`], optional, seed 004): every pixel's stored values
//!    together become an index into a codebook of `C` vectors found by k-means. A
//!    frame under uniform lights then relights the codebook and looks every pixel up
//!    ([`crate::engine::lookup`]).
//! 4. **Perceptual gain** ([`gain`], optional): every function plane divided per
//!    pixel by a stored gain, so that one quantiser step is the same error on screen
//!    in dark and bright pixels.
//! 5. **Entropy coding** per tile ([`TileCodec`]): zstd of prediction residuals
//!    (lossless for the codes) or JPEG (lossy, what a browser decodes).
//!
//! [`pack`] runs them; [`unpack`] undoes them into ordinary maps ([`indexed`] into an
//! indexed image, for a codebook file).

pub mod bands;
pub mod budget;
pub mod container;
pub mod gain;
pub mod layout;
pub mod planes;
pub mod projection;
pub mod vq;

pub use layout::Layout;
pub use planes::{Quantizer, TileCodec};

use crate::basis::{Basis, BasisSpec, Projected};
use crate::maps::{CoefficientMaps, Metadata, RelightableImage};
use crate::sphere::Vec3;
use crate::{Error, Result};
use rayon::prelude::*;

/// Pixels the principal components are found on (a regular subsample beyond).
const PCA_PIXELS: usize = 1 << 16;

/// Pixels a block's principal components are found on: 160 or more a function for
/// K ≤ 25, and a quarter or a sixteenth of the work of all the pixels of a block of 128
/// or 256.
const BLOCK_PCA_PIXELS: usize = 1 << 12;

/// The most mip levels a file may hold: those of a side of 2^16 pixels, the largest
/// [`Header`] allows.
const MAX_LEVELS: usize = 17;

/// Tile sides a file may use.
pub const TILE_SIDES: std::ops::RangeInclusive<usize> = 16..=4096;

/// What [`pack`] does.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub layout: Layout,
    /// Components per function (`K′`); `None` keeps all `K` (a rotation: lossless
    /// before quantisation, and it decorrelates the planes).
    pub components: Option<usize>,
    /// Components of the chroma functions of `ycc` (default: a third of `K′`, at
    /// least 1).
    pub chroma: Option<usize>,
    /// Quantisation: the first plane's range in `2^bits − 1` steps (2–16). JPEG planes
    /// are always 8-bit, each over its own range.
    pub bits: u32,
    pub codec: TileCodec,
    /// Tile side in pixels.
    pub tile: usize,
    /// Vector quantisation: this many codebook entries (2–65536) instead of planes.
    pub codebook: Option<usize>,
    /// With a codebook: keep the `K′` components as planes and vector-quantise only the
    /// next this many principal components of every function channel (what the planes
    /// leave: the PCA residual), one index a pixel beside the planes.
    pub residual: Option<usize>,
    /// How JPEG planes map values to their 256 codes.
    pub jpeg_range: JpegRange,
    /// The capture's light directions, to weigh the components by the lights the maps
    /// will be seen under; `None` uses the basis' domain.
    pub directions: Option<Vec<Vec3>>,
    /// Divide the function planes by a stored per-pixel perceptual gain ([`gain`]).
    pub gain: bool,
    /// Find the principal components per block of this many pixels a side instead of
    /// once for the file ([`Header::pca_block`]); `None`: once.
    pub pca_block: Option<usize>,
    /// Store mip levels too ([`Header::levels`]), so that a zoomed-out view reads a
    /// coarse level's tiles instead of level 0's.
    pub mip_levels: bool,
}

impl Default for Settings {
    /// Near-lossless: all components, 12 bits, zstd.
    fn default() -> Self {
        Settings {
            layout: Layout::Rgb,
            components: None,
            chroma: None,
            bits: 12,
            codec: TileCodec::Zstd { level: 12 },
            tile: 512,
            codebook: None,
            residual: None,
            jpeg_range: JpegRange::Shared,
            directions: None,
            gain: false,
            pca_block: None,
            mip_levels: false,
        }
    }
}

impl Settings {
    /// A short description (`ycc k9/3 b10 zstd:12`).
    pub fn describe(&self) -> String {
        let k = self.components.map_or("all".to_string(), |k| k.to_string());
        let chroma = match (self.layout, self.chroma) {
            (Layout::Ycc, Some(c)) => format!("/{c}"),
            _ => String::new(),
        };
        let bits = match self.codec {
            c if c.is_image() && self.jpeg_range == JpegRange::PerPlane => " own".into(),
            c if c.is_image() => String::new(),
            _ => format!(" b{}", self.bits),
        };
        let vq = match (self.codebook, self.residual) {
            (Some(c), Some(r)) => format!(" vq{c}+r{r}"),
            (Some(c), None) => format!(" vq{c}"),
            (None, _) => String::new(),
        };
        let gain = if self.gain { " gain" } else { "" };
        let block = self.pca_block.map_or(String::new(), |b| format!(" pca{b}"));
        let mip = if self.mip_levels { " mip" } else { "" };
        format!(
            "{} k{k}{chroma}{bits}{vq}{gain}{block}{mip} {}",
            self.layout.name(),
            self.codec.name()
        )
    }
}

/// How JPEG planes map values to their 256 codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JpegRange {
    /// Every function plane with the first plane's step (its range in 256 codes): the
    /// error is spread evenly over the components, as for zstd planes, and a
    /// low-variance plane costs few bits. On item1 (hsh:25, ycc 9/3, q90) 35.17 dB at
    /// 8.9 bits/px against 35.57 at 34.7 for `PerPlane`, whose q75 gives 34.77 at 19.9.
    Shared,
    /// Each plane over its own range: finer for the minor components, at many more bits.
    PerPlane,
}

impl JpegRange {
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "shared" => Ok(JpegRange::Shared),
            "plane" => Ok(JpegRange::PerPlane),
            _ => Err(Error::invalid(format!(
                "JPEG range `{s}`: expected shared or plane"
            ))),
        }
    }
}

/// One stored plane: which channel and component, and its quantiser.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlaneEntry {
    pub channel: String,
    pub index: usize,
    #[serde(flatten)]
    pub quantizer: Quantizer,
}

/// Everything in a compressed file but its tiles.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Header {
    /// What every relightable file states (basis, colour space, camera, fit…),
    /// flattened into the header's fields.
    #[serde(flatten)]
    pub meta: Metadata,
    pub width: usize,
    pub height: usize,
    pub tile: usize,
    pub layout: Layout,
    pub codec: TileCodec,
    pub planes: Vec<PlaneEntry>,
    /// Vector quantisation: the codebook's entries. Its values (in `planes`' order and
    /// quantisers) are the first section, and each pixel's index (tiles of one plane)
    /// replaces the planes' tiles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub codebook: Option<usize>,
    /// With a codebook, the components it holds when the pixels keep their planes too
    /// (vector quantisation of the PCA residual): components `K′ … K′+R−1` of each
    /// function channel, channel by channel, each with the quantiser of its codebook
    /// values. The codebook section and the index tiles then follow the planes' tiles
    /// (always zstd), and a pixel's components past its planes' are its entry's.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub residual: Vec<PlaneEntry>,
    /// Whether the function planes are divided by the per-pixel plane `gain`
    /// ([`gain`]), the last of the planes.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub gain: bool,
    /// Principal components found per block of this many pixels a side (blocks in
    /// raster order from the top left, smaller at the right and bottom edges) instead
    /// of once for the file. The planes then hold each block's own `K′` coordinates;
    /// `meta.basis` is the basis they decode into (`K` functions, not a projection),
    /// and the last section holds every block's `rows × K` maps onto it
    /// (docs/format.md): a pixel's coefficients are `c = Pᵀ c′`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pca_block: Option<usize>,
    /// Whether depth follows the planes (f32, lossless).
    pub depth: bool,
    /// Mip levels the file holds, level 0 included (OpenEXR's MIPMAP_LEVELS sizes,
    /// rounding down: [`crate::maps::mip_sizes`]). Level `L ≥ 1` holds the 2×2
    /// means of level `L − 1`'s maps (and of its depth's hits), coded with level 0's
    /// planes, projection and quantisers, so that one basis relights every level. Its
    /// sections follow all of level 0's: its planes' tiles, then its depth's. Files of
    /// planes with one projection only (no codebook, no projection a block).
    #[serde(default = "one_level", skip_serializing_if = "is_one_level")]
    pub levels: usize,
}

fn one_level() -> usize {
    1
}

fn is_one_level(levels: &usize) -> bool {
    *levels == 1
}

impl Header {
    /// Tiles across and down.
    pub fn tiles(&self) -> (usize, usize) {
        (
            self.width.div_ceil(self.tile),
            self.height.div_ceil(self.tile),
        )
    }

    /// The pixel rectangle `(x0, y0, w, h)` of tile `t` (raster order).
    pub fn tile_rect(&self, t: usize) -> (usize, usize, usize, usize) {
        tile_rect(self.width, self.height, self.tile, t)
    }

    /// The names of the per-pixel planes: the layout's (albedo), then the gain.
    pub fn per_pixel_channels(&self) -> Vec<&'static str> {
        let mut names = self.layout.channels().1.to_vec();
        if self.gain {
            names.push(gain::CHANNEL);
        }
        names
    }

    /// The sections the file holds: every plane's tiles (or the codebook and the index
    /// plane's tiles; or both, the planes' first, for a codebook of the residual), then
    /// depth's, then the blocks' principal components when they are found per block;
    /// then each finer mip level's ([`Header::level_sections`]).
    pub fn sections(&self) -> usize {
        let finer = (1..self.levels.min(MAX_LEVELS)).map(|l| self.level_sections(l).len());
        self.level_zero_sections() + finer.sum::<usize>()
    }

    /// Level 0's sections: [`Header::sections`] of a file without levels.
    fn level_zero_sections(&self) -> usize {
        let (a, d) = self.tiles();
        self.plane_sections() + self.depth as usize * a * d + self.pca_block.is_some() as usize
    }

    /// The size of level `level` (level 0: the image's).
    pub fn level_size(&self, level: usize) -> (usize, usize) {
        let shift = level.min(usize::BITS as usize - 1);
        ((self.width >> shift).max(1), (self.height >> shift).max(1))
    }

    /// The sizes of the levels the file holds, level 0 first (at most as many as the
    /// image has: a header is not trusted before it is checked).
    pub fn level_sizes(&self) -> Vec<(usize, usize)> {
        let mut sizes = crate::maps::mip_sizes(self.width, self.height);
        sizes.truncate(self.levels.max(1));
        sizes
    }

    /// The sections of level `level ≥ 1` in the file: its planes' tiles, then its
    /// depth's.
    pub fn level_sections(&self, level: usize) -> std::ops::Range<usize> {
        let mut start = self.level_zero_sections();
        for l in 1..=level {
            let (w, h) = self.level_size(l);
            let tiles = w.div_ceil(self.tile) * h.div_ceil(self.tile);
            let len = tiles.saturating_mul(self.planes.len() + self.depth as usize);
            if l == level {
                return start..start.saturating_add(len);
            }
            start = start.saturating_add(len);
        }
        start..start
    }

    /// Level `level`'s header, as a file of that one level would have it: its size,
    /// and level 0's planes and quantisers ([`Packed::level`] gives its sections).
    pub fn at_level(&self, level: usize) -> Header {
        let (width, height) = self.level_size(level);
        Header {
            width,
            height,
            levels: 1,
            ..self.clone()
        }
    }

    /// The level and its own section number (as [`Header::at_level`]'s file numbers
    /// them) of the file's section `s`.
    pub fn section_level(&self, s: usize) -> (usize, usize) {
        let zero = self.level_zero_sections();
        if s < zero {
            return (0, s);
        }
        for level in 1..self.levels.min(MAX_LEVELS) {
            let range = self.level_sections(level);
            if range.contains(&s) {
                return (level, s - range.start);
            }
        }
        (self.levels, s)
    }

    /// Whether every pixel is only an index (a codebook file without planes): frames
    /// under uniform lights can then relight the entries and look pixels up.
    pub fn indexed_pixels(&self) -> bool {
        self.codebook.is_some() && self.residual.is_empty()
    }

    /// The section of the codebook, when there is one: the first, or the one after the
    /// planes' tiles for a codebook of the residual. The index tiles follow it.
    pub fn codebook_section(&self) -> Option<usize> {
        let (a, d) = self.tiles();
        self.codebook
            .map(|_| (!self.indexed_pixels()) as usize * self.planes.len() * a * d)
    }

    /// What the codebook's values are, in order: the planes, or the residual's
    /// components.
    pub fn codebook_values(&self) -> &[PlaneEntry] {
        if self.residual.is_empty() {
            &self.planes
        } else {
            &self.residual
        }
    }

    /// The codec of the index tiles: the file's when it is lossless, zstd otherwise
    /// (indices must come back exactly).
    pub fn index_codec(&self) -> TileCodec {
        if self.codec.lossless() {
            self.codec
        } else {
            TileCodec::Zstd { level: 19 }
        }
    }

    /// The sections of the planes and of the codebook and its index tiles: the first.
    fn plane_sections(&self) -> usize {
        let (a, d) = self.tiles();
        let tiles = a * d;
        let planes = if self.indexed_pixels() {
            0
        } else {
            self.planes.len() * tiles
        };
        planes + self.codebook.map_or(0, |_| 1 + tiles)
    }

    /// Blocks of [`Header::pca_block`] across and down (none without it).
    pub fn pca_blocks(&self) -> (usize, usize) {
        match self.pca_block {
            Some(b) => (self.width.div_ceil(b), self.height.div_ceil(b)),
            None => (0, 0),
        }
    }

    /// Bytes per index of a codebook file.
    fn index_width(&self) -> usize {
        if self.codebook.unwrap_or(0) <= 256 {
            1
        } else {
            2
        }
    }

    /// The function channels and their component counts, then the per-pixel planes,
    /// checked against the layout; the number of functions `K′` of the basis.
    fn check(&self) -> Result<usize> {
        let bad = |why: String| Error::parse(format!("compressed file: {why}"));
        if self.width == 0 || self.height == 0 || self.width > 1 << 16 || self.height > 1 << 16 {
            return Err(bad(format!("bad size {}×{}", self.width, self.height)));
        }
        if !TILE_SIDES.contains(&self.tile) {
            return Err(bad(format!("bad tile side {}", self.tile)));
        }
        if let Some(c) = self.codebook {
            if !(2..=vq::MAX_ENTRIES).contains(&c) {
                return Err(bad(format!("a codebook of {c} entries")));
            }
            if self.residual.is_empty() && !self.codec.lossless() {
                return Err(bad("codebook indices need a lossless codec".into()));
            }
            if self.gain {
                return Err(bad("a codebook file has no gain plane".into()));
            }
            if self.pca_block.is_some() {
                return Err(bad(
                    "a codebook file has one projection, not one a block".into()
                ));
            }
        }
        if let Some(b) = self.pca_block {
            if !TILE_SIDES.contains(&b) {
                return Err(bad(format!("bad block side {b}")));
            }
        }
        let most = crate::maps::mip_sizes(self.width, self.height).len();
        if self.levels == 0 || self.levels > most {
            return Err(bad(format!(
                "{} mip levels of a {}×{} image (1 to {most})",
                self.levels, self.width, self.height
            )));
        }
        if self.levels > 1 && (self.codebook.is_some() || self.pca_block.is_some()) {
            return Err(bad(
                "mip levels with a codebook or a projection a block".into()
            ));
        }
        let functions = self.layout.channels().0;
        let per_pixel = self.per_pixel_channels();
        let mut counts = vec![0usize; functions.len()];
        let mut expected: Vec<(String, usize)> = Vec::new();
        for p in &self.planes {
            if let Some(f) = functions.iter().position(|&c| c == p.channel) {
                expected.push((p.channel.clone(), counts[f]));
                counts[f] += 1;
            } else if per_pixel.contains(&p.channel.as_str()) {
                expected.push((p.channel.clone(), 0));
            } else {
                return Err(bad(format!("plane of unknown channel `{}`", p.channel)));
            }
            let q = &p.quantizer;
            if q.levels == 0 || q.levels > self.codec.max_levels() {
                return Err(bad(format!("plane with {} levels", q.levels)));
            }
            if !(q.coding.scale.is_finite() && q.coding.offset.is_finite() && q.coding.scale >= 0.0)
            {
                return Err(bad("plane with a non-finite coding".into()));
            }
        }
        if self
            .planes
            .iter()
            .zip(&expected)
            .any(|(p, (c, i))| p.channel != *c || p.index != *i)
        {
            return Err(bad("planes out of order".into()));
        }
        let present = |c: &str| self.planes.iter().filter(|p| p.channel == c).count();
        if per_pixel.iter().any(|c| present(c) != 1) {
            return Err(bad(format!("needs one plane each of {per_pixel:?}")));
        }
        let k = counts[0];
        if k == 0 || counts.iter().any(|&c| c > k) {
            return Err(bad(format!("bad component counts {counts:?}")));
        }
        Ok(k + self.check_residual(k, functions)?)
    }

    /// The residual's components a function channel ([`Header::residual`]), checked:
    /// components `k …` of every function channel in order, with codebook quantisers.
    fn check_residual(&self, k: usize, functions: &[&str]) -> Result<usize> {
        let bad = |why: &str| Error::parse(format!("compressed file: {why}"));
        if self.residual.is_empty() {
            return Ok(0);
        }
        if self.codebook.is_none() {
            return Err(bad("residual components without a codebook"));
        }
        let r = self.residual.len() / functions.len();
        let expected = functions
            .iter()
            .flat_map(|&c| (k..k + r).map(move |j| (c, j)));
        if r == 0
            || r * functions.len() != self.residual.len()
            || self
                .residual
                .iter()
                .zip(expected)
                .any(|(p, (c, j))| p.channel != c || p.index != j)
        {
            return Err(bad("residual components out of order"));
        }
        for q in self.residual.iter().map(|p| &p.quantizer) {
            if q.levels == 0 || q.levels > 1 << 16 {
                return Err(bad("residual component with bad levels"));
            }
            if !(q.coding.scale.is_finite() && q.coding.offset.is_finite() && q.coding.scale >= 0.0)
            {
                return Err(bad("residual component with a non-finite coding"));
            }
        }
        Ok(r)
    }
}

/// The pixel rectangle `(x0, y0, w, h)` of tile `t` (raster order) of a `width ×
/// height` image in tiles of side `tile`.
fn tile_rect(width: usize, height: usize, tile: usize, t: usize) -> (usize, usize, usize, usize) {
    let across = width.div_ceil(tile);
    let (x0, y0) = ((t % across) * tile, (t / across) * tile);
    (x0, y0, tile.min(width - x0), tile.min(height - y0))
}

/// A compressed image in memory: the header and its sections (tiles of each plane in
/// raster order, plane after plane, then depth's tiles).
#[derive(Clone, Debug, PartialEq)]
pub struct Packed {
    pub header: Header,
    pub sections: Vec<Vec<u8>>,
}

impl Packed {
    /// Bytes of the sections.
    pub fn payload_bytes(&self) -> usize {
        self.sections.iter().map(Vec::len).sum()
    }

    /// Mip level `level` as a file of that one level ([`Header::at_level`]): what
    /// [`unpack`], [`unpack_region`] and [`unpack_depth_region`] read. Level 0 is the
    /// file without its finer levels' sections; any other takes its own sections out of
    /// `self`.
    pub fn level(mut self, level: usize) -> Result<Packed> {
        let header = &self.header;
        header.check()?;
        if self.sections.len() != header.sections() {
            return Err(Error::parse("compressed file: wrong number of sections"));
        }
        if level >= header.levels {
            return Err(Error::invalid(format!(
                "level {level} of a file of {} mip level{}",
                header.levels,
                if header.levels == 1 { "" } else { "s" }
            )));
        }
        let at = header.at_level(level);
        let sections = if level == 0 {
            self.sections.truncate(header.level_zero_sections());
            self.sections
        } else {
            let range = header.level_sections(level);
            self.sections.drain(range).collect()
        };
        Ok(Packed {
            header: at,
            sections,
        })
    }
}

/// The basis stored as an inner basis and a map onto it: `(inner, P)` with `P` the
/// identity for a basis that is not projected.
/// The basis planes of `rows` components of `principal` relight with: the projection
/// composed with the map the maps' basis `spec` already had.
fn stored_basis(
    spec: &BasisSpec,
    principal: &projection::Principal,
    rows: usize,
) -> Result<BasisSpec> {
    let (inner, prior) = inner_and_map(spec)?;
    let inner_k = inner.len();
    let k = prior.len() / inner_k;
    let mut matrix = vec![0.0; rows * inner_k];
    for j in 0..rows {
        for i in 0..inner_k {
            matrix[j * inner_k + i] = (0..k)
                .map(|m| principal.basis_map[j * k + m] * prior[m * inner_k + i])
                .sum();
        }
    }
    Ok(Projected::new(inner, matrix)?.spec())
}

fn inner_and_map(spec: &BasisSpec) -> Result<(Box<dyn Basis>, Vec<f64>)> {
    let basis = spec.build()?;
    if let Some(p) = basis.as_any().downcast_ref::<Projected>() {
        let inner = p.inner().spec().build()?;
        return Ok((inner, p.matrix().to_vec()));
    }
    let k = basis.len();
    let mut identity = vec![0.0; k * k];
    (0..k).for_each(|i| identity[i * k + i] = 1.0);
    Ok((basis, identity))
}

/// Compress `image` with `settings`.
pub fn pack(image: &RelightableImage, settings: &Settings) -> Result<Packed> {
    pack_with_gain(image, settings, None)
}

/// [`pack`], with the perceptual gain ([`gain::perceptual`] of the image at the
/// settings' directions) when the caller has it already (`--budget` packs one image
/// many ways); `None` computes it when the settings ask for it.
pub fn pack_with_gain(
    image: &RelightableImage,
    settings: &Settings,
    perceptual_gain: Option<&[f32]>,
) -> Result<Packed> {
    if settings.mip_levels && (settings.codebook.is_some() || settings.pca_block.is_some()) {
        return Err(Error::invalid(
            "mip levels are coded with level 0's projection and quantisers: a codebook or \
             principal components per block do not combine with them",
        ));
    }
    let (mut packed, fixed) = pack_level(image, settings, perceptual_gain, None)?;
    if settings.mip_levels {
        let sizes = crate::maps::mip_sizes(image.width(), image.height());
        let mut finer: Option<RelightableImage> = None;
        for pair in sizes.windows(2) {
            let level = crate::maps::halved(finer.as_ref().unwrap_or(image), pair[1]);
            let (coded, _) = pack_level(&level, settings, None, Some(&fixed))?;
            if coded.header.meta.basis != packed.header.meta.basis {
                return Err(Error::invalid(
                    "a mip level was coded in another basis than level 0",
                ));
            }
            packed.sections.extend(coded.sections);
            finer = Some(level);
        }
        packed.header.levels = sizes.len();
    }
    Ok(packed)
}

/// What level 0 of a file fixes for its finer mip levels: the projection (per
/// projection group) and every plane's quantiser.
struct Fixed {
    principals: Vec<projection::Principal>,
    planes: Vec<PlaneEntry>,
}

/// [`pack_with_gain`] of one level: `fixed` (level 0's) gives the projection and the
/// quantisers, where `None` finds them from `image`. Returns what it fixed.
fn pack_level(
    image: &RelightableImage,
    settings: &Settings,
    perceptual_gain: Option<&[f32]>,
    fixed: Option<&Fixed>,
) -> Result<(Packed, Fixed)> {
    let maps = &image.maps;
    let (n, k) = (maps.pixels(), maps.k);
    let basis = image.meta.basis.build()?;
    if basis.len() != k {
        return Err(Error::invalid("the maps and their basis disagree on K"));
    }
    let Counts {
        components,
        chroma,
        extra,
    } = Counts::checked(settings, k)?;
    let layout = settings.layout;
    let (functions, _) = layout.channels();

    // The gain as a reader will decode it (the function planes carry its error).
    let gain_plane: Option<(std::borrow::Cow<[f32]>, Quantizer)> = if settings.gain {
        let values: std::borrow::Cow<[f32]> = match perceptual_gain {
            Some(g) if g.len() == n => g.into(),
            Some(_) => return Err(Error::invalid("the gain has the wrong number of pixels")),
            None => gain::perceptual(maps, basis.as_ref(), settings.directions.as_deref()).into(),
        };
        let fixed_gain = fixed.and_then(|f| f.planes.iter().find(|p| p.channel == gain::CHANNEL));
        let quantizer = match fixed_gain {
            Some(entry) => entry.quantizer,
            None => gain_quantizer(&PlaneStats::of(&values, settings.codec), settings.codec),
        };
        Some((values, quantizer))
    } else {
        None
    };
    // Its tiles are coded once: their bytes are the gain plane's sections, and what a
    // reader decodes from them is the divisor.
    let (gain_sections, divisor) = match &gain_plane {
        Some((values, q)) => {
            let (sections, decoded) = coded_gain(values, q, maps.width, maps.height, settings)?;
            (sections, Some(decoded))
        }
        None => (Vec::new(), None),
    };

    // Layout: the function channels' coefficient planes (plane i·F + f), per-pixel
    // planes (albedo) apart.
    let gram = projection::gram(basis.as_ref(), settings.directions.as_deref());
    let fcount = functions.len();
    // A pixel's coefficients of every function channel (`undivided`), divided by its
    // gain where there is one.
    let function_values = |p: usize, all: &mut [f32]| {
        undivided_all(layout, maps, p, all);
        if let Some(d) = &divisor {
            all.iter_mut().for_each(|v| *v /= d[p]);
        }
    };
    let counts = Counts {
        components,
        chroma,
        extra,
    }
    .per_function(layout);
    // Principal components of the first function channel (R, G and B alike for rgb),
    // once for the file; or once a block for each group of function channels that
    // share a projection (ycc's chroma has its own there: the luma's leading
    // directions hold a block's chroma poorly).
    let groups = projection_groups(layout, settings.pca_block.is_some());
    let principal_of = |pixels: &[usize], group: usize, most: usize| {
        let channels = &groups[group];
        let step = (pixels.len() / most).max(1);
        let chosen: Vec<usize> = pixels.iter().step_by(step).copied().collect();
        // The group's channels' coefficients, pixel by pixel in order.
        let vectors: Vec<f64> = chosen
            .par_chunks(1024)
            .flat_map_iter(|chunk| {
                let mut all = vec![0.0f32; fcount * k];
                let mut out = Vec::with_capacity(chunk.len() * channels.len() * k);
                for &p in chunk {
                    function_values(p, &mut all);
                    for &f in channels {
                        out.extend(all[f * k..(f + 1) * k].iter().map(|&v| v as f64));
                    }
                }
                out
            })
            .collect();
        // A codebook of the residual holds the next `extra` components of each.
        projection::principal(&gram, &vectors, k, counts[channels[0]] + extra)
    };
    let width = maps.width;
    let whole: Vec<projection::Principal> = match fixed {
        Some(f) => f.principals.clone(),
        None => {
            let all: Vec<usize> = (0..n).collect();
            (0..groups.len())
                .map(|g| principal_of(&all, g, PCA_PIXELS))
                .collect::<Result<_>>()?
        }
    };
    let fixed_principals = whole.clone();
    let principals: Vec<Vec<projection::Principal>> = match settings.pca_block {
        None => vec![whole],
        // Each block's directions turned to point the way the file's do (a direction's
        // sign is arbitrary): otherwise a plane changes sign from block to block, its
        // range doubles and so does the quantiser's step.
        Some(b) => (0..maps.width.div_ceil(b) * maps.height.div_ceil(b))
            .into_par_iter()
            .map(|block| {
                let (x0, y0, w, h) = tile_rect(maps.width, maps.height, b, block);
                let pixels: Vec<usize> = (y0..y0 + h)
                    .flat_map(|y| y * width + x0..y * width + x0 + w)
                    .collect();
                (0..groups.len())
                    .map(|g| {
                        let mut own = principal_of(&pixels, g, BLOCK_PCA_PIXELS)?;
                        own.orient_like(&whole[g]);
                        Ok(own)
                    })
                    .collect::<Result<Vec<_>>>()
            })
            .collect::<Result<_>>()?,
    };
    let group_of: Vec<usize> = (0..fcount).map(|f| group_of(&groups, f)).collect();
    let principal_at = |p: usize, f: usize| -> &projection::Principal {
        let block = match settings.pca_block {
            None => 0,
            Some(b) => {
                let (x, y) = (p % width, p / width);
                (y / b) * width.div_ceil(b) + x / b
            }
        };
        &principals[block][group_of[f]]
    };

    // Project every pixel: plane (f, j) of components, then the residual's components
    // (f, components + r) at `residual_start + f · extra + r`.
    let residual_start: usize = counts.iter().sum();
    let mut projected: Vec<Vec<f32>> = counts
        .iter()
        .map(|&c| c + extra)
        .flat_map(|c| (0..c).map(|_| vec![0.0f32; n]))
        .collect();
    let starts: Vec<usize> = counts
        .iter()
        .scan(0, |s, &c| {
            let at = *s;
            *s += c;
            Some(at)
        })
        .collect();
    const CHUNK: usize = 4096;
    {
        chunks_of_planes(&mut projected, CHUNK)
            .into_par_iter()
            .enumerate()
            .for_each(|(chunk, mut outs)| {
                let mut all = vec![0.0f32; fcount * k];
                let mut y = vec![0.0f32; components + extra];
                for local in 0..outs[0].len() {
                    let p = chunk * CHUNK + local;
                    function_values(p, &mut all);
                    for (f, &count) in counts.iter().enumerate() {
                        let c = &all[f * k..(f + 1) * k];
                        let rows = if extra > 0 { components + extra } else { count };
                        principal_at(p, f).apply(c, &mut y[..rows]);
                        for j in 0..count {
                            outs[starts[f] + j][local] = y[j];
                        }
                        for r in 0..extra {
                            outs[residual_start + f * extra + r][local] = y[components + r];
                        }
                    }
                }
            });
    }
    // Per-pixel albedo of lrgb: the least-squares scale of each channel's function onto
    // the luminance function, in the relit image's metric: (cᵀ G l) / (lᵀ G l), with
    // G l formed once a pixel for the three channels (this is most of an lrgb pack).
    // The luminance function is the undivided one: a reader multiplies by the gain and
    // by the albedo.
    let mut albedo: Vec<Vec<f32>> = Vec::new();
    if layout == Layout::Lrgb {
        let per_pixel: Vec<[f32; 3]> = (0..n)
            .into_par_iter()
            .map_init(
                || (vec![0.0f64; k], vec![0.0f64; k]),
                |scratch, p| albedo_at(maps, &gram, p, scratch),
            )
            .collect();
        albedo = (0..3)
            .map(|ch| per_pixel.iter().map(|a| a[ch]).collect())
            .collect();
    }

    // Quantisers.
    let range = |v: &[f32]| crate::storage::FiniteRange::of(v.iter().copied());
    let function_planes: usize = counts.iter().sum();
    let plane_values = |i: usize| -> &[f32] {
        if i < function_planes {
            &projected[i]
        } else {
            &albedo[i - function_planes]
        }
    };
    let quantizers = plane_entries(
        settings,
        &counts,
        albedo.len(),
        fixed.map(|f| f.planes.as_slice()),
        &|i| PlaneStats::of(plane_values(i), settings.codec),
    )?;
    let mut entries: Vec<(PlaneEntry, &[f32])> = quantizers
        .into_iter()
        .enumerate()
        .map(|(i, entry)| (entry, plane_values(i)))
        .collect();
    if let Some((values, quantizer)) = &gain_plane {
        entries.push((
            PlaneEntry {
                channel: gain::CHANNEL.to_string(),
                index: 0,
                quantizer: *quantizer,
            },
            values,
        ));
    }

    // The residual's components, each of its own range in 16 bits (a codebook is
    // small): the codebook's values.
    let residual: Vec<(PlaneEntry, &[f32])> = (0..fcount * extra)
        .map(|i| {
            let plane = &projected[residual_start + i];
            let entry = residual_entry(layout, components, extra, i, range(plane));
            (entry, plane.as_slice())
        })
        .collect();

    // Vector quantisation of every pixel's stored values together, or of the residual.
    let quantized = match settings.codebook {
        Some(entries_wanted) if extra > 0 => Some(quantize_vectors(
            &residual,
            &vec![extra; fcount],
            n,
            entries_wanted,
        )?),
        Some(entries_wanted) => {
            if !settings.codec.lossless() {
                return Err(Error::invalid(
                    "a codebook's indices need the lossless codec (zstd), not an image codec",
                ));
            }
            Some(quantize_vectors(&entries, &counts, n, entries_wanted)?)
        }
        None => None,
    };

    // The basis the planes relight with: P of the components composed with the map
    // the input basis already had. Blocks' planes decode into the input basis instead,
    // each by its own P (the last section).
    let stored_basis = match settings.pca_block {
        Some(_) => image.meta.basis.clone(),
        None => stored_basis(&image.meta.basis, &principals[0][0], components + extra)?,
    };

    let header = Header {
        meta: Metadata {
            format_version: crate::maps::FORMAT_VERSION,
            basis: stored_basis,
            ..image.meta.clone()
        },
        width: maps.width,
        height: maps.height,
        tile: settings.tile,
        layout,
        codec: settings.codec,
        planes: entries.iter().map(|(e, _)| e.clone()).collect(),
        codebook: quantized.as_ref().map(|(book, _)| book.entries()),
        residual: residual.iter().map(|(e, _)| e.clone()).collect(),
        gain: settings.gain,
        pca_block: settings.pca_block,
        depth: image.depth.is_some(),
        levels: 1,
    };
    let (across, down) = header.tiles();
    let tiles = across * down;
    let tile_codes =
        |t: usize, code: &dyn Fn(usize) -> u16| tile_codes(maps.width, header.tile_rect(t), code);
    let mut sections: Vec<Vec<u8>> = Vec::new();
    if !header.indexed_pixels() {
        // The gain plane, the last, is coded already.
        let coded = entries.len() - gain_plane.is_some() as usize;
        let jobs: Vec<(usize, usize)> = (0..coded)
            .flat_map(|p| (0..tiles).map(move |t| (p, t)))
            .collect();
        sections = jobs
            .par_iter()
            .map(|&(p, t)| {
                let (entry, plane) = &entries[p];
                let q = &entry.quantizer;
                let codes = tile_codes(t, &|i| q.code(plane[i]));
                let (_, _, w, h) = header.tile_rect(t);
                planes::encode_tile(&codes, w, h, q.width(), settings.codec)
            })
            .collect::<Result<_>>()?;
        sections.extend(gain_sections);
    }
    if let Some((book, indices)) = &quantized {
        sections.push(codebook_bytes(&header, book)?);
        let codec = header.index_codec();
        let width = header.index_width();
        let more: Vec<Vec<u8>> = (0..tiles)
            .into_par_iter()
            .map(|t| {
                let codes = tile_codes(t, &|i| indices[i]);
                let (_, _, w, h) = header.tile_rect(t);
                planes::encode_tile(&codes, w, h, width, codec)
            })
            .collect::<Result<_>>()?;
        sections.extend(more);
    }
    if let Some(depth) = &image.depth {
        let more: Vec<Vec<u8>> = (0..tiles)
            .into_par_iter()
            .map(|t| {
                let (x0, y0, w, h) = header.tile_rect(t);
                let mut values = Vec::with_capacity(w * h);
                for y in y0..y0 + h {
                    values.extend_from_slice(&depth[y * maps.width + x0..y * maps.width + x0 + w]);
                }
                encode_floats(&values)
            })
            .collect::<Result<_>>()?;
        sections.extend(more);
    }
    if settings.pca_block.is_some() {
        // Each block's P as the reader uses it: f32, rounded once here.
        sections.push(
            principals
                .iter()
                .flatten()
                .flat_map(|p| p.basis_map.iter().map(|&v| v as f32))
                .flat_map(f32::to_le_bytes)
                .collect(),
        );
    }
    let fixed = Fixed {
        principals: fixed_principals,
        planes: header.planes.clone(),
    };
    Ok((Packed { header, sections }, fixed))
}

/// Every `chunk` pixels of `planes` (all of one length), each chunk as its part of every
/// plane: what threads that each project a chunk of pixels onto every plane write.
fn chunks_of_planes(planes: &mut [Vec<f32>], chunk: usize) -> Vec<Vec<&mut [f32]>> {
    let pixels = planes.first().map_or(0, Vec::len);
    let mut parts: Vec<_> = planes.iter_mut().map(|p| p.chunks_mut(chunk)).collect();
    (0..pixels.div_ceil(chunk))
        .map(|_| {
            parts
                .iter_mut()
                .map(|it| it.next().expect("planes of one length"))
                .collect()
        })
        .collect()
}

/// Every function channel's coefficients of `layout` at pixel `p` of `maps`, before any
/// gain divides them, into `out` (channel `f`'s `K` at `f·K`): [`undivided`] of each,
/// with the colours of a coefficient read and turned once for all channels.
fn undivided_all(layout: Layout, maps: &CoefficientMaps, p: usize, out: &mut [f32]) {
    let k = maps.k;
    let n = maps.pixels();
    let data = &maps.data;
    for i in 0..k {
        let rgb = [
            data[3 * i * n + p],
            data[(3 * i + 1) * n + p],
            data[(3 * i + 2) * n + p],
        ];
        match layout {
            Layout::Rgb => (0..3).for_each(|f| out[f * k + i] = rgb[f]),
            Layout::Ycc => {
                let ycc = layout::ycc(rgb);
                (0..3).for_each(|f| out[f * k + i] = ycc[f]);
            }
            Layout::Lrgb => out[i] = layout::luma(rgb),
        }
    }
}

/// Coefficient `i` of function channel `f` of `layout` at pixel `p` of `maps`, before
/// any gain divides it.
fn undivided(layout: Layout, maps: &CoefficientMaps, i: usize, f: usize, p: usize) -> f32 {
    let rgb = || {
        [
            maps.plane(i, 0)[p],
            maps.plane(i, 1)[p],
            maps.plane(i, 2)[p],
        ]
    };
    match layout {
        Layout::Rgb => maps.plane(i, f)[p],
        Layout::Ycc => layout::ycc(rgb())[f],
        Layout::Lrgb => layout::luma(rgb()),
    }
}

/// `lrgb`'s albedo of pixel `p`: the least-squares scale of each channel's function
/// onto the luminance function in the relit image's metric `gram`, (cᵀ G l) / (lᵀ G l),
/// with G l formed once for the three channels. `scratch`: two vectors of `K`.
fn albedo_at(
    maps: &CoefficientMaps,
    gram: &[f64],
    p: usize,
    (l, gl): &mut (Vec<f64>, Vec<f64>),
) -> [f32; 3] {
    let k = maps.k;
    for (i, li) in l.iter_mut().enumerate() {
        *li = undivided(Layout::Lrgb, maps, i, 0, p) as f64;
    }
    for (i, gli) in gl.iter_mut().enumerate() {
        *gli = gram[i * k..(i + 1) * k]
            .iter()
            .zip(l.iter())
            .map(|(g, l)| g * l)
            .sum();
    }
    let ll: f64 = l.iter().zip(gl.iter()).map(|(a, b)| a * b).sum();
    std::array::from_fn(|ch| {
        if ll > 1e-20 {
            let cl: f64 = (0..k).map(|i| maps.plane(i, ch)[p] as f64 * gl[i]).sum();
            (cl / ll) as f32
        } else {
            1.0
        }
    })
}

/// How many planes `settings` keeps of a `k`-coefficient basis, checked with the rest
/// of the settings.
struct Counts {
    /// Components per function (`K′`).
    components: usize,
    /// Components of `ycc`'s chroma functions.
    chroma: usize,
    /// Components of the residual a codebook holds.
    extra: usize,
}

impl Counts {
    fn checked(settings: &Settings, k: usize) -> Result<Counts> {
        if !(2..=16).contains(&settings.bits) {
            return Err(Error::invalid(format!(
                "bits must be 2–16, not {}",
                settings.bits
            )));
        }
        if !TILE_SIDES.contains(&settings.tile) {
            return Err(Error::invalid(format!(
                "tile side must be {}–{}, not {}",
                TILE_SIDES.start(),
                TILE_SIDES.end(),
                settings.tile
            )));
        }
        let components = settings.components.unwrap_or(k);
        if components == 0 || components > k {
            return Err(Error::invalid(format!(
                "{components} components of a {}-coefficient basis: choose 1 to {k}",
                k
            )));
        }
        let chroma = settings
            .chroma
            .unwrap_or(components.div_ceil(3))
            .clamp(1, components);
        let extra = settings.residual.unwrap_or(0);
        if settings.residual.is_some() {
            if settings.codebook.is_none() {
                return Err(Error::invalid(
                    "residual components are vector-quantised: give a codebook (--codebook) too",
                ));
            }
            if extra == 0 || components + extra > k {
                return Err(Error::invalid(format!(
                    "{components} planes and {extra} residual components of a {k}-coefficient basis: choose 1 to {} residual components",
                    k - components
                )));
            }
        }
        if settings.gain && settings.codebook.is_some() {
            return Err(Error::invalid(
                "a codebook and the perceptual gain do not combine: choose one",
            ));
        }
        if let Some(b) = settings.pca_block {
            if settings.codebook.is_some() {
                return Err(Error::invalid(
                    "a codebook needs one projection for the whole file: principal components per block do not combine with it",
                ));
            }
            if !TILE_SIDES.contains(&b) {
                return Err(Error::invalid(format!(
                    "block side must be {}–{}, not {b}",
                    TILE_SIDES.start(),
                    TILE_SIDES.end()
                )));
            }
        }
        Ok(Counts {
            components,
            chroma,
            extra,
        })
    }

    /// The components of each function channel of `layout`.
    fn per_function(&self, layout: Layout) -> Vec<usize> {
        (0..layout.channels().0.len())
            .map(|f| {
                if layout == Layout::Ycc && f > 0 {
                    self.chroma
                } else {
                    self.components
                }
            })
            .collect()
    }
}

/// The function channels that share one projection, group by group: every channel of
/// the layout in one group, except that with a projection a block, `ycc`'s chroma
/// channels are a group of their own.
fn projection_groups(layout: Layout, per_block: bool) -> Vec<Vec<usize>> {
    match (layout, per_block) {
        (Layout::Rgb, _) => vec![vec![0, 1, 2]],
        (Layout::Ycc, true) => vec![vec![0], vec![1, 2]],
        (Layout::Ycc, false) | (Layout::Lrgb, _) => vec![vec![0]],
    }
}

/// The projection group ([`projection_groups`]) of function channel `f`.
fn group_of(groups: &[Vec<usize>], f: usize) -> usize {
    groups.iter().position(|g| g.contains(&f)).unwrap_or(0)
}

/// The codes of the pixels of the rectangle `(x0, y0, w, h)` of a plane `width` pixels
/// wide, row by row: `code(i)` of each pixel index `i`.
fn tile_codes(
    width: usize,
    (x0, y0, w, h): (usize, usize, usize, usize),
    code: &dyn Fn(usize) -> u16,
) -> Vec<u16> {
    let mut codes = Vec::with_capacity(w * h);
    for y in y0..y0 + h {
        codes.extend((y * width + x0..y * width + x0 + w).map(code));
    }
    codes
}

/// The gain plane coded by `quantizer` in tiles with [`gain::codec`]: the tiles' bytes
/// (its sections in the file) and the gain a reader applies from them, per pixel.
fn coded_gain(
    plane: &[f32],
    quantizer: &Quantizer,
    width: usize,
    height: usize,
    settings: &Settings,
) -> Result<(Vec<Vec<u8>>, Vec<f32>)> {
    let codec = gain::codec(settings.codec);
    let tiles = width.div_ceil(settings.tile) * height.div_ceil(settings.tile);
    let coded: Vec<(Vec<u8>, Vec<u16>)> = (0..tiles)
        .into_par_iter()
        .map(|t| {
            let rect = tile_rect(width, height, settings.tile, t);
            let (_, _, w, h) = rect;
            let mut codes = tile_codes(width, rect, &|i| quantizer.code(plane[i]));
            let bytes = planes::encode_tile(&codes, w, h, quantizer.width(), codec)?;
            if !codec.lossless() {
                planes::decode_tile(
                    &bytes,
                    w,
                    h,
                    quantizer.width(),
                    quantizer.levels,
                    codec,
                    &mut codes,
                )?;
            }
            Ok((bytes, codes))
        })
        .collect::<Result<_>>()?;
    let mut gain = vec![0.0f32; width * height];
    let mut sections = Vec::with_capacity(tiles);
    for (t, (bytes, codes)) in coded.into_iter().enumerate() {
        let (x0, y0, w, h) = tile_rect(width, height, settings.tile, t);
        for y in 0..h {
            for (o, &q) in gain[(y0 + y) * width + x0..(y0 + y) * width + x0 + w]
                .iter_mut()
                .zip(&codes[y * w..(y + 1) * w])
            {
                *o = gain::applied(quantizer.coding.decode(q as f32));
            }
        }
        sections.push(bytes);
    }
    Ok((sections, gain))
}

/// The gain plane's quantiser, from its statistics (as [`PlaneStats::of`] the gain of
/// every pixel of level 0 gives them): its range in 256 codes for zstd, as an albedo
/// plane's for the image codecs. Finer mip levels keep level 0's.
fn gain_quantizer(stats: &PlaneStats, codec: TileCodec) -> Quantizer {
    let max_levels = codec.max_levels();
    match codec {
        TileCodec::Zstd { .. } => {
            let r = stats.range;
            Quantizer::spanning(r.lo, r.hi, (r.hi - r.lo) / 255.0, max_levels)
        }
        TileCodec::Jpeg { .. } | TileCodec::Webp { .. } => {
            plane_quantizer(stats, codec, 0.0, max_levels)
        }
    }
}

/// Vector-quantise the per-pixel values of `entries`: the codebook (in the planes'
/// units) and every pixel's index. Function planes weigh alike (the components are
/// orthonormal in the relit image's metric); a per-pixel albedo plane weighs by the
/// mean energy of the function it scales, so that distance approximates the error of
/// the relit image.
fn quantize_vectors(
    entries: &[(PlaneEntry, &[f32])],
    counts: &[usize],
    n: usize,
    codebook: usize,
) -> Result<(vq::Codebook, Vec<u16>)> {
    let dims = entries.len();
    let functions: usize = counts.iter().sum();
    let squares = entries[..counts[0]]
        .iter()
        .map(|(_, plane)| plane.iter().fold(0.0, |s, &v| s + squared(v)));
    let weights = codebook_weights(dims, functions, squares, n);
    let mut vectors = vec![0.0f32; n * dims];
    vectors.par_chunks_mut(dims).enumerate().for_each(|(p, v)| {
        for (j, x) in v.iter_mut().enumerate() {
            *x = entries[j].1[p] * weights[j];
        }
    });
    let mut book = vq::train(&vectors, dims, codebook)?;
    let indices = vq::assign(&book, &vectors);
    for entry in book.values.chunks_exact_mut(dims) {
        for (x, w) in entry.iter_mut().zip(&weights) {
            *x /= w;
        }
    }
    Ok((book, indices))
}

/// The entry of the residual's plane `i` (component `components + i % extra` of function
/// channel `i / extra`) whose values span `range`: that range in 16 bits (a codebook is
/// small).
fn residual_entry(
    layout: Layout,
    components: usize,
    extra: usize,
    i: usize,
    range: crate::storage::FiniteRange,
) -> PlaneEntry {
    let step = (range.hi - range.lo) / 65535.0;
    PlaneEntry {
        channel: layout.channels().0[i / extra].to_string(),
        index: components + i % extra,
        quantizer: Quantizer::spanning(range.lo, range.hi, step, 1 << 16),
    }
}

/// `v`², what the codebook's weights sum over a plane.
fn squared(v: f32) -> f64 {
    (v as f64).powi(2)
}

/// The weight of each of a codebook's `dims` values (`functions` function planes, then
/// per-pixel albedo planes): a function plane 1 (the components are orthonormal in the
/// relit image's metric), an albedo plane the root mean energy of the function it scales
/// (`squares`, each of that function's planes' sum of [`squared`] values over the `n`
/// pixels).
fn codebook_weights(
    dims: usize,
    functions: usize,
    squares: impl Iterator<Item = f64>,
    n: usize,
) -> Vec<f32> {
    let energy = if dims > functions {
        (squares.sum::<f64>() / n.max(1) as f64).max(1e-12)
    } else {
        1.0
    };
    (0..dims)
        .map(|j| {
            if j < functions {
                1.0
            } else {
                energy.sqrt() as f32
            }
        })
        .collect()
}

/// The codebook's section: every value's code (in [`Header::codebook_values`]' order,
/// entry by entry), zstd.
fn codebook_bytes(header: &Header, book: &vq::Codebook) -> Result<Vec<u8>> {
    let mut codes: Vec<u8> = Vec::with_capacity(2 * book.values.len());
    for (j, entry) in header.codebook_values().iter().enumerate() {
        for e in 0..book.entries() {
            let code = entry.quantizer.code(book.entry(e)[j]);
            codes.extend_from_slice(&code.to_le_bytes());
        }
    }
    let TileCodec::Zstd { level } = header.index_codec() else {
        unreachable!("indices are coded losslessly")
    };
    zstd::bulk::compress(&codes, level)
        .map_err(|e| Error::new(crate::ErrorKind::Io, format!("zstd: {e}")))
}

/// The quantisers of the function planes (channel by channel, component by component)
/// and of `albedo` per-pixel planes, in the file's order: `fixed` (a finer level takes
/// level 0's: its values are means of level 0's, within their ranges where the planes
/// are linear in the coefficients, clamped where not), or found from each plane's
/// statistics (`stats(i)`, plane `i` in that order).
fn plane_entries(
    settings: &Settings,
    counts: &[usize],
    albedo: usize,
    fixed: Option<&[PlaneEntry]>,
    stats: &(dyn Fn(usize) -> PlaneStats + Sync),
) -> Result<Vec<PlaneEntry>> {
    let (functions, per_pixel) = settings.layout.channels();
    let names: Vec<(&str, usize)> = counts
        .iter()
        .enumerate()
        .flat_map(|(f, &count)| (0..count).map(move |j| (functions[f], j)))
        .chain(per_pixel.iter().take(albedo).map(|&name| (name, 0)))
        .collect();
    if let Some(planes) = fixed {
        let same = planes.len() >= names.len()
            && planes
                .iter()
                .zip(&names)
                .all(|(p, &(channel, index))| p.channel == channel && p.index == index);
        if !same {
            return Err(Error::invalid("a mip level has other planes than level 0"));
        }
        return Ok(planes[..names.len()].to_vec());
    }
    let max_levels = settings.codec.max_levels();
    let steps = ((1u64 << settings.bits) - 1) as f32;
    let function_planes: usize = counts.iter().sum();
    // The first plane's statistics set the shared step; every plane's are dropped as soon
    // as its quantiser is found.
    let first = stats(0);
    let function_step = match settings.codec {
        TileCodec::Zstd { .. } => {
            let r = first.range;
            ((r.hi - r.lo) / steps).max(f32::MIN_POSITIVE)
        }
        // JPEG codes are 8-bit: the first plane's range in 256 codes, or no shared step.
        TileCodec::Jpeg { .. } | TileCodec::Webp { .. } => match settings.jpeg_range {
            JpegRange::Shared => {
                let (lo, hi) = first.percentiles(1e-4);
                ((hi - lo) / 255.0).max(f32::MIN_POSITIVE)
            }
            JpegRange::PerPlane => 0.0,
        },
    };
    Ok(names
        .par_iter()
        .enumerate()
        .map(|(i, &(channel, index))| {
            let own;
            let plane = if i == 0 {
                &first
            } else {
                own = stats(i);
                &own
            };
            let step = if i < function_planes {
                function_step
            } else {
                // Albedo planes span their own range (JPEG: in 256 codes).
                match settings.codec {
                    TileCodec::Zstd { .. } => {
                        ((plane.range.hi - plane.range.lo) / steps).max(f32::MIN_POSITIVE)
                    }
                    TileCodec::Jpeg { .. } | TileCodec::Webp { .. } => 0.0,
                }
            };
            PlaneEntry {
                channel: channel.to_string(),
                index,
                quantizer: plane_quantizer(plane, settings.codec, step, max_levels),
            }
        })
        .collect())
}

/// The quantiser of one plane: the shared step for zstd; for JPEG 256 codes of that
/// step or wider, enough for the plane's 0.01 %–99.99 % range (outliers clamped).
fn plane_quantizer(plane: &PlaneStats, codec: TileCodec, step: f32, max_levels: u32) -> Quantizer {
    let r = plane.range;
    match codec {
        TileCodec::Zstd { .. } => Quantizer::spanning(r.lo, r.hi, step, max_levels),
        TileCodec::Jpeg { .. } | TileCodec::Webp { .. } => {
            let (lo, hi) = plane.percentiles(1e-4);
            // All 256 codes stay valid (JPEG's ringing can reach any of them); a plane
            // narrower than 256 steps sits in the middle of them.
            let scale = (step.max((hi - lo) / 255.0)).max(f32::MIN_POSITIVE);
            if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
                return Quantizer::spanning(lo, hi, 0.0, 256);
            }
            Quantizer {
                coding: crate::storage::PlaneCoding {
                    scale,
                    offset: 0.5 * (lo + hi) - 127.5 * scale,
                },
                levels: 256,
            }
        }
    }
}

/// What a plane's quantiser is found from: the range of its finite values and a
/// regular subsample of them (every [`PlaneStats::stride`]-th pixel), which a packer
/// that sees the plane a band at a time gathers as well as one that holds it.
#[derive(Clone, Debug)]
struct PlaneStats {
    range: crate::storage::FiniteRange,
    /// Empty where the codec needs no quantiles (zstd planes span their range).
    sample: Vec<f32>,
    sampled: bool,
}

impl PlaneStats {
    /// Values the quantiles are found on, at most about.
    const SAMPLE: usize = 200_000;

    /// Pixels between two of the subsample in a plane of `pixels`.
    fn stride(pixels: usize) -> usize {
        (pixels / Self::SAMPLE).max(1)
    }

    /// No values yet, for a plane coded by `codec`.
    fn empty(codec: TileCodec) -> PlaneStats {
        PlaneStats {
            range: crate::storage::FiniteRange::EMPTY,
            sample: Vec::new(),
            sampled: codec.is_image(),
        }
    }

    /// The statistics of a whole plane coded by `codec`.
    fn of(plane: &[f32], codec: TileCodec) -> PlaneStats {
        let sampled = codec.is_image();
        PlaneStats {
            range: crate::storage::FiniteRange::of(plane.iter().copied()),
            sample: if sampled {
                plane
                    .iter()
                    .step_by(Self::stride(plane.len()))
                    .copied()
                    .filter(|v| v.is_finite())
                    .collect()
            } else {
                Vec::new()
            },
            sampled,
        }
    }

    /// Pixel `p`'s value `v` of a plane of `pixels`, seen in pixel order.
    fn see(&mut self, p: usize, pixels: usize, v: f32) {
        self.range = self.range.with(v);
        if self.sampled && p.is_multiple_of(Self::stride(pixels)) && v.is_finite() {
            self.sample.push(v);
        }
    }

    /// The `q` and `1 − q` quantiles of the finite values (by the subsample: the values
    /// at those places of it sorted, selected without sorting it all).
    fn percentiles(&self, q: f64) -> (f32, f32) {
        let mut v = self.sample.clone();
        if v.is_empty() {
            return (0.0, 0.0);
        }
        let place = |f: f64| ((v.len() - 1) as f64 * f).round() as usize;
        let (lo, hi) = (place(q), place(1.0 - q));
        let (_, &mut low, above) = v.select_nth_unstable_by(lo, f32::total_cmp);
        let high = match hi.checked_sub(lo + 1) {
            Some(at) => *above.select_nth_unstable_by(at, f32::total_cmp).1,
            None => low,
        };
        (low, high)
    }
}

/// f32 values, byte planes apart (sign/exponent bytes compress well together), zstd.
fn encode_floats(values: &[f32]) -> Result<Vec<u8>> {
    let n = values.len();
    let mut shuffled = vec![0u8; 4 * n];
    for (i, v) in values.iter().enumerate() {
        for (b, byte) in v.to_le_bytes().into_iter().enumerate() {
            shuffled[b * n + i] = byte;
        }
    }
    zstd::bulk::compress(&shuffled, 9)
        .map_err(|e| Error::new(crate::ErrorKind::Io, format!("zstd: {e}")))
}

fn decode_floats(bytes: &[u8], n: usize) -> Result<Vec<f32>> {
    use std::io::Read;
    let mut raw = Vec::new();
    zstd::stream::read::Decoder::new(bytes)
        .and_then(|d| d.take(4 * n as u64 + 1).read_to_end(&mut raw))
        .map_err(|e| Error::parse(format!("a depth tile does not decompress: {e}")))?;
    if raw.len() != 4 * n {
        return Err(Error::parse("a depth tile has the wrong size"));
    }
    Ok((0..n)
        .map(|i| f32::from_le_bytes([raw[i], raw[n + i], raw[2 * n + i], raw[3 * n + i]]))
        .collect())
}

/// Undo [`pack`]: ordinary maps in the stored (projected) basis, RGB.
pub fn unpack(packed: &Packed) -> Result<RelightableImage> {
    let header = &packed.header;
    let kp = checked(packed)?;
    if header.indexed_pixels() {
        return Ok(indexed_checked(packed, kp)?.expand());
    }
    Ok(RelightableImage {
        meta: header.meta.clone(),
        maps: region_maps(packed, kp, (0, 0, header.width, header.height))?,
        depth: depth(packed)?,
    })
}

/// The maps of `region` of a file with `kp` functions: the tiles it touches, decoded
/// (first, so that memory grows with what the file really holds) and copied into place;
/// a codebook's values where the pixels' indices say (every plane's values where the
/// pixels are only indices, or the residual's).
fn region_maps(
    packed: &Packed,
    kp: usize,
    region: (usize, usize, usize, usize),
) -> Result<CoefficientMaps> {
    let header = &packed.header;
    let (x, y, w, h) = region;
    let tiles = header.tiles().0 * header.tiles().1;
    let touched: Vec<usize> = (0..tiles)
        .filter(|&t| tile_overlap(header, t, region).is_some())
        .collect();
    let indexed = header.indexed_pixels();
    let coded_planes = if indexed { 0 } else { header.planes.len() };
    let decoded: Vec<Vec<u16>> = (0..coded_planes * touched.len())
        .into_par_iter()
        .map(|i| {
            let (p, t) = (i / touched.len(), touched[i % touched.len()]);
            let q = &header.planes[p].quantizer;
            decode_codes(packed, p * tiles + t, t, q.width(), q.levels, header.codec)
        })
        .collect::<Result<_>>()?;
    // A codebook of the residual: its codes and the touched tiles' indices.
    let (book, indices) = match header.codebook {
        Some(_) => (
            codebook_codes(packed)?,
            touched
                .par_iter()
                .map(|&t| index_tile(packed, t))
                .collect::<Result<Vec<_>>>()?,
        ),
        None => (Vec::new(), Vec::new()),
    };
    let entries = header.codebook.unwrap_or(0);
    let blocks = match header.pca_block {
        Some(_) => Some(BlockDecoder::new(packed, kp, (x, y))?),
        None => None,
    };
    Ok(assemble(header, kp, w, h, blocks.as_ref(), |p, out| {
        // The codebook's values this plane takes: all of them for indices alone.
        let in_book = match indexed {
            true => Some(p),
            false => p.checked_sub(header.planes.len()),
        };
        let coding = match p.checked_sub(header.planes.len()) {
            Some(r) => header.residual[r].quantizer.coding,
            None => header.planes[p].quantizer.coding,
        };
        for (i, &t) in touched.iter().enumerate() {
            let (tx, ty, tw, _) = header.tile_rect(t);
            let (ox, oy, ow, oh) = tile_overlap(header, t, region).expect("touched");
            for r in 0..oh {
                let src = (oy + r - ty) * tw + (ox - tx);
                let dst = (oy + r - y) * w + (ox - x);
                let out = &mut out[dst..dst + ow];
                match in_book {
                    Some(j) => {
                        let values = &book[j * entries..(j + 1) * entries];
                        for (o, &e) in out.iter_mut().zip(&indices[i][src..src + ow]) {
                            *o = coding.decode(values[e as usize] as f32);
                        }
                    }
                    None => {
                        let codes = &decoded[p * touched.len() + i][src..src + ow];
                        for (o, &q) in out.iter_mut().zip(codes) {
                            *o = coding.decode(q as f32);
                        }
                    }
                }
            }
        }
    }))
}

/// Rows of each projection group's map in a file with a projection a block
/// ([`projection_groups`]): `K′` for the first, the chroma's components for `ycc`'s
/// second.
fn block_rows(header: &Header, kp: usize) -> Vec<usize> {
    let chroma = header.planes.iter().filter(|p| p.channel == "Co").count();
    match header.layout {
        Layout::Ycc => vec![kp, chroma],
        Layout::Rgb | Layout::Lrgb => vec![kp],
    }
}

/// Every block's maps from its `kp` stored coordinates onto the header's basis of `k`
/// functions, read from the last section of a file already [`checked`]: per block, per
/// projection group ([`block_rows`]), a `rows × K` matrix, row-major.
fn block_maps(packed: &Packed, kp: usize, k: usize) -> Result<Vec<f32>> {
    let header = &packed.header;
    let (across, down) = header.pca_blocks();
    let per_block: usize = block_rows(header, kp).iter().map(|r| r * k).sum();
    let want = across * down * per_block * 4;
    let bytes = &packed.sections[header.level_zero_sections() - 1];
    if header.pca_block.is_none() || bytes.len() != want {
        return Err(Error::parse(format!(
            "compressed file: the blocks' projections take {} bytes, not {want}",
            bytes.len(),
        )));
    }
    let values: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    if values.iter().any(|v| !v.is_finite()) {
        return Err(Error::parse(
            "compressed file: a block's projection is not finite",
        ));
    }
    Ok(values)
}

/// Decodes a region's stored coordinates of a file with a projection a block into the
/// header's basis: `c = Pᵀ c′` with the pixel's block's `P` for the channel's group.
struct BlockDecoder {
    maps: Vec<f32>,
    rows: Vec<usize>,
    k: usize,
    block: usize,
    across: usize,
    /// The region's top-left pixel.
    origin: (usize, usize),
}

impl BlockDecoder {
    /// The decoder of a file already [`checked`], with `kp` stored functions.
    fn new(packed: &Packed, kp: usize, origin: (usize, usize)) -> Result<Self> {
        let header = &packed.header;
        let k = header.meta.basis.build()?.len();
        Ok(BlockDecoder {
            maps: block_maps(packed, kp, k)?,
            rows: block_rows(header, kp),
            k,
            block: header.pca_block.expect("a file with blocks"),
            across: header.pca_blocks().0,
            origin,
        })
    }

    /// Into `out`, `K` zeroed coefficient planes (`w` pixels a row), the coordinates
    /// `coords` of projection group `group` (fewer planes than its rows: the rest are 0).
    fn decode(&self, coords: &[&[f32]], group: usize, w: usize, out: Vec<&mut [f32]>) {
        let (k, block, (x, y)) = (self.k, self.block, self.origin);
        let per_block: usize = self.rows.iter().map(|r| r * k).sum();
        let offset: usize = self.rows[..group].iter().map(|r| r * k).sum();
        let n = coords.first().map_or(0, |c| c.len());
        let h = n.checked_div(w).unwrap_or(0);
        debug_assert_eq!(out.len(), k);
        out.into_par_iter().enumerate().for_each(|(i, out)| {
            for row in 0..h {
                let by = (y + row) / block;
                let mut col = 0;
                while col < w {
                    // A run of the row inside one block.
                    let bx = (x + col) / block;
                    let end = ((bx + 1) * block - x).min(w);
                    let p = &self.maps[(by * self.across + bx) * per_block + offset..];
                    let dst = &mut out[row * w + col..row * w + end];
                    for (j, plane) in coords.iter().enumerate().take(self.rows[group]) {
                        let weight = p[j * k + i];
                        let src = &plane[row * w + col..row * w + end];
                        dst.iter_mut().zip(src).for_each(|(o, &c)| *o += weight * c);
                    }
                    col = end;
                }
            }
        });
    }
}

/// Whether [`unpack_region`] needs section `s` of a file for the region `(x, y, w, h)`:
/// a plane's tile that the region touches, a codebook and the index tiles the region
/// touches (depth is not read).
pub fn section_needed(header: &Header, s: usize, region: (usize, usize, usize, usize)) -> bool {
    if header.pca_block.is_some() && s + 1 == header.level_zero_sections() {
        return true;
    }
    let (across, down) = header.tiles();
    let tiles = across * down;
    let plane_tiles = match header.indexed_pixels() {
        true => 0,
        false => header.planes.len() * tiles,
    };
    if s < plane_tiles {
        return tile_overlap(header, s % tiles, region).is_some();
    }
    // A codebook (of every plane's values, or of the residual's), and the index tiles
    // the region touches.
    match header.codebook_section() {
        Some(book) if s == book => true,
        Some(book) if s > book && s <= book + tiles => {
            tile_overlap(header, s - book - 1, region).is_some()
        }
        _ => false,
    }
}

/// The part of tile `t` inside `region`, as `(x0, y0, w, h)` in image pixels.
fn tile_overlap(
    header: &Header,
    t: usize,
    (x, y, w, h): (usize, usize, usize, usize),
) -> Option<(usize, usize, usize, usize)> {
    let (tx, ty, tw, th) = header.tile_rect(t);
    let (x0, y0) = (tx.max(x), ty.max(y));
    let (x1, y1) = ((tx + tw).min(x + w), (ty + th).min(y + h));
    (x1 > x0 && y1 > y0).then_some((x0, y0, x1 - x0, y1 - y0))
}

/// Refuse a region `(x, y, w, h)` that is empty or not inside the file's image.
fn check_region(header: &Header, (x, y, w, h): (usize, usize, usize, usize)) -> Result<()> {
    if w == 0
        || h == 0
        || x.checked_add(w).is_none_or(|e| e > header.width)
        || y.checked_add(h).is_none_or(|e| e > header.height)
    {
        return Err(Error::invalid(format!(
            "region {x},{y} {w}×{h} is not inside the {}×{} image",
            header.width, header.height
        )));
    }
    Ok(())
}

/// The region `(x, y, w, h)` of a file's maps, from the sections
/// [`section_needed`] names (the others may be empty): the tiles it touches, decoded
/// and cropped. The result is a `w × h` image with no camera or depth, for lights
/// that are the same at every pixel (directional, environment); it equals that crop
/// of [`unpack`].
pub fn unpack_region(
    packed: &Packed,
    region: (usize, usize, usize, usize),
) -> Result<RelightableImage> {
    let header = &packed.header;
    check_region(header, region)?;
    let kp = checked(packed)?;
    let maps = region_maps(packed, kp, region)?;
    let mut meta = header.meta.clone();
    meta.camera = None;
    Ok(RelightableImage {
        meta,
        maps,
        depth: None,
    })
}

/// A codebook file as an indexed image (entries relit once a frame, pixels looked up:
/// [`crate::engine::lookup`]); depth is not read.
pub fn indexed(packed: &Packed) -> Result<crate::engine::lookup::IndexedImage> {
    indexed_checked(packed, checked(packed)?)
}

/// [`indexed`] of a file already [`checked`], with `kp` functions.
fn indexed_checked(packed: &Packed, kp: usize) -> Result<crate::engine::lookup::IndexedImage> {
    let header = &packed.header;
    let Some(entries) = header.codebook else {
        return Err(Error::invalid(
            "not a codebook file: its pixels are planes, not indices",
        ));
    };
    if !header.indexed_pixels() {
        return Err(Error::invalid(
            "a codebook of the residual: its pixels keep planes too, so the file relights as maps",
        ));
    }
    let codes = codebook_codes(packed)?;
    let code = |j: usize, e: usize| codes[j * entries + e];
    let maps = assemble(header, kp, entries, 1, None, |j, out| {
        let coding = header.planes[j].quantizer.coding;
        for (e, o) in out.iter_mut().enumerate() {
            *o = coding.decode(code(j, e) as f32);
        }
    });
    let (w, h) = (header.width, header.height);
    let tiles = header.tiles().0 * header.tiles().1;
    let parts: Vec<Vec<u16>> = (0..tiles)
        .into_par_iter()
        .map(|t| index_tile(packed, t))
        .collect::<Result<_>>()?;
    let mut indices = vec![0u16; w * h];
    for (t, part) in parts.iter().enumerate() {
        let (x0, y0, tw, th) = header.tile_rect(t);
        for y in 0..th {
            indices[(y0 + y) * w + x0..(y0 + y) * w + x0 + tw]
                .copy_from_slice(&part[y * tw..(y + 1) * tw]);
        }
    }
    Ok(crate::engine::lookup::IndexedImage {
        entries: RelightableImage {
            meta: header.meta.clone(),
            maps,
            // The image's depth, one value a pixel (what `expand` and the viewer keep).
            depth: depth(packed)?,
        },
        indices,
        width: w,
        height: h,
    })
}

/// The header checked against the basis and the sections; `K′`.
fn checked(packed: &Packed) -> Result<usize> {
    let header = &packed.header;
    let kp = header.check()?;
    let basis = header.meta.basis.build()?;
    // Blocks' planes hold K′ ≤ K coordinates of the basis; others are the basis' own.
    let fits = match header.pca_block {
        Some(_) => basis.len() >= kp,
        None => basis.len() == kp,
    };
    if !fits {
        return Err(Error::parse(format!(
            "compressed file: the basis has {} functions, the planes {kp}",
            basis.len()
        )));
    }
    if packed.sections.len() != header.sections() {
        return Err(Error::parse("compressed file: wrong number of sections"));
    }
    Ok(kp)
}

/// The codes of tile `t` from section `s`, coded by `codec`.
fn decode_codes(
    packed: &Packed,
    s: usize,
    t: usize,
    width: usize,
    levels: u32,
    codec: TileCodec,
) -> Result<Vec<u16>> {
    let (_, _, tw, th) = packed.header.tile_rect(t);
    let mut codes = vec![0u16; tw * th];
    planes::decode_tile(
        &packed.sections[s],
        tw,
        th,
        width,
        levels,
        codec,
        &mut codes,
    )?;
    Ok(codes)
}

/// The codebook's codes of a file already [`checked`]: value `j` of entry `e` at
/// `j · entries + e` ([`Header::codebook_values`]), each checked against its levels.
fn codebook_codes(packed: &Packed) -> Result<Vec<u16>> {
    use std::io::Read;
    let header = &packed.header;
    let (Some(entries), Some(s)) = (header.codebook, header.codebook_section()) else {
        return Err(Error::invalid("not a codebook file"));
    };
    let values = header.codebook_values();
    let want = 2 * entries * values.len();
    let mut raw = Vec::new();
    zstd::stream::read::Decoder::new(&packed.sections[s][..])
        .and_then(|d| d.take(want as u64 + 1).read_to_end(&mut raw))
        .map_err(|e| Error::parse(format!("the codebook does not decompress: {e}")))?;
    if raw.len() != want {
        return Err(Error::parse(format!(
            "the codebook holds {} bytes, not {want}",
            raw.len()
        )));
    }
    let codes: Vec<u16> = raw
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    for (j, value) in values.iter().enumerate() {
        let levels = value.quantizer.levels;
        if codes[j * entries..(j + 1) * entries]
            .iter()
            .any(|&c| c as u32 >= levels)
        {
            return Err(Error::parse("a codebook value is past its plane's codes"));
        }
    }
    Ok(codes)
}

/// The indices of tile `t` of a codebook file already [`checked`].
fn index_tile(packed: &Packed, t: usize) -> Result<Vec<u16>> {
    let header = &packed.header;
    let (Some(entries), Some(book)) = (header.codebook, header.codebook_section()) else {
        return Err(Error::invalid("not a codebook file"));
    };
    decode_codes(
        packed,
        book + 1 + t,
        t,
        header.index_width(),
        entries as u32,
        header.index_codec(),
    )
}

/// Whether section `s` holds part of the depth map (its tiles follow the planes').
pub fn depth_section(header: &Header, s: usize) -> bool {
    let (across, down) = header.tiles();
    let base = header.plane_sections();
    header.depth && (base..base + across * down).contains(&s)
}

/// Whether section `s` holds the depth of a tile that `region` `(x, y, w, h)` touches.
pub fn depth_section_in(header: &Header, s: usize, region: (usize, usize, usize, usize)) -> bool {
    let base = header.plane_sections();
    depth_section(header, s) && tile_overlap(header, s - base, region).is_some()
}

/// The depth of `region` `(x, y, w, h)` of a file whose sections
/// [`depth_section_in`] names were read (the others may be empty), when it has depth:
/// that crop of [`unpack`]'s depth.
pub fn unpack_depth_region(
    packed: &Packed,
    region: (usize, usize, usize, usize),
) -> Result<Option<Vec<f32>>> {
    let header = &packed.header;
    if packed.sections.len() != header.sections() {
        return Err(Error::parse("compressed file: wrong number of sections"));
    }
    if !header.depth {
        return Ok(None);
    }
    check_region(header, region)?;
    depth_in(packed, region).map(Some)
}

/// The depth map, when the file has one (its tiles follow the planes').
fn depth(packed: &Packed) -> Result<Option<Vec<f32>>> {
    let header = &packed.header;
    if !header.depth {
        return Ok(None);
    }
    depth_in(packed, (0, 0, header.width, header.height)).map(Some)
}

/// The depth of `region` (inside the image) of a file with depth: the depth tiles it
/// touches, decoded side by side and cropped into place.
fn depth_in(packed: &Packed, region: (usize, usize, usize, usize)) -> Result<Vec<f32>> {
    let header = &packed.header;
    let (x, y, w, h) = region;
    let base = header.plane_sections();
    let tiles = header.tiles().0 * header.tiles().1;
    let touched: Vec<usize> = (0..tiles)
        .filter(|&t| tile_overlap(header, t, region).is_some())
        .collect();
    let parts: Vec<Vec<f32>> = touched
        .par_iter()
        .map(|&t| {
            let (_, _, tw, th) = header.tile_rect(t);
            decode_floats(&packed.sections[base + t], tw * th)
        })
        .collect::<Result<_>>()?;
    let mut depth = vec![0.0f32; w * h];
    for (&t, part) in touched.iter().zip(&parts) {
        let (tx, ty, tw, _) = header.tile_rect(t);
        let (ox, oy, ow, oh) = tile_overlap(header, t, region).expect("a touched tile");
        for r in 0..oh {
            let from = (oy + r - ty) * tw + ox - tx;
            let to = (oy + r - y) * w + ox - x;
            depth[to..to + ow].copy_from_slice(&part[from..from + ow]);
        }
    }
    Ok(depth)
}

/// RGB coefficient maps of `w × h` pixels from the stored planes (`plane_values(p,
/// out)` fills plane `p` of the header), undoing the colour layout.
fn assemble(
    header: &Header,
    kp: usize,
    w: usize,
    h: usize,
    blocks: Option<&BlockDecoder>,
    plane_values: impl Fn(usize, &mut [f32]),
) -> CoefficientMaps {
    let n = w * h;
    let mut maps = CoefficientMaps::zeros(w, h, kp);
    let groups = projection_groups(header.layout, blocks.is_some());
    let (functions, _) = header.layout.channels();
    // A codebook of the residual holds components past the planes': its values are
    // planes `planes.len() + r` of `plane_values`.
    let index_of = |channel: &str, j: usize| {
        header
            .planes
            .iter()
            .chain(&header.residual)
            .position(|e| e.channel == channel && e.index == j)
    };
    match header.layout {
        Layout::Rgb | Layout::Ycc => {
            for j in 0..kp {
                for (f, name) in functions.iter().enumerate() {
                    if let Some(p) = index_of(name, j) {
                        plane_values(p, maps.plane_mut(j, f));
                    }
                }
            }
            // A projection a block decodes each function channel into the basis before
            // the layout is undone (ycc's luma and chroma have their own).
            if let Some(decoder) = blocks {
                let mut decoded = CoefficientMaps::zeros(w, h, decoder.k);
                for f in 0..functions.len() {
                    let coords: Vec<&[f32]> = (0..kp).map(|j| maps.plane(j, f)).collect();
                    // Planes (i, f) of the decoded maps, i = 0…K−1.
                    let out = decoded.data.chunks_mut(n).skip(f).step_by(3).collect();
                    decoder.decode(&coords, group_of(&groups, f), w, out);
                }
                maps = decoded;
            }
            if header.layout == Layout::Ycc {
                let (pixels, data) = (n, &mut maps.data);
                data.par_chunks_mut(3 * pixels).for_each(|coefficient| {
                    let (y, rest) = coefficient.split_at_mut(pixels);
                    let (co, cg) = rest.split_at_mut(pixels);
                    for p in 0..pixels {
                        let [r, g, b] = layout::rgb_of_ycc([y[p], co[p], cg[p]]);
                        (y[p], co[p], cg[p]) = (r, g, b);
                    }
                });
            }
        }
        Layout::Lrgb => {
            let mut albedo = vec![vec![0.0f32; n]; 3];
            for (c, a) in albedo.iter_mut().enumerate() {
                let p = index_of(["aR", "aG", "aB"][c], 0).expect("checked");
                plane_values(p, a);
            }
            let mut luminance: Vec<Vec<f32>> = (0..kp)
                .map(|j| {
                    let mut l = vec![0.0f32; n];
                    plane_values(index_of("L", j).expect("checked"), &mut l);
                    l
                })
                .collect();
            if let Some(decoder) = blocks {
                let mut decoded = vec![vec![0.0f32; n]; decoder.k];
                let coords: Vec<&[f32]> = luminance.iter().map(Vec::as_slice).collect();
                decoder.decode(
                    &coords,
                    0,
                    w,
                    decoded.iter_mut().map(Vec::as_mut_slice).collect(),
                );
                luminance = decoded;
                maps = CoefficientMaps::zeros(w, h, decoder.k);
            }
            for (j, l) in luminance.iter().enumerate() {
                for (c, a) in albedo.iter().enumerate() {
                    maps.plane_mut(j, c)
                        .iter_mut()
                        .zip(l)
                        .zip(a)
                        .for_each(|((o, &l), &a)| *o = l * a);
                }
            }
        }
    }
    if header.gain {
        let p = index_of(gain::CHANNEL, 0).expect("checked");
        let mut g = vec![0.0f32; n];
        plane_values(p, &mut g);
        g.iter_mut().for_each(|v| *v = gain::applied(*v));
        maps.data.par_chunks_mut(n).for_each(|plane| {
            plane.iter_mut().zip(&g).for_each(|(o, &g)| *o *= g);
        });
    }
    maps
}

#[cfg(test)]
mod tests;
