//! What the data-driven families share: an interpolation of each pixel's samples over
//! the captured light directions, compressed across pixels by principal components.
//!
//! An interpolation scheme is a linear operator `T` (`C × N`) from a pixel's `N` samples
//! (one per captured light) to the scheme's `C` parameters (RBF weights, grid values),
//! which the scheme then evaluates at any direction. Its functions span `N` dimensions;
//! the `K` principal directions `U_k` of the samples (over a pixel subsample, uncentred)
//! pick the `K` combinations that matter for this capture, and the basis function `k` is
//! the interpolant of `U_k`: parameters `T · U_k`. A pixel whose samples lie in the span
//! of the `U_k` is reproduced at every captured light, and between them the scheme
//! interpolates — which is what lets these bases follow the sharp features (shadows,
//! highlights) that a band-limited basis blurs.

use super::Samples;
use crate::memo::Memo;
use crate::{Error, Result};

/// The space the principal components are found in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum PcaSpace {
    /// Linear radiance: the brightest pixels dominate.
    Linear,
    /// sRGB-encoded values: dark and bright pixels weigh as a person sees them.
    Srgb,
}

impl PcaSpace {
    pub(super) fn parse(s: &str) -> Result<PcaSpace> {
        match s {
            "linear" => Ok(PcaSpace::Linear),
            "srgb" => Ok(PcaSpace::Srgb),
            _ => Err(Error::parse(format!("bad PCA space `{s}`: linear or srgb"))),
        }
    }
}

/// The `K` principal directions of `samples` (uncentred, so the mean response is the
/// first), each `N` long, found in `space`.
pub(super) fn principal_directions(
    samples: &Samples,
    k: usize,
    space: PcaSpace,
) -> Result<Vec<f64>> {
    let n = samples.n;
    let rows = samples.series();
    if rows == 0 || n == 0 {
        return Err(Error::invalid("no samples to find principal components in"));
    }
    if k > n {
        return Err(Error::invalid(format!(
            "{k} components need at least {k} captured lights, the capture has {n}"
        )));
    }
    // Below this many lights every principal direction is found (a symmetric
    // eigendecomposition), and `k` only says how many to return: one decomposition
    // serves every size of every data-driven family on the same samples, remembered
    // (`crate::memo`; on RealRTI item3 the decompositions were a seventh of the fit's
    // processor time).
    if n <= crate::linalg::EXACT_PCA_LIGHTS {
        let all = DIRECTIONS.get_or(
            |(s, m, v)| *s == space && *m == n && crate::memo::same_bits_f32(v, samples.values),
            || (space, n, samples.values.to_vec()),
            || crate::linalg::principal_directions(&in_space(samples, space), rows, n, n),
            |all| all.len() * 8 + samples.values.len() * 4,
        );
        return Ok(all[..k * n].to_vec());
    }
    Ok(crate::linalg::principal_directions(
        &in_space(samples, space),
        rows,
        n,
        k,
    ))
}

/// The remembered principal directions, with the samples they were found in: at most
/// 16 MiB.
static DIRECTIONS: Memo<(PcaSpace, usize, Vec<f32>), Vec<f64>> = Memo::new(16 << 20);

/// Forget the remembered principal directions.
pub(super) fn forget() {
    DIRECTIONS.clear();
}

/// The samples' values in `space`, as doubles.
fn in_space(samples: &Samples, space: PcaSpace) -> Vec<f64> {
    let mut values: Vec<f64> = samples.values.iter().map(|&v| v as f64).collect();
    if let PcaSpace::Srgb = space {
        // Encoded in place through a small buffer, so that the samples are held once
        // (negative radiance encodes as black: the tabulated curve clamps it).
        let mut linear = [0.0; 1024];
        for part in values.chunks_mut(linear.len()) {
            let linear = &mut linear[..part.len()];
            linear.copy_from_slice(part);
            crate::color::linear_to_srgb_tabulated_batch(linear, part);
        }
    }
    values
}

/// The parameters of the `K` basis functions, `K × C` row-major: `T · U_k` for the
/// operator `t` (`C × N` row-major) and the principal directions `u` (`K × N`).
pub(super) fn component_parameters(t: &[f64], c: usize, u: &[f64], n: usize) -> Vec<f64> {
    let k = u.len() / n;
    let mut out = vec![0.0; k * c];
    for comp in 0..k {
        let uk = &u[comp * n..(comp + 1) * n];
        for p in 0..c {
            out[comp * c + p] = t[p * n..(p + 1) * n]
                .iter()
                .zip(uk)
                .map(|(a, b)| a * b)
                .sum();
        }
    }
    out
}

/// Solve the regularised least squares `(AᵀA + R) T = Aᵀ` for the operator `T`
/// (`C × N`), `a` being `N × C` (row-major) and `r` a `C × C` regulariser.
///
/// Dense captures reach `C` = 1024 kernels over `N` = 3072 lights, billions of
/// multiply-adds: the normal matrix is one GEMM; its Cholesky factor `L` is inverted
/// column by column in parallel (forward substitution reads `L` by rows, which keeps
/// it in cache), and `T = L⁻ᵀ L⁻¹ Aᵀ` is two more GEMMs.
pub(super) fn least_squares_operator(a: &[f64], n: usize, c: usize, r: &[f64]) -> Result<Vec<f64>> {
    use rayon::prelude::*;
    let mut m = vec![0.0; c * c];
    crate::linalg::matmul_at(c, n, c, a, a, &mut m); // AᵀA
    m.iter_mut().zip(r).for_each(|(x, y)| *x += y);
    if !crate::linalg::cholesky(&mut m, c) {
        return Err(Error::new(
            crate::ErrorKind::Numerical,
            "the interpolation's normal equations are singular",
        ));
    }
    // Chunk i becomes L⁻¹ eᵢ, column i of L⁻¹: together, W = L⁻ᵀ row-major.
    let mut w = vec![0.0; c * c];
    (0..c).for_each(|i| w[i * c + i] = 1.0);
    w.par_chunks_mut(c)
        .for_each(|col| crate::linalg::forward_solve(&m, c, col));
    let mut inverse = vec![0.0; c * c];
    crate::linalg::matmul_bt(c, c, c, &w, &w, &mut inverse); // L⁻ᵀ L⁻¹ = M⁻¹
    let mut t = vec![0.0; c * n];
    crate::linalg::matmul_bt(c, c, n, &inverse, a, &mut t); // M⁻¹ Aᵀ
    Ok(t)
}

/// Parse a stored `K × C` parameter table.
pub(super) fn stored_table(
    params: &serde_json::Map<String, serde_json::Value>,
    key: &str,
    family: &str,
) -> Result<Vec<f64>> {
    params
        .get(key)
        .and_then(|v| v.as_array())
        .ok_or_else(|| Error::parse(format!("a `{family}` basis needs `{key}`")))?
        .iter()
        .map(|v| {
            v.as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| Error::parse(format!("`{family}` `{key}`: a non-number")))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `(AᵀA + R) T = Aᵀ` holds for the operator, on both sides of `N = C`.
    #[test]
    fn least_squares_operator_solves_the_normal_equations() {
        for (n, c) in [(40, 12), (12, 40), (20, 20)] {
            let mut state = 0x9E37_79B9_7F4A_7C15u64;
            let mut next = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            let a: Vec<f64> = (0..n * c).map(|_| next()).collect();
            let mut r = vec![0.0; c * c];
            (0..c).for_each(|i| r[i * c + i] = 0.1);
            let t = least_squares_operator(&a, n, c, &r).unwrap();
            for p in 0..c {
                for j in 0..n {
                    // Row p of (AᵀA + R) times column j of T, against Aᵀ[p][j].
                    let lhs: f64 = (0..c)
                        .map(|q| {
                            let ata: f64 = (0..n).map(|i| a[i * c + p] * a[i * c + q]).sum();
                            (ata + r[p * c + q]) * t[q * n + j]
                        })
                        .sum();
                    assert!((lhs - a[j * c + p]).abs() < 1e-9, "n {n} c {c}: {lhs}");
                }
            }
        }
    }
}
