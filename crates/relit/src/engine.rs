//! The CPU relighting engine: coefficient maps + lights → linear images.
//!
//! A directional light has one light vector for the whole image, so its effect is a
//! weighted sum of the coefficient planes with the basis values `B_i(L)` as weights
//! (seed 000, figure 6). Several such lights on linear maps fold into one weight per
//! plane before any pixel is touched, so the cost is one pass over the planes whatever
//! their number. Lights with a position (point, spot, projector, area) have a light
//! vector per pixel, `L = S − P` with `P` the pixel's surface point from the camera
//! and depth (seed 004 eq. 3), and evaluate the basis per pixel (seed 000, figure 8):
//! SH by its f32 recurrence, any other basis from its half-float weight table (the
//! weights the GPU and the browser viewer read). Environment lights are one weight
//! vector per frame for every basis (`crate::envmap`: SH's exact projection, or a
//! quadrature of the map for the others). Nothing here names a particular basis.
//! Display-referred maps are evaluated per light and decoded to linear before adding.
//!
//! Known limitation (seed 004 §VI): the maps record shadows cast by *directional*
//! light. A non-directional light placed between an occluder and the surface seen
//! through a pixel still relights with the shadow the capture recorded, because the
//! pixel's function knows only directions, not distances.

use crate::basis::Basis;
use crate::camera::{Camera, CameraSpec};
use crate::envmap::{BasisEnvironment, EnvironmentLight};
use crate::image::ImageRgb;
use crate::light::{Light, LightRig, PreparedLight};
use crate::maps::{MapSpace, RelightableImage};
use crate::sphere::Vec3;
use crate::{Error, Result};
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock};

mod bounds;
mod kernels;
pub mod lookup;
mod points;
mod tiles;

pub use bounds::{fma_peak, fma_throughput, FmaPeak};

use crate::storage::{CompactPlanes, Planes, Precision};
pub use kernels::BasisEvaluator;

/// The kernels the CPU engine runs on this machine: `avx2+fma+f16c` or `portable`.
pub fn cpu_kernels() -> &'static str {
    kernels::Simd::detect().name()
}
use kernels::{PixelBasis, Simd};
use points::SurfacePoints;
use tiles::{Frame, PositionalLight, Scratch, UniformPass, TILE};

/// Frames of at least this many bytes are written with non-temporal stores (see
/// `Simd::interleave_stream`): far more than the L2 caches and a fair share of an L3.
/// Measured: at 8192×2048 (192 MiB frames) 5–10 % faster for f16 and u8 planes, no
/// change for f32; at 1024×256 (3 MiB, which stays in L3 between frames) about 15 %
/// slower for f16 and u8, so small frames are written as usual.
const STREAM_BYTES: usize = 64 << 20;

/// Directional lights an environment is lumped into on display-referred maps
/// ([`Relighter::environment_lights`]): each costs one pass per frame, so a few must
/// stand for the map. Measured on a display-referred fit of RealRTI item2 (sh:16) under
/// the seven shared maps turned by (30°, −10°, 5°), 8-bit sRGB PSNR of a 96×96 crop
/// against 4096 lights (the 64×64 quadrature, each decoded on its own): 16 lights
/// 27.5–49.0 dB, 32 lights 35.6–58.4, 64 lights 52.9–65.5 (every map above an 8-bit
/// step's 48 dB); folding the map into one weight vector, as the engine did before,
/// scored 7.2–17.6 dB. The ignored test `display_environment_lumps_measurement`
/// (`crates/relit/tests/display_environment.rs`) measures it. The GPU engine's frame
/// holds these passes and 32 more.
pub const DISPLAY_ENVIRONMENT_LIGHTS: usize = 64;

/// What `make` builds from the file at `path`, built once per file and kept in `cache`.
fn cached<T>(
    cache: &Mutex<HashMap<PathBuf, Arc<T>>>,
    path: &std::path::Path,
    make: impl FnOnce() -> Result<T>,
) -> Result<Arc<T>> {
    let mut cache = cache.lock().expect("file cache");
    if let Some(v) = cache.get(path) {
        return Ok(v.clone());
    }
    let v = Arc::new(make()?);
    cache.insert(path.to_path_buf(), v.clone());
    Ok(v)
}

/// An environment's median-cut lights: direction (light frame, unrotated) and RGB.
type EnvironmentLumps = Vec<(Vec3, [f64; 3])>;

/// Options of [`relight`].
#[derive(Clone, Debug, Default)]
pub struct RelightOptions {
    /// Exposure in stops applied to the result (each +1 doubles it).
    pub exposure: f64,
    /// Folder that relative paths in lights (projector slides) resolve against.
    pub resource_dir: PathBuf,
}

/// A region of interest: the window of pixels a frame is computed for, `x, y` its
/// top-left corner (image convention: y down). A frame relit over a region is
/// `width × height` pixels and equals that crop of the full frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Roi {
    pub x: usize,
    pub y: usize,
    pub width: usize,
    pub height: usize,
}

impl Roi {
    /// The whole `width × height` image.
    pub fn full(width: usize, height: usize) -> Self {
        Self {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// Parse `x,y,w,h` (pixels).
    pub fn parse(s: &str) -> Result<Self> {
        let numbers: Option<Vec<usize>> = s.split(',').map(|p| p.trim().parse().ok()).collect();
        match numbers.as_deref() {
            Some(&[x, y, width, height]) => Ok(Self {
                x,
                y,
                width,
                height,
            }),
            _ => Err(Error::parse(format!(
                "bad region `{s}`: expected `x,y,width,height` in pixels"
            ))),
        }
    }

    /// Check that the region is non-empty and inside a `width × height` image.
    pub fn validate(&self, width: usize, height: usize) -> Result<()> {
        let inside = self.width > 0
            && self.height > 0
            && self.x.checked_add(self.width).is_some_and(|r| r <= width)
            && self.y.checked_add(self.height).is_some_and(|b| b <= height);
        if inside {
            Ok(())
        } else {
            Err(Error::invalid(format!(
                "region {}×{} at ({}, {}) is empty or leaves the {width}×{height} image",
                self.width, self.height, self.x, self.y
            )))
        }
    }

    /// Pixels in the region.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// This region of `image` (which must contain it), as an image of its own.
    pub fn crop(&self, image: &ImageRgb) -> ImageRgb {
        let mut out = ImageRgb::new(self.width, self.height);
        for (r, row) in out.data.chunks_exact_mut(3 * self.width).enumerate() {
            let at = 3 * ((self.y + r) * image.width + self.x);
            row.copy_from_slice(&image.data[at..at + 3 * self.width]);
        }
        out
    }
}

/// Relight `image` with `rig` (a one-off; [`Relighter`] reuses work across frames).
pub fn relight(
    image: &RelightableImage,
    rig: &LightRig,
    options: &RelightOptions,
) -> Result<ImageRgb> {
    Relighter::new(image)?.relight(rig, options)
}

/// Relights one relightable image many times, keeping what does not depend on the lights
/// (the planes in their storage type, the basis, the per-pixel surface points, loaded
/// slides and environment maps).
///
/// Speed (see `engine/kernels.rs` and `engine/tiles.rs`): the planes are read in their
/// planar layout, tile by tile (rayon over tiles of [`tiles::TILE`] pixels, or over
/// rows of a region), with AVX2/FMA/F16C code when the CPU has it. Directional and
/// environment lights on linear maps fold into one weight per plane, so a frame reads
/// each plane once; positional lights (point, spot, projector, area) evaluate the
/// basis per block of 64 pixels at each pixel's light vectors (SH by an f32 recurrence,
/// other bases from their half-float weight table; an area light's samples summed on
/// the basis before one dot with the coefficients).
pub struct Relighter<'a> {
    image: &'a RelightableImage,
    basis: Box<dyn Basis>,
    /// The basis per pixel (its weight table built on the first frame that needs it).
    pixel_basis: OnceLock<PixelBasis>,
    planes: Planes<'a>,
    simd: Simd,
    /// Frames of at least this many bytes are written with non-temporal stores.
    stream_from: usize,
    points: OnceLock<Result<Vec<Option<Vec3>>, String>>,
    /// Surface points rebuilt per block from camera and depth.
    point_rows: OnceLock<Result<SurfacePoints<'a>, String>>,
    slides: Mutex<HashMap<PathBuf, Arc<ImageRgb>>>,
    /// Environment maps made ready for the basis, by file.
    environments: Mutex<HashMap<PathBuf, Arc<BasisEnvironment>>>,
    /// Environment maps as a few directional lights (display-referred maps), by file.
    environment_lumps: Mutex<HashMap<PathBuf, Arc<EnvironmentLumps>>>,
}

impl<'a> Relighter<'a> {
    /// A relighter that reads the maps' own f32 values (no copy).
    pub fn new(image: &'a RelightableImage) -> Result<Self> {
        Self::with_precision(image, Precision::F32)
    }

    /// A relighter that reads the planes in `precision`: f32 borrows the maps, f16 and
    /// u8 (per-plane scale and offset) hold a compact copy made here.
    pub fn with_precision(image: &'a RelightableImage, precision: Precision) -> Result<Self> {
        let basis = image.meta.basis.build()?;
        if basis.len() != image.maps.k {
            return Err(Error::invalid(format!(
                "the maps hold {} coefficients but the basis has {}",
                image.maps.k,
                basis.len()
            )));
        }
        if image.maps.data.len() != 3 * image.maps.k * image.maps.pixels() {
            return Err(Error::invalid(
                "the coefficient maps' data does not match their size",
            ));
        }
        Ok(Self::over(
            image,
            basis,
            Planes::new(&image.maps, precision),
        ))
    }

    /// A relighter over checked planes, with nothing computed yet.
    fn over(image: &'a RelightableImage, basis: Box<dyn Basis>, planes: Planes<'a>) -> Self {
        Self {
            image,
            basis,
            pixel_basis: OnceLock::new(),
            planes,
            simd: Simd::detect(),
            stream_from: STREAM_BYTES,
            points: OnceLock::new(),
            point_rows: OnceLock::new(),
            slides: Mutex::new(HashMap::new()),
            environments: Mutex::new(HashMap::new()),
            environment_lumps: Mutex::new(HashMap::new()),
        }
    }

    /// A relighter over compact planes decoded without the f32 maps
    /// (`read_compact` of the EXR codec): `image` supplies the metadata, sizes and
    /// depth; its `maps.data` is not read and may be empty.
    pub fn with_compact(image: &'a RelightableImage, planes: CompactPlanes) -> Result<Self> {
        let basis = image.meta.basis.build()?;
        let k = image.maps.k;
        if basis.len() != k || planes.count != 3 * k || planes.pixels != image.maps.pixels() {
            return Err(Error::invalid(format!(
                "compact planes ({} of {} values) do not match the file's {}×{} maps of {} coefficients (basis {})",
                planes.count,
                planes.pixels,
                image.width(),
                image.height(),
                k,
                basis.len()
            )));
        }
        Ok(Self::over(image, basis, planes.planes))
    }

    /// Run the portable kernels even where the CPU has AVX2 (tests compare both).
    #[cfg(test)]
    fn baseline(mut self) -> Self {
        self.simd = Simd::baseline();
        self
    }

    /// Write every frame that can be streamed with non-temporal stores (tests).
    #[cfg(test)]
    fn streaming(mut self) -> Self {
        self.stream_from = 0;
        self
    }

    /// The precision of the planes this relighter reads.
    pub fn precision(&self) -> Precision {
        self.planes.precision()
    }

    /// Bytes of the planes one uniform frame streams.
    pub fn plane_bytes(&self) -> usize {
        self.planes.bytes()
    }

    /// Which kernels run: `avx2+fma+f16c` or `portable`.
    pub fn kernels(&self) -> &'static str {
        self.simd.name()
    }

    /// The camera the file was captured with (its stored camera, or its projection with
    /// the default pose).
    pub fn camera(&self) -> Result<Camera> {
        let meta = &self.image.meta;
        let spec = meta.camera.clone().unwrap_or(CameraSpec {
            projection: meta.projection.clone(),
            width: self.image.width(),
            height: self.image.height(),
            pose: Default::default(),
            orthographic_height: None,
        });
        spec.build()
    }

    /// Surface points of every pixel (`None` where nothing was hit), from camera and depth.
    pub fn surface_points(&self) -> Result<&[Option<Vec3>]> {
        let points = self.points.get_or_init(|| {
            let (camera, depth) = self.depth_camera()?;
            camera
                .positions_from_depth(depth)
                .map_err(|e| e.to_string())
        });
        points.as_deref().map_err(|e| Error::invalid(e.clone()))
    }

    fn depth_camera(&self) -> std::result::Result<(Camera, &'a [f32]), String> {
        let depth = self.image.depth.as_deref().ok_or_else(|| {
            "lights with a position need a depth map: fit a capture that has one (a manifest `depth`, or `relit capture`)".to_string()
        })?;
        let camera = self.camera().map_err(|e| e.to_string())?;
        if depth.len() != camera.width() * camera.height()
            || depth.len() != self.image.maps.pixels()
        {
            return Err(format!(
                "the depth map has {} values and the camera is {}×{}, but the maps are {}×{}",
                depth.len(),
                camera.width(),
                camera.height(),
                self.image.width(),
                self.image.height()
            ));
        }
        Ok((camera, depth))
    }

    /// How the basis is evaluated per pixel, made once (a weight table is built here
    /// for bases other than SH).
    fn pixel_basis(&self) -> &PixelBasis {
        self.pixel_basis
            .get_or_init(|| PixelBasis::new(self.basis.as_ref()))
    }

    /// The basis the maps are relit in (built once, from the file's description).
    pub fn basis(&self) -> &dyn Basis {
        self.basis.as_ref()
    }

    /// How lights with a position evaluate the basis: `sh recurrence`, `hsh recurrence` or `weight
    /// table` (building the table if needed).
    pub fn pixel_path(&self) -> &'static str {
        self.pixel_basis().name()
    }

    /// The per-block source of surface points, made once.
    fn point_rows(&self) -> Result<&SurfacePoints<'a>> {
        let rows = self.point_rows.get_or_init(|| {
            let (camera, depth) = self.depth_camera()?;
            Ok(SurfacePoints::new(&camera, depth))
        });
        rows.as_ref().map_err(|e| Error::invalid(e.clone()))
    }

    /// The basis weights of an environment light for these maps, times the light's
    /// colour: the map made ready for the basis once per file
    /// ([`EnvironmentLight::for_basis`]), then rotated (and, on bases with bands,
    /// windowed) per call.
    pub fn environment_weights(
        &self,
        light: &crate::light::EnvironmentMapLight,
        resource_dir: &std::path::Path,
    ) -> Result<[Vec<f64>; 3]> {
        light.validate()?;
        let path = resource_dir.join(&light.map);
        let entry = cached(&self.environments, &path, || {
            EnvironmentLight::load(&path)?.for_basis(self.basis.as_ref())
        })?;
        let mut weights = entry
            .weights(self.basis.as_ref(), light.rotation()?, light.window)
            .map_err(|e| Error::invalid(format!("environment light {}: {e}", light.map)))?;
        let rgb = Light::Environment(light.clone()).rgb();
        for (c, w) in weights.iter_mut().enumerate() {
            w.iter_mut().for_each(|v| *v *= rgb[c]);
        }
        Ok(weights)
    }

    /// The directional lights an environment stands for on display-referred maps, where
    /// each light is decoded to radiance on its own before lights add up (so no one
    /// weight vector can stand for the map): the map's quadrature lumped into
    /// [`DISPLAY_ENVIRONMENT_LIGHTS`] lights by median cut ([`crate::envmap::median_cut`],
    /// once per file), turned by the light's rotation, times its colour. A window has no
    /// part in it (it attenuates a basis' bands of a projection).
    pub fn environment_lights(
        &self,
        light: &crate::light::EnvironmentMapLight,
        resource_dir: &std::path::Path,
    ) -> Result<Vec<PreparedLight>> {
        light.validate()?;
        let path = resource_dir.join(&light.map);
        let lumps = cached(&self.environment_lumps, &path, || {
            let env = EnvironmentLight::load(&path)?;
            let quadrature = crate::envmap::environment_quadrature(
                env.map(),
                crate::envmap::QUADRATURE_WIDTH,
                crate::envmap::QUADRATURE_HEIGHT,
            );
            Ok(crate::envmap::median_cut(
                &quadrature,
                DISPLAY_ENVIRONMENT_LIGHTS,
            ))
        })?;
        let rotation = light.rotation()?;
        let rgb = Light::Environment(light.clone()).rgb();
        Ok(lumps
            .iter()
            .map(|(d, i)| PreparedLight::Directional {
                direction: crate::basis::mat3_apply(&rotation, *d),
                rgb: std::array::from_fn(|c| i[c] * rgb[c]),
            })
            .collect())
    }

    /// Prepare one light for this file (environment weights, cached slides): one
    /// prepared light, or several where an environment lights display-referred maps
    /// ([`Relighter::environment_lights`]).
    pub fn prepare(&self, light: &Light, options: &RelightOptions) -> Result<Vec<PreparedLight>> {
        if let Light::Environment(env) = light {
            if self.image.meta.color_space == MapSpace::Srgb {
                return self.environment_lights(env, &options.resource_dir);
            }
            return Ok(vec![PreparedLight::Weights(
                self.environment_weights(env, &options.resource_dir)?,
            )]);
        }
        if let Light::Projector(p) = light {
            p.validate()?;
            let path = options.resource_dir.join(&p.slide);
            let slide = cached(&self.slides, &path, || {
                crate::image::load_linear(&path, None)
            })?;
            return Ok(vec![PreparedLight::Projector(
                Box::new(p.with_slide(slide)),
                light.rgb(),
            )]);
        }
        Ok(vec![light.prepare(&options.resource_dir)?])
    }

    /// Prepare every light of `rig` ([`Relighter::prepare`]), in order.
    pub fn prepare_rig(
        &self,
        rig: &LightRig,
        options: &RelightOptions,
    ) -> Result<Vec<PreparedLight>> {
        let mut out = Vec::with_capacity(rig.lights.len());
        for light in &rig.lights {
            out.extend(self.prepare(light, options)?);
        }
        Ok(out)
    }

    /// Relight with `rig`.
    pub fn relight(&self, rig: &LightRig, options: &RelightOptions) -> Result<ImageRgb> {
        self.relight_roi(rig, options, self.full())
    }

    /// Relight only `roi` (lazy relighting of the visible window): the result is
    /// `roi.width × roi.height` and equals that crop of [`Relighter::relight`].
    pub fn relight_roi(
        &self,
        rig: &LightRig,
        options: &RelightOptions,
        roi: Roi,
    ) -> Result<ImageRgb> {
        let lights = self.prepare_rig(rig, options)?;
        self.relight_prepared_roi(&lights, options.exposure, roi)
    }

    /// Relight with lights already prepared.
    pub fn relight_prepared(&self, lights: &[PreparedLight], exposure: f64) -> Result<ImageRgb> {
        self.relight_prepared_roi(lights, exposure, self.full())
    }

    fn full(&self) -> Roi {
        Roi::full(self.image.width(), self.image.height())
    }

    /// Relight `roi` with lights already prepared.
    pub fn relight_prepared_roi(
        &self,
        lights: &[PreparedLight],
        exposure: f64,
        roi: Roi,
    ) -> Result<ImageRgb> {
        let mut out = ImageRgb::new(0, 0);
        self.relight_prepared_into(lights, exposure, roi, &mut out)?;
        Ok(out)
    }

    /// Relight `roi` into `out`, which becomes `roi.width × roi.height` and reuses its
    /// buffer when large enough (frames of an interactive viewer or a benchmark then
    /// allocate nothing).
    pub fn relight_prepared_into(
        &self,
        lights: &[PreparedLight],
        exposure: f64,
        roi: Roi,
        out: &mut ImageRgb,
    ) -> Result<()> {
        let image = self.image;
        let width = image.width();
        roi.validate(width, image.height())?;
        let k = self.basis.len();
        let scale = 2f64.powf(exposure);
        let display = image.meta.color_space == MapSpace::Srgb;
        // Uniform lights: one weight vector per channel and pass. Linear maps fold every
        // such light into one pass; display-referred maps need one pass per light.
        let mut passes: Vec<UniformPass> = Vec::new();
        let mut folded: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; k]);
        let mut any_folded = false;
        for light in lights {
            let (weights, tint) = match light {
                PreparedLight::Directional { direction, rgb } => {
                    let y = self.basis.values(*direction);
                    if display {
                        ([y.clone(), y.clone(), y], rgb.map(|v| v * scale))
                    } else {
                        (
                            std::array::from_fn(|c| y.iter().map(|v| v * rgb[c]).collect()),
                            [scale; 3],
                        )
                    }
                }
                PreparedLight::Weights(w) => {
                    if w.iter().any(|w| w.len() != k) {
                        return Err(Error::invalid(format!(
                            "a light's basis weights must have {k} entries per channel"
                        )));
                    }
                    (w.clone(), [scale; 3])
                }
                _ => continue,
            };
            if display {
                passes.push(UniformPass::new(
                    &weights,
                    tint.map(|v| v as f32),
                    &self.planes,
                ));
            } else {
                any_folded = true;
                for c in 0..3 {
                    for (f, w) in folded[c].iter_mut().zip(&weights[c]) {
                        *f += w * tint[c];
                    }
                }
            }
        }
        if any_folded {
            passes.push(UniformPass::new(&folded, [1.0; 3], &self.planes));
        }
        let positional: Vec<PositionalLight> = lights
            .iter()
            .filter_map(|l| PositionalLight::new(l, scale))
            .collect();
        let (points, pixel_basis) = if positional.is_empty() {
            (None, None)
        } else {
            (Some(self.point_rows()?), Some(self.pixel_basis()))
        };
        let frame = Frame {
            simd: self.simd,
            planes: &self.planes,
            n: image.maps.pixels(),
            k,
            display,
            passes: &passes,
            lights: &positional,
            points,
            basis: pixel_basis,
            stream: passes.len() == 1
                && positional.is_empty()
                && 12 * roi.pixels() >= self.stream_from,
        };
        let positional = !positional.is_empty();
        let run = |p0: usize, dst: &mut [f32], scratch: &mut Scratch| frame.tile(p0, dst, scratch);
        out.width = roi.width;
        out.height = roi.height;
        // Every value is overwritten by the tiles: no need to clear a reused buffer.
        out.data.resize(3 * roi.pixels(), 0.0);
        if roi.x == 0 && roi.width == width {
            // Whole rows: one run of consecutive pixels, cut into tiles.
            let start = roi.y * width;
            out.data
                .par_chunks_mut(3 * TILE)
                .enumerate()
                .for_each(|(t, dst)| {
                    Scratch::with(k, positional, |scratch| run(start + t * TILE, dst, scratch))
                });
        } else {
            out.data
                .par_chunks_mut(3 * roi.width)
                .enumerate()
                .for_each(|(r, row)| {
                    let start = (roi.y + r) * width + roi.x;
                    Scratch::with(k, positional, |scratch| {
                        for (t, dst) in row.chunks_mut(3 * TILE).enumerate() {
                            run(start + t * TILE, dst, scratch);
                        }
                    })
                });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisSpec;
    use crate::camera::Projection;
    use crate::color;
    use crate::maps::{CoefficientMaps, Metadata};
    use crate::sphere::Vec3;

    fn one_pixel(coef: &[f32], space: MapSpace) -> RelightableImage {
        let mut maps = CoefficientMaps::zeros(1, 1, coef.len());
        for (i, &v) in coef.iter().enumerate() {
            for c in 0..3 {
                maps.plane_mut(i, c)[0] = v;
            }
        }
        RelightableImage {
            meta: Metadata::new(
                BasisSpec::named("sh:4").unwrap(),
                space,
                Projection::default(),
            ),
            maps,
            depth: None,
        }
    }

    #[test]
    fn lights_superpose_and_colours_scale() {
        let img = one_pixel(&[0.5, 0.1, 0.3, -0.2], MapSpace::Linear);
        let a = Light::directional([0.0, 1.0, 1.0], [1.0, 0.5, 0.0]);
        let b = Light::directional([1.0, 0.0, 0.2], [0.0, 0.5, 2.0]);
        let opts = RelightOptions::default();
        let ra = relight(&img, &LightRig::new(vec![a.clone()]), &opts).unwrap();
        let rb = relight(&img, &LightRig::new(vec![b.clone()]), &opts).unwrap();
        let both = relight(&img, &LightRig::new(vec![a, b]), &opts).unwrap();
        for c in 0..3 {
            assert!((both.data[c] - ra.data[c] - rb.data[c]).abs() < 1e-6);
        }
        // White light from the pole: Σ c_i Y_i(0,0,1).
        let sh = BasisSpec::named("sh:4").unwrap().build().unwrap();
        let y = sh.values(Vec3::new(0.0, 0.0, 1.0));
        let want = 0.5 * y[0] + 0.3 * y[2];
        let pole = relight(
            &img,
            &LightRig::new(vec![Light::directional([0.0, 0.0, 1.0], [1.0; 3])]),
            &opts,
        )
        .unwrap();
        assert!((pole.data[0] as f64 - want).abs() < 1e-6);
        let brighter = relight(
            &img,
            &LightRig::new(vec![Light::directional([0.0, 0.0, 1.0], [1.0; 3])]),
            &RelightOptions {
                exposure: 1.0,
                ..Default::default()
            },
        )
        .unwrap();
        assert!((brighter.data[0] - 2.0 * pole.data[0]).abs() < 1e-6);
    }

    #[test]
    fn display_maps_decode_each_light() {
        // Display value 0.5 from the constant term alone: Y_00 = 0.2821.
        let img = one_pixel(&[0.5 / 0.282_094_79, 0.0, 0.0, 0.0], MapSpace::Srgb);
        let rig = LightRig::new(vec![
            Light::directional([0.0, 0.0, 1.0], [1.0; 3]),
            Light::directional([1.0, 0.0, 0.0], [1.0; 3]),
        ]);
        let out = relight(&img, &rig, &RelightOptions::default()).unwrap();
        let want = 2.0 * color::srgb_to_linear(0.5);
        assert!(
            (out.data[0] - want).abs() < 1e-4,
            "{} vs {want}",
            out.data[0]
        );
    }

    /// A 6×4 image of pseudo-random 9-coefficient maps seen by a perspective camera,
    /// every pixel at depth 2.
    fn positioned_image() -> RelightableImage {
        let (w, h, k) = (6, 4, 9);
        let mut maps = CoefficientMaps::zeros(w, h, k);
        for (x, v) in maps.data.iter_mut().enumerate() {
            *v = if (x / (w * h)) < 3 {
                0.6
            } else {
                ((x * 7919 % 101) as f32 / 101.0 - 0.5) * 0.3
            };
        }
        let mut meta = Metadata::new(
            BasisSpec::named("sh:9").unwrap(),
            MapSpace::Linear,
            Projection::Planar {
                fov_y_deg: Some(50.0),
            },
        );
        meta.camera = Some(crate::camera::CameraSpec {
            projection: Projection::Planar {
                fov_y_deg: Some(50.0),
            },
            width: w,
            height: h,
            pose: Default::default(),
            orthographic_height: None,
        });
        RelightableImage {
            meta,
            maps,
            depth: Some(vec![2.0; w * h]),
        }
    }

    fn max_relative_difference(a: &ImageRgb, b: &ImageRgb) -> f64 {
        a.data
            .iter()
            .zip(&b.data)
            .map(|(x, y)| ((x - y).abs() / y.abs().max(1e-3)) as f64)
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_far_point_light_becomes_the_directional_light() {
        let img = positioned_image();
        let dir = Vec3::new(0.3, 0.5, 0.8).normalized().unwrap();
        let far = 1e5;
        let point = Light::Point(crate::light::PointLight {
            position: dir * far,
            color: [1.0; 3],
            intensity: far * far,
            attenuation: Default::default(),
        });
        let opts = RelightOptions::default();
        let a = relight(&img, &LightRig::new(vec![point]), &opts).unwrap();
        let b = relight(
            &img,
            &LightRig::new(vec![Light::directional(dir, [1.0; 3])]),
            &opts,
        )
        .unwrap();
        assert!(max_relative_difference(&a, &b) < 1e-3);
    }

    #[test]
    fn small_area_lights_and_wide_spots_become_point_lights() {
        let img = positioned_image();
        let s = Vec3::new(0.5, 1.0, -1.0);
        let opts = RelightOptions::default();
        let point = relight(&img, &LightRig::new(vec![Light::point(s, [1.0; 3])]), &opts).unwrap();
        // A disk of radius r facing every pixel roughly, radiance 1/(πr²): power of a unit point light.
        let r = 1e-3;
        let area = Light::Area(crate::light::AreaLight {
            shape: crate::light::AreaShape::Disk {
                center: s,
                normal: Vec3::new(-0.5, -1.0, -1.0),
                radius: r,
            },
            color: [1.0; 3],
            intensity: 1.0 / (std::f64::consts::PI * r * r),
            two_sided: true,
            samples: 4,
        });
        let a = relight(&img, &LightRig::new(vec![area]), &opts).unwrap();
        // A tiny disk is a point light whose intensity follows the emitter's cosine toward
        // each pixel's surface point: the ratio must be exactly that cosine.
        let points = Relighter::new(&img)
            .unwrap()
            .surface_points()
            .unwrap()
            .to_vec();
        let normal = Vec3::new(-0.5, -1.0, -1.0).normalized().unwrap();
        for (p, px) in points.iter().enumerate() {
            let cosine = (px.unwrap() - s).normalized().unwrap().dot(normal);
            for c in 0..3 {
                let ratio = (a.data[3 * p + c] / point.data[3 * p + c]) as f64;
                assert!(
                    (ratio - cosine).abs() < 2e-3,
                    "pixel {p}: {ratio} vs cos {cosine}"
                );
            }
        }
        let spot = Light::parse_spec("spot:0.5,1,-1/-0.3,-1,-1/89").unwrap();
        let sp = relight(&img, &LightRig::new(vec![spot]), &opts).unwrap();
        assert!(max_relative_difference(&sp, &point) < 1e-6);
    }

    #[test]
    fn positional_lights_without_depth_are_a_clear_error() {
        let mut img = positioned_image();
        img.depth = None;
        let err = relight(
            &img,
            &LightRig::new(vec![Light::point([0.0, 1.0, 0.0], [1.0; 3])]),
            &RelightOptions::default(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("depth"), "{err}");
    }
    /// A pseudo-random `w × h` image of `bands²`-coefficient SH maps (module below).
    fn random_image(w: usize, h: usize, bands: usize, space: MapSpace) -> RelightableImage {
        let spec = BasisSpec::named(&format!("sh:{}", bands * bands)).unwrap();
        random_image_of(w, h, spec, bands * bands, space)
    }

    /// A pseudo-random `w × h` image of `k`-coefficient maps of basis `spec` (bright
    /// first coefficient) seen by a perspective camera, depth 1.5–2.5, a few pixels
    /// without depth.
    fn random_image_of(
        w: usize,
        h: usize,
        spec: BasisSpec,
        k: usize,
        space: MapSpace,
    ) -> RelightableImage {
        let mut maps = CoefficientMaps::zeros(w, h, k);
        let n = w * h;
        let mut s = 0x2545_F491_4F6C_DD1Du64;
        for (x, v) in maps.data.iter_mut().enumerate() {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let r = (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
            *v = if x < 3 * n { 0.8 + 0.2 * r } else { 0.4 * r };
        }
        let projection = Projection::Planar {
            fov_y_deg: Some(60.0),
        };
        let mut meta = Metadata::new(spec, space, projection.clone());
        meta.camera = Some(crate::camera::CameraSpec {
            projection,
            width: w,
            height: h,
            pose: Default::default(),
            orthographic_height: None,
        });
        let depth = (0..n)
            .map(|p| {
                if p % 97 == 5 {
                    0.0
                } else {
                    2.0 + 0.5 * ((p * 7919 % 1000) as f32 / 1000.0 - 0.5)
                }
            })
            .collect();
        RelightableImage {
            meta,
            maps,
            depth: Some(depth),
        }
    }

    /// The relit frame computed the plain way: per pixel, in f64, from the values the
    /// relighter's storage holds, every light through `illuminate` (uniform weights as
    /// a dot product).
    fn reference(r: &Relighter, lights: &[PreparedLight], exposure: f64) -> ImageRgb {
        reference_within(r, lights, exposure, 0.0).0
    }

    /// [`reference`], and per pixel and channel the bound on what a weight table of
    /// largest weight error `eps` may change in it: Σ over the pixel's light vectors of
    /// |rgb| · Σ_i |c_i| · eps, times the largest slope of the sRGB decode (2.3) on
    /// display-referred maps.
    #[allow(clippy::needless_range_loop)]
    fn reference_within(
        r: &Relighter,
        lights: &[PreparedLight],
        exposure: f64,
        eps: f64,
    ) -> (ImageRgb, Vec<f64>) {
        let img = r.image;
        let (w, h) = (img.width(), img.height());
        let n = w * h;
        let k = r.basis.len();
        let display = img.meta.color_space == MapSpace::Srgb;
        let camera = r.camera().unwrap();
        let depth = img.depth.as_ref().unwrap();
        let scale = 2f64.powf(exposure);
        let decode = |v: f64| {
            if display {
                color::srgb_to_linear(v.clamp(0.0, 1.0) as f32) as f64
            } else {
                v
            }
        };
        let slope = if display { 2.3 } else { 1.0 };
        let mut out = ImageRgb::new(w, h);
        let mut bound = vec![0.0; 3 * n];
        for p in 0..n {
            let coef: Vec<f64> = (0..3 * k).map(|j| r.planes.value(j, p, n) as f64).collect();
            let dot = |c: usize, y: &[f64]| (0..k).map(|i| coef[3 * i + c] * y[i]).sum::<f64>();
            let l1: [f64; 3] =
                std::array::from_fn(|c| (0..k).map(|i| coef[3 * i + c].abs()).sum::<f64>());
            let mut sum = [0.0f64; 3];
            let d = depth[p];
            let surface = (d > 0.0).then(|| camera.position(p % w, p / w, d as f64));
            for light in lights {
                if let PreparedLight::Weights(wt) = light {
                    for c in 0..3 {
                        sum[c] += decode(dot(c, &wt[c]));
                    }
                    continue;
                }
                let Some(surface) =
                    surface.or(light.is_uniform().then_some(Vec3::new(0.0, 0.0, 0.0)))
                else {
                    continue;
                };
                light.illuminate(surface, p, &mut |l, rgb| {
                    let y = r.basis.values(l);
                    for c in 0..3 {
                        sum[c] += rgb[c] * decode(dot(c, &y));
                        if !light.is_uniform() {
                            bound[3 * p + c] += rgb[c].abs() * l1[c] * eps * slope * scale;
                        }
                    }
                });
            }
            for c in 0..3 {
                out.data[3 * p + c] = (sum[c] * scale) as f32;
            }
        }
        (out, bound)
    }

    fn max_abs(a: &ImageRgb, b: &ImageRgb) -> (f64, f64) {
        assert_eq!((a.width, a.height), (b.width, b.height));
        let diff = a
            .data
            .iter()
            .zip(&b.data)
            .map(|(x, y)| (x - y).abs() as f64)
            .fold(0.0, f64::max);
        let peak = b.data.iter().map(|v| v.abs() as f64).fold(0.0, f64::max);
        (diff, peak)
    }

    fn rig_lights(r: &Relighter) -> Vec<(&'static str, Vec<PreparedLight>)> {
        let k = r.basis.len();
        let prep = |l: Light| l.prepare(std::path::Path::new("")).unwrap();
        let weights: [Vec<f64>; 3] = std::array::from_fn(|c| {
            (0..k)
                .map(|i| (0.3 + 0.1 * c as f64) / (1.0 + i as f64))
                .collect()
        });
        let spot = Light::Spot(crate::light::SpotLight {
            position: Vec3::new(0.2, 0.5, 0.3),
            direction: Vec3::new(0.0, -0.3, -1.0),
            cone_deg: 25.0,
            softness_deg: 8.0,
            color: [1.0, 0.7, 0.5],
            intensity: 3.0,
            attenuation: Default::default(),
        });
        let hard_spot = Light::Spot(crate::light::SpotLight {
            softness_deg: 0.0,
            attenuation: crate::light::Attenuation::InverseDistance(0.7),
            ..match &spot {
                Light::Spot(s) => s.clone(),
                _ => unreachable!(),
            }
        });
        let area = Light::Area(crate::light::AreaLight {
            shape: crate::light::AreaShape::Disk {
                center: Vec3::new(-0.5, 0.8, 0.0),
                normal: Vec3::new(0.5, -0.8, -1.0),
                radius: 0.3,
            },
            color: [0.9, 1.0, 0.8],
            intensity: 2.0,
            two_sided: false,
            samples: 4,
        });
        let area_light = |shape, two_sided, samples| {
            prep(Light::Area(crate::light::AreaLight {
                shape,
                color: [1.0, 0.8, 0.9],
                intensity: 1.5,
                two_sided,
                samples,
            }))
        };
        // Facing down and a little toward the camera: the pixels high in the image lie
        // behind it (one-sided: dark there).
        let rect = crate::light::AreaShape::Rect {
            center: Vec3::new(0.3, 0.9, -0.5),
            u: Vec3::new(0.4, 0.0, 0.0),
            v: Vec3::new(0.0, 0.1, 0.3),
        };
        // Amid the surface points, edge-on to some of them.
        let disk = crate::light::AreaShape::Disk {
            center: Vec3::new(0.2, -0.3, -1.0),
            normal: Vec3::new(0.0, 1.0, 0.3),
            radius: 0.4,
        };
        // A slide of 13 × 7 texels (odd sizes, distinct colours) and two projectors
        // whose frusta cover parts of the image.
        let mut slide = ImageRgb::new(13, 7);
        for (i, v) in slide.data.iter_mut().enumerate() {
            *v = 0.1 + (i * 37 % 29) as f32 / 29.0;
        }
        let slide = Arc::new(slide);
        let projector = |position: Vec3, direction: Vec3, up: Vec3, fov_deg, attenuation| {
            let light = crate::light::ProjectorLight {
                position,
                direction,
                up,
                fov_deg,
                slide: String::new(),
                color: [0.9, 1.0, 0.7],
                intensity: 2.0,
                attenuation,
            };
            let rgb = Light::Projector(light.clone()).rgb();
            PreparedLight::Projector(Box::new(light.with_slide(slide.clone())), rgb)
        };
        vec![
            (
                "directional",
                vec![
                    prep(Light::directional([-0.4, 0.7, 0.6], [1.0, 0.9, 0.8])),
                    prep(Light::directional([0.5, 0.1, 0.9], [0.2, 0.3, 0.5])),
                ],
            ),
            ("environment", vec![PreparedLight::Weights(weights)]),
            (
                "point",
                vec![prep(Light::point([0.3, 0.5, 0.2], [1.0, 0.9, 0.8]))],
            ),
            ("spot", vec![prep(spot), prep(hard_spot)]),
            ("area disk one-sided", vec![prep(area)]),
            (
                "area rect one-sided",
                vec![area_light(rect.clone(), false, 5)],
            ),
            ("area rect two-sided", vec![area_light(rect, true, 16)]),
            (
                "area disk two-sided",
                vec![
                    area_light(disk.clone(), true, 7),
                    area_light(disk, false, 1),
                ],
            ),
            (
                "projector",
                vec![
                    projector(
                        Vec3::new(0.1, 0.2, 0.3),
                        Vec3::new(0.1, -0.1, -1.0),
                        Vec3::new(0.0, 1.0, 0.0),
                        30.0,
                        Default::default(),
                    ),
                    projector(
                        Vec3::new(-0.4, -0.1, 0.0),
                        Vec3::new(-0.2, 0.1, -1.0),
                        Vec3::new(0.3, 1.0, 0.0),
                        45.0,
                        crate::light::Attenuation::InverseDistance(0.6),
                    ),
                ],
            ),
            (
                "mixed",
                vec![
                    prep(Light::directional([0.0, 1.0, 0.2], [0.5; 3])),
                    prep(Light::point([-0.3, 0.2, 0.5], [0.4, 0.5, 0.6])),
                ],
            ),
        ]
    }

    /// Every storage type, the AVX2 and the portable kernels (and streaming stores),
    /// every light type (area lights: rectangles and disks, one- and two-sided, square
    /// and ragged strata; projectors), linear and display-referred maps: equal to the
    /// per-pixel f64 reference within f32 rounding (1e-5 of the peak; the f32 light
    /// vectors and SH recurrence of positional lights 1e-4). 211 × 97 pixels: two
    /// tiles, the second partial, and a partial last run and block.
    #[test]
    fn every_storage_and_kernel_equals_the_reference() {
        const { assert!(TILE < 211 * 97 && 211 * 97 < 2 * TILE) };
        for space in [MapSpace::Linear, MapSpace::Srgb] {
            for bands in [3, 4, 5] {
                let img = random_image(211, 97, bands, space);
                for storage in Precision::ALL {
                    for mode in ["detected", "portable", "streaming"] {
                        let mut r = Relighter::with_precision(&img, storage).unwrap();
                        match mode {
                            "portable" => r = r.baseline(),
                            "streaming" => r = r.streaming(),
                            _ => {}
                        }
                        for (name, lights) in rig_lights(&r) {
                            let got = r.relight_prepared(&lights, 0.5).unwrap();
                            let want = reference(&r, &lights, 0.5);
                            let (diff, peak) = max_abs(&got, &want);
                            let tol = if name == "directional" || name == "environment" {
                                1e-5
                            } else {
                                1e-4
                            };
                            assert!(
                                peak > 0.0 && diff <= tol * peak,
                                "{space:?} bands {bands} {storage:?} {} {mode} {name}: {diff} vs peak {peak}",
                                r.kernels()
                            );
                        }
                    }
                }
            }
        }
    }

    /// f16 and 8-bit planes relight within their quantisation step of the f32 frame.
    #[test]
    fn compact_storage_stays_close_to_f32() {
        let img = random_image(64, 40, 4, MapSpace::Linear);
        let f32_engine = Relighter::new(&img).unwrap();
        let lights = vec![Light::directional([-0.4, 0.7, 0.6], [1.0; 3])
            .prepare(std::path::Path::new(""))
            .unwrap()];
        let want = f32_engine.relight_prepared(&lights, 0.0).unwrap();
        for (storage, tol) in [(Precision::F16, 2e-3), (Precision::U8, 2e-2)] {
            let r = Relighter::with_precision(&img, storage).unwrap();
            assert_eq!(r.precision(), storage);
            let (diff, peak) = max_abs(&r.relight_prepared(&lights, 0.0).unwrap(), &want);
            assert!(diff <= tol * peak, "{storage:?}: {diff} vs {peak}");
        }
    }

    /// A region relights to exactly the crop of the full frame, for every light type and
    /// storage (full rows, narrow windows, single pixels, the last pixel).
    #[test]
    fn a_region_equals_the_crop_of_the_full_frame() {
        let img = random_image(97, 53, 4, MapSpace::Linear);
        for storage in Precision::ALL {
            let r = Relighter::with_precision(&img, storage).unwrap();
            for (name, lights) in rig_lights(&r) {
                let full = r.relight_prepared(&lights, 0.0).unwrap();
                for roi in [
                    Roi::full(97, 53),
                    Roi {
                        x: 0,
                        y: 10,
                        width: 97,
                        height: 7,
                    },
                    Roi {
                        x: 13,
                        y: 5,
                        width: 40,
                        height: 30,
                    },
                    Roi {
                        x: 1,
                        y: 1,
                        width: 70,
                        height: 1,
                    },
                    Roi {
                        x: 96,
                        y: 52,
                        width: 1,
                        height: 1,
                    },
                ] {
                    let part = r.relight_prepared_roi(&lights, 0.0, roi).unwrap();
                    assert_eq!((part.width, part.height), (roi.width, roi.height));
                    assert_eq!(part, roi.crop(&full), "{storage:?} {name} {roi:?}");
                }
            }
        }
        let r = Relighter::new(&img).unwrap();
        let bad = Roi {
            x: 90,
            y: 0,
            width: 10,
            height: 1,
        };
        assert!(r.relight_prepared_roi(&[], 0.0, bad).is_err());
        assert_eq!(
            Roi::parse("1, 2,3,4").unwrap(),
            Roi {
                x: 1,
                y: 2,
                width: 3,
                height: 4
            }
        );
        assert!(Roi::parse("1,2,3").is_err());
    }
    /// `series` pixel series at the captured directions `dirs`: mixtures of eight fixed
    /// lobes with weights varying by series, as a capture's pixels would be.
    fn capture_samples(dirs: &[Vec3], series: usize) -> Vec<f32> {
        let lobes = crate::sphere::fibonacci(8);
        let mut out = Vec::with_capacity(series * dirs.len());
        for s in 0..series {
            for d in dirs {
                let v: f64 = lobes
                    .iter()
                    .enumerate()
                    .map(|(i, l)| {
                        let w = 1.0 + ((s * 8 + i) * 7919 % 1000) as f64 / 1000.0;
                        w * (4.0 * (d.dot(*l) - 1.0)).exp()
                    })
                    .sum();
                out.push(v as f32);
            }
        }
        out
    }

    /// Every registered family at a size near 16 (rbf and bilinear built from a
    /// synthetic capture).
    fn every_family() -> Vec<Box<dyn crate::basis::Basis>> {
        use crate::basis::{BasisChoice, Samples, FAMILIES};
        let dirs = crate::sphere::hemisphere_fibonacci(48);
        let values = capture_samples(&dirs, 200);
        let samples = Samples {
            values: &values,
            n: dirs.len(),
        };
        let mut out: Vec<Box<dyn crate::basis::Basis>> = FAMILIES
            .iter()
            .filter_map(|family| {
                let sizes = family.sizes(64);
                let k = sizes.iter().copied().min_by_key(|&k| k.abs_diff(16))?;
                let choice = BasisChoice::parse(&format!("{}:{k}", family.name())).unwrap();
                Some(choice.build(&dirs, Some(samples)).unwrap())
            })
            .collect();
        // The bilinear family's other grid (the default one is octahedral).
        out.push(
            BasisChoice::parse("bilinear:16:map=square")
                .unwrap()
                .build(&dirs, Some(samples))
                .unwrap(),
        );
        // The family that compression makes rather than fits: combinations of a
        // table-driven and of a recurrence basis.
        for inner in ["rbf:16", "sh:16"] {
            let inner = BasisChoice::parse(inner)
                .unwrap()
                .build(&dirs, Some(samples))
                .unwrap();
            let matrix = (0..9 * 16)
                .map(|i| ((i * 37 % 11) as f64 - 5.0) / 7.0)
                .collect();
            out.push(Box::new(
                crate::basis::Projected::new(inner, matrix).unwrap(),
            ));
        }
        out
    }

    /// Every registered family, every light type, linear and display-referred maps: the
    /// engine's frame equals the per-pixel reference with `basis.eval` itself, within
    /// what the basis' half-float weight table may cost per pixel (`reference_within`,
    /// with the table's largest error measured on 4096 directions, doubled for the
    /// directions between them) plus f32 rounding (1e-4 of the peak). A basis with an
    /// exact kernel of its own (SH and HSH: their recurrence) has no table, a bound of 0.
    #[test]
    fn every_basis_relights_every_light_like_its_reference() {
        for basis in every_family() {
            let name = basis.name();
            for space in [MapSpace::Linear, MapSpace::Srgb] {
                let img = random_image_of(73, 45, basis.spec(), basis.len(), space);
                let r = Relighter::new(&img).unwrap();
                let eps = match r.pixel_basis().table_accuracy() {
                    None => 0.0,
                    Some(accuracy) => {
                        let peak = crate::sphere::fibonacci(4096)
                            .into_iter()
                            .flat_map(|d| basis.values(d))
                            .fold(0f64, |m, v| m.max(v.abs()));
                        2.0 * accuracy.relative_max * peak
                    }
                };
                let exact = PixelBasis::evaluates_exactly(basis.as_ref());
                assert_eq!(eps == 0.0, exact, "{name}");
                if basis.planar_grid().is_some() {
                    // Its own grid: the basis up to half-float rounding (2⁻¹¹ relative).
                    assert_eq!(r.pixel_path(), "planar grid", "{name}");
                    let accuracy = r.pixel_basis().table_accuracy().expect("a grid");
                    assert!(accuracy.relative_max < 1e-3, "{name}: {accuracy:?}");
                }
                let mut worst = 0f64;
                for (light, lights) in rig_lights(&r) {
                    let got = r.relight_prepared(&lights, 0.5).unwrap();
                    let (want, bound) = reference_within(&r, &lights, 0.5, eps);
                    let (_, peak) = max_abs(&got, &want);
                    assert!(peak > 0.0, "{name} {space:?} {light}: a black frame");
                    for ((g, w), b) in got.data.iter().zip(&want.data).zip(&bound) {
                        let err = (g - w).abs() as f64;
                        let allowed = b + 1e-4 * peak;
                        worst = worst.max(err / allowed);
                        assert!(
                            err <= allowed,
                            "{name} {space:?} {light}: {g} vs {w} (allowed {allowed:e})"
                        );
                    }
                }
                eprintln!(
                    "{name} {space:?} ({}): at most {:.0} % of the bound",
                    r.pixel_path(),
                    100.0 * worst
                );
            }
        }
    }

    /// A fresh directory holding `sky.exr`: a 64×32 lat-long map of radiance
    /// `sky(row fraction, channel)` with a 3×3-texel sun of radiance `sun`.
    fn sky_in(tag: &str, sun: f32, sky: impl Fn(f32, usize) -> f32) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("relit-engine-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (w, h) = (64, 32);
        let mut map = ImageRgb::new(w, h);
        for (i, v) in map.data.iter_mut().enumerate() {
            let (x, y) = ((i / 3) % w, (i / 3) / w);
            let in_sun = (x as i64 - 20).abs() <= 1 && (y as i64 - 9).abs() <= 1;
            *v = if in_sun {
                sun
            } else {
                sky(y as f32 / h as f32, i % 3)
            };
        }
        crate::image::save(&dir.join("sky.exr"), &map, 0.0).unwrap();
        dir
    }

    /// An environment light on a basis without bands is the sum of directional lights
    /// over the map's quadrature, their directions turned by the light's rotation and
    /// their intensities times its colour; band windows are refused there (and taken on
    /// SH).
    #[test]
    fn environments_on_other_bases_are_their_quadrature() {
        use crate::envmap::{environment_quadrature, QUADRATURE_HEIGHT, QUADRATURE_WIDTH};
        let dir = sky_in("env", 8.0, |up, c| 0.2 + 0.3 * up + 0.1 * c as f32);
        let light: crate::light::EnvironmentMapLight = serde_json::from_str(
            r#"{ "map": "sky.exr", "yaw_deg": 40, "pitch_deg": -15, "roll_deg": 10, "color": [1, 0.8, 0.6], "intensity": 0.7 }"#,
        )
        .unwrap();
        let rotation = light.rotation().unwrap();
        let rgb = Light::Environment(light.clone()).rgb();
        let basis = BasisSpec::named("hsh:16").unwrap();
        let img = random_image_of(37, 23, basis, 16, MapSpace::Linear);
        let r = Relighter::new(&img).unwrap();
        let options = RelightOptions {
            exposure: 0.0,
            resource_dir: dir.clone(),
        };
        let got = r
            .relight(
                &LightRig::new(vec![Light::Environment(light.clone())]),
                &options,
            )
            .unwrap();
        let map = crate::image::load_linear(&dir.join("sky.exr"), None).unwrap();
        let directional: Vec<PreparedLight> =
            environment_quadrature(&map, QUADRATURE_WIDTH, QUADRATURE_HEIGHT)
                .into_iter()
                .map(|(d, i)| PreparedLight::Directional {
                    direction: crate::basis::mat3_apply(&rotation, d),
                    rgb: std::array::from_fn(|c| i[c] * rgb[c]),
                })
                .collect();
        let want = r.relight_prepared(&directional, 0.0).unwrap();
        let (diff, peak) = max_abs(&got, &want);
        assert!(peak > 0.0 && diff <= 1e-5 * peak, "{diff} vs peak {peak}");
        let hann = crate::light::EnvironmentMapLight {
            window: crate::envmap::Window::Hann,
            ..light
        };
        let err = r.environment_weights(&hann, &dir).unwrap_err().to_string();
        assert!(err.contains("window") && err.contains("hsh:16"), "{err}");
        let sh = random_image(37, 23, 4, MapSpace::Linear);
        assert!(Relighter::new(&sh)
            .unwrap()
            .environment_weights(&hann, &dir)
            .is_ok());
        std::fs::remove_dir_all(&dir).ok();
    }

    /// On display-referred maps an environment is its median-cut lights, each decoded on
    /// its own: the frame equals those directional lights', and differs from folding
    /// the map into one weight vector (which decodes the sum of display values).
    #[test]
    fn environments_on_display_maps_are_their_median_cut_lights() {
        use crate::envmap::{environment_quadrature, median_cut};
        let dir = sky_in("envd", 4.0, |up, _| 0.02 + 0.03 * up);
        let light: crate::light::EnvironmentMapLight = serde_json::from_str(
            r#"{ "map": "sky.exr", "yaw_deg": 40, "pitch_deg": -15, "intensity": 0.2 }"#,
        )
        .unwrap();
        let rotation = light.rotation().unwrap();
        let img = random_image(37, 23, 3, MapSpace::Srgb);
        let r = Relighter::new(&img).unwrap();
        let options = RelightOptions {
            exposure: 0.0,
            resource_dir: dir.clone(),
        };
        let rig = LightRig::new(vec![Light::Environment(light.clone())]);
        let got = r.relight(&rig, &options).unwrap();
        let map = crate::image::load_linear(&dir.join("sky.exr"), None).unwrap();
        let lumps = median_cut(
            &environment_quadrature(&map, 128, 64),
            DISPLAY_ENVIRONMENT_LIGHTS,
        );
        assert_eq!(lumps.len(), DISPLAY_ENVIRONMENT_LIGHTS);
        let directional: Vec<PreparedLight> = lumps
            .iter()
            .map(|(d, i)| PreparedLight::Directional {
                direction: crate::basis::mat3_apply(&rotation, *d),
                rgb: i.map(|v| v * 0.2),
            })
            .collect();
        let want = r.relight_prepared(&directional, 0.0).unwrap();
        let (diff, peak) = max_abs(&got, &want);
        assert!(peak > 0.0 && diff <= 1e-5 * peak, "{diff} vs peak {peak}");
        let folded = r
            .relight_prepared(
                &[PreparedLight::Weights(
                    r.environment_weights(&light, &dir).unwrap(),
                )],
                0.0,
            )
            .unwrap();
        let (apart, _) = max_abs(&got, &folded);
        assert!(apart > 1e-2 * peak, "{apart} vs peak {peak}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn the_fma_probe_runs() {
        assert!(fma_throughput(0.01) > 1e6);
    }
}
