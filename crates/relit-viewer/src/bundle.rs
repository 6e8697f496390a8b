//! What the browser loads: `info.json` plus coefficient layers, depth and environments.
//!
//! Layers are *channel-major*: with `n = ⌈k/4⌉` layers per colour channel, layer
//! `c·n + j` holds coefficients `4j … 4j+3` of channel `c` in its R, G, B, A components
//! (components past `k` are zero). So the shader relights a channel with `n` dot
//! products of a texel and a weight `vec4`.
//!
//! * `u8` storage: each layer is an RGBA 8-bit PNG; component `q` of a plane decodes
//!   to `bias + scale · q / 255`, with the plane's own `scale` and `bias` in `info.json`
//!   (the plane's range, so the quantisation step is `(max − min)/255`).
//! * `f16` storage: each layer is `width × height × 4` little-endian IEEE half floats,
//!   row-major from the top-left pixel, RGBA interleaved; `scale` 1 and `bias` 0.
//!
//! The depth map (when the file has one) is `width × height` little-endian `f32`
//! (`data/depth.f32`), 0 where nothing was hit; with the camera in `info.json` the
//! viewer recomputes each pixel's surface point `P = O + d·V` exactly as the CPU engine.

use crate::{invalid, Result};
use relit::camera::CameraSpec;
use relit::envmap::EnvironmentLight;
use relit::maps::RelightableImage;
use serde::Serialize;
use serde_json::json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The format version of `info.json`.
pub const WEB_FORMAT_VERSION: u32 = 1;

/// Largest side the viewer accepts (WebGL2 guarantees textures of 2048 and most
/// implementations, SwiftShader included, give 8192 or more).
pub const MAX_SIDE: usize = 16384;

/// How coefficient planes are stored for the web.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PlaneStorage {
    /// 8-bit PNG per layer, quantised with a scale and bias per plane.
    U8,
    /// Raw little-endian half floats per layer.
    #[default]
    F16,
}

impl PlaneStorage {
    pub fn name(self) -> &'static str {
        match self {
            PlaneStorage::U8 => "u8",
            PlaneStorage::F16 => "f16",
        }
    }
    fn extension(self) -> &'static str {
        match self {
            PlaneStorage::U8 => "png",
            PlaneStorage::F16 => "f16",
        }
    }
}

impl std::str::FromStr for PlaneStorage {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "u8" | "8" | "png" => Ok(PlaneStorage::U8),
            "f16" | "half" | "16" => Ok(PlaneStorage::F16),
            other => Err(format!("unknown storage `{other}` (u8 or f16)")),
        }
    }
}

/// Options of a bundle.
#[derive(Clone, Debug, Default)]
pub struct BundleOptions {
    pub storage: PlaneStorage,
    /// Lat-long environment maps whose SH projections go into `info.json`; the rig JSON
    /// names each by its file name.
    pub environments: Vec<PathBuf>,
    /// A name for the source shown by the viewer (usually the EXR's file name).
    pub source_name: String,
}

/// One environment map projected onto the file's SH basis.
#[derive(Clone, Debug, Serialize)]
pub struct EnvironmentInfo {
    /// The name a rig's `map` field uses (the file name).
    pub map: String,
    pub width: usize,
    pub height: usize,
    /// `∫ E(ω) Y_i(ω) dω` per colour channel in the light frame, unrotated, unwindowed.
    pub coefficients: [Vec<f64>; 3],
    /// A small sRGB preview (`data/env/N.png`).
    pub preview: String,
}

/// The files of a web bundle, by path relative to the site root (`data/...`).
#[derive(Clone, Debug)]
pub struct WebBundle {
    pub files: BTreeMap<String, Vec<u8>>,
}

impl WebBundle {
    /// Build every data file of `image`.
    pub fn build(image: &RelightableImage, options: &BundleOptions) -> Result<WebBundle> {
        let environments = options
            .environments
            .iter()
            .enumerate()
            .map(|(i, p)| project_environment(image, p, i))
            .collect::<Result<Vec<_>>>()?;
        let mut files = BTreeMap::new();
        let info = info_json_with(image, options, &environments)?;
        let layers = info["layers"].as_array().cloned().unwrap_or_default();
        let n = layers_per_channel(image.maps.k);
        for (l, layer) in layers.iter().enumerate() {
            let file = layer["file"].as_str().expect("layer file").to_string();
            let bytes = encode_layer(image, l / n, l % n, options.storage)?;
            files.insert(format!("data/{file}"), bytes);
        }
        if let Some(depth) = &image.depth {
            let bytes: Vec<u8> = depth
                .iter()
                .flat_map(|&d| {
                    let d = if d.is_finite() && d > 0.0 { d } else { 0.0 };
                    d.to_le_bytes()
                })
                .collect();
            files.insert("data/depth.f32".to_string(), bytes);
        }
        for (i, env) in environments.iter().enumerate() {
            files.insert(format!("data/env/{i}.png"), env.1.clone());
        }
        let text = serde_json::to_string_pretty(&info).expect("info serialises");
        files.insert("data/info.json".to_string(), text.into_bytes());
        Ok(WebBundle { files })
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

/// Layers per colour channel for `k` coefficients.
pub fn layers_per_channel(k: usize) -> usize {
    k.div_ceil(4)
}

/// The camera of `image`: its stored camera, or its projection at the default pose.
pub fn camera_spec(image: &RelightableImage) -> CameraSpec {
    image.meta.camera.clone().unwrap_or(CameraSpec {
        projection: image.meta.projection.clone(),
        width: image.width(),
        height: image.height(),
        pose: Default::default(),
        orthographic_height: None,
    })
}

/// The `info.json` of `image` (without environments' previews being computed twice).
pub fn info_json(image: &RelightableImage, options: &BundleOptions) -> Result<serde_json::Value> {
    let environments = options
        .environments
        .iter()
        .enumerate()
        .map(|(i, p)| project_environment(image, p, i))
        .collect::<Result<Vec<_>>>()?;
    info_json_with(image, options, &environments)
}

fn check_image(image: &RelightableImage) -> Result<usize> {
    let (w, h, k) = (image.width(), image.height(), image.maps.k);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(invalid(format!(
            "the viewer shows images of 1 to {MAX_SIDE} pixels a side, not {w}×{h}"
        )));
    }
    let bands = relit::basis::SphericalHarmonics::bands_of(&image.meta.basis).unwrap_or(0);
    if bands * bands != k || !(1..=8).contains(&bands) {
        return Err(invalid(format!(
            "the viewer needs 1 to 8 SH bands with k = bands² maps, not {k} maps of {bands} bands"
        )));
    }
    if image.maps.data.len() != 3 * k * w * h {
        return Err(invalid("the coefficient maps have the wrong length"));
    }
    if let Some(d) = &image.depth {
        if d.len() != w * h {
            return Err(invalid("the depth map has the wrong length"));
        }
    }
    camera_spec(image).build()?;
    Ok(bands)
}

fn info_json_with(
    image: &RelightableImage,
    options: &BundleOptions,
    environments: &[(EnvironmentInfo, Vec<u8>)],
) -> Result<serde_json::Value> {
    let bands = check_image(image)?;
    let k = image.maps.k;
    let n = layers_per_channel(k);
    let mut layers = Vec::new();
    for c in 0..3 {
        for j in 0..n {
            let mut scale = [0.0f64; 4];
            let mut bias = [0.0f64; 4];
            let mut coefficients = Vec::new();
            for (q, (s, b)) in scale.iter_mut().zip(bias.iter_mut()).enumerate() {
                let i = 4 * j + q;
                if i >= k {
                    continue;
                }
                coefficients.push(i);
                match options.storage {
                    PlaneStorage::F16 => *s = 1.0,
                    PlaneStorage::U8 => {
                        let (lo, hi) = plane_range(image.maps.plane(i, c));
                        *b = lo as f64;
                        *s = (hi - lo) as f64;
                    }
                }
            }
            layers.push(json!({
                "file": format!("planes/L{:02}.{}", c * n + j, options.storage.extension()),
                "channel": c,
                "coefficients": coefficients,
                "scale": scale,
                "bias": bias,
            }));
        }
    }
    let camera = camera_spec(image);
    Ok(json!({
        "format": "relit-web",
        "version": WEB_FORMAT_VERSION,
        "source": options.source_name,
        "width": image.width(),
        "height": image.height(),
        "bands": bands,
        "k": k,
        "color_space": image.meta.color_space,
        "light_frame": image.meta.light_frame,
        "projection": image.meta.projection,
        "camera": camera,
        "storage": options.storage,
        "layers_per_channel": n,
        "layers": layers,
        "depth": image.depth.as_ref().map(|_| json!({ "file": "depth.f32", "format": "f32le" })),
        "environments": environments.iter().map(|e| &e.0).collect::<Vec<_>>(),
    }))
}

/// The finite range of a plane (0, 0 when nothing is finite).
fn plane_range(plane: &[f32]) -> (f32, f32) {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for &v in plane.iter().filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if lo > hi {
        (0.0, 0.0)
    } else {
        (lo, hi)
    }
}

/// Quantise `v` of a plane with range `[lo, lo + scale]` to 8 bits.
pub fn quantize_u8(v: f32, lo: f32, scale: f32) -> u8 {
    if scale.is_nan() || scale <= 0.0 || !v.is_finite() {
        return 0;
    }
    ((v - lo) / scale * 255.0).round().clamp(0.0, 255.0) as u8
}

fn encode_layer(
    image: &RelightableImage,
    c: usize,
    j: usize,
    storage: PlaneStorage,
) -> Result<Vec<u8>> {
    let (w, h, k) = (image.width(), image.height(), image.maps.k);
    let pixels = w * h;
    let planes: Vec<Option<&[f32]>> = (0..4)
        .map(|q| (4 * j + q < k).then(|| image.maps.plane(4 * j + q, c)))
        .collect();
    match storage {
        PlaneStorage::F16 => {
            let mut out = Vec::with_capacity(pixels * 8);
            for p in 0..pixels {
                for plane in &planes {
                    let v = plane.map_or(0.0, |pl| pl[p]);
                    let v = if v.is_finite() { v } else { 0.0 };
                    out.extend_from_slice(&half::f16::from_f32(v).to_le_bytes());
                }
            }
            Ok(out)
        }
        PlaneStorage::U8 => {
            let ranges: Vec<(f32, f32)> = planes
                .iter()
                .map(|pl| pl.map_or((0.0, 0.0), plane_range))
                .collect();
            let mut rgba = Vec::with_capacity(pixels * 4);
            for p in 0..pixels {
                for (plane, &(lo, hi)) in planes.iter().zip(&ranges) {
                    rgba.push(plane.map_or(0, |pl| quantize_u8(pl[p], lo, hi - lo)));
                }
            }
            encode_png(w, h, image::ExtendedColorType::Rgba8, &rgba)
        }
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

/// Project one environment map onto the file's SH bands and make its preview.
fn project_environment(
    image: &RelightableImage,
    path: &Path,
    index: usize,
) -> Result<(EnvironmentInfo, Vec<u8>)> {
    let bands = relit::basis::SphericalHarmonics::bands_of(&image.meta.basis).unwrap_or(0);
    let env = EnvironmentLight::load(path)?;
    let coefficients = env.project(bands)?;
    let map = env.map();
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string());
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
    Ok((
        EnvironmentInfo {
            map: name,
            width: map.width,
            height: map.height,
            coefficients,
            preview: format!("env/{index}.png"),
        },
        preview,
    ))
}
