//! A light at infinity: one light vector for every pixel.

use super::{one, white};
use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// `direction` points toward the light; intensity 1 reproduces a captured image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectionalLight {
    pub direction: Vec3,
    #[serde(default = "white")]
    pub color: [f64; 3],
    #[serde(default = "one")]
    pub intensity: f64,
}

impl DirectionalLight {
    pub fn validate(&self) -> Result<()> {
        self.direction.normalized().ok_or_else(|| {
            Error::invalid("a directional light needs a non-zero finite direction")
        })?;
        Ok(())
    }

    /// The unit light vector.
    pub fn unit(&self) -> Vec3 {
        self.direction
            .normalized()
            .unwrap_or(Vec3::new(0.0, 0.0, 1.0))
    }
}
