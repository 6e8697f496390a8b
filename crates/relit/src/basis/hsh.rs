//! Hemispherical harmonics: the spherical harmonics of the upper hemisphere.
//!
//! Definition (Gautron, Křivánek, Pattanaik, Bouatouch 2004, "A Novel Hemispherical
//! Basis for Accurate and Efficient Rendering"): with θ the angle from +z, the pole of
//! an RTI dome, the hemisphere `θ ∈ [0, π/2]` is stretched over the whole sphere by
//! `cos θ' = 2 cos θ − 1`, and
//!
//! ```text
//!   H_lm(θ, φ) = √2 · Y_lm(θ', φ)
//! ```
//!
//! with `Y_lm` relit's real spherical harmonics ([`super::sh`]): the same flat index
//! `l(l+1) + m`, cos for `m > 0`, sin for `m < 0`, **with the Condon–Shortley phase**.
//! Since `d(cos θ) = d(cos θ')/2` the `√2` makes them orthonormal over the hemisphere:
//! `∫_{z≥0} H_i H_j dω = δ_ij`. The OpenLIME viewer (`shared/clients/openlime`, whose
//! formulas come from relight) hard-codes the first nine functions with every `m ≠ 0`
//! one negated, lists them `m = l … −l` within a band, and clamps the light's elevation
//! to at least 0.15 rad; these functions follow the paper down to the horizon.
//!
//! The stretched direction `(sin θ' cos φ, sin θ' sin φ, cos θ')` is
//! `(a·x, a·y, 2z − 1)` with `a = sin θ'/sin θ = 2·√(z/(1+z))`, so the evaluator is the
//! SH evaluator at that point, free of trigonometry and of the pole's 0/0.
//!
//! **Below the horizon** (`z < 0`) the functions take their value at the horizon
//! direction `(x, y, 0)/|(x, y)|`, which the stretch sends to the far pole whatever the
//! azimuth: every `m ≠ 0` function is 0 there and every `m = 0` one a constant, so the
//! continuation is continuous and simply `z` clamped to 0.
//!
//! The functions with `|m| = 1` grow like `√z` off the horizon, so their mean squared
//! gradient over the hemisphere diverges (logarithmically, at the horizon). The penalty
//! is therefore the numerical default ([`super::roughness_penalty`]), whose Fibonacci
//! points stop half a row short of the horizon; no closed form exists to check it by.

use super::{Basis, BasisSpec, BuildContext, Domain, Family, SphericalHarmonics};
use crate::sphere::Vec3;
use crate::{Error, Result};

/// The `hsh` family: `hsh:K` with K = order², order 2 to [`MAX_ORDER`].
pub(super) struct HshFamily;

pub(super) static FAMILY: HshFamily = HshFamily;

/// The most orders offered (K = 25): domes hold 40 to 80 lights, and more functions than
/// about half the lights leave the fit to the regulariser.
pub const MAX_ORDER: usize = 5;

/// The fewest: one order is a constant, which no RTI wants.
const MIN_ORDER: usize = 2;

impl Family for HshFamily {
    fn name(&self) -> &'static str {
        "hsh"
    }

    fn summary(&self) -> &'static str {
        "hemispherical harmonics, orthonormal over z ≥ 0 (K = 4, 9, 16, 25)"
    }

    fn sizes(&self, max: usize) -> Vec<usize> {
        (MIN_ORDER..=MAX_ORDER)
            .map(|o| o * o)
            .filter(|&k| k <= max)
            .collect()
    }

    fn nested(&self, _: usize) -> bool {
        // The spherical harmonics in order, at the stretched direction.
        true
    }

    fn build(&self, k: usize, _: &BuildContext) -> Result<Box<dyn Basis>> {
        let order = (k as f64).sqrt().round() as usize;
        if order * order != k {
            return Err(Error::invalid(format!(
                "hemispherical harmonics have a square number of coefficients, not {k}"
            )));
        }
        Ok(Box::new(HemisphericalHarmonics::new(order)?))
    }

    fn rebuild(
        &self,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Box<dyn Basis>> {
        let order = params
            .get("order")
            .and_then(|v| v.as_u64())
            .ok_or_else(|| Error::parse("an `hsh` basis needs an integer `order`"))?;
        if params.len() != 1 {
            return Err(Error::parse("an `hsh` basis has only `order`"));
        }
        Ok(Box::new(HemisphericalHarmonics::new(order as usize)?))
    }
}

/// Real hemispherical harmonics of `order` orders; coefficient `i = l(l+1) + m`.
#[derive(Clone, Debug)]
pub struct HemisphericalHarmonics {
    sh: SphericalHarmonics,
}

impl HemisphericalHarmonics {
    /// Hemispherical harmonics of `order` orders (2..=5): `order²` functions.
    pub fn new(order: usize) -> Result<Self> {
        if !(MIN_ORDER..=MAX_ORDER).contains(&order) {
            return Err(Error::invalid(format!(
                "hemispherical harmonics need {MIN_ORDER} to {MAX_ORDER} orders, got {order}"
            )));
        }
        Ok(Self {
            sh: SphericalHarmonics::new(order)?,
        })
    }

    /// The number of orders (bands).
    pub fn order(&self) -> usize {
        self.sh.bands()
    }
}

/// The point of the whole sphere that the hemisphere direction `dir` is stretched to;
/// directions below the horizon go where the horizon goes, the far pole.
#[inline]
fn stretched(dir: Vec3) -> Vec3 {
    let z = dir.z.clamp(0.0, 1.0);
    let a = 2.0 * (z / (1.0 + z)).sqrt();
    Vec3::new(a * dir.x, a * dir.y, 2.0 * z - 1.0)
}

impl Basis for HemisphericalHarmonics {
    fn spec(&self) -> BasisSpec {
        BasisSpec::new("hsh", serde_json::json!({ "order": self.order() }))
    }

    fn family(&self) -> &'static str {
        "hsh"
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn len(&self) -> usize {
        self.sh.len()
    }

    fn domain(&self) -> Domain {
        Domain::UpperHemisphere
    }

    fn eval(&self, dir: Vec3, out: &mut [f64]) {
        self.sh.eval(stretched(dir), out);
        out[..self.len()]
            .iter_mut()
            .for_each(|v| *v *= std::f64::consts::SQRT_2);
    }

    fn label(&self, i: usize) -> String {
        self.sh.label(i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::sh_index;
    use std::f64::consts::PI;

    /// The paper's definition transcribed literally: θ and φ by trigonometry, the
    /// stretch `2 cos θ − 1`, factorials, and the associated Legendre function by the
    /// textbook closed form for `P_l^l` and the recurrence in `l`, Condon–Shortley
    /// phase included. Nothing here is shared with the fast evaluator.
    fn paper_h(l: usize, m: isize, theta: f64, phi: f64) -> f64 {
        fn legendre(l: usize, m: usize, x: f64) -> f64 {
            let double_factorial = (1..=2 * m).step_by(2).map(|f| f as f64).product::<f64>();
            let sign = if m % 2 == 1 { -1.0 } else { 1.0 };
            let pmm = sign * double_factorial * (1.0 - x * x).powf(m as f64 / 2.0);
            if l == m {
                return pmm;
            }
            let (mut p0, mut p1) = (pmm, x * (2 * m + 1) as f64 * pmm);
            for n in m + 2..=l {
                let p2 = ((2 * n - 1) as f64 * x * p1 - (n + m - 1) as f64 * p0) / (n - m) as f64;
                p0 = p1;
                p1 = p2;
            }
            p1
        }
        let fact = |n: usize| (1..=n).map(|f| f as f64).product::<f64>();
        let am = m.unsigned_abs();
        let k = ((2 * l + 1) as f64 / (2.0 * PI) * fact(l - am) / fact(l + am)).sqrt();
        let p = legendre(l, am, 2.0 * theta.cos() - 1.0);
        match m.cmp(&0) {
            std::cmp::Ordering::Greater => 2f64.sqrt() * k * (m as f64 * phi).cos() * p,
            std::cmp::Ordering::Equal => k * p,
            std::cmp::Ordering::Less => 2f64.sqrt() * k * (am as f64 * phi).sin() * p,
        }
    }

    /// Two evaluations of the same function in double precision.
    const TRANSCRIPTION_TOLERANCE: f64 = 1e-11;

    #[test]
    fn fast_evaluator_equals_the_papers_definition_for_every_l_m() {
        let hsh = HemisphericalHarmonics::new(MAX_ORDER).unwrap();
        for d in crate::sphere::hemisphere_fibonacci(60) {
            let h = hsh.values(d);
            let (theta, phi) = d.to_spherical();
            for l in 0..MAX_ORDER {
                for m in -(l as isize)..=(l as isize) {
                    let want = paper_h(l, m, theta, phi);
                    let got = h[sh_index(l, m)];
                    assert!(
                        (got - want).abs() < TRANSCRIPTION_TOLERANCE,
                        "l={l} m={m} at {d:?}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_nine_functions_of_openlime_up_to_sign() {
        // OpenLIME hard-codes the first nine functions (order 3) in the frame of an `.lp`
        // file; every one with m ≠ 0 is ours negated (no Condon–Shortley phase for
        // |m| = 1, the opposite sign for |m| = 2). Written out here from its formulas.
        let d = Vec3::new(0.3, -0.5, 0.8).normalized().unwrap();
        let (theta, phi) = d.to_spherical();
        let (c, s) = (theta.cos(), (theta.cos() - theta.cos().powi(2)).sqrt());
        let tools = [
            (0, 0, 1.0 / (2.0 * PI).sqrt()),
            (1, 1, (6.0 / PI).sqrt() * s * phi.cos()),
            (1, 0, (3.0 / (2.0 * PI)).sqrt() * (2.0 * c - 1.0)),
            (1, -1, (6.0 / PI).sqrt() * s * phi.sin()),
            (2, 2, (30.0 / PI).sqrt() * (c * c - c) * (2.0 * phi).cos()),
            (2, 1, (30.0 / PI).sqrt() * (2.0 * c - 1.0) * s * phi.cos()),
            (
                2,
                0,
                (5.0 / (2.0 * PI)).sqrt() * (6.0 * c * c - 6.0 * c + 1.0),
            ),
            (2, -1, (30.0 / PI).sqrt() * (2.0 * c - 1.0) * s * phi.sin()),
            (2, -2, (30.0 / PI).sqrt() * (c * c - c) * (2.0 * phi).sin()),
        ];
        let h = HemisphericalHarmonics::new(3).unwrap().values(d);
        for (l, m, theirs) in tools {
            let sign = if m == 0 { 1.0 } else { -1.0 };
            let got = h[sh_index(l, m)];
            assert!(
                (got - sign * theirs).abs() < TRANSCRIPTION_TOLERANCE,
                "l={l} m={m}: {got} vs {}",
                sign * theirs
            );
        }
    }

    /// Midpoint quadrature in `cos θ` and φ: the φ sum is exact for these trigonometric
    /// polynomials, and products of functions of equal `|m|` are polynomials in `cos θ`
    /// of degree ≤ 8, on which 2000 rings leave an error near 1e-6.
    const QUADRATURE_TOLERANCE: f64 = 1e-5;

    #[test]
    fn orthonormal_over_the_upper_hemisphere() {
        let (rings, columns) = (2000, 32);
        let hsh = HemisphericalHarmonics::new(MAX_ORDER).unwrap();
        let k = hsh.len();
        let cell = 2.0 * PI / (rings * columns) as f64;
        let mut gram = vec![0.0; k * k];
        for r in 0..rings {
            let z = (r as f64 + 0.5) / rings as f64;
            for c in 0..columns {
                let phi = 2.0 * PI * (c as f64 + 0.5) / columns as f64;
                let h = hsh.values(Vec3::from_spherical(z.acos(), phi));
                for i in 0..k {
                    for j in 0..k {
                        gram[i * k + j] += cell * h[i] * h[j];
                    }
                }
            }
        }
        for i in 0..k {
            for j in 0..k {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!(
                    (gram[i * k + j] - want).abs() < QUADRATURE_TOLERANCE,
                    "<H{i},H{j}> = {}",
                    gram[i * k + j]
                );
            }
        }
    }

    #[test]
    fn the_first_function_is_constant_and_the_continuation_is_the_horizon() {
        let hsh = HemisphericalHarmonics::new(4).unwrap();
        for d in crate::sphere::fibonacci(200) {
            let h = hsh.values(d);
            assert!((h[0] - 1.0 / (2.0 * PI).sqrt()).abs() < 1e-15);
            if d.z < 0.0 {
                let horizon = Vec3::new(d.x, d.y, 0.0).normalized().unwrap();
                assert_eq!(h, hsh.values(horizon));
            }
        }
        // Just above and just below the horizon agree: the continuation is continuous.
        let above = hsh.values(Vec3::new(0.6, 0.8, 1e-12).normalized().unwrap());
        let below = hsh.values(Vec3::new(0.6, 0.8, -0.3).normalized().unwrap());
        for (a, b) in above.iter().zip(&below) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
        // The far pole has no horizon direction and needs none.
        assert!(hsh
            .values(Vec3::new(0.0, 0.0, -1.0))
            .iter()
            .all(|v| v.is_finite()));
    }

    /// The octahedral table cannot follow the `√z` of the `|m| = 1` functions at the
    /// horizon (its error there shrinks only like the cell size: relative RMS over the
    /// sphere 2.5e-3 to 7.6e-3 at 256 cells for orders 2 to 5, 1.1e-3 to 3.3e-3 at 512), so
    /// [`WeightTable::for_basis`] never reaches its tolerance. Above 2° of elevation, where
    /// RTI lights are, 256 cells do for orders 2 to 4 (measured 2.2e-4, 5.0e-4, 9.0e-4).
    #[test]
    fn a_weight_table_of_256_reproduces_it_above_two_degrees() {
        use crate::basis::table::{WeightTable, TABLE_TOLERANCE};
        let lowest = 2f64.to_radians().sin();
        for order in 2..=4 {
            let hsh = HemisphericalHarmonics::new(order).unwrap();
            let table = WeightTable::new(&hsh, 256);
            let (mut sq_err, mut sq) = (0.0, 0.0);
            let mut t = vec![0f32; hsh.len()];
            for d in crate::sphere::fibonacci(20000) {
                if d.z < lowest {
                    continue;
                }
                table.sample(d, &mut t);
                for (a, b) in hsh.values(d).iter().zip(&t) {
                    sq_err += (a - *b as f64).powi(2);
                    sq += a * a;
                }
            }
            let rms = (sq_err / sq).sqrt();
            assert!(rms <= TABLE_TOLERANCE, "order {order}: {rms}");
        }
    }

    #[test]
    fn orders_are_checked() {
        assert!(HemisphericalHarmonics::new(1).is_err());
        assert!(HemisphericalHarmonics::new(MAX_ORDER + 1).is_err());
        assert_eq!(HemisphericalHarmonics::new(4).unwrap().len(), 16);
        let bad = serde_json::json!({"order": 3, "bands": 3});
        assert!(BasisSpec::new("hsh", bad).build().is_err());
        assert!(BasisSpec::new("hsh", serde_json::json!({"order": "3"}))
            .build()
            .is_err());
    }
}
