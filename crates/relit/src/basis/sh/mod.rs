//! Real spherical harmonics, orthonormal, with the Condon–Shortley phase.
//!
//! Definition: the appendix of seed 000 (Wong, Or, Fu), identical to the `Y_CS` column of
//! `shared/reference/sh_reference_values.csv`. The evaluator below avoids trigonometry:
//! `sinᵐθ·cos(mφ)` and `sinᵐθ·sin(mφ)` are the real and imaginary parts of `(x + iy)ᵐ`,
//! so each `Y_lm` is a polynomial in `(x, y, z)` built by the appendix's recurrence on
//! the associated Legendre functions with the `sinᵐθ` factor taken out.

mod environment;
mod rotation;

pub use environment::ShEnvironment;
pub use rotation::ShRotation;

use super::{Basis, BasisSpec, BuildContext, Family, PreparedEnvironment};
use crate::image::ImageRgb;
use crate::sphere::Vec3;
use crate::{Error, Result};
use std::f64::consts::PI;

/// The `sh` family: `sh:K` with K = bands², 1 ≤ bands ≤ [`MAX_BANDS`].
pub(super) struct ShFamily;

pub(super) static FAMILY: ShFamily = ShFamily;

impl Family for ShFamily {
    fn name(&self) -> &'static str {
        "sh"
    }

    fn summary(&self) -> &'static str {
        "real spherical harmonics (K = 1, 4, 9, …, 64)"
    }

    fn sizes(&self, max: usize) -> Vec<usize> {
        (1..=MAX_BANDS)
            .map(|b| b * b)
            .filter(|&k| k <= max)
            .collect()
    }

    fn nested(&self, _: usize) -> bool {
        // Bands in order, each with its closed-form penalty.
        true
    }

    fn build(&self, k: usize, _: &BuildContext) -> Result<Box<dyn Basis>> {
        let bands = (k as f64).sqrt().round() as usize;
        if bands * bands != k {
            return Err(Error::invalid(format!(
                "spherical harmonics have a square number of coefficients, not {k}"
            )));
        }
        Ok(Box::new(SphericalHarmonics::new(bands)?))
    }

    fn rebuild(
        &self,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Box<dyn Basis>> {
        let bands = params
            .get("bands")
            .and_then(|v| v.as_u64())
            .ok_or_else(|| Error::parse("an `sh` basis needs an integer `bands`"))?;
        if params.len() != 1 {
            return Err(Error::parse("an `sh` basis has only `bands`"));
        }
        Ok(Box::new(SphericalHarmonics::new(bands as usize)?))
    }
}

/// The most bands relit supports (k = 64 coefficients).
pub const MAX_BANDS: usize = 8;

/// Real SH of `bands` bands; coefficient `i = l(l+1) + m`.
#[derive(Clone, Debug)]
pub struct SphericalHarmonics {
    bands: usize,
    /// `K_lm` for m = 0 and `√2·K_lm` for m > 0, indexed `l * MAX_BANDS + m`.
    norm: Vec<f64>,
}

/// The factor of the real `Y_lm` (m ≥ 0) over `P_lᵐ(cos θ)·cos(mφ)`:
/// `K_lm = sqrt((2l+1)/(4π) · (l−m)!/(l+m)!)`, times √2 for m > 0. The one definition;
/// the SIMD kernel takes its constants from here.
pub(crate) fn normalisation(l: usize, m: usize) -> f64 {
    let ratio: f64 = ((l - m + 1)..=(l + m)).map(|f| 1.0 / f as f64).product();
    let k = ((2 * l + 1) as f64 / (4.0 * PI) * ratio).sqrt();
    if m == 0 {
        k
    } else {
        std::f64::consts::SQRT_2 * k
    }
}

impl SphericalHarmonics {
    /// Spherical harmonics of `bands` bands (1..=8).
    pub fn new(bands: usize) -> Result<Self> {
        if !(1..=MAX_BANDS).contains(&bands) {
            return Err(Error::invalid(format!(
                "spherical harmonics need 1 to {MAX_BANDS} bands, got {bands}"
            )));
        }
        let mut norm = vec![0.0; MAX_BANDS * MAX_BANDS];
        for l in 0..bands {
            for m in 0..=l {
                norm[l * MAX_BANDS + m] = normalisation(l, m);
            }
        }
        Ok(Self { bands, norm })
    }

    /// The number of bands.
    pub fn bands(&self) -> usize {
        self.bands
    }
}

/// Flat index `l(l+1) + m`.
#[inline]
pub fn sh_index(l: usize, m: isize) -> usize {
    ((l * (l + 1)) as isize + m) as usize
}

impl Basis for SphericalHarmonics {
    fn spec(&self) -> BasisSpec {
        BasisSpec::new("sh", serde_json::json!({ "bands": self.bands }))
    }

    fn family(&self) -> &'static str {
        "sh"
    }

    fn environment(&self, map: &ImageRgb) -> Option<Result<Box<dyn PreparedEnvironment>>> {
        Some(
            ShEnvironment::project(map, self.bands)
                .map(|e| Box::new(e) as Box<dyn PreparedEnvironment>),
        )
    }

    fn coefficient_bands(&self) -> Option<Vec<usize>> {
        Some(
            (0..self.bands)
                .flat_map(|l| std::iter::repeat_n(l, 2 * l + 1))
                .collect(),
        )
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn len(&self) -> usize {
        self.bands * self.bands
    }

    fn eval(&self, dir: Vec3, out: &mut [f64]) {
        let (x, y, z) = (dir.x, dir.y, dir.z);
        let n = self.bands;
        // (x + iy)^m, built incrementally.
        let (mut cm, mut sm) = (1.0f64, 0.0f64);
        // P̃_mm = (-1)^m (2m-1)!!, the Condon–Shortley phase included.
        let mut pmm = 1.0f64;
        for m in 0..n {
            if m > 0 {
                let (c, s) = (x * cm - y * sm, x * sm + y * cm);
                cm = c;
                sm = s;
                pmm *= -((2 * m - 1) as f64);
            }
            // Walk l = m, m+1, … with the three-term recurrence.
            let mut p_prev = 0.0f64;
            let mut p_cur = pmm;
            for l in m..n {
                if l == m + 1 {
                    p_prev = p_cur;
                    p_cur = (2 * m + 1) as f64 * z * pmm;
                } else if l > m + 1 {
                    let next = ((2 * l - 1) as f64 * z * p_cur - (l + m - 1) as f64 * p_prev)
                        / (l - m) as f64;
                    p_prev = p_cur;
                    p_cur = next;
                }
                let base = l * (l + 1);
                let k = self.norm[l * MAX_BANDS + m];
                if m == 0 {
                    out[base] = k * p_cur;
                } else {
                    out[base + m] = k * p_cur * cm;
                    out[base - m] = k * p_cur * sm;
                }
            }
        }
    }

    fn penalty(&self) -> Vec<f64> {
        // ∫|∇f|² dω = Σ l(l+1) c_lm² for orthonormal SH; divided by 4π it is a mean.
        let k = self.len();
        let mut p = vec![0.0; k * k];
        for l in 0..self.bands {
            for i in l * l..(l + 1) * (l + 1) {
                p[i * k + i] = (l * (l + 1)) as f64 / (4.0 * PI);
            }
        }
        p
    }

    fn label(&self, i: usize) -> String {
        let l = (i as f64).sqrt() as usize;
        let m = i as isize - (l * (l + 1)) as isize;
        format!("l{l}m{m}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The appendix of seed 000 transcribed literally (θ, φ, factorials, the Q recurrence
    /// with the √(1-x²) factor), slow and obviously right: the fast evaluator is checked
    /// against it for every (l, m).
    fn appendix_y(l: usize, m: isize, theta: f64, phi: f64) -> f64 {
        fn q(l: usize, m: usize, x: f64) -> f64 {
            if l == 0 && m == 0 {
                1.0
            } else if l == m {
                (1.0 - 2.0 * m as f64) * (1.0 - x * x).sqrt() * q(m - 1, m - 1, x)
            } else if l == m + 1 {
                (2 * m + 1) as f64 * x * q(m, m, x)
            } else {
                ((2 * l - 1) as f64 / (l - m) as f64) * x * q(l - 1, m, x)
                    - ((l + m - 1) as f64 / (l - m) as f64) * q(l - 2, m, x)
            }
        }
        let fact = |n: usize| (1..=n).map(|f| f as f64).product::<f64>();
        let am = m.unsigned_abs();
        let n = ((2 * l + 1) as f64 / (2.0 * PI) * fact(l - am) / fact(l + am)).sqrt();
        let x = theta.cos();
        match m.cmp(&0) {
            std::cmp::Ordering::Greater => n * q(l, am, x) * (m as f64 * phi).cos(),
            std::cmp::Ordering::Equal => n * q(l, 0, x) / std::f64::consts::SQRT_2,
            std::cmp::Ordering::Less => n * q(l, am, x) * (am as f64 * phi).sin(),
        }
    }

    /// Rows of the `Y_CS` column of shared/reference/sh_reference_values.csv (SciPy 1.17),
    /// copied here so the tests run without shared/: (direction, l, m, value).
    const D2: [f64; 3] = [0.267261241912424, 0.534522483824849, 0.801783725737273];
    const D3: [f64; 3] = [-0.872871560943970, 0.436435780471985, -0.218217890235992];
    #[rustfmt::skip]
    #[allow(clippy::excessive_precision)] // SciPy's digits, as printed
    const REFERENCE: &[([f64; 3], usize, isize, f64)] = &[
        (D2,0,0,2.820947917738781e-01),(D2,1,-1,-2.611690282654089e-01),(D2,1,0,3.917535423981135e-01),(D2,1,1,-1.305845141327045e-01),
        (D2,2,-2,1.560783472274399e-01),(D2,2,-1,-4.682350416823196e-01),(D2,2,0,2.928635963059114e-01),(D2,2,1,-2.341175208411599e-01),(D2,2,2,-1.170587604205798e-01),
        (D2,3,-3,2.252796894660853e-02),(D2,3,-2,3.310921731627339e-01),(D2,3,-1,-5.409527810353756e-01),(D2,3,0,6.411572363594455e-02),(D2,3,1,-2.704763905176878e-01),(D2,3,2,-2.483191298720503e-01),(D2,3,3,1.239038292063471e-01),
        (D2,4,-4,-7.663294719785828e-02),(D2,4,-3,5.418767662591615e-02),(D2,4,-2,4.730873478787799e-01),(D2,4,-1,-4.301013494296858e-01),(D2,4,0,-1.926808175955506e-01),(D2,4,1,-2.150506747148429e-01),(D2,4,2,-3.548155109090848e-01),(D2,4,3,2.980322214425393e-01),(D2,4,4,-2.235127626604203e-02),
        (D3,0,0,2.820947917738781e-01),(D3,1,-1,-2.132436186229232e-01),(D3,1,0,-1.066218093114616e-01),(D3,1,1,4.264872372458462e-01),
        (D3,2,-2,-4.162089259398398e-01),(D3,2,-1,1.040522314849600e-01),(D3,2,0,-2.703356273593028e-01),(D3,2,1,-2.081044629699199e-01),(D3,2,2,3.121566944548796e-01),
        (D3,3,-3,-5.395576155244555e-01),(D3,3,-2,2.402983354304916e-01),(D3,3,-1,1.519780115814982e-01),(D3,3,0,2.249122673838838e-01),(D3,3,1,-3.039560231629963e-01),(D3,3,2,-1.802237515728686e-01),(D3,3,3,9.810138464080932e-02),
        (D3,4,-4,-5.449454022958813e-01),(D3,4,-3,3.532233735615284e-01),(D3,4,-2,2.402983354304914e-01),(D3,4,-1,-1.699165824907402e-01),(D3,4,0,1.746301091933530e-01),(D3,4,1,3.398331649814803e-01),(D3,4,2,-1.802237515728684e-01),(D3,4,3,-6.422243155664102e-02),(D3,4,4,-1.589424090029657e-01),
        ([0.0,0.0,1.0],0,0,2.820947917738781e-01),([0.0,0.0,1.0],1,0,4.886025119029199e-01),([0.0,0.0,1.0],2,0,6.307831305050400e-01),([0.0,0.0,1.0],3,0,7.463526651802308e-01),([0.0,0.0,1.0],4,0,8.462843753216343e-01),
    ];

    /// SciPy prints 16 significant digits; the recurrence loses a few ulps.
    const REFERENCE_TOLERANCE: f64 = 1e-13;

    #[test]
    fn matches_scipy_reference_values() {
        let sh = SphericalHarmonics::new(5).unwrap();
        for &(d, l, m, expected) in REFERENCE {
            let y = sh.values(Vec3::from(d));
            let got = y[sh_index(l, m)];
            assert!(
                (got - expected).abs() < REFERENCE_TOLERANCE,
                "Y_{l},{m} at {d:?}: {got} vs {expected}"
            );
        }
        // The pole row lists all 25 (l, m); the off-axis ones must vanish there.
        let pole = sh.values(Vec3::new(0.0, 0.0, 1.0));
        for l in 0..5usize {
            for m in -(l as isize)..=(l as isize) {
                if m != 0 {
                    assert!(pole[sh_index(l, m)].abs() < REFERENCE_TOLERANCE);
                }
            }
        }
    }

    /// Agreement between two evaluations of the same polynomial in double precision.
    const APPENDIX_TOLERANCE: f64 = 1e-11;

    #[test]
    fn fast_evaluator_equals_the_appendix_for_every_l_m() {
        let sh = SphericalHarmonics::new(MAX_BANDS).unwrap();
        for d in crate::sphere::fibonacci(40) {
            let y = sh.values(d);
            let (theta, phi) = d.to_spherical();
            for l in 0..MAX_BANDS {
                for m in -(l as isize)..=(l as isize) {
                    let want = appendix_y(l, m, theta, phi);
                    let got = y[sh_index(l, m)];
                    assert!(
                        (got - want).abs() < APPENDIX_TOLERANCE,
                        "l={l} m={m}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn orthonormal_under_quadrature() {
        // A fine grid with solid-angle weights integrates products of band-limited functions.
        let dirs = crate::sphere::grid(64, 128);
        let w = crate::sphere::grid_quadrature_weights(&dirs).unwrap();
        let sh = SphericalHarmonics::new(4).unwrap();
        let k = sh.len();
        let mut gram = vec![0.0; k * k];
        for (d, wd) in dirs.iter().zip(&w) {
            let y = sh.values(*d);
            for i in 0..k {
                for j in 0..k {
                    gram[i * k + j] += wd * y[i] * y[j] * 4.0 * PI / dirs.len() as f64;
                }
            }
        }
        for i in 0..k {
            for j in 0..k {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!(
                    (gram[i * k + j] - want).abs() < 2e-3,
                    "<Y{i},Y{j}> = {}",
                    gram[i * k + j]
                );
            }
        }
    }

    #[test]
    fn band_limits_are_enforced() {
        assert!(SphericalHarmonics::new(0).is_err());
        assert!(SphericalHarmonics::new(9).is_err());
        assert_eq!(SphericalHarmonics::new(8).unwrap().len(), 64);
    }
}
