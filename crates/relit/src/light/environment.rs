//! An environment light: a lat-long HDR/EXR map all around the scene (seed 003).
//!
//! With spherical-harmonic maps the relit pixel is one dot product, `Σ_i c_i e_i`, where
//! `e_i` are the map's SH coefficients (rotated and windowed; see [`crate::envmap`] for the
//! map's direction convention and the derivation). The cost does not depend on how many
//! images were captured, and rotating the environment rotates `e` in microseconds.

use super::{one, white};
use crate::basis::{rotation_from_yaw_pitch_roll, Mat3};
use crate::envmap::Window;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// `map` is a lat-long image file (relative to the rig file). The map is turned by
/// `yaw_deg` about +y, `pitch_deg` about +x and `roll_deg` about +z (roll first), and
/// its SH coefficients are attenuated by `window` against ringing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentMapLight {
    pub map: String,
    #[serde(default)]
    pub yaw_deg: f64,
    #[serde(default)]
    pub pitch_deg: f64,
    #[serde(default)]
    pub roll_deg: f64,
    #[serde(default)]
    pub window: Window,
    #[serde(default = "white")]
    pub color: [f64; 3],
    #[serde(default = "one")]
    pub intensity: f64,
}

impl EnvironmentMapLight {
    pub fn validate(&self) -> Result<()> {
        if self.map.is_empty() {
            return Err(Error::invalid("an environment light needs a `map` file"));
        }
        self.window.validate()?;
        self.rotation().map(|_| ())
    }

    /// The rotation applied to the map.
    pub fn rotation(&self) -> Result<Mat3> {
        rotation_from_yaw_pitch_roll(self.yaw_deg, self.pitch_deg, self.roll_deg)
    }
}
