//! Rotation of real spherical-harmonic coefficient vectors by a 3×3 rotation matrix.
//!
//! **Convention.** [`ShRotation::new`]`(R)` maps the coefficients `c` of a function `f`
//! to the coefficients `c'` of the rotated function `f'(d) = f(Rᵀ d)`: whatever `f` had
//! at direction `d` is found at `R d` afterwards. Because each band `l` spans a space
//! that rotations map to itself, the rotation is block diagonal, one orthogonal
//! `(2l+1)×(2l+1)` matrix per band, and rotating loses nothing (seed 003, §4.2). The
//! block acts on the coefficients of one band in the order `m = -l..=l` of the flat
//! index `l(l+1) + m`: `c'_{l,m} = Σ_n D^l_{mn} c_{l,n}`.
//!
//! **Method.** The recurrence of Ivanic & Ruedenberg (J. Phys. Chem. 100, 6342, 1996,
//! with the corrections of J. Phys. Chem. A 102, 9099, 1998) builds `D^l` from `D^1`
//! and `D^{l-1}` in `O(l²)` operations, without trigonometry or Euler angles. It is
//! stated for real harmonics *without* the Condon–Shortley phase, whose `l = 1`
//! functions are proportional to `(y, z, x)`, so that `D^1` is `R` with its rows and
//! columns permuted. relit's harmonics carry the phase (see the conventions): they are
//! `Y^CS_{l,m} = (-1)^m Y_{l,m}` for the phase-free `Y_{l,m}`, so each finished block is
//! conjugated by `diag((-1)^m)`: `D^CS_{mn} = (-1)^(m+n) D_{mn}`. The tests pin the
//! result to the "CS (google/Sloan)" matrices of `shared/reference/rotation_reference.txt`.

use super::MAX_BANDS;
use crate::basis::rotation::{check_rotation, Mat3};
use crate::{Error, Result};

/// The rotation of real SH coefficient vectors (with the Condon–Shortley phase) of up to
/// `bands` bands by a 3×3 rotation: `f'(d) = f(Rᵀ d)`.
#[derive(Clone, Debug, PartialEq)]
pub struct ShRotation {
    bands: usize,
    matrix: Mat3,
    /// `blocks[l]` is `D^l`, `(2l+1)²` entries, row-major, rows and columns `m = -l..=l`.
    blocks: Vec<Vec<f64>>,
}

impl ShRotation {
    /// The SH rotation of `bands` bands (1..=8) for the rotation matrix `r`.
    ///
    /// `r` must be orthonormal (`rᵀr = I` within 1e-6) with determinant +1: a
    /// reflection has no SH rotation of this form and is refused.
    pub fn new(r: Mat3, bands: usize) -> Result<Self> {
        if !(1..=MAX_BANDS).contains(&bands) {
            return Err(Error::invalid(format!(
                "an SH rotation needs 1 to {MAX_BANDS} bands, got {bands}"
            )));
        }
        check_rotation(&r)?;
        let mut blocks: Vec<Vec<f64>> = Vec::with_capacity(bands);
        blocks.push(vec![1.0]);
        if bands > 1 {
            // Phase-free l = 1 functions are ∝ (y, z, x): D¹ is R with rows and columns permuted.
            const YZX: [usize; 3] = [1, 2, 0];
            blocks.push(
                YZX.iter()
                    .flat_map(|&i| YZX.iter().map(move |&j| r[i][j]))
                    .collect(),
            );
        }
        for l in 2..bands {
            let next = ivanic_ruedenberg_band(l, &blocks[1], &blocks[l - 1]);
            blocks.push(next);
        }
        // Conjugate by diag((-1)^m) into the Condon–Shortley convention: (-1)^(m+n)
        // is (-1)^(row+column) because m + n = row + column - 2l.
        for (l, block) in blocks.iter_mut().enumerate() {
            let n = 2 * l + 1;
            for (k, v) in block.iter_mut().enumerate() {
                if (k / n + k % n) % 2 == 1 {
                    *v = -*v;
                }
            }
        }
        Ok(Self {
            bands,
            matrix: r,
            blocks,
        })
    }

    /// The number of bands the rotation covers.
    pub fn bands(&self) -> usize {
        self.bands
    }

    /// The 3×3 rotation it was built from.
    pub fn matrix(&self) -> Mat3 {
        self.matrix
    }

    /// `D^l`, `(2l+1)²` entries row-major (rows: new `m`, columns: old `m`, both
    /// `-l..=l`), or `None` when `l` is not below [`Self::bands`].
    pub fn band_matrix(&self, l: usize) -> Option<&[f64]> {
        self.blocks.get(l).map(Vec::as_slice)
    }

    /// Rotate `coeffs` into `out`. Both hold the same number of coefficients, a square
    /// `b²` with `1 ≤ b ≤ bands` (rotation never mixes bands, so fewer bands than the
    /// rotation was built for are fine).
    pub fn apply(&self, coeffs: &[f64], out: &mut [f64]) -> Result<()> {
        let bands = self.check_lengths(coeffs.len(), out.len())?;
        for (l, block) in self.blocks.iter().take(bands).enumerate() {
            let (n, base) = (2 * l + 1, l * l);
            let src = &coeffs[base..base + n];
            for (row, o) in block.chunks_exact(n).zip(&mut out[base..base + n]) {
                *o = row.iter().zip(src).map(|(a, b)| a * b).sum();
            }
        }
        Ok(())
    }

    /// Rotate `coeffs` (see [`Self::apply`]), allocating.
    pub fn rotate(&self, coeffs: &[f64]) -> Result<Vec<f64>> {
        let mut out = vec![0.0; coeffs.len()];
        self.apply(coeffs, &mut out)?;
        Ok(out)
    }

    /// Rotate RGB-interleaved coefficients (`coeffs[i]` holds coefficient `i` of each
    /// colour) into `out`; lengths as for [`Self::apply`].
    pub fn apply_rgb(&self, coeffs: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<()> {
        let bands = self.check_lengths(coeffs.len(), out.len())?;
        for (l, block) in self.blocks.iter().take(bands).enumerate() {
            let (n, base) = (2 * l + 1, l * l);
            let src = &coeffs[base..base + n];
            for (row, o) in block.chunks_exact(n).zip(&mut out[base..base + n]) {
                *o = [0.0; 3];
                for (a, s) in row.iter().zip(src) {
                    for c in 0..3 {
                        o[c] += a * s[c];
                    }
                }
            }
        }
        Ok(())
    }

    /// The band count of `len` coefficients, checked against the rotation and `out_len`.
    fn check_lengths(&self, len: usize, out_len: usize) -> Result<usize> {
        if len != out_len {
            return Err(Error::invalid(format!(
                "SH rotation: {len} coefficients in but room for {out_len} out; the lengths must match"
            )));
        }
        let bands = (len as f64).sqrt().round() as usize;
        if bands * bands != len || bands == 0 || bands > self.bands {
            return Err(Error::invalid(format!(
                "SH rotation of {} bands cannot rotate {len} coefficients: expected b² with 1 ≤ b ≤ {}",
                self.bands, self.bands
            )));
        }
        Ok(bands)
    }
}

/// `D^l` (phase-free) from `D^1` and `D^{l-1}` by Ivanic & Ruedenberg's recurrence
/// (their Table 2 with the 1998 corrections): `D^l_{mn} = u·U + v·V + w·W`.
fn ivanic_ruedenberg_band(l: usize, d1: &[f64], prev: &[f64]) -> Vec<f64> {
    let li = l as isize;
    let n = 2 * l + 1;
    // Entry (m, n) of a band-`band` block, indices centred on zero.
    let at = |block: &[f64], band: isize, m: isize, k: isize| -> f64 {
        block[((m + band) * (2 * band + 1) + (k + band)) as usize]
    };
    // Their function P^l_{i,a,b}.
    let p = |i: isize, a: isize, b: isize| -> f64 {
        let lp = li - 1;
        if b == li {
            at(d1, 1, i, 1) * at(prev, lp, a, lp) - at(d1, 1, i, -1) * at(prev, lp, a, -lp)
        } else if b == -li {
            at(d1, 1, i, 1) * at(prev, lp, a, -lp) + at(d1, 1, i, -1) * at(prev, lp, a, lp)
        } else {
            at(d1, 1, i, 0) * at(prev, lp, a, b)
        }
    };
    let mut block = vec![0.0; n * n];
    for m in -li..=li {
        for k in -li..=li {
            let (u, v, w) = uvw(m, k, li);
            let delta = |a: isize, b: isize| -> f64 {
                if a == b {
                    1.0
                } else {
                    0.0
                }
            };
            let mut value = 0.0;
            if u != 0.0 {
                value += u * p(0, m, k);
            }
            if v != 0.0 {
                let big_v = match m.cmp(&0) {
                    std::cmp::Ordering::Equal => p(1, 1, k) + p(-1, -1, k),
                    std::cmp::Ordering::Greater => {
                        p(1, m - 1, k) * (1.0 + delta(m, 1)).sqrt()
                            - p(-1, -m + 1, k) * (1.0 - delta(m, 1))
                    }
                    std::cmp::Ordering::Less => {
                        p(1, m + 1, k) * (1.0 - delta(m, -1))
                            + p(-1, -m - 1, k) * (1.0 + delta(m, -1)).sqrt()
                    }
                };
                value += v * big_v;
            }
            if w != 0.0 {
                // w vanishes for m = 0 and |m| ≥ l - 1, so the indices stay in band l - 1.
                let big_w = if m > 0 {
                    p(1, m + 1, k) + p(-1, -m - 1, k)
                } else {
                    p(1, m - 1, k) - p(-1, -m + 1, k)
                };
                value += w * big_w;
            }
            block[((m + li) as usize) * n + (k + li) as usize] = value;
        }
    }
    block
}

/// The coefficients `u, v, w` of Ivanic & Ruedenberg's Table 2 (corrected).
fn uvw(m: isize, k: isize, l: isize) -> (f64, f64, f64) {
    let d = if m == 0 { 1.0 } else { 0.0 };
    let (lf, am) = (l as f64, m.abs() as f64);
    let denom = if k.abs() == l {
        2.0 * lf * (2.0 * lf - 1.0)
    } else {
        ((l + k) * (l - k)) as f64
    };
    let u = (((l + m) * (l - m)) as f64 / denom).sqrt();
    let v = 0.5 * ((1.0 + d) * (lf + am - 1.0) * (lf + am) / denom).sqrt() * (1.0 - 2.0 * d);
    let w = -0.5 * ((lf - am - 1.0) * (lf - am) / denom).max(0.0).sqrt() * (1.0 - d);
    (u, v, w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::rotation::{
        compose, mat3_apply, rotation_about_axis, transpose, MAT3_IDENTITY,
    };
    use crate::basis::{Basis, SphericalHarmonics};
    use crate::sphere::Vec3;
    use std::f64::consts::PI;

    /// The rotation of shared/reference/rotation_reference.txt (rotvec 0.7 rad about
    /// normalize(0.3, -0.5, 0.8)), copied so the tests run without shared/.
    const REFERENCE_R: Mat3 = [
        [0.786438312942, -0.55660005157, -0.267789399584],
        [0.484612966044, 0.824831425222, -0.291210221503],
        [0.382968736424, 0.099244660102, 0.918414636405],
    ];

    /// The "CS (google/Sloan)" band matrices of the same file for l = 1..4, rows and
    /// columns m = -l..l.
    #[rustfmt::skip]
    const REFERENCE_CS: [&[f64]; 4] = [
        &[
            0.824831425222, 0.291210221503, 0.484612966044,
            -0.099244660102, 0.918414636405, -0.382968736424,
            -0.55660005157, 0.267789399584, 0.786438312942,
        ],
        &[
            0.378943432622, 0.058793487812, 0.135070536086, 0.358793090518, 0.840219417261,
            -0.363979897777, 0.728636194039, 0.463239984411, 0.333551230444, -0.103731500823,
            0.06583109787, -0.157872531264, 0.765228166544, -0.609203999006, 0.118485742383,
            0.135110615384, -0.537766301926, 0.425983527118, 0.619721489249, -0.356420869914,
            -0.837455609003, -0.38925093566, -0.011338204273, 0.069475594448, 0.377089377916,
        ],
        &[
            -0.132228607356, -0.174401953939, -0.094510067887, 0.030004841258, 0.112619567852, 0.410061894143, 0.87260139029,
            -0.279867403468, 0.289902828836, 0.073139375073, 0.277385925958, 0.473797374916, 0.640098213804, -0.348035329255,
            0.144934510779, -0.511049784349, 0.59710088021, 0.573760941454, 0.133737609805, -0.11913483464, 0.003488454736,
            -0.033749139132, 0.135193215105, -0.195538155635, 0.559051489635, -0.754549416652, 0.243326770708, -0.035458599961,
            -0.015850449221, 0.212292553138, -0.508726041455, 0.527615745161, 0.397107049997, -0.488608686198, 0.145146884087,
            0.346964354621, -0.626955631423, -0.564220046285, -0.023284562141, 0.104852210086, 0.281086346488, -0.278661840307,
            -0.872587711893, -0.409816701601, -0.117504900075, -0.038678497961, -0.083152359528, -0.175995770058, -0.13209353664,
        ],
        &[
            -0.560750920506, -0.409437284348, -0.17934996985, -0.057508953564, -0.003020074582, 0.005741975613, 0.063250367169, 0.276063558591, 0.634186120512,
            -0.050857390514, -0.089482143469, -0.220499556685, -0.180377319584, 0.072908665607, 0.202357424345, 0.524547565514, 0.587876418679, -0.491159248186,
            0.153076298368, -0.359589825005, 0.19210549282, 0.066763257763, 0.427602976024, 0.486371062239, 0.417288936436, -0.446521785803, 0.113965234683,
            -0.053957768897, 0.264571500523, -0.580813811224, 0.443740715901, 0.614103489537, -0.087050868636, -0.089307475867, -0.002073339101, 0.0126055725,
            0.015381899141, -0.082006922763, 0.208406468055, -0.20928692603, 0.324600748616, -0.807603648691, 0.375099244641, -0.086160736038, 0.009569394824,
            -0.008052207556, -0.037395005912, 0.280545820595, -0.468931471793, 0.564713710587, 0.147216801005, -0.534745717958, 0.26524954831, -0.05522160464,
            -0.113651454397, 0.441880901121, -0.380438250236, -0.671994779492, -0.035894207799, 0.131864788503, 0.167384824161, -0.354365724051, 0.152462808216,
            0.491132882372, -0.587785133728, -0.523485065735, -0.217954905633, -0.093984755652, -0.14411537556, -0.227406085163, -0.088580727631, -0.050928624951,
            -0.634191244763, -0.276002751788, -0.063680769988, -0.003810525712, -0.0178621188, -0.053196191759, -0.17988809776, -0.409391764749, -0.560753021064,
        ],
    ];

    /// The reference prints 12 decimals (rounding ≤ 5e-13, in R and in each entry);
    /// the recurrence adds a few ulps per band.
    const REFERENCE_TOLERANCE: f64 = 1e-9;

    /// Two double-precision evaluations of the same band-limited function, through
    /// eight bands of recurrence and a 64-term sum.
    const EVAL_TOLERANCE: f64 = 1e-10;

    /// A tiny deterministic generator (xorshift64*) so the tests need no dependency.
    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn signed(&mut self) -> f64 {
            2.0 * self.uniform() - 1.0
        }
        fn direction(&mut self) -> Vec3 {
            loop {
                let v = Vec3::new(self.signed(), self.signed(), self.signed());
                if v.length() > 0.1 && v.length() <= 1.0 {
                    return v.normalized().unwrap();
                }
            }
        }
        fn rotation(&mut self) -> Mat3 {
            let axis = self.direction();
            rotation_about_axis(axis, PI * self.signed()).unwrap()
        }
    }

    fn eval(sh: &SphericalHarmonics, coeffs: &[f64], d: Vec3) -> f64 {
        sh.values(d).iter().zip(coeffs).map(|(y, c)| y * c).sum()
    }

    #[test]
    fn matches_the_condon_shortley_reference_band_matrices() {
        let rotation = ShRotation::new(REFERENCE_R, 5).unwrap();
        assert_eq!(rotation.band_matrix(0).unwrap(), &[1.0]);
        for (l, want) in (1..=4).zip(REFERENCE_CS) {
            let got = rotation.band_matrix(l).unwrap();
            assert_eq!(got.len(), want.len());
            for (k, (g, w)) in got.iter().zip(want).enumerate() {
                let n = 2 * l + 1;
                assert!(
                    (g - w).abs() < REFERENCE_TOLERANCE,
                    "band {l} entry (m={}, n={}): {g} vs {w}",
                    (k / n) as isize - l as isize,
                    (k % n) as isize - l as isize
                );
            }
        }
        // The reference rotation is the stated rotation vector.
        let from_axis = rotation_about_axis(Vec3::new(0.3, -0.5, 0.8), 0.7).unwrap();
        for (a, b) in from_axis.iter().flatten().zip(REFERENCE_R.iter().flatten()) {
            assert!((a - b).abs() < REFERENCE_TOLERANCE);
        }
    }

    #[test]
    fn rotate_then_evaluate_equals_evaluate_at_the_inverse_rotated_direction() {
        let mut rng = Rng(0x5eed_1234_abcd_0001);
        for bands in 1..=MAX_BANDS {
            let sh = SphericalHarmonics::new(bands).unwrap();
            for _ in 0..4 {
                let r = rng.rotation();
                let rotation = ShRotation::new(r, bands).unwrap();
                let coeffs: Vec<f64> = (0..bands * bands).map(|_| rng.signed()).collect();
                let rotated = rotation.rotate(&coeffs).unwrap();
                for _ in 0..8 {
                    let d = rng.direction();
                    let want = eval(&sh, &coeffs, mat3_apply(&transpose(&r), d));
                    let got = eval(&sh, &rotated, d);
                    assert!(
                        (got - want).abs() < EVAL_TOLERANCE,
                        "bands {bands}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn rotation_about_z_has_the_closed_form() {
        // f(Rᵀd) shifts the azimuth by -α: c'_m = cos(mα) c_m - sin(mα) c_-m and
        // c'_-m = sin(mα) c_m + cos(mα) c_-m, for m > 0; m = 0 is unchanged.
        let alpha = 0.8;
        let rotation = ShRotation::new(
            rotation_about_axis(Vec3::new(0.0, 0.0, 1.0), alpha).unwrap(),
            8,
        )
        .unwrap();
        for l in 0..MAX_BANDS {
            let li = l as isize;
            let block = rotation.band_matrix(l).unwrap();
            let n = 2 * l + 1;
            let entry = |m: isize, k: isize| block[(m + li) as usize * n + (k + li) as usize];
            for m in -li..=li {
                for k in -li..=li {
                    let ma = m.abs() as f64 * alpha;
                    let want = if m == 0 && k == 0 {
                        1.0
                    } else if m != 0 && k == m {
                        ma.cos()
                    } else if m > 0 && k == -m {
                        -ma.sin()
                    } else if m < 0 && k == -m {
                        ma.sin()
                    } else {
                        0.0
                    };
                    assert!(
                        (entry(m, k) - want).abs() < 1e-12,
                        "l={l} ({m},{k}): {} vs {want}",
                        entry(m, k)
                    );
                }
            }
        }
    }

    #[test]
    fn composition_equals_applying_both() {
        let mut rng = Rng(42);
        for bands in [3, 8] {
            let (r1, r2) = (rng.rotation(), rng.rotation());
            let coeffs: Vec<f64> = (0..bands * bands).map(|_| rng.signed()).collect();
            let both = ShRotation::new(compose(&r1, &r2), bands)
                .unwrap()
                .rotate(&coeffs)
                .unwrap();
            let first = ShRotation::new(r2, bands).unwrap().rotate(&coeffs).unwrap();
            let then = ShRotation::new(r1, bands).unwrap().rotate(&first).unwrap();
            for (a, b) in both.iter().zip(&then) {
                assert!((a - b).abs() < EVAL_TOLERANCE, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn band_matrices_are_orthogonal() {
        let mut rng = Rng(7);
        for _ in 0..3 {
            let rotation = ShRotation::new(rng.rotation(), MAX_BANDS).unwrap();
            for l in 0..MAX_BANDS {
                let n = 2 * l + 1;
                let d = rotation.band_matrix(l).unwrap();
                for i in 0..n {
                    for j in 0..n {
                        let dot: f64 = (0..n).map(|k| d[i * n + k] * d[j * n + k]).sum();
                        let want = if i == j { 1.0 } else { 0.0 };
                        assert!((dot - want).abs() < 1e-12, "band {l} ({i},{j}): {dot}");
                    }
                }
            }
        }
    }

    #[test]
    fn identity_rotation_is_the_identity_on_every_band() {
        let rotation = ShRotation::new(MAT3_IDENTITY, MAX_BANDS).unwrap();
        let coeffs: Vec<f64> = (0..64).map(|i| i as f64 - 20.0).collect();
        assert_eq!(rotation.rotate(&coeffs).unwrap(), coeffs);
    }

    #[test]
    fn rgb_and_truncated_vectors_rotate_like_single_channels() {
        let mut rng = Rng(99);
        let rotation = ShRotation::new(rng.rotation(), 6).unwrap();
        let rgb: Vec<[f64; 3]> = (0..16)
            .map(|_| [rng.signed(), rng.signed(), rng.signed()])
            .collect();
        let mut out = vec![[0.0; 3]; 16];
        rotation.apply_rgb(&rgb, &mut out).unwrap();
        for c in 0..3 {
            let channel: Vec<f64> = rgb.iter().map(|v| v[c]).collect();
            let want = rotation.rotate(&channel).unwrap();
            for (o, w) in out.iter().zip(&want) {
                assert!((o[c] - w).abs() < 1e-14);
            }
        }
        // l = 1 of a 4-band vector is moved like a direction: c' for Y_1 ∝ (-y, z, -x).
        let sh = SphericalHarmonics::new(2).unwrap();
        let d = Vec3::new(0.2, -0.4, 0.7).normalized().unwrap();
        let lobe = sh.values(d); // a function peaking at d, in bands 0..1
        let r = rotation.matrix();
        let turned = rotation.rotate(&lobe).unwrap();
        let want = sh.values(mat3_apply(&r, d));
        for i in 0..4 {
            assert!((turned[i] - want[i]).abs() < 1e-14, "{i}");
        }
    }

    #[test]
    fn bad_input_is_refused_with_an_error() {
        let mirror = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let err = ShRotation::new(mirror, 3).unwrap_err();
        assert!(err.to_string().contains("reflection"), "{err}");
        let sheared = [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(ShRotation::new(sheared, 3)
            .unwrap_err()
            .to_string()
            .contains("orthonormal"));
        let mut nan = MAT3_IDENTITY;
        nan[1][2] = f64::NAN;
        assert!(ShRotation::new(nan, 3).is_err());
        assert!(ShRotation::new(MAT3_IDENTITY, 0).is_err());
        assert!(ShRotation::new(MAT3_IDENTITY, 9).is_err());
        let rotation = ShRotation::new(MAT3_IDENTITY, 3).unwrap();
        assert!(rotation.band_matrix(3).is_none());
        let mut out = vec![0.0; 16];
        assert!(
            rotation.apply(&[0.0; 16], &mut out).is_err(),
            "more bands than built for"
        );
        assert!(
            rotation.apply(&[0.0; 5], &mut out[..5]).is_err(),
            "not a square length"
        );
        assert!(
            rotation.apply(&[0.0; 9], &mut out[..4]).is_err(),
            "lengths differ"
        );
        assert!(
            rotation.apply(&[1.0; 4], &mut out[..4]).is_ok(),
            "fewer bands are fine"
        );
    }
}
