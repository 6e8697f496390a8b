//! Per-pixel light vectors and weights of the positional lights, a block of
//! [`BLOCK`] pixels at a time, in f32: point and spot lights ([`Simd::light_block`]),
//! projectors ([`Simd::projector_block`]) and the samples of area lights
//! ([`Simd::area_sample`]). Each is the f32 form of the light's own `illuminate`
//! (`crate::light`), which the engine's tests compare with per pixel in f64.

use super::{Simd, BLOCK};
use crate::image::ImageRgb;
use crate::light::{AreaLight, AreaShape, Attenuation, PreparedProjector};
use crate::sphere::Vec3;
use std::sync::Arc;

fn f3(v: Vec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

#[inline(always)]
fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// How a positional light's irradiance falls off with distance `d` (as
/// `light::Attenuation`, in f32; `d` is clamped to 1e-9 first).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Falloff {
    InverseSquare,
    InverseDistance(f32),
    None,
}

impl Falloff {
    pub(crate) fn of(a: Attenuation) -> Self {
        match a {
            Attenuation::InverseSquare => Falloff::InverseSquare,
            Attenuation::InverseDistance(c0) => Falloff::InverseDistance(c0 as f32),
            Attenuation::None => Falloff::None,
        }
    }
}

/// A spotlight's cone: unit axis from the light into the scene, cosines of the outer
/// and inner half-angles (`SpotLight::cone_factor`, in f32).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cone {
    pub axis: [f32; 3],
    pub outer: f32,
    pub inner: f32,
}

impl Simd {
    /// Unit light vectors from a block of surface points `at` (NaN where nothing was
    /// hit) toward `position`, and the factor (falloff × cone) of each; pixels without
    /// a surface point, or on the light, get a zero vector and factor 0.
    pub(crate) fn light_block(
        self,
        position: [f32; 3],
        falloff: Falloff,
        cone: Option<Cone>,
        at: &[[f32; BLOCK]; 3],
        dir: &mut [[f32; BLOCK]; 3],
        factor: &mut [f32; BLOCK],
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `axpy`.
            return unsafe { light_block_avx2(position, falloff, cone, at, dir, factor) };
        }
        light_block_body(position, falloff, cone, at, dir, factor)
    }
}

#[inline(always)]
fn light_block_body(
    position: [f32; 3],
    falloff: Falloff,
    cone: Option<Cone>,
    at: &[[f32; BLOCK]; 3],
    dir: &mut [[f32; BLOCK]; 3],
    factor: &mut [f32; BLOCK],
) {
    let mut dist = [0f32; BLOCK];
    for p in 0..BLOCK {
        let d = [
            position[0] - at[0][p],
            position[1] - at[1][p],
            position[2] - at[2][p],
        ];
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        // NaN (no surface point) fails both comparisons.
        let ok = r > 1e-12 && r < f32::INFINITY;
        let inv = if ok { 1.0 / r } else { 0.0 };
        for a in 0..3 {
            dir[a][p] = if ok { d[a] * inv } else { 0.0 };
        }
        dist[p] = if ok { r.max(1e-9) } else { 0.0 };
    }
    match falloff {
        Falloff::InverseSquare => {
            for p in 0..BLOCK {
                factor[p] = if dist[p] > 0.0 {
                    1.0 / (dist[p] * dist[p])
                } else {
                    0.0
                };
            }
        }
        Falloff::InverseDistance(c0) => {
            for p in 0..BLOCK {
                factor[p] = if dist[p] > 0.0 { c0 / dist[p] } else { 0.0 };
            }
        }
        Falloff::None => {
            for p in 0..BLOCK {
                factor[p] = if dist[p] > 0.0 { 1.0 } else { 0.0 };
            }
        }
    }
    if let Some(Cone { axis, outer, inner }) = cone {
        let soft = inner > outer;
        let scale = if soft { 1.0 / (inner - outer) } else { 0.0 };
        for p in 0..BLOCK {
            let cos = -(dir[0][p] * axis[0] + dir[1][p] * axis[1] + dir[2][p] * axis[2]);
            let edge = if soft {
                let t = ((cos - outer) * scale).clamp(0.0, 1.0);
                t * t * (3.0 - 2.0 * t)
            } else if cos >= inner {
                1.0
            } else {
                0.0
            };
            factor[p] *= edge;
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn light_block_avx2(
    position: [f32; 3],
    falloff: Falloff,
    cone: Option<Cone>,
    at: &[[f32; BLOCK]; 3],
    dir: &mut [[f32; BLOCK]; 3],
    factor: &mut [f32; BLOCK],
) {
    light_block_body(position, falloff, cone, at, dir, factor)
}

/// An area light's emitter and its samples (`AreaLight::illuminate`, in f32).
#[derive(Clone, Debug)]
pub(crate) struct AreaSamples {
    emitter: Emitter,
    /// Unit normal of the emitting face.
    normal: [f32; 3],
    two_sided: bool,
    /// Area per sample.
    weight: f32,
    pub samples: usize,
    columns: usize,
    rows: usize,
    /// `cos`, `sin` of `2π·row/rows` for each row of strata (disks).
    row_angles: Vec<(f32, f32)>,
}

#[derive(Clone, Debug)]
enum Emitter {
    /// `center + a·u + b·v`, `a, b ∈ [−1, 1]`.
    Rect {
        center: [f32; 3],
        u: [f32; 3],
        v: [f32; 3],
    },
    /// `center + r cos φ · a + r sin φ · b`, `r ≤ radius`.
    Disk {
        center: [f32; 3],
        a: [f32; 3],
        b: [f32; 3],
        radius: f32,
    },
}

impl AreaSamples {
    /// The f32 form of a validated area light.
    pub(crate) fn new(light: &AreaLight) -> Option<Self> {
        let (columns, rows) = light.strata();
        let (emitter, normal) = match (&light.shape, light.disk_frame()) {
            (AreaShape::Rect { center, u, v }, _) => (
                Emitter::Rect {
                    center: f3(*center),
                    u: f3(*u),
                    v: f3(*v),
                },
                u.cross(*v).normalized()?,
            ),
            (AreaShape::Disk { center, radius, .. }, Some((n, a, b))) => (
                Emitter::Disk {
                    center: f3(*center),
                    a: f3(a),
                    b: f3(b),
                    radius: *radius as f32,
                },
                n,
            ),
            (AreaShape::Disk { .. }, None) => return None,
        };
        let row_angles = (0..rows)
            .map(|r| {
                let (s, c) = (std::f64::consts::TAU * r as f64 / rows as f64).sin_cos();
                (c as f32, s as f32)
            })
            .collect();
        Some(Self {
            emitter,
            normal: f3(normal),
            two_sided: light.two_sided,
            weight: (light.area() / light.samples as f64) as f32,
            samples: light.samples,
            columns,
            rows,
            row_angles,
        })
    }
}

/// The strata shift of a block's pixels (`AreaLight::shift`): `s` the shift in the
/// first coordinate; for rectangles `t` the shift in the second, for disks `cos β`,
/// `sin β` of the angle `β = 2π·shift / rows` it turns the samples by.
pub(crate) struct Shift {
    s: [f32; BLOCK],
    t: [f32; BLOCK],
    u: [f32; BLOCK],
}

impl Shift {
    pub(crate) fn new() -> Self {
        Self {
            s: [0.0; BLOCK],
            t: [0.0; BLOCK],
            u: [0.0; BLOCK],
        }
    }

    /// The shifts of pixels `pixel0 .. pixel0 + BLOCK` for `light` (scalar: a 64-bit
    /// hash per pixel, once per pixel for all its samples).
    pub(crate) fn fill(&mut self, light: &AreaSamples, pixel0: usize) {
        for p in 0..BLOCK {
            let (jx, jy) = AreaLight::shift(pixel0 + p);
            self.s[p] = jx as f32;
            match light.emitter {
                Emitter::Rect { .. } => self.t[p] = jy as f32,
                Emitter::Disk { .. } => {
                    let beta = std::f64::consts::TAU * jy / light.rows as f64;
                    let (s, c) = beta.sin_cos();
                    (self.t[p], self.u[p]) = (c as f32, s as f32);
                }
            }
        }
    }
}

impl Simd {
    /// Sample `k` of an area light at a block of surface points `at` (NaN where nothing
    /// was hit): the unit vectors toward the sample's emitter point and its weight
    /// `area/n · cos θ_e / r²`; zero vector and weight where the emitter faces away
    /// (one-sided), or the point has no surface or lies on the emitter.
    pub(crate) fn area_sample(
        self,
        light: &AreaSamples,
        k: usize,
        shift: &Shift,
        at: &[[f32; BLOCK]; 3],
        dir: &mut [[f32; BLOCK]; 3],
        weight: &mut [f32; BLOCK],
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `detect` found avx2, fma and f16c on this CPU.
            return unsafe { area_sample_avx2(light, k, shift, at, dir, weight) };
        }
        area_sample_body(light, k, shift, at, dir, weight)
    }
}

// Lane-wise loops over several arrays at once read best with an index.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn area_sample_body(
    light: &AreaSamples,
    k: usize,
    shift: &Shift,
    at: &[[f32; BLOCK]; 3],
    dir: &mut [[f32; BLOCK]; 3],
    weight: &mut [f32; BLOCK],
) {
    let column = (k % light.columns) as f32;
    let row = k / light.columns;
    let mut x = [[0f32; BLOCK]; 3];
    match &light.emitter {
        Emitter::Rect { center, u, v } => {
            let (su, sv) = (2.0 / light.columns as f32, 2.0 / light.rows as f32);
            let row = row as f32;
            for p in 0..BLOCK {
                let a = (column + shift.s[p]) * su - 1.0;
                let b = (row + shift.t[p]) * sv - 1.0;
                for d in 0..3 {
                    x[d][p] = center[d] + u[d] * a + v[d] * b;
                }
            }
        }
        Emitter::Disk {
            center,
            a,
            b,
            radius,
        } => {
            let inv = 1.0 / light.columns as f32;
            // φ = 2π·row/rows + β: the angle sum, β's cosine and sine per pixel.
            let (ca, sa) = light.row_angles[row];
            for p in 0..BLOCK {
                let r = radius * ((column + shift.s[p]) * inv).sqrt();
                let (cb, sb) = (shift.t[p], shift.u[p]);
                let (c, s) = (r * (ca * cb - sa * sb), r * (sa * cb + ca * sb));
                for d in 0..3 {
                    x[d][p] = center[d] + a[d] * c + b[d] * s;
                }
            }
        }
    }
    let n = light.normal;
    for p in 0..BLOCK {
        let d = [x[0][p] - at[0][p], x[1][p] - at[1][p], x[2][p] - at[2][p]];
        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        // NaN (no surface point) fails both comparisons.
        let ok = r2 > 1e-18 && r2 < f32::INFINITY;
        let inv = if ok { 1.0 / r2.sqrt() } else { 0.0 };
        let l = d.map(|v| v * inv);
        let mut cos = -(l[0] * n[0] + l[1] * n[1] + l[2] * n[2]);
        if light.two_sided {
            cos = cos.abs();
        }
        let lit = ok && cos > 0.0;
        weight[p] = if lit {
            light.weight * cos * inv * inv
        } else {
            0.0
        };
        for a in 0..3 {
            dir[a][p] = if lit { l[a] } else { 0.0 };
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn area_sample_avx2(
    light: &AreaSamples,
    k: usize,
    shift: &Shift,
    at: &[[f32; BLOCK]; 3],
    dir: &mut [[f32; BLOCK]; 3],
    weight: &mut [f32; BLOCK],
) {
    area_sample_body(light, k, shift, at, dir, weight)
}

/// A slide projector in f32 (`PreparedProjector::illuminate`), its RGB scaled.
#[derive(Clone, Debug)]
pub(crate) struct Projector {
    position: [f32; 3],
    forward: [f32; 3],
    right: [f32; 3],
    up: [f32; 3],
    tan_x: f32,
    tan_y: f32,
    falloff: Falloff,
    rgb: [f32; 3],
    slide: Arc<ImageRgb>,
}

impl Projector {
    pub(crate) fn new(p: &PreparedProjector, rgb: [f32; 3]) -> Self {
        Self {
            position: f3(p.light.position),
            forward: f3(p.forward),
            right: f3(p.right),
            up: f3(p.up),
            tan_x: p.tan_half_x as f32,
            tan_y: p.tan_half_y as f32,
            falloff: Falloff::of(p.light.attenuation),
            rgb,
            slide: p.slide.clone(),
        }
    }
}

impl Simd {
    /// Unit light vectors from a block of surface points `at` toward a projector and
    /// their RGB weights: the slide's colour where the point projects (bilinear) ×
    /// falloff × the light's RGB, zero outside the frustum or without a surface point.
    pub(crate) fn projector_block(
        self,
        light: &Projector,
        at: &[[f32; BLOCK]; 3],
        dir: &mut [[f32; BLOCK]; 3],
        weight: &mut [[f32; BLOCK]; 3],
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `area_sample`.
            return unsafe { projector_block_avx2(light, at, dir, weight) };
        }
        projector_block_body(light, at, dir, weight)
    }
}

#[inline(always)]
fn projector_block_body(
    light: &Projector,
    at: &[[f32; BLOCK]; 3],
    dir: &mut [[f32; BLOCK]; 3],
    weight: &mut [[f32; BLOCK]; 3],
) {
    let mut factor = [0f32; BLOCK];
    light_block_body(light.position, light.falloff, None, at, dir, &mut factor);
    let slide = &*light.slide;
    if slide.data.is_empty() {
        *weight = [[0.0; BLOCK]; 3];
        return;
    }
    let (w, h) = (slide.width as f32, slide.height as f32);
    let (o, f, r, u) = (light.position, light.forward, light.right, light.up);
    let (mut fx, mut fy) = ([0f32; BLOCK], [0f32; BLOCK]);
    for p in 0..BLOCK {
        let d = [at[0][p] - o[0], at[1][p] - o[1], at[2][p] - o[2]];
        let z = dot3(d, f);
        let sx = dot3(d, r) / (z * light.tan_x);
        let sy = dot3(d, u) / (z * light.tan_y);
        // NaN (no surface point) fails every comparison.
        let inside = z > 1e-9 && sx.abs() <= 1.0 && sy.abs() <= 1.0;
        if !inside {
            factor[p] = 0.0;
        }
        // Slide pixel coordinates: x right, y down, centres at half-integers.
        fx[p] = if inside {
            ((sx + 1.0) * 0.5 * w - 0.5).clamp(0.0, w - 1.0)
        } else {
            0.0
        };
        fy[p] = if inside {
            ((1.0 - sy) * 0.5 * h - 0.5).clamp(0.0, h - 1.0)
        } else {
            0.0
        };
    }
    // The texel reads are gathers: one pixel at a time.
    for p in 0..BLOCK {
        if factor[p] == 0.0 {
            for c in weight.iter_mut() {
                c[p] = 0.0;
            }
            continue;
        }
        let (x0, y0) = (fx[p] as usize, fy[p] as usize);
        let (x1, y1) = (
            (x0 + 1).min(slide.width - 1),
            (y0 + 1).min(slide.height - 1),
        );
        let (tx, ty) = (fx[p] - x0 as f32, fy[p] - y0 as f32);
        let (a, b, c, e) = (
            slide.get(x0, y0),
            slide.get(x1, y0),
            slide.get(x0, y1),
            slide.get(x1, y1),
        );
        for k in 0..3 {
            let top = a[k] * (1.0 - tx) + b[k] * tx;
            let bottom = c[k] * (1.0 - tx) + e[k] * tx;
            weight[k][p] = light.rgb[k] * (top * (1.0 - ty) + bottom * ty) * factor[p];
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn projector_block_avx2(
    light: &Projector,
    at: &[[f32; BLOCK]; 3],
    dir: &mut [[f32; BLOCK]; 3],
    weight: &mut [[f32; BLOCK]; 3],
) {
    projector_block_body(light, at, dir, weight)
}
