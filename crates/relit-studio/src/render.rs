//! Rendering from a fixed viewpoint: trace what the camera sees once, light it many times.
//!
//! [`Renderer::new`] traces the primary rays into a G-buffer (per sample: the surface
//! point, its normals, the direction to the eye and the reflectance with its texture
//! already looked up), the depth map and the mask; with one-bounce indirect light it
//! also traces the bounce rays once and keeps the surfaces they hit. Lighting the
//! buffer under an emitter ([`Renderer::render`]) then costs only shadow rays. Capture
//! images and ground truth come from this one function, so for the same light they
//! are identical, sample for sample.
//!
//! Everything is deterministic: sample positions are fixed, bounce directions come
//! from a stratified pattern rotated by a hash of the pixel, and rows are rendered in
//! parallel into fixed places.

use crate::emitter::{Emitter, Illuminant};
use crate::material::Reflectance;
use crate::math::{v3, V3};
use crate::scene::Scene;
use crate::texture::hash2;
use crate::{invalid, Result};
use rayon::prelude::*;
use relit::camera::Camera;
use relit::image::ImageRgb;
use relit::progress::Progress;
use relit::sphere::Vec3;
use std::time::Instant;

/// How a [`Renderer`] samples the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderOptions {
    /// Samples per pixel along each axis (1 = one ray through the centre; 2 = 2×2 …).
    pub supersample: u32,
    /// Bounce rays per sample for one-bounce diffuse indirect light (0 = direct only).
    pub indirect_samples: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            supersample: 1,
            indirect_samples: 0,
        }
    }
}

impl RenderOptions {
    /// Check the options.
    pub fn validate(&self) -> Result<()> {
        if !(1..=8).contains(&self.supersample) {
            return Err(invalid(format!(
                "supersampling must be 1 to 8 per axis, not {}",
                self.supersample
            )));
        }
        if self.indirect_samples > 256 {
            return Err(invalid(format!(
                "at most 256 indirect samples, not {}",
                self.indirect_samples
            )));
        }
        Ok(())
    }
}

/// A visible surface sample of the G-buffer.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sample {
    /// The surface point, moved off the surface toward the eye by the ray epsilon.
    pub(crate) origin: V3,
    pub(crate) geometric_normal: V3,
    pub(crate) shading_normal: V3,
    /// Unit direction toward the eye.
    pub(crate) to_eye: V3,
    pub(crate) reflectance: Reflectance,
}

/// A surface seen by a bounce ray (diffuse only).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bounce {
    pub(crate) origin: V3,
    pub(crate) geometric_normal: V3,
    pub(crate) shading_normal: V3,
    pub(crate) albedo: V3,
}

/// A G-buffer of one scene from one camera, ready to be lit.
pub struct Renderer<'s> {
    scene: &'s Scene,
    camera: Camera,
    samples_per_pixel: usize,
    bounces_per_sample: usize,
    /// `pixels × samples_per_pixel` slots, `None` where the ray escaped.
    samples: Vec<Option<Sample>>,
    /// `samples.len() × bounces_per_sample` slots.
    bounces: Vec<Option<Bounce>>,
    depth: Vec<f32>,
    mask: Vec<f32>,
    primary_rays: u64,
    seconds: f64,
}

/// One lit image and what it cost.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub image: ImageRgb,
    /// Shadow rays traced.
    pub rays: u64,
}

impl<'s> Renderer<'s> {
    /// Trace the G-buffer of `scene` seen by `camera`.
    pub fn new(
        scene: &'s Scene,
        camera: &Camera,
        options: &RenderOptions,
        progress: &dyn Progress,
    ) -> Result<Renderer<'s>> {
        options.validate()?;
        let start = Instant::now();
        let (w, h) = (camera.width(), camera.height());
        let s = options.supersample as usize;
        let k = options.indirect_samples as usize;
        let epsilon = scene.ray_epsilon();
        progress.begin("primary rays", h as u64);
        struct Row {
            samples: Vec<Option<Sample>>,
            bounces: Vec<Option<Bounce>>,
            depth: Vec<f32>,
            rays: u64,
        }
        let rows: Vec<Row> = (0..h)
            .into_par_iter()
            .map(|y| {
                let mut row = Row {
                    samples: Vec::with_capacity(w * s * s),
                    bounces: Vec::with_capacity(w * s * s * k),
                    depth: Vec::with_capacity(w),
                    rays: 0,
                };
                for x in 0..w {
                    // The centre ray gives depth and mask; with one sample it is the sample.
                    let centre =
                        trace_primary(scene, camera, x as f64 + 0.5, y as f64 + 0.5, epsilon);
                    row.rays += 1;
                    row.depth.push(centre.map_or(0.0, |(_, t)| t));
                    for sy in 0..s {
                        for sx in 0..s {
                            let sample = if s == 1 {
                                centre.map(|(sample, _)| sample)
                            } else {
                                row.rays += 1;
                                let (fx, fy) =
                                    ((sx as f64 + 0.5) / s as f64, (sy as f64 + 0.5) / s as f64);
                                trace_primary(scene, camera, x as f64 + fx, y as f64 + fy, epsilon)
                                    .map(|(sample, _)| sample)
                            };
                            let seed = ((y * w + x) * s * s + sy * s + sx) as u32;
                            for b in 0..k {
                                let bounce = sample
                                    .and_then(|smp| trace_bounce(scene, &smp, seed, b, k, epsilon));
                                row.rays += sample.is_some() as u64;
                                row.bounces.push(bounce);
                            }
                            row.samples.push(sample);
                        }
                    }
                }
                progress.advance(1);
                row
            })
            .collect();
        progress.end();
        let mut renderer = Renderer {
            scene,
            camera: camera.clone(),
            samples_per_pixel: s * s,
            bounces_per_sample: k,
            samples: Vec::with_capacity(w * h * s * s),
            bounces: Vec::with_capacity(w * h * s * s * k),
            depth: Vec::with_capacity(w * h),
            mask: Vec::new(),
            primary_rays: 0,
            seconds: 0.0,
        };
        for row in rows {
            renderer.samples.extend(row.samples);
            renderer.bounces.extend(row.bounces);
            renderer.depth.extend(row.depth);
            renderer.primary_rays += row.rays;
        }
        renderer.mask = renderer
            .depth
            .iter()
            .map(|&d| if d > 0.0 { 1.0 } else { 0.0 })
            .collect();
        renderer.seconds = start.elapsed().as_secs_f64();
        Ok(renderer)
    }

    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    pub fn scene(&self) -> &Scene {
        self.scene
    }

    /// Distance from the ray origin along each pixel's centre ray (row-major); 0 where
    /// nothing was hit.
    pub fn depth(&self) -> &[f32] {
        &self.depth
    }

    /// 1 where the centre ray hit geometry, 0 elsewhere.
    pub fn mask(&self) -> &[f32] {
        &self.mask
    }

    /// Rays traced to fill the G-buffer (primary and bounce rays).
    pub fn primary_rays(&self) -> u64 {
        self.primary_rays
    }

    /// Camera samples per pixel (supersampling).
    pub(crate) fn samples_per_pixel(&self) -> usize {
        self.samples_per_pixel
    }

    /// The G-buffer samples of `pixel` and, per sample, its bounce slots.
    pub(crate) fn pixel_samples(
        &self,
        pixel: usize,
    ) -> impl Iterator<Item = (Option<&Sample>, &[Option<Bounce>])> {
        let (spp, k) = (self.samples_per_pixel, self.bounces_per_sample);
        (pixel * spp..(pixel + 1) * spp)
            .map(move |i| (self.samples[i].as_ref(), &self.bounces[i * k..(i + 1) * k]))
    }

    /// Seconds spent filling the G-buffer.
    pub fn gbuffer_seconds(&self) -> f64 {
        self.seconds
    }

    /// The image under `emitters` together (linear radiance).
    pub fn render(&self, emitters: &[Emitter]) -> Rendered {
        let (w, h) = (self.camera.width(), self.camera.height());
        let mut image = ImageRgb::new(w, h);
        let spp = self.samples_per_pixel;
        let weight = 1.0 / spp as f32;
        let rays: u64 = image
            .data
            .par_chunks_mut(3 * w)
            .enumerate()
            .map(|(y, row)| {
                let mut rays = 0u64;
                for x in 0..w {
                    let first = (y * w + x) * spp;
                    let mut sum = V3::ZERO;
                    for idx in first..first + spp {
                        if let Some(sample) = &self.samples[idx] {
                            sum += self.shade(sample, idx, emitters, &mut rays);
                        }
                    }
                    let value = sum * weight;
                    row[3 * x..3 * x + 3].copy_from_slice(&value.to_array());
                }
                rays
            })
            .sum();
        Rendered { image, rays }
    }

    /// The image under one white directional light toward `direction` (a capture image).
    pub fn render_directional(&self, direction: Vec3) -> Result<Rendered> {
        Ok(self.render(&[Emitter::directional(direction, [1.0; 3])?]))
    }

    /// Per pixel, the fraction of `emitter`'s light samples whose visibility the capture
    /// gets wrong: the ray toward the light is blocked somewhere (so the pixel's captured
    /// function, which knows only directions, records a shadow) but the segment up to
    /// the light is clear (so the light really reaches the point) — an occluder
    /// *behind* the light, seed 004 §VI's limitation seen from the other side. Pixels
    /// without geometry, and samples arriving from behind the surface, count as right.
    pub fn visibility_mismatch(&self, emitter: &Emitter) -> Vec<f32> {
        let spp = self.samples_per_pixel;
        (0..self.depth.len())
            .into_par_iter()
            .map(|pixel| {
                let Some(sample) = &self.samples[pixel * spp] else {
                    return 0.0;
                };
                let (mut total, mut wrong) = (0u32, 0u32);
                emitter.illuminate(sample.origin, pixel, &mut |incident| {
                    if sample.geometric_normal.dot(incident.direction) <= 0.0
                        || !incident.distance.is_finite()
                    {
                        return;
                    }
                    total += 1;
                    let towards =
                        self.scene
                            .occluded(sample.origin, incident.direction, f32::INFINITY);
                    if towards
                        && !self.scene.occluded(
                            sample.origin,
                            incident.direction,
                            incident.distance,
                        )
                    {
                        wrong += 1;
                    }
                });
                if total == 0 {
                    0.0
                } else {
                    wrong as f32 / total as f32
                }
            })
            .collect()
    }

    /// Direct light on one sample plus its one-bounce indirect light.
    fn shade(&self, sample: &Sample, index: usize, emitters: &[Emitter], rays: &mut u64) -> V3 {
        let pixel = index / self.samples_per_pixel;
        let mut direct = V3::ZERO;
        for emitter in emitters {
            emitter.illuminate(sample.origin, pixel, &mut |incident| {
                // Light from behind the geometric surface never reaches the side we see.
                if sample.geometric_normal.dot(incident.direction) <= 0.0 {
                    return;
                }
                let f = sample.reflectance.reflect(
                    sample.shading_normal,
                    sample.to_eye,
                    incident.direction,
                );
                if f.max_component() <= 0.0 || incident.irradiance.max_component() <= 0.0 {
                    return;
                }
                *rays += 1;
                if !self
                    .scene
                    .occluded(sample.origin, incident.direction, incident.distance)
                {
                    direct += f.modulate(incident.irradiance);
                }
            });
        }
        let k = self.bounces_per_sample;
        if k == 0 {
            return direct;
        }
        // Cosine-weighted bounce directions: the diffuse reflection of the bounced
        // radiance is the albedo times its plain average (see `material`'s units).
        let mut gathered = V3::ZERO;
        for bounce in self.bounces[index * k..(index + 1) * k].iter().flatten() {
            for emitter in emitters {
                emitter.illuminate(bounce.origin, pixel, &mut |incident| {
                    let cos = bounce.shading_normal.dot(incident.direction);
                    if bounce.geometric_normal.dot(incident.direction) <= 0.0 || cos <= 0.0 {
                        return;
                    }
                    *rays += 1;
                    if !self
                        .scene
                        .occluded(bounce.origin, incident.direction, incident.distance)
                    {
                        gathered += bounce.albedo.modulate(incident.irradiance) * cos;
                    }
                });
            }
        }
        direct + sample.reflectance.albedo.modulate(gathered) * (1.0 / k as f32)
    }
}

/// The G-buffer sample and depth of the camera ray through `(x, y)`.
fn trace_primary(
    scene: &Scene,
    camera: &Camera,
    x: f64,
    y: f64,
    epsilon: f32,
) -> Option<(Sample, f32)> {
    let ray = camera.ray(x, y);
    let (origin, direction) = (V3::from(ray.origin), V3::from(ray.direction).normalized());
    let hit = scene.intersect(origin, direction, f32::INFINITY)?;
    let sample = Sample {
        origin: hit.position + hit.geometric_normal * epsilon,
        geometric_normal: hit.geometric_normal,
        shading_normal: hit.shading_normal,
        to_eye: -direction,
        reflectance: hit.reflectance,
    };
    Some((sample, hit.t))
}

/// Bounce ray `b` of `k` from `sample`: cosine-weighted about the shading normal,
/// stratified in the first coordinate and rotated per sample by a hash.
fn trace_bounce(
    scene: &Scene,
    sample: &Sample,
    seed: u32,
    b: usize,
    k: usize,
    epsilon: f32,
) -> Option<Bounce> {
    let u1 = ((b as f32 + hash2(seed as i32, 2 * b as i32 + 1)) / k as f32).min(0.999_999);
    let u2 = (hash2(seed as i32, -1) + b as f32 * 0.618_034).fract();
    let direction = cosine_direction(sample.shading_normal, u1, u2);
    if sample.geometric_normal.dot(direction) <= 0.0 {
        return None;
    }
    let hit = scene.intersect(sample.origin, direction, f32::INFINITY)?;
    Some(Bounce {
        origin: hit.position + hit.geometric_normal * epsilon,
        geometric_normal: hit.geometric_normal,
        shading_normal: hit.shading_normal,
        albedo: hit.reflectance.albedo,
    })
}

/// Two unit vectors completing the unit vector `n` to an orthonormal frame.
pub(crate) fn tangent_frame(n: V3) -> (V3, V3) {
    let helper = if n.x.abs() < 0.9 {
        v3(1.0, 0.0, 0.0)
    } else {
        v3(0.0, 1.0, 0.0)
    };
    let t = helper.cross(n).normalized();
    (t, n.cross(t))
}

/// The direction about the unit normal `n` that `(u1, u2) ∈ [0, 1)²` maps to with
/// density `cos θ / π` (Malley's method: a uniform disc point lifted to the hemisphere).
pub(crate) fn cosine_direction(n: V3, u1: f32, u2: f32) -> V3 {
    cosine_direction_in(n, tangent_frame(n), u1, u2)
}

/// [`cosine_direction`] with `n`'s [`tangent_frame`] already at hand.
pub(crate) fn cosine_direction_in(n: V3, (t, bt): (V3, V3), u1: f32, u2: f32) -> V3 {
    let (r, phi) = (u1.sqrt(), std::f32::consts::TAU * u2);
    (t * (r * phi.cos()) + bt * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalized()
}
