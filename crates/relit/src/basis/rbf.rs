//! `rbf:K` — Gaussian radial basis functions centred on the captured light directions,
//! interpolating each pixel's samples, compressed across pixels to `K` functions by
//! principal components ([`super::pca`]), as the RTI tool relight does.
//!
//! Kernel: `φ(ω, μ) = exp(−(1 − ω·μ) / σ²)`, a Gaussian of the chord distance
//! (`|ω − μ|² = 2(1 − ω·μ)`) of width `σ` radians. The default `σ` is the mean angular
//! distance from a captured light to its nearest neighbour times `width` (option,
//! default 2): a kernel keeps `e^{−1/8}` of its peak at its neighbour, smooth enough to
//! interpolate without flattening a shadow edge across several lights. Captures with
//! more than [`MAX_CENTRES`] lights (option `centres`) use that many centres spread over
//! them (farthest-point order), fitted by least squares rather than interpolation; `σ`
//! still follows the lights' spacing, which is the detail the data hold, but is never
//! narrower than the centres' own spacing, which would leave gaps between kernels. (On
//! the attic with 3072 lights, 64 functions: 256 centres 24.10 dB held-out, 1024 centres
//! at the centres' spacing 24.26, at 1.5× 24.23, at 2× 24.19; 3072 centres 24.15.)
//! Far from every captured light (below the horizon of a dome) the functions fall to
//! zero.
//!
//! Stored: the centres, `σ`, and the `K × C` kernel weights of each function.
//!
//! **relight's kernel** (`"kernel": "relight"`, read from the relight/OpenLIME web
//! format by `codec/web.rs`; nothing fits it): the centres' Gaussians of the
//! Euclidean distance `d_c = |ω − μ_c|`, of a width that follows the light,
//! normalised to sum to one: `φ_c(ω) = exp(−r d_c²) / Σ_c′ exp(−r d_c′²)` with
//! `r = α / m`, `m = Σ d_c e^{−β d_c} / Σ e^{−β d_c}` a soft nearest distance (OpenLIME:
//! `α = 8`, `β = 2`). The centres are the file's light vectors as written (relight
//! rounds them to three decimals; OpenLIME measures from those). `σ` is unused.

use super::pca::{self, PcaSpace};
use super::{Basis, BasisSpec, BuildContext, Domain, Family};
use crate::memo::Memo;
use crate::sphere::Vec3;
use crate::{Error, Result};
use std::sync::Arc;

/// The most kernel centres: beyond, interpolation gains nothing a person sees and the
/// `C × C` solve grows as `C³` (about a second at 1024 on two cores).
pub const MAX_CENTRES: usize = 1024;

/// The sizes `rbf:K` offers.
const SIZES: [usize; 11] = [4, 6, 9, 12, 16, 18, 25, 27, 36, 49, 64];

pub(super) struct RbfFamily;

pub(super) static FAMILY: RbfFamily = RbfFamily;

impl Family for RbfFamily {
    fn name(&self) -> &'static str {
        "rbf"
    }

    fn summary(&self) -> &'static str {
        "Gaussian RBF interpolation over the captured lights, PCA-compressed to K"
    }

    fn sizes(&self, max: usize) -> Vec<usize> {
        SIZES.iter().copied().filter(|&k| k <= max).collect()
    }

    fn needs_samples(&self) -> bool {
        true
    }

    fn option_keys(&self) -> &'static [&'static str] {
        &["width", "pca", "ridge", "centres"]
    }

    fn nested(&self, lights: usize) -> bool {
        // The functions are the interpolants of the samples' principal directions in
        // order, from one eigendecomposition up to `EXACT_PCA_LIGHTS` (beyond, subspace
        // iteration finds the first `k` for each `k`).
        lights <= crate::linalg::EXACT_PCA_LIGHTS
    }

    fn build(&self, k: usize, context: &BuildContext) -> Result<Box<dyn Basis>> {
        let samples = context
            .samples
            .ok_or_else(|| Error::invalid("an rbf basis is built from samples"))?;
        let dirs = context.directions;
        let n = dirs.len();
        if samples.n != n {
            return Err(Error::invalid("samples and directions disagree"));
        }
        let width: f64 = context.option("width", 2.0)?;
        if !(width.is_finite() && width > 0.0) {
            return Err(Error::invalid("rbf width must be positive"));
        }
        let space = PcaSpace::parse(&context.option("pca", "srgb".to_string())?)?;
        let most: usize = context.option("centres", MAX_CENTRES)?;
        if most == 0 {
            return Err(Error::invalid("rbf needs at least one centre"));
        }
        let centres = spread(dirs, most);
        let mut sigma = width * mean_nearest_angle(dirs);
        if centres.len() < n {
            sigma = sigma.max(mean_nearest_angle(&centres));
        }
        let c = centres.len();
        let mut phi = vec![0.0; n * c];
        for (j, d) in dirs.iter().enumerate() {
            for (i, m) in centres.iter().enumerate() {
                phi[j * c + i] = kernel(*d, *m, sigma);
            }
        }
        let ridge_scale: f64 = context.option("ridge", 1e-3)?;
        // A whisper of ridge keeps the solve definite when kernels nearly coincide.
        let mut ridge = vec![0.0; c * c];
        (0..c).for_each(|i| ridge[i * c + i] = ridge_scale * n as f64);
        let t = pca::least_squares_operator(&phi, n, c, &ridge)?;
        let u = pca::principal_directions(&samples, k, space)?;
        let weights = pca::component_parameters(&t, c, &u, n);
        Ok(Box::new(Rbf {
            centres,
            sigma,
            weights,
            kernel: Kernel::Gaussian,
        }))
    }

    fn rebuild(
        &self,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Box<dyn Basis>> {
        let bad = |what: &str| Error::parse(format!("rbf basis: {what}"));
        let centres: Vec<Vec3> = params
            .get("centres")
            .and_then(|v| v.as_array())
            .ok_or_else(|| bad("needs `centres`"))?
            .iter()
            .map(|v| {
                let a: [f64; 3] =
                    serde_json::from_value(v.clone()).map_err(|_| bad("a bad centre"))?;
                let c = Vec3::from(a);
                // relight's centres are unit vectors rounded to three decimals.
                let slack = if params.contains_key("kernel") {
                    0.01
                } else {
                    1e-9
                };
                if !(c.length() - 1.0).abs().le(&slack) {
                    return Err(bad("a centre that is not a unit vector"));
                }
                Ok(c)
            })
            .collect::<Result<_>>()?;
        let sigma = params
            .get("sigma")
            .and_then(|v| v.as_f64())
            .filter(|s| s.is_finite() && *s > 0.0)
            .ok_or_else(|| bad("needs a positive `sigma`"))?;
        let weights = pca::stored_table(params, "weights", "rbf")?;
        let c = centres.len();
        if c == 0 || weights.is_empty() || weights.len() % c != 0 || weights.len() / c > 64 {
            return Err(bad("`weights` must hold K × centres values, K ≤ 64"));
        }
        let kernel = match params.get("kernel").map(|v| v.as_str()) {
            None => Kernel::Gaussian,
            Some(Some("relight")) => {
                let number = |key: &str| {
                    params
                        .get(key)
                        .and_then(|v| v.as_f64())
                        .filter(|v| v.is_finite() && *v > 0.0)
                        .ok_or_else(|| bad(&format!("relight's kernel needs a positive `{key}`")))
                };
                Kernel::Relight {
                    alpha: number("alpha")?,
                    beta: number("beta")?,
                }
            }
            Some(_) => return Err(bad("`kernel` is `relight` or absent")),
        };
        let expected = match kernel {
            Kernel::Gaussian => 3,
            Kernel::Relight { .. } => 6,
        };
        if params.len() != expected {
            return Err(bad(
                "has only `centres`, `sigma` and `weights` (and `kernel`, `alpha`, `beta`)",
            ));
        }
        Ok(Box::new(Rbf {
            centres,
            sigma,
            weights,
            kernel,
        }))
    }
}

#[inline]
fn kernel(d: Vec3, centre: Vec3, sigma: f64) -> f64 {
    (-(1.0 - d.dot(centre)) / (sigma * sigma)).exp()
}

/// A [`gradient_gram`] and the number of points it sums over.
struct KernelGram {
    /// `c×c`, row-major.
    matrix: Vec<f64>,
    /// How many points it sums over.
    points: usize,
}

/// The Gaussian kernels' gradient Gram matrix `G` (`c×c`, summed over the penalty's
/// points on `domain`) for `centres` and `sigma`, remembered for the last few
/// arguments ([`crate::memo`]): the basis choice builds every `rbf` size on each fold's
/// lights, in each space, the same kernels each time, and this matrix product over 2048
/// points (with the page faults of its 2 MiB of gradients) was a quarter of the
/// choice's time on RealRTI item5.
fn gradient_gram(centres: &[Vec3], sigma: f64, domain: Domain) -> Arc<KernelGram> {
    remembered_gram(&GRAMS, centres, sigma, domain)
}

/// The remembered [`gradient_gram`]s: at most 32 MiB (a 1024-centre Gram is 8 MiB).
static GRAMS: Memo<GramArguments, KernelGram> = Memo::new(32 << 20);

/// Forget the remembered [`gradient_gram`]s.
pub(super) fn forget() {
    GRAMS.clear();
}

/// The arguments of a [`gradient_gram`]: centres, `σ`'s bits, domain.
type GramArguments = (Vec<Vec3>, u64, Domain);

/// [`gradient_gram`] through `kept`.
fn remembered_gram(
    kept: &Memo<GramArguments, KernelGram>,
    centres: &[Vec3],
    sigma: f64,
    domain: Domain,
) -> Arc<KernelGram> {
    let bits = |v: &Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
    kept.get_or(
        |(c, s, d)| {
            *s == sigma.to_bits()
                && *d == domain
                && c.len() == centres.len()
                && c.iter().zip(centres).all(|(a, b)| bits(a) == bits(b))
        },
        || (centres.to_vec(), sigma.to_bits(), domain),
        || computed_gram(centres, sigma, domain),
        |g| g.matrix.len() * std::mem::size_of::<f64>(),
    )
}

/// [`gradient_gram`] computed.
fn computed_gram(centres: &[Vec3], sigma: f64, domain: Domain) -> KernelGram {
    let c = centres.len();
    let points = super::penalty_points(domain, super::PENALTY_POINTS);
    let inv_sigma2 = 1.0 / (sigma * sigma);
    let mut gradients = vec![0.0; 3 * points.len() * c];
    for (d, rows) in points.iter().zip(gradients.chunks_exact_mut(3 * c)) {
        for (i, m) in centres.iter().enumerate() {
            let v = kernel(*d, *m, sigma);
            if v < 1e-12 {
                continue;
            }
            let t = (*m - *d * d.dot(*m)) * (v * inv_sigma2);
            rows[i] = t.x;
            rows[c + i] = t.y;
            rows[2 * c + i] = t.z;
        }
    }
    let mut matrix = vec![0.0; c * c];
    crate::linalg::matmul_at(c, 3 * points.len(), c, &gradients, &gradients, &mut matrix);
    KernelGram {
        matrix,
        points: points.len(),
    }
}

/// Up to `max` of `dirs` spread over them: all of them when there are few enough,
/// otherwise farthest-point order from the first (deterministic).
pub(super) fn spread(dirs: &[Vec3], max: usize) -> Vec<Vec3> {
    if dirs.len() <= max {
        return dirs.to_vec();
    }
    let mut chosen = vec![dirs[0]];
    let mut nearest: Vec<f64> = dirs.iter().map(|d| d.dot(dirs[0])).collect();
    while chosen.len() < max {
        let (far, _) = nearest
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .expect("directions");
        let pick = dirs[far];
        chosen.push(pick);
        for (n, d) in nearest.iter_mut().zip(dirs) {
            *n = n.max(d.dot(pick));
        }
    }
    chosen
}

/// The mean angle (radians) from each direction to its nearest neighbour.
pub(super) fn mean_nearest_angle(dirs: &[Vec3]) -> f64 {
    if dirs.len() < 2 {
        return 1.0;
    }
    let total: f64 = dirs
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let best = dirs
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, e)| d.dot(*e))
                .fold(-1.0f64, f64::max);
            best.clamp(-1.0, 1.0).acos()
        })
        .sum();
    (total / dirs.len() as f64).max(1e-3)
}

/// How the centres' kernels are shaped (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kernel {
    /// `exp(−(1 − ω·μ)/σ²)`.
    Gaussian,
    /// relight's normalised Gaussians of a width that follows the light.
    Relight { alpha: f64, beta: f64 },
}

/// Gaussian RBF functions: `b_k(ω) = Σ_c weights[k][c] φ(ω, centre_c)`.
#[derive(Clone, Debug)]
pub struct Rbf {
    centres: Vec<Vec3>,
    sigma: f64,
    /// `K × C`, row-major.
    weights: Vec<f64>,
    kernel: Kernel,
}

/// relight's kernel values at `dir` for every centre (see the module docs): the weights
/// OpenLIME blends an `rbf` file's nodes with.
pub fn relight_kernels(centres: &[Vec3], dir: Vec3, alpha: f64, beta: f64, out: &mut Vec<f64>) {
    out.clear();
    out.extend(centres.iter().map(|c| (dir - *c).length()));
    let (mut num, mut den) = (0.0, 0.0);
    for &d in out.iter() {
        let e = (-beta * d).exp();
        num += d * e;
        den += e;
    }
    let r = alpha / (num / den).max(1e-12);
    // Exponents relative to the largest, so that no light far from every centre
    // underflows them all.
    let top = out.iter().fold(f64::INFINITY, |m, &d| m.min(d));
    let mut total = 0.0;
    for d in out.iter_mut() {
        *d = (-r * (*d * *d - top * top)).exp();
        total += *d;
    }
    out.iter_mut().for_each(|v| *v /= total);
}

/// An rbf basis with relight's kernel over `centres` (light vectors as the file gives
/// them): `weights` is `K × centres`.
pub fn relight_rbf(
    centres: Vec<Vec3>,
    weights: Vec<f64>,
    alpha: f64,
    beta: f64,
) -> Result<Box<dyn Basis>> {
    BasisSpec::new(
        "rbf",
        serde_json::json!({
            "centres": centres.iter().map(|c| [c.x, c.y, c.z]).collect::<Vec<_>>(),
            "sigma": 1.0,
            "weights": weights,
            "kernel": "relight",
            "alpha": alpha,
            "beta": beta,
        }),
    )
    .build()
}

impl Basis for Rbf {
    fn spec(&self) -> BasisSpec {
        let mut params = serde_json::json!({
            "centres": self.centres.iter().map(|c| [c.x, c.y, c.z]).collect::<Vec<_>>(),
            "sigma": self.sigma,
            "weights": self.weights,
        });
        if let Kernel::Relight { alpha, beta } = self.kernel {
            params["kernel"] = "relight".into();
            params["alpha"] = alpha.into();
            params["beta"] = beta.into();
        }
        BasisSpec::new("rbf", params)
    }

    fn family(&self) -> &'static str {
        "rbf"
    }

    fn len(&self) -> usize {
        self.weights.len() / self.centres.len()
    }

    fn domain(&self) -> Domain {
        if self.centres.iter().all(|c| c.z > -1e-9) {
            Domain::UpperHemisphere
        } else {
            Domain::Sphere
        }
    }

    /// The measured roughness of [`roughness_penalty`](super::roughness_penalty), with the
    /// Gaussian kernels' surface gradients in closed form, `∇k(d) = k(d)/σ² · (m −
    /// (d·m) d)`, instead of central differences: one kernel evaluation per point instead
    /// of four, which made the penalty a quarter of the basis choice's time on RealRTI
    /// item1 (five RBF sizes, ten folds, each building its own basis).
    fn penalty(&self) -> Vec<f64> {
        if self.kernel != Kernel::Gaussian {
            return super::roughness_penalty(self, super::PENALTY_POINTS);
        }
        // The kernels' own gradient Gram matrix (`c×c`, one matrix product over the
        // points' gradient rows), then the functions' as `W·G·Wᵀ`: the functions are
        // fixed combinations of the kernels.
        let (c, k) = (self.centres.len(), self.len());
        let gram = gradient_gram(&self.centres, self.sigma, self.domain());
        let mut half = vec![0.0; k * c];
        crate::linalg::matmul(k, c, c, &self.weights, &gram.matrix, &mut half);
        let mut p = vec![0.0; k * k];
        crate::linalg::matmul_bt(k, c, k, &half, &self.weights, &mut p);
        let count = gram.points as f64;
        for a in 0..k {
            for b in a..k {
                let v = p[a * k + b] / count;
                p[a * k + b] = v;
                p[b * k + a] = v;
            }
        }
        p
    }

    fn eval(&self, dir: Vec3, out: &mut [f64]) {
        let c = self.centres.len();
        let k = self.len();
        out[..k].fill(0.0);
        if let Kernel::Relight { alpha, beta } = self.kernel {
            let mut phi = Vec::with_capacity(c);
            relight_kernels(&self.centres, dir, alpha, beta, &mut phi);
            for (o, row) in out[..k].iter_mut().zip(self.weights.chunks_exact(c)) {
                *o = row.iter().zip(&phi).map(|(a, b)| a * b).sum();
            }
            return;
        }
        for (i, centre) in self.centres.iter().enumerate() {
            let v = kernel(dir, *centre, self.sigma);
            if v < 1e-12 {
                continue;
            }
            for (o, row) in out[..k].iter_mut().zip(self.weights.chunks_exact(c)) {
                *o += row[i] * v;
            }
        }
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{BasisChoice, Samples};

    /// Samples of `series` mixtures of four fixed lobes (a rank-4 family) at `dirs`.
    fn samples_of(dirs: &[Vec3], series: usize) -> Vec<f32> {
        let lobes = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.8, 0.0, 0.6),
            Vec3::new(-0.5, 0.6, 0.62),
            Vec3::new(0.1, -0.9, 0.42),
        ];
        let mut v = Vec::new();
        for s in 0..series {
            for d in dirs {
                let value: f64 = lobes
                    .iter()
                    .enumerate()
                    .map(|(i, l)| {
                        (1.0 + ((s * (i + 2)) as f64 * 0.7).sin()) * d.dot(*l).max(0.0).powi(3)
                    })
                    .sum();
                v.push(value as f32);
            }
        }
        v
    }

    #[test]
    fn closed_form_penalty_matches_the_measured_one() {
        for dirs in [
            crate::sphere::hemisphere_fibonacci(40),
            crate::sphere::fibonacci(30),
        ] {
            let values = samples_of(&dirs, 200);
            let samples = Samples {
                values: &values,
                n: dirs.len(),
            };
            let basis = BasisChoice::parse("rbf:9")
                .unwrap()
                .build(&dirs, Some(samples))
                .unwrap();
            let closed = basis.penalty();
            let measured = crate::basis::roughness_penalty(basis.as_ref(), 2048);
            let scale = measured.iter().map(|v| v.abs()).fold(0.0, f64::max);
            assert!(scale > 0.0);
            for (a, b) in closed.iter().zip(&measured) {
                assert!(
                    (a - b).abs() < 1e-5 * scale,
                    "{a} against {b} (scale {scale})"
                );
            }
        }
    }

    #[test]
    fn a_remembered_gradient_gram_is_the_computed_one_for_its_own_arguments() {
        let a = crate::sphere::hemisphere_fibonacci(40);
        let b = crate::sphere::hemisphere_fibonacci(41);
        let mut c = a.clone();
        c[7].x = f64::from_bits(c[7].x.to_bits() + 1); // one bit away from `a`
        let args = [
            (&a, 0.3, Domain::UpperHemisphere),
            (&b, 0.3, Domain::UpperHemisphere),
            (&a, 0.3 + 1e-12, Domain::UpperHemisphere),
            (&c, 0.3, Domain::UpperHemisphere),
            (&a, 0.3, Domain::Sphere),
        ];
        let computed: Vec<KernelGram> = args
            .iter()
            .map(|(dirs, sigma, domain)| computed_gram(dirs, *sigma, *domain))
            .collect();
        for i in 0..args.len() {
            for j in 0..i {
                assert_ne!(computed[i].matrix, computed[j].matrix, "{i} and {j}");
            }
        }
        // Room for four of the five (a memory keeps values of up to a quarter of its
        // budget): asked in an order that both finds remembered ones and forgets the
        // oldest.
        let largest = computed.iter().map(|g| g.matrix.len() * 8).max().unwrap();
        let kept = Memo::new(4 * largest);
        for &i in &[0, 1, 0, 2, 3, 1, 4, 4, 0, 2, 2, 3, 1, 0] {
            let (dirs, sigma, domain) = args[i];
            let got = remembered_gram(&kept, dirs, sigma, domain);
            assert_eq!(got.matrix, computed[i].matrix, "arguments {i}");
            assert_eq!(got.points, computed[i].points);
            assert!((1..=4).contains(&kept.len()), "{} kept", kept.len());
        }
    }

    #[test]
    fn interpolates_what_its_components_span_and_round_trips() {
        let dirs = crate::sphere::hemisphere_fibonacci(40);
        let values = samples_of(&dirs, 300);
        let samples = Samples {
            values: &values,
            n: dirs.len(),
        };
        let choice = BasisChoice::parse("rbf:4:pca=linear,width=1,ridge=1e-8").unwrap();
        let basis = choice.build(&dirs, Some(samples)).unwrap();
        assert_eq!(basis.len(), 4);
        // The span reproduces a series at the captured lights (least squares on the
        // design the fit would build).
        let k = basis.len();
        let a: Vec<Vec<f64>> = dirs.iter().map(|d| basis.values(*d)).collect();
        let target = &values[..dirs.len()];
        let mut m = vec![0.0; k * k];
        let mut b = vec![0.0; k];
        for (row, &t) in a.iter().zip(target) {
            for p in 0..k {
                b[p] += row[p] * t as f64;
                for q in 0..k {
                    m[p * k + q] += row[p] * row[q];
                }
            }
        }
        (0..k).for_each(|i| m[i * k + i] += 1e-12);
        assert!(crate::linalg::cholesky(&mut m, k));
        crate::linalg::cholesky_solve(&m, k, &mut b);
        let worst = a
            .iter()
            .zip(target)
            .map(|(row, &t)| (row.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>() - t as f64).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-4, "worst residual {worst}");
        // Far below the dome the functions fade out.
        let top = basis.values(Vec3::new(0.0, 0.0, 1.0));
        let scale = top.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let below = basis.values(Vec3::new(0.0, 0.0, -1.0));
        assert!(below.iter().all(|v| v.abs() < 1e-2 * scale), "{below:?}");
        // The spec rebuilds the same functions.
        let again = basis.spec().build().unwrap();
        for d in crate::sphere::fibonacci(9) {
            assert_eq!(again.values(d), basis.values(d));
        }
    }

    #[test]
    fn dense_captures_use_spread_centres() {
        let dirs = crate::sphere::fibonacci(600);
        let picked = spread(&dirs, 100);
        assert_eq!(picked.len(), 100);
        // Farthest-point order leaves no direction far from a centre.
        let angle = mean_nearest_angle(&picked);
        let worst = dirs
            .iter()
            .map(|d| picked.iter().map(|c| d.dot(*c)).fold(-1.0, f64::max).acos())
            .fold(0.0, f64::max);
        assert!(worst < 1.2 * angle, "{worst} vs spacing {angle}");
    }
}
