//! Light emitters as the tracer sees them: for a shading point, the directions light
//! arrives from, its irradiance and how far a shadow ray must reach.
//!
//! Every emitter answers one question, [`Illuminant::illuminate`]: "what light reaches
//! point P?", as zero or more [`Incident`] samples. A directional light gives one
//! sample with an infinite shadow ray; the lights of issue 4 fit the same shape — a
//! point or spot light one sample toward its position (irradiance falling off as
//! 1/r², a spot's cone or a slide projector's image modulating it), an area light or
//! an environment map several samples with their own weights. Adding one is a struct
//! implementing [`Illuminant`], one [`Emitter`] variant, and one arm in
//! [`Emitter::from_light`].

use crate::math::V3;
use crate::{invalid, Result};
use relit::light::Light;
use relit::sphere::Vec3;

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
    /// Call `emit` once per sample of the light reaching `point`.
    fn illuminate(&self, point: V3, emit: &mut dyn FnMut(Incident));
}

/// A light at infinity: the same direction and irradiance everywhere.
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
    fn illuminate(&self, _point: V3, emit: &mut dyn FnMut(Incident)) {
        emit(Incident {
            direction: self.direction,
            irradiance: self.irradiance,
            distance: f32::INFINITY,
        });
    }
}

/// Every emitter the tracer knows; each method forwards to the variant.
#[derive(Clone, Debug, PartialEq)]
pub enum Emitter {
    Directional(Directional),
}

impl Emitter {
    /// A directional light of RGB scale `rgb`.
    pub fn directional(direction: Vec3, rgb: [f64; 3]) -> Result<Emitter> {
        Ok(Emitter::Directional(Directional::new(direction, rgb)?))
    }

    /// The emitter of a relit light, so that ground truth and relighting share one
    /// description of every light.
    pub fn from_light(light: &Light) -> Result<Emitter> {
        light.validate()?;
        match light {
            Light::Directional(d) => Emitter::directional(d.direction, light.rgb()),
            // Lights the engine gains before the studio does are refused, not mis-rendered.
            #[allow(unreachable_patterns)]
            other => {
                let kind = serde_json::to_value(other)
                    .ok()
                    .and_then(|v| v["type"].as_str().map(String::from));
                Err(invalid(format!(
                    "the capture studio cannot render {} lights yet",
                    kind.unwrap_or_else(|| "these".into())
                )))
            }
        }
    }

    fn inner(&self) -> &dyn Illuminant {
        match self {
            Emitter::Directional(d) => d,
        }
    }
}

impl Illuminant for Emitter {
    fn illuminate(&self, point: V3, emit: &mut dyn FnMut(Incident)) {
        self.inner().illuminate(point, emit)
    }
}
