//! A spotlight: a point light limited to a cone with a soft edge.

use super::{one, white, Attenuation, Emit};
use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

fn default_softness() -> f64 {
    5.0
}

/// A spotlight at `position` shining along `direction` (from the light into the scene).
/// Full intensity within `cone_deg − softness_deg` of the axis, none beyond `cone_deg`,
/// a smooth (smoothstep in cosine) edge between.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpotLight {
    pub position: Vec3,
    pub direction: Vec3,
    pub cone_deg: f64,
    #[serde(default = "default_softness")]
    pub softness_deg: f64,
    #[serde(default = "white")]
    pub color: [f64; 3],
    #[serde(default = "one")]
    pub intensity: f64,
    #[serde(default)]
    pub attenuation: Attenuation,
}

impl SpotLight {
    pub fn validate(&self) -> Result<()> {
        if !self.position.is_finite() || self.direction.normalized().is_none() {
            return Err(Error::invalid(
                "a spotlight needs a finite position and a non-zero direction",
            ));
        }
        let cone_ok = self.cone_deg > 0.0 && self.cone_deg < 180.0;
        if !cone_ok || self.softness_deg.is_nan() || self.softness_deg < 0.0 {
            return Err(Error::invalid(
                "a spotlight's cone_deg must be in (0, 180) and softness_deg ≥ 0",
            ));
        }
        self.attenuation.validate()
    }

    /// The cone's falloff for a point seen from the light at angle with cosine `cos_angle`.
    pub fn cone_factor(&self, cos_angle: f64) -> f64 {
        let outer = self.cone_deg.to_radians().cos();
        let inner = (self.cone_deg - self.softness_deg)
            .max(0.0)
            .to_radians()
            .cos();
        if cos_angle >= inner {
            return 1.0;
        }
        if cos_angle <= outer || inner <= outer {
            return 0.0;
        }
        let t = (cos_angle - outer) / (inner - outer);
        t * t * (3.0 - 2.0 * t)
    }

    /// The light reaching surface point `p`.
    pub fn illuminate(&self, p: Vec3, rgb: [f64; 3], emit: &mut Emit) {
        let to_light = self.position - p;
        let Some(l) = to_light.normalized() else {
            return;
        };
        let axis = self.direction.normalized().expect("validated");
        let cone = self.cone_factor((-l).dot(axis));
        if cone > 0.0 {
            let a = cone * self.attenuation.factor(to_light.length());
            emit(l, rgb.map(|c| c * a));
        }
    }
}
