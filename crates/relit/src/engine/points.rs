//! Surface points `P = O + d·V` rebuilt a block at a time from the depth map.
//!
//! Positional lights need every pixel's surface point. Holding them costs three f32 a
//! pixel: 0.2× of the maps at k = 16 in u8 storage, more than the whole budget the
//! engine allows itself beside the maps and the output. Every camera's rays factor into
//! a column part and a row part ([`crate::camera::RayFactors`]), so the points come
//! from the depth the file carries anyway and `width + height` table entries, at a few
//! multiply-adds and one square root a pixel.

use super::kernels::{Simd, BLOCK};
use crate::camera::Camera;

/// One row's ray terms in f32: origin x, y, z, scale, direction x, y, z, and the
/// reciprocal of the direction's length where that is the row's (else NaN, unused).
type RowTerms = [f32; 8];

pub(crate) struct SurfacePoints<'a> {
    width: usize,
    depth: &'a [f32],
    /// Per column: origin x, y, z, then direction x, y, z.
    columns: [Vec<f32>; 6],
    rows: Vec<RowTerms>,
    norm_per_row: bool,
}

impl<'a> SurfacePoints<'a> {
    /// The points of `camera`'s pixels at `depth` (row-major, the camera's size).
    pub fn new(camera: &Camera, depth: &'a [f32]) -> Self {
        let factors = camera.ray_factors();
        let mut columns: [Vec<f32>; 6] =
            std::array::from_fn(|_| Vec::with_capacity(factors.columns.len()));
        for c in &factors.columns {
            let terms = [
                c.origin.x,
                c.origin.y,
                c.origin.z,
                c.direction.x,
                c.direction.y,
                c.direction.z,
            ];
            for (column, t) in columns.iter_mut().zip(terms) {
                column.push(t as f32);
            }
        }
        let rows = factors
            .rows
            .iter()
            .map(|r| {
                let inv_norm = match factors.columns.first() {
                    Some(c) if factors.norm_per_row => {
                        1.0 / (c.direction * r.scale + r.direction).length()
                    }
                    _ => f64::NAN,
                };
                [
                    r.origin.x,
                    r.origin.y,
                    r.origin.z,
                    r.scale,
                    r.direction.x,
                    r.direction.y,
                    r.direction.z,
                    inv_norm,
                ]
                .map(|t| t as f32)
            })
            .collect();
        SurfacePoints {
            width: camera.width(),
            depth,
            columns,
            rows,
            norm_per_row: factors.norm_per_row,
        }
    }

    /// The points of pixels `q0 .. q0 + bl` into `at` (x, y, z rows), NaN where nothing
    /// was hit (a depth that is not a positive finite number) and past `bl`.
    pub fn fill(&self, simd: Simd, q0: usize, bl: usize, at: &mut [[f32; BLOCK]; 3]) {
        let mut b = 0;
        while b < bl {
            let q = q0 + b;
            let (i0, j) = (q % self.width, q / self.width);
            let len = (self.width - i0).min(bl - b);
            let depth = &self.depth[q..q + len];
            #[cfg(target_arch = "x86_64")]
            if simd.avx2() {
                // SAFETY: `simd` says the CPU has AVX2, FMA and F16C.
                unsafe { self.fill_run_avx2(j, i0, depth, b, at) };
                b += len;
                continue;
            }
            self.fill_run(j, i0, depth, b, at);
            b += len;
        }
        for row in at.iter_mut() {
            row[bl..].fill(f32::NAN);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn fill_run_avx2(
        &self,
        j: usize,
        i0: usize,
        depth: &[f32],
        b: usize,
        at: &mut [[f32; BLOCK]; 3],
    ) {
        self.fill_run(j, i0, depth, b, at)
    }

    /// Pixels `i0 .. i0 + depth.len()` of row `j` into `at[..][b ..]`: one row's terms
    /// and contiguous column terms, a loop the compiler vectorises.
    #[inline(always)]
    fn fill_run(&self, j: usize, i0: usize, depth: &[f32], b: usize, at: &mut [[f32; BLOCK]; 3]) {
        let n = depth.len();
        let [ro_x, ro_y, ro_z, scale, rd_x, rd_y, rd_z, inv_norm] = self.rows[j];
        let [co_x, co_y, co_z, cd_x, cd_y, cd_z] =
            std::array::from_fn(|a| &self.columns[a][i0..i0 + n]);
        let [ax, ay, az] = at;
        let (ax, ay, az) = (&mut ax[b..b + n], &mut ay[b..b + n], &mut az[b..b + n]);
        // A non-positive or non-finite depth is a miss; NaN marks it for the lights.
        let hit = |d: f32| d > 0.0 && d < f32::INFINITY;
        if self.norm_per_row {
            // Panoramas: one normalisation per row, no square root per pixel.
            for t in 0..n {
                let d = depth[t];
                let along = if hit(d) { d * inv_norm } else { f32::NAN };
                ax[t] = ro_x + co_x[t] + along * (scale * cd_x[t] + rd_x);
                ay[t] = ro_y + co_y[t] + along * (scale * cd_y[t] + rd_y);
                az[t] = ro_z + co_z[t] + along * (scale * cd_z[t] + rd_z);
            }
            return;
        }
        for t in 0..n {
            let (vx, vy, vz) = (
                scale * cd_x[t] + rd_x,
                scale * cd_y[t] + rd_y,
                scale * cd_z[t] + rd_z,
            );
            let d = depth[t];
            let along = if hit(d) {
                d / (vx * vx + vy * vy + vz * vz).sqrt()
            } else {
                f32::NAN
            };
            ax[t] = ro_x + co_x[t] + along * vx;
            ay[t] = ro_y + co_y[t] + along * vy;
            az[t] = ro_z + co_z[t] + along * vz;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Pose, Projection};
    use crate::sphere::Vec3;

    #[test]
    fn blocks_match_the_camera_positions_across_rows_and_misses() {
        let pose = Pose::look_at(
            Vec3::new(0.5, 1.0, 2.0),
            Vec3::new(-1.0, 0.5, -1.0),
            Vec3::new(0.0, 1.0, 0.0),
        )
        .unwrap();
        for projection in [
            Projection::Planar {
                fov_y_deg: Some(60.0),
            },
            Projection::Planar { fov_y_deg: None },
            Projection::Cylindrical { fov_y_deg: None },
            Projection::Equirectangular,
        ] {
            // 37 columns: blocks of 64 straddle rows at every offset.
            let camera = Camera::new(&projection, 37, 11, pose).unwrap();
            let n = 37 * 11;
            let depth: Vec<f32> = (0..n)
                .map(|p| match p % 17 {
                    3 => 0.0,
                    5 => f32::INFINITY,
                    7 => f32::NAN,
                    9 => -1.0,
                    _ => 0.5 + (p % 29) as f32 * 0.37,
                })
                .collect();
            let points = SurfacePoints::new(&camera, &depth);
            for simd in [Simd::detect(), Simd::baseline()] {
                for q0 in (0..n).step_by(BLOCK - 3) {
                    let bl = BLOCK.min(n - q0);
                    let mut at = [[0f32; BLOCK]; 3];
                    points.fill(simd, q0, bl, &mut at);
                    let [xs, ys, zs] = &at;
                    for (b, ((&x, &y), &z)) in xs.iter().zip(ys).zip(zs).enumerate() {
                        let got = [x, y, z];
                        let q = q0 + b;
                        let d = if b < bl { depth[q] } else { f32::NAN };
                        if !(d.is_finite() && d > 0.0) {
                            assert!(
                                got.iter().all(|v| v.is_nan()),
                                "{projection:?} q {q}: {got:?}"
                            );
                            continue;
                        }
                        let want = camera.position(q % 37, q / 37, d as f64);
                        let err = (Vec3::new(got[0] as f64, got[1] as f64, got[2] as f64) - want)
                            .length();
                        // f32 arithmetic on coordinates of size ≤ 10: a few ulps.
                        assert!(err < 5e-6, "{projection:?} q {q}: {got:?} vs {want:?}");
                    }
                }
            }
        }
    }
}
