//! Spherical bases: how a pixel's apparent BRDF is expressed as a few coefficients.
//!
//! Everything downstream (fitting, files, relighting) works through the [`Basis`] trait
//! and never assumes a particular basis. [`BasisSpec`] is the serialisable name of a
//! basis and the one factory that builds it; adding a basis is one new file plus one
//! variant there.

mod rotation;
mod sh;

pub use rotation::{
    check_rotation, compose, mat3_apply, rotation_about_axis, rotation_from_yaw_pitch_roll,
    transpose, Mat3, ShRotation, MAT3_IDENTITY,
};
pub use sh::{sh_index, SphericalHarmonics, MAX_BANDS};

use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// A set of `len()` real functions on the sphere of light directions.
pub trait Basis: Send + Sync + std::fmt::Debug {
    /// The serialisable description that rebuilds this basis.
    fn spec(&self) -> BasisSpec;

    /// The number of coefficients `k`.
    fn len(&self) -> usize;

    /// Whether the basis has no functions (never true for a built basis).
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Evaluate every basis function at the unit light vector `dir` into `out[..len()]`.
    fn eval(&self, dir: Vec3, out: &mut [f64]);

    /// The diagonal of the smoothness penalty the fit regularises with, one entry per
    /// coefficient, scaled so that `Σ_i p_i c_i²` is the mean over the sphere of the
    /// squared magnitude being penalised. Entries may be zero for functions that must
    /// not be shrunk (a constant term).
    fn penalty(&self) -> Vec<f64>;

    /// A short human label for coefficient `i` (e.g. `l2m-1`).
    fn label(&self, i: usize) -> String;

    /// Evaluate at `dir`, allocating.
    fn values(&self, dir: Vec3) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        self.eval(dir, &mut out);
        out
    }
}

/// The serialisable identity of a basis, stored in every relightable file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum BasisSpec {
    /// Real spherical harmonics of `bands` bands (`bands²` coefficients, 1 ≤ bands ≤ 8).
    Sh { bands: usize },
}

impl Default for BasisSpec {
    fn default() -> Self {
        BasisSpec::Sh { bands: 5 }
    }
}

impl BasisSpec {
    /// Build the basis, checking its parameters.
    pub fn build(&self) -> Result<Box<dyn Basis>> {
        match *self {
            BasisSpec::Sh { bands } => Ok(Box::new(SphericalHarmonics::new(bands)?)),
        }
    }

    /// The number of coefficients, without building.
    pub fn len(&self) -> usize {
        match *self {
            BasisSpec::Sh { bands } => bands * bands,
        }
    }

    /// Whether the spec describes no functions.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// A compact name such as `sh5`.
    pub fn short_name(&self) -> String {
        match *self {
            BasisSpec::Sh { bands } => format!("sh{bands}"),
        }
    }

    /// Parse the compact name (`sh5`, `sh:5`).
    pub fn parse_short(s: &str) -> Result<Self> {
        let s = s.trim().to_ascii_lowercase();
        if let Some(rest) = s.strip_prefix("sh") {
            let bands: usize = rest.trim_start_matches(':').parse().map_err(|_| {
                Error::parse(format!("bad basis `{s}`: expected e.g. `sh5` (5 bands)"))
            })?;
            let spec = BasisSpec::Sh { bands };
            spec.build()?;
            return Ok(spec);
        }
        Err(Error::parse(format!(
            "unknown basis `{s}` (known: sh1..sh8)"
        )))
    }
}
