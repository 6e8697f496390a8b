//! Light emitters as the tracer sees them: for a shading point, the directions light
//! arrives from, its irradiance and how far a shadow ray must reach.
//!
//! Every emitter answers one question, [`Illuminant::illuminate`]: "what light reaches
//! point P?", as zero or more [`Incident`] samples. A directional light gives one
//! sample with an infinite shadow ray; a point, spot or slide-projector light one
//! sample toward its position; an area light one per sample of its surface. The
//! lights of relit's engine ([`relit::light`]) are shone by the engine's own code
//! ([`EngineLight`]), so ground truth and relighting share one definition of every
//! light: the studio adds only the shadow rays. An environment map, which the engine
//! shines as SH weights (band-limited, windowed), is instead integrated here by
//! importance sampling the map itself ([`EnvironmentEmitter`]), so that its ground
//! truth is free of the engine's approximations.

use crate::math::V3;
use crate::{invalid, Result};
use relit::envmap::{latlong_direction, texel_solid_angle, EnvironmentLight};
use relit::light::{EnvironmentMapLight, Light, LightRig, PreparedLight};
use relit::sphere::Vec3;
use std::path::Path;

/// Light arriving at a point from one direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Unit vector from the point toward the light.
    pub direction: V3,
    /// RGB irradiance on a surface facing the light, in relit's unit: a unit
    /// directional light gives 1 (see [`crate::material`]).
    pub irradiance: V3,
    /// How far the shadow ray must stay clear (∞ for lights at infinity).
    pub distance: f32,
}

/// Anything that lights a scene.
pub trait Illuminant: Send + Sync {
    /// Call `emit` once per sample of the light reaching `point`, seen through image
    /// pixel `pixel` (sampled lights vary their pattern per pixel).
    fn illuminate(&self, point: V3, pixel: usize, emit: &mut dyn FnMut(Incident));
}

/// A light at infinity: the same direction and irradiance everywhere (the capture
/// light, kept apart from [`EngineLight`] because captures shine it millions of times).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Directional {
    direction: V3,
    irradiance: V3,
}

impl Directional {
    /// A light toward `direction` (normalised; light frame) with RGB scale `rgb`.
    pub fn new(direction: Vec3, rgb: [f64; 3]) -> Result<Directional> {
        let direction = direction
            .normalized()
            .ok_or_else(|| invalid("a directional light needs a non-zero finite direction"))?;
        if rgb.iter().any(|c| !c.is_finite()) {
            return Err(invalid("a light's colour must be finite"));
        }
        Ok(Directional {
            direction: direction.into(),
            irradiance: V3::from(rgb.map(|c| c as f32)),
        })
    }

    /// The unit direction toward the light.
    pub fn direction(&self) -> V3 {
        self.direction
    }
}

impl Illuminant for Directional {
    fn illuminate(&self, _point: V3, _pixel: usize, emit: &mut dyn FnMut(Incident)) {
        emit(Incident {
            direction: self.direction,
            irradiance: self.irradiance,
            distance: f32::INFINITY,
        })
    }
}

/// Any light of relit's engine, evaluated by the engine's code; the studio adds how
/// far each incident sample's shadow ray must reach.
#[derive(Clone, Debug)]
pub struct EngineLight {
    light: PreparedLight,
}

/// Shadow rays toward a light with a position stop this fraction short of it, so the
/// geometry of a lamp placed at the light does not shadow its own light.
const SHORT_OF_THE_LIGHT: f64 = 1e-4;

impl EngineLight {
    /// Prepare `light`; files it refers to (a projector's slide) resolve against `base`.
    pub fn new(light: &Light, base: &Path) -> Result<EngineLight> {
        Ok(EngineLight {
            light: light.prepare(base)?,
        })
    }

    /// The distance from `p` to the light along unit direction `l`.
    fn distance(&self, p: Vec3, l: Vec3) -> f64 {
        let to = |position: Vec3| (position - p).length();
        match &self.light {
            PreparedLight::Directional { .. } => f64::INFINITY,
            PreparedLight::Point(light, _) => to(light.position),
            PreparedLight::Spot(light, _) => to(light.position),
            PreparedLight::Projector(light, _) => to(light.light.position),
            // Area lights are planar: the sample lies where the ray meets their plane.
            PreparedLight::Area(light, _) => {
                let (centre, normal) = light.point(0.5, 0.5);
                let along = l.dot(normal);
                if along.abs() < 1e-12 {
                    f64::INFINITY
                } else {
                    ((centre - p).dot(normal) / along).abs()
                }
            }
            // Lights the engine gains later without a position (an environment given
            // as basis weights) reach the tracer as lights at infinity, if at all.
            #[allow(unreachable_patterns)]
            _ => f64::INFINITY,
        }
    }
}

impl Illuminant for EngineLight {
    fn illuminate(&self, point: V3, pixel: usize, emit: &mut dyn FnMut(Incident)) {
        let p = Vec3::from(point);
        self.light
            .illuminate(p, pixel, &mut |l: Vec3, rgb: [f64; 3]| {
                let distance = self.distance(p, l) * (1.0 - SHORT_OF_THE_LIGHT);
                emit(Incident {
                    direction: V3::from(l),
                    irradiance: V3::from(rgb.map(|c| c as f32)),
                    distance: if distance.is_finite() {
                        distance as f32
                    } else {
                        f32::INFINITY
                    },
                })
            });
    }
}

/// An environment map all around the scene, integrated per shading point by sampling
/// its texels in proportion to their power (luminance × solid angle, with a floor so
/// that every texel can be drawn), stratified over the samples and decorrelated between
/// pixels. Each sample is a light at infinity with irradiance `E·ΔΩ / (p·N)`, so the
/// estimate of `∫ f E dω` is unbiased; the noise falls as `1/√N`.
#[derive(Clone, Debug)]
pub struct EnvironmentEmitter {
    light: EnvironmentLight,
    rgb: [f32; 3],
    samples: usize,
    /// Cumulative texel power, normalised to end at 1.
    cdf: Vec<f64>,
    /// Irradiance factor `ΔΩ_t / p_t` of each texel (the inverse of its draw
    /// probability per unit solid angle).
    inverse_pdf: Vec<f64>,
}

/// Samples per shading point of an environment emitter unless told otherwise.
pub const DEFAULT_ENVIRONMENT_SAMPLES: usize = 256;

impl EnvironmentEmitter {
    /// The rig light `light` (map file relative to `base`), `samples` draws per point.
    pub fn new(light: &EnvironmentMapLight, base: &Path, samples: usize) -> Result<Self> {
        light.validate()?;
        if samples == 0 {
            return Err(invalid("an environment emitter needs at least one sample"));
        }
        let env =
            EnvironmentLight::load(&base.join(&light.map))?.with_rotation(light.rotation()?)?;
        let map = env.map();
        let (w, h) = (map.width, map.height);
        let power: Vec<f64> = (0..w * h)
            .map(|t| {
                let rgb = map.get(t % w, t / w);
                let luminance = rgb.iter().map(|&c| c.max(0.0) as f64).sum::<f64>() / 3.0;
                luminance * texel_solid_angle(w, h, t / w)
            })
            .collect();
        let total: f64 = power.iter().sum();
        // A floor of 1% of the mean keeps dark texels reachable (no bias where the
        // map is black but a colour channel is not).
        let floor = 0.01 * total / (w * h) as f64 + 1e-30;
        let weights: Vec<f64> = power.iter().map(|p| p + floor).collect();
        let sum: f64 = weights.iter().sum();
        let mut cdf = Vec::with_capacity(w * h);
        let mut acc = 0.0;
        for wt in &weights {
            acc += wt / sum;
            cdf.push(acc);
        }
        let inverse_pdf = weights
            .iter()
            .enumerate()
            .map(|(t, wt)| texel_solid_angle(w, h, t / w) * sum / wt)
            .collect();
        Ok(EnvironmentEmitter {
            light: env,
            rgb: Light::Environment(light.clone()).rgb().map(|c| c as f32),
            samples,
            cdf,
            inverse_pdf,
        })
    }
}

/// A well-mixed 64-bit hash (SplitMix64's finaliser) of a pixel and a sample index.
fn hash(a: u64, b: u64) -> u64 {
    let mut z = a.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ b.wrapping_add(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn unit(bits: u64) -> f64 {
    (bits >> 11) as f64 / (1u64 << 53) as f64
}

impl Illuminant for EnvironmentEmitter {
    fn illuminate(&self, _point: V3, pixel: usize, emit: &mut dyn FnMut(Incident)) {
        let map = self.light.map();
        let (w, h) = (map.width, map.height);
        let n = self.samples;
        let rotation = self.light.rotation();
        let offset = unit(hash(pixel as u64, 0x5eed));
        for i in 0..n {
            // Stratified over the CDF with one random shift per pixel.
            let xi = ((i as f64 + offset) / n as f64).min(1.0 - 1e-16);
            let t = self.cdf.partition_point(|&c| c <= xi).min(w * h - 1);
            let (col, row) = (t % w, t / w);
            let r = hash(pixel as u64, i as u64 + 1);
            let u = (col as f64 + unit(r)) / w as f64;
            // Uniform in cos θ inside the texel's row: uniform in solid angle.
            let (top, bottom) = (
                (std::f64::consts::PI * row as f64 / h as f64).cos(),
                (std::f64::consts::PI * (row + 1) as f64 / h as f64).cos(),
            );
            let cos_t = top + (bottom - top) * unit(hash(r, 7));
            let v = cos_t.clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
            let local = latlong_direction(u, v);
            let direction = relit::basis::mat3_apply(&rotation, local);
            let radiance = map.get(col, row);
            let scale = self.inverse_pdf[t] / n as f64;
            emit(Incident {
                direction: V3::from(direction),
                irradiance: V3::from(std::array::from_fn::<f32, 3, _>(|c| {
                    (radiance[c] as f64 * scale) as f32 * self.rgb[c]
                })),
                distance: f32::INFINITY,
            });
        }
    }
}

/// Every emitter the tracer knows; each method forwards to the variant.
#[derive(Clone, Debug)]
pub enum Emitter {
    Directional(Directional),
    Engine(EngineLight),
    Environment(Box<EnvironmentEmitter>),
}

impl Emitter {
    /// A directional light of RGB scale `rgb`.
    pub fn directional(direction: Vec3, rgb: [f64; 3]) -> Result<Emitter> {
        Ok(Emitter::Directional(Directional::new(direction, rgb)?))
    }

    /// The emitter of a relit light, so that ground truth and relighting share one
    /// description of every light. A projector's slide resolves against `base`.
    pub fn from_light_in(light: &Light, base: &Path) -> Result<Emitter> {
        Emitter::from_light_sampled(light, base, DEFAULT_ENVIRONMENT_SAMPLES)
    }

    /// [`Emitter::from_light_in`] with `environment_samples` samples per shading point
    /// for an environment light.
    pub fn from_light_sampled(
        light: &Light,
        base: &Path,
        environment_samples: usize,
    ) -> Result<Emitter> {
        light.validate()?;
        match light {
            Light::Directional(d) => Emitter::directional(d.direction, light.rgb()),
            Light::Environment(e) => Ok(Emitter::Environment(Box::new(EnvironmentEmitter::new(
                e,
                base,
                environment_samples,
            )?))),
            _ => Ok(Emitter::Engine(EngineLight::new(light, base)?)),
        }
    }

    /// [`Emitter::from_light_in`] with files relative to the working folder.
    pub fn from_light(light: &Light) -> Result<Emitter> {
        Emitter::from_light_in(light, Path::new("."))
    }

    /// The emitters of a light rig read from `path` (relit's rig JSON).
    pub fn from_rig_file(path: &Path) -> Result<Vec<Emitter>> {
        let rig = LightRig::load(path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        rig.lights
            .iter()
            .map(|l| Emitter::from_light_in(l, base))
            .collect()
    }

    fn inner(&self) -> &dyn Illuminant {
        match self {
            Emitter::Directional(d) => d,
            Emitter::Engine(e) => e,
            Emitter::Environment(e) => e.as_ref(),
        }
    }
}

impl Illuminant for Emitter {
    fn illuminate(&self, point: V3, pixel: usize, emit: &mut dyn FnMut(Incident)) {
        self.inner().illuminate(point, pixel, emit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::v3;

    fn collect(e: &Emitter, p: V3) -> Vec<Incident> {
        let mut out = Vec::new();
        e.illuminate(p, 7, &mut |i| out.push(i));
        out
    }

    #[test]
    fn engine_lights_get_shadow_distances() {
        let point = Emitter::from_light(&Light::point([0.0, 4.0, 0.0], [1.0; 3])).unwrap();
        let got = collect(&point, v3(0.0, 1.0, 0.0));
        assert_eq!(got.len(), 1);
        assert!((got[0].direction - v3(0.0, 1.0, 0.0)).length() < 1e-6);
        assert!(
            (got[0].distance - 3.0).abs() < 1e-3 && got[0].distance < 3.0,
            "{}",
            got[0].distance
        );
        let rig: LightRig = serde_json::from_str(
            r#"{"lights":[{"type":"area","shape":{"rect":{"center":[0,3,0],"u":[0.5,0,0],"v":[0,0,0.5]}},"samples":4}]}"#,
        )
        .unwrap();
        let area = Emitter::from_light(&rig.lights[0]).unwrap();
        let samples = collect(&area, v3(0.2, 0.0, 0.1));
        assert_eq!(
            samples.len(),
            4,
            "the rectangle faces down, toward the point"
        );
        for incident in samples {
            // Each sample's shadow ray ends on the light's plane, y = 3.
            let end = v3(0.2, 0.0, 0.1) + incident.direction * incident.distance;
            assert!((end.y - 3.0).abs() < 1e-3, "{end:?}");
        }
        let sun = Emitter::from_light(&Light::directional([0.0, 0.0, 2.0], [1.0; 3])).unwrap();
        assert!(matches!(sun, Emitter::Directional(_)));
        assert_eq!(collect(&sun, V3::ZERO)[0].distance, f32::INFINITY);
    }
}
