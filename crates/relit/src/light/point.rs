//! A point light: the light vector differs per pixel, `L = S − P` (seed 000 eq. 2).

use super::{one, white, Attenuation, Emit};
use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// A point light at `position` (light frame, scene units). Its `intensity` is the
/// irradiance it gives at unit distance, relative to a unit directional light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointLight {
    pub position: Vec3,
    #[serde(default = "white")]
    pub color: [f64; 3],
    #[serde(default = "one")]
    pub intensity: f64,
    #[serde(default)]
    pub attenuation: Attenuation,
}

impl PointLight {
    pub fn validate(&self) -> Result<()> {
        if !self.position.is_finite() {
            return Err(Error::invalid("a point light needs a finite position"));
        }
        self.attenuation.validate()
    }

    /// The light reaching surface point `p`.
    pub fn illuminate(&self, p: Vec3, rgb: [f64; 3], emit: &mut Emit) {
        let to_light = self.position - p;
        let distance = to_light.length();
        if let Some(l) = to_light.normalized() {
            let a = self.attenuation.factor(distance);
            emit(l, rgb.map(|c| c * a));
        }
    }
}
