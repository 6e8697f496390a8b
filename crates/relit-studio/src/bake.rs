//! Precomputed radiance transfer: relightable maps baked from the geometry (seed 003).
//!
//! A capture measures each pixel's response `f_p(ω)` to a unit directional light
//! toward `ω` and fits a basis to it. When the scene is known, the same function can be
//! integrated directly: per camera sample, rays from the visible point find which
//! directions are open, and `f_p` is projected onto the basis,
//! `c_i = ∫ f_p(ω) Y_i(ω) dω`: a basis orthonormal over the sphere whose coefficients
//! come in bands (`Basis::coefficient_bands`; relit's real spherical harmonics, `sh:K`),
//! so that the projection is that integral and the Funk–Hecke closed form below holds
//! band by band. The result is the file a fit writes (same basis, camera
//! and depth), so every light type and every command after the fit works on it
//! unchanged; relit's environment lights are `Σ_i c_i e_i` with the map's own SH
//! coefficients `e_i` ([`relit::envmap`]), seed 003's dot product.
//!
//! # Transfers
//!
//! * `visibility`: `V(ω)`, 1 where a ray toward `ω` leaves the scene and `ω` is above
//!   the geometric surface (the same in the three colour channels).
//! * `diffuse`: `ρ(ω) · max(0, n·ω) · V(ω)`, the surface's reflectance toward the
//!   camera under a unit light from `ω`, which is what a capture measures: the albedo
//!   `a` and, on glossy materials, the Blinn–Phong lobe seen from the fixed eye. With
//!   `lambert` only `a · max(0, n·ω) · V(ω)`, seed 003's diffuse transfer (seed 003
//!   writes `a/π`; relit's unit light has irradiance π ([`crate::material`]), which
//!   cancels the `1/π`).
//! * `bleeding`: `diffuse` plus one bounce, `a_p · 1/k Σ_b a_q · max(0, n_q·ω) · V_q(ω)`
//!   over the `k` cosine-weighted bounce rays of the [`Renderer`] that hit a surface
//!   `q`: exactly what `render-truth --indirect k` adds, with the same bounce rays. The
//!   transfer at each bounce point is itself a projection (seed 003's colour-bleeding
//!   pass gathers it from the first pass; here it is traced where the bounce lands).
//!
//! # Estimators
//!
//! Each camera sample traces `N` directions: Hammersley sets `((j + ½)/n, φ₂(j))`
//! shifted modulo 1 by a hash of the sample's index (a Cranley–Patterson rotation:
//! deterministic, and decorrelated between pixels so that the error is noise, not a
//! pattern). `visibility` maps it uniformly onto the hemisphere about the geometric
//! normal, `c_i ≈ 2π/N · Σ_j V(ω_j) Y_i(ω_j)`. `diffuse` and `bleeding` map it to the
//! cosine-weighted hemisphere about the shading normal, where for a Lambertian surface
//! `c_i ≈ π/N · Σ_j a · V(ω_j) · Y_i(ω_j)`; a glossy surface gives its lobe a share of
//! the directions in proportion to its energy, drawn along the lobe, and weighs every
//! direction by the density of both strategies together (multiple importance sampling,
//! balance heuristic). Bounce points trace `M` directions, cosine-weighted.
//!
//! The `N` directions are two such sets of `N/2` with independent shifts, so they give
//! two independent estimates whose difference measures the error of their mean. The
//! noise stated is that of the *white-sky image* (each pixel under a uniform unit
//! environment, `∫ f_p dω`), as the RMS over pixels of that standard error.

use crate::material::Reflectance;
use crate::math::V3;
use crate::render::{cosine_direction_in, tangent_frame, Bounce, RenderOptions, Renderer, Sample};
use crate::scene::Scene;
use crate::texture::hash2;
use crate::{invalid, Result};
use rayon::prelude::*;
use relit::basis::{Basis, BasisSpec};
use relit::camera::{Camera, CameraSpec};
use relit::envmap::Window;
use relit::maps::{BakeInfo, CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::progress::Progress;
use serde::Serialize;
use std::f32::consts::PI;
use std::time::Instant;

/// Which light transport a bake projects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Transfer {
    /// Directional visibility `V(ω)`.
    Visibility,
    /// Diffuse transfer `a · max(0, n·ω) · V(ω)`.
    Diffuse,
    /// Diffuse transfer plus one-bounce interreflection.
    Bleeding,
}

impl Transfer {
    /// Parse `visibility`, `diffuse` or `bleeding`.
    pub fn parse(name: &str) -> Result<Transfer> {
        match name {
            "visibility" => Ok(Transfer::Visibility),
            "diffuse" => Ok(Transfer::Diffuse),
            "bleeding" => Ok(Transfer::Bleeding),
            other => Err(invalid(format!(
                "unknown transfer `{other}`: use visibility, diffuse or bleeding"
            ))),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Transfer::Visibility => "visibility",
            Transfer::Diffuse => "diffuse",
            Transfer::Bleeding => "bleeding",
        }
    }
}

/// What to bake and how finely.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    pub transfer: Transfer,
    /// The basis the transfer is projected onto: one whose coefficients come in bands
    /// ([`Basis::coefficient_bands`]: orthonormal over the sphere, band by band), which
    /// the Funk–Hecke closed form and the band windows need; `sh:25` by default.
    pub basis: BasisSpec,
    /// Directions traced per camera sample.
    pub samples: u32,
    /// Bounce rays per camera sample (`bleeding` only; as `render-truth --indirect`).
    pub indirect: u32,
    /// Directions traced per bounce point (`bleeding` only).
    pub bounce_samples: u32,
    /// Camera samples per pixel along each axis.
    pub supersample: u32,
    /// Band window applied to the baked coefficients (seed 003 §4.1). The default,
    /// the Laplacian window that halves the top band, is the bake's counterpart of the
    /// fit's roughness penalty (see `docs/transfer.md` for how it was chosen).
    pub window: Window,
    /// Drop the materials' glossy lobes: seed 003's diffuse transfer exactly, instead of
    /// everything the camera sees.
    pub lambert: bool,
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions {
            transfer: Transfer::Diffuse,
            basis: BasisSpec::default(),
            samples: 256,
            indirect: 0,
            bounce_samples: 64,
            supersample: 1,
            window: Window::Laplacian { lambda: None },
            lambert: false,
        }
    }
}

impl BakeOptions {
    /// Check the options.
    pub fn validate(&self) -> Result<()> {
        let (_, bands) = self.banded_basis()?;
        if !(1..=1 << 16).contains(&self.samples) {
            return Err(invalid(format!(
                "directions per sample must be 1 to 65536, not {}",
                self.samples
            )));
        }
        match self.transfer {
            Transfer::Bleeding => {
                if self.indirect == 0 {
                    return Err(invalid("bleeding needs at least one bounce ray per sample"));
                }
                if !(1..=4096).contains(&self.bounce_samples) {
                    return Err(invalid(format!(
                        "directions per bounce point must be 1 to 4096, not {}",
                        self.bounce_samples
                    )));
                }
            }
            _ if self.indirect > 0 => {
                return Err(invalid(format!(
                    "bounce rays apply only to the bleeding transfer, not {}",
                    self.transfer.name()
                )));
            }
            _ => {}
        }
        self.render_options().validate()?;
        self.window.factors(band_count(&bands))?;
        Ok(())
    }

    /// The basis, with the band of each of its coefficients.
    fn banded_basis(&self) -> Result<(Box<dyn Basis>, Vec<usize>)> {
        let basis = self.basis.build()?;
        let bands = basis.coefficient_bands().ok_or_else(|| {
            invalid(format!(
                "a bake projects onto a basis whose coefficients come in bands (orthonormal \
                 over the sphere, band by band, for the Funk–Hecke closed form): {} has none",
                basis.name()
            ))
        })?;
        Ok((basis, bands))
    }

    fn render_options(&self) -> RenderOptions {
        RenderOptions {
            supersample: self.supersample,
            indirect_samples: self.indirect,
        }
    }
}

/// What a bake cost and how noisy it is.
#[derive(Clone, Debug, Serialize)]
pub struct BakeStats {
    pub width: usize,
    pub height: usize,
    /// The basis the transfer was projected onto (`sh:25`).
    pub basis: String,
    pub coefficients: usize,
    pub gbuffer_seconds: f64,
    pub transfer_seconds: f64,
    pub total_seconds: f64,
    /// Rays traced, primary and bounce rays included.
    pub rays: u64,
    pub rays_per_second: f64,
    /// Mean of the white-sky image over the pixels with geometry.
    pub white_sky_mean: f64,
    /// RMS standard error of the white-sky image over those pixels (upper estimate).
    pub white_sky_noise: f64,
}

impl BakeStats {
    /// [`BakeStats::white_sky_noise`] relative to [`BakeStats::white_sky_mean`].
    pub fn relative_noise(&self) -> f64 {
        if self.white_sky_mean > 0.0 {
            self.white_sky_noise / self.white_sky_mean
        } else {
            0.0
        }
    }
}

/// Baked maps and their cost.
pub struct Baked {
    pub image: RelightableImage,
    pub stats: BakeStats,
}

/// Bake `options.transfer` of `scene` as seen by `camera`.
pub fn bake(
    scene: &Scene,
    camera: &Camera,
    options: &BakeOptions,
    progress: &dyn Progress,
) -> Result<Baked> {
    options.validate()?;
    let start = Instant::now();
    let renderer = Renderer::new(scene, camera, &options.render_options(), progress)?;
    let gbuffer_seconds = start.elapsed().as_secs_f64();
    let (basis, bands) = options.banded_basis()?;
    let k = basis.len();
    let (w, h) = (camera.width(), camera.height());
    let baker = Baker {
        scene,
        basis: basis.as_ref(),
        bands: &bands,
        options,
        clamped_cosine: funk_hecke(band_count(&bands), |t| t),
        hemisphere: funk_hecke(band_count(&bands), |_| 1.0),
    };
    progress.begin("transfer", h as u64);
    let rows: Vec<RowResult> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut row = RowResult {
                coefficients: vec![0.0; w * 3 * k],
                white: Vec::with_capacity(w),
                variance: Vec::with_capacity(w),
                rays: 0,
            };
            let mut weights = vec![0.0; k];
            for x in 0..w {
                let pixel = y * w + x;
                let out = &mut row.coefficients[x * 3 * k..(x + 1) * 3 * k];
                let stats = baker.pixel(&renderer, pixel, out, &mut weights);
                row.white.push(stats.white);
                row.variance.push(stats.variance);
                row.rays += stats.rays;
            }
            progress.advance(1);
            row
        })
        .collect();
    progress.end();
    let transfer_seconds = start.elapsed().as_secs_f64() - gbuffer_seconds;

    let factors = options.window.factors(band_count(&bands))?;
    let n = w * h;
    let mut maps = CoefficientMaps::zeros(w, h, k);
    let (mut rays, mut white_sum, mut variance_sum, mut covered) = (0u64, 0.0, 0.0, 0usize);
    for (y, row) in rows.iter().enumerate() {
        rays += row.rays;
        for x in 0..w {
            let pixel = y * w + x;
            for i in 0..k {
                for c in 0..3 {
                    maps.data[(3 * i + c) * n + pixel] =
                        (row.coefficients[(x * 3 + c) * k + i] * factors[bands[i]]) as f32;
                }
            }
            if renderer.mask()[pixel] > 0.0 {
                white_sum += row.white[x];
                variance_sum += row.variance[x];
                covered += 1;
            }
        }
    }
    let total_seconds = start.elapsed().as_secs_f64();
    let rays = rays + renderer.primary_rays();
    let covered = covered.max(1) as f64;
    let stats = BakeStats {
        width: w,
        height: h,
        basis: basis.name(),
        coefficients: k,
        gbuffer_seconds,
        transfer_seconds,
        total_seconds,
        rays,
        rays_per_second: rays as f64 / total_seconds.max(1e-9),
        white_sky_mean: white_sum / covered,
        white_sky_noise: (variance_sum / covered).sqrt(),
    };
    let mut meta = Metadata::new(basis.spec(), MapSpace::Linear, camera.projection().clone());
    meta.camera = Some(CameraSpec::from(camera));
    meta.bake = Some(BakeInfo {
        transfer: options.transfer.name().to_string(),
        samples: options.samples,
        indirect: options.indirect,
        bounce_samples: if options.transfer == Transfer::Bleeding {
            options.bounce_samples
        } else {
            0
        },
        supersample: options.supersample,
        window: options.window.name().to_string(),
        lambert: options.lambert,
        noise: stats.relative_noise(),
        seconds: total_seconds,
    });
    let image = RelightableImage {
        meta,
        maps,
        depth: Some(renderer.depth().to_vec()),
    };
    Ok(Baked { image, stats })
}

/// One row's coefficients (pixel-major, then channel, then coefficient) and noise.
struct RowResult {
    coefficients: Vec<f64>,
    white: Vec<f64>,
    variance: Vec<f64>,
    rays: u64,
}

/// One pixel's white-sky value, its sampling variance and the rays it cost.
struct PixelStats {
    white: f64,
    variance: f64,
    rays: u64,
}

struct Baker<'a> {
    scene: &'a Scene,
    basis: &'a dyn Basis,
    /// The band of each coefficient.
    bands: &'a [usize],
    options: &'a BakeOptions,
    /// Funk–Hecke factors per band of the clamped cosine and of the hemisphere.
    clamped_cosine: Vec<f64>,
    hemisphere: Vec<f64>,
}

/// What is integrated against the basis over one set of directions.
#[derive(Clone, Copy)]
enum Integrand {
    /// `V(ω)`, sampled uniformly over the hemisphere of the geometric normal.
    Visibility,
    /// `tint · reflect(n, wo, ω) · V(ω)`: the surface's response toward `to_eye`,
    /// sampled cosine-weighted and, where it has one, along its glossy lobe.
    Reflect {
        shading_normal: V3,
        to_eye: V3,
        reflectance: Reflectance,
        tint: V3,
    },
}

/// Where one set of directions starts and what it integrates.
struct Gather {
    origin: V3,
    geometric_normal: V3,
    integrand: Integrand,
    count: u32,
    seed: u32,
}

/// The strategies that draw a set's directions, with their counts.
struct Strategies {
    uniform: u32,
    cosine: u32,
    lobe: u32,
}

impl Baker<'_> {
    /// Bake pixel `pixel` into `out` (`3 × k`, channel-major), averaging its samples.
    fn pixel(
        &self,
        renderer: &Renderer,
        pixel: usize,
        out: &mut [f64],
        weights: &mut [f64],
    ) -> PixelStats {
        let spp = renderer.samples_per_pixel();
        let scale = 1.0 / spp as f64;
        let mut stats = PixelStats {
            white: 0.0,
            variance: 0.0,
            rays: 0,
        };
        for (s, (sample, bounces)) in renderer.pixel_samples(pixel).enumerate() {
            let Some(sample) = sample else { continue };
            let seed = (pixel * spp + s) as u32;
            let mut halves = [0.0f64; 2];
            let integrand = match self.options.transfer {
                Transfer::Visibility => Integrand::Visibility,
                Transfer::Diffuse | Transfer::Bleeding => Integrand::Reflect {
                    shading_normal: sample.shading_normal,
                    to_eye: sample.to_eye,
                    reflectance: if self.options.lambert {
                        Reflectance {
                            specular: 0.0,
                            ..sample.reflectance
                        }
                    } else {
                        sample.reflectance
                    },
                    tint: V3::splat(1.0),
                },
            };
            let direct = Gather {
                origin: sample.origin,
                geometric_normal: sample.geometric_normal,
                integrand,
                count: self.options.samples,
                seed,
            };
            stats.rays += self.gather(&direct, scale, out, weights, &mut halves);
            if self.options.transfer == Transfer::Bleeding {
                stats.rays += self.bleed(sample, bounces, seed, scale, out, weights, &mut halves);
            }
            let [a, b] = halves;
            stats.white += a + b;
            stats.variance += (a - b) * (a - b);
        }
        stats
    }

    /// One bounce: the diffuse transfer of every surface the sample's bounce rays hit,
    /// reflected by the sample's albedo (as the renderer's bounce: diffuse only).
    #[allow(clippy::too_many_arguments)]
    fn bleed(
        &self,
        sample: &Sample,
        bounces: &[Option<Bounce>],
        seed: u32,
        scale: f64,
        out: &mut [f64],
        weights: &mut [f64],
        halves: &mut [f64; 2],
    ) -> u64 {
        let tint = sample.reflectance.albedo * (1.0 / bounces.len() as f32);
        let mut rays = 0;
        for (b, bounce) in bounces.iter().enumerate() {
            let Some(q) = bounce else { continue };
            let gather = Gather {
                origin: q.origin,
                geometric_normal: q.geometric_normal,
                integrand: Integrand::Reflect {
                    shading_normal: q.shading_normal,
                    to_eye: q.shading_normal,
                    reflectance: Reflectance {
                        albedo: q.albedo,
                        specular: 0.0,
                        shininess: 1.0,
                    },
                    tint,
                },
                count: self.options.bounce_samples,
                seed: hash_seed(seed, b as u32 + 1),
            };
            rays += self.gather(&gather, scale, out, weights, halves);
        }
        rays
    }

    /// How `g`'s directions are drawn: the glossy lobe gets a share of the directions
    /// in proportion to its part of the reflected energy.
    fn strategies(g: &Gather) -> Strategies {
        match g.integrand {
            Integrand::Visibility => Strategies {
                uniform: g.count,
                cosine: 0,
                lobe: 0,
            },
            Integrand::Reflect { reflectance, .. } => {
                let diffuse =
                    (reflectance.albedo.x + reflectance.albedo.y + reflectance.albedo.z) / 3.0;
                let glossy = reflectance.specular;
                let lobe = if glossy > 0.0 && g.count > 1 {
                    ((g.count as f32 * glossy / (glossy + diffuse)).round() as u32)
                        .clamp(1, g.count - 1)
                } else {
                    0
                };
                Strategies {
                    uniform: 0,
                    cosine: g.count - lobe,
                    lobe,
                }
            }
        }
    }

    /// Add `g`'s integral against the basis to `out` (times `scale`).
    ///
    /// The unoccluded part has a closed form: by the Funk–Hecke theorem a kernel of
    /// `n·ω` alone (the clamped cosine of a Lambertian surface, the hemisphere of
    /// visibility) projects to `λ_l Y_i(n)`. Only what the scene blocks is left to
    /// Monte Carlo, `f = f_open − f_open·(1 − V)`, so an open surface has no noise at
    /// all and a partly shadowed one only that of its shadow. Glossy lobes have no
    /// closed form here and are integrated as `lobe · V`. Each traced direction adds
    /// `estimate(ω) Y(ω) / p(ω)`, with `p` the density of all strategies together (the
    /// balance heuristic of multiple importance sampling). Each strategy's directions
    /// are two Hammersley sets of half the count with independent shifts, whose
    /// white-sky sums go to `halves`: two independent estimates, so their difference
    /// measures the error.
    fn gather(
        &self,
        g: &Gather,
        scale: f64,
        out: &mut [f64],
        weights: &mut [f64],
        halves: &mut [f64; 2],
    ) -> u64 {
        let k = weights.len();
        let strategies = Self::strategies(g);
        let frame = tangent_frame(g.geometric_normal);
        let (axis, open, kernel) = match g.integrand {
            Integrand::Visibility => (g.geometric_normal, V3::splat(1.0), &self.hemisphere),
            Integrand::Reflect {
                shading_normal,
                reflectance,
                tint,
                ..
            } => (
                shading_normal,
                reflectance.albedo.modulate(tint),
                &self.clamped_cosine,
            ),
        };
        let axis_frame = tangent_frame(axis);
        self.basis.eval(axis.into(), weights);
        let open = [open.x as f64, open.y as f64, open.z as f64];
        for (c, &v) in open.iter().enumerate() {
            for (i, (o, &y)) in out[c * k..(c + 1) * k]
                .iter_mut()
                .zip(weights.iter())
                .enumerate()
            {
                *o += scale * v * kernel[self.bands[i]] * y;
            }
        }
        // Y_0 is constant, so the white-sky value of the closed form is λ_0 · open.
        let open_white = scale * kernel[0] * (open[0] + open[1] + open[2]) / 3.0;
        halves[0] += 0.5 * open_white;
        halves[1] += 0.5 * open_white;
        let mut rays = 0;
        let plan = [
            (0u32, strategies.uniform),
            (1, strategies.cosine),
            (2, strategies.lobe),
        ];
        for (strategy, count) in plan {
            let sizes = [count.div_ceil(2), count / 2];
            let shifts = [0, 1].map(|h| {
                let seed = hash_seed(g.seed, 2 * strategy + h) as i32;
                (hash2(seed, 0x5eed), hash2(seed, -0x0b1e))
            });
            for j in 0..count {
                let (half, i) = ((j & 1) as usize, j >> 1);
                let (shift_u, shift_v) = shifts[half];
                let u1 = ((i as f32 + 0.5) / sizes[half] as f32 + shift_u).fract();
                let u2 = (radical_inverse(i) + shift_v).fract();
                let direction = match (strategy, g.integrand) {
                    (0, _) => uniform_direction(g.geometric_normal, frame, u1, u2),
                    (1, Integrand::Reflect { shading_normal, .. }) => {
                        cosine_direction_in(shading_normal, axis_frame, u1, u2)
                    }
                    (
                        _,
                        Integrand::Reflect {
                            shading_normal,
                            to_eye,
                            reflectance,
                            ..
                        },
                    ) => lobe_direction(shading_normal, to_eye, reflectance.shininess, u1, u2),
                    _ => unreachable!("the visibility integrand has only the uniform strategy"),
                };
                if !direction.is_finite() {
                    continue;
                }
                // What the closed form counted here (`blocked`, lost unless the
                // direction is open) and what only an open direction adds (`glossy`),
                // both over the density.
                let (blocked, glossy) = match g.integrand {
                    Integrand::Visibility => {
                        if g.geometric_normal.dot(direction) <= 0.0 {
                            continue;
                        }
                        (V3::splat(2.0 * PI / count as f32), V3::ZERO)
                    }
                    Integrand::Reflect {
                        shading_normal,
                        to_eye,
                        reflectance,
                        tint,
                    } => {
                        let cos = shading_normal.dot(direction);
                        if cos <= 0.0 {
                            continue;
                        }
                        let density = strategies.cosine as f32 * cos / PI
                            + if strategies.lobe > 0 {
                                strategies.lobe as f32
                                    * lobe_density(
                                        shading_normal,
                                        to_eye,
                                        reflectance.shininess,
                                        direction,
                                    )
                            } else {
                                0.0
                            };
                        let lambert = reflectance.albedo.modulate(tint) * (cos / density);
                        let lobe = reflectance.reflect(shading_normal, to_eye, direction)
                            - reflectance.albedo * cos;
                        (lambert, lobe.modulate(tint) * (1.0 / density))
                    }
                };
                // Below the geometric surface nothing arrives, whatever the shading
                // normal says: blocked without a ray.
                let open = g.geometric_normal.dot(direction) > 0.0 && {
                    rays += 1;
                    !self.scene.occluded(g.origin, direction, f32::INFINITY)
                };
                let value = if open { glossy } else { V3::ZERO - blocked };
                if value == V3::ZERO {
                    continue;
                }
                self.basis.eval(direction.into(), weights);
                let value = [value.x as f64, value.y as f64, value.z as f64];
                for (c, &v) in value.iter().enumerate() {
                    let v = v * scale;
                    for (o, &y) in out[c * k..(c + 1) * k].iter_mut().zip(weights.iter()) {
                        *o += v * y;
                    }
                }
                halves[half] += scale * (value[0] + value[1] + value[2]) / 3.0;
            }
        }
        rays
    }
}

/// How many bands `bands` (each coefficient's) span.
fn band_count(bands: &[usize]) -> usize {
    bands.iter().max().map_or(0, |&l| l + 1)
}

/// The Funk–Hecke factors `λ_l = 2π ∫₋₁¹ k(t) P_l(t) dt` of a kernel `k` of `n·ω` that
/// vanishes for `t ≤ 0`, for `l < bands`: `∫ k(n·ω) Y_lm(ω) dω = λ_l Y_lm(n)`, for every
/// function `Y_lm` of band `l` of a basis orthonormal band by band (a zonal kernel acts on
/// each band's functions as one factor).
pub(crate) fn funk_hecke(bands: usize, kernel: impl Fn(f64) -> f64) -> Vec<f64> {
    // The integrands are polynomials on [0, 1]: the midpoint rule with this many
    // steps is exact to about 1e-9.
    let steps = 1 << 14;
    let mut lambda = vec![0.0; bands];
    for s in 0..steps {
        let t = (s as f64 + 0.5) / steps as f64;
        let (mut previous, mut legendre) = (0.0, 1.0);
        for (l, value) in lambda.iter_mut().enumerate() {
            *value += kernel(t) * legendre / steps as f64;
            let next = ((2 * l + 1) as f64 * t * legendre - l as f64 * previous) / (l + 1) as f64;
            previous = legendre;
            legendre = next;
        }
    }
    lambda
        .iter()
        .map(|v| 2.0 * std::f64::consts::PI * v)
        .collect()
}

/// A direction drawn along the Blinn–Phong lobe of exponent `s` seen from `to_eye`: the
/// half vector with density `(s + 1)/(2π) cosˢθ_h` about `n`, reflected.
fn lobe_direction(n: V3, to_eye: V3, s: f32, u1: f32, u2: f32) -> V3 {
    let cos_h = u1.powf(1.0 / (s + 1.0));
    let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u2;
    let (t, b) = tangent_frame(n);
    let h = t * (sin_h * phi.cos()) + b * (sin_h * phi.sin()) + n * cos_h;
    h * (2.0 * to_eye.dot(h)) - to_eye
}

/// The density of [`lobe_direction`] at `direction`.
fn lobe_density(n: V3, to_eye: V3, s: f32, direction: V3) -> f32 {
    let h = (direction + to_eye).normalized();
    let (cos_h, cos_oh) = (n.dot(h), to_eye.dot(h));
    if cos_h <= 0.0 || cos_oh <= 0.0 || !h.is_finite() {
        return 0.0;
    }
    (s + 1.0) / std::f32::consts::TAU * cos_h.powf(s) / (4.0 * cos_oh)
}

/// Uniform density over the hemisphere about the unit normal `n` (frame `t`, `b`).
fn uniform_direction(n: V3, (t, b): (V3, V3), u1: f32, u2: f32) -> V3 {
    let z = u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u2;
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * z).normalized()
}

/// The base-2 radical inverse (van der Corput) of `i`, in `[0, 1)`.
fn radical_inverse(i: u32) -> f32 {
    (i.reverse_bits() as f64 / 4_294_967_296.0) as f32
}

/// A seed for sub-stream `salt` of `seed`.
fn hash_seed(seed: u32, salt: u32) -> u32 {
    let mut h = seed.wrapping_mul(0x9e37_79b9) ^ salt.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 16;
    h.wrapping_mul(0x7feb_352d)
}
