//! Fidelity of every light type against ray-traced truth: capture a scene, fit it,
//! then for each light of a rig render the truth with the studio and the relit image
//! with the engine, and compare (`relit eval --scene`).
//!
//! Two things are measured apart, because they are properties of image-based
//! relighting rather than errors of the fit:
//!
//! * **The occlusion limitation** (seed 004 §VI). A pixel's captured function knows
//!   light *directions*, not distances: its shadow under a light at position `S` is the
//!   shadow the capture recorded toward `(S − P)`'s direction at infinity. Where
//!   something blocks that ray *beyond* `S`, the relit pixel stays dark though the light
//!   reaches it. [`Renderer::visibility_mismatch`] finds those pixels by tracing both
//!   the segment to the light and the ray past it; the PSNR is reported inside and
//!   outside them.
//! * **Environment lights against brute force.** Besides the truth, an environment light
//!   is compared with `Σ_j w_j I_j`, the captured images weighted by the environment's
//!   radiance around each captured direction
//!   ([`EnvironmentLight::weights_for_directions`]), for each SH window.

use crate::bake::{bake, BakeOptions, BakeStats};
use crate::emitter::Emitter;
use crate::plan::LightPlan;
use crate::render::{RenderOptions, Renderer};
use crate::scene::Scene;
use crate::{capture, invalid, Result};
use relit::camera::{Camera, CameraSpec};
use relit::engine::{RelightOptions, Relighter};
use relit::envmap::{EnvironmentLight, Window};
use relit::fit::{self, FitOptions, FitReport};
use relit::image::ImageRgb;
use relit::light::{
    AreaLight, AreaShape, EnvironmentMapLight, Light, LightRig, PointLight, ProjectorLight,
    SpotLight,
};
use relit::progress::Progress;
use relit::sphere::Vec3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What to capture and how to fit it.
#[derive(Clone, Debug)]
pub struct SceneEvalOptions {
    /// The captured lights.
    pub plan: LightPlan,
    pub fit: FitOptions,
    pub render: RenderOptions,
    /// Compare environment lights with brute-force integration over the captured
    /// images, for each of these windows.
    pub windows: Vec<Window>,
    /// Samples per pixel of an environment light's ground truth (its noise falls as
    /// `1/√N`; the cost is N shadow rays per pixel).
    pub environment_samples: usize,
    /// Emitter samples per pixel of an area light's ground truth, at least (the rig's
    /// own count is the relit image's quality knob, measured against this).
    pub truth_area_samples: usize,
    /// Sample counts at which area lights are also relit, to measure the sampling error
    /// against [`Self::converged_area_samples`] samples.
    pub area_samples: Vec<usize>,
    /// Samples of the converged relit image the sampling error is measured against.
    pub converged_area_samples: usize,
    /// Also bake the scene's transfer ([`crate::bake`]) and score the baked maps under
    /// every light beside the fitted ones: the two routes to the same maps, side by side.
    pub bake: Option<BakeOptions>,
}

impl Default for SceneEvalOptions {
    fn default() -> Self {
        SceneEvalOptions {
            plan: LightPlan::parse("fibonacci:300").expect("a valid plan"),
            fit: FitOptions::default(),
            render: RenderOptions::default(),
            windows: vec![
                Window::None,
                Window::Hann,
                Window::Lanczos,
                Window::Laplacian { lambda: None },
            ],
            environment_samples: crate::emitter::DEFAULT_ENVIRONMENT_SAMPLES,
            truth_area_samples: 256,
            area_samples: vec![1, 4, 16, 64],
            converged_area_samples: 1024,
            bake: None,
        }
    }
}

/// PSNR of one comparison, over the pixels with geometry.
pub use relit::metrics::Psnr;

/// The occlusion limitation under one light.
#[derive(Clone, Debug, Serialize)]
pub struct Occlusion {
    /// Fraction of the pixels with geometry where some of the light's samples reach the
    /// surface although the ray in their direction is blocked beyond the light.
    pub affected_fraction: f64,
    /// PSNR inside those pixels (absent when there are none).
    pub affected: Option<Psnr>,
    /// PSNR over the other pixels.
    pub clear: Option<Psnr>,
    /// Mean linear radiance of the truth and of the relit image over the other pixels:
    /// their ratio is the fit's brightness error alone, without the limitation's.
    pub clear_truth_mean: f64,
    pub clear_relit_mean: f64,
}

/// One light of the rig.
#[derive(Clone, Debug, Serialize)]
pub struct LightResult {
    #[serde(rename = "type")]
    pub kind: String,
    pub light: Light,
    pub psnr_linear: f64,
    pub psnr_srgb8: f64,
    /// Mean linear radiance of the truth over pixels with geometry (how bright the test is).
    pub truth_mean: f64,
    /// Mean linear radiance of the relit image over the same pixels: `relit_mean /
    /// truth_mean` shows a fit that darkens or brightens the scene.
    pub relit_mean: f64,
    pub relight_seconds: f64,
    pub truth_seconds: f64,
    /// Lights with a position only.
    pub occlusion: Option<Occlusion>,
    /// The baked maps under the same light, when [`SceneEvalOptions::bake`] asks.
    pub baked: Option<BakedScore>,
}

/// Baked maps under one light of the rig.
#[derive(Clone, Debug, Serialize)]
pub struct BakedScore {
    pub psnr_linear: f64,
    pub psnr_srgb8: f64,
    pub relit_mean: f64,
}

/// An environment light against brute-force integration over the captured images.
///
/// Two brute forces, both `Σ_j w_j I_j` over the raw captured images `I_j`:
/// * `brute_force_raw`: `w_j` the radiance of the full-resolution map around each
///   captured direction, the best any relighting of this capture can do;
/// * `brute_force`: `w_j` from the *band-limited, windowed* environment that the
///   relighting of a basis with bands itself applies
///   ([`EnvironmentLight::band_limited`]). The dot product and this sum light the scene
///   identically, so any gap between them is the fit's (and a wrong projection,
///   rotation, window or direction convention would show as a large one). For a basis without bands (HSH, SG, RBF, …) there is no band limit
///   to mirror: `brute_force` is `brute_force_raw`, and only the unwindowed light is
///   checked.
#[derive(Clone, Debug, Serialize)]
pub struct EnvironmentCheck {
    /// Index of the light in the rig.
    pub light: usize,
    pub window: Window,
    /// The SH relighting against the truth.
    pub relit: Psnr,
    /// The brute force under the same band-limited, windowed lighting, against the truth.
    pub brute_force: Psnr,
    /// The brute force under the full map, against the truth.
    pub brute_force_raw: Psnr,
    /// The SH relighting against `brute_force`'s image.
    pub relit_vs_brute_force: Psnr,
    /// `relit.psnr_linear − brute_force.psnr_linear`; the check passes at ≥ −0.5 dB.
    pub gain_linear_db: f64,
    /// `relit.psnr_linear − brute_force_raw.psnr_linear`: what band-limiting the
    /// environment (and the window) costs against the raw captures.
    pub gain_vs_raw_linear_db: f64,
    pub relight_seconds: f64,
}

/// An area light's sampling error: relit with `samples` emitter samples per pixel.
#[derive(Clone, Debug, Serialize)]
pub struct AreaCheck {
    /// Index of the light in the rig.
    pub light: usize,
    pub samples: usize,
    /// Against the same light relit with `converged_samples`: the sampling error alone.
    pub vs_converged: Psnr,
    pub converged_samples: usize,
    /// Against the ray-traced truth (which has the fit's and the occlusion's errors too).
    pub vs_truth: Psnr,
    pub relight_seconds: f64,
}

/// Lat-long resolution of the band-limited environment the brute force integrates:
/// far finer than 8 SH bands vary, and than any capture's cells.
const BAND_LIMITED_MAP: (usize, usize) = (256, 128);

/// Everything [`evaluate`] measured.
#[derive(Clone, Debug, Serialize)]
pub struct SceneEvalReport {
    pub scene: String,
    pub width: usize,
    pub height: usize,
    pub projection: String,
    pub plan: String,
    pub images: usize,
    pub coefficients: usize,
    pub capture_seconds: f64,
    pub capture_rays_per_second: f64,
    pub fit: FitReport,
    /// What the bake cost, when [`SceneEvalOptions::bake`] asks.
    pub bake: Option<BakeStats>,
    pub lights: Vec<LightResult>,
    pub environment: Vec<EnvironmentCheck>,
    pub area: Vec<AreaCheck>,
}

/// Receives, for each light of the rig, its index, the light, the truth, the relit image
/// and the mask of the pixels the figures are computed over (`> 0.5`: geometry).
pub type ImageSink<'a> = dyn FnMut(usize, &Light, &ImageRgb, &ImageRgb, &[f32]) -> Result<()> + 'a;

/// Capture `scene` through `camera`, fit it, and compare relit and ray-traced images
/// under each light of `rig` (files it names resolve against `base`). `sink`, if given,
/// sees every pair of images.
pub fn evaluate(
    scene: &Scene,
    camera: &Camera,
    rig: &LightRig,
    base: &Path,
    options: &SceneEvalOptions,
    progress: &dyn Progress,
    mut sink: Option<&mut ImageSink>,
) -> Result<SceneEvalReport> {
    rig.validate()?;
    if rig.lights.is_empty() {
        return Err(invalid("the rig has no lights to evaluate"));
    }
    // Every light's emitter first, so that a rig naming a missing or bad file fails
    // before the capture and fit, not after.
    let emitters = rig
        .lights
        .iter()
        .map(|light| {
            let mut truth_light = light.clone();
            if let Light::Area(a) = &mut truth_light {
                a.samples = a.samples.max(options.truth_area_samples);
            }
            Emitter::from_light_sampled(&truth_light, base, options.environment_samples)
        })
        .collect::<Result<Vec<_>>>()?;
    let directions = options.plan.directions();
    let captured =
        capture::capture_in_memory(scene, camera, &directions, &options.render, progress)?;
    let mut capture = captured.capture;
    capture.camera = Some(CameraSpec::from(camera));
    let fitted = fit::fit(&capture, &options.fit, progress)?;
    let relighter = Relighter::new(&fitted.image)?;
    let banded = relighter.basis().coefficient_bands().is_some();
    let baked_maps = options
        .bake
        .as_ref()
        .map(|bake_options| bake(scene, camera, bake_options, progress))
        .transpose()?;
    let baked = baked_maps
        .as_ref()
        .map(|baked| Ok::<_, crate::Error>((Relighter::new(&baked.image)?, baked.stats.clone())))
        .transpose()?;
    let truth = Renderer::new(scene, camera, &options.render, progress)?;
    let mask = truth.mask().to_vec();
    let relight_options = RelightOptions {
        resource_dir: base.to_path_buf(),
        ..RelightOptions::default()
    };

    let mut lights = Vec::with_capacity(rig.lights.len());
    let mut environment = Vec::new();
    let mut area = Vec::new();
    progress.begin("lights", rig.lights.len() as u64);
    for (index, (light, emitter)) in rig.lights.iter().zip(&emitters).enumerate() {
        let t = Instant::now();
        let reference = truth.render(std::slice::from_ref(emitter)).image;
        let truth_seconds = t.elapsed().as_secs_f64();
        let single = LightRig::new(vec![light.clone()]);
        let t = Instant::now();
        let relit = relighter.relight(&single, &relight_options)?;
        let relight_seconds = t.elapsed().as_secs_f64();
        let all = compare_in(&relit, &reference, &mask);
        if let Some(sink) = sink.as_mut() {
            sink(index, light, &reference, &relit, &mask)?;
        }
        let occlusion = (!light.is_uniform()).then(|| {
            let wrong = truth.visibility_mismatch(emitter);
            let affected: Vec<f32> = wrong
                .iter()
                .zip(&mask)
                .map(|(&w, &m)| if w > 0.0 && m > 0.5 { 1.0 } else { 0.0 })
                .collect();
            let clear: Vec<f32> = affected
                .iter()
                .zip(&mask)
                .map(|(&a, &m)| if a == 0.0 && m > 0.5 { 1.0 } else { 0.0 })
                .collect();
            let inside = mask.iter().filter(|&&m| m > 0.5).count().max(1);
            let count = affected.iter().filter(|&&a| a > 0.5).count();
            Occlusion {
                affected_fraction: count as f64 / inside as f64,
                affected: (count > 0).then(|| compare_in(&relit, &reference, &affected)),
                clear: (count < inside).then(|| compare_in(&relit, &reference, &clear)),
                clear_truth_mean: mean_in(&reference, &clear),
                clear_relit_mean: mean_in(&relit, &clear),
            }
        });
        if let Light::Environment(env) = light {
            environment.extend(environment_checks(
                index,
                env,
                base,
                &capture,
                &relighter,
                &relight_options,
                &reference,
                &mask,
                &options.windows,
                banded,
            )?);
        }
        if let Light::Area(a) = light {
            area.extend(area_checks(
                index,
                a,
                &relighter,
                &relight_options,
                &reference,
                &mask,
                options,
            )?);
        }
        let baked_score = baked
            .as_ref()
            .map(|(relighter, _)| {
                let image = relighter.relight(&single, &relight_options)?;
                let score = compare_in(&image, &reference, &mask);
                Ok::<_, crate::Error>(BakedScore {
                    psnr_linear: score.psnr_linear,
                    psnr_srgb8: score.psnr_srgb8,
                    relit_mean: mean_in(&image, &mask),
                })
            })
            .transpose()?;
        lights.push(LightResult {
            kind: light.kind().into(),
            light: light.clone(),
            psnr_linear: all.psnr_linear,
            psnr_srgb8: all.psnr_srgb8,
            truth_mean: mean_in(&reference, &mask),
            relit_mean: mean_in(&relit, &mask),
            relight_seconds,
            truth_seconds,
            occlusion,
            baked: baked_score,
        });
        progress.advance(1);
    }
    progress.end();
    Ok(SceneEvalReport {
        scene: scene.name.clone(),
        width: camera.width(),
        height: camera.height(),
        projection: camera.projection().name().into(),
        plan: options.plan.describe(),
        images: directions.len(),
        coefficients: fitted.report.coefficients,
        capture_seconds: captured.stats.total_seconds,
        capture_rays_per_second: captured.stats.rays_per_second,
        fit: fitted.report,
        bake: baked.map(|(_, stats)| stats),
        lights,
        environment,
        area,
    })
}

fn area_checks(
    index: usize,
    light: &AreaLight,
    relighter: &Relighter,
    relight_options: &RelightOptions,
    reference: &ImageRgb,
    mask: &[f32],
    options: &SceneEvalOptions,
) -> Result<Vec<AreaCheck>> {
    let relight = |samples: usize| -> Result<(ImageRgb, f64)> {
        let mut sampled = light.clone();
        sampled.samples = samples;
        let t = Instant::now();
        let image =
            relighter.relight(&LightRig::new(vec![Light::Area(sampled)]), relight_options)?;
        Ok((image, t.elapsed().as_secs_f64()))
    };
    let converged_samples = options.converged_area_samples;
    let (converged, _) = relight(converged_samples)?;
    options
        .area_samples
        .iter()
        .map(|&samples| {
            let (image, relight_seconds) = relight(samples)?;
            Ok(AreaCheck {
                light: index,
                samples,
                vs_converged: compare_in(&image, &converged, mask),
                converged_samples,
                vs_truth: compare_in(&image, reference, mask),
                relight_seconds,
            })
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn environment_checks(
    index: usize,
    light: &EnvironmentMapLight,
    base: &Path,
    capture: &relit::capture::Capture,
    relighter: &Relighter,
    relight_options: &RelightOptions,
    reference: &ImageRgb,
    mask: &[f32],
    windows: &[Window],
    banded: bool,
) -> Result<Vec<EnvironmentCheck>> {
    let env = EnvironmentLight::load(&base.join(&light.map))?.with_rotation(light.rotation()?)?;
    let directions = capture.directions();
    let rgb = Light::Environment(light.clone()).rgb();
    let raw = brute_force(capture, &env.weights_for_directions(&directions)?, rgb)?;
    let brute_force_raw = compare_in(&raw, reference, mask);
    // Windows scale bands; a basis without bands is relit unwindowed, and its
    // "same lighting" brute force is the full map (there is no band limit to mirror).
    windows
        .iter()
        .filter(|&&window| banded || window == Window::None)
        .map(|&window| {
            let mut windowed = light.clone();
            windowed.window = window;
            let t = Instant::now();
            let relit = relighter.relight(
                &LightRig::new(vec![Light::Environment(windowed)]),
                relight_options,
            )?;
            let relight_seconds = t.elapsed().as_secs_f64();
            let (w, h) = BAND_LIMITED_MAP;
            let brute = if banded {
                let limited =
                    env.clone()
                        .with_window(window)?
                        .band_limited(relighter.basis(), w, h)?;
                brute_force(capture, &limited.weights_for_directions(&directions)?, rgb)?
            } else {
                raw.clone()
            };
            let against_truth = compare_in(&relit, reference, mask);
            let brute_against_truth = compare_in(&brute, reference, mask);
            Ok(EnvironmentCheck {
                light: index,
                window,
                relit: against_truth,
                brute_force: brute_against_truth,
                brute_force_raw,
                relit_vs_brute_force: compare_in(&relit, &brute, mask),
                gain_linear_db: against_truth.psnr_linear - brute_against_truth.psnr_linear,
                gain_vs_raw_linear_db: against_truth.psnr_linear - brute_force_raw.psnr_linear,
                relight_seconds,
            })
        })
        .collect()
}

/// `Σ_j (w_j · rgb) I_j` over the captured images (those of zero weight are not read).
fn brute_force(
    capture: &relit::capture::Capture,
    weights: &[[f64; 3]],
    rgb: [f64; 3],
) -> Result<ImageRgb> {
    let mut sum = ImageRgb::new(capture.width, capture.height);
    for (j, wj) in weights.iter().enumerate() {
        if wj.iter().all(|&v| v == 0.0) {
            continue;
        }
        let image = capture.load(j)?;
        let scale: [f32; 3] = std::array::from_fn(|c| (wj[c] * rgb[c]) as f32);
        for (dst, src) in sum.data.chunks_exact_mut(3).zip(image.data.chunks_exact(3)) {
            for c in 0..3 {
                dst[c] += scale[c] * src[c];
            }
        }
    }
    Ok(sum)
}

/// PSNR (linear, peak 1; and 8-bit sRGB) of `test` against `reference` over the pixels
/// where `mask > 0.5`.
pub fn compare_in(test: &ImageRgb, reference: &ImageRgb, mask: &[f32]) -> Psnr {
    relit::metrics::compare(&test.data, &reference.data, Some(mask))
}

fn mean_in(image: &ImageRgb, mask: &[f32]) -> f64 {
    relit::metrics::mean_radiance(&image.data, Some(mask))
}

/// One light of each type the engine has, placed for `camera`'s view of a scene whose
/// surfaces lie at the distances `depth` (so it suits any scene's scale): a directional
/// light, a point light, a spotlight and a slide projector aimed at what the camera looks
/// at, a rectangular area light above the eye, and an environment (a procedural sky
/// with a sun). The slide and sky are written into `dir`, which the rig's files are
/// relative to.
pub fn default_rig(camera: &Camera, depth: &[f32], dir: &Path) -> Result<LightRig> {
    let mut hits: Vec<f32> = depth.iter().copied().filter(|&d| d > 0.0).collect();
    if hits.is_empty() {
        return Err(invalid(
            "the camera sees no geometry to place the default lights around",
        ));
    }
    hits.sort_by(f32::total_cmp);
    let scale = 0.35 * hits[hits.len() / 2] as f64;
    let pose = camera.pose();
    let (right, up, back) = (pose.right, pose.up, pose.back);
    let eye = pose.eye;
    let (w, h) = (camera.width(), camera.height());
    // What the camera looks at: the surface through the image centre, and one lower.
    let seen = |fx: f64, fy: f64| -> Vec3 {
        let (i, j) = (
            ((fx * w as f64) as usize).min(w - 1),
            ((fy * h as f64) as usize).min(h - 1),
        );
        let d = depth[j * w + i];
        if d > 0.0 {
            camera.position(i, j, d as f64)
        } else {
            eye - back * (2.0 * scale)
        }
    };
    let centre = seen(0.5, 0.5);
    let low = seen(0.5, 0.75);
    let irradiance_one_at = |d: f64| d * d; // inverse-square intensity for irradiance 1 at d

    let point_at = eye + right * (0.5 * scale) - up * (0.3 * scale) - back * (0.8 * scale);
    let spot_at = eye + up * (0.4 * scale) - right * (0.3 * scale);
    let projector_at = eye - right * (0.2 * scale) + up * (0.15 * scale);
    let area_centre = eye + up * (0.6 * scale) - back * (0.3 * scale);
    let half = 0.25 * scale;
    let median = hits[hits.len() / 2] as f64;

    std::fs::create_dir_all(dir).map_err(|e| crate::io_error(dir, "create", e))?;
    let slide = "slide.png";
    relit::image::save(&dir.join(slide), &test_slide(256, 192), 0.0)?;
    let sky = "sky.exr";
    relit::image::save(&dir.join(sky), &procedural_sky(256, 128), 0.0)?;

    let lights = vec![
        Light::directional([0.35, 0.8, 0.45], [1.0, 0.95, 0.85]),
        Light::Point(PointLight {
            position: point_at,
            color: [1.0, 0.85, 0.6],
            intensity: irradiance_one_at(scale),
            attenuation: Default::default(),
        }),
        Light::Spot(SpotLight {
            position: spot_at,
            direction: low - spot_at,
            cone_deg: 30.0,
            softness_deg: 6.0,
            color: [0.7, 0.85, 1.0],
            intensity: irradiance_one_at((low - spot_at).length()),
            attenuation: Default::default(),
        }),
        Light::Projector(ProjectorLight {
            position: projector_at,
            direction: centre - projector_at,
            up,
            fov_deg: 40.0,
            slide: slide.into(),
            color: [1.0; 3],
            intensity: irradiance_one_at((centre - projector_at).length()),
            attenuation: Default::default(),
        }),
        Light::Area(AreaLight {
            shape: AreaShape::Rect {
                center: area_centre,
                u: right * half,
                v: back * half,
            },
            color: [1.0, 0.95, 0.9],
            // Radiance whose irradiance straight below, as far as the camera's median
            // surface, is about 1 (E ≈ L·A/d² for a small emitter).
            intensity: median * median / (4.0 * half * half),
            two_sided: false,
            samples: 32,
        }),
        Light::Environment(EnvironmentMapLight {
            map: sky.into(),
            yaw_deg: 0.0,
            pitch_deg: 0.0,
            roll_deg: 0.0,
            window: Window::None,
            color: [1.0; 3],
            intensity: 1.0,
        }),
    ];
    let rig = LightRig::new(lights);
    rig.validate()?;
    Ok(rig)
}

/// A colourful slide with edges of every orientation: quadrants of colour, a grid and a
/// diagonal band (linear RGB).
pub fn test_slide(width: usize, height: usize) -> ImageRgb {
    let mut image = ImageRgb::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = (x as f64 / width as f64, y as f64 / height as f64);
            let mut rgb = match (u < 0.5, v < 0.5) {
                (true, true) => [1.0, 0.25, 0.2],
                (false, true) => [0.25, 1.0, 0.3],
                (true, false) => [0.2, 0.35, 1.0],
                (false, false) => [1.0, 0.9, 0.3],
            };
            if (x / 32 + y / 32) % 2 == 0 {
                rgb = rgb.map(|c| c * 0.35);
            }
            if ((u - v) * 8.0).abs() < 0.5 {
                rgb = [1.0; 3];
            }
            let o = 3 * (y * width + x);
            image.data[o..o + 3].copy_from_slice(&rgb.map(|c| c as f32));
        }
    }
    image
}

/// A sky for the default environment light: a blue gradient brighter toward the
/// horizon, a dim ground, and a sun 35° high (linear RGB lat-long). Irradiance on
/// an open upward surface is about 1.5, half of it from the sun.
pub fn procedural_sky(width: usize, height: usize) -> ImageRgb {
    let sun = Vec3::new(0.5, 35f64.to_radians().sin(), -0.6)
        .normalized()
        .expect("a non-zero vector");
    let sun_radius = 4f64.to_radians();
    let sun_solid_angle = std::f64::consts::TAU * (1.0 - sun_radius.cos());
    let sun_radiance = 0.8 / (sun.y * sun_solid_angle);
    let mut image = ImageRgb::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let d = relit::envmap::latlong_direction(
                (x as f64 + 0.5) / width as f64,
                (y as f64 + 0.5) / height as f64,
            );
            let mut rgb = if d.y >= 0.0 {
                let t = 1.0 - d.y;
                [0.12 + 0.1 * t, 0.16 + 0.08 * t, 0.26 + 0.02 * t]
            } else {
                [0.05, 0.045, 0.04]
            };
            if d.dot(sun) >= sun_radius.cos() {
                rgb = [sun_radiance, sun_radiance * 0.93, sun_radiance * 0.8];
            }
            let o = 3 * (y * width + x);
            image.data[o..o + 3].copy_from_slice(&rgb.map(|c| c as f32));
        }
    }
    image
}

/// The folder for the default rig's files: a fresh temporary directory.
pub fn scratch_dir() -> Result<(tempfile::TempDir, PathBuf)> {
    let dir = tempfile::tempdir()
        .map_err(|e| crate::io_error(Path::new("."), "create a temporary folder in", e))?;
    let path = dir.path().to_path_buf();
    Ok((dir, path))
}
