//! 3×3 rotations of light directions and environments, in the light frame.
//!
//! **Building rotations.** [`rotation_about_axis`] (right-hand rule) and
//! [`rotation_from_yaw_pitch_roll`] (degrees; yaw about +y, pitch about +x, roll about +z
//! of the light frame, `R = R_y(yaw)·R_x(pitch)·R_z(roll)`) make matrices;
//! [`compose`] multiplies them.

use crate::sphere::Vec3;
use crate::{Error, Result};

/// A 3×3 matrix, row-major: `m[row][column]`, acting on column vectors `(x, y, z)`.
pub type Mat3 = [[f64; 3]; 3];

/// The identity rotation.
pub const MAT3_IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// How far `RᵀR` may stray from the identity. Matrices written as decimal text keep
/// about 1e-12; products of a few rotations in double precision keep ~1e-15. A matrix
/// further off than this is not a rotation someone meant.
const ORTHONORMAL_TOLERANCE: f64 = 1e-6;

/// The rotation applying `inner` first, then `outer`: the product `outer · inner`.
pub fn compose(outer: &Mat3, inner: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| outer[i][k] * inner[k][j]).sum();
        }
    }
    m
}

/// The transpose of `m` (the inverse of a rotation).
pub fn transpose(m: &Mat3) -> Mat3 {
    let mut t = [[0.0; 3]; 3];
    for (i, row) in m.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            t[j][i] = v;
        }
    }
    t
}

/// `m · v`.
pub fn mat3_apply(m: &Mat3, v: Vec3) -> Vec3 {
    let row = |r: &[f64; 3]| r[0] * v.x + r[1] * v.y + r[2] * v.z;
    Vec3::new(row(&m[0]), row(&m[1]), row(&m[2]))
}

/// The rotation by `angle_rad` radians about `axis` (any length but zero), right-hand
/// rule: with the thumb along `axis`, positive angles turn the fingers' way (Rodrigues).
pub fn rotation_about_axis(axis: Vec3, angle_rad: f64) -> Result<Mat3> {
    let a = axis
        .normalized()
        .ok_or_else(|| Error::invalid("a rotation axis must be a non-zero finite vector"))?;
    if !angle_rad.is_finite() {
        return Err(Error::invalid(format!(
            "a rotation angle must be finite, not {angle_rad}"
        )));
    }
    let (s, c) = angle_rad.sin_cos();
    let t = 1.0 - c;
    Ok([
        [
            c + t * a.x * a.x,
            t * a.x * a.y - s * a.z,
            t * a.x * a.z + s * a.y,
        ],
        [
            t * a.y * a.x + s * a.z,
            c + t * a.y * a.y,
            t * a.y * a.z - s * a.x,
        ],
        [
            t * a.z * a.x - s * a.y,
            t * a.z * a.y + s * a.x,
            c + t * a.z * a.z,
        ],
    ])
}

/// The rotation `R_y(yaw) · R_x(pitch) · R_z(roll)`, angles in degrees, each about an
/// axis of the light frame (x right, y up, z toward the camera) by the right-hand rule.
/// Applied to a vector, roll acts first, then pitch, then yaw. For the forward
/// direction −z: positive yaw turns it toward −x (left, counter-clockwise seen from
/// above), positive pitch raises it toward +y; positive roll turns +x toward +y
/// (counter-clockwise as the camera sees it).
pub fn rotation_from_yaw_pitch_roll(yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> Result<Mat3> {
    let yaw = rotation_about_axis(Vec3::new(0.0, 1.0, 0.0), yaw_deg.to_radians())?;
    let pitch = rotation_about_axis(Vec3::new(1.0, 0.0, 0.0), pitch_deg.to_radians())?;
    let roll = rotation_about_axis(Vec3::new(0.0, 0.0, 1.0), roll_deg.to_radians())?;
    Ok(compose(&yaw, &compose(&pitch, &roll)))
}

/// Check that `r` is a proper rotation: finite, orthonormal, determinant +1.
pub fn check_rotation(r: &Mat3) -> Result<()> {
    if r.iter().flatten().any(|v| !v.is_finite()) {
        return Err(Error::invalid("a rotation matrix must have finite entries"));
    }
    let rtr = compose(&transpose(r), r);
    let deviation = (0..9)
        .map(|k| (rtr[k / 3][k % 3] - if k / 3 == k % 3 { 1.0 } else { 0.0 }).abs())
        .fold(0.0f64, f64::max);
    if deviation > ORTHONORMAL_TOLERANCE {
        return Err(Error::invalid(format!(
            "a rotation matrix must be orthonormal (RᵀR = I within {ORTHONORMAL_TOLERANCE:e}); this one is off by {deviation:.3e}"
        )));
    }
    let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
        - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
        + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
    if det < 0.0 {
        return Err(Error::invalid(format!(
            "a rotation matrix must have determinant +1; this one is a reflection (determinant {det:.6})"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_pitch_roll_follow_the_documented_axes_and_order() {
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-12;
        let forward = Vec3::new(0.0, 0.0, -1.0);
        let yaw = rotation_from_yaw_pitch_roll(90.0, 0.0, 0.0).unwrap();
        assert!(close(mat3_apply(&yaw, forward), Vec3::new(-1.0, 0.0, 0.0)));
        let pitch = rotation_from_yaw_pitch_roll(0.0, 90.0, 0.0).unwrap();
        assert!(close(mat3_apply(&pitch, forward), Vec3::new(0.0, 1.0, 0.0)));
        let roll = rotation_from_yaw_pitch_roll(0.0, 0.0, 90.0).unwrap();
        assert!(close(
            mat3_apply(&roll, Vec3::new(1.0, 0.0, 0.0)),
            Vec3::new(0.0, 1.0, 0.0)
        ));
        // Roll first, then pitch, then yaw.
        let all = rotation_from_yaw_pitch_roll(30.0, -20.0, 50.0).unwrap();
        let parts = compose(
            &rotation_from_yaw_pitch_roll(30.0, 0.0, 0.0).unwrap(),
            &compose(
                &rotation_from_yaw_pitch_roll(0.0, -20.0, 0.0).unwrap(),
                &rotation_from_yaw_pitch_roll(0.0, 0.0, 50.0).unwrap(),
            ),
        );
        for (a, b) in all.iter().flatten().zip(parts.iter().flatten()) {
            assert!((a - b).abs() < 1e-15);
        }
        check_rotation(&all).unwrap();
    }

    #[test]
    fn bad_input_is_refused_with_an_error() {
        assert!(rotation_about_axis(Vec3::new(0.0, 0.0, 0.0), 1.0).is_err());
        assert!(rotation_from_yaw_pitch_roll(f64::INFINITY, 0.0, 0.0).is_err());
    }
}
