//! Single-precision vectors and affine transforms for the ray tracer.
//!
//! The tracer works in `f32`: a million triangles fit in half the memory of `f64`, and
//! scenes of a few hundred metres keep sub-millimetre precision. Conversions to and
//! from relit's `f64` [`relit::sphere::Vec3`] happen at the API boundary.

use relit::sphere::Vec3;
use std::ops::{Add, AddAssign, Mul, Neg, Sub};

/// A 3-vector (point, direction or RGB triple) in the light frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V3 {
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

/// Shorthand constructor.
pub const fn v3(x: f32, y: f32, z: f32) -> V3 {
    V3 { x, y, z }
}

impl V3 {
    pub const ZERO: V3 = v3(0.0, 0.0, 0.0);

    pub const fn splat(v: f32) -> V3 {
        v3(v, v, v)
    }
    pub fn dot(self, o: V3) -> f32 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    pub fn cross(self, o: V3) -> V3 {
        v3(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    pub fn length(self) -> f32 {
        self.dot(self).sqrt()
    }
    /// The unit vector along `self`; a zero vector stays zero.
    pub fn normalized(self) -> V3 {
        let len = self.length();
        if len > 0.0 {
            self * (1.0 / len)
        } else {
            self
        }
    }
    pub fn min(self, o: V3) -> V3 {
        v3(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }
    pub fn max(self, o: V3) -> V3 {
        v3(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }
    /// Component-wise product (colours).
    pub fn modulate(self, o: V3) -> V3 {
        v3(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    /// Component `axis` (0 = x, 1 = y, 2 = z).
    pub fn axis(self, axis: usize) -> f32 {
        match axis {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }
    pub fn max_component(self) -> f32 {
        self.x.max(self.y).max(self.z)
    }
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
    pub fn to_array(self) -> [f32; 3] {
        [self.x, self.y, self.z]
    }
    /// Linear interpolation `self + (o − self)·t`.
    pub fn lerp(self, o: V3, t: f32) -> V3 {
        self + (o - self) * t
    }
}

impl From<[f32; 3]> for V3 {
    fn from(a: [f32; 3]) -> V3 {
        v3(a[0], a[1], a[2])
    }
}
impl From<Vec3> for V3 {
    fn from(v: Vec3) -> V3 {
        v3(v.x as f32, v.y as f32, v.z as f32)
    }
}
impl From<V3> for Vec3 {
    fn from(v: V3) -> Vec3 {
        Vec3::new(v.x as f64, v.y as f64, v.z as f64)
    }
}
impl Add for V3 {
    type Output = V3;
    fn add(self, o: V3) -> V3 {
        v3(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl AddAssign for V3 {
    fn add_assign(&mut self, o: V3) {
        *self = *self + o;
    }
}
impl Sub for V3 {
    type Output = V3;
    fn sub(self, o: V3) -> V3 {
        v3(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl Mul<f32> for V3 {
    type Output = V3;
    fn mul(self, s: f32) -> V3 {
        v3(self.x * s, self.y * s, self.z * s)
    }
}
impl Neg for V3 {
    type Output = V3;
    fn neg(self) -> V3 {
        v3(-self.x, -self.y, -self.z)
    }
}

/// An affine map `p ↦ M·p + t` (object space to the light frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Rows of the linear part.
    m: [V3; 3],
    t: V3,
}

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

impl Transform {
    pub const IDENTITY: Transform = Transform {
        m: [v3(1.0, 0.0, 0.0), v3(0.0, 1.0, 0.0), v3(0.0, 0.0, 1.0)],
        t: V3::ZERO,
    };

    /// The map sending the object axes to `x`, `y`, `z` and the origin to `origin`.
    pub fn from_columns(x: V3, y: V3, z: V3, origin: V3) -> Transform {
        Transform {
            m: [v3(x.x, y.x, z.x), v3(x.y, y.y, z.y), v3(x.z, y.z, z.z)],
            t: origin,
        }
    }

    pub fn translate(t: V3) -> Transform {
        Transform {
            t,
            ..Transform::IDENTITY
        }
    }
    /// Scale each axis.
    pub fn scale(s: V3) -> Transform {
        Transform {
            m: [v3(s.x, 0.0, 0.0), v3(0.0, s.y, 0.0), v3(0.0, 0.0, s.z)],
            t: V3::ZERO,
        }
    }
    /// Rotation about +x by `deg` degrees (right-handed: y turns toward z).
    pub fn rotate_x(deg: f32) -> Transform {
        let (s, c) = deg.to_radians().sin_cos();
        Transform {
            m: [v3(1.0, 0.0, 0.0), v3(0.0, c, -s), v3(0.0, s, c)],
            t: V3::ZERO,
        }
    }
    /// Rotation about +y by `deg` degrees (z turns toward x).
    pub fn rotate_y(deg: f32) -> Transform {
        let (s, c) = deg.to_radians().sin_cos();
        Transform {
            m: [v3(c, 0.0, s), v3(0.0, 1.0, 0.0), v3(-s, 0.0, c)],
            t: V3::ZERO,
        }
    }
    /// Rotation about +z by `deg` degrees (x turns toward y).
    pub fn rotate_z(deg: f32) -> Transform {
        let (s, c) = deg.to_radians().sin_cos();
        Transform {
            m: [v3(c, -s, 0.0), v3(s, c, 0.0), v3(0.0, 0.0, 1.0)],
            t: V3::ZERO,
        }
    }

    /// `self` applied after `first`: `(self ∘ first)(p) = self(first(p))`.
    pub fn then(self, after: Transform) -> Transform {
        let cols = |t: &Transform, j: usize| v3(t.m[0].axis(j), t.m[1].axis(j), t.m[2].axis(j));
        let m = std::array::from_fn(|i| {
            v3(
                after.m[i].dot(cols(&self, 0)),
                after.m[i].dot(cols(&self, 1)),
                after.m[i].dot(cols(&self, 2)),
            )
        });
        Transform {
            m,
            t: after.point(self.t),
        }
    }

    pub fn point(&self, p: V3) -> V3 {
        v3(self.m[0].dot(p), self.m[1].dot(p), self.m[2].dot(p)) + self.t
    }
    pub fn vector(&self, v: V3) -> V3 {
        v3(self.m[0].dot(v), self.m[1].dot(v), self.m[2].dot(v))
    }
    /// A surface normal mapped by the inverse transpose (cofactor matrix: the same
    /// direction up to a positive factor when the determinant is positive), unit length.
    pub fn normal(&self, n: V3) -> V3 {
        let [a, b, c] = self.m;
        // The rows of det(M)·M⁻ᵀ are the cross products of the rows of M.
        let n2 = v3(b.cross(c).dot(n), c.cross(a).dot(n), a.cross(b).dot(n));
        let sign = if self.determinant() < 0.0 { -1.0 } else { 1.0 };
        (n2 * sign).normalized()
    }
    pub fn determinant(&self) -> f32 {
        self.m[0].dot(self.m[1].cross(self.m[2]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn composition_and_normals() {
        let t = Transform::scale(v3(2.0, 1.0, 1.0))
            .then(Transform::rotate_y(90.0))
            .then(Transform::translate(v3(0.0, 1.0, 0.0)));
        let p = t.point(v3(1.0, 0.0, 0.0));
        // x scaled to 2, rotated about y by 90°: +x goes to −z, then lifted by 1.
        assert!((p - v3(0.0, 1.0, -2.0)).length() < 1e-6, "{p:?}");
        // A plane tilted 45° in x-y, stretched along x: its normal must stay perpendicular.
        let s = Transform::scale(v3(3.0, 1.0, 1.0));
        let (tangent, normal) = (v3(1.0, -1.0, 0.0), v3(1.0, 1.0, 0.0).normalized());
        assert!(s.vector(tangent).dot(s.normal(normal)).abs() < 1e-6);
        let turned = Transform::rotate_z(30.0).then(Transform::scale(v3(1.0, 2.0, 0.5)));
        let tangent2 = v3(0.3, 0.0, 1.0);
        let normal2 = v3(0.0, 1.0, 0.0);
        assert!(turned.vector(tangent2).dot(turned.normal(normal2)).abs() < 1e-6);
        assert!(
            turned
                .vector(v3(1.0, 0.0, 0.0))
                .dot(turned.normal(normal2))
                .abs()
                < 1e-6
        );
        let mirror = Transform::scale(v3(-1.0, 1.0, 1.0));
        assert!((mirror.normal(v3(1.0, 0.0, 0.0)) - v3(-1.0, 0.0, 0.0)).length() < 1e-6);
    }
}
