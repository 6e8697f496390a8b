//! A basis seen through a fixed linear map: `K′` functions `b′_j = Σ_i P_ji b_i` of an
//! inner basis of `K` functions.
//!
//! This is what principal components across pixels make of any basis (the compressed
//! file of the `compress` module): the coefficient vectors of a capture's pixels crowd into
//! a few directions of `ℝᴷ`, and a pixel stored as its `K′` coordinates `c′` along them
//! relights as `b(L)·(Qᵀ c′) = (P b(L))·c′` with `P` the map from inner weights to
//! the `K′` weights. A directional frame therefore costs `K′` multiply-adds per pixel
//! with the weights projected once per frame, and every back end (CPU, wgpu, browser)
//! sees one more basis, evaluated like any other.
//!
//! Stored: the inner basis' spec and `P` (`K′ × K`, row-major). The family offers no
//! sizes: nothing fits one directly; compression makes it.

use super::{Basis, BasisSpec, BuildContext, Domain, Family, PlanarGrid, MAX_PROJECTED_INNER};
use crate::sphere::Vec3;
use crate::{Error, Result};

pub(super) struct ProjectedFamily;

pub(super) static FAMILY: ProjectedFamily = ProjectedFamily;

impl Family for ProjectedFamily {
    fn name(&self) -> &'static str {
        "projected"
    }

    fn summary(&self) -> &'static str {
        "a fixed linear map of another basis (what principal components across pixels make)"
    }

    fn sizes(&self, _max: usize) -> Vec<usize> {
        Vec::new()
    }

    fn build(&self, _k: usize, _: &BuildContext) -> Result<Box<dyn Basis>> {
        Err(Error::invalid(
            "a projected basis is made by compressing fitted maps (`relit convert`), not fitted",
        ))
    }

    fn rebuild(
        &self,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Box<dyn Basis>> {
        let bad = |why: &str| Error::parse(format!("a `projected` basis {why}"));
        if let Some(key) = params
            .keys()
            .find(|k| !["basis", "matrix"].contains(&k.as_str()))
        {
            return Err(bad(&format!(
                "has only `basis` and `matrix`, found `{key}`"
            )));
        }
        let inner: BasisSpec = params
            .get("basis")
            .cloned()
            .ok_or_else(|| bad("needs `basis`"))
            .and_then(|v| {
                serde_json::from_value(v).map_err(|e| bad(&format!("has a bad `basis`: {e}")))
            })?;
        if inner.family == "projected" {
            return Err(bad("cannot project another projected basis"));
        }
        let inner = inner.build()?;
        let matrix = super::pca::stored_table(params, "matrix", "projected")?;
        Ok(Box::new(Projected::new(inner, matrix)?))
    }
}

/// `K′` combinations of an inner basis' functions.
#[derive(Debug)]
pub struct Projected {
    inner: Box<dyn Basis>,
    /// `K′ × K`, row-major: row `j` gives `b′_j`.
    matrix: Vec<f64>,
}

impl Projected {
    /// `b′_j = Σ_i matrix[j·K + i] b_i` for the `K` functions of `inner`.
    pub fn new(inner: Box<dyn Basis>, matrix: Vec<f64>) -> Result<Self> {
        let k = inner.len();
        if k == 0 || k > MAX_PROJECTED_INNER || matrix.is_empty() || !matrix.len().is_multiple_of(k)
        {
            return Err(Error::parse(format!(
                "a projected basis needs K′ × {k} matrix values (K ≤ {MAX_PROJECTED_INNER}), got {}",
                matrix.len()
            )));
        }
        if matrix.len() / k > k {
            return Err(Error::parse(format!(
                "a projected basis has at most as many functions as its inner basis ({k})"
            )));
        }
        if matrix.iter().any(|v| !v.is_finite()) {
            return Err(Error::parse("a projected basis' matrix must be finite"));
        }
        Ok(Projected { inner, matrix })
    }

    /// The inner basis.
    pub fn inner(&self) -> &dyn Basis {
        self.inner.as_ref()
    }

    /// The `K′ × K` map (row-major).
    pub fn matrix(&self) -> &[f64] {
        &self.matrix
    }

    /// `out[j] = Σ_i P_ji w[i]`: inner weights to this basis' weights.
    fn project(&self, w: &[f64], out: &mut [f64]) {
        let k = self.inner.len();
        for (o, row) in out.iter_mut().zip(self.matrix.chunks_exact(k)) {
            *o = row.iter().zip(w).map(|(a, b)| a * b).sum();
        }
    }
}

impl Basis for Projected {
    fn spec(&self) -> BasisSpec {
        BasisSpec::new(
            "projected",
            serde_json::json!({ "basis": self.inner.spec(), "matrix": self.matrix }),
        )
    }

    fn family(&self) -> &'static str {
        "projected"
    }

    fn len(&self) -> usize {
        self.matrix.len() / self.inner.len()
    }

    fn name(&self) -> String {
        format!("{}→{}", self.inner.name(), self.len())
    }

    fn domain(&self) -> Domain {
        self.inner.domain()
    }

    fn eval(&self, dir: Vec3, out: &mut [f64]) {
        let mut w = [0.0; MAX_PROJECTED_INNER];
        let k = self.inner.len();
        self.inner.eval(dir, &mut w[..k]);
        self.project(&w[..k], &mut out[..self.len()]);
    }

    /// `P R Pᵀ` for the inner penalty `R`: the same roughness, measured on the
    /// combinations.
    fn penalty(&self) -> Vec<f64> {
        let (k, kp) = (self.inner.len(), self.len());
        let r = self.inner.penalty();
        let mut pr = vec![0.0; kp * k];
        for j in 0..kp {
            for i in 0..k {
                pr[j * k + i] = (0..k).map(|m| self.matrix[j * k + m] * r[m * k + i]).sum();
            }
        }
        let mut out = vec![0.0; kp * kp];
        for a in 0..kp {
            for b in 0..kp {
                out[a * kp + b] = (0..k).map(|i| pr[a * k + i] * self.matrix[b * k + i]).sum();
            }
        }
        out
    }

    /// The inner grid's nodes mapped: a projected bilinear basis is still bilinear.
    fn planar_grid(&self) -> Option<PlanarGrid> {
        let inner = self.inner.planar_grid()?;
        let (k, kp) = (self.inner.len(), self.len());
        let mut nodes = vec![0.0; inner.nodes.len() / k * kp];
        for (w, o) in inner.nodes.chunks_exact(k).zip(nodes.chunks_exact_mut(kp)) {
            self.project(w, o);
        }
        Some(PlanarGrid { nodes, ..inner })
    }

    fn label(&self, i: usize) -> String {
        format!("pc{i}")
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisChoice;

    fn projected_sh() -> Projected {
        let inner = BasisChoice::parse("sh:9")
            .unwrap()
            .build(&[], None)
            .unwrap();
        // Two combinations: the constant, and l1 y plus half of l2.
        let mut m = vec![0.0; 2 * 9];
        m[0] = 1.0;
        m[9 + 1] = 1.0;
        m[9 + 4] = 0.5;
        Projected::new(inner, m).unwrap()
    }

    #[test]
    fn weights_are_the_inner_weights_mapped() {
        let p = projected_sh();
        assert_eq!(p.len(), 2);
        let d = Vec3::new(0.36, -0.48, 0.8);
        let w = p.inner().values(d);
        let got = p.values(d);
        assert_eq!(got[0], w[0]);
        assert!((got[1] - (w[1] + 0.5 * w[4])).abs() < 1e-15);
    }

    #[test]
    fn round_trips_through_its_spec_and_refuses_bad_ones() {
        let p = projected_sh();
        let json = serde_json::to_string(&p.spec()).unwrap();
        let spec: BasisSpec = serde_json::from_str(&json).unwrap();
        let again = spec.build().unwrap();
        assert_eq!(again.len(), 2);
        let d = Vec3::new(0.0, 0.6, 0.8);
        assert_eq!(again.values(d), p.values(d));
        for bad in [
            r#"{"type":"projected","basis":{"type":"sh","bands":3},"matrix":[1,2]}"#,
            r#"{"type":"projected","basis":{"type":"sh","bands":3}}"#,
            r#"{"type":"projected","matrix":[1]}"#,
            r#"{"type":"projected","basis":{"type":"sh","bands":3},"matrix":[1,0,0,0,0,0,0,0,0],"x":1}"#,
        ] {
            let spec: BasisSpec = serde_json::from_str(bad).unwrap();
            assert!(spec.build().is_err(), "{bad}");
        }
    }

    #[test]
    fn the_penalty_is_the_inner_penalty_mapped() {
        let p = projected_sh();
        let inner = p.inner().penalty();
        let got = p.penalty();
        // Row 0 is the constant: no roughness. Row 1: R11 + 0.25 R44 (SH is diagonal).
        assert!(got[0].abs() < 1e-12);
        assert!((got[3] - (inner[9 + 1] + 0.25 * inner[4 * 9 + 4])).abs() < 1e-9);
    }

    #[test]
    fn it_is_not_offered_to_fits() {
        assert!(FAMILY.sizes(64).is_empty());
        assert!(BasisChoice::parse("projected:4").is_err());
    }
}
