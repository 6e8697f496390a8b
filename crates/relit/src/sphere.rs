//! Directions on the unit sphere and the light plans captures are made with.
//!
//! Directions follow the light frame of the [crate conventions](crate): light vectors
//! point toward the light; x right, y up, z toward the camera.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::ops::{Add, Mul, Neg, Sub};

/// A 3-vector in the light frame (or any right-handed frame the context names).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(from = "[f64; 3]", into = "[f64; 3]")]
pub struct Vec3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

impl Vec3 {
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Self { x, y, z }
    }
    pub fn dot(self, o: Self) -> f64 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    pub fn length(self) -> f64 {
        self.dot(self).sqrt()
    }
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
    /// The unit vector along `self`, or `None` for a zero or non-finite vector.
    pub fn normalized(self) -> Option<Self> {
        let len = self.length();
        (self.is_finite() && len.is_finite() && len > 1e-12).then(|| self * (1.0 / len))
    }
    /// Polar angle from +z and azimuth from +x toward +y, in radians.
    pub fn to_spherical(self) -> (f64, f64) {
        (self.z.clamp(-1.0, 1.0).acos(), self.y.atan2(self.x))
    }
    /// The unit vector at polar angle `theta` (from +z) and azimuth `phi`.
    pub fn from_spherical(theta: f64, phi: f64) -> Self {
        let s = theta.sin();
        Self::new(s * phi.cos(), s * phi.sin(), theta.cos())
    }
}

impl From<[f64; 3]> for Vec3 {
    fn from(a: [f64; 3]) -> Self {
        Self::new(a[0], a[1], a[2])
    }
}
impl From<Vec3> for [f64; 3] {
    fn from(v: Vec3) -> Self {
        [v.x, v.y, v.z]
    }
}
impl Add for Vec3 {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl Sub for Vec3 {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl Mul<f64> for Vec3 {
    type Output = Self;
    fn mul(self, s: f64) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}
impl Neg for Vec3 {
    type Output = Self;
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}

/// `n` nearly uniform directions over the whole sphere (spherical Fibonacci lattice).
pub fn fibonacci(n: usize) -> Vec<Vec3> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// `n` nearly uniform directions over the upper hemisphere `z > 0`, as an RTI dome lights.
pub fn hemisphere_fibonacci(n: usize) -> Vec<Vec3> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// The centres of a `n_theta × n_phi` spherical grid (seed 004 samples 70×140), ring by ring.
pub fn grid(n_theta: usize, n_phi: usize) -> Vec<Vec3> {
    let mut dirs = Vec::with_capacity(n_theta * n_phi);
    for t in 0..n_theta {
        let theta = PI * (t as f64 + 0.5) / n_theta as f64;
        for p in 0..n_phi {
            let phi = 2.0 * PI * (p as f64 + 0.5) / n_phi as f64;
            dirs.push(Vec3::from_spherical(theta, phi));
        }
    }
    dirs
}

/// Quadrature weights (mean 1) when `dirs` form a full spherical grid of latitude rings,
/// each ring evenly spaced in azimuth; `None` for any other layout.
///
/// A least-squares fit with equal weights over a θ×φ grid over-weights the poles,
/// where rings crowd together; weighting each sample by the solid angle of its cell
/// turns the fit into the quadrature of the projection integral of seed 000's appendix.
pub fn grid_quadrature_weights(dirs: &[Vec3]) -> Option<Vec<f64>> {
    const RING_TOLERANCE: f64 = 1e-6; // polar angles closer than this share a ring
    if dirs.len() < 8 {
        return None;
    }
    let angles: Vec<(f64, f64)> = dirs.iter().map(|d| d.to_spherical()).collect();
    let mut thetas: Vec<f64> = angles.iter().map(|a| a.0).collect();
    thetas.sort_by(f64::total_cmp);
    thetas.dedup_by(|a, b| (*a - *b).abs() < RING_TOLERANCE);
    let rings = thetas.len();
    if rings < 3 || rings * 3 > dirs.len() {
        return None;
    }
    // The rings must reach both poles: the first and last sit within one spacing of them.
    let spacing = PI / rings as f64;
    if thetas[0] > 1.01 * spacing || thetas[rings - 1] < PI - 1.01 * spacing {
        return None;
    }
    let ring_of = |theta: f64| {
        thetas
            .iter()
            .position(|t| (t - theta).abs() < RING_TOLERANCE)
    };
    let mut counts = vec![0usize; rings];
    let mut phis: Vec<Vec<f64>> = vec![Vec::new(); rings];
    for &(theta, phi) in &angles {
        let r = ring_of(theta)?;
        counts[r] += 1;
        phis[r].push(phi);
    }
    // Each ring must be evenly spaced in azimuth.
    for ring in &mut phis {
        if ring.len() < 3 {
            return None;
        }
        ring.sort_by(f64::total_cmp);
        let step = 2.0 * PI / ring.len() as f64;
        for w in ring.windows(2) {
            if ((w[1] - w[0]) - step).abs() > 1e-4 {
                return None;
            }
        }
    }
    // The band of ring r spans the midpoints to its neighbours (the poles at the ends).
    let edge = |r: usize| -> f64 {
        if r == 0 {
            0.0
        } else if r == rings {
            PI
        } else {
            0.5 * (thetas[r - 1] + thetas[r])
        }
    };
    let band: Vec<f64> = (0..rings)
        .map(|r| 2.0 * PI * (edge(r).cos() - edge(r + 1).cos()))
        .collect();
    let mut weights: Vec<f64> = angles
        .iter()
        .map(|&(theta, _)| {
            let r = ring_of(theta).unwrap_or(0);
            band[r] / counts[r] as f64
        })
        .collect();
    let mean = weights.iter().sum::<f64>() / weights.len() as f64;
    weights.iter_mut().for_each(|w| *w /= mean);
    Some(weights)
}

/// The light vector of texture position `(u, v)` of a lat-long map: `θ = π·v` from +y,
/// azimuth `α = 2π·(u − ½)` from −z toward +x, `ω = (sin θ sin α, cos θ, −sin θ cos α)`;
/// the centre column looks along −z and the seam is behind the camera, the layout of a
/// panorama taken by the equirectangular camera at the default pose.
pub fn latlong_direction(u: f64, v: f64) -> Vec3 {
    let (sin_t, cos_t) = (PI * v).sin_cos();
    let (sin_a, cos_a) = (2.0 * PI * (u - 0.5)).sin_cos();
    Vec3::new(sin_t * sin_a, cos_t, -sin_t * cos_a)
}

/// The texture position `[u, v]` of the non-zero direction `dir`: the inverse of
/// [`latlong_direction`], with `u ∈ [0, 1]` (both ends are the seam behind the camera)
/// and `v ∈ [0, 1]`.
pub fn latlong_uv(dir: Vec3) -> [f64; 2] {
    let u = dir.x.atan2(-dir.z) / (2.0 * PI) + 0.5;
    let v = dir.x.hypot(dir.z).atan2(dir.y) / PI;
    [u, v]
}

/// The solid angle of a texel in row `row` of a `width × height` lat-long map:
/// `(2π / width)·(cos θ_top − cos θ_bottom)`.
pub fn texel_solid_angle(width: usize, height: usize, row: usize) -> f64 {
    let theta = |r: usize| PI * r as f64 / height as f64;
    2.0 * PI / width as f64 * (theta(row).cos() - theta(row + 1).cos())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_are_unit_and_in_their_domain() {
        for d in fibonacci(100).iter().chain(grid(7, 14).iter()) {
            assert!((d.length() - 1.0).abs() < 1e-12);
        }
        assert!(hemisphere_fibonacci(50)
            .iter()
            .all(|d| d.z > 0.0 && (d.length() - 1.0).abs() < 1e-12));
    }

    #[test]
    fn grid_weights_integrate_the_sphere() {
        let dirs = grid(24, 48);
        let w = grid_quadrature_weights(&dirs).expect("a full grid is recognised");
        // Mean-1 weights times 4π/N integrate: ∫ z² dω = 4π/3 (midpoint rule over 24
        // bands: error ~0.2%).
        let integral: f64 = dirs.iter().zip(&w).map(|(d, w)| w * d.z * d.z).sum::<f64>() * 4.0 * PI
            / dirs.len() as f64;
        assert!((integral - 4.0 * PI / 3.0).abs() < 0.01, "{integral}");
        assert!(grid_quadrature_weights(&fibonacci(200)).is_none());
        assert!(grid_quadrature_weights(&hemisphere_fibonacci(60)).is_none());
    }

    #[test]
    fn normalize_rejects_degenerate_vectors() {
        assert!(Vec3::new(0.0, 0.0, 0.0).normalized().is_none());
        assert!(Vec3::new(f64::NAN, 0.0, 1.0).normalized().is_none());
        assert!(Vec3::new(f64::INFINITY, 0.0, 1.0).normalized().is_none());
        let n = Vec3::new(0.0, 3.0, 4.0).normalized().unwrap();
        assert!((n - Vec3::new(0.0, 0.6, 0.8)).length() < 1e-15);
    }
}
