//! Choosing a basis per capture: validation on the capture's own lights.
//!
//! Exact leave-one-out (what the λ choice of an analytic basis uses) is not valid for
//! data-driven bases: their functions are built from every captured light, so a light
//! left out of the solve still shaped the basis, and the estimate would flatter them.
//! Every candidate is therefore judged the same honest way: the captured lights are
//! split into folds; for each fold the basis is *built* from the other folds' lights
//! only (directions and, for data-driven families, samples), the pixel subsample is
//! fitted there and predicted at the fold's lights, and the error a person sees —
//! sRGB-encoded, negative radiance shown as black, lights that do not reach the scene
//! left out — is summed over folds. The evaluation hold-outs of `relit eval` never take
//! part: they are not in the capture the fit sees.

use super::{light_relevance, perceptual_weight, srgb_shown, Objective, Regularizer};
use crate::basis::{Basis, BasisChoice, Samples, FAMILIES};
use crate::linalg;
use crate::sphere::Vec3;
use crate::Result;
use rayon::prelude::*;
use serde::Serialize;

/// The λ values each candidate is validated at.
pub const VALIDATION_LADDER: [f64; 6] = [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1];

/// Folds of the captured lights (fewer for captures of very few lights).
const FOLDS: usize = 5;

/// One candidate's validation score.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CandidateScore {
    /// `family:K`.
    pub basis: String,
    /// The λ of smallest validation error.
    pub lambda: f64,
    /// Root-mean-square display error at that λ (sRGB values, 0–1).
    pub display_rmse: f64,
    /// The same as a PSNR (peak 1), the figure to read.
    pub psnr: f64,
}

/// The candidates `auto` considers within `max_coefficients`: every size of every
/// family from 4 coefficients up (fewer cannot follow a light at all), none with more
/// coefficients than the folds leave lights to fit.
pub fn candidates(max_coefficients: usize, lights: usize) -> Vec<BasisChoice> {
    let train = lights - lights.div_ceil(folds(lights));
    FAMILIES
        .iter()
        .flat_map(|f| {
            f.sizes(max_coefficients)
                .into_iter()
                .filter(move |&k| k >= 4 && k < train)
                .map(|k| BasisChoice::parse(&format!("{}:{k}", f.name())).expect("a listed size"))
        })
        .collect()
}

fn folds(n: usize) -> usize {
    FOLDS.min(n / 4).max(2)
}

/// The pixel subsample the fit reads, as the validation sees it.
pub(super) struct Subsample<'a> {
    /// `count × n × 3` (pixel, light, channel).
    pub values: &'a [f32],
    pub count: usize,
    pub n: usize,
}

/// Validate `choice` under `objective` (linear or perceptual) on `sub`, lit from `dirs`
/// with quadrature weights `q`; returns the best λ of [`VALIDATION_LADDER`] and its error.
pub(super) fn validate(
    choice: &BasisChoice,
    objective: Objective,
    regularizer: Regularizer,
    dirs: &[Vec3],
    q: &[f64],
    sub: &Subsample,
) -> Result<CandidateScore> {
    let n = sub.n;
    let series = sub.count * 3;
    let relevance = light_relevance(sub.values, sub.count, n);
    let folds = folds(n);
    let mut err = [0.0f64; VALIDATION_LADDER.len()];
    let mut weight = 0.0f64;
    for fold in 0..folds {
        let train: Vec<usize> = (0..n).filter(|j| j % folds != fold).collect();
        let held: Vec<usize> = (0..n).filter(|j| j % folds == fold).collect();
        let values: Vec<f32> = (0..series)
            .flat_map(|s| {
                let (p, c) = (s / 3, s % 3);
                train.iter().map(move |&j| sub.values[(p * n + j) * 3 + c])
            })
            .collect();
        let train_dirs: Vec<Vec3> = train.iter().map(|&j| dirs[j]).collect();
        let basis = choice.build(
            &train_dirs,
            Some(Samples {
                values: &values,
                n: train.len(),
            }),
        )?;
        let fold_err = fold_errors(
            basis.as_ref(),
            objective,
            regularizer,
            &train_dirs,
            &held.iter().map(|&j| dirs[j]).collect::<Vec<_>>(),
            &train.iter().map(|&j| q[j]).collect::<Vec<_>>(),
            &held
                .iter()
                .map(|&j| q[j] * relevance[j])
                .collect::<Vec<_>>(),
            &values,
            &held,
            sub,
        );
        for (e, f) in err.iter_mut().zip(fold_err) {
            *e += f;
        }
        weight += held.iter().map(|&j| q[j] * relevance[j]).sum::<f64>() * series as f64;
    }
    let (best, &e) = err
        .iter()
        .enumerate()
        .filter(|(_, e)| e.is_finite())
        .min_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((0, &f64::INFINITY));
    let rmse = (e / weight.max(1e-300)).sqrt();
    Ok(CandidateScore {
        basis: choice.name(),
        lambda: VALIDATION_LADDER[best],
        display_rmse: rmse,
        psnr: crate::metrics::psnr(rmse * rmse, 1.0),
    })
}

/// Summed weighted squared display errors at the held-out lights, one per λ.
#[allow(clippy::too_many_arguments)]
fn fold_errors(
    basis: &dyn Basis,
    objective: Objective,
    regularizer: Regularizer,
    train_dirs: &[Vec3],
    held_dirs: &[Vec3],
    q_train: &[f64],
    seen: &[f64],
    train_values: &[f32],
    held: &[usize],
    sub: &Subsample,
) -> [f64; VALIDATION_LADDER.len()] {
    let k = basis.len();
    let nt = train_dirs.len();
    let a_train: Vec<f64> = train_dirs.iter().flat_map(|d| basis.values(*d)).collect();
    let a_held: Vec<f64> = held_dirs.iter().flat_map(|d| basis.values(*d)).collect();
    let penalty = match regularizer {
        Regularizer::Roughness => basis.penalty(),
        Regularizer::Ridge => {
            let mut p = vec![0.0; k * k];
            (0..k).for_each(|i| p[i * k + i] = 1.0 / (4.0 * std::f64::consts::PI));
            p
        }
    };
    let normal = |w: &[f64]| -> (Vec<f64>, f64) {
        let mut m = vec![0.0; k * k];
        for (j, &wj) in w.iter().enumerate() {
            let row = &a_train[j * k..(j + 1) * k];
            for r in 0..k {
                let v = wj * row[r];
                for c in r..k {
                    m[r * k + c] += v * row[c];
                }
            }
        }
        for r in 0..k {
            for c in 0..r {
                m[r * k + c] = m[c * k + r];
            }
        }
        (m, w.iter().sum())
    };
    let factor = |m: &[f64], total: f64, lambda: f64| -> Option<Vec<f64>> {
        let mut f = m.to_vec();
        for (v, &p) in f.iter_mut().zip(&penalty) {
            *v += total * lambda * p;
        }
        (0..k).for_each(|i| f[i * k + i] += total * 1e-10);
        linalg::cholesky(&mut f, k).then_some(f)
    };
    // The linear objective shares one matrix (and its factors) across pixels.
    let shared: Option<Vec<Option<Vec<f64>>>> = (objective == Objective::Linear).then(|| {
        let (m, total) = normal(q_train);
        VALIDATION_LADDER
            .iter()
            .map(|&l| factor(&m, total, l))
            .collect()
    });
    let series = sub.count * 3;
    (0..series)
        .into_par_iter()
        .fold(
            || [0.0f64; VALIDATION_LADDER.len()],
            |mut acc, s| {
                let obs = &train_values[s * nt..(s + 1) * nt];
                let (p, c) = (s / 3, s % 3);
                let own;
                let factors: &[Option<Vec<f64>>] = match &shared {
                    Some(f) => f,
                    None => {
                        let w: Vec<f64> = obs
                            .iter()
                            .zip(q_train)
                            .map(|(&v, &q)| q * perceptual_weight(v as f64))
                            .collect();
                        let (m, total) = normal(&w);
                        own = VALIDATION_LADDER
                            .iter()
                            .map(|&l| factor(&m, total, l))
                            .collect::<Vec<_>>();
                        &own
                    }
                };
                let mut rhs0 = vec![0.0; k];
                for (j, &v) in obs.iter().enumerate() {
                    let w = match objective {
                        Objective::Linear => q_train[j],
                        _ => q_train[j] * perceptual_weight(v as f64),
                    };
                    let row = &a_train[j * k..(j + 1) * k];
                    for r in 0..k {
                        rhs0[r] += w * row[r] * v as f64;
                    }
                }
                for (li, f) in factors.iter().enumerate() {
                    let Some(f) = f else {
                        acc[li] = f64::INFINITY;
                        continue;
                    };
                    let mut coef = rhs0.clone();
                    linalg::cholesky_solve(f, k, &mut coef);
                    for (h, &j) in held.iter().enumerate() {
                        let pred: f64 = a_held[h * k..(h + 1) * k]
                            .iter()
                            .zip(&coef)
                            .map(|(a, b)| a * b)
                            .sum();
                        let o = sub.values[(p * sub.n + j) * 3 + c] as f64;
                        let d = srgb_shown(pred) - srgb_shown(o);
                        acc[li] += seen[h] * d * d;
                    }
                }
                acc
            },
        )
        .reduce(
            || [0.0; VALIDATION_LADDER.len()],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                a
            },
        )
}
