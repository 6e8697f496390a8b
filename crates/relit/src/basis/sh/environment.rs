//! The exact lighting of SH coefficient maps by a lat-long environment map: the map's
//! projection onto SH, turned with [`ShRotation`] and windowed band by band.
//!
//! # Projection
//!
//! The map (laid out as [`crate::sphere::latlong_direction`] says) is taken as constant
//! radiance over each texel, and that piecewise-constant function is projected exactly:
//! `e_i = Σ_texels E_t ∫_t Y_i dω`. A texel spans `Δα = 2π/width` in azimuth and
//! `[θ_top, θ_bottom]` in polar angle, a solid angle of `Δα·(cos θ_top − cos θ_bottom)`
//! ([`crate::sphere::texel_solid_angle`]); the solid angles of the whole map add up to
//! exactly 4π, so a constant map projects onto `Y_0` alone.
//!
//! In a frame whose polar axis is the map's (+y) the integral separates: `Y_{l,m}` is
//! `N_{l,|m|}(θ)` times `cos(mφ)` (m > 0), 1 or `sin(|m|φ)` (m < 0), so
//! `e_{l,m} = Σ_rows Θ_{l,|m|}(row) Σ_columns E Φ_m(column)` with the azimuth integrals
//! `Φ_m` in closed form and the polar ones `Θ_{l,m} = ∫ N_{l,m}(θ) sin θ dθ` by 8-point
//! Gauss–Legendre quadrature in θ (exact to rounding: the integrand is a trigonometric
//! polynomial of degree ≤ 8 over a short interval). The coefficients are then rotated
//! from that frame into the light frame by one [`ShRotation`]. The cost is
//! `3 (2·bands − 1)` multiply-adds per texel.
//!
//! # Rotation and windows
//!
//! Turning the environment by `R` (`E'(ω) = E(Rᵀ ω)`) turns its projection by
//! [`ShRotation`], exactly and at no cost per pixel, so the projection is made once
//! ([`ShEnvironment`]) and every frame only rotates and windows it (microseconds). The
//! band windows ([`Window`]) scale band `l` of the coefficients by `h_l`.

use super::{sh_index, ShRotation, SphericalHarmonics, MAX_BANDS};
use crate::basis::{Basis, Mat3, PreparedEnvironment, Window};
use crate::image::ImageRgb;
use crate::sphere::Vec3;
use crate::{Error, Result};
use rayon::prelude::*;
use std::f64::consts::PI;

/// From the map frame (polar axis +y, azimuth φ = −α from −z toward −x; its axes are
/// −z, −x, +y of the light frame) to the light frame: the columns are those axes.
const MAP_TO_LIGHT: Mat3 = [[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]];

fn check_bands(bands: usize) -> Result<()> {
    if !(1..=MAX_BANDS).contains(&bands) {
        return Err(Error::invalid(format!(
            "an environment light needs 1 to {MAX_BANDS} SH bands, got {bands}"
        )));
    }
    Ok(())
}

/// The exact SH projection `∫ E(ω) Y_i(ω) dω` of a lat-long map, in the light frame,
/// unrotated and unwindowed: what does not change when the environment turns.
#[derive(Clone, Debug)]
pub struct ShEnvironment {
    projection: [Vec<f64>; 3],
}

impl ShEnvironment {
    /// The projection of `map` onto `bands` bands (1..=8): `bands²` coefficients per
    /// colour channel.
    pub fn project(map: &ImageRgb, bands: usize) -> Result<Self> {
        let map_frame = project_map_frame(map, bands)?;
        Ok(Self {
            projection: rotate_channels(&ShRotation::new(MAP_TO_LIGHT, bands)?, &map_frame)?,
        })
    }

    /// A projection made earlier (`bands²` coefficients in each of 3 channels).
    pub fn from_projection(projection: [Vec<f64>; 3]) -> Result<Self> {
        let len = projection[0].len();
        let bands = (len as f64).sqrt().round() as usize;
        if bands * bands != len || projection.iter().any(|c| c.len() != len) {
            return Err(Error::invalid(format!(
                "an SH projection needs bands² coefficients in each of its 3 channels, got {}, {} and {}",
                projection[0].len(),
                projection[1].len(),
                projection[2].len()
            )));
        }
        check_bands(bands)?;
        Ok(Self { projection })
    }

    /// The projection per colour channel.
    pub fn projection(&self) -> &[Vec<f64>; 3] {
        &self.projection
    }

    fn bands(&self) -> usize {
        (self.projection[0].len() as f64).sqrt().round() as usize
    }
}

impl PreparedEnvironment for ShEnvironment {
    /// The projection turned by `rotation`, then windowed.
    fn weights(&self, rotation: &Mat3, window: Window) -> Result<[Vec<f64>; 3]> {
        let bands = self.bands();
        let mut weights = rotate_channels(&ShRotation::new(*rotation, bands)?, &self.projection)?;
        apply_window(&window, bands, &mut weights)?;
        Ok(weights)
    }
}

fn rotate_channels(rotation: &ShRotation, coeffs: &[Vec<f64>; 3]) -> Result<[Vec<f64>; 3]> {
    Ok([
        rotation.rotate(&coeffs[0])?,
        rotation.rotate(&coeffs[1])?,
        rotation.rotate(&coeffs[2])?,
    ])
}

fn apply_window(window: &Window, bands: usize, coeffs: &mut [Vec<f64>; 3]) -> Result<()> {
    let h = window.factors(bands)?;
    for channel in coeffs.iter_mut() {
        for (l, &hl) in h.iter().enumerate() {
            channel[l * l..(l + 1) * (l + 1)]
                .iter_mut()
                .for_each(|c| *c *= hl);
        }
    }
    Ok(())
}

/// Rows of the map one parallel task handles; fixed so that sums are reproducible.
const ROWS_PER_TASK: usize = 16;

/// 8-point Gauss–Legendre nodes and weights on [−1, 1] (the nodes come in ± pairs).
const GAUSS_LEGENDRE_8: [(f64, f64); 4] = [
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
];

/// Rows are split into at least this many quadrature intervals in total, so that even a
/// map a few rows high is integrated exactly (each interval at most π/16 wide).
const MIN_POLAR_INTERVALS: usize = 16;

/// The exact projection of the piecewise-constant map onto SH of the map frame, whose
/// polar axis is +y and whose azimuth is `φ = −α` (module docs).
fn project_map_frame(map: &ImageRgb, bands: usize) -> Result<[Vec<f64>; 3]> {
    check_bands(bands)?;
    let sh = SphericalHarmonics::new(bands)?;
    let (w, h) = (map.width, map.height);
    let top = bands as isize - 1;
    let orders = 2 * bands - 1; // m = -top..=top, stored at m + top

    // Azimuth integrals Φ_m over each column. Column x spans α ∈ [α_x, α_x + Δ], so
    // φ = −α spans an interval of width Δ centred on φ_c = −2π((x + ½)/w − ½).
    let delta = 2.0 * PI / w as f64;
    let mut phi_integrals = vec![0.0; orders * w];
    for x in 0..w {
        let centre = -2.0 * PI * ((x as f64 + 0.5) / w as f64 - 0.5);
        for m in -top..=top {
            let k = m.unsigned_abs() as f64;
            // ∫ cos(kφ) = (2/k) cos(kφ_c) sin(kΔ/2); ∫ sin(kφ) = (2/k) sin(kφ_c) sin(kΔ/2).
            let value = match m.cmp(&0) {
                std::cmp::Ordering::Equal => delta,
                std::cmp::Ordering::Greater => {
                    2.0 / k * (k * centre).cos() * (k * delta / 2.0).sin()
                }
                std::cmp::Ordering::Less => 2.0 / k * (k * centre).sin() * (k * delta / 2.0).sin(),
            };
            phi_integrals[(m + top) as usize * w + x] = value;
        }
    }

    // Polar integrals Θ_{l,m}(row) = ∫ N_{l,m}(θ) sin θ dθ for m ≥ 0, where N_{l,m}(θ) is
    // Y_{l,m} at azimuth 0, by Gauss–Legendre over `pieces` sub-intervals of the row.
    let pieces = MIN_POLAR_INTERVALS.div_ceil(h);
    let polar_integrals = |y: usize| -> Vec<f64> {
        let mut theta_int = vec![0.0; bands * bands];
        let mut values = vec![0.0; bands * bands];
        let row_width = PI / h as f64;
        let piece_width = row_width / pieces as f64;
        for piece in 0..pieces {
            let mid = row_width * y as f64 + piece_width * (piece as f64 + 0.5);
            for &(node, weight) in &GAUSS_LEGENDRE_8 {
                for theta in [
                    mid - node * piece_width / 2.0,
                    mid + node * piece_width / 2.0,
                ] {
                    let (s, c) = theta.sin_cos();
                    sh.eval(Vec3::new(s, 0.0, c), &mut values);
                    let scale = weight * piece_width / 2.0 * s;
                    theta_int
                        .iter_mut()
                        .zip(&values)
                        .for_each(|(t, v)| *t += scale * v);
                }
            }
        }
        theta_int
    };

    let k = bands * bands;
    let partials: Vec<Vec<f64>> = (0..h)
        .collect::<Vec<_>>()
        .par_chunks(ROWS_PER_TASK)
        .map(|rows| {
            let mut acc = vec![0.0; 3 * k];
            let mut planar = vec![0.0f64; 3 * w];
            let mut sums = vec![0.0f64; 3 * orders];
            for &y in rows {
                let row = &map.data[3 * w * y..3 * w * (y + 1)];
                for (x, px) in row.chunks_exact(3).enumerate() {
                    for c in 0..3 {
                        planar[c * w + x] = f64::from(px[c]);
                    }
                }
                // Σ_columns E_c Φ_m for each channel and order.
                for (mi, phi) in phi_integrals.chunks_exact(w).enumerate() {
                    for c in 0..3 {
                        sums[c * orders + mi] = planar[c * w..(c + 1) * w]
                            .iter()
                            .zip(phi)
                            .map(|(e, p)| e * p)
                            .sum();
                    }
                }
                let theta_int = polar_integrals(y);
                for l in 0..bands {
                    for m in -(l as isize)..=(l as isize) {
                        let t = theta_int[sh_index(l, m.abs())];
                        let mi = (m + top) as usize;
                        for c in 0..3 {
                            acc[c * k + sh_index(l, m)] += t * sums[c * orders + mi];
                        }
                    }
                }
            }
            acc
        })
        .collect();
    let mut out = [vec![0.0; k], vec![0.0; k], vec![0.0; k]];
    for part in &partials {
        for (c, channel) in out.iter_mut().enumerate() {
            channel
                .iter_mut()
                .zip(&part[c * k..(c + 1) * k])
                .for_each(|(o, p)| *o += p);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{mat3_apply, rotation_about_axis, rotation_from_yaw_pitch_roll, transpose};
    use crate::image::test_maps::{sampled_map, smooth_sky};

    /// Rounding in sums over a few thousand texels, with f32 radiance stored exactly.
    const EXACT_TOLERANCE: f64 = 1e-9;

    fn project(map: &ImageRgb, bands: usize) -> [Vec<f64>; 3] {
        ShEnvironment::project(map, bands)
            .unwrap()
            .projection()
            .clone()
    }

    #[test]
    fn constant_map_projects_onto_the_constant_only() {
        let radiance = [1.5f32, 2.0, 0.25];
        for (w, h) in [(64, 32), (30, 13), (5, 3)] {
            let mut map = ImageRgb::new(w, h);
            map.data
                .chunks_exact_mut(3)
                .for_each(|p| p.copy_from_slice(&radiance));
            let e = project(&map, MAX_BANDS);
            for c in 0..3 {
                let want = radiance[c] as f64 * (4.0 * PI).sqrt();
                assert!(
                    (e[c][0] - want).abs() < EXACT_TOLERANCE,
                    "{w}×{h} e_0: {} vs {want}",
                    e[c][0]
                );
                for (i, v) in e[c].iter().enumerate().skip(1) {
                    assert!(v.abs() < EXACT_TOLERANCE, "{w}×{h} channel {c} e_{i} = {v}");
                }
            }
        }
    }

    /// A map sampling `Y_i` at texel centres differs from `Y_i` within each texel by
    /// O(texel²): the worst coefficient error over all 64 harmonics is 5.1e-3 at
    /// 128×64, 1.3e-3 at 256×128 and 3.2e-4 at 512×256 (measured).
    const SAMPLED_TOLERANCE: f64 = 2e-3;

    #[test]
    fn a_map_of_one_harmonic_projects_onto_that_harmonic() {
        let bands = MAX_BANDS;
        let sh = SphericalHarmonics::new(bands).unwrap();
        for i in [0, 1, 2, 3, 6, 8, 13, 22, 30, 41, 48, 56, 63] {
            let map = sampled_map(256, 128, |d| {
                let y = sh.values(d)[i];
                [y, -0.5 * y, 2.0 * y]
            });
            let e = project(&map, bands);
            for (c, scale) in [1.0, -0.5, 2.0].into_iter().enumerate() {
                for (j, v) in e[c].iter().enumerate() {
                    let want = if j == i { scale } else { 0.0 };
                    let error = (v - want).abs();
                    assert!(
                        error < SAMPLED_TOLERANCE * scale.abs(),
                        "Y_{i}, channel {c}: e_{j} = {v}"
                    );
                }
            }
        }
    }

    #[test]
    fn yaw_by_whole_columns_equals_shifting_the_map() {
        // Yaw ψ moves the content toward smaller u by ψ/2π of the width: 90° is 8 of 32
        // columns, and the projection of the shifted map is exact.
        let (w, h) = (32, 16);
        let map = sampled_map(w, h, smooth_sky);
        let mut shifted = ImageRgb::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let src = map.get((x + w / 4) % w, y);
                shifted.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&src);
            }
        }
        let yaw = rotation_about_axis(Vec3::new(0.0, 1.0, 0.0), 90f64.to_radians()).unwrap();
        let got = ShEnvironment::project(&map, MAX_BANDS)
            .unwrap()
            .weights(&yaw, Window::None)
            .unwrap();
        let want = project(&shifted, MAX_BANDS);
        for c in 0..3 {
            for (i, (g, w)) in got[c].iter().zip(&want[c]).enumerate() {
                assert!(
                    (g - w).abs() < EXACT_TOLERANCE,
                    "channel {c} e_{i}: {g} vs {w}"
                );
            }
        }
    }

    /// Both maps sample a smooth function at texel centres of a 256×128 grid; the
    /// rotated one samples different points, so they agree to the sampling error
    /// (measured: 1.4e-9 for a yaw, which only shifts azimuths; 5.4e-5 for a general
    /// rotation, against e_0 ≈ 2.2).
    const RESAMPLED_TOLERANCE: f64 = 3e-4;

    #[test]
    fn rotating_the_weights_equals_reprojecting_a_rotated_map() {
        for (yaw, pitch, roll) in [(37.0, 0.0, 0.0), (-20.0, 35.0, 10.0)] {
            let r = rotation_from_yaw_pitch_roll(yaw, pitch, roll).unwrap();
            let env = ShEnvironment::project(&sampled_map(256, 128, smooth_sky), 6).unwrap();
            let inverse = transpose(&r);
            let rotated_map = sampled_map(256, 128, |d| smooth_sky(mat3_apply(&inverse, d)));
            let want = project(&rotated_map, 6);
            let got = env.weights(&r, Window::None).unwrap();
            for c in 0..3 {
                for i in 0..36 {
                    assert!(
                        (got[c][i] - want[c][i]).abs() < RESAMPLED_TOLERANCE,
                        "{yaw}/{pitch}/{roll} c{c} e_{i}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_window_scales_the_weights_band_by_band() {
        let env = ShEnvironment::project(&sampled_map(32, 16, smooth_sky), 4).unwrap();
        let plain = env
            .weights(&crate::basis::MAT3_IDENTITY, Window::None)
            .unwrap();
        let hann = env
            .weights(&crate::basis::MAT3_IDENTITY, Window::Hann)
            .unwrap();
        let h = Window::Hann.factors(4).unwrap();
        for i in 0..16 {
            let l = (i as f64).sqrt() as usize;
            assert!((hann[1][i] - h[l] * plain[1][i]).abs() < 1e-15);
        }
    }

    #[test]
    fn bad_input_is_refused_with_an_error() {
        let map = sampled_map(8, 4, smooth_sky);
        assert!(ShEnvironment::project(&map, 0).is_err());
        assert!(ShEnvironment::project(&map, 9).is_err());
        assert!(
            ShEnvironment::from_projection([vec![0.0; 4], vec![0.0; 4], vec![0.0; 3]]).is_err()
        );
        assert!(
            ShEnvironment::from_projection([vec![0.0; 81], vec![0.0; 81], vec![0.0; 81]]).is_err()
        );
        let env =
            ShEnvironment::from_projection([vec![0.0; 4], vec![0.0; 4], vec![0.0; 4]]).unwrap();
        assert!(env
            .weights(
                &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]],
                Window::None
            )
            .is_err());
    }

    #[test]
    fn shared_envmaps_project() {
        let Some(paths) = crate::image::test_maps::shared_envmaps() else {
            println!("skipped: shared/data/envmaps is not present");
            return;
        };
        for (n, path) in paths.iter().enumerate() {
            if n > 0 {
                break;
            }
            let map = crate::image::load_linear(path, None).unwrap();
            // Timings on the first map only (the machine is shared).
            let time = |f: &mut dyn FnMut()| {
                let start = std::time::Instant::now();
                f();
                start.elapsed().as_secs_f64() * 1e3
            };
            let mut e5: [Vec<f64>; 3] = Default::default();
            let mut e8: [Vec<f64>; 3] = Default::default();
            let t5 = time(&mut || e5 = project(&map, 5));
            let t8 = time(&mut || e8 = project(&map, 8));
            let turn = rotation_from_yaw_pitch_roll(30.0, 10.0, -5.0).unwrap();
            let prepared = ShEnvironment::from_projection(e8.clone()).unwrap();
            let mut weights: [Vec<f64>; 3] = Default::default();
            let t_rot = time(&mut || weights = prepared.weights(&turn, Window::None).unwrap());
            println!(
                "{}: project 5 bands {t5:.1} ms, 8 bands {t8:.1} ms; rotate 8 bands {:.3} ms",
                path.file_name().unwrap().to_string_lossy(),
                t_rot
            );
            // Lower bands do not depend on how many are projected; rotation keeps each
            // band's energy; the mean radiance is positive.
            for c in 0..3 {
                assert!(e8[c][0] > 0.0);
                for i in 0..25 {
                    assert!((e5[c][i] - e8[c][i]).abs() <= 1e-9 * e8[c][0]);
                }
                for l in 0..8 {
                    let band = |v: &[f64]| {
                        v[l * l..(l + 1) * (l + 1)]
                            .iter()
                            .map(|x| x * x)
                            .sum::<f64>()
                    };
                    assert!(
                        (band(&weights[c]) - band(&e8[c])).abs() <= 1e-9 * band(&e8[c]).max(1e-300)
                    );
                }
            }
        }
    }
}
