//! What the browser loads: `info.json` plus coefficient layers, the basis' weight
//! table, depth and environments.
//!
//! Layers are *channel-major*: with `n = ⌈k/4⌉` layers per colour channel, layer
//! `c·n + j` holds coefficients `4j … 4j+3` of channel `c` in its R, G, B, A components
//! (components past `k` are zero). So the shader relights a channel with `n` dot
//! products of a texel and a weight `vec4`.
//!
//! Every layer component holds a stored number `q` whose value is
//! `offset + scale · q`, with the component's own `scale` and `offset` in `info.json`:
//! the planes in a [`Precision`] with their [`PlaneCoding`]s, encoded by
//! `relit::storage` as the CPU and GPU engines' planes are (`info.json`'s `storage`
//! names the precision):
//!
//! * `u8`: each layer is an RGBA 8-bit PNG; `q` is the byte, 0–255, `offset` the
//!   plane's least finite value and `scale` one step of its range in 255 steps.
//! * `f16`: each layer is `width × height × 4` little-endian IEEE half floats, row-major
//!   from the top-left pixel, RGBA interleaved; `q` is the value (`scale` 1, `offset` 0).
//!
//! The viewer knows no basis. `info.json` names it (`basis.name`, `basis.spec`) and
//! ships its [`WeightTable`] (`data/weights.f16`: the `(N+1)²·k` values of
//! `WeightTable::values`, vertex-major, as little-endian half floats), from which the
//! browser takes the weights of every light: a directional light's in JavaScript, a
//! light with a position's per pixel in the shader, an environment's as a quadrature
//! over its map. Half floats halve the download (a k = 25 SH table: 3.3 MB instead of
//! 6.6) for little error: measured against the basis on 4096 directions, the relative
//! RMS error of SH tables grows from 8.64e-4 to 8.79e-4 (k = 16), 3.48e-4 to 3.82e-4
//! (k = 25) and 8.96e-4 to 9.07e-4 (k = 64), their largest error not at all;
//! `info.json` gives the shipped table's own. Files of SH bases also carry the band
//! windows of environment lights, per coefficient (`basis.windows`).
//!
//! A codebook file (vector quantisation, `relit convert --codebook C`) is shipped as it
//! is stored: its layers hold the `C` entries instead of the pixels, [`CODEBOOK_WIDTH`]
//! entries a row (`info.json` `codebook`: `entries`, `width`, `height`), and
//! `data/indices.u16` holds one little-endian 16-bit entry index a pixel, row-major. The
//! shader fetches each pixel's coefficients through its index (blending four pixels'
//! entries by hand when smoothing) and relights them as any pixel's: every light type
//! works, and the download is 2 bytes a pixel plus the entries.
//!
//! A *tiled* bundle ([`crate::tiles`], `info.json` `tiles`: `side`, the `levels`'
//! sizes, the `overview` level and the tiles' `path`) ships its layers at the size of
//! the overview, a coarse level of the image's mip pyramid, and serves every finer
//! level as tiles of all layers, read from the file as they are asked for.
//!
//! The depth map (when the file has one) is `width × height` little-endian `f32`
//! (`data/depth.f32`, `info.json` `depth` naming its size), 0 where nothing was hit; with
//! the camera in `info.json` the viewer recomputes each pixel's surface point
//! `P = O + d·V` exactly as the CPU engine. A tiled bundle's is the overview's, and each
//! tile carries its own.
//!
//! Environment maps are shipped as the quadrature the library integrates maps of
//! bases other than SH with (`relit::envmap::quadrature`): at most
//! [`QUADRATURE_WIDTH`] × [`QUADRATURE_HEIGHT`] directional lights, each gathering the
//! texels whose centres a coarse texel holds, with their summed intensity `Σ E ΔΩ`
//! (so `∫ E dω` is kept exactly) at their energy's centroid. `data/env/N.f32` holds
//! six little-endian `f32` per light: its unit direction (light frame, unrotated) and
//! its RGB intensity; a small sRGB preview is `data/env/N.png`. The viewer turns the
//! directions and sums `I_t b(R ω_t)` with the weights from the table, for every basis
//! (SH included: it has no SH rotation). For display-referred maps the file holds the
//! quadrature's [`relit::engine::DISPLAY_ENVIRONMENT_LIGHTS`] median-cut lights
//! (`relit::envmap::median_cut`), the lights the CPU engine relights such maps with:
//! there each light is decoded from sRGB on its own, so the viewer passes them to the
//! shader one by one (a float texture) instead of folding them into weights.

use crate::tiles::{TileSource, Tiling, DEFAULT_TILE_SIDE, OVERVIEW_BYTES, WHOLE_BYTES};
use crate::{invalid, Result};
use relit::basis::{Basis, WeightTable};
use relit::camera::CameraSpec;
use relit::engine::lookup::IndexedImage;
use relit::envmap::{EnvironmentLight, Window};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::storage::{PlaneCoding, Precision};
use serde::Serialize;
use serde_json::json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The format version of `info.json` (2: any basis, its weight table, environments as
/// quadratures).
pub const WEB_FORMAT_VERSION: u32 = 2;

/// The most coefficients per channel the viewer relights (its shader holds 16 layers a
/// channel).
pub const MAX_K: usize = 64;

/// The quadrature of an environment map (its texels gathered into at most
/// [`QUADRATURE_WIDTH`] × [`QUADRATURE_HEIGHT`] directional lights, a size chosen by
/// measurement in `relit::envmap::quadrature`): the library's, which the CPU engine
/// lights bases other than SH with.
pub use relit::envmap::{environment_quadrature, QUADRATURE_HEIGHT, QUADRATURE_WIDTH};

/// Largest side the viewer accepts (WebGL2 guarantees textures of 2048 and most
/// implementations, SwiftShader included, give 8192 or more).
pub const MAX_SIDE: usize = 16384;

/// The precisions the viewer reads (WebGL2 textures of half floats or bytes).
pub const PRECISIONS: [Precision; 2] = [Precision::F16, Precision::U8];

/// The file extension of a layer in `precision`.
fn extension(precision: Precision) -> &'static str {
    match precision {
        Precision::U8 => "png",
        _ => "f16",
    }
}

/// Options of a bundle.
#[derive(Clone, Debug)]
pub struct BundleOptions {
    /// The precision of the coefficient layers: f16 (the default) or u8.
    pub precision: Precision,
    /// Lat-long environment maps shipped with the bundle; the rig JSON names each by its
    /// file name.
    pub environments: Vec<PathBuf>,
    /// A name for the source shown by the viewer (usually the EXR's file name).
    pub source_name: String,
    /// Whole layers or tiles ([`crate::tiles`]).
    pub tiling: Tiling,
    /// A tiled bundle's overview: the finest level whose layers take at most this.
    pub overview_bytes: usize,
}

impl Default for BundleOptions {
    fn default() -> Self {
        BundleOptions {
            precision: Precision::F16,
            environments: Vec::new(),
            source_name: String::new(),
            tiling: Tiling::Auto,
            overview_bytes: OVERVIEW_BYTES,
        }
    }
}

/// One environment map as the bundle ships it.
#[derive(Clone, Debug, Serialize)]
pub struct EnvironmentInfo {
    /// The name a rig's `map` field uses (the file name).
    pub map: String,
    /// The size of the map as loaded.
    pub width: usize,
    pub height: usize,
    /// Its quadrature (`data/env/N.f32`, module docs) and the number of its lights.
    pub file: String,
    pub lights: usize,
    /// A small sRGB preview (`data/env/N.png`).
    pub preview: String,
}

/// An environment's files: its entry in `info.json`, its quadrature and preview bytes.
struct Environment {
    info: EnvironmentInfo,
    quadrature: Vec<u8>,
    preview: Vec<u8>,
}

/// The files of a web bundle, by path relative to the site root (`data/...`), and for a
/// tiled bundle the source of its tiles, read as they are asked for.
#[derive(Clone, Debug)]
pub struct WebBundle {
    pub files: BTreeMap<String, Vec<u8>>,
    pub tiles: Option<Arc<TileSource>>,
}

impl WebBundle {
    /// Build every data file of the relightable file at `path`: a codebook `.rlz` as its
    /// entries and indices ([`WebBundle::build_indexed`]), anything else as planes.
    pub fn read(path: &Path, options: &BundleOptions) -> Result<WebBundle> {
        use relit::codec::{packed, FileForm};
        let form = FileForm::of(path)?;
        if let Some(side) = tile_side(path, form, options)? {
            return Self::read_tiled(path, side, options);
        }
        if form == FileForm::Compressed {
            let file = packed::read_packed(path)?;
            if file.header.indexed_pixels() {
                return Self::build_indexed(&relit::compress::indexed(&file)?, options);
            }
        }
        Self::build(&relit::codec::read(path)?, options)
    }

    /// The tile side a bundle of `path` takes under `options` (its `tiling`), or `None`
    /// for whole layers.
    pub fn tile_side(path: &Path, options: &BundleOptions) -> Result<Option<usize>> {
        tile_side(path, relit::codec::FileForm::of(path)?, options)
    }

    /// A tiled bundle of the relit EXR or `.rlz` file at `path` ([`crate::tiles`]): its
    /// overview, depth and every other file now, its tiles as they are asked for.
    pub fn read_tiled(path: &Path, side: usize, options: &BundleOptions) -> Result<WebBundle> {
        options
            .precision
            .require(&[Precision::F16], "a tiled bundle")?;
        let opened = TileSource::open(path, side, options.overview_bytes)?;
        let image = &opened.overview;
        let (width, height) = opened.source.sizes()[0];
        let shape = Shape {
            width,
            height,
            meta: &image.meta,
            depth: image.depth.as_deref(),
            depth_size: (image.maps.width, image.maps.height),
        };
        let source = Arc::new(opened.source);
        let mut bundle = Self::assemble(
            &shape,
            &image.maps,
            Planes::Overview(&source),
            image.meta.basis.build()?,
            options,
        )?;
        bundle.tiles = Some(source);
        Ok(bundle)
    }

    /// Build every data file of `image`, in the basis its metadata names.
    pub fn build(image: &RelightableImage, options: &BundleOptions) -> Result<WebBundle> {
        Self::build_in(image, image.meta.basis.build()?, options)
    }

    /// Build every data file of `image` relit in `basis` (maps of a basis no family
    /// rebuilds: tests, experiments).
    pub fn build_in(
        image: &RelightableImage,
        basis: Box<dyn Basis>,
        options: &BundleOptions,
    ) -> Result<WebBundle> {
        let shape = Shape::of(image);
        Self::assemble(&shape, &image.maps, Planes::Image, basis, options)
    }

    /// Build every data file of a codebook image (module docs): the layers hold the
    /// entries, laid out [`CODEBOOK_WIDTH`] to a row, and `data/indices.u16` one entry a
    /// pixel; the viewer fetches each pixel's coefficients through its index.
    pub fn build_indexed(image: &IndexedImage, options: &BundleOptions) -> Result<WebBundle> {
        let entries = &image.entries;
        let c = entries.maps.pixels();
        if entries.height() != 1 || c == 0 || c > 1 << 16 {
            return Err(invalid("a codebook is a C × 1 image of 1 to 65536 entries"));
        }
        let n = image.width * image.height;
        if image.indices.len() != n || image.indices.iter().any(|&i| i as usize >= c) {
            return Err(invalid(
                "a codebook image needs one index a pixel, each below the entries",
            ));
        }
        let depth = entries.depth.as_deref().filter(|d| d.len() == n);
        let shape = Shape {
            width: image.width,
            height: image.height,
            meta: &entries.meta,
            depth,
            depth_size: (image.width, image.height),
        };
        // The entries as a CODEBOOK_WIDTH-wide texture, the last row padded with the
        // last entry (which leaves every plane's range, and so its coding, as it is).
        let k = entries.maps.k;
        let (cw, ch) = (CODEBOOK_WIDTH.min(c), c.div_ceil(CODEBOOK_WIDTH));
        let mut table = CoefficientMaps::zeros(cw, ch, k);
        for i in 0..k {
            for channel in 0..3 {
                let from = entries.maps.plane(i, channel);
                let to = table.plane_mut(i, channel);
                to[..c].copy_from_slice(from);
                to[c..].fill(from[c - 1]);
            }
        }
        let indices: Vec<u8> = image.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        Self::assemble(
            &shape,
            &table,
            Planes::Codebook(c, indices),
            entries.meta.basis.build()?,
            options,
        )
    }

    fn assemble(
        shape: &Shape,
        planes: &CoefficientMaps,
        kind: Planes,
        basis: Box<dyn Basis>,
        options: &BundleOptions,
    ) -> Result<WebBundle> {
        check_shape(
            shape,
            planes,
            !matches!(kind, Planes::Image),
            basis.as_ref(),
        )?;
        options.precision.require(&PRECISIONS, "the viewer")?;
        let environments = options
            .environments
            .iter()
            .enumerate()
            .map(|(i, p)| load_environment(p, i, shape.meta.color_space))
            .collect::<Result<Vec<_>>>()?;
        let (table, _) = WeightTable::for_basis(basis.as_ref());
        let table = shipped_table(&table);
        let accuracy = table.accuracy(basis.as_ref());
        let mut files = BTreeMap::new();
        let mut info = info_json_with(
            shape,
            planes,
            basis.as_ref(),
            &table,
            &accuracy,
            options,
            &environments,
        )?;
        match kind {
            Planes::Image => {}
            Planes::Codebook(entries, indices) => {
                info["codebook"] = json!({
                    "entries": entries,
                    "width": planes.width,
                    "height": planes.height,
                    "indices": { "file": INDICES_FILE, "format": "u16le" },
                });
                files.insert(format!("data/{INDICES_FILE}"), indices);
            }
            Planes::Overview(source) => {
                info["tiles"] = json!({
                    "side": source.side(),
                    "levels": source.sizes(),
                    "overview": source.overview_level(),
                    "path": "tiles/{level}/{x}_{y}.f16",
                    "format": "f16le",
                });
            }
        }
        let layers = info["layers"].as_array().cloned().unwrap_or_default();
        let n = layers_per_channel(planes.k);
        for (l, layer) in layers.iter().enumerate() {
            let file = layer["file"].as_str().expect("layer file").to_string();
            let bytes = encode_layer(planes, l / n, l % n, options.precision)?;
            files.insert(format!("data/{file}"), bytes);
        }
        files.insert(
            format!("data/{WEIGHTS_FILE}"),
            table
                .values
                .iter()
                .flat_map(|&v| half::f16::from_f32(v).to_le_bytes())
                .collect(),
        );
        if let Some(depth) = shape.depth {
            files.insert("data/depth.f32".to_string(), depth_bytes(depth));
        }
        for env in environments {
            files.insert(format!("data/{}", env.info.file), env.quadrature);
            files.insert(format!("data/{}", env.info.preview), env.preview);
        }
        let text = serde_json::to_string_pretty(&info).expect("info serialises");
        files.insert("data/info.json".to_string(), text.into_bytes());
        Ok(WebBundle { files, tiles: None })
    }

    /// The bytes of `data/info.json`.
    pub fn info(&self) -> &[u8] {
        &self.files["data/info.json"]
    }

    /// Total bytes of the data files.
    pub fn bytes(&self) -> usize {
        self.files.values().map(Vec::len).sum()
    }
}

/// What a bundle's layers hold.
enum Planes<'a> {
    /// The image's pixels.
    Image,
    /// A codebook's entries (their number) and the pixels' indices (little-endian u16).
    Codebook(usize, Vec<u8>),
    /// The overview of a tiled bundle, whose finer levels `TileSource` serves.
    Overview(&'a TileSource),
}

/// The tile side a bundle of `path` takes under `options`, or `None` for whole layers.
fn tile_side(
    path: &Path,
    form: relit::codec::FileForm,
    options: &BundleOptions,
) -> Result<Option<usize>> {
    use relit::codec::{exr, packed, FileForm};
    // What tiles can be read from: a relit EXR, or a compressed file of planes (a
    // codebook file is already small: entries and an index a pixel).
    let size_and_k = match form {
        FileForm::Exr => {
            let shape = exr::read_shape(path)?;
            Some((shape.width, shape.height, shape.k))
        }
        FileForm::Compressed => {
            let header = packed::read_header(path)?;
            match header.indexed_pixels() {
                true => None,
                false => Some((
                    header.width,
                    header.height,
                    header.meta.basis.build()?.len(),
                )),
            }
        }
        _ => None,
    };
    match (options.tiling, size_and_k) {
        (Tiling::Whole, _) | (Tiling::Auto, None) => Ok(None),
        (Tiling::Tiles(side), Some(_)) => Ok(Some(side)),
        (Tiling::Tiles(_), None) => Err(invalid(format!(
            "{}: tiles are read by region from a relit EXR or a .rlz file of planes (not a codebook); convert it first (`relit convert {} -o X.exr`)",
            path.display(),
            path.display()
        ))),
        (Tiling::Auto, Some((w, h, k))) => {
            let bytes = w * h * 3 * layers_per_channel(k) * 8;
            if bytes <= WHOLE_BYTES {
                return Ok(None);
            }
            if options.precision != Precision::F16 {
                return Err(invalid(format!(
                    "{}: its whole layers would take {} MiB; tiles (the default for files this big) are half floats, so leave out --storage {} or ask for whole layers with --tiles off",
                    path.display(),
                    bytes >> 20,
                    options.precision.name()
                )));
            }
            Ok(Some(DEFAULT_TILE_SIDE))
        }
    }
}

/// The weight table's file under `data/`.
const WEIGHTS_FILE: &str = "weights.f16";

/// A depth map as the viewer reads it: little-endian `f32`, 0 where nothing was hit.
pub(crate) fn depth_bytes(depth: &[f32]) -> Vec<u8> {
    depth
        .iter()
        .flat_map(|&d| {
            let d = if d.is_finite() && d > 0.0 { d } else { 0.0 };
            d.to_le_bytes()
        })
        .collect()
}

/// A codebook image's indices under `data/`.
const INDICES_FILE: &str = "indices.u16";

/// Entries per row of a codebook's layers (65536 entries make 256 rows).
pub const CODEBOOK_WIDTH: usize = 256;

/// What a bundle describes besides the coefficients: the image's size, metadata and
/// depth.
struct Shape<'a> {
    width: usize,
    height: usize,
    meta: &'a Metadata,
    depth: Option<&'a [f32]>,
    /// The depth map's size: the image's, or a tiled bundle's overview's.
    depth_size: (usize, usize),
}

impl<'a> Shape<'a> {
    fn of(image: &'a RelightableImage) -> Self {
        Shape {
            width: image.width(),
            height: image.height(),
            meta: &image.meta,
            depth: image.depth.as_deref(),
            depth_size: (image.width(), image.height()),
        }
    }

    fn camera(&self) -> CameraSpec {
        self.meta.camera.clone().unwrap_or(CameraSpec {
            projection: self.meta.projection.clone(),
            width: self.width,
            height: self.height,
            pose: Default::default(),
            orthographic_height: None,
        })
    }
}

/// `table` as the bundle ships it: every weight rounded to a half float (module docs).
pub fn shipped_table(table: &WeightTable) -> WeightTable {
    WeightTable {
        values: table
            .values
            .iter()
            .map(|&v| half::f16::from_f32(v).to_f32())
            .collect(),
        ..table.clone()
    }
}

/// Layers per colour channel for `k` coefficients.
pub fn layers_per_channel(k: usize) -> usize {
    k.div_ceil(4)
}

/// The camera of `image`: its stored camera, or its projection at the default pose.
pub fn camera_spec(image: &RelightableImage) -> CameraSpec {
    Shape::of(image).camera()
}

fn check_shape(
    shape: &Shape,
    planes: &CoefficientMaps,
    own_size: bool,
    basis: &dyn Basis,
) -> Result<()> {
    let (w, h, k) = (shape.width, shape.height, planes.k);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(invalid(format!(
            "the viewer shows images of 1 to {MAX_SIDE} pixels a side, not {w}×{h}"
        )));
    }
    if basis.len() != k {
        return Err(invalid(format!(
            "the file has {k} coefficient maps per channel but its basis {} has {}",
            basis.name(),
            basis.len()
        )));
    }
    if k > MAX_K {
        return Err(invalid(format!(
            "the viewer relights at most {MAX_K} coefficients per channel, not {k} ({})",
            basis.name()
        )));
    }
    let texels = if own_size { planes.pixels() } else { w * h };
    if planes.data.len() != 3 * k * texels {
        return Err(invalid("the coefficient maps have the wrong length"));
    }
    if let Some(d) = shape.depth {
        if d.len() != shape.depth_size.0 * shape.depth_size.1 {
            return Err(invalid("the depth map has the wrong length"));
        }
    }
    shape.camera().build()?;
    Ok(())
}

/// The band windows of environment lights, per coefficient, for bases with bands
/// ([`Basis::coefficient_bands`]); `None` for others. A Laplacian window of the rig's own
/// λ needs the eigenvalue `l(l+1)` of each coefficient's band (`h = 1/(1 + λ·e²)`),
/// shipped too.
fn band_windows(basis: &dyn Basis) -> Result<Option<serde_json::Value>> {
    let Some(band) = basis.coefficient_bands() else {
        return Ok(None);
    };
    let bands = band.iter().max().map_or(0, |&l| l + 1);
    let mut windows = serde_json::Map::new();
    for (name, window) in [
        ("none", Window::None),
        ("hann", Window::Hann),
        ("lanczos", Window::Lanczos),
        ("laplacian", Window::Laplacian { lambda: None }),
    ] {
        let h = window.factors(bands)?;
        windows.insert(
            name.into(),
            json!(band.iter().map(|&l| h[l]).collect::<Vec<_>>()),
        );
    }
    let eigenvalues: Vec<usize> = band.iter().map(|&l| l * (l + 1)).collect();
    Ok(Some(
        json!({ "factors": windows, "laplacian_eigenvalues": eigenvalues }),
    ))
}

fn info_json_with(
    shape: &Shape,
    planes: &CoefficientMaps,
    basis: &dyn Basis,
    table: &WeightTable,
    accuracy: &relit::basis::TableAccuracy,
    options: &BundleOptions,
    environments: &[Environment],
) -> Result<serde_json::Value> {
    let k = planes.k;
    let n = layers_per_channel(k);
    let mut layers = Vec::new();
    for c in 0..3 {
        for j in 0..n {
            let mut scale = [0.0f64; 4];
            let mut offset = [0.0f64; 4];
            let mut coefficients = Vec::new();
            for (q, (s, o)) in scale.iter_mut().zip(offset.iter_mut()).enumerate() {
                let i = 4 * j + q;
                if i >= k {
                    continue;
                }
                coefficients.push(i);
                let coding = options.precision.coding(planes.plane(i, c));
                *s = coding.scale as f64;
                *o = coding.offset as f64;
            }
            layers.push(json!({
                "file": format!("planes/L{:02}.{}", c * n + j, extension(options.precision)),
                "channel": c,
                "coefficients": coefficients,
                "scale": scale,
                "offset": offset,
            }));
        }
    }
    let camera = shape.camera();
    let meta = shape.meta;
    let mut basis_info = json!({ "name": basis.name(), "spec": basis.spec(), "k": k });
    if let Some(windows) = band_windows(basis)? {
        basis_info["windows"] = windows;
    }
    Ok(json!({
        "format": "relit-web",
        "version": WEB_FORMAT_VERSION,
        "source": options.source_name,
        "width": shape.width,
        "height": shape.height,
        "basis": basis_info,
        "k": k,
        "weights": {
            "file": WEIGHTS_FILE,
            "format": "f16le",
            "resolution": table.resolution,
            "relative_rms_error": accuracy.relative_rms,
            "relative_max_error": accuracy.relative_max,
        },
        "color_space": meta.color_space,
        "light_frame": meta.light_frame,
        "projection": meta.projection,
        "camera": camera,
        "storage": options.precision,
        "layers_per_channel": n,
        "layers": layers,
        "depth": shape.depth.map(|_| json!({
            "file": "depth.f32",
            "format": "f32le",
            "width": shape.depth_size.0,
            "height": shape.depth_size.1,
        })),
        "environments": environments.iter().map(|e| &e.info).collect::<Vec<_>>(),
    }))
}

/// Layer `j` of channel `c`: planes `4j … 4j+3` (zero past `k`), each encoded by
/// [`Precision::encode`] with its coding, interleaved per pixel.
pub(crate) fn encode_layer(
    planes: &CoefficientMaps,
    c: usize,
    j: usize,
    precision: Precision,
) -> Result<Vec<u8>> {
    let (w, h, k) = (planes.width, planes.height, planes.k);
    let pixels = w * h;
    let b = precision.bytes_per_value();
    let planes: Vec<Vec<u8>> = (0..4)
        .map(|q| {
            let mut bytes = Vec::with_capacity(pixels * b);
            if 4 * j + q < k {
                let plane = planes.plane(4 * j + q, c);
                precision.encode(plane, precision.coding(plane), &mut bytes);
            } else {
                // A component past k: zeros, whose value is 0 in the coding `(0, 0)`.
                let zeros = vec![0.0; pixels];
                let none = PlaneCoding {
                    scale: 0.0,
                    offset: 0.0,
                };
                precision.encode(&zeros, none, &mut bytes);
            }
            bytes
        })
        .collect();
    let mut texels = Vec::with_capacity(pixels * 4 * b);
    for p in 0..pixels {
        for plane in &planes {
            texels.extend_from_slice(&plane[p * b..(p + 1) * b]);
        }
    }
    match precision {
        Precision::U8 => encode_png(w, h, image::ExtendedColorType::Rgba8, &texels),
        _ => Ok(texels),
    }
}

fn encode_png(w: usize, h: usize, color: image::ExtendedColorType, data: &[u8]) -> Result<Vec<u8>> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Adaptive)
        .write_image(data, w as u32, h as u32, color)
        .map_err(|e| invalid(format!("could not encode a PNG layer: {e}")))?;
    Ok(out)
}

/// Load environment map `index`: its quadrature (for display-referred maps its
/// median-cut lights, which the viewer decodes one by one as the CPU engine does) and
/// its preview.
fn load_environment(path: &Path, index: usize, space: MapSpace) -> Result<Environment> {
    let env = EnvironmentLight::load(path)?;
    let map = env.map();
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
    let mut lights = environment_quadrature(map, QUADRATURE_WIDTH, QUADRATURE_HEIGHT);
    if space == MapSpace::Srgb {
        lights = relit::envmap::median_cut(&lights, relit::engine::DISPLAY_ENVIRONMENT_LIGHTS);
    }
    // A 128×64 preview, nearest texel, clipped and sRGB encoded.
    let (pw, ph) = (128usize, 64usize);
    let mut rgb = Vec::with_capacity(pw * ph * 3);
    for y in 0..ph {
        for x in 0..pw {
            let sx = (x * map.width / pw).min(map.width - 1);
            let sy = (y * map.height / ph).min(map.height - 1);
            for v in map.get(sx, sy) {
                rgb.push(relit::color::linear_to_srgb8(v));
            }
        }
    }
    let preview = encode_png(pw, ph, image::ExtendedColorType::Rgb8, &rgb)?;
    Ok(Environment {
        info: EnvironmentInfo {
            map: name,
            width: map.width,
            height: map.height,
            file: format!("env/{index}.f32"),
            lights: lights.len(),
            preview: format!("env/{index}.png"),
        },
        quadrature: lights
            .iter()
            .flat_map(|(d, i)| [d.x, d.y, d.z, i[0], i[1], i[2]])
            .flat_map(|v| (v as f32).to_le_bytes())
            .collect(),
        preview,
    })
}
