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
use crate::storage::{CompactPlanes, FiniteRange, PlaneCoding, Precision};
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

/// Read a compressed file as ordinary maps (in its projected basis): level 0, a run of
/// tiles at a time (see [`read_compact`]), so that the file's bytes are never held
/// beside the maps; its finer levels' sections are not read.
pub fn read(path: &Path) -> Result<RelightableImage> {
    let in_file = |e: Error| Error::new(e.kind(), format!("{}: {e}", path.display()));
    let runs = Runs::open(path, COMPACT_RUN_BYTES).map_err(in_file)?;
    if runs.header.indexed_pixels() {
        return read_indexed(path);
    }
    let (w, count) = (runs.header.width, 3 * runs.k);
    let what = format!("{}: the maps", path.display());
    let mut data = super::exr::try_zeroed::<f32>(runs.pixels().checked_mul(count), &what)?;
    runs.each(&mut |rect, maps| {
        place(&mut data, rect, w, maps, |_, from, to| {
            to.copy_from_slice(from)
        })
    })?;
    runs.into_image(data).map_err(in_file)
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

/// A pixel rectangle `(x, y, w, h)`.
type Rect = (usize, usize, usize, usize);

/// Bytes of f32 maps [`read_compact`] decodes at once: a run of tiles of one row of
/// tiles (at least one tile), so that its peak is the compact planes and this.
const COMPACT_RUN_BYTES: usize = 64 << 20;

/// Level 0 of a compressed file as compact planes (f16 or u8, as
/// [`crate::storage::CompactPlanes::from_maps`] makes them from the decoded maps),
/// without holding the f32 maps or the file's bytes: runs of tiles are read and decoded
/// one after another (u8 reads them twice, first for each plane's range). The image
/// holds the metadata and depth, no maps. A codebook file is expanded whole.
pub fn read_compact(
    path: &Path,
    precision: Precision,
) -> Result<(RelightableImage, CompactPlanes)> {
    read_compact_in_runs(path, precision, COMPACT_RUN_BYTES)
}

/// [`read_compact`], decoding at most `run_bytes` of f32 maps at once (at least a tile).
pub(crate) fn read_compact_in_runs(
    path: &Path,
    precision: Precision,
    run_bytes: usize,
) -> Result<(RelightableImage, CompactPlanes)> {
    let precision = precision.require(&[Precision::F16, Precision::U8], "read_compact")?;
    let runs = Runs::open(path, run_bytes)?;
    if runs.header.indexed_pixels() {
        let mut image = read_indexed(path)?;
        let planes = CompactPlanes::from_maps(&image.maps, precision)?;
        image.maps.data = Vec::new();
        return Ok((image, planes));
    }
    let (w, pixels, count) = (runs.header.width, runs.pixels(), 3 * runs.k);
    let each_run = |f: &mut dyn FnMut(Rect, &crate::maps::CoefficientMaps)| runs.each(f);
    let what = format!("{}: the compact planes", path.display());
    let planes = match precision {
        Precision::F16 => {
            let mut bits = super::exr::try_zeroed::<u16>(pixels.checked_mul(count), &what)?;
            each_run(&mut |rect, maps| {
                place(&mut bits, rect, w, maps, |_, from, to| {
                    crate::storage::to_f16_bits(from, to)
                })
            })?;
            CompactPlanes::from_f16_bits(bits, pixels, count)
        }
        _ => {
            let mut ranges = vec![FiniteRange::EMPTY; count];
            each_run(&mut |_, maps| {
                for (range, plane) in ranges.iter_mut().zip(maps.data.chunks_exact(maps.pixels())) {
                    *range = plane.iter().fold(*range, |r, &v| r.with(v));
                }
            })?;
            let coding: Vec<PlaneCoding> = ranges.into_iter().map(PlaneCoding::u8).collect();
            let mut data = super::exr::try_zeroed::<u8>(pixels.checked_mul(count), &what)?;
            each_run(&mut |rect, maps| {
                place(&mut data, rect, w, maps, |j, from, to| {
                    to.iter_mut()
                        .zip(from)
                        .for_each(|(q, &v)| *q = coding[j].quantize(v))
                })
            })?;
            CompactPlanes::from_u8(data, coding, pixels, count)
        }
    }
    .expect("the planes were sized from the header");
    Ok((runs.into_image(Vec::new())?, planes))
}

/// A codebook file (every pixel an index), expanded: its level 0 read whole (its index
/// tiles decode into one index plane).
fn read_indexed(path: &Path) -> Result<RelightableImage> {
    let (packed, _, _) = read_sections(path, &|h, s| h.section_level(s).0 == 0)?;
    compress::unpack(&packed).map_err(|e| Error::new(e.kind(), format!("{}: {e}", path.display())))
}

/// Level 0 of a compressed file of planes, read a run of tiles at a time: its header,
/// checked.
struct Runs<'a> {
    path: &'a Path,
    header: compress::Header,
    k: usize,
    runs: Vec<Rect>,
}

impl<'a> Runs<'a> {
    /// Runs of at most `run_bytes` of f32 maps (at least a tile), along each row of
    /// tiles.
    fn open(path: &'a Path, run_bytes: usize) -> Result<Runs<'a>> {
        // Taking level 0 checks the header before any size from it is used.
        let (file, _, _) = read_sections(path, &|_, _| false)?;
        let header = file.level(0)?.header;
        let k = header.meta.basis.build()?.len();
        let (w, h, tile) = (header.width, header.height, header.tile);
        let tiles_a_run = (run_bytes / (tile * tile * 3 * k * 4)).max(1);
        let runs = (0..h.div_ceil(tile))
            .flat_map(|ty| {
                (0..w.div_ceil(tile * tiles_a_run)).map(move |r| {
                    let (x, y) = (r * tile * tiles_a_run, ty * tile);
                    (x, y, (tile * tiles_a_run).min(w - x), tile.min(h - y))
                })
            })
            .collect();
        Ok(Runs {
            path,
            header,
            k,
            runs,
        })
    }

    fn pixels(&self) -> usize {
        self.header.width * self.header.height
    }

    /// Each run's maps handed to `f` with its rectangle, in order. As many runs as
    /// there are threads are read and decoded side by side: one run alone leaves cores
    /// idle while its sections are read and its planes assembled.
    fn each(&self, f: &mut dyn FnMut(Rect, &crate::maps::CoefficientMaps)) -> Result<()> {
        use rayon::prelude::*;
        for window in self.runs.chunks(rayon::current_num_threads().max(1)) {
            let decoded = window
                .par_iter()
                .map(|&rect| read_region_with(self.path, rect, false).map(|(image, _, _)| image))
                .collect::<Result<Vec<_>>>()?;
            for (&rect, image) in window.iter().zip(&decoded) {
                f(rect, &image.maps);
            }
        }
        Ok(())
    }

    /// The image of the file's metadata and depth (its depth sections read now) with
    /// the maps `data` (empty: none).
    fn into_image(self, data: Vec<f32>) -> Result<RelightableImage> {
        let (w, h) = (self.header.width, self.header.height);
        let (depth, _, _) = read_sections(self.path, &|h, s| compress::depth_section(h, s))?;
        let depth = compress::unpack_depth_region(&depth.level(0)?, (0, 0, w, h))?;
        Ok(RelightableImage {
            maps: crate::maps::CoefficientMaps {
                width: w,
                height: h,
                k: self.k,
                data,
            },
            meta: self.header.meta,
            depth,
        })
    }
}

/// Every plane of `maps`, the maps of `rect` of an image `width` pixels wide, put into
/// `planes` (the image's planes one after another) a row at a time by `put(plane,
/// values, into)`.
fn place<T: Send>(
    planes: &mut [T],
    (x, y, rw, rh): Rect,
    width: usize,
    maps: &crate::maps::CoefficientMaps,
    put: impl Fn(usize, &[f32], &mut [T]) + Sync,
) {
    use rayon::prelude::*;
    let pixels = planes.len() / (3 * maps.k).max(1);
    planes
        .par_chunks_mut(pixels.max(1))
        .zip(maps.data.par_chunks(rw * rh))
        .enumerate()
        .for_each(|(j, (out, plane))| {
            for r in 0..rh {
                let at = (y + r) * width + x;
                put(j, &plane[r * rw..][..rw], &mut out[at..at + rw]);
            }
        });
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

/// Compress the EXR file `input` into `path` with `settings`, a band of rows at a time
/// ([`compress::bands`]: the maps are never held whole, the sections wait in a
/// temporary file); returns the header written. Settings that need every pixel at once
/// ([`compress::bands::packs_in_bands`]) are refused.
pub fn write_in_bands(
    input: &Path,
    path: &Path,
    settings: &compress::Settings,
    progress: &dyn crate::progress::Progress,
) -> Result<compress::Header> {
    let source = ExrBands::open(input)?;
    write_bands_of(&source, path, settings, progress)
}

/// [`write_in_bands`] of any band source.
fn write_bands_of(
    source: &dyn compress::bands::BandSource,
    path: &Path,
    settings: &compress::Settings,
    progress: &dyn crate::progress::Progress,
) -> Result<compress::Header> {
    let packed = pack_bands_of(source, settings, progress)?;
    packed.write(path)?;
    Ok(packed.header)
}

/// A file packed a band of rows at a time, its sections waiting in a temporary file:
/// its size is known before it is written.
pub struct PackedInBands {
    pub header: compress::Header,
    head: Vec<u8>,
    sections: Vec<(u64, u64, u32)>,
    spilled: SpilledSections,
}

impl PackedInBands {
    /// The file's bytes.
    pub fn bytes(&self) -> u64 {
        self.head.len() as u64 + self.sections.iter().map(|s| s.1).sum::<u64>()
    }

    /// Write the file to `path` (atomically: nothing is left there on failure).
    pub fn write(&self, path: &Path) -> Result<()> {
        let mut file = &self.spilled.file;
        write_atomically(path, |out| {
            let failed = |e: std::io::Error| Error::io(path, "write", e);
            out.write_all(&self.head).map_err(failed)?;
            let mut buffer = Vec::new();
            for &(at, len, _) in &self.sections {
                use std::io::Seek;
                buffer.resize(len as usize, 0);
                file.seek(std::io::SeekFrom::Start(at))
                    .and_then(|_| file.read_exact(&mut buffer))
                    .map_err(|e| {
                        Error::new(ErrorKind::Io, "cannot read back a packed section")
                            .with_source(e)
                    })?;
                out.write_all(&buffer).map_err(failed)?;
            }
            Ok(())
        })
    }
}

/// Compress the EXR file `input` with `settings` a band of rows at a time, as
/// [`write_in_bands`] does, keeping the file to be written (or not) once its size is
/// known.
pub fn pack_in_bands(
    input: &Path,
    settings: &compress::Settings,
    progress: &dyn crate::progress::Progress,
) -> Result<PackedInBands> {
    pack_bands_of(&ExrBands::open(input)?, settings, progress)
}

fn pack_bands_of(
    source: &dyn compress::bands::BandSource,
    settings: &compress::Settings,
    progress: &dyn crate::progress::Progress,
) -> Result<PackedInBands> {
    let mut spilled = SpilledSections::new()?;
    let header = compress::bands::pack_in_bands(source, settings, &mut spilled, progress)?;
    let sections = spilled.in_order(header.sections())?;
    let lengths: Vec<(u64, u32)> = sections.iter().map(|&(_, len, crc)| (len, crc)).collect();
    let head = compress::container::head(&header, &lengths)?;
    Ok(PackedInBands {
        header,
        head,
        sections,
        spilled,
    })
}

struct ExrBands<'a> {
    path: &'a Path,
    shape: crate::codec::exr::FileShape,
}

impl<'a> ExrBands<'a> {
    fn open(path: &'a Path) -> Result<ExrBands<'a>> {
        Ok(ExrBands {
            path,
            shape: crate::codec::exr::read_shape(path)?,
        })
    }
}

impl compress::bands::BandSource for ExrBands<'_> {
    fn meta(&self) -> &crate::maps::Metadata {
        &self.shape.meta
    }

    fn shape(&self) -> (usize, usize, usize) {
        (self.shape.width, self.shape.height, self.shape.k)
    }

    fn has_depth(&self) -> bool {
        self.shape.depth
    }

    fn band(&self, rows: std::ops::Range<usize>) -> Result<RelightableImage> {
        let rect = (0, rows.start, self.shape.width, rows.len());
        Ok(crate::codec::exr::read_region_with(self.path, 0, rect, self.shape.depth)?.image)
    }
}

/// Sections as they are packed, in a temporary file: where each one is, its length and
/// its CRC-32.
struct SpilledSections {
    file: std::fs::File,
    written: u64,
    /// By section number: its offset in `file`, length and CRC-32.
    made: Vec<Option<(u64, u64, u32)>>,
}

impl SpilledSections {
    fn new() -> Result<SpilledSections> {
        let file = tempfile::tempfile().map_err(|e| {
            Error::new(
                ErrorKind::Io,
                "cannot create a temporary file for the sections",
            )
            .with_source(e)
        })?;
        Ok(SpilledSections {
            file,
            written: 0,
            made: Vec::new(),
        })
    }

    /// Every one of `count` sections' offset, length and CRC-32, in order (each must
    /// have been made).
    fn in_order(&self, count: usize) -> Result<Vec<(u64, u64, u32)>> {
        if self.made.len() != count || self.made.iter().any(Option::is_none) {
            return Err(Error::invalid(
                "a packed file was left with sections missing",
            ));
        }
        Ok(self.made.iter().flatten().copied().collect())
    }
}

impl compress::bands::SectionSink for SpilledSections {
    fn put(&mut self, section: usize, bytes: Vec<u8>) -> Result<()> {
        if self.made.len() <= section {
            self.made.resize(section + 1, None);
        }
        if self.made[section].is_some() {
            return Err(Error::invalid(format!(
                "section {section} was packed twice"
            )));
        }
        self.file.write_all(&bytes).map_err(|e| {
            Error::new(
                ErrorKind::Io,
                "cannot write a packed section to a temporary file",
            )
            .with_source(e)
        })?;
        self.made[section] = Some((self.written, bytes.len() as u64, crc32fast::hash(&bytes)));
        self.written += bytes.len() as u64;
        Ok(())
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compress::{Layout, Settings, TileCodec};

    /// A 9-coefficient SH image of smooth, varied pixels with depth.
    fn sample(w: usize, h: usize) -> RelightableImage {
        let basis = crate::basis::BasisChoice::parse("sh:9")
            .unwrap()
            .build(&crate::sphere::hemisphere_fibonacci(32), None)
            .unwrap();
        let mut maps = crate::maps::CoefficientMaps::zeros(w, h, 9);
        for (j, plane) in maps.data.chunks_exact_mut(w * h).enumerate() {
            for (p, v) in plane.iter_mut().enumerate() {
                let (x, y) = ((p % w) as f32 / w as f32, (p / w) as f32 / h as f32);
                *v = ((j as f32 + 1.0) * x + y * y).sin() / (1.0 + (j / 3) as f32);
            }
        }
        let mut meta = crate::maps::Metadata::new(
            basis.spec(),
            crate::maps::MapSpace::Linear,
            crate::camera::Projection::Planar {
                fov_y_deg: Some(50.0),
            },
        );
        meta.fit = None;
        RelightableImage {
            meta,
            maps,
            depth: Some((0..w * h).map(|p| 1.0 + p as f32 * 0.01).collect()),
        }
    }

    /// A file packed a band at a time from an EXR file is the file packed from the
    /// image read whole, byte for byte, with and without mip levels, depth, the
    /// perceptual gain and a codebook; settings the band packer leaves to the whole one
    /// (a codebook with mip levels) are refused before anything is written.
    #[test]
    fn a_file_packed_in_bands_from_an_exr_file_is_the_file_packed_whole() {
        let dir = tempfile::tempdir().unwrap();
        let exr = dir.path().join("maps.exr");
        for (i, settings) in [
            Settings {
                tile: 16,
                mip_levels: true,
                ..Settings::default()
            },
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:90").unwrap(),
                components: Some(4),
                tile: 32,
                ..Settings::default()
            },
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:80").unwrap(),
                components: Some(4),
                tile: 16,
                gain: true,
                mip_levels: true,
                ..Settings::default()
            },
            Settings {
                components: Some(4),
                tile: 16,
                codebook: Some(40),
                ..Settings::default()
            },
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("webp:80").unwrap(),
                components: Some(3),
                tile: 32,
                codebook: Some(20),
                residual: Some(2),
                ..Settings::default()
            },
        ]
        .into_iter()
        .enumerate()
        {
            let mut img = sample(70, 45);
            if i % 2 == 1 {
                img.depth = None;
            }
            crate::codec::exr::write(&exr, &img, Precision::F32).unwrap();
            let (whole, bands) = (dir.path().join("whole.rlz"), dir.path().join("bands.rlz"));
            super::write(&whole, &img, &settings).unwrap();
            let header = write_in_bands(&exr, &bands, &settings, &crate::progress::Silent).unwrap();
            assert_eq!(header, read_header(&whole).unwrap());
            assert!(
                std::fs::read(&whole).unwrap() == std::fs::read(&bands).unwrap(),
                "case {i}: the same bytes"
            );
        }
        let refused = dir.path().join("refused.rlz");
        let codebook = Settings {
            codebook: Some(16),
            mip_levels: true,
            ..Settings::default()
        };
        assert!(write_in_bands(&exr, &refused, &codebook, &crate::progress::Silent).is_err());
        assert!(!refused.exists(), "nothing written");
    }

    /// `read_compact` of a compressed file decodes it a run of tiles at a time into the
    /// planes `CompactPlanes::from_maps` makes from the whole decoded maps: the same values
    /// (and u8 codings) in every layout, with a projection a block and with a codebook.
    #[test]
    fn compact_planes_read_by_runs_of_tiles_equal_those_of_the_decoded_maps() {
        let dir = tempfile::tempdir().unwrap();
        let img = sample(70, 45);
        for (i, settings) in [
            Settings {
                components: Some(5),
                tile: 16,
                ..Settings::default()
            },
            Settings {
                layout: Layout::Ycc,
                codec: TileCodec::parse("jpeg:90").unwrap(),
                pca_block: Some(24),
                components: Some(4),
                tile: 32,
                mip_levels: false,
                ..Settings::default()
            },
            Settings {
                layout: Layout::Lrgb,
                gain: true,
                tile: 16,
                mip_levels: true,
                ..Settings::default()
            },
            Settings {
                codebook: Some(16),
                tile: 16,
                ..Settings::default()
            },
        ]
        .into_iter()
        .enumerate()
        {
            let path = dir.path().join(format!("f{i}.rlz"));
            super::write(&path, &img, &settings).unwrap();
            // `read` decodes by runs too: the maps of the whole file decoded at once.
            let whole = super::read(&path).unwrap();
            let at_once = compress::unpack(&read_packed(&path).unwrap()).unwrap();
            assert!(
                whole == at_once,
                "{i}: read by runs equals the whole file unpacked"
            );
            // Runs of one tile, and whole rows of tiles.
            for (precision, run_bytes) in [
                (Precision::F16, 1),
                (Precision::U8, 1),
                (Precision::F16, 1 << 26),
                (Precision::U8, 1 << 26),
            ] {
                let (image, planes) =
                    super::read_compact_in_runs(&path, precision, run_bytes).unwrap();
                let want = CompactPlanes::from_maps(&whole.maps, precision).unwrap();
                assert_eq!((image.width(), image.height()), (70, 45));
                assert_eq!(image.maps.k, whole.maps.k);
                assert!(image.maps.data.is_empty(), "no f32 maps are kept");
                assert_eq!(image.meta, whole.meta);
                assert_eq!(image.depth, whole.depth);
                assert_eq!(planes.bytes(), want.bytes());
                for j in 0..3 * whole.maps.k {
                    assert_eq!(
                        planes.coding(j),
                        want.coding(j),
                        "{i} {precision:?} plane {j}"
                    );
                    for p in 0..70 * 45 {
                        assert_eq!(
                            planes.value(j, p).to_bits(),
                            want.value(j, p).to_bits(),
                            "{i} {precision:?} plane {j} pixel {p}"
                        );
                    }
                }
            }
        }
    }
}
