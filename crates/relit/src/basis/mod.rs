//! Bases: how a pixel's apparent BRDF is expressed as a few coefficients.
//!
//! A [`Basis`] is `k` real functions `b_i` on the sphere of light directions. A pixel's
//! response to a unit directional light toward `L` is `Σ_i c_i b_i(L)`: relighting is a
//! dot product of the pixel's coefficients with the weight vector `b(L)`, which is all
//! that anything after the fit asks of a basis. Files, the CPU and GPU engines, the
//! browser viewer, environment lights and the studio never name a particular basis: a
//! directional or environment light is one weight vector per frame (for an environment,
//! from the basis' own [`Basis::environment`] where it has one, else from a quadrature
//! of the map), a light with a position evaluates [`Basis::eval`] per pixel (or samples
//! a [`WeightTable`] of it, which is how back ends that cannot run Rust get any basis).
//!
//! The bases live one per module, each registered once in [`FAMILIES`]; a basis with
//! maths of its own beyond evaluation keeps it in its module (SH's rotation and exact
//! environment projection live in [`sh`]):
//!
//! | name | functions |
//! |---|---|
//! | `sh:K` | real spherical harmonics, K = 1, 4, 9, …, 64 ([`sh`]) |
//! | `hsh:K` | hemispherical harmonics, orthonormal over `z ≥ 0`, K = 4, 9, 16, 25 ([`hsh`]) |
//! | `ptm:6` | polynomial texture map, biquadratic in the light's `(x, y)` ([`ptm`]) |
//! | `sg:K` | spherical Gaussian lobes of one sharpness plus a constant, K = 4, 9, …, 64 ([`sg`]) |
//! | `rbf:K` | Gaussian RBF interpolation over the captured lights, PCA to K ([`rbf`]) |
//! | `bilinear:K` | samples on a grid over the hemisphere, bilinear, PCA to K ([`bilinear`]) |
//! | `projected` | K′ fixed combinations of another basis, made by compression ([`Projected`]) |
//!
//! A basis is named `family:K` (K coefficients per colour channel), optionally with
//! family options: `sg:25:centres=hemisphere,sharpness=8`. [`BasisSpec`] is what a file
//! stores: the family and every parameter needed to rebuild the basis, data-dependent
//! tables included.

mod bilinear;
mod hsh;
mod pca;
mod projected;
mod ptm;
mod rbf;
mod rotation;
mod sg;
pub(crate) mod sh;
pub(crate) mod table;
mod window;

pub use bilinear::{grid_basis, GridMap};
pub use hsh::HemisphericalHarmonics;
pub use projected::Projected;
pub use ptm::PolynomialTextureMap;
pub use rbf::{relight_kernels, relight_rbf};
pub use rotation::{
    check_rotation, compose, mat3_apply, rotation_about_axis, rotation_from_yaw_pitch_roll,
    transpose, Mat3, MAT3_IDENTITY,
};
pub use sg::{mean_nearest_angle, sharpness_for_width, SphericalGaussians};
pub use sh::{sh_index, ShEnvironment, ShRotation, SphericalHarmonics, MAX_BANDS};
pub use table::{octahedral_direction, octahedral_uv, TableAccuracy, WeightTable};
pub use window::Window;

/// Forget what building bases remembers to build the next ones faster (the RBF
/// kernels' gradient Gram matrices, the samples' principal directions): a fit's basis
/// choice, which builds every size of every family on each fold, calls it when done,
/// so that what it remembered does not stay in the fit's memory.
pub(crate) fn forget_remembered() {
    pca::forget();
    rbf::forget();
}

use crate::image::ImageRgb;
use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Where a basis is meant to represent functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Domain {
    /// Every direction.
    Sphere,
    /// Directions with `z ≥ 0` (toward the camera: an RTI dome's lights). Below the
    /// horizon the basis has its own continuation; fits regularise on the hemisphere.
    UpperHemisphere,
}

/// `k` real functions on the sphere of light directions.
pub trait Basis: Send + Sync + std::fmt::Debug {
    /// The serialisable description that rebuilds this basis.
    fn spec(&self) -> BasisSpec;

    /// The family's name (`sh`, `rbf`, …).
    fn family(&self) -> &'static str;

    /// The number of coefficients `k`.
    fn len(&self) -> usize;

    /// Whether the basis has no functions (never true for a built basis).
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// `family:K`, the name users type.
    fn name(&self) -> String {
        format!("{}:{}", self.family(), self.len())
    }

    /// Where the basis is meant to represent functions.
    fn domain(&self) -> Domain {
        Domain::Sphere
    }

    /// Evaluate every basis function at the unit light vector `dir` into `out[..len()]`:
    /// the weights that relight a pixel lit from `dir` by a dot product.
    fn eval(&self, dir: Vec3, out: &mut [f64]);

    /// The smoothness penalty the fit regularises with: a symmetric `k×k` matrix
    /// (row-major) with `cᵀ P c` the mean over the basis' domain of the squared gradient
    /// of `Σ c_i b_i` (a constant function costs nothing). The default measures it
    /// numerically ([`roughness_penalty`]); bases with a closed form override it.
    fn penalty(&self) -> Vec<f64> {
        roughness_penalty(self, PENALTY_POINTS)
    }

    /// The basis' own way of lighting its maps by the lat-long environment `map` (linear
    /// RGB, laid out as [`crate::sphere::latlong_direction`] says), made once per map,
    /// where it has one finer than sampling the map as directional lights; `None` (the
    /// default): environment lights take the generic quadrature of the map.
    fn environment(&self, map: &ImageRgb) -> Option<Result<Box<dyn PreparedEnvironment>>> {
        let _ = map;
        None
    }

    /// Per coefficient, its band `l` when the basis is orthonormal over the sphere and
    /// its coefficients come in bands that the spherical Laplacian scales by `l(l+1)`,
    /// so that band windows ([`Window`]) apply and `Σ_i e_i b_i` is the environment
    /// its weights `e` light with; `None` otherwise (windows are refused).
    fn coefficient_bands(&self) -> Option<Vec<usize>> {
        None
    }

    /// The grid, when the basis is exactly the bilinear blend of weights at the nodes of
    /// a `G × G` grid over a square that a light vector lands on by a [`GridMap`]. The
    /// CPU engine then reads that grid (exact and small) instead of an octahedral weight
    /// table.
    fn planar_grid(&self) -> Option<PlanarGrid> {
        None
    }

    /// A short human label for coefficient `i` (e.g. `l2m-1`).
    fn label(&self, i: usize) -> String {
        format!("c{i}")
    }

    /// Evaluate at `dir`, allocating.
    fn values(&self, dir: Vec3) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        self.eval(dir, &mut out);
        out
    }

    /// This basis as `Any`, for back ends with a fast path of their own for one family
    /// (the SH kernel of the CPU engine); nothing else may downcast.
    fn as_any(&self) -> &dyn std::any::Any;
}

/// An environment map made ready by a basis for its own lighting
/// ([`Basis::environment`]): what does not change when the environment turns.
pub trait PreparedEnvironment: Send + Sync + std::fmt::Debug {
    /// The weights per colour channel that relight the basis' maps by one dot product
    /// per pixel, the environment turned by `rotation` (`E'(ω) = E(Rᵀ ω)`) and windowed.
    fn weights(&self, rotation: &Mat3, window: Window) -> Result<[Vec<f64>; 3]>;
}

/// Points a measured roughness penalty averages over.
pub const PENALTY_POINTS: usize = 2048;

/// `points` Fibonacci points spread over `domain`: where a roughness penalty is measured.
pub fn penalty_points(domain: Domain, points: usize) -> Vec<Vec3> {
    match domain {
        Domain::Sphere => crate::sphere::fibonacci(points),
        Domain::UpperHemisphere => crate::sphere::hemisphere_fibonacci(points),
    }
}

/// The mean over `basis`' domain of `∇b_i · ∇b_j`, by central differences along two
/// tangent directions at `points` Fibonacci points (step 1e-4 rad: far below any
/// basis' detail, far above rounding).
pub fn roughness_penalty<B: Basis + ?Sized>(basis: &B, points: usize) -> Vec<f64> {
    let k = basis.len();
    let dirs = penalty_points(basis.domain(), points);
    const H: f64 = 1e-4;
    // One row of gradients per point and tangent, then their Gram matrix in one
    // matrix product (the sum of outer products, loop by loop, had been most of it).
    let mut gradients = vec![0.0; 2 * dirs.len() * k];
    let (mut plus, mut minus) = (vec![0.0; k], vec![0.0; k]);
    for (d, rows) in dirs.iter().zip(gradients.chunks_exact_mut(2 * k)) {
        let helper = if d.x.abs() < 0.9 {
            Vec3::new(1.0, 0.0, 0.0)
        } else {
            Vec3::new(0.0, 1.0, 0.0)
        };
        let t1 = d.cross(helper).normalized().expect("a tangent");
        let t2 = d.cross(t1);
        for (t, grad) in [t1, t2].into_iter().zip(rows.chunks_exact_mut(k)) {
            basis.eval((*d + t * H).normalized().expect("unit"), &mut plus);
            basis.eval((*d - t * H).normalized().expect("unit"), &mut minus);
            for i in 0..k {
                grad[i] = (plus[i] - minus[i]) / (2.0 * H);
            }
        }
    }
    gram_mean(&gradients, k, dirs.len())
}

/// `GᵀG / points` for the gradient rows `g` (any number of rows of `k`), made exactly
/// symmetric: the roughness penalty from sampled gradients.
fn gram_mean(g: &[f64], k: usize, points: usize) -> Vec<f64> {
    let rows = g.len() / k.max(1);
    let mut p = vec![0.0; k * k];
    crate::linalg::matmul_at(k, rows, k, g, g, &mut p);
    let count = points as f64;
    for a in 0..k {
        for b in a..k {
            let v = p[a * k + b] / count;
            p[a * k + b] = v;
            p[b * k + a] = v;
        }
    }
    p
}

/// The pixel samples a data-driven family builds its functions from: `series` series
/// (a pixel's channel) of `n` values, one per captured light, series-major.
#[derive(Clone, Copy, Debug)]
pub struct Samples<'a> {
    pub values: &'a [f32],
    pub n: usize,
}

impl Samples<'_> {
    pub fn series(&self) -> usize {
        self.values.len() / self.n.max(1)
    }
    pub fn row(&self, s: usize) -> &[f32] {
        &self.values[s * self.n..(s + 1) * self.n]
    }
}

/// How far below the horizon a light of a dome may sit: light directions calibrated from
/// highlights put a dome's lowest ring a little below it (RealRTI item7: −0.07°), and a
/// capture of the whole sphere has lights far lower.
pub const DOME_SLACK_DEG: f64 = 5.0;

/// What a family builds a basis from.
#[derive(Clone, Copy, Debug)]
pub struct BuildContext<'a> {
    /// The captured light directions (unit vectors), in the order of the samples.
    pub directions: &'a [Vec3],
    /// Samples of the capture (a pixel subsample), for families whose functions depend
    /// on the data; analytic families ignore them.
    pub samples: Option<Samples<'a>>,
    /// Family options from the name (`key=value`).
    pub options: &'a BTreeMap<String, String>,
}

impl BuildContext<'_> {
    /// Whether every captured light lies in the upper hemisphere (an RTI dome), up to
    /// [`DOME_SLACK_DEG`] below the horizon.
    pub fn hemisphere_only(&self) -> bool {
        let lowest = -DOME_SLACK_DEG.to_radians().sin();
        !self.directions.is_empty() && self.directions.iter().all(|d| d.z > lowest)
    }

    /// A family option parsed as `T`, or `default`.
    pub fn option<T: std::str::FromStr>(&self, key: &str, default: T) -> Result<T> {
        match self.options.get(key) {
            None => Ok(default),
            Some(v) => v
                .parse()
                .map_err(|_| Error::parse(format!("bad basis option `{key}={v}`"))),
        }
    }
}

/// A basis that is a bilinear grid over the light vector's square ([`Basis::planar_grid`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PlanarGrid {
    /// `G`, the nodes a side.
    pub grid: usize,
    /// `len()` weights per node, node `(i, j)` at `(j·G + i)·len()`.
    pub nodes: Vec<f64>,
    /// How a light vector lands on the square `[−1, 1]²`.
    pub map: GridMap,
}

/// A kind of basis: how to build one of a given size and how to rebuild a stored one.
pub trait Family: Sync {
    /// The name before the colon (`sh`).
    fn name(&self) -> &'static str;

    /// One line for help texts.
    fn summary(&self) -> &'static str;

    /// The sizes (coefficients per channel) this family offers, up to `max`, ascending.
    fn sizes(&self, max: usize) -> Vec<usize>;

    /// Whether [`Family::build`] needs [`BuildContext::samples`].
    fn needs_samples(&self) -> bool {
        false
    }

    /// The option keys the family understands.
    fn option_keys(&self) -> &'static [&'static str] {
        &[]
    }

    /// Whether, built from the same `lights` directions (and samples and options), a
    /// basis of this family is the first functions of every larger one, and its
    /// roughness penalty the larger penalty's leading block: then a validation judges
    /// every size from the largest one's systems (`fit::select::validate`). Checked for
    /// every family that says so by `basis::tests::nested_families_are_nested`.
    fn nested(&self, lights: usize) -> bool {
        let _ = lights;
        false
    }

    /// A basis of `k` functions for a capture.
    fn build(&self, k: usize, context: &BuildContext) -> Result<Box<dyn Basis>>;

    /// Rebuild a basis from the parameters its [`Basis::spec`] stored.
    fn rebuild(
        &self,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Box<dyn Basis>>;
}

/// Every family relit knows: adding a basis is one file and one line here.
pub static FAMILIES: &[&dyn Family] = &[
    &sh::FAMILY,
    &hsh::FAMILY,
    &ptm::FAMILY,
    &sg::FAMILY,
    &rbf::FAMILY,
    &bilinear::FAMILY,
    &projected::FAMILY,
];

/// The most functions of a basis that a [`Projected`] basis combines (every family
/// offers at most 64).
pub const MAX_PROJECTED_INNER: usize = 64;

/// The family called `name`.
pub fn family(name: &str) -> Result<&'static dyn Family> {
    FAMILIES
        .iter()
        .copied()
        .find(|f| f.name() == name)
        .ok_or_else(|| {
            Error::parse(format!(
                "unknown basis `{name}` (known: {})",
                FAMILIES
                    .iter()
                    .map(|f| f.name())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })
}

/// The serialisable identity of a built basis, stored in every relightable file: its
/// family (`"type"`) and the family's parameters beside it, e.g.
/// `{"type": "sh", "bands": 5}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BasisSpec {
    #[serde(rename = "type")]
    pub family: String,
    #[serde(flatten)]
    pub params: serde_json::Map<String, serde_json::Value>,
}

impl BasisSpec {
    /// A spec of `family` with `params` (a JSON object's fields).
    pub fn new(family: &str, params: serde_json::Value) -> BasisSpec {
        let params = match params {
            serde_json::Value::Object(map) => map,
            _ => serde_json::Map::new(),
        };
        BasisSpec {
            family: family.to_string(),
            params,
        }
    }

    /// The spec of an analytic basis by name (`sh:25`): one that needs no capture.
    pub fn named(name: &str) -> Result<BasisSpec> {
        Ok(BasisChoice::parse(name)?.build(&[], None)?.spec())
    }

    /// Rebuild the basis, checking its parameters.
    pub fn build(&self) -> Result<Box<dyn Basis>> {
        family(&self.family)?.rebuild(&self.params)
    }
}

impl Default for BasisSpec {
    /// `sh:25`.
    fn default() -> Self {
        sh::SphericalHarmonics::new(5).expect("five bands").spec()
    }
}

/// A basis a user names before any data is seen: `family:K[:key=value,…]`.
#[derive(Clone, Debug, PartialEq)]
pub struct BasisChoice {
    pub family: &'static str,
    pub k: usize,
    pub options: BTreeMap<String, String>,
}

impl BasisChoice {
    /// Parse `sh:25`, `sg:25:centres=hemisphere,sharpness=8`.
    pub fn parse(s: &str) -> Result<BasisChoice> {
        let s = s.trim().to_ascii_lowercase();
        let mut parts = s.splitn(3, ':');
        let name = parts.next().unwrap_or_default();
        let fam = family(name)?;
        let k: usize = parts
            .next()
            .ok_or_else(|| {
                Error::parse(format!(
                    "basis `{s}` needs a size: `{name}:K` with K one of {:?}",
                    fam.sizes(64)
                ))
            })?
            .parse()
            .map_err(|_| Error::parse(format!("bad basis size in `{s}`")))?;
        if !fam.sizes(usize::MAX >> 1).contains(&k) {
            return Err(Error::invalid(format!(
                "basis `{name}` has no size {k}: it offers {:?} (up to 64)",
                fam.sizes(64)
            )));
        }
        let mut options = BTreeMap::new();
        if let Some(rest) = parts.next() {
            for kv in rest.split(',').filter(|p| !p.is_empty()) {
                let (key, value) = kv.split_once('=').ok_or_else(|| {
                    Error::parse(format!("bad basis option `{kv}`: expected key=value"))
                })?;
                if !fam.option_keys().contains(&key) {
                    return Err(Error::parse(format!(
                        "basis `{name}` has no option `{key}` (options: {:?})",
                        fam.option_keys()
                    )));
                }
                options.insert(key.to_string(), value.to_string());
            }
        }
        Ok(BasisChoice {
            family: fam.name(),
            k,
            options,
        })
    }

    /// `family:K` (options left out).
    pub fn name(&self) -> String {
        format!("{}:{}", self.family, self.k)
    }

    /// Whether this is the first functions of `larger` when both are built from the same
    /// `lights` directions and samples ([`Family::nested`]): the same family and
    /// options, no more functions.
    pub fn nests_in(&self, larger: &BasisChoice, lights: usize) -> bool {
        self.family == larger.family
            && self.options == larger.options
            && self.k <= larger.k
            && family(self.family).is_ok_and(|f| f.nested(lights))
    }

    /// Whether building needs pixel samples.
    pub fn needs_samples(&self) -> bool {
        family(self.family).is_ok_and(|f| f.needs_samples())
    }

    /// Build for a capture lit from `directions`, with `samples` for data-driven families.
    pub fn build(&self, directions: &[Vec3], samples: Option<Samples>) -> Result<Box<dyn Basis>> {
        let fam = family(self.family)?;
        if fam.needs_samples() && samples.is_none() {
            return Err(Error::invalid(format!(
                "basis `{}` is built from the capture's samples",
                self.name()
            )));
        }
        fam.build(
            self.k,
            &BuildContext {
                directions,
                samples,
                options: &self.options,
            },
        )
    }
}

impl Default for BasisChoice {
    fn default() -> Self {
        BasisChoice::parse("sh:25").expect("a valid basis")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_and_refuse_what_is_not_there() {
        let c = BasisChoice::parse("sh:25").unwrap();
        assert_eq!((c.family, c.k), ("sh", 25));
        assert_eq!(c.name(), "sh:25");
        assert!(BasisChoice::parse("sh:24").is_err());
        assert!(BasisChoice::parse("sh").is_err());
        assert!(BasisChoice::parse("nope:4").is_err());
        assert!(BasisChoice::parse("sh:9:bogus=1").is_err());
        for fam in FAMILIES {
            for k in fam.sizes(64) {
                let name = format!("{}:{k}", fam.name());
                assert_eq!(BasisChoice::parse(&name).unwrap().k, k, "{name}");
            }
        }
    }

    /// What `Family::nested` promises, for every family that makes the promise: built
    /// from the same lights and samples, each size's functions are the largest size's
    /// first ones and its penalty that penalty's leading block.
    #[test]
    fn nested_families_are_nested() {
        let dirs = crate::sphere::hemisphere_fibonacci(60);
        let lobes = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.7, 0.1, 0.7),
            Vec3::new(-0.3, 0.8, 0.5),
        ];
        // Pixels that mix a diffuse term and two glossy lobes, differently each.
        let values: Vec<f32> = (0..96)
            .flat_map(|s| {
                let (a, b) = ((s % 7) as f64 / 7.0, (s % 5) as f64 / 5.0);
                dirs.iter().map(move |d| {
                    let lobe = |l: Vec3, p: i32| d.dot(l.normalized().unwrap()).max(0.0).powi(p);
                    (0.1 + 0.4 * a * d.z.max(0.0)
                        + b * lobe(lobes[1], 20)
                        + 0.3 * lobe(lobes[2], 8)) as f32
                })
            })
            .collect();
        let samples = || Samples {
            values: &values,
            n: dirs.len(),
        };
        let probes = crate::sphere::fibonacci(200);
        let mut checked = Vec::new();
        for fam in FAMILIES.iter().filter(|f| f.nested(dirs.len())) {
            let sizes: Vec<usize> = fam
                .sizes(64)
                .into_iter()
                .filter(|&k| k < dirs.len())
                .collect();
            let build = |k: usize| {
                BasisChoice::parse(&format!("{}:{k}", fam.name()))
                    .unwrap()
                    .build(&dirs, fam.needs_samples().then(samples))
                    .unwrap()
            };
            let largest = build(*sizes.last().unwrap());
            let big_k = largest.len();
            let big_penalty = largest.penalty();
            let scale = big_penalty.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for &k in &sizes {
                let basis = build(k);
                for &d in &probes {
                    let (small, big) = (basis.values(d), largest.values(d));
                    for i in 0..k {
                        assert!(
                            (small[i] - big[i]).abs() <= 1e-9 * (1.0 + big[i].abs()),
                            "{}:{k} function {i} at {d:?}: {} against {}",
                            fam.name(),
                            small[i],
                            big[i]
                        );
                    }
                }
                let penalty = basis.penalty();
                for r in 0..k {
                    for c in 0..k {
                        let (a, b) = (penalty[r * k + c], big_penalty[r * big_k + c]);
                        assert!(
                            (a - b).abs() <= 1e-9 * scale,
                            "{}:{k} penalty ({r}, {c}): {a} against {b}",
                            fam.name()
                        );
                    }
                }
            }
            checked.push(fam.name());
        }
        assert_eq!(checked, ["sh", "hsh", "rbf", "bilinear"]);
        // Beyond one eigendecomposition the data-driven families promise nothing.
        let (rbf_small, rbf_big) = (
            BasisChoice::parse("rbf:9").unwrap(),
            BasisChoice::parse("rbf:16").unwrap(),
        );
        assert!(rbf_small.nests_in(&rbf_big, 60));
        assert!(!rbf_small.nests_in(&rbf_big, crate::linalg::EXACT_PCA_LIGHTS + 1));
        assert!(!rbf_big.nests_in(&rbf_small, 60));
        assert!(!BasisChoice::parse("sg:9")
            .unwrap()
            .nests_in(&BasisChoice::parse("sg:16").unwrap(), 60));
        let wide = BasisChoice::parse("rbf:16:width=3").unwrap();
        assert!(!rbf_small.nests_in(&wide, 60));
    }

    #[test]
    fn every_analytic_family_round_trips_through_its_spec() {
        let dirs = crate::sphere::fibonacci(64);
        for fam in FAMILIES.iter().filter(|f| !f.needs_samples()) {
            for k in fam.sizes(64) {
                let options = BTreeMap::new();
                let context = BuildContext {
                    directions: &dirs,
                    samples: None,
                    options: &options,
                };
                let basis = fam.build(k, &context).unwrap();
                assert_eq!(basis.len(), k);
                let json = serde_json::to_string(&basis.spec()).unwrap();
                let spec: BasisSpec = serde_json::from_str(&json).unwrap();
                let again = spec.build().unwrap();
                assert_eq!(again.name(), basis.name());
                for d in crate::sphere::fibonacci(7) {
                    assert_eq!(again.values(d), basis.values(d), "{}", basis.name());
                }
            }
        }
    }

    #[test]
    fn the_numerical_penalty_equals_the_closed_form_of_sh() {
        let sh = SphericalHarmonics::new(4).unwrap();
        let exact = sh.penalty();
        let numeric = roughness_penalty(&sh, 4096);
        let k = sh.len();
        for i in 0..k {
            for j in 0..k {
                let scale = exact[i * k + i].max(exact[j * k + j]).max(0.05);
                assert!(
                    (numeric[i * k + j] - exact[i * k + j]).abs() < 0.02 * scale,
                    "P[{i},{j}] = {} vs {}",
                    numeric[i * k + j],
                    exact[i * k + j]
                );
            }
        }
    }
}
