//! A slide projector: a pinhole frustum that colours each pixel's light with the slide
//! image sampled where the surface point projects (seed 004, figure 9).

use super::{one, white, Attenuation, Emit};
use crate::image::ImageRgb;
use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

fn default_up() -> Vec3 {
    Vec3::new(0.0, 1.0, 0.0)
}

/// A projector at `position` aimed along `direction`, `up` giving the slide's up, with
/// vertical field of view `fov_deg`; the horizontal one follows the slide's aspect.
/// `slide` is an image file (relative to the rig file), linearised on loading.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectorLight {
    pub position: Vec3,
    pub direction: Vec3,
    #[serde(default = "default_up")]
    pub up: Vec3,
    pub fov_deg: f64,
    pub slide: String,
    #[serde(default = "white")]
    pub color: [f64; 3],
    #[serde(default = "one")]
    pub intensity: f64,
    #[serde(default)]
    pub attenuation: Attenuation,
}

/// A projector with its slide loaded and its frame computed.
///
/// The CPU engine evaluates [`PreparedProjector::illuminate`] eight pixels at a time in
/// f32 from these fields (`engine/kernels/lights.rs`): a change here must be made there
/// too.
#[derive(Clone, Debug)]
pub struct PreparedProjector {
    pub light: ProjectorLight,
    pub(crate) slide: Arc<ImageRgb>,
    /// Unit vectors of the frustum: along its axis, toward the slide's right and up.
    pub(crate) forward: Vec3,
    pub(crate) right: Vec3,
    pub(crate) up: Vec3,
    pub(crate) tan_half_y: f64,
    pub(crate) tan_half_x: f64,
}

impl ProjectorLight {
    pub fn validate(&self) -> Result<()> {
        if !self.position.is_finite() || self.direction.normalized().is_none() {
            return Err(Error::invalid(
                "a projector needs a finite position and a non-zero direction",
            ));
        }
        if !(self.fov_deg > 0.0 && self.fov_deg < 179.0) {
            return Err(Error::invalid("a projector's fov_deg must be in (0, 179)"));
        }
        if self.up.cross(self.direction).normalized().is_none() {
            return Err(Error::invalid(
                "a projector's up must not be parallel to its direction",
            ));
        }
        self.attenuation.validate()
    }

    /// Load the slide (relative to `base`) and set up the frustum.
    pub fn prepare(&self, base: &Path) -> Result<PreparedProjector> {
        self.validate()?;
        let path = base.join(&self.slide);
        let slide = crate::image::load_linear(&path, None)?;
        Ok(self.with_slide(Arc::new(slide)))
    }

    /// Set up the frustum with a slide already in memory.
    pub fn with_slide(&self, slide: Arc<ImageRgb>) -> PreparedProjector {
        let forward = self.direction.normalized().expect("validated");
        let right = forward.cross(self.up).normalized().expect("validated");
        let up = right.cross(forward);
        let tan_half_y = (0.5 * self.fov_deg.to_radians()).tan();
        let aspect = slide.width as f64 / slide.height.max(1) as f64;
        PreparedProjector {
            light: self.clone(),
            slide,
            forward,
            right,
            up,
            tan_half_y,
            tan_half_x: tan_half_y * aspect,
        }
    }
}

impl PreparedProjector {
    /// The slide's linear colour where `p` projects, or `None` outside the frustum.
    pub fn slide_color(&self, p: Vec3) -> Option<[f64; 3]> {
        let d = p - self.light.position;
        let z = d.dot(self.forward);
        if z <= 1e-9 {
            return None;
        }
        let sx = d.dot(self.right) / (z * self.tan_half_x);
        let sy = d.dot(self.up) / (z * self.tan_half_y);
        if sx.abs() > 1.0 || sy.abs() > 1.0 {
            return None;
        }
        // Slide pixel coordinates: x right, y down, centres at half-integers.
        let (w, h) = (self.slide.width as f64, self.slide.height as f64);
        let fx = ((sx + 1.0) * 0.5 * w - 0.5).clamp(0.0, w - 1.0);
        let fy = ((1.0 - sy) * 0.5 * h - 0.5).clamp(0.0, h - 1.0);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = (
            (x0 + 1).min(self.slide.width - 1),
            (y0 + 1).min(self.slide.height - 1),
        );
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        let (a, b, c, e) = (
            self.slide.get(x0, y0),
            self.slide.get(x1, y0),
            self.slide.get(x0, y1),
            self.slide.get(x1, y1),
        );
        Some(std::array::from_fn(|k| {
            let top = a[k] as f64 * (1.0 - tx) + b[k] as f64 * tx;
            let bottom = c[k] as f64 * (1.0 - tx) + e[k] as f64 * tx;
            top * (1.0 - ty) + bottom * ty
        }))
    }

    /// The light reaching surface point `p`.
    pub fn illuminate(&self, p: Vec3, rgb: [f64; 3], emit: &mut Emit) {
        let to_light = self.light.position - p;
        let Some(l) = to_light.normalized() else {
            return;
        };
        let Some(slide) = self.slide_color(p) else {
            return;
        };
        let a = self.light.attenuation.factor(to_light.length());
        emit(l, std::array::from_fn(|k| rgb[k] * slide[k] * a));
    }
}
