//! Light emitters as the tracer sees them: for a shading point, the directions light
//! arrives from, its irradiance and how far a shadow ray must reach.
//!
//! Every emitter answers one question, [`Illuminant::illuminate`]: "what light reaches
//! point P?", as zero or more [`Incident`] samples. A directional light gives one
//! sample with an infinite shadow ray; a point, spot or slide-projector light one
//! sample toward its position; an area light one per sample of its surface. The
//! lights of relit's engine ([`relit::light`]) are shone by the engine's own code
//! ([`EngineLight`]), so ground truth and relighting share one definition of every
//! light: the studio adds only the shadow rays. Adding a light the engine does not
//! have (an environment map, say) is a struct implementing [`Illuminant`] and one
//! [`Emitter`] variant.

use crate::math::V3;
use crate::{invalid, Result};
use relit::light::{Light, LightRig, PreparedLight};
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

/// Every emitter the tracer knows; each method forwards to the variant.
#[derive(Clone, Debug)]
pub enum Emitter {
    Directional(Directional),
    Engine(EngineLight),
}

impl Emitter {
    /// A directional light of RGB scale `rgb`.
    pub fn directional(direction: Vec3, rgb: [f64; 3]) -> Result<Emitter> {
        Ok(Emitter::Directional(Directional::new(direction, rgb)?))
    }

    /// The emitter of a relit light, so that ground truth and relighting share one
    /// description of every light. A projector's slide resolves against `base`.
    pub fn from_light_in(light: &Light, base: &Path) -> Result<Emitter> {
        light.validate()?;
        match light {
            Light::Directional(d) => Emitter::directional(d.direction, light.rgb()),
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
