//! The relight/OpenLIME web format: a folder with `info.json` and coefficient planes as
//! 8-bit images, written by the RTI tool relight (cnr-isti-vclab/relight) and shown by
//! the OpenLIME viewer that museums publish RTIs with.
//!
//! # What the folder holds
//!
//! `info.json` gives the size, the `type` of functions (`ptm`, `hsh`, `sh`, `rbf`,
//! `bilinear`), the `colorspace` of the planes (`rgb`, `lrgb`, `mrgb`, `mycc`),
//! `nplanes` (or `yccplanes` for `mycc`), `materials[0]` with a `scale` and `bias` per
//! plane, and for the principal-component colour spaces a `basis` table of bytes. The
//! planes are grouped three to an image (`plane_N`, channels R, G, B are planes `3N`,
//! `3N+1`, `3N+2`), a plane's value being `(byte/255 − bias) · scale`. Layouts, found
//! from the files present: single images (`plane_N.jpg|png`), Deep Zoom
//! (`plane_N.dzi` + `plane_N_files/LEVEL/X_Y.jpg`), tarzoom (`plane_N.tzi` JSON with tile
//! offsets into `plane_N.tzb`) and itarzoom (`planes.tzi`/`.tzb`, the images of a tile
//! side by side, `stride` of them). Only the full-resolution level of a pyramid is read:
//! the deepest one, tiles indexed as OpenLIME does (level after level, rows of tiles).
//!
//! # How it maps onto relit
//!
//! Every type's functions are expressed with relit's bases, so relighting a folder is
//! relighting any relightable file; the maps are display-referred
//! ([`MapSpace::Srgb`]): relight fits sRGB-encoded pixels and OpenLIME shows the sum —
//! except where relight ≥ 2026 writes `"colorprofile": "RGB"`, its default, for values
//! fitted in linear light ([`MapSpace::Linear`]).
//!
//! * `ptm` + `rgb`: OpenLIME weighs plane images by `1, x, y, x², xy, y²`; relit's
//!   `ptm:6` orders the same monomials `x², y², xy, x, y, 1` ([`crate::basis`]): a
//!   permutation.
//! * `hsh` + `rgb`: OpenLIME's nine functions are relit's `hsh:9` with every `m ≠ 0`
//!   function negated and the band listed `m = l … −l` (the tests check this against
//!   the viewer's formulas). OpenLIME clamps the light's elevation to ≥ 0.15 rad; relit
//!   follows the functions to the horizon, so the two differ only for lights within
//!   8.6° of it.
//! * `sh` + `rgb`: OpenLIME's nine are relit's `sh:9` reordered, with signs and its `Y₂₀`
//!   doubled (its π is 3.1415, a 3·10⁻⁵ relative difference).
//! * `lrgb` (of any of those): plane image 0 is a colour, the rest luminance
//!   coefficients: relit's coefficient `i` of channel `c` is `colour_c · lum_i`, exact.
//! * `bilinear` + `mrgb`/`mycc`: a pixel's colour is `mean(L) + Σ_p coef_p · basis_p(L)`
//!   with `mean` and `basis_p` RGB (or YCC) values on a `resolution²` grid over relight's
//!   octahedral diamond, blended bilinearly: relit's `bilinear` basis with
//!   `map = octahedral`. Each channel's function is a grid of node values; relit shares
//!   one basis across channels, so the reader finds the principal node-space directions
//!   of every pixel's three grids (`pca_to_nodes`) and keeps as many as the 8-bit
//!   planes can tell apart (dropped energy under a quarter of a code, at most 64):
//!   within that of the exact decode.
//! * `mycc`: relight stores the first `yccplanes[1]` plane images as (Y, C1, C2)
//!   triples and the rest as three Y planes each, with `R = Y + C1/2 − C2/2`,
//!   `G = Y + C2/2`, `B = Y − C1/2 − C2/2`; the basis table agrees (a Y plane's C entries
//!   are all the zero code 127). OpenLIME 1.2.6 tests the plane image's index against
//!   `yccplanes[0]` instead, so it reads every image as a triple and drops the second and
//!   third Y plane of each Y-only image; relit decodes what the file holds (on relight's
//!   `ybln` fixture OpenLIME's canvas is then 26 dB from relit's, and 36.7 dB from relit
//!   decoding as OpenLIME does, the figure of the other types; OpenLIME's own picture
//!   shows colour fringes the file's decode does not).
//! * `rbf` + `mrgb`/`mycc`: the same with the nodes being the file's `lights`, blended
//!   by OpenLIME's normalised Gaussians of a light-dependent width: relit's `rbf` basis
//!   with `kernel = relight` (α = 8, β = 2, OpenLIME's constants).
//!
//! # Writing
//!
//! [`write`] writes `ptm:6`, `hsh:9` (or `hsh:4`, padded) and `sh:9` maps that are
//! display-referred as `ptm`/`hsh`/`sh` + `rgb` directly (or `lrgb`). Any other basis,
//! linear maps, and any maps when asked ([`WriteOptions::functions`]), go out as
//! principal components of each pixel's function tabulated at nodes, as relight does:
//!
//! * `bilinear`: the function's values at the nodes of a 12×12 octahedral grid (relight's
//!   is 8; see [`WriteOptions::resolution`]), which bilinear blending interpolates.
//! * `rbf`: 64 nodes over the upper hemisphere ([`WriteOptions::rbf_nodes`]), which
//!   OpenLIME blends with wide normalised Gaussians that do not interpolate; each node's
//!   value is fitted so that the blend follows the function (see `RBF_PULL`).
//!
//! Node values are sRGB-encoded when the maps are linear. In `mrgb` the `3·nodes` values
//! of the pixels are compressed to `planes` principal components together; in `mycc`
//! ([`WriteOptions::chroma_planes`]) they become luma and two chroma values per node,
//! each channel with components of its own. The stored mean is what the bytes can hold
//! (0 to 1; a negative chroma mean cannot be written), and the components are taken
//! about that mean. Planes are 8-bit with a scale and bias each (the full range of the
//! plane over 255 codes), as JPEG single images or pyramids.

use crate::basis::{grid_basis, BasisSpec, GridMap};
use crate::camera::Projection;
use crate::fsutil::StagedFolder;
use crate::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use crate::{Error, ErrorKind, Result};
use rayon::prelude::*;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The description file of a web folder.
pub const INFO: &str = "info.json";

/// The largest `info.json` read: a 64-light `rbf` basis of 64 planes is under 1 MiB.
const MAX_INFO_BYTES: u64 = 64 << 20;

/// The most planes a folder may declare (relight writes up to about 30).
const MAX_PLANES: usize = 192;

/// The finest bilinear grid read: relight writes 8; the node-space PCA is `resolution⁴`.
const MAX_RESOLUTION: usize = 32;

/// The most lights an `rbf` file may interpolate: its node-space PCA is `lights³`.
const MAX_RBF_LIGHTS: usize = 400;

/// OpenLIME's constants of relight's kernel (`α`, `β`: see [`crate::basis`]'s rbf).
const RBF_ALPHA: f64 = 8.0;
const RBF_BETA: f64 = 2.0;

/// Dropped node-space energy allowed when reading PCA planes, per value: a quarter of an
/// 8-bit code, far below the planes' own quantisation.
const READ_TOLERANCE: f64 = 0.25 / 255.0;

/// Whether `path` is a web folder (or its `info.json`).
pub fn is_web(path: &Path) -> bool {
    info_path(path).is_some()
}

fn info_path(path: &Path) -> Option<PathBuf> {
    if path.is_dir() {
        let info = path.join(INFO);
        info.is_file().then_some(info)
    } else if path.file_name().is_some_and(|n| n == INFO) && path.is_file() {
        Some(path.to_path_buf())
    } else {
        None
    }
}

#[derive(Debug, Deserialize)]
struct Info {
    width: usize,
    height: usize,
    #[serde(rename = "type")]
    kind: String,
    colorspace: String,
    #[serde(default)]
    nplanes: Option<usize>,
    #[serde(default)]
    yccplanes: Option<[usize; 3]>,
    #[serde(default)]
    resolution: Option<usize>,
    #[serde(default)]
    format: Option<String>,
    materials: Vec<Material>,
    #[serde(default)]
    basis: Option<Vec<f64>>,
    #[serde(default)]
    lights: Option<Vec<f64>>,
    /// relight ≥ 2026 states what its values are: `RGB` for linear light (its default),
    /// `sRGB` or `P3` for display-referred; older folders say nothing (display-referred).
    #[serde(default)]
    colorprofile: Option<String>,
}

#[derive(Debug, Deserialize)]
struct Material {
    scale: Vec<f64>,
    bias: Vec<f64>,
    #[serde(default)]
    range: Option<Vec<f64>>,
}

/// Read a web folder (or the folder of the `info.json` at `path`).
pub fn read(path: &Path) -> Result<RelightableImage> {
    let info_file = info_path(path).ok_or_else(|| {
        Error::new(
            ErrorKind::Io,
            format!("{} is not a web folder (no {INFO})", path.display()),
        )
    })?;
    let folder = info_file.parent().unwrap_or(Path::new(".")).to_path_buf();
    let bad = |what: String| Error::parse(format!("{}: {what}", info_file.display()));
    let len = std::fs::metadata(&info_file)
        .map_err(|e| Error::io(&info_file, "read", e))?
        .len();
    if len > MAX_INFO_BYTES {
        return Err(bad(format!("{len} bytes is too large for a description")));
    }
    let text = std::fs::read(&info_file).map_err(|e| Error::io(&info_file, "read", e))?;
    let info: Info = serde_json::from_slice(&text).map_err(|e| bad(e.to_string()))?;
    let nplanes = match (info.colorspace.as_str(), info.yccplanes, info.nplanes) {
        ("mycc", Some(y), _) => y.iter().sum(),
        ("mycc", None, _) => return Err(bad("`mycc` needs `yccplanes`".into())),
        (_, _, Some(n)) => n,
        _ => return Err(bad("`nplanes` is missing".into())),
    };
    if nplanes == 0 || !nplanes.is_multiple_of(3) || nplanes > MAX_PLANES {
        return Err(bad(format!(
            "`nplanes` {nplanes}: a positive multiple of 3 up to {MAX_PLANES}"
        )));
    }
    if info.width == 0 || info.height == 0 {
        return Err(bad("`width` and `height` must be positive".into()));
    }
    let material = match info.materials.as_slice() {
        [m, ..] => m,
        [] => return Err(bad("`materials` is empty".into())),
    };
    for (name, v) in [("scale", &material.scale), ("bias", &material.bias)] {
        if v.len() != nplanes || v.iter().any(|x| !x.is_finite()) {
            return Err(bad(format!(
                "`materials[0].{name}` must hold {nplanes} finite numbers, it has {}",
                v.len()
            )));
        }
    }
    let planes = PlaneImages::load(&folder, &info, nplanes)?;
    let value = |p: usize, pixel: usize| -> f32 {
        let byte = planes.images[p / 3][3 * pixel + p % 3] as f64;
        ((byte / 255.0 - material.bias[p]) * material.scale[p]) as f32
    };
    let n = info.width * info.height;
    let (spec, maps) = match (info.kind.as_str(), info.colorspace.as_str()) {
        ("ptm" | "hsh" | "sh", space @ ("rgb" | "lrgb")) => {
            let table = fixed_functions(&info.kind, nplanes, space == "lrgb").map_err(bad)?;
            let k = table.functions.len();
            let mut maps = CoefficientMaps::zeros(info.width, info.height, k);
            for (j, &(index, factor)) in table.functions.iter().enumerate() {
                for c in 0..3 {
                    let plane = maps.plane_mut(index, c);
                    if space == "rgb" {
                        let p = 3 * j + c;
                        plane
                            .par_iter_mut()
                            .enumerate()
                            .for_each(|(i, v)| *v = factor * value(p, i));
                    } else {
                        // Plane image 0 is the colour, then the luminance coefficients.
                        plane
                            .par_iter_mut()
                            .enumerate()
                            .for_each(|(i, v)| *v = factor * value(c, i) * value(3 + j, i));
                    }
                }
            }
            (BasisSpec::named(&table.name)?, maps)
        }
        ("bilinear", space @ ("mrgb" | "mycc")) => {
            let r = info
                .resolution
                .filter(|r| (2..=MAX_RESOLUTION).contains(r))
                .ok_or_else(|| {
                    bad(format!(
                        "`resolution` must be 2 to {MAX_RESOLUTION} for `bilinear`"
                    ))
                })?;
            let c = r * r;
            let grids = pca_grids(&info, material, nplanes, c, space == "mycc").map_err(bad)?;
            let coefficients: Vec<Vec<f32>> = (0..nplanes)
                .map(|p| (0..n).into_par_iter().map(|i| value(p, i)).collect())
                .collect();
            drop(planes);
            let (values, maps) = pca_to_nodes(&grids, c, &coefficients, info.width, info.height);
            let spec = grid_basis(r, values, GridMap::Octahedral)?.spec();
            (spec, maps)
        }
        ("rbf", space @ ("mrgb" | "mycc")) => {
            let lights = info
                .lights
                .as_ref()
                .ok_or_else(|| bad("`rbf` needs `lights`".into()))?;
            if lights.is_empty()
                || !lights.len().is_multiple_of(3)
                || lights.len() / 3 > MAX_RBF_LIGHTS
                || lights.iter().any(|v| !v.is_finite())
            {
                return Err(bad(format!(
                    "`lights` must hold 1 to {MAX_RBF_LIGHTS} finite (x, y, z), it has {} numbers",
                    lights.len()
                )));
            }
            let centres: Vec<crate::sphere::Vec3> = lights
                .chunks_exact(3)
                .map(|l| crate::sphere::Vec3::new(l[0], l[1], l[2]))
                .collect();
            let nodes = centres.len();
            let grids = pca_grids(&info, material, nplanes, nodes, space == "mycc").map_err(bad)?;
            let coefficients: Vec<Vec<f32>> = (0..nplanes)
                .map(|p| (0..n).into_par_iter().map(|i| value(p, i)).collect())
                .collect();
            drop(planes);
            let (values, maps) =
                pca_to_nodes(&grids, nodes, &coefficients, info.width, info.height);
            let spec = crate::basis::relight_rbf(centres, values, RBF_ALPHA, RBF_BETA)
                .map_err(|e| bad(format!("`lights`: {e}")))?
                .spec();
            (spec, maps)
        }
        (kind, space) => {
            return Err(bad(format!(
                "type `{kind}` with colour space `{space}` is not a combination relight writes"
            )))
        }
    };
    let space = match info.colorprofile.as_deref() {
        Some("RGB") => MapSpace::Linear,
        _ => MapSpace::Srgb,
    };
    let meta = Metadata::new(spec, space, Projection::default());
    Ok(RelightableImage {
        meta,
        maps,
        depth: None,
    })
}

/// One line about a web folder's own form: type, colour space, planes and layout.
pub fn describe(path: &Path) -> Result<String> {
    let info_file = info_path(path).ok_or_else(|| {
        Error::new(
            ErrorKind::Io,
            format!("{} is not a web folder", path.display()),
        )
    })?;
    let folder = info_file.parent().unwrap_or(Path::new("."));
    let text = std::fs::read(&info_file).map_err(|e| Error::io(&info_file, "read", e))?;
    let info: Info = serde_json::from_slice(&text)
        .map_err(|e| Error::parse(format!("{}: {e}", info_file.display())))?;
    let planes = match info.yccplanes {
        Some(y) if info.colorspace == "mycc" => y.iter().sum(),
        _ => info.nplanes.unwrap_or(0),
    };
    let layout = if folder.join("planes.tzi").is_file() {
        "itarzoom"
    } else if folder.join("plane_0.tzi").is_file() {
        "tarzoom"
    } else if folder.join("plane_0.dzi").is_file() {
        "Deep Zoom"
    } else {
        "single images"
    };
    Ok(format!(
        "relight/OpenLIME web folder: type {}, colour space {}, {planes} planes, {layout}",
        info.kind, info.colorspace
    ))
}

/// The plane images of a folder, decoded to 8-bit RGB at full resolution.
struct PlaneImages {
    images: Vec<Vec<u8>>,
}

impl PlaneImages {
    fn load(folder: &Path, info: &Info, nplanes: usize) -> Result<PlaneImages> {
        let count = nplanes / 3;
        let (w, h) = (info.width, info.height);
        let format = info.format.as_deref().unwrap_or("jpg");
        let images = if folder.join("planes.tzi").is_file() {
            itarzoom(folder, w, h, count)?
        } else {
            (0..count)
                .map(|j| {
                    let stem = format!("plane_{j}");
                    let tzi = folder.join(format!("{stem}.tzi"));
                    let dzi = folder.join(format!("{stem}.dzi"));
                    if tzi.is_file() {
                        let (index, tzb) = read_tarzoom(&tzi, w, h, 1)?;
                        index.assemble(&tzi, &tzb, 0)
                    } else if dzi.is_file() {
                        deep_zoom(&dzi, &folder.join(format!("{stem}_files")), w, h)
                    } else {
                        let wanted = folder.join(format!("{stem}.{format}"));
                        let path = [format, "jpg", "png"]
                            .iter()
                            .map(|ext| folder.join(format!("{stem}.{ext}")))
                            .find(|p| p.is_file())
                            .ok_or_else(|| {
                                Error::new(
                                    ErrorKind::Io,
                                    format!("{} is missing (no tiles either)", wanted.display()),
                                )
                            })?;
                        single_image(&path, w, h)
                    }
                })
                .collect::<Result<Vec<_>>>()?
        };
        Ok(PlaneImages { images })
    }
}

fn single_image(path: &Path, w: usize, h: usize) -> Result<Vec<u8>> {
    let (iw, ih) = image::image_dimensions(path).map_err(|e| Error::image(path, e))?;
    if (iw as usize, ih as usize) != (w, h) {
        return Err(Error::parse(format!(
            "{}: {iw}×{ih}, but {INFO} says {w}×{h}",
            path.display()
        )));
    }
    let image = image::open(path).map_err(|e| Error::image(path, e))?;
    Ok(image.to_rgb8().into_raw())
}

/// Tiles of a pyramid: `tilesize`, `overlap`, and the full-resolution level's grid.
#[derive(Clone, Copy, Debug)]
struct TileGrid {
    tilesize: usize,
    overlap: usize,
    columns: usize,
    rows: usize,
    width: usize,
    height: usize,
}

impl TileGrid {
    fn new(width: usize, height: usize, tilesize: usize, overlap: usize) -> Result<TileGrid> {
        if tilesize == 0 || overlap >= tilesize {
            return Err(Error::parse(format!(
                "tile size {tilesize} with overlap {overlap}"
            )));
        }
        Ok(TileGrid {
            tilesize,
            overlap,
            columns: width.div_ceil(tilesize),
            rows: height.div_ceil(tilesize),
            width,
            height,
        })
    }

    /// The number of levels OpenLIME counts for this size.
    fn levels(&self) -> usize {
        let ratio = self.width.max(self.height) as f64 / self.tilesize as f64;
        (ratio.log2().ceil().max(0.0) as usize) + 1
    }

    /// The size tile `(x, y)`'s image must have (its overlap included).
    fn tile_size(&self, x: usize, y: usize) -> (usize, usize) {
        let span = |i: usize, total: usize, count: usize| {
            let start = i * self.tilesize;
            let inner = self.tilesize.min(total - start);
            inner
                + if i > 0 { self.overlap } else { 0 }
                + if i + 1 < count { self.overlap } else { 0 }
        };
        (
            span(x, self.width, self.columns),
            span(y, self.height, self.rows),
        )
    }

    /// The full-resolution image from every tile (`tile(x, y)` decodes one, naming
    /// its source). The tiles are decoded first, each within the image decoder's memory
    /// limits and checked against the grid, so the image is allocated only once real
    /// tiles cover it, never from the header's size alone.
    fn assemble(
        &self,
        mut tile: impl FnMut(usize, usize) -> Result<(image::RgbImage, String)>,
    ) -> Result<Vec<u8>> {
        let mut tiles = Vec::new();
        for y in 0..self.rows {
            for x in 0..self.columns {
                tiles.push((x, y, tile(x, y)?));
            }
        }
        let mut out = vec![0u8; 3 * self.width * self.height];
        for (x, y, (decoded, source)) in tiles {
            self.place(x, y, &decoded, &mut out, &source)?;
        }
        Ok(out)
    }

    /// Copy tile `(x, y)`'s pixels (RGB, its own size checked) into `out`.
    fn place(
        &self,
        x: usize,
        y: usize,
        tile: &image::RgbImage,
        out: &mut [u8],
        source: &str,
    ) -> Result<()> {
        let (tw, th) = self.tile_size(x, y);
        if (tile.width() as usize, tile.height() as usize) != (tw, th) {
            return Err(Error::parse(format!(
                "{source}: tile ({x}, {y}) is {}×{}, expected {tw}×{th}",
                tile.width(),
                tile.height()
            )));
        }
        let (x0, y0) = (x * self.tilesize, y * self.tilesize);
        let skip_x = if x > 0 { self.overlap } else { 0 };
        let skip_y = if y > 0 { self.overlap } else { 0 };
        let cols = self.tilesize.min(self.width - x0);
        let rows = self.tilesize.min(self.height - y0);
        let raw = tile.as_raw();
        for r in 0..rows {
            let from = 3 * ((r + skip_y) * tw + skip_x);
            let to = 3 * ((y0 + r) * self.width + x0);
            out[to..to + 3 * cols].copy_from_slice(&raw[from..from + 3 * cols]);
        }
        Ok(())
    }
}

fn decode_tile(bytes: &[u8], expected: (usize, usize), source: &str) -> Result<image::RgbImage> {
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::parse(format!("{source}: {e}")))?;
    // The header's size is checked before the pixels are decoded, so no claim in a
    // tile makes the reader allocate more than the tile grid allows.
    let (w, h) = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::parse(format!("{source}: {e}")))?
        .into_dimensions()
        .map_err(|e| Error::parse(format!("{source}: {e}")))?;
    if (w as usize, h as usize) != expected {
        return Err(Error::parse(format!(
            "{source}: a {w}×{h} tile, expected {}×{}",
            expected.0, expected.1
        )));
    }
    Ok(reader
        .decode()
        .map_err(|e| Error::parse(format!("{source}: {e}")))?
        .to_rgb8())
}

fn deep_zoom(dzi: &Path, files: &Path, w: usize, h: usize) -> Result<Vec<u8>> {
    let text = std::fs::read_to_string(dzi).map_err(|e| Error::io(dzi, "read", e))?;
    let attribute = |name: &str| -> Result<usize> {
        let key = format!("{name}=\"");
        let start = text
            .find(&key)
            .ok_or_else(|| Error::parse(format!("{}: no `{name}`", dzi.display())))?
            + key.len();
        text[start..]
            .split('"')
            .next()
            .and_then(|v| v.trim().parse().ok())
            .ok_or_else(|| Error::parse(format!("{}: a bad `{name}`", dzi.display())))
    };
    let (dw, dh) = (attribute("Width")?, attribute("Height")?);
    if (dw, dh) != (w, h) {
        return Err(Error::parse(format!(
            "{}: {dw}×{dh}, but {INFO} says {w}×{h}",
            dzi.display()
        )));
    }
    let grid = TileGrid::new(w, h, attribute("TileSize")?, attribute("Overlap")?)?;
    let format = text
        .split("Format=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .unwrap_or("jpg")
        .to_string();
    // The deepest level is the full resolution whether levels are counted from the
    // tile size (relight, OpenLIME) or from one pixel (the Deep Zoom standard).
    let level = std::fs::read_dir(files)
        .map_err(|e| Error::io(files, "list", e))?
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<usize>().ok())
        .max()
        .ok_or_else(|| Error::parse(format!("{}: no levels", files.display())))?;
    grid.assemble(|x, y| {
        let path = files.join(format!("{level}/{x}_{y}.{format}"));
        let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, "read the tile", e))?;
        let source = path.display().to_string();
        Ok((decode_tile(&bytes, grid.tile_size(x, y), &source)?, source))
    })
}

#[derive(Debug, Deserialize)]
struct TarzoomIndex {
    tilesize: usize,
    #[serde(default)]
    overlap: usize,
    width: usize,
    height: usize,
    offsets: Vec<u64>,
    #[serde(default)]
    stride: Option<usize>,
}

/// A tarzoom index checked against its data file.
struct Tarzoom {
    grid: TileGrid,
    /// Index of the first full-resolution tile.
    first: usize,
    stride: usize,
    offsets: Vec<u64>,
}

fn read_tarzoom(tzi: &Path, w: usize, h: usize, stride: usize) -> Result<(Tarzoom, Vec<u8>)> {
    let bad = |what: String| Error::parse(format!("{}: {what}", tzi.display()));
    let len = std::fs::metadata(tzi)
        .map_err(|e| Error::io(tzi, "read", e))?
        .len();
    if len > MAX_INFO_BYTES {
        return Err(bad("too large for a tile index".into()));
    }
    let text = std::fs::read(tzi).map_err(|e| Error::io(tzi, "read", e))?;
    let index: TarzoomIndex = serde_json::from_slice(&text).map_err(|e| bad(e.to_string()))?;
    if (index.width, index.height) != (w, h) {
        return Err(bad(format!(
            "{}×{}, but {INFO} says {w}×{h}",
            index.width, index.height
        )));
    }
    let stride = index.stride.unwrap_or(stride);
    if stride == 0 {
        return Err(bad("`stride` must be positive".into()));
    }
    let grid =
        TileGrid::new(w, h, index.tilesize, index.overlap).map_err(|e| bad(e.to_string()))?;
    let levels = grid.levels();
    let tiles_at = |level: usize| {
        let size = grid.tilesize << (levels - 1 - level);
        w.div_ceil(size) * h.div_ceil(size)
    };
    let first: usize = (0..levels - 1).map(tiles_at).sum();
    let tiles = first + grid.columns * grid.rows;
    if index.offsets.len() != tiles * stride + 1 {
        return Err(bad(format!(
            "{} offsets, but {levels} levels of {}-pixel tiles need {}",
            index.offsets.len(),
            grid.tilesize,
            tiles * stride + 1
        )));
    }
    if index.offsets.windows(2).any(|p| p[1] < p[0]) {
        return Err(bad("`offsets` must not decrease".into()));
    }
    let tzb = tzi.with_extension("tzb");
    let data_len = std::fs::metadata(&tzb)
        .map_err(|e| Error::io(&tzb, "read", e))?
        .len();
    let end = *index.offsets.last().expect("offsets");
    if end > data_len {
        return Err(bad(format!(
            "offsets reach byte {end}, but {} has {data_len}",
            tzb.display()
        )));
    }
    let data = std::fs::read(&tzb).map_err(|e| Error::io(&tzb, "read", e))?;
    Ok((
        Tarzoom {
            grid,
            first,
            stride,
            offsets: index.offsets,
        },
        data,
    ))
}

impl Tarzoom {
    /// Plane image `image` (of `stride` per tile) at full resolution.
    fn assemble(&self, tzi: &Path, data: &[u8], image: usize) -> Result<Vec<u8>> {
        let grid = self.grid;
        grid.assemble(|x, y| {
            let i = (self.first + y * grid.columns + x) * self.stride + image;
            let (a, b) = (self.offsets[i] as usize, self.offsets[i + 1] as usize);
            let source = format!("{} tile ({x}, {y}) image {image}", tzi.display());
            Ok((
                decode_tile(&data[a..b], grid.tile_size(x, y), &source)?,
                source,
            ))
        })
    }
}

fn itarzoom(folder: &Path, w: usize, h: usize, count: usize) -> Result<Vec<Vec<u8>>> {
    let tzi = folder.join("planes.tzi");
    let (index, data) = read_tarzoom(&tzi, w, h, count)?;
    if index.stride != count {
        return Err(Error::parse(format!(
            "{}: `stride` {} but {INFO} declares {count} plane images",
            tzi.display(),
            index.stride
        )));
    }
    (0..count).map(|j| index.assemble(&tzi, &data, j)).collect()
}

/// A fixed family's functions in the file's order: for each, relit's index and the
/// factor `f` with `file function = f · relit function` (so a file coefficient times
/// `f` is relit's coefficient).
struct FixedFunctions {
    name: String,
    functions: Vec<(usize, f32)>,
}

/// The file's order of `kind`'s functions as relit coefficients (see the module docs).
fn fixed_functions(
    kind: &str,
    nplanes: usize,
    lrgb: bool,
) -> std::result::Result<FixedFunctions, String> {
    let k = if lrgb { nplanes - 3 } else { nplanes / 3 };
    let functions: Vec<(usize, f32)> = match (kind, k) {
        // 1, x, y, x², xy, y² against relit's x², y², xy, x, y, 1.
        ("ptm", 6) => [5, 3, 4, 0, 2, 1].iter().map(|&i| (i, 1.0)).collect(),
        ("hsh", 4 | 9) => {
            let order = if k == 4 { 2 } else { 3 };
            (0..order as i64)
                .flat_map(|l| (-l..=l).rev().map(move |m| (l, m)))
                .map(|(l, m)| ((l * (l + 1) + m) as usize, if m == 0 { 1.0 } else { -1.0 }))
                .collect()
        }
        // OpenLIME: c₀, c₁x, c₁z, c₁y, c₂xy, c₂xz, c₂₀(3z²−1), c₂yz, c₂(y²−x²)/2 against
        // relit's Condon–Shortley Y₁₋₁ = −c₁y, Y₁₁ = −c₁x, Y₂₋₁ = −c₂yz, Y₂₁ = −c₂xz,
        // Y₂₂ = c₂(x²−y²)/2.
        ("sh", 9) => vec![
            (0, 1.0),
            (3, -1.0),
            (2, 1.0),
            (1, -1.0),
            (4, 1.0),
            (7, -1.0),
            // OpenLIME's c₂₀ is ½√(5/π), twice relit's Y₂₀ factor.
            (6, 2.0),
            (5, -1.0),
            (8, -1.0),
        ],
        _ => {
            return Err(format!(
                "type `{kind}` with {k} coefficients per channel is not one OpenLIME shows"
            ))
        }
    };
    let name = format!("{kind}:{}", if kind == "hsh" { k } else { functions.len() });
    Ok(FixedFunctions { name, functions })
}

/// The node matrices `G_c` (`nodes × (P+1)`, row-major) of a principal-component file:
/// channel `c` of a pixel is `Σ_t G_c[node][t] u_t` at each node, `u = (1, coef_0, …)`.
fn pca_grids(
    info: &Info,
    material: &Material,
    nplanes: usize,
    nodes: usize,
    ycc: bool,
) -> std::result::Result<[Vec<f64>; 3], String> {
    let basis = info.basis.as_ref().ok_or("`basis` is missing")?;
    let expected = 3 * (nplanes + 1) * nodes;
    if basis.len() != expected {
        return Err(format!(
            "`basis` holds {} values, {nplanes} planes on {nodes} nodes need {expected}",
            basis.len()
        ));
    }
    if basis.iter().any(|b| !(0.0..=255.0).contains(b)) {
        return Err("`basis` holds bytes, 0 to 255".into());
    }
    let range = material
        .range
        .as_ref()
        .filter(|r| r.len() == nplanes && r.iter().all(|v| v.is_finite() && *v != 0.0))
        .ok_or(format!(
            "`materials[0].range` must hold {nplanes} non-zero numbers"
        ))?;
    let decoded = |t: usize, node: usize, s: usize| -> f64 {
        let byte = basis[3 * (t * nodes + node) + s];
        if t == 0 {
            byte / 255.0
        } else {
            (byte - 127.0) / range[t - 1]
        }
    };
    // Which YCC component a plane feeds: triples first, then Y only.
    let triples = if ycc {
        let [ny, nc1, nc2] = info.yccplanes.expect("checked");
        let images = nplanes / 3;
        if nc1 != nc2 || nc1 > images || ny != nc1 + 3 * (images - nc1) {
            return Err(format!(
                "`yccplanes` [{ny}, {nc1}, {nc2}] is not relight's layout of {images} images"
            ));
        }
        nc1
    } else {
        0
    };
    let to_rgb = |v: [f64; 3]| -> [f64; 3] {
        if ycc {
            let [y, c1, c2] = v;
            [
                y + c1 / 2.0 - c2 / 2.0,
                y + c2 / 2.0,
                y - c1 / 2.0 - c2 / 2.0,
            ]
        } else {
            v
        }
    };
    let width = nplanes + 1;
    let mut g = [
        vec![0.0; nodes * width],
        vec![0.0; nodes * width],
        vec![0.0; nodes * width],
    ];
    for node in 0..nodes {
        for t in 0..width {
            let mut v = [0.0; 3];
            if t == 0 || !ycc {
                (0..3).for_each(|s| v[s] = decoded(t, node, s));
            } else {
                let p = t - 1;
                let s = if p / 3 < triples { p % 3 } else { 0 };
                v[s] = decoded(t, node, s);
            }
            let rgb = to_rgb(v);
            for c in 0..3 {
                g[c][node * width + t] = rgb[c];
            }
        }
    }
    Ok(g)
}

/// The principal node-space directions of the pixels' grids `f_c = G_c u` (the first
/// `K` that leave less than [`READ_TOLERANCE`] per value, at most 64) as `K` grids, and
/// each pixel's coordinates along them: `(grids K × nodes, maps)`.
pub(crate) fn pca_to_nodes(
    g: &[Vec<f64>; 3],
    nodes: usize,
    coefficients: &[Vec<f32>],
    width: usize,
    height: usize,
) -> (Vec<f64>, CoefficientMaps) {
    let n = width * height;
    let t = coefficients.len() + 1;
    // Second moments of u over the pixels: the pixels enter only through them.
    let rows: Vec<Vec<f64>> = (0..n)
        .into_par_iter()
        .fold(
            || vec![0.0; t * t],
            |mut s, i| {
                let mut u = vec![1.0f64; t];
                for (p, plane) in coefficients.iter().enumerate() {
                    u[p + 1] = plane[i] as f64;
                }
                for a in 0..t {
                    for b in a..t {
                        s[a * t + b] += u[a] * u[b];
                    }
                }
                s
            },
        )
        .collect();
    let mut s = vec![0.0; t * t];
    for part in rows {
        s.iter_mut().zip(&part).for_each(|(a, b)| *a += b);
    }
    for a in 0..t {
        for b in 0..a {
            s[a * t + b] = s[b * t + a];
        }
    }
    // M = Σ_c G_c S G_cᵀ.
    let mut m = vec![0.0; nodes * nodes];
    for gc in g {
        let mut gs = vec![0.0; nodes * t];
        crate::linalg::matmul_bt(nodes, t, t, gc, &s, &mut gs);
        let mut part = vec![0.0; nodes * nodes];
        crate::linalg::matmul_bt(nodes, t, nodes, &gs, gc, &mut part);
        m.iter_mut().zip(&part).for_each(|(a, b)| *a += b);
    }
    let (values, vectors) = crate::linalg::symmetric_eigen(&m, nodes);
    let allowed = READ_TOLERANCE * READ_TOLERANCE * (3 * n * nodes) as f64;
    let most = nodes.min(64);
    let mut k = most;
    let mut dropped: f64 = values[most..].iter().map(|v| v.max(0.0)).sum();
    while k > 1 && dropped + values[k - 1].max(0.0) <= allowed {
        dropped += values[k - 1].max(0.0);
        k -= 1;
    }
    let grids = vectors[..k * nodes].to_vec();
    // A_c = Eᵀ G_c: each channel's coordinates are a fixed mix of u.
    let mixes: Vec<Vec<f64>> = g
        .iter()
        .map(|gc| {
            let mut a = vec![0.0; k * t];
            for q in 0..k {
                for node in 0..nodes {
                    let e = grids[q * nodes + node];
                    for j in 0..t {
                        a[q * t + j] += e * gc[node * t + j];
                    }
                }
            }
            a
        })
        .collect();
    let mut maps = CoefficientMaps::zeros(width, height, k);
    maps.data
        .par_chunks_mut(n)
        .enumerate()
        .for_each(|(plane, out)| {
            let (q, c) = (plane / 3, plane % 3);
            let row = &mixes[c][q * t..(q + 1) * t];
            for (i, v) in out.iter_mut().enumerate() {
                let mut sum = row[0];
                for (p, coef) in coefficients.iter().enumerate() {
                    sum += row[p + 1] * coef[i] as f64;
                }
                *v = sum as f32;
            }
        });
    (grids, maps)
}

/// How [`write`] lays out and encodes the planes.
#[derive(Clone, Debug)]
pub struct WriteOptions {
    /// JPEG quality of the plane images, 1–100.
    pub quality: u8,
    /// Principal components kept when the maps are written as `bilinear` (a multiple of
    /// 3; relight's default is 18).
    pub planes: usize,
    /// Nodes per side of the `bilinear` grid. relight writes 8; relit 12, which costs
    /// no bytes in the planes and follows a fit's highlights and shadows better
    /// (RealRTI item1, rbf:16 fitted by relit, against its photos at five captured
    /// lights: 32.4–39.3 dB at 8, 32.7–40.7 dB at 12; the EXR itself 33.3–42.5 dB).
    /// `None`: a basis that is itself an octahedral bilinear grid of at most
    /// [`MAX_WRITE_RESOLUTION`] nodes a side keeps its grid (the file then holds its
    /// functions exactly, before the principal components and JPEG); any other, 12.
    pub resolution: Option<usize>,
    /// How the plane images are laid out: OpenLIME's `image`, `deepzoom`, `tarzoom` or
    /// `itarzoom`.
    pub layout: Layout,
    /// Write `ptm`, `hsh` and `sh` files as `lrgb` (one colour image times luminance
    /// coefficients, a third of the planes) instead of `rgb`.
    pub lrgb: bool,
    /// Which functions the file holds: the maps' own where OpenLIME has them, or
    /// principal components tabulated on a grid or at blended nodes.
    pub functions: WebFunctions,
    /// Nodes of an `rbf` file, spread over the upper hemisphere.
    pub rbf_nodes: usize,
    /// Write the principal components in relight's `mycc` colour space (luma and two
    /// chroma channels, each its own components) with this many planes per chroma
    /// channel, instead of `mrgb`. `planes / 3` makes every plane image a (Y, C1, C2)
    /// triple, the one `mycc` layout OpenLIME 1.2.6 reads as relight means it (it reads
    /// the luma-only images of fewer chroma planes as triples too; relit reads both).
    pub chroma_planes: Option<usize>,
}

/// The functions a web folder holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WebFunctions {
    /// `ptm`, `hsh` or `sh` + `rgb` for display-referred maps of those bases, `bilinear`
    /// for the rest.
    #[default]
    Auto,
    /// Principal components on relight's octahedral grid.
    Bilinear,
    /// Principal components at nodes blended by OpenLIME's normalised Gaussians.
    Rbf,
}

/// The layouts of a web folder's plane images, as OpenLIME names them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Layout {
    /// One JPEG per plane image (`plane_N.jpg`).
    #[default]
    Image,
    /// A Deep Zoom pyramid per plane image (`plane_N.dzi`, `plane_N_files/L/X_Y.jpg`).
    DeepZoom,
    /// A pyramid per plane image in one file (`plane_N.tzb`) with its tiles' byte
    /// offsets in `plane_N.tzi`: one request per tile instead of a file.
    Tarzoom,
    /// One pyramid for all plane images (`planes.tzb`, `planes.tzi`): each tile's images
    /// side by side, fetched in one request.
    Itarzoom,
}

impl Layout {
    /// The name OpenLIME's `layout` option takes.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Image => "image",
            Layout::DeepZoom => "deepzoom",
            Layout::Tarzoom => "tarzoom",
            Layout::Itarzoom => "itarzoom",
        }
    }
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            quality: 95,
            planes: 18,
            resolution: None,
            layout: Layout::Image,
            lrgb: false,
            functions: WebFunctions::Auto,
            rbf_nodes: DEFAULT_RBF_NODES,
            chroma_planes: None,
        }
    }
}

/// Nodes of a written `rbf` file. RealRTI items 1, 2 and 6 (as for [`RBF_PULL`]), mean
/// over the fifteen photos: 32 nodes 37.5 dB, 48 37.5, 64 37.7, 96 37.2.
pub const DEFAULT_RBF_NODES: usize = 64;

/// Tile side of a written Deep Zoom pyramid (relight's).
const DEEP_ZOOM_TILE: usize = 256;

fn encode_jpeg(rgb: &[u8], w: usize, h: usize, quality: u8) -> Result<Vec<u8>> {
    crate::image::jpeg::encode_rgb(rgb, w, h, quality)
}

/// The tile side and the levels of a written pyramid: relight's 256-pixel tiles, or the
/// least power of two covering a small image (whose level count OpenLIME would
/// otherwise make zero), halving down to the one-tile level.
fn pyramid_shape(w: usize, h: usize) -> Result<(usize, usize)> {
    let tile = DEEP_ZOOM_TILE.min(w.max(h).next_power_of_two());
    Ok((tile, TileGrid::new(w, h, tile, 0)?.levels()))
}

/// A plane image's levels, finest first: each the 2×2 means of the one before, sizes
/// rounded up.
fn pyramid(rgb: &[u8], w: usize, h: usize, levels: usize) -> Vec<(usize, usize, Vec<u8>)> {
    let mut pyramid = vec![(w, h, rgb.to_vec())];
    for _ in 1..levels {
        let (pw, ph, prev) = pyramid.last().expect("a level");
        let (nw, nh) = (pw.div_ceil(2), ph.div_ceil(2));
        let mut next = vec![0u8; 3 * nw * nh];
        for y in 0..nh {
            for x in 0..nw {
                for c in 0..3 {
                    let (mut sum, mut count) = (0u32, 0u32);
                    for (sx, sy) in [
                        (2 * x, 2 * y),
                        (2 * x + 1, 2 * y),
                        (2 * x, 2 * y + 1),
                        (2 * x + 1, 2 * y + 1),
                    ] {
                        if sx < *pw && sy < *ph {
                            sum += prev[3 * (sy * pw + sx) + c] as u32;
                            count += 1;
                        }
                    }
                    next[3 * (y * nw + x) + c] = ((sum + count / 2) / count) as u8;
                }
            }
        }
        pyramid.push((nw, nh, next));
    }
    pyramid
}

/// One JPEG tile of a pyramid: its level (0 at the one-tile level), column and row.
struct PyramidTile {
    level: usize,
    x: usize,
    y: usize,
    jpeg: Vec<u8>,
}

/// Every tile of a plane image, in the order OpenLIME numbers them: level by level from
/// the one-tile level, rows top to bottom, columns left to right.
fn pyramid_tiles(rgb: &[u8], w: usize, h: usize, quality: u8) -> Result<Vec<PyramidTile>> {
    let (tile, levels) = pyramid_shape(w, h)?;
    let mut tiles = Vec::new();
    for (level, (lw, lh, pixels)) in pyramid(rgb, w, h, levels).iter().rev().enumerate() {
        for ty in 0..lh.div_ceil(tile) {
            for tx in 0..lw.div_ceil(tile) {
                let (x0, y0) = (tx * tile, ty * tile);
                let (cw, ch) = (tile.min(lw - x0), tile.min(lh - y0));
                let mut cut = Vec::with_capacity(3 * cw * ch);
                for y in y0..y0 + ch {
                    cut.extend_from_slice(&pixels[3 * (y * lw + x0)..3 * (y * lw + x0 + cw)]);
                }
                tiles.push(PyramidTile {
                    level,
                    x: tx,
                    y: ty,
                    jpeg: encode_jpeg(&cut, cw, ch, quality)?,
                });
            }
        }
    }
    Ok(tiles)
}

/// A plane image as Deep Zoom files (name relative to the folder, bytes): the `.dzi`
/// and every level's tiles, levels numbered as OpenLIME counts them, from the one-tile
/// level.
fn deep_zoom_files(
    stem: &str,
    rgb: &[u8],
    w: usize,
    h: usize,
    quality: u8,
) -> Result<Vec<(String, Vec<u8>)>> {
    let (tile, _) = pyramid_shape(w, h)?;
    let mut files = vec![(
        format!("{stem}.dzi"),
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Image xmlns=\"http://schemas.microsoft.com/deepzoom/2008\" Format=\"jpg\" Overlap=\"0\" TileSize=\"{tile}\">\n  <Size Height=\"{h}\" Width=\"{w}\"/>\n</Image>\n"
        )
        .into_bytes(),
    )];
    for t in pyramid_tiles(rgb, w, h, quality)? {
        files.push((
            format!("{stem}_files/{}/{}_{}.jpg", t.level, t.x, t.y),
            t.jpeg,
        ));
    }
    Ok(files)
}

/// A tarzoom pair (`STEM.tzi`, `STEM.tzb`) holding `images` tile lists (each in
/// [`pyramid_tiles`]' order) interleaved: tile 0 of every image, then tile 1, …
/// (`stride` = the number of images; 1 is plain tarzoom, more is itarzoom).
fn tarzoom_files(
    stem: &str,
    images: &[Vec<PyramidTile>],
    w: usize,
    h: usize,
) -> Result<Vec<(String, Vec<u8>)>> {
    let (tile, levels) = pyramid_shape(w, h)?;
    let tiles = images.first().map_or(0, |t| t.len());
    let mut data = Vec::new();
    let mut offsets = vec![0u64];
    for t in 0..tiles {
        for image in images {
            data.extend_from_slice(&image[t].jpeg);
            offsets.push(data.len() as u64);
        }
    }
    let mut index = serde_json::json!({
        "tilesize": tile,
        "overlap": 0,
        "format": "jpg",
        "width": w,
        "height": h,
        "nlevels": levels,
        "offsets": offsets,
    });
    if images.len() > 1 {
        index["stride"] = images.len().into();
    }
    let index = serde_json::to_vec(&index).map_err(|e| Error::invalid(e.to_string()))?;
    Ok(vec![
        (format!("{stem}.tzi"), index),
        (format!("{stem}.tzb"), data),
    ])
}

/// What [`write`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct WriteSummary {
    /// The file's `type` (`ptm`, `hsh`, `bilinear`).
    pub kind: String,
    /// The file's `colorspace`.
    pub colorspace: String,
    /// Planes written.
    pub planes: usize,
    /// Files written (`info.json` included) and their bytes.
    pub files: usize,
    pub bytes: u64,
}

/// The most nodes per side [`write`] uses: its principal components are found in
/// `3·resolution²` dimensions by a dense eigen-decomposition ([`crate::linalg::symmetric_eigen`]).
pub const MAX_WRITE_RESOLUTION: usize = 12;

/// The `bilinear` grid written for a basis that is not one ([`WriteOptions::resolution`]).
pub const DEFAULT_WRITE_RESOLUTION: usize = 12;

/// Write `image` as a web folder at `folder` (created, or its files replaced one by one
/// through [`crate::fsutil::StagedFolder`]): `info.json` and JPEG planes, single
/// images or Deep Zoom tiles.
/// See the module docs for which maps go out as which type.
pub fn write(
    folder: &Path,
    image: &RelightableImage,
    options: &WriteOptions,
) -> Result<WriteSummary> {
    if !(1..=100).contains(&options.quality) {
        return Err(Error::invalid("JPEG quality is 1 to 100"));
    }
    let (w, h) = (image.width(), image.height());
    if w == 0 || h == 0 || w > 65535 || h > 65535 {
        return Err(Error::invalid(format!(
            "a {w}×{h} image does not fit JPEG planes (1 to 65535 pixels a side)"
        )));
    }
    let basis = image.meta.basis.build()?;
    let own_functions = options.functions == WebFunctions::Auto && options.chroma_planes.is_none();
    let fixed = match (image.meta.color_space, basis.family(), basis.len()) {
        _ if !own_functions => None,
        (MapSpace::Srgb, "ptm", 6) => Some(("ptm", 6)),
        (MapSpace::Srgb, "hsh", k @ (4 | 9)) => Some(("hsh", k)),
        (MapSpace::Srgb, "sh", 9) => Some(("sh", 9)),
        _ => None,
    };
    let (mut info, planes) = match fixed {
        Some((kind, k)) if options.lrgb => {
            let (mut info, planes) = fixed_planes(image, kind, k)?;
            info["colorspace"] = "lrgb".into();
            (info, lrgb_planes(&planes))
        }
        Some((kind, k)) => fixed_planes(image, kind, k)?,
        None => {
            let table = match options.functions {
                WebFunctions::Rbf => rbf_nodes(basis.as_ref(), options.rbf_nodes)?,
                WebFunctions::Auto | WebFunctions::Bilinear => {
                    let own = basis
                        .planar_grid()
                        .filter(|p| p.map == GridMap::Octahedral)
                        .map(|p| p.grid)
                        .filter(|&g| g <= MAX_WRITE_RESOLUTION);
                    let r = options
                        .resolution
                        .or(own)
                        .unwrap_or(DEFAULT_WRITE_RESOLUTION);
                    bilinear_nodes(basis.as_ref(), r)?
                }
            };
            pca_planes(image, &table, options)?
        }
    };
    let nplanes = planes.len();
    let quantised: Vec<(Vec<u8>, f64, f64)> = planes.par_iter().map(|p| quantise(p)).collect();
    drop(planes);
    info["width"] = w.into();
    info["height"] = h.into();
    info["format"] = "jpg".into();
    info["nplanes"] = nplanes.into();
    info["quality"] = options.quality.into();
    let material = info["materials"][0].as_object_mut().expect("a material");
    material.insert(
        "scale".into(),
        quantised.iter().map(|q| q.1).collect::<Vec<_>>().into(),
    );
    material.insert(
        "bias".into(),
        quantised.iter().map(|q| q.2).collect::<Vec<_>>().into(),
    );
    let staged = StagedFolder::new(folder)?;
    let interleave = |three: &[(Vec<u8>, f64, f64)]| {
        let mut rgb = vec![0u8; 3 * w * h];
        for (c, (codes, _, _)) in three.iter().enumerate() {
            rgb.iter_mut()
                .skip(c)
                .step_by(3)
                .zip(codes)
                .for_each(|(o, v)| *o = *v);
        }
        rgb
    };
    let encoded: Vec<Vec<(String, Vec<u8>)>> = if options.layout == Layout::Itarzoom {
        let tiles: Vec<_> = quantised
            .par_chunks(3)
            .map(|three| pyramid_tiles(&interleave(three), w, h, options.quality))
            .collect::<Result<_>>()?;
        vec![tarzoom_files("planes", &tiles, w, h)?]
    } else {
        quantised
            .par_chunks(3)
            .enumerate()
            .map(|(j, three)| {
                let rgb = interleave(three);
                let stem = format!("plane_{j}");
                match options.layout {
                    Layout::Image => Ok(vec![(
                        format!("{stem}.jpg"),
                        encode_jpeg(&rgb, w, h, options.quality)?,
                    )]),
                    Layout::DeepZoom => deep_zoom_files(&stem, &rgb, w, h, options.quality),
                    Layout::Tarzoom | Layout::Itarzoom => {
                        let tiles = pyramid_tiles(&rgb, w, h, options.quality)?;
                        tarzoom_files(&stem, &[tiles], w, h)
                    }
                }
            })
            .collect::<Result<_>>()?
    };
    let mut bytes = 0u64;
    let mut files = 1;
    for (name, data) in encoded.iter().flatten() {
        let path = staged.file(name)?;
        std::fs::write(&path, data).map_err(|e| Error::io(&path, "write", e))?;
        bytes += data.len() as u64;
        files += 1;
    }
    let text = serde_json::to_vec(&info).map_err(|e| Error::invalid(e.to_string()))?;
    let path = staged.file(INFO)?;
    std::fs::write(&path, &text).map_err(|e| Error::io(&path, "write", e))?;
    bytes += text.len() as u64;
    staged.commit()?;
    Ok(WriteSummary {
        kind: info["type"].as_str().unwrap_or_default().to_string(),
        colorspace: info["colorspace"].as_str().unwrap_or_default().to_string(),
        planes: nplanes,
        files,
        bytes,
    })
}

/// 8-bit codes of a plane with relight's scale and bias: `value = (code/255 − bias)·scale`
/// over the plane's finite range.
fn quantise(plane: &[f32]) -> (Vec<u8>, f64, f64) {
    let (lo, hi) = plane
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v as f64), b.max(v as f64))
        });
    let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
    let scale = if hi > lo { hi - lo } else { 1.0 };
    let codes = plane
        .iter()
        .map(|&v| {
            let v = if v.is_finite() { v as f64 } else { lo };
            ((v - lo) / scale * 255.0).round().clamp(0.0, 255.0) as u8
        })
        .collect();
    (codes, scale, -lo / scale)
}

/// `ptm`, `hsh`, `sh` + `rgb`: the maps' own coefficients in the file's order.
fn fixed_planes(
    image: &RelightableImage,
    kind: &str,
    k: usize,
) -> Result<(serde_json::Value, Vec<Vec<f32>>)> {
    // hsh:4 goes out as OpenLIME's nine functions, the second band zero.
    let order = if kind == "hsh" { 27 } else { 3 * k };
    let table = fixed_functions(kind, order, false).map_err(Error::invalid)?;
    let n = image.maps.pixels();
    let mut planes = Vec::new();
    for &(index, factor) in &table.functions {
        for c in 0..3 {
            planes.push(if index < k {
                image
                    .maps
                    .plane(index, c)
                    .iter()
                    .map(|v| v / factor)
                    .collect()
            } else {
                vec![0.0; n]
            });
        }
    }
    let info = serde_json::json!({
        "type": kind,
        "colorspace": "rgb",
        "materials": [{}],
    });
    Ok((info, planes))
}

/// How much brighter than the pixel the written luminance is (and the colour darker):
/// OpenLIME returns the luminance as the fragment's alpha, so a luminance under 1 shows
/// the page through the image; at this scale only a pixel darker than 1/255 of white is
/// not opaque.
const LRGB_LUMINANCE_SCALE: f64 = 255.0;

/// `rgb` planes (three per function) as `lrgb`: a colour (planes 0–2) times one
/// luminance coefficient per function (planes 3…, padded with zeros to whole images).
/// Each pixel's colour and luminances are the least-squares rank-one factors of its
/// functions × channels, the luminance being the channels' mean (times
/// [`LRGB_LUMINANCE_SCALE`]): exact where a pixel's channels are one function scaled, as
/// in a PTM LRGB file.
fn lrgb_planes(rgb: &[Vec<f32>]) -> Vec<Vec<f32>> {
    let k = rgb.len() / 3;
    let n = rgb.first().map_or(0, |p| p.len());
    let images = k.div_ceil(3);
    let mut out = vec![vec![0f32; n]; 3 + 3 * images];
    let (colour, rest) = out.split_at_mut(3);
    for i in 0..n {
        let mut norm = 0.0f64;
        for j in 0..k {
            let lum =
                LRGB_LUMINANCE_SCALE * (0..3).map(|c| rgb[3 * j + c][i] as f64).sum::<f64>() / 3.0;
            rest[j][i] = lum as f32;
            norm += lum * lum;
        }
        if norm > 0.0 {
            for (c, plane) in colour.iter_mut().enumerate() {
                let dot: f64 = (0..k)
                    .map(|j| rgb[3 * j + c][i] as f64 * rest[j][i] as f64)
                    .sum();
                plane[i] = (dot / norm) as f32;
            }
        }
    }
    out
}

/// Where a principal-component file tabulates each pixel's function, and how a pixel's
/// coefficients become the values there.
struct NodeTable {
    /// The file's `type`.
    kind: &'static str,
    nodes: usize,
    /// `nodes × k`, row-major: a channel's node values are this matrix times its `k`
    /// coefficients.
    to_nodes: Vec<f64>,
    /// The fields of `info.json` that place the nodes (`resolution` or `lights`).
    fields: serde_json::Map<String, serde_json::Value>,
}

/// `bilinear`: the octahedral grid's nodes, each holding the function's value there
/// (bilinear blending interpolates them).
fn bilinear_nodes(basis: &dyn crate::basis::Basis, r: usize) -> Result<NodeTable> {
    if !(2..=MAX_WRITE_RESOLUTION).contains(&r) {
        return Err(Error::invalid(format!(
            "the bilinear grid has 2 to {MAX_WRITE_RESOLUTION} nodes a side, not {r}"
        )));
    }
    let k = basis.len();
    let mut to_nodes = vec![0.0; r * r * k];
    for j in 0..r {
        for i in 0..r {
            let d = GridMap::Octahedral.node_direction(r, i, j);
            basis.eval(d, &mut to_nodes[(j * r + i) * k..(j * r + i + 1) * k]);
        }
    }
    let mut fields = serde_json::Map::new();
    fields.insert("resolution".into(), r.into());
    Ok(NodeTable {
        kind: "bilinear",
        nodes: r * r,
        to_nodes,
        fields,
    })
}

/// How strongly `rbf` node values are held to the function's own value at their node,
/// relative to the blending's mean weight. OpenLIME blends nodes with wide normalised
/// Gaussians that do not interpolate (a node's own weight is well under one), so values
/// taken at the nodes come out blurred; values fitted so that the *blend* follows the
/// function undo part of that, and this pull keeps the fit from swinging between close
/// nodes. The fit weighs directions by `z²`: a function's far extrapolation toward the
/// horizon, below a dome's lowest lights, would otherwise cost it where the lights are.
/// Chosen on RealRTI items 1, 2 and 6 (relit's auto fits written at 48 nodes, 18 planes,
/// read back and compared with the photos at the five peer-protocol lights; pulls 0.01
/// to 1, weights 1, z, z², z³, z⁴): mean 37.5 dB, against 38.5 for `bilinear` 12×12.
/// A pull of 100 (values all but taken at the nodes) was tried on item1 only, with
/// mixed results across its lights; it was not measured on the three items.
const RBF_PULL: f64 = 0.3;

/// Directions the `rbf` node values are fitted over, per node.
const RBF_FIT_DIRECTIONS_PER_NODE: usize = 24;

/// `rbf`: `count` nodes spread over the upper hemisphere (where the viewer's lights
/// are), blended by OpenLIME's normalised Gaussians; each node's value the least-squares
/// one that makes the blend follow the function (see [`RBF_PULL`]).
fn rbf_nodes(basis: &dyn crate::basis::Basis, count: usize) -> Result<NodeTable> {
    if !(4..=MAX_RBF_LIGHTS).contains(&count) {
        return Err(Error::invalid(format!(
            "an rbf web folder has 4 to {MAX_RBF_LIGHTS} nodes, not {count}"
        )));
    }
    // The lights as the file will hold them (JSON keeps an f64 exactly), so the blend
    // fitted here is the one the viewer computes.
    let centres = crate::sphere::hemisphere_fibonacci(count);
    let k = basis.len();
    let dirs = crate::sphere::hemisphere_fibonacci(RBF_FIT_DIRECTIONS_PER_NODE * count);
    // Normal equations (ΦᵀΦ + μI) V = ΦᵀB + μ B_nodes, for V = to_nodes.
    let mut gram = vec![0.0; count * count];
    let mut rhs = vec![0.0; count * k];
    let (mut phi, mut b) = (Vec::with_capacity(count), vec![0.0; k]);
    for &d in &dirs {
        crate::basis::relight_kernels(&centres, d, RBF_ALPHA, RBF_BETA, &mut phi);
        basis.eval(d, &mut b);
        let w = d.z * d.z;
        for r in 0..count {
            for c in 0..count {
                gram[r * count + c] += w * phi[r] * phi[c];
            }
            for i in 0..k {
                rhs[r * k + i] += w * phi[r] * b[i];
            }
        }
    }
    let mean_diagonal = (0..count).map(|r| gram[r * count + r]).sum::<f64>() / count as f64;
    let pull = RBF_PULL * mean_diagonal;
    for (r, &c) in centres.iter().enumerate() {
        gram[r * count + r] += pull;
        basis.eval(c, &mut b);
        for i in 0..k {
            rhs[r * k + i] += pull * b[i];
        }
    }
    if !crate::linalg::cholesky(&mut gram, count) {
        return Err(Error::new(
            ErrorKind::Numerical,
            "the rbf nodes' blending matrix is not positive definite",
        ));
    }
    let mut to_nodes = vec![0.0; count * k];
    let mut column = vec![0.0; count];
    for i in 0..k {
        (0..count).for_each(|r| column[r] = rhs[r * k + i]);
        crate::linalg::cholesky_solve(&gram, count, &mut column);
        (0..count).for_each(|r| to_nodes[r * k + i] = column[r]);
    }
    let mut fields = serde_json::Map::new();
    fields.insert(
        "lights".into(),
        centres
            .iter()
            .flat_map(|c| [c.x, c.y, c.z])
            .collect::<Vec<_>>()
            .into(),
    );
    Ok(NodeTable {
        kind: "rbf",
        nodes: count,
        to_nodes,
        fields,
    })
}

/// relight's luma/chroma of an RGB triple, the inverse of OpenLIME's `toRgb`
/// (`R = Y + C1/2 − C2/2`, `G = Y + C2/2`, `B = Y − C1/2 − C2/2`).
const RGB_TO_YCC: [[f64; 3]; 3] = [[0.25, 0.5, 0.25], [1.0, 0.0, -1.0], [-0.5, 1.0, -0.5]];

/// Principal components over some of a pixel's node values, and the planes of the
/// file that hold their coordinates.
struct ComponentGroup {
    /// Indices into the `3·nodes` node values (`3·node + channel`).
    dims: Vec<usize>,
    /// The file's plane index of each component, most energetic first.
    planes: Vec<usize>,
}

/// The component groups of `planes` planes: `mrgb` one over all node values; `mycc`
/// one per luma/chroma channel, the first `chroma` plane images (Y, C1, C2) triples and
/// the rest three luma planes each (relight's layout).
fn component_groups(nodes: usize, planes: usize, chroma: Option<usize>) -> Vec<ComponentGroup> {
    let Some(nc) = chroma else {
        return vec![ComponentGroup {
            dims: (0..3 * nodes).collect(),
            planes: (0..planes).collect(),
        }];
    };
    (0..3)
        .map(|s| ComponentGroup {
            dims: (0..nodes).map(|n| 3 * n + s).collect(),
            planes: (0..nc)
                .map(|q| 3 * q + s)
                .chain((3 * nc..planes).filter(|_| s == 0))
                .collect(),
        })
        .collect()
}

/// Any basis as `bilinear` or `rbf` + `mrgb` or `mycc` (see the module docs): the
/// pixels' functions at the nodes (sRGB-encoded), their principal components, the
/// planes along them.
fn pca_planes(
    image: &RelightableImage,
    table: &NodeTable,
    options: &WriteOptions,
) -> Result<(serde_json::Value, Vec<Vec<f32>>)> {
    let nodes = table.nodes;
    let dims = 3 * nodes;
    let planes = options.planes;
    let limit = dims.min(MAX_PLANES);
    if planes == 0 || !planes.is_multiple_of(3) || planes > limit {
        return Err(Error::invalid(format!(
            "the planes of {} files are a positive multiple of 3 up to {limit}, not {planes}",
            table.kind
        )));
    }
    let images = planes / 3;
    let chroma = options.chroma_planes;
    if let Some(nc) = chroma {
        if nc == 0 || nc > images || planes - 2 * nc > nodes {
            return Err(Error::invalid(format!(
                "mycc with {planes} planes keeps 1 to {images} chroma planes per channel, \
                 and at most {nodes} luma planes"
            )));
        }
    }
    let groups = component_groups(nodes, planes, chroma);
    let k = table.to_nodes.len() / nodes;
    let maps = &image.maps;
    let n = maps.pixels();
    let linear = image.meta.color_space == MapSpace::Linear;
    // A channel's value at every node is linear in the coefficients, and so is the luma
    // and chroma of the three: one `3·nodes × 3k` matrix from a pixel's coefficients
    // (`3·i + c`) to its node values.
    let mix: [[f64; 3]; 3] = if chroma.is_some() {
        RGB_TO_YCC
    } else {
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    };
    // A pixel's node values, `3·node + channel` (the basis table's order), sRGB-encoded.
    let node_values = |p: usize, out: &mut [f64]| {
        for node in 0..nodes {
            let row = &table.to_nodes[node * k..(node + 1) * k];
            let mut rgb = [0.0; 3];
            for (c, v) in rgb.iter_mut().enumerate() {
                *v = (0..k)
                    .map(|i| row[i] * maps.data[(3 * i + c) * n + p] as f64)
                    .sum();
                if linear {
                    *v = crate::color::linear_to_srgb(*v as f32) as f64;
                }
            }
            for s in 0..3 {
                out[3 * node + s] = (0..3).map(|c| mix[s][c] * rgb[c]).sum();
            }
        }
    };
    // The components come from at most 65 536 pixels spread over the image; the
    // projection then covers every pixel.
    let step = n.div_ceil(65_536).max(1);
    let sample: Vec<usize> = (0..n).step_by(step).collect();
    let (sum, second) = sample
        .par_iter()
        .fold(
            || (vec![0.0; dims], vec![0.0; dims * dims], vec![0.0; dims]),
            |(mut sum, mut second, mut f), &p| {
                node_values(p, &mut f);
                for a in 0..dims {
                    sum[a] += f[a];
                    for b in a..dims {
                        second[a * dims + b] += f[a] * f[b];
                    }
                }
                (sum, second, f)
            },
        )
        .map(|(s, q, _)| (s, q))
        .reduce(
            || (vec![0.0; dims], vec![0.0; dims * dims]),
            |(mut s1, mut q1), (s2, q2)| {
                s1.iter_mut().zip(&s2).for_each(|(a, b)| *a += b);
                q1.iter_mut().zip(&q2).for_each(|(a, b)| *a += b);
                (s1, q1)
            },
        );
    let count = sample.len() as f64;
    // The mean as the file's bytes hold it (0 to 1: a negative chroma mean cannot be
    // written); the components are taken about that, so whatever the bytes lose of the
    // true mean is one more direction for them to carry.
    let mut table_bytes = vec![127u8; 3 * (planes + 1) * nodes];
    let mut decoded_mean = vec![0.0; dims];
    for d in 0..dims {
        let byte = (sum[d] / count * 255.0).round().clamp(0.0, 255.0);
        table_bytes[d] = byte as u8;
        decoded_mean[d] = byte / 255.0;
    }
    let mut ranges = vec![0.0; planes];
    // Each plane's row over the node values, zero outside its group.
    let mut project = vec![0.0; planes * dims];
    for group in &groups {
        let g = group.dims.len();
        let mut cov = vec![0.0; g * g];
        for (a, &da) in group.dims.iter().enumerate() {
            for (b, &db) in group.dims.iter().enumerate().skip(a) {
                let (lo, hi) = (da.min(db), da.max(db));
                let v = second[lo * dims + hi] / count
                    - sum[da] / count * decoded_mean[db]
                    - decoded_mean[da] * sum[db] / count
                    + decoded_mean[da] * decoded_mean[db];
                cov[a * g + b] = v;
                cov[b * g + a] = v;
            }
        }
        let (_, vectors) = crate::linalg::symmetric_eigen(&cov, g);
        let m = group.planes.len();
        let mut decoded = vec![0.0; m * g];
        for (j, &plane) in group.planes.iter().enumerate() {
            let e = &vectors[j * g..(j + 1) * g];
            let peak = e.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
            let range = 127.0 / peak;
            ranges[plane] = range;
            for (a, &d) in group.dims.iter().enumerate() {
                let byte = (127.0 + e[a] * range).round().clamp(0.0, 255.0);
                table_bytes[(plane + 1) * dims + d] = byte as u8;
                decoded[j * g + a] = (byte - 127.0) / range;
            }
        }
        // Coordinates against the decoded (no longer orthonormal) components: least
        // squares.
        let mut gram = vec![0.0; m * m];
        crate::linalg::matmul_bt(m, g, m, &decoded, &decoded, &mut gram);
        if !crate::linalg::cholesky(&mut gram, m) {
            return Err(Error::new(
                ErrorKind::Numerical,
                "the quantised principal components are degenerate (too many planes for these maps?)",
            ));
        }
        let mut column = vec![0.0; m];
        for (a, &d) in group.dims.iter().enumerate() {
            (0..m).for_each(|j| column[j] = decoded[j * g + a]);
            crate::linalg::cholesky_solve(&gram, m, &mut column);
            for (j, &plane) in group.planes.iter().enumerate() {
                project[plane * dims + d] = column[j];
            }
        }
    }
    let mut pixel_major = vec![0.0f32; n * planes];
    if linear {
        pixel_major
            .par_chunks_mut(planes)
            .enumerate()
            .for_each_init(
                || vec![0.0; dims],
                |f, (p, coords)| {
                    node_values(p, f);
                    for (q, v) in coords.iter_mut().enumerate() {
                        let row = &project[q * dims..(q + 1) * dims];
                        *v = (0..dims)
                            .map(|d| row[d] * (f[d] - decoded_mean[d]))
                            .sum::<f64>() as f32;
                    }
                },
            );
    } else {
        // Display-referred maps are linear all the way to the planes: one `planes × 3k`
        // matrix from a pixel's coefficients to its planes, instead of the nodes.
        let mut fold = vec![0.0; planes * 3 * k];
        let mut offset = vec![0.0; planes];
        for q in 0..planes {
            let row = &project[q * dims..(q + 1) * dims];
            offset[q] = -(0..dims).map(|d| row[d] * decoded_mean[d]).sum::<f64>();
            for node in 0..nodes {
                let weights = &table.to_nodes[node * k..(node + 1) * k];
                for s in 0..3 {
                    let r = row[3 * node + s];
                    if r == 0.0 {
                        continue;
                    }
                    for c in 0..3 {
                        let rc = r * mix[s][c];
                        for (i, w) in weights.iter().enumerate() {
                            fold[(q * 3 + c) * k + i] += rc * w;
                        }
                    }
                }
            }
        }
        pixel_major
            .par_chunks_mut(planes)
            .enumerate()
            .for_each(|(p, coords)| {
                for (q, v) in coords.iter_mut().enumerate() {
                    let mut sum = offset[q];
                    for c in 0..3 {
                        let row = &fold[(q * 3 + c) * k..(q * 3 + c + 1) * k];
                        for (i, m) in row.iter().enumerate() {
                            sum += m * maps.data[(3 * i + c) * n + p] as f64;
                        }
                    }
                    *v = sum as f32;
                }
            });
    }
    let out: Vec<Vec<f32>> = (0..planes)
        .into_par_iter()
        .map(|q| {
            pixel_major
                .iter()
                .skip(q)
                .step_by(planes)
                .copied()
                .collect()
        })
        .collect();
    let mut info = serde_json::json!({
        "type": table.kind,
        "colorspace": if chroma.is_some() { "mycc" } else { "mrgb" },
        "materials": [{ "range": ranges }],
        "basis": table_bytes,
    });
    if let Some(nc) = chroma {
        info["yccplanes"] = serde_json::json!([planes - 2 * nc, nc, nc]);
    }
    for (key, value) in &table.fields {
        info[key] = value.clone();
    }
    Ok((info, out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::{Light, LightRig};
    use crate::sphere::Vec3;

    /// The π OpenLIME's shader code writes: the formulas below are its, not the maths'.
    #[allow(clippy::approx_constant)]
    const OPENLIME_PI: f64 = 3.1415;

    /// OpenLIME 1.2.6's hemispherical harmonics (`rti` shader's light weights), written
    /// out from its formulas: θ from +z clamped to π/2 − 0.15, φ = atan2(y, x), π taken
    /// as 3.1415.
    fn openlime_hsh(d: Vec3) -> [f64; 9] {
        let pi = OPENLIME_PI;
        let mut phi = d.y.atan2(d.x);
        if phi < 0.0 {
            phi += 2.0 * pi;
        }
        let theta = d.z.acos().min(pi / 2.0 - 0.15);
        let (r, cp, sp) = (theta.cos(), phi.cos(), phi.sin());
        let s = (r - r * r).sqrt();
        [
            1.0 / (2.0 * pi).sqrt(),
            (6.0 / pi).sqrt() * cp * s,
            (3.0 / (2.0 * pi)).sqrt() * (2.0 * r - 1.0),
            (6.0 / pi).sqrt() * s * sp,
            (30.0 / pi).sqrt() * (2.0 * phi).cos() * (r * r - r),
            (30.0 / pi).sqrt() * cp * (2.0 * r - 1.0) * s,
            (5.0 / (2.0 * pi)).sqrt() * (1.0 - 6.0 * r + 6.0 * r * r),
            (30.0 / pi).sqrt() * (2.0 * r - 1.0) * s * sp,
            (30.0 / pi).sqrt() * (r * r - r) * (2.0 * phi).sin(),
        ]
    }

    /// OpenLIME's `sh` light weights, from its formulas.
    fn openlime_sh(d: Vec3) -> [f64; 9] {
        let pi = OPENLIME_PI;
        let (a, b) = (0.5 * (3.0 / pi).sqrt(), 0.5 * (15.0 / pi).sqrt());
        [
            0.5 / pi.sqrt(),
            a * d.x,
            a * d.z,
            a * d.y,
            b * d.x * d.y,
            b * d.x * d.z,
            0.5 * (5.0 / pi).sqrt() * (3.0 * d.z * d.z - 1.0),
            b * d.y * d.z,
            0.5 * b * (d.y * d.y - d.x * d.x),
        ]
    }

    fn openlime_ptm(d: Vec3) -> [f64; 6] {
        [1.0, d.x, d.y, d.x * d.x, d.x * d.y, d.y * d.y]
    }

    /// OpenLIME takes π as 3.1415 (a relative 3·10⁻⁵ in the constants) and wraps a
    /// negative φ by 2·3.1415, turning the lower half 1.9·10⁻⁴ rad: the `m ≠ 0`
    /// functions of `hsh` move by up to about 6·10⁻⁴ there.
    const PI_TOLERANCE: f64 = 1e-3;

    fn check_table(kind: &str, planes: usize, openlime: impl Fn(Vec3) -> Vec<f64>) {
        let table = fixed_functions(kind, planes, false).unwrap();
        let basis = BasisSpec::named(&table.name).unwrap().build().unwrap();
        // Above OpenLIME's elevation clamp (0.15 rad), where the two must agree.
        let dirs: Vec<Vec3> = crate::sphere::hemisphere_fibonacci(200)
            .into_iter()
            .filter(|d| d.z > 0.16)
            .collect();
        assert!(dirs.len() > 150);
        for d in dirs {
            let ours = basis.values(d);
            for (j, (&(index, factor), theirs)) in
                table.functions.iter().zip(openlime(d)).enumerate()
            {
                let got = factor as f64 * ours[index];
                assert!(
                    (got - theirs).abs() < PI_TOLERANCE,
                    "{kind} function {j} at {d:?}: relit {got}, OpenLIME {theirs}"
                );
            }
        }
    }

    #[test]
    fn the_file_order_of_each_fixed_family_is_openlimes() {
        check_table("hsh", 27, |d| openlime_hsh(d).to_vec());
        check_table("hsh", 12, |d| openlime_hsh(d)[..4].to_vec());
        check_table("sh", 27, |d| openlime_sh(d).to_vec());
        check_table("ptm", 18, |d| openlime_ptm(d).to_vec());
    }

    fn fitted(basis: &str, space: MapSpace) -> RelightableImage {
        let plane = crate::synth::BumpyPlane {
            width: 40,
            height: 28,
        };
        let dirs = crate::sphere::hemisphere_fibonacci(30);
        let options = crate::fit::FitOptions {
            basis: crate::fit::BasisRequest::parse(basis).unwrap(),
            color_space: Some(space),
            lambda: crate::fit::Lambda::Fixed(1e-3),
            // The codec's figures below are of the plain least-squares maps; the
            // automatic objective's choice on this capture is a close call (its
            // leave-one-out display errors differ by 4 %) that these tests do not judge.
            objective: crate::fit::Objective::Linear,
            ..Default::default()
        };
        crate::fit::fit(&plane.capture(&dirs), &options, &crate::progress::Silent)
            .unwrap()
            .image
    }

    fn relit(image: &RelightableImage, d: Vec3) -> Vec<f32> {
        let rig = LightRig::new(vec![Light::directional(d, [1.0; 3])]);
        crate::engine::relight(image, &rig, &Default::default())
            .unwrap()
            .data
    }

    /// The worst 8-bit sRGB PSNR of `b` against `a` over lights across the dome.
    fn worst_psnr(a: &RelightableImage, b: &RelightableImage) -> f64 {
        [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.5, 0.2, 0.84),
            Vec3::new(-0.6, 0.4, 0.69),
            Vec3::new(0.1, -0.8, 0.59),
            Vec3::new(-0.3, -0.3, 0.9),
        ]
        .into_iter()
        .map(|d| {
            let d = d.normalized().unwrap();
            crate::metrics::psnr_srgb8(&relit(b, d), &relit(a, d))
        })
        .fold(f64::INFINITY, f64::min)
    }

    /// Write, read back, relight both. Direct types lose only the 8-bit codes (a plane's
    /// range in 255 steps) and JPEG at quality 100; `bilinear` also the grid between
    /// its nodes and 18 components. Measured (worst of five lights): ptm 48.7 dB,
    /// hsh 49.7 dB, sh:9 linear as bilinear 39.5 dB (the 12×12 grid's interpolation; 33.6
    /// dB at relight's 8×8); an octahedral bilinear:9 of 7 nodes a side on its own grid
    /// 41.7 dB (only the components and JPEG), regridded to 12 nodes 37.6 dB.
    #[test]
    fn what_is_written_reads_back() {
        let options = WriteOptions {
            quality: 100,
            ..Default::default()
        };
        for (basis, space, kind, floor) in [
            ("ptm:6", MapSpace::Srgb, "ptm", 45.0),
            ("hsh:9", MapSpace::Srgb, "hsh", 46.0),
            ("sh:9", MapSpace::Linear, "bilinear", 36.0),
            ("bilinear:9:grid=7", MapSpace::Srgb, "bilinear", 39.0),
        ] {
            let image = fitted(basis, space);
            let dir = tempfile::tempdir().unwrap();
            let folder = dir.path().join("web");
            let summary = write(&folder, &image, &options).unwrap();
            assert_eq!(summary.kind, kind);
            assert!(super::super::FileForm::of(&folder).unwrap() == super::super::FileForm::Web);
            let back = super::super::read(&folder).unwrap();
            assert_eq!(back.meta.color_space, MapSpace::Srgb);
            let psnr = worst_psnr(&image, &back);
            eprintln!("{basis} as {kind}: {psnr:.1} dB");
            assert!(psnr > floor, "{basis} as {kind}: {psnr:.1} dB");
            if basis.starts_with("bilinear") {
                // A bilinear basis keeps its own grid; anything else gets 12 nodes.
                let info: serde_json::Value =
                    serde_json::from_slice(&std::fs::read(folder.join("info.json")).unwrap())
                        .unwrap();
                assert_eq!(info["resolution"], 7);
                let regridded = dir.path().join("regridded");
                let twelve = WriteOptions {
                    resolution: Some(12),
                    ..options.clone()
                };
                write(&regridded, &image, &twelve).unwrap();
                let other = worst_psnr(&image, &super::super::read(&regridded).unwrap());
                eprintln!("{basis} on a 12-node grid: {other:.1} dB");
                assert!(
                    psnr > other + 1.0,
                    "own grid {psnr:.1}, 12 nodes {other:.1}"
                );
            }
        }
    }

    /// The principal-component types and colour spaces, written and read back: `rbf` at
    /// its blended nodes, `mycc` as every plane image a triple and in relight's layout
    /// of fewer chroma planes. Measured (worst of five lights, sh:9 linear, 18 planes):
    /// bilinear mycc 36.3 dB (six components a channel, against mrgb's 18 shared: 39.5),
    /// rbf mrgb 34.4 dB (OpenLIME's wide blend), rbf mycc 33.6 dB, with 2 chroma planes
    /// of 6 images 32.5 dB.
    #[test]
    fn rbf_and_mycc_read_back() {
        let image = fitted("sh:9", MapSpace::Linear);
        for (functions, chroma, kind, space, yccplanes, floor) in [
            (
                WebFunctions::Bilinear,
                Some(6),
                "bilinear",
                "mycc",
                Some([6, 6, 6]),
                34.0,
            ),
            (WebFunctions::Rbf, None, "rbf", "mrgb", None, 31.0),
            (
                WebFunctions::Rbf,
                Some(6),
                "rbf",
                "mycc",
                Some([6, 6, 6]),
                30.0,
            ),
            (
                WebFunctions::Rbf,
                Some(2),
                "rbf",
                "mycc",
                Some([14, 2, 2]),
                30.0,
            ),
        ] {
            let options = WriteOptions {
                quality: 100,
                functions,
                chroma_planes: chroma,
                ..Default::default()
            };
            let dir = tempfile::tempdir().unwrap();
            let folder = dir.path().join("web");
            let summary = write(&folder, &image, &options).unwrap();
            assert_eq!(
                (summary.kind.as_str(), summary.colorspace.as_str()),
                (kind, space)
            );
            let info: serde_json::Value =
                serde_json::from_slice(&std::fs::read(folder.join(INFO)).unwrap()).unwrap();
            assert_eq!(
                info.get("yccplanes").cloned(),
                yccplanes.map(|y| serde_json::json!(y))
            );
            if kind == "rbf" {
                assert_eq!(
                    info["lights"].as_array().unwrap().len(),
                    3 * DEFAULT_RBF_NODES
                );
            }
            let psnr = worst_psnr(&image, &read(&folder).unwrap());
            eprintln!("{kind} {space} {yccplanes:?}: {psnr:.1} dB");
            assert!(psnr > floor, "{kind} {space} {yccplanes:?}: {psnr:.1} dB");
        }
        // Layouts that cannot be written are refused by what they ask.
        for (functions, nodes, chroma, planes, needle) in [
            (WebFunctions::Rbf, 2, None, 18, "4 to 400 nodes"),
            (WebFunctions::Rbf, 401, None, 18, "4 to 400 nodes"),
            (WebFunctions::Bilinear, 64, Some(0), 18, "chroma planes"),
            (WebFunctions::Bilinear, 64, Some(7), 18, "chroma planes"),
            (WebFunctions::Rbf, 8, Some(1), 18, "luma planes"),
            (WebFunctions::Rbf, 4, None, 18, "up to 12"),
        ] {
            let options = WriteOptions {
                functions,
                rbf_nodes: nodes,
                chroma_planes: chroma,
                planes,
                ..Default::default()
            };
            let dir = tempfile::tempdir().unwrap();
            let err = write(&dir.path().join("web"), &image, &options).unwrap_err();
            assert!(err.to_string().contains(needle), "{err}");
            assert!(!dir.path().join("web").exists());
        }
    }

    /// A folder written then broken one way at a time: each read fails with a message
    /// naming the file and the field, and nothing panics.
    #[test]
    fn malformed_folders_are_refused_by_name() {
        let image = fitted("ptm:6", MapSpace::Srgb);
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("good");
        write(&good, &image, &WriteOptions::default()).unwrap();
        let info: serde_json::Value =
            serde_json::from_slice(&std::fs::read(good.join(INFO)).unwrap()).unwrap();
        let broken =
            |name: &str, edit: &dyn Fn(&mut serde_json::Value, &Path), needles: &[&str]| {
                let folder = dir.path().join(name);
                std::fs::create_dir_all(&folder).unwrap();
                for entry in std::fs::read_dir(&good).unwrap() {
                    let entry = entry.unwrap();
                    std::fs::copy(entry.path(), folder.join(entry.file_name())).unwrap();
                }
                let mut v = info.clone();
                edit(&mut v, &folder);
                std::fs::write(folder.join(INFO), serde_json::to_vec(&v).unwrap()).unwrap();
                let err = read(&folder).expect_err(name).to_string();
                for needle in needles {
                    assert!(err.contains(needle), "{name}: `{err}` lacks `{needle}`");
                }
            };
        broken(
            "no-planes",
            &|v, _| {
                v.as_object_mut().unwrap().remove("nplanes");
            },
            &["info.json", "nplanes"],
        );
        broken(
            "short-scale",
            &|v, _| {
                v["materials"][0]["scale"].as_array_mut().unwrap().pop();
            },
            &["info.json", "materials[0].scale"],
        );
        broken(
            "huge",
            &|v, _| {
                v["width"] = 1_000_000.into();
            },
            &["plane_0.jpg", "1000000"],
        );
        broken(
            "unknown-type",
            &|v, _| {
                v["type"] = "nope".into();
            },
            &["info.json", "nope"],
        );
        broken(
            "missing-plane",
            &|_, f| {
                std::fs::remove_file(f.join("plane_3.jpg")).unwrap();
            },
            &["plane_3.jpg"],
        );
        broken(
            "bad-basis",
            &|v, _| {
                v["type"] = "bilinear".into();
                v["colorspace"] = "mrgb".into();
                v["resolution"] = 8.into();
                v["basis"] = vec![0; 10].into();
                v["materials"][0]["range"] = vec![1.0; 18].into();
            },
            &["info.json", "basis", "10"],
        );
        broken(
            "tarzoom-past-the-end",
            &|_, f| {
                let index = serde_json::json!({
                    "tilesize": 256, "overlap": 0, "width": 40, "height": 28,
                    "offsets": [0, 1_000_000_000u64],
                });
                for j in 0..6 {
                    std::fs::write(f.join(format!("plane_{j}.tzi")), index.to_string()).unwrap();
                    std::fs::write(f.join(format!("plane_{j}.tzb")), b"tiny").unwrap();
                }
            },
            &["plane_0.tzi", "offsets", "1000000000"],
        );
        broken(
            "tarzoom-too-few-tiles",
            &|_, f| {
                let index = serde_json::json!({
                    "tilesize": 16, "overlap": 0, "width": 40, "height": 28,
                    "offsets": [0, 4],
                });
                for j in 0..6 {
                    std::fs::write(f.join(format!("plane_{j}.tzi")), index.to_string()).unwrap();
                    std::fs::write(f.join(format!("plane_{j}.tzb")), b"tiny").unwrap();
                }
            },
            &["plane_0.tzi", "offsets"],
        );
    }

    /// A tiny principal-component folder with random codes in lossless PNG planes.
    struct PcaFolder {
        kind: &'static str,
        ycc: Option<[usize; 3]>,
        nodes: usize,
        lights: Vec<Vec3>,
        resolution: usize,
        planes: usize,
        basis: Vec<u8>,
        codes: Vec<Vec<u8>>,
        scale: Vec<f64>,
        bias: Vec<f64>,
        range: Vec<f64>,
    }

    const W: usize = 7;
    const H: usize = 5;

    fn random_bytes(seed: u64, n: usize, lo: u8, hi: u8) -> Vec<u8> {
        let mut x = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                lo + ((x >> 33) % (hi - lo) as u64 + 1) as u8 - 1
            })
            .collect()
    }

    impl PcaFolder {
        fn new(kind: &'static str, ycc: Option<[usize; 3]>, planes: usize) -> PcaFolder {
            let (nodes, resolution, lights) = if kind == "rbf" {
                let lights: Vec<Vec3> = crate::sphere::hemisphere_fibonacci(12)
                    .into_iter()
                    .map(|d| {
                        Vec3::new(
                            (d.x * 1e3).round() / 1e3,
                            (d.y * 1e3).round() / 1e3,
                            (d.z * 1e3).round() / 1e3,
                        )
                    })
                    .collect();
                (12, 0, lights)
            } else {
                (16, 4, Vec::new())
            };
            let mut basis = random_bytes(1, 3 * (planes + 1) * nodes, 0, 255);
            // The mean: a mid grey, so that sums stay mostly within [0, 1].
            basis[..3 * nodes].iter_mut().for_each(|b| *b = 90 + *b / 4);
            if let Some([_, nc, _]) = ycc {
                // A Y-only plane's chroma entries hold the zero code, as relight writes.
                for p in 0..planes {
                    let s = if p / 3 < nc { p % 3 } else { 0 };
                    for node in 0..nodes {
                        for c in (0..3).filter(|&c| c != s) {
                            basis[3 * ((p + 1) * nodes + node) + c] = 127;
                        }
                    }
                }
            }
            PcaFolder {
                kind,
                ycc,
                nodes,
                lights,
                resolution,
                planes,
                basis,
                codes: (0..planes / 3)
                    .map(|j| random_bytes(10 + j as u64, 3 * W * H, 0, 255))
                    .collect(),
                scale: (0..planes).map(|p| 0.3 + 0.05 * p as f64).collect(),
                bias: (0..planes).map(|p| 0.5 - 0.02 * p as f64).collect(),
                range: (0..planes).map(|p| 300.0 + 40.0 * p as f64).collect(),
            }
        }

        fn write(&self, folder: &Path) {
            std::fs::create_dir_all(folder).unwrap();
            let mut info = serde_json::json!({
                "width": W, "height": H, "format": "png", "type": self.kind,
                "colorspace": if self.ycc.is_some() { "mycc" } else { "mrgb" },
                "materials": [{"scale": self.scale, "bias": self.bias, "range": self.range}],
                "basis": self.basis,
            });
            match self.ycc {
                Some(y) => info["yccplanes"] = y.to_vec().into(),
                None => info["nplanes"] = self.planes.into(),
            }
            if self.kind == "rbf" {
                info["lights"] = self
                    .lights
                    .iter()
                    .flat_map(|l| [l.x, l.y, l.z])
                    .collect::<Vec<_>>()
                    .into();
            } else {
                info["resolution"] = self.resolution.into();
            }
            std::fs::write(folder.join(INFO), info.to_string()).unwrap();
            for (j, codes) in self.codes.iter().enumerate() {
                image::RgbImage::from_raw(W as u32, H as u32, codes.clone())
                    .unwrap()
                    .save(folder.join(format!("plane_{j}.png")))
                    .unwrap();
            }
        }

        /// OpenLIME's light weights over the nodes, from its formulas.
        fn weights(&self, l: Vec3) -> Vec<f64> {
            let mut w = vec![0.0; self.nodes];
            if self.kind == "rbf" {
                let d: Vec<f64> = self.lights.iter().map(|c| (l - *c).length()).collect();
                let (num, den) = d.iter().fold((0.0, 0.0), |(a, b), &d| {
                    (a + d * (-2.0 * d).exp(), b + (-2.0 * d).exp())
                });
                let r = 8.0 / (num / den);
                let total: f64 = d.iter().map(|d| (-r * d * d).exp()).sum();
                for (wi, di) in w.iter_mut().zip(&d) {
                    *wi = (-r * di * di).exp() / total;
                }
            } else {
                let res = self.resolution;
                let s = l.x.abs() + l.y.abs() + l.z.abs();
                let n = ((l.x + l.y) / s + 1.0) / 2.0 * (res - 1) as f64;
                let r = ((l.y - l.x) / s + 1.0) / 2.0 * (res - 1) as f64;
                let o = (n.floor().max(0.0) as usize).min(res - 2);
                let a = (r.floor().max(0.0) as usize).min(res - 2);
                let (fx, fy) = (n - o as f64, r - a as f64);
                w[o + a * res] += (1.0 - fx) * (1.0 - fy);
                w[o + 1 + a * res] += fx * (1.0 - fy);
                w[o + (a + 1) * res] += (1.0 - fx) * fy;
                w[o + 1 + (a + 1) * res] += fx * fy;
            }
            w
        }

        /// The colour the file means at pixel `i` under light `l` (sRGB-encoded).
        fn colour(&self, i: usize, l: Vec3) -> [f64; 3] {
            let w = self.weights(l);
            let base = |t: usize, s: usize| -> f64 {
                (0..self.nodes)
                    .map(|node| {
                        let b = self.basis[3 * (t * self.nodes + node) + s] as f64;
                        w[node]
                            * if t == 0 {
                                b / 255.0
                            } else {
                                (b - 127.0) / self.range[t - 1]
                            }
                    })
                    .sum()
            };
            let mut v = [base(0, 0), base(0, 1), base(0, 2)];
            for p in 0..self.planes {
                let r = (self.codes[p / 3][3 * i + p % 3] as f64 / 255.0 - self.bias[p])
                    * self.scale[p];
                match self.ycc {
                    Some([_, nc, _]) => {
                        let s = if p / 3 < nc { p % 3 } else { 0 };
                        v[s] += base(p + 1, s) * r;
                    }
                    None => (0..3).for_each(|s| v[s] += base(p + 1, s) * r),
                }
            }
            if self.ycc.is_some() {
                let [y, c1, c2] = v;
                v = [
                    y + c1 / 2.0 - c2 / 2.0,
                    y + c2 / 2.0,
                    y - c1 / 2.0 - c2 / 2.0,
                ];
            }
            v
        }
    }

    /// bilinear and rbf in mrgb and mycc, read by relit, relit at lights across the
    /// dome, against the file's formulas (OpenLIME's, with mycc's Y-only images as relight
    /// writes them): within a fraction of an 8-bit code (the reader keeps node-space
    /// components down to a quarter code of dropped energy).
    #[test]
    fn principal_component_files_relight_as_their_formulas_say() {
        let dir = tempfile::tempdir().unwrap();
        for (name, folder) in [
            ("bilinear mrgb", PcaFolder::new("bilinear", None, 6)),
            (
                "bilinear mycc",
                PcaFolder::new("bilinear", Some([4, 1, 1]), 6),
            ),
            ("rbf mrgb", PcaFolder::new("rbf", None, 9)),
            ("rbf mycc", PcaFolder::new("rbf", Some([7, 1, 1]), 9)),
        ] {
            let path = dir.path().join(name.replace(' ', "-"));
            folder.write(&path);
            let image = read(&path).unwrap();
            let mut worst = 0.0f64;
            for l in [
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(0.5, 0.2, 0.84),
                Vec3::new(-0.6, 0.4, 0.69),
                Vec3::new(0.1, -0.8, 0.59),
                Vec3::new(-0.7, -0.6, 0.39),
            ] {
                let l = l.normalized().unwrap();
                let ours = relit(&image, l);
                for i in 0..W * H {
                    let want = folder.colour(i, l);
                    for c in 0..3 {
                        let got = crate::color::linear_to_srgb(ours[3 * i + c]) as f64;
                        worst = worst.max((got - want[c].clamp(0.0, 1.0)).abs());
                    }
                }
            }
            eprintln!("{name}: worst {:.2} codes", worst * 255.0);
            assert!(
                worst < 0.5 / 255.0,
                "{name}: {:.2} codes off",
                worst * 255.0
            );
        }
    }

    /// `ptm` + `lrgb`: image 0 the colour, images 1 and 2 the six luminance coefficients;
    /// OpenLIME shows `colour · Σ_j lum_j · (1, x, y, x², xy, y²)_j`.
    #[test]
    fn lrgb_is_a_colour_times_a_luminance_polynomial() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("lrgb");
        std::fs::create_dir_all(&folder).unwrap();
        let codes: Vec<Vec<u8>> = (0..3)
            .map(|j| random_bytes(20 + j, 3 * W * H, 0, 255))
            .collect();
        let scale: Vec<f64> = (0..9).map(|p| 0.5 + 0.1 * p as f64).collect();
        let bias: Vec<f64> = (0..9).map(|p| 0.3 + 0.02 * p as f64).collect();
        let info = serde_json::json!({
            "width": W, "height": H, "format": "png", "type": "ptm", "colorspace": "lrgb",
            "nplanes": 9, "materials": [{"scale": scale, "bias": bias}],
        });
        std::fs::write(folder.join(INFO), info.to_string()).unwrap();
        for (j, c) in codes.iter().enumerate() {
            image::RgbImage::from_raw(W as u32, H as u32, c.clone())
                .unwrap()
                .save(folder.join(format!("plane_{j}.png")))
                .unwrap();
        }
        let image = read(&folder).unwrap();
        assert_eq!(image.meta.basis.family, "ptm");
        let value =
            |p: usize, i: usize| (codes[p / 3][3 * i + p % 3] as f64 / 255.0 - bias[p]) * scale[p];
        let l = Vec3::new(0.3, -0.2, 0.93).normalized().unwrap();
        let ours = relit(&image, l);
        let mut worst = 0.0f64;
        for i in 0..W * H {
            let lum: f64 = openlime_ptm(l)
                .iter()
                .enumerate()
                .map(|(j, w)| w * value(3 + j, i))
                .sum();
            for c in 0..3 {
                let want = (lum * value(c, i)).clamp(0.0, 1.0);
                let got = crate::color::linear_to_srgb(ours[3 * i + c]) as f64;
                worst = worst.max((got - want).abs());
            }
        }
        assert!(worst < 0.5 / 255.0, "{:.2} codes off", worst * 255.0);
    }

    /// Deep Zoom: a 600×300 image (three levels, 3×2 full-resolution tiles with partial
    /// ones at the edges) reads back as the single-image layout does. Measured: the same
    /// PSNR (51.0 dB both: smooth maps, 8-bit codes and JPEG at quality 100).
    /// Display-referred ptm:6 maps, as RTI tools write them.
    fn display_ptm(maps: CoefficientMaps) -> RelightableImage {
        RelightableImage {
            meta: Metadata::new(
                BasisSpec::named("ptm:6").unwrap(),
                MapSpace::Srgb,
                Projection::default(),
            ),
            maps,
            depth: None,
        }
    }

    #[test]
    fn lrgb_writing_keeps_a_colour_times_a_luminance_exactly() {
        let (w, h) = (64, 48);
        let mut maps = CoefficientMaps::zeros(w, h, 6);
        for p in 0..w * h {
            let (x, y) = ((p % w) as f32 / w as f32, (p / w) as f32 / h as f32);
            let colour = [0.9 - 0.5 * x, 0.4 + 0.3 * y, 0.2 + 0.6 * x * y];
            for i in 0..6 {
                let lum = 0.3 * ((3.0 * x + i as f32).sin() + 0.2 * i as f32 * y);
                for (c, tint) in colour.iter().enumerate() {
                    maps.plane_mut(i, c)[p] = tint * lum;
                }
            }
        }
        let image = display_ptm(maps);
        let dir = tempfile::tempdir().unwrap();
        let options = WriteOptions {
            quality: 100,
            lrgb: true,
            ..Default::default()
        };
        let summary = write(&dir.path().join("lrgb"), &image, &options).unwrap();
        assert_eq!((summary.colorspace.as_str(), summary.planes), ("lrgb", 9));
        let psnr = worst_psnr(&image, &read(&dir.path().join("lrgb")).unwrap());
        assert!(psnr > 40.0, "{psnr:.2} dB");
    }

    #[test]
    fn deep_zoom_tiles_read_back_like_single_images() {
        let (w, h) = (600, 300);
        let mut maps = CoefficientMaps::zeros(w, h, 6);
        for (p, plane) in maps.data.chunks_mut(w * h).enumerate() {
            for (i, v) in plane.iter_mut().enumerate() {
                let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
                *v = 0.3 * (6.0 * x + p as f32).sin() * (4.0 * y).cos()
                    + if p >= 15 { 0.4 } else { 0.0 };
            }
        }
        let image = display_ptm(maps);
        let dir = tempfile::tempdir().unwrap();
        let mut options = WriteOptions {
            quality: 100,
            ..Default::default()
        };
        write(&dir.path().join("single"), &image, &options).unwrap();
        options.layout = Layout::DeepZoom;
        let summary = write(&dir.path().join("tiled"), &image, &options).unwrap();
        // 6 images × (1 + 2 + 6 tiles + the .dzi) + info.json.
        assert_eq!(summary.files, 6 * 10 + 1);
        assert!(dir.path().join("tiled/plane_5_files/2/2_1.jpg").is_file());
        let single = worst_psnr(&image, &read(&dir.path().join("single")).unwrap());
        let tiled = worst_psnr(&image, &read(&dir.path().join("tiled")).unwrap());
        eprintln!("single {single:.2} dB, tiled {tiled:.2} dB");
        assert!(
            tiled > 45.0 && (tiled - single).abs() < 0.5,
            "single {single:.2} dB, tiled {tiled:.2} dB"
        );
        // The same tiles in tarzoom files (one per plane image, and one for all).
        let deep = read(&dir.path().join("tiled")).unwrap();
        for (layout, files, offsets) in [
            (Layout::Tarzoom, 6 * 2 + 1, 9 + 1),
            (Layout::Itarzoom, 3, 9 * 6 + 1),
        ] {
            options.layout = layout;
            let folder = dir.path().join(layout.name());
            let summary = write(&folder, &image, &options).unwrap();
            assert_eq!(summary.files, files, "{layout:?}");
            let index = if layout == Layout::Tarzoom {
                "plane_5.tzi"
            } else {
                "planes.tzi"
            };
            let index: serde_json::Value =
                serde_json::from_slice(&std::fs::read(folder.join(index)).unwrap()).unwrap();
            assert_eq!(
                index["offsets"].as_array().unwrap().len(),
                offsets,
                "{layout:?}"
            );
            assert_eq!(index["nlevels"], 3);
            assert_eq!(read(&folder).unwrap().maps, deep.maps, "{layout:?}");
        }
    }
}
