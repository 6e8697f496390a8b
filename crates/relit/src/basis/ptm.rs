//! The polynomial texture map: Malzbender, Gelb, Wolters 2001, "Polynomial Texture Maps".
//!
//! A pixel is a biquadratic in the light's projection `(lu, lv)` onto the image plane,
//!
//! ```text
//!   a0·lu² + a1·lv² + a2·lu·lv + a3·lu + a4·lv + a5
//! ```
//!
//! with `(lu, lv)` the light vector's x and y in the capture's frame (x right, y up:
//! the `.lp` frame, [conventions](crate)). The coefficients keep the paper's order
//! `a0..a5` because the `.ptm` file stores them in that order.
//!
//! The polynomial only sees `(lu, lv)`, so on its own a light below the horizon would
//! act as its mirror image above. Instead, **below the horizon** (`z < 0`) it takes its
//! value at the horizon direction `(x, y, 0)/|(x, y)|`; at the far pole, whose horizon
//! direction is every one, it takes the mean over the horizon (`lu² = lv² = ½`).

use super::{Basis, BasisSpec, BuildContext, Domain, Family};
use crate::sphere::Vec3;
use crate::{Error, Result};

/// The `ptm` family: `ptm:6` only.
pub(super) struct PtmFamily;

pub(super) static FAMILY: PtmFamily = PtmFamily;

/// The coefficients of a biquadratic.
const K: usize = 6;

impl Family for PtmFamily {
    fn name(&self) -> &'static str {
        "ptm"
    }

    fn summary(&self) -> &'static str {
        "polynomial texture map, biquadratic in the light's (x, y) (K = 6)"
    }

    fn sizes(&self, max: usize) -> Vec<usize> {
        [K].into_iter().filter(|&k| k <= max).collect()
    }

    fn build(&self, k: usize, _: &BuildContext) -> Result<Box<dyn Basis>> {
        if k != K {
            return Err(Error::invalid(format!(
                "a polynomial texture map has {K} coefficients, not {k}"
            )));
        }
        Ok(Box::new(PolynomialTextureMap))
    }

    fn rebuild(
        &self,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Box<dyn Basis>> {
        if let Some(key) = params.keys().next() {
            return Err(Error::parse(format!(
                "a `ptm` basis has no parameters, found `{key}`"
            )));
        }
        Ok(Box::new(PolynomialTextureMap))
    }
}

/// The six functions `lu², lv², lu·lv, lu, lv, 1`.
#[derive(Clone, Copy, Debug, Default)]
pub struct PolynomialTextureMap;

impl Basis for PolynomialTextureMap {
    fn spec(&self) -> BasisSpec {
        BasisSpec::new("ptm", serde_json::json!({}))
    }

    fn family(&self) -> &'static str {
        "ptm"
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn len(&self) -> usize {
        K
    }

    fn domain(&self) -> Domain {
        Domain::UpperHemisphere
    }

    fn eval(&self, dir: Vec3, out: &mut [f64]) {
        /// Below this `|(x, y)|` a light under the horizon is taken to be at the far pole.
        const FAR_POLE: f64 = 1e-12;
        let (lu, lv) = if dir.z >= 0.0 {
            (dir.x, dir.y)
        } else {
            let r = dir.x.hypot(dir.y);
            if r < FAR_POLE {
                out[..K].copy_from_slice(&[0.5, 0.5, 0.0, 0.0, 0.0, 1.0]);
                return;
            }
            (dir.x / r, dir.y / r)
        };
        out[..K].copy_from_slice(&[lu * lu, lv * lv, lu * lv, lu, lv, 1.0]);
    }

    /// The mean over the hemisphere of `|∇_S f|² = |∇f|² − (∇f·L)²` (the surface
    /// gradient is the plane gradient in `(x, y)` with its radial part removed). Every
    /// product is a polynomial in `x, y` even in `z`, so hemisphere and sphere means
    /// agree, and the even moments `⟨x²⟩ = 1/3`, `⟨x⁴⟩ = 1/5`, `⟨x²y²⟩ = 1/15` give
    /// `⟨|∇x²|²⟩ = 4/3 − 4/5`, `⟨∇x²·∇y²⟩ = −4/15`, `⟨|∇xy|²⟩ = 2/3 − 4/15`,
    /// `⟨|∇x|²⟩ = 2/3`; odd products vanish.
    fn penalty(&self) -> Vec<f64> {
        #[rustfmt::skip]
        let p = vec![
            8.0 / 15.0, -4.0 / 15.0, 0.0,       0.0,       0.0,       0.0,
            -4.0 / 15.0, 8.0 / 15.0, 0.0,       0.0,       0.0,       0.0,
            0.0,        0.0,         2.0 / 5.0, 0.0,       0.0,       0.0,
            0.0,        0.0,         0.0,       2.0 / 3.0, 0.0,       0.0,
            0.0,        0.0,         0.0,       0.0,       2.0 / 3.0, 0.0,
            0.0,        0.0,         0.0,       0.0,       0.0,       0.0,
        ];
        p
    }

    fn label(&self, i: usize) -> String {
        ["lu2", "lv2", "lulv", "lu", "lv", "1"][i].to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Products of a few exactly representable numbers.
    const EXACT: f64 = 1e-15;

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < EXACT)
    }

    #[test]
    fn values_at_known_directions() {
        let ptm = PolynomialTextureMap;
        // Straight on: only the constant.
        let top = ptm.values(Vec3::new(0.0, 0.0, 1.0));
        assert!(close(&top, &[0.0, 0.0, 0.0, 0.0, 0.0, 1.0]));
        // From the right (+x) at the horizon, and from above (+y).
        let right = ptm.values(Vec3::new(1.0, 0.0, 0.0));
        assert!(close(&right, &[1.0, 0.0, 0.0, 1.0, 0.0, 1.0]));
        let up = ptm.values(Vec3::new(0.0, 1.0, 0.0));
        assert!(close(&up, &[0.0, 1.0, 0.0, 0.0, 1.0, 1.0]));
        // A 3-4-5 light from the lower left: lu = -0.36, lv = -0.48, z = 0.8.
        let d = Vec3::new(-0.36, -0.48, 0.8);
        let want = [0.1296, 0.2304, 0.1728, -0.36, -0.48, 1.0];
        assert!(close(&ptm.values(d), &want), "{:?}", ptm.values(d));
    }

    #[test]
    fn below_the_horizon_is_the_horizon_not_the_mirror_image() {
        let ptm = PolynomialTextureMap;
        let below = Vec3::new(0.36, -0.48, -0.8);
        let horizon = Vec3::new(0.6, -0.8, 0.0);
        assert!(close(&ptm.values(below), &ptm.values(horizon)));
        let mirror = ptm.values(Vec3::new(0.36, -0.48, 0.8));
        assert!(!close(&ptm.values(below), &mirror));
        // Continuous across the horizon.
        let just_below = Vec3::new(0.6, -0.8, -1e-9).normalized().unwrap();
        let just_above = Vec3::new(0.6, -0.8, 1e-9).normalized().unwrap();
        for (a, b) in ptm.values(just_below).iter().zip(ptm.values(just_above)) {
            assert!((a - b).abs() < 1e-12);
        }
        let far = ptm.values(Vec3::new(0.0, 0.0, -1.0));
        assert!(close(&far, &[0.5, 0.5, 0.0, 0.0, 0.0, 1.0]));
    }

    #[test]
    fn the_closed_form_penalty_equals_the_numerical_one() {
        let ptm = PolynomialTextureMap;
        let exact = ptm.penalty();
        let numeric = crate::basis::roughness_penalty(&ptm, 8192);
        for (i, (a, b)) in exact.iter().zip(&numeric).enumerate() {
            assert!((a - b).abs() < 5e-3, "P[{}, {}] = {b} vs {a}", i / K, i % K);
        }
    }

    #[test]
    fn a_weight_table_of_256_reproduces_it() {
        use crate::basis::table::{WeightTable, TABLE_TOLERANCE};
        // Measured: 256 cells, relative RMS 3.9e-4; the largest error sits at the far
        // pole, where the horizon continuation turns with the azimuth.
        let (table, accuracy) = WeightTable::for_basis(&PolynomialTextureMap);
        assert!(table.resolution <= 256, "{accuracy:?}");
        assert!(accuracy.relative_rms <= TABLE_TOLERANCE);
    }

    #[test]
    fn only_six_and_no_parameters() {
        assert!(FAMILY
            .build(
                9,
                &BuildContext {
                    directions: &[],
                    samples: None,
                    options: &Default::default(),
                },
            )
            .is_err());
        assert!(BasisSpec::new("ptm", serde_json::json!({"k": 6}))
            .build()
            .is_err());
        assert_eq!(BasisSpec::named("ptm:6").unwrap().build().unwrap().len(), 6);
    }
}
