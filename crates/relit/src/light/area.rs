//! Area lights: rectangles and disks, integrated by sampling the emitter.
//!
//! The relit value of a pixel is `∫_A f_p(ω(x)) · L_e · cos θ_e / r² dA`: each emitter
//! point `x` acts as a tiny directional light (from `ω`, the direction from the surface
//! point to `x`) of perpendicular irradiance `L_e cos θ_e dA / r²`. The integral is
//! estimated with `samples` stratified points, the strata shifted per pixel
//! (Cranley–Patterson rotation) so the residual error is fine noise rather than bands.
//! `samples` is the quality knob; the error against a converged integral is measured by
//! the light tests and `relit eval --scene`.

use super::{one, white, Emit};
use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

fn default_samples() -> usize {
    16
}

/// The emitting shape.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum AreaShape {
    /// A parallelogram `center ± u ± v`; it emits toward `u × v`.
    Rect { center: Vec3, u: Vec3, v: Vec3 },
    /// A disk of `radius` around `center`; it emits toward `normal`.
    Disk {
        center: Vec3,
        normal: Vec3,
        radius: f64,
    },
}

/// An area light of emitted radiance `color × intensity`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AreaLight {
    pub shape: AreaShape,
    #[serde(default = "white")]
    pub color: [f64; 3],
    #[serde(default = "one")]
    pub intensity: f64,
    /// Emit from both faces.
    #[serde(default)]
    pub two_sided: bool,
    /// Emitter samples per pixel.
    #[serde(default = "default_samples")]
    pub samples: usize,
}

impl AreaLight {
    pub fn validate(&self) -> Result<()> {
        if self.samples == 0 || self.samples > 4096 {
            return Err(Error::invalid("an area light needs 1 to 4096 samples"));
        }
        match &self.shape {
            AreaShape::Rect { center, u, v } => {
                if !center.is_finite() || u.cross(*v).normalized().is_none() {
                    return Err(Error::invalid(
                        "a rectangular light needs a finite centre and two non-parallel edges",
                    ));
                }
            }
            AreaShape::Disk {
                center,
                normal,
                radius,
            } => {
                if !center.is_finite()
                    || normal.normalized().is_none()
                    || !(*radius > 0.0 && radius.is_finite())
                {
                    return Err(Error::invalid(
                        "a disk light needs a finite centre, a normal and a positive radius",
                    ));
                }
            }
        }
        Ok(())
    }

    /// Area of the emitter.
    pub fn area(&self) -> f64 {
        match &self.shape {
            AreaShape::Rect { u, v, .. } => 4.0 * u.cross(*v).length(),
            AreaShape::Disk { radius, .. } => std::f64::consts::PI * radius * radius,
        }
    }

    /// The emitter point and normal for stratified coordinates `(s, t)` in `[0, 1)²`.
    pub fn point(&self, s: f64, t: f64) -> (Vec3, Vec3) {
        match &self.shape {
            AreaShape::Rect { center, u, v } => (
                *center + *u * (2.0 * s - 1.0) + *v * (2.0 * t - 1.0),
                u.cross(*v).normalized().expect("validated"),
            ),
            AreaShape::Disk {
                center,
                normal,
                radius,
            } => {
                let (n, a, b) = disk_frame(*normal);
                // Uniform over the disk: r = R√s.
                let (r, phi) = (radius * s.sqrt(), std::f64::consts::TAU * t);
                (*center + a * (r * phi.cos()) + b * (r * phi.sin()), n)
            }
        }
    }

    /// The strata of the samples: `columns × rows` cells of `[0, 1)²`, sample `k` in
    /// cell `(k mod columns, k div columns)` (the last row may be partly empty).
    pub fn strata(&self) -> (usize, usize) {
        let columns = (self.samples as f64).sqrt().ceil() as usize;
        (columns, self.samples.div_ceil(columns))
    }

    /// The unit normal of a disk and the unit vectors of its `φ = 0` and `φ = π/2` axes
    /// ([`AreaLight::point`]); `None` for a rectangle.
    pub fn disk_frame(&self) -> Option<(Vec3, Vec3, Vec3)> {
        match &self.shape {
            AreaShape::Disk { normal, .. } => Some(disk_frame(*normal)),
            AreaShape::Rect { .. } => None,
        }
    }

    /// The per-pixel shift of the strata (Cranley–Patterson rotation) of pixel `pixel`.
    #[inline]
    pub(crate) fn shift(pixel: usize) -> (f64, f64) {
        cranley_patterson(pixel)
    }

    /// The light reaching surface point `p` (of pixel `pixel`, which seeds the strata
    /// shift). The CPU engine computes the same samples eight pixels at a time in f32
    /// (`engine/kernels/lights.rs`): a change here must be made there too.
    pub fn illuminate(&self, p: Vec3, pixel: usize, rgb: [f64; 3], emit: &mut Emit) {
        let n = self.samples;
        let (columns, rows) = self.strata();
        let (jx, jy) = cranley_patterson(pixel);
        let weight = self.area() / n as f64;
        for k in 0..n {
            let s = ((k % columns) as f64 + jx) / columns as f64;
            let t = ((k / columns) as f64 + jy) / rows as f64;
            let (x, normal) = self.point(s, t);
            let to_light = x - p;
            let r2 = to_light.dot(to_light);
            let Some(l) = to_light.normalized() else {
                continue;
            };
            let mut cos_e = -(l.dot(normal));
            if self.two_sided {
                cos_e = cos_e.abs();
            }
            if cos_e <= 0.0 || r2 <= 1e-18 {
                continue;
            }
            let g = weight * cos_e / r2;
            emit(l, rgb.map(|c| c * g));
        }
    }
}

/// A disk's unit normal and the two unit vectors spanning its plane (`a`, `b`,
/// `a × b = n`), the axes of `φ = 0` and `φ = π/2` in [`AreaLight::point`].
fn disk_frame(normal: Vec3) -> (Vec3, Vec3, Vec3) {
    let n = normal.normalized().expect("validated");
    let helper = if n.x.abs() < 0.9 {
        Vec3::new(1.0, 0.0, 0.0)
    } else {
        Vec3::new(0.0, 1.0, 0.0)
    };
    let a = helper.cross(n).normalized().expect("not parallel");
    (n, a, n.cross(a))
}

/// A per-pixel shift in `[0, 1)²` from a hash of the pixel index.
#[inline]
fn cranley_patterson(pixel: usize) -> (f64, f64) {
    let mut h = (pixel as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    (
        (h & 0xFFFF_FFFF) as f64 / 4_294_967_296.0,
        (h >> 32) as f64 / 4_294_967_296.0,
    )
}
