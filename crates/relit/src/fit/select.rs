//! Choosing a basis per capture: validation on the capture's own lights.
//!
//! Exact leave-one-out (what the λ choice of an analytic basis uses) is not valid for
//! data-driven bases: their functions are built from every captured light, so a light
//! left out of the solve still shaped the basis, and the estimate would flatter them.
//! Every candidate is therefore judged the same honest way: the captured lights are
//! split into folds; for each fold the basis is *built* from the other folds' lights
//! only (directions and, for data-driven families, samples), the pixel subsample is
//! fitted there and predicted at the fold's lights, and the error is summed over
//! folds, lights that do not reach the scene left out. The error is judged as the
//! capture's images hold it ([`Criterion`]): for photographs (8- and 16-bit, sRGB),
//! the error a person sees — sRGB-encoded, negative radiance shown as black; for
//! radiance images (EXR, HDR, rendered), the error in linear radiance, whose highlights
//! above display white the sRGB error would clip away. The evaluation hold-outs of
//! `relit eval` never take part: they are not in the capture the fit sees.

use super::{
    brightness_kept, light_relevance, perceptual_weight_encoded, srgb_on_screen, Objective,
    Regularizer,
};
use crate::basis::{Basis, BasisChoice, BasisSpec, Family, Samples, FAMILIES};
use crate::color;
use crate::linalg::{self, Lanes, LANES};
use crate::maps::MapSpace;
use crate::memo::Memo;
use crate::sphere::Vec3;
use crate::Result;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::sync::Arc;

/// The λ values each candidate is validated at.
pub const VALIDATION_LADDER: [f64; 6] = [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1];

const LADDER: usize = VALIDATION_LADDER.len();
const _: () = assert!(
    LADDER.is_multiple_of(2),
    "the validation solves its λ in pairs"
);

/// Per held-out light: squared display errors per λ, summed predictions per λ, the
/// summed observation (linear radiance) and squared linear errors per λ.
const SLOTS: usize = 3 * LADDER + 1;

/// Where the squared linear errors start in a light's slots.
const LINEAR: usize = 2 * LADDER + 1;

/// What the validation error is measured in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// 8-bit-style display values: sRGB-encoded, clipped to `[0, 1]` (photographs).
    #[default]
    Display,
    /// Linear radiance, unclipped above white (radiance images).
    Linear,
}

impl Criterion {
    /// The criterion for a capture: linear where its images hold radiance.
    pub fn for_capture(capture: &crate::capture::Capture) -> Criterion {
        if capture.radiance_images() {
            Criterion::Linear
        } else {
            Criterion::Display
        }
    }
}

/// Folds of the captured lights (fewer for captures of very few lights).
const FOLDS: usize = 10;

/// Multiply-adds one candidate's perceptual validation may spend per fold on normal
/// matrices (each pixel has its own, `n·k²`, which its three channels share): a dense
/// capture validates on fewer pixels rather than for minutes (a 60-light RTI capture
/// keeps all of them).
const PERCEPTUAL_BUDGET: f64 = 3e8;

/// Pixels of the subsample a perceptual validation of `k` coefficients on `n` lights
/// uses, out of `count`.
fn perceptual_pixels(count: usize, n: usize, k: usize) -> usize {
    let per_pixel = n as f64 * (k * k) as f64;
    ((PERCEPTUAL_BUDGET / per_pixel) as usize)
        .max(32)
        .min(count)
}

/// One candidate's validation score.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CandidateScore {
    /// `family:K`.
    pub basis: String,
    /// The λ of smallest validation error.
    pub lambda: f64,
    /// Root-mean-square display error at that λ over every light (sRGB values, 0–1).
    pub display_rmse: f64,
    /// What `psnr` measures.
    pub criterion: Criterion,
    /// The space the candidate's maps would store (and were fitted in).
    #[serde(default)]
    pub space: MapSpace,
    /// The mean over the captured lights of each light's PSNR (peak 1) when held out,
    /// in display values or linear radiance as `criterion` says: what the choice
    /// maximises, comparable to `relit eval`'s figures.
    pub psnr: f64,
    /// Mean held-out prediction over mean observation, linear radiance (1: unbiased);
    /// candidates beyond a factor `MAX_MEAN_BIAS` lose to every unbiased one.
    pub mean_bias: f64,
    /// Pixels of the subsample the score was measured on: the finalists' full
    /// validation, or the screening (fewer pixels and folds) that set the other
    /// candidates aside.
    #[serde(default)]
    pub pixels: usize,
    /// Each captured light's PSNR when held out (at the chosen λ, by `criterion`,
    /// capped at 100 dB) and its weight in `psnr` (quadrature × whether the light
    /// reaches the scene): how much of a lead over another candidate is noise.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<(f64, f64)>,
}

impl CandidateScore {
    /// Whether the candidate keeps the scene's brightness.
    pub fn unbiased(&self) -> bool {
        brightness_kept(self.mean_bias)
    }

    /// Whether `self` is the better candidate: unbiased first, then the higher PSNR.
    pub fn beats(&self, other: &CandidateScore) -> bool {
        match (self.unbiased(), other.unbiased()) {
            (true, false) => true,
            (false, true) => false,
            _ => self.psnr > other.psnr,
        }
    }
}

/// The sizes `auto` tries where a family offers them: a ladder that roughly doubles the
/// coefficients at each step (finer steps cost time and, with more candidates, make the
/// winner's validation score more flattering).
const AUTO_SIZES: [usize; 8] = [4, 6, 9, 16, 25, 36, 49, 64];

/// The candidates `auto` considers within `max_coefficients`: every family at the sizes
/// of [`AUTO_SIZES`] it offers, from 4 coefficients up (fewer cannot follow a light at
/// all), none with more coefficients than the folds leave lights to fit.
pub fn candidates(max_coefficients: usize, lights: usize) -> Vec<BasisChoice> {
    let train = training_lights(lights);
    FAMILIES
        .iter()
        .flat_map(|f| family_sizes(*f, max_coefficients))
        .filter(|c| c.k < train)
        .collect()
}

/// The lights each validation fold of a capture of `n` lights trains on: a candidate
/// needs fewer coefficients than these.
pub(super) fn training_lights(n: usize) -> usize {
    n - n.div_ceil(folds(n))
}

/// The bases a `--candidate` value names: `family:K` itself, or a family alone for its
/// sizes of [`AUTO_SIZES`] within `max_coefficients` (`hsh`: `auto` among the
/// hemispherical harmonics only).
pub fn parse_candidates(spec: &str, max_coefficients: usize) -> Result<Vec<BasisChoice>> {
    let name = spec.trim();
    if name.contains(':') {
        return Ok(vec![BasisChoice::parse(name)?]);
    }
    let family = crate::basis::family(name)?;
    let sizes = family_sizes(family, max_coefficients);
    if sizes.is_empty() {
        return Err(crate::Error::invalid(format!(
            "basis `{name}` has no size on auto's ladder {AUTO_SIZES:?} within \
             {max_coefficients} coefficients: its sizes are {:?}",
            family.sizes(64)
        )));
    }
    Ok(sizes)
}

fn family_sizes(family: &dyn Family, max_coefficients: usize) -> Vec<BasisChoice> {
    family
        .sizes(max_coefficients)
        .into_iter()
        .filter(|k| AUTO_SIZES.contains(k))
        .map(|k| BasisChoice::parse(&format!("{}:{k}", family.name())).expect("a listed size"))
        .collect()
}

/// Series (pixel channels) a task of the linear objective's validation predicts.
const SERIES_BLOCK: usize = 64;

/// Pixels a task of the perceptual objective's validation solves (two lane groups).
const PIXEL_BLOCK: usize = 2 * LANES;

/// Folds for `n` lights: [`FOLDS`], fewer when there are few lights (each fold keeps
/// four or more) and half as many for dense captures, whose folds hold plenty of lights
/// (and each fold costs a basis and a fit).
pub(super) fn folds(n: usize) -> usize {
    let f = if n > 200 { FOLDS / 2 } else { FOLDS };
    f.min(n / 4).max(2)
}

/// Folds of the screening that sets most candidates aside before the full validation:
/// half of [`folds`] (each fold costs a basis and a fit), as long as every candidate
/// of up to `max_k` coefficients still has more training lights than coefficients.
pub(super) fn screening_folds(n: usize, max_k: usize) -> usize {
    let half = (folds(n) / 2).max(2);
    if max_k < n - n.div_ceil(half) {
        half
    } else {
        folds(n)
    }
}

/// The pixel subsample the fit reads, as the validation sees it.
pub(super) struct Subsample<'a> {
    /// `count × n × 3` (pixel, light, channel).
    pub values: &'a [f32],
    pub count: usize,
    pub n: usize,
}

impl Subsample<'_> {
    /// The values of `keep` of the pixels, evenly spread over the subsample.
    pub fn thinned(&self, keep: usize) -> Vec<f32> {
        let (n, count) = (self.n, self.count);
        (0..keep.min(count))
            .flat_map(|i| {
                let p = i * count / keep.min(count);
                self.values[p * n * 3..(p + 1) * n * 3].iter().copied()
            })
            .collect()
    }
}

/// The regularisation matrices of the bases a basis choice validates, kept for bases
/// that do not depend on the fold's samples: an analytic basis is the same in every
/// fold, space and objective, and its roughness penalty (numerical for most families)
/// would otherwise be computed for each of them.
pub(super) struct Penalties(Memo<BasisSpec, Vec<f64>>);

impl Default for Penalties {
    /// Every analytic candidate's penalty is kept while the choice lasts: a few dozen
    /// `k×k` matrices.
    fn default() -> Self {
        Self(Memo::new(usize::MAX))
    }
}

impl Penalties {
    /// The penalty of `basis` under `regularizer`, computed once per basis where
    /// `data_driven` is false.
    fn of(&self, basis: &dyn Basis, regularizer: Regularizer, data_driven: bool) -> Arc<Vec<f64>> {
        let compute = || regularizer.matrix(basis);
        if data_driven || regularizer == Regularizer::Ridge {
            return Arc::new(compute());
        }
        let spec = basis.spec();
        self.0.get_or(
            |s| *s == spec,
            || spec.clone(),
            compute,
            |p| p.len() * std::mem::size_of::<f64>(),
        )
    }
}

/// Validate `choice` under each of `objectives` (linear or perceptual) on `sub`, lit
/// from `dirs` with quadrature weights `q`: for each, in order, the best λ of
/// [`VALIDATION_LADDER`] by `criterion` and its error. `space` is what `sub` holds and
/// the candidate's maps would store: linear radiance, or sRGB-encoded display values
/// (then only the plain objective applies, and predictions are shown as they are,
/// clipped to `[0, 1]`, and decoded for the linear error), so that both kinds of maps
/// are judged on one scale.
///
/// Objectives that validate on the same pixels share each fold's basis: building a
/// data-driven basis (its principal components, its roughness penalty) is a good part
/// of a fold's cost, and it depends on the fold's lights and pixels, not the objective.
///
/// `nested` is one candidate, or sizes of one nested family ([`Family::nested`]) with
/// the same options, ascending: those are judged together from the largest size's
/// basis and systems in each fold. A size's functions are the largest's first ones, so
/// its normal matrix is the leading block and its factor the factor's leading block
/// (`linalg::cholesky_pivots`): each size is solved as it would be alone, and a fold
/// builds one basis instead of one per size. `ladders` are per objective, per candidate
/// (an empty one: that candidate is not judged under that objective, and its score
/// there means nothing). The scores are per candidate of `nested`, per objective.
#[allow(clippy::too_many_arguments)]
pub(super) fn validate(
    nested: &[BasisChoice],
    space: MapSpace,
    objectives: &[Objective],
    regularizer: Regularizer,
    criterion: Criterion,
    dirs: &[Vec3],
    q: &[f64],
    sub: &Subsample,
    folds: usize,
    ladders: &[Vec<Range<usize>>],
    penalties: &Penalties,
) -> Result<Vec<Vec<CandidateScore>>> {
    assert_eq!(ladders.len(), objectives.len());
    assert!(ladders.iter().all(|l| l.len() == nested.len()));
    assert!(
        space == MapSpace::Linear || objectives.iter().all(|&o| o == Objective::Linear),
        "display-referred maps are fitted with the plain objective"
    );
    let n = sub.n;
    let keeps_of = |choice: &BasisChoice| -> Vec<usize> {
        objectives
            .iter()
            .map(|o| match o {
                Objective::Perceptual => perceptual_pixels(sub.count, n, choice.k),
                _ => sub.count,
            })
            .collect()
    };
    // Sizes that validate on different pixels (a dense capture's perceptual budget) are
    // judged apart.
    if nested
        .windows(2)
        .any(|w| keeps_of(&w[0]) != keeps_of(&w[1]))
    {
        return nested
            .iter()
            .enumerate()
            .map(|(c, choice)| {
                let own: Vec<Vec<Range<usize>>> =
                    ladders.iter().map(|l| vec![l[c].clone()]).collect();
                let mut one = validate(
                    std::slice::from_ref(choice),
                    space,
                    objectives,
                    regularizer,
                    criterion,
                    dirs,
                    q,
                    sub,
                    folds,
                    &own,
                    penalties,
                )?;
                Ok(one.remove(0))
            })
            .collect();
    }
    assert!(
        nested
            .windows(2)
            .all(|w| w[0].k < w[1].k && w[0].nests_in(&w[1], n)),
        "sizes of one nested family, ascending"
    );
    let largest = nested.last().expect("a candidate to validate");
    let sizes: Vec<usize> = nested.iter().map(|c| c.k).collect();
    let keeps = keeps_of(largest);
    let mut distinct = keeps.clone();
    distinct.sort_unstable();
    distinct.dedup();
    let mut scores: Vec<Vec<Option<CandidateScore>>> =
        vec![vec![None; objectives.len()]; nested.len()];
    for keep in distinct {
        let group: Vec<usize> = (0..objectives.len())
            .filter(|&i| keeps[i] == keep)
            .collect();
        let grouped: Vec<(Objective, Vec<Range<usize>>)> = group
            .iter()
            .map(|&i| (objectives[i], ladders[i].clone()))
            .collect();
        let thinned: Vec<f32>;
        let thin;
        let sub = if keep < sub.count {
            thinned = sub.thinned(keep);
            thin = Subsample {
                values: &thinned,
                count: keep,
                n,
            };
            &thin
        } else {
            sub
        };
        let series = sub.count * 3;
        // Which lights reach the scene, judged on radiance in either space.
        let relevance = match space {
            MapSpace::Linear => light_relevance(sub.values, sub.count, n),
            MapSpace::Srgb => {
                let radiance: Vec<f32> = sub
                    .values
                    .iter()
                    .map(|&v| color::srgb_to_linear(v))
                    .collect();
                light_relevance(&radiance, sub.count, n)
            }
        };
        // An analytic basis' perceptual systems summed over every light once, each
        // fold's then the sums less its held-out lights.
        let perceptual = grouped.iter().any(|(o, _)| *o == Objective::Perceptual);
        let full = (perceptual && space == MapSpace::Linear && !largest.needs_samples())
            .then(|| -> Result<FullSums> {
                let basis = largest.build(dirs, None)?;
                Ok(FullSums::new(basis.as_ref(), dirs, q, sub))
            })
            .transpose()?;
        // Folds in parallel too: a fold's basis is built on one thread, and two folds
        // keep both cores of a small machine busy where one fold's blocks would not.
        let fold_results = (0..folds)
            .into_par_iter()
            .map(|fold| {
                fold_result(
                    largest,
                    &sizes,
                    space,
                    &grouped,
                    regularizer,
                    dirs,
                    q,
                    sub,
                    folds,
                    fold,
                    penalties,
                    full.as_ref(),
                )
            })
            .collect::<Result<Vec<_>>>()?;
        for (g, &i) in group.iter().enumerate() {
            for (size, choice) in nested.iter().enumerate() {
                // Squared display errors per captured light (each is held out once) and
                // λ.
                let mut per_light = vec![[0.0f64; SLOTS]; n];
                for (held, errors) in &fold_results {
                    for (&j, e) in held.iter().zip(&errors[g][size]) {
                        per_light[j] = *e;
                    }
                }
                scores[size][i] = Some(score_lights(
                    choice, space, criterion, q, &relevance, &per_light, series,
                )?);
            }
        }
    }
    Ok(scores
        .into_iter()
        .map(|per_objective| {
            per_objective
                .into_iter()
                .map(|s| s.expect("every objective is in a group"))
                .collect()
        })
        .collect())
}

/// The errors of one fold of [`validate`] and each objective: the fold's held-out
/// lights, and per objective and size their errors.
type FoldErrors = (Vec<usize>, Vec<Vec<Vec<[f64; SLOTS]>>>);

/// One fold of [`validate`]: the basis of `choice` (the largest of `sizes`) built
/// once, then each objective's errors at each size.
#[allow(clippy::too_many_arguments)]
fn fold_result(
    choice: &BasisChoice,
    sizes: &[usize],
    space: MapSpace,
    objectives: &[(Objective, Vec<Range<usize>>)],
    regularizer: Regularizer,
    dirs: &[Vec3],
    q: &[f64],
    sub: &Subsample,
    folds: usize,
    fold: usize,
    penalties: &Penalties,
    full: Option<&FullSums>,
) -> Result<FoldErrors> {
    let n = sub.n;
    let series = sub.count * 3;
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
    let held_dirs: Vec<Vec3> = held.iter().map(|&j| dirs[j]).collect();
    let q_train: Vec<f64> = train.iter().map(|&j| q[j]).collect();
    let penalty = penalties.of(basis.as_ref(), regularizer, choice.needs_samples());
    let lights = FoldLights {
        train: &train,
        held: &held,
        train_dirs: &train_dirs,
        held_dirs: &held_dirs,
        q_train: &q_train,
        q,
    };
    // The sums over every light serve this fold where its basis is theirs (an analytic
    // basis built on the fold's lights is the one built on all of them, save where the
    // fold's lights change its domain).
    let full = full.filter(|f| f.spec == basis.spec());
    let errors = objectives
        .iter()
        .map(|(objective, ladder)| {
            fold_errors(
                basis.as_ref(),
                sizes,
                space,
                *objective,
                ladder,
                &penalty,
                &lights,
                &values,
                sub,
                full,
            )
        })
        .collect();
    Ok((held, errors))
}

/// One fold's lights: those it trains on and those it holds out, with their directions
/// and quadrature weights.
#[derive(Clone, Copy)]
struct FoldLights<'a> {
    train: &'a [usize],
    held: &'a [usize],
    train_dirs: &'a [Vec3],
    held_dirs: &'a [Vec3],
    /// The training lights' quadrature weights.
    q_train: &'a [f64],
    /// Every captured light's.
    q: &'a [f64],
}

/// A perceptual validation's normal equations over every captured light, per lane group
/// of the subsample's pixels, for an analytic basis: the same basis in every fold, so a
/// fold's own are these less its held-out lights' terms (the held-out tenth summed
/// instead of the training nine tenths).
pub(super) struct FullSums {
    /// The basis they were summed for: a fold whose basis differs sums its own.
    spec: BasisSpec,
    groups: Vec<GroupSums>,
}

/// [`FullSums`] of one lane group of pixels.
struct GroupSums {
    /// The weighted outer products' sums (packed upper triangle, tiled).
    sums: Vec<Lanes>,
    /// Each channel's weighted observations times the rows (tiled).
    rhs: [Vec<Lanes>; 3],
    /// The weights' sums.
    total: Lanes,
}

impl GroupSums {
    fn zeros(t_cols: usize, k_cols: usize) -> GroupSums {
        GroupSums {
            sums: vec![[0.0; LANES]; t_cols],
            rhs: std::array::from_fn(|_| vec![[0.0; LANES]; k_cols]),
            total: [0.0; LANES],
        }
    }

    /// The sums over `lights` of the `used` pixels from `first`, weighted by `weights`
    /// (pixel-major, `lights.len()` a pixel): `tables` are the lights' outer products
    /// ([`outer_table`]) and rows ([`padded_columns`]); `lanes` and `weighted` are
    /// scratch of `lights.len()`. Lanes past `used` sum nothing. Each lane's sums run
    /// over its lights in order.
    #[allow(clippy::too_many_arguments)]
    fn sum(
        &mut self,
        sub: &Subsample,
        first: usize,
        used: usize,
        lights: &[usize],
        weights: &[f64],
        (outer, rows): (&[f64], &[f64]),
        lanes: &mut [Lanes],
        weighted: &mut [Lanes],
    ) {
        let (n, nl) = (sub.n, lights.len());
        series_lanes(lanes, 0, used, |x| weights[x]);
        self.total = std::array::from_fn(|l| {
            if l < used {
                weights[l * nl..(l + 1) * nl].iter().sum()
            } else {
                0.0
            }
        });
        linalg::lane_products_f64(lanes, outer, self.sums.len(), &mut self.sums);
        // Each channel's right-hand sides, every lane at once: the weighted observations
        // times the lights' rows.
        for (c, rhs) in self.rhs.iter_mut().enumerate() {
            for ((wv, w), &light) in weighted.iter_mut().zip(&*lanes).zip(lights) {
                *wv = std::array::from_fn(|l| {
                    if l < used {
                        w[l] * sub.values[((first + l) * n + light) * 3 + c] as f64
                    } else {
                        0.0
                    }
                });
            }
            linalg::lane_products_f64(weighted, rows, rhs.len(), rhs);
        }
    }

    /// `whole` less these sums, in place: a fold's sums from the sums over every light
    /// and its held-out lights' (lanes past `used` keep a zero total).
    fn taken_from(&mut self, whole: &GroupSums, used: usize) {
        let minus = |whole: &Lanes, part: &mut Lanes| {
            *part = std::array::from_fn(|l| whole[l] - part[l]);
        };
        for (part, whole) in self.sums.iter_mut().zip(&whole.sums) {
            minus(whole, part);
        }
        for (rhs, whole) in self.rhs.iter_mut().zip(&whole.rhs) {
            for (part, whole) in rhs.iter_mut().zip(whole) {
                minus(whole, part);
            }
        }
        for (t, w) in self.total.iter_mut().zip(&whole.total).take(used) {
            *t = w - *t;
        }
    }
}

impl FullSums {
    /// The sums over every light of `dirs` for `basis` on the pixels of `sub`, weighted
    /// as [`fold_errors`] weighs them ([`mean_channel_weights`]).
    fn new(basis: &dyn Basis, dirs: &[Vec3], q: &[f64], sub: &Subsample) -> FullSums {
        let (n, k) = (sub.n, basis.len());
        let a: Vec<f64> = dirs.iter().flat_map(|d| basis.values(*d)).collect();
        let pairs = super::packed_pairs(k);
        let outer = outer_table(&a, k, &pairs);
        let (t_cols, k_cols) = (linalg::tiled(pairs.len()), linalg::tiled(k));
        let a_tiled = padded_columns(&a, k);
        let every: Vec<usize> = (0..n).collect();
        let groups = (0..sub.count.div_ceil(LANES))
            .into_par_iter()
            .map(|g| {
                let first = g * LANES;
                let used = LANES.min(sub.count - first);
                let weights = mean_channel_weights(sub, first..first + used, &every, q);
                let mut group = GroupSums::zeros(t_cols, k_cols);
                let mut scratch = vec![[0.0; LANES]; 2 * n];
                let (lanes, weighted) = scratch.split_at_mut(n);
                group.sum(
                    sub,
                    first,
                    used,
                    &every,
                    &weights,
                    (&outer, &a_tiled),
                    lanes,
                    weighted,
                );
                group
            })
            .collect();
        FullSums {
            spec: basis.spec(),
            groups,
        }
    }
}

/// The outer products of the rows of `a` (`k` values each), one row of packed pairs
/// per row of `a`, padded with zeros to whole tiles of [`linalg::lane_products_f64`].
fn outer_table(a: &[f64], k: usize, pairs: &[(usize, usize)]) -> Vec<f64> {
    let t_cols = linalg::tiled(pairs.len());
    a.chunks_exact(k.max(1))
        .flat_map(|row| {
            let products = pairs.iter().map(move |&(r, c)| row[r] * row[c]);
            products.chain(std::iter::repeat_n(0.0, t_cols - pairs.len()))
        })
        .collect()
}

/// The perceptual validation's weight of each of `lights` for each pixel of `pixels`
/// (pixel-major): the mean over the pixel's channels of `q_j · s(v)²` at the
/// observation (as the fit's first pass weighs them), the block's encodings a batch at
/// a time.
fn mean_channel_weights(
    sub: &Subsample,
    pixels: Range<usize>,
    lights: &[usize],
    q: &[f64],
) -> Vec<f64> {
    let (n, nl) = (sub.n, lights.len());
    // Pixel, channel, light.
    let values: Vec<f64> = pixels
        .flat_map(|p| {
            (0..3).flat_map(move |c| {
                lights
                    .iter()
                    .map(move |&j| sub.values[(p * n + j) * 3 + c] as f64)
            })
        })
        .collect();
    let mut encoded = vec![0.0; values.len()];
    color::linear_to_srgb_tabulated_batch(&values, &mut encoded);
    let each: Vec<f64> = values
        .iter()
        .zip(&encoded)
        .zip(lights.iter().cycle())
        .map(|((&v, &e), &j)| q[j] * perceptual_weight_encoded(v, e))
        .collect();
    each.chunks_exact(3 * nl)
        .flat_map(|p| {
            let (r, rest) = p.split_at(nl);
            let (g, b) = rest.split_at(nl);
            r.iter().zip(g).zip(b).map(|((r, g), b)| (r + g + b) / 3.0)
        })
        .collect()
}

/// The score of a candidate from its errors per held-out light.
fn score_lights(
    choice: &BasisChoice,
    space: MapSpace,
    criterion: Criterion,
    q: &[f64],
    relevance: &[f64],
    per_light: &[[f64; SLOTS]],
    series: usize,
) -> Result<CandidateScore> {
    let n = per_light.len();
    // The mean over lights of each light's PSNR, as the peer protocol averages its
    // hold-outs (a pooled error would let the few worst lights decide); lights that do
    // not reach the scene do not count.
    let weights: Vec<f64> = (0..n).map(|j| q[j] * relevance[j]).collect();
    let total: f64 = weights.iter().sum::<f64>().max(1e-300);
    let judged = match criterion {
        Criterion::Display => 0,
        Criterion::Linear => LINEAR,
    };
    // A light's PSNR when held out, at ladder step `li`.
    let light_psnr =
        |e: &[f64; SLOTS], li: usize| crate::metrics::psnr(e[judged + li] / series as f64, 1.0);
    let score = |li: usize| -> (f64, f64, f64) {
        let (mut psnr, mut pooled, mut pred, mut obs) = (0.0, 0.0, 0.0, 0.0);
        for (e, &w) in per_light.iter().zip(&weights) {
            let mse = e[li] / series as f64;
            psnr += w * light_psnr(e, li);
            pooled += w * mse;
            pred += w * e[LADDER + li];
            obs += w * e[2 * LADDER];
        }
        (
            psnr / total,
            (pooled / total).sqrt(),
            pred / obs.max(1e-300),
        )
    };
    // The best λ among those that keep the scene's brightness (any, if none does).
    let scored: Vec<(usize, (f64, f64, f64))> = (0..LADDER)
        .map(|li| (li, score(li)))
        .filter(|(_, (p, _, _))| p.is_finite())
        .collect();
    let unbiased = brightness_kept;
    let any_unbiased = scored.iter().any(|(_, (_, _, b))| unbiased(*b));
    let (best, (psnr, rmse, bias)) = scored
        .into_iter()
        .filter(|(_, (_, _, b))| !any_unbiased || unbiased(*b))
        .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        .unwrap_or((0, (f64::NEG_INFINITY, f64::INFINITY, f64::INFINITY)));
    let lights = per_light
        .iter()
        .zip(&weights)
        .map(|(e, &w)| {
            let p = light_psnr(e, best);
            (w, if p.is_nan() { 0.0 } else { p.min(100.0) })
        })
        .collect();
    Ok(CandidateScore {
        basis: choice.name(),
        lambda: VALIDATION_LADDER[best],
        display_rmse: rmse,
        criterion,
        space,
        psnr,
        mean_bias: bias,
        pixels: series / 3,
        lights,
    })
}

/// Factor `m + λ·total·P` (plus the definiteness term), `k×k`, of each of the first
/// `used` lanes into `f`; unused lanes factor the identity. Per lane, how many leading
/// pivots were positive (`k`: positive definite).
fn factor_lanes(
    f: &mut [Lanes],
    m: &[Lanes],
    penalty: &[f64],
    total: Lanes,
    lambda: f64,
    k: usize,
    used: usize,
) -> [usize; LANES] {
    // The lower triangle only: all that the factorisation and the solve read. The
    // products are those of `total·λ·P + total·DEFINITENESS`, in that order.
    let scaled: Lanes = std::array::from_fn(|l| total[l] * lambda);
    let definiteness: Lanes = std::array::from_fn(|l| total[l] * super::DEFINITENESS);
    for r in 0..k {
        for c in 0..=r {
            let x = r * k + c;
            let dst = &mut f[x];
            *dst = linalg::plus_scaled(&m[x], &scaled, penalty[x]);
            if r == c {
                for l in 0..LANES {
                    dst[l] += definiteness[l];
                }
            }
            if used < LANES {
                dst[used..].fill(if r == c { 1.0 } else { 0.0 });
            }
        }
    }
    linalg::cholesky_lanes_pivots(f, k)
}

/// Summed squared display errors over the subsample at each held-out light, per λ of
/// its ladder, for each of `sizes` (ascending, the last `basis.len()`): the basis'
/// first functions of that many, solved with the leading block of its systems'
/// factors. A size with an empty ladder is not judged.
#[allow(clippy::too_many_arguments)]
fn fold_errors(
    basis: &dyn Basis,
    sizes: &[usize],
    space: MapSpace,
    objective: Objective,
    ladders: &[Range<usize>],
    penalty: &[f64],
    lights: &FoldLights,
    train_values: &[f32],
    sub: &Subsample,
    full: Option<&FullSums>,
) -> Vec<Vec<[f64; SLOTS]>> {
    let FoldLights {
        train,
        held,
        train_dirs,
        held_dirs,
        q_train,
        q,
    } = *lights;
    // Perceptual systems downdated from the sums over every light: the held-out lights'
    // terms taken away rather than the training lights' added up (a tenth of the work).
    let full = full.filter(|_| objective == Objective::Perceptual);
    let k = basis.len();
    debug_assert!(sizes.last() == Some(&k) && sizes.windows(2).all(|w| w[0] < w[1]));
    debug_assert_eq!(ladders.len(), sizes.len());
    // Every λ some size is judged at (the ladders come in the pairs the solves take).
    let judged = ladders.iter().filter(|l| !l.is_empty());
    let span = judged.clone().map(|l| l.start).min().unwrap_or(0)
        ..judged.clone().map(|l| l.end).max().unwrap_or(0);
    debug_assert!(ladders
        .iter()
        .all(|l| l.is_empty() || (l.start.is_multiple_of(2) && l.end.is_multiple_of(2))));
    let nt = train_dirs.len();
    let a_train: Vec<f64> = train_dirs.iter().flat_map(|d| basis.values(*d)).collect();
    let a_held: Vec<f64> = held_dirs.iter().flat_map(|d| basis.values(*d)).collect();
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
    // The factor and how many of its leading pivots were positive.
    let factor = |m: &[f64], total: f64, lambda: f64| -> (Vec<f64>, usize) {
        let mut f = m.to_vec();
        for (v, &p) in f.iter_mut().zip(penalty) {
            *v += total * lambda * p;
        }
        (0..k).for_each(|i| f[i * k + i] += total * super::DEFINITENESS);
        let pivots = linalg::cholesky_pivots(&mut f, k);
        (f, pivots)
    };
    // The linear objective shares one matrix across pixels, so each λ's held-out
    // predictions are one linear map of a series' training values: the operator
    // `A_held (AᵀQA + λ·total·P)⁻¹ AᵀQ` (held × train), applied to a block of series
    // by one matrix product instead of a solve per series. Per λ, per size judged at
    // that λ: the operator, or none where the system was not positive definite.
    type Operators = Vec<Option<Option<Vec<f64>>>>;
    let shared: Option<Vec<Operators>> = (objective == Objective::Linear).then(|| {
        let (m, total) = normal(q_train);
        (0..LADDER)
            .map(|li| {
                if !ladders.iter().any(|l| l.contains(&li)) {
                    return vec![None; sizes.len()];
                }
                let (f, pivots) = factor(&m, total, VALIDATION_LADDER[li]);
                sizes
                    .iter()
                    .zip(ladders)
                    .map(|(&size, own)| {
                        own.contains(&li).then(|| {
                            (size <= pivots).then(|| {
                                padded_columns(
                                    &prediction_operator(&f, size, &a_train, &a_held, q_train, k),
                                    held_dirs.len(),
                                )
                            })
                        })
                    })
                    .collect()
            })
            .collect()
    });
    let series = sub.count * 3;
    let lights = held.len();
    // The perceptual objective's normal matrices, a lane group of series at a time:
    // the weights (lanes × N) times the table of the rows' outer products (N × packed
    // upper triangle, padded to whole tiles) by `linalg::lane_products_f64`.
    let pairs = super::packed_pairs(k);
    let t_cols = linalg::tiled(pairs.len());
    // The lights whose terms the perceptual systems sum: the training lights, or the
    // held-out ones taken away from the sums over every light.
    let (summed, a_summed) = match full {
        Some(_) => (held, &a_held),
        None => (train, &a_train),
    };
    let outer = if shared.is_none() {
        outer_table(a_summed, k, &pairs)
    } else {
        Vec::new()
    };
    let k_cols = linalg::tiled(k);
    let a_summed_tiled = if shared.is_none() {
        padded_columns(a_summed, k)
    } else {
        Vec::new()
    };
    // The perceptual objective's blocks hold whole pixels (their channels share a
    // normal matrix).
    let block_series = if shared.is_some() {
        SERIES_BLOCK
    } else {
        3 * PIXEL_BLOCK
    };
    (0..series.div_ceil(block_series))
        .into_par_iter()
        .map(|block| {
            let mut acc = vec![vec![[0.0f64; SLOTS]; lights]; sizes.len()];
            let first = block * block_series;
            let len = block_series.min(series - first);
            // The held-out observations and how a screen shows them, per series of the
            // block and held-out light, the same at every λ.
            let held_obs: Vec<(f64, f64)> = (first..first + len)
                .flat_map(|s| {
                    let (p, c) = (s / 3, s % 3);
                    held.iter().map(move |&j| {
                        let v = sub.values[(p * sub.n + j) * 3 + c];
                        match space {
                            MapSpace::Linear => (v as f64, srgb_on_screen(v as f64)),
                            MapSpace::Srgb => (color::srgb_to_linear_tabulated(v) as f64, v as f64),
                        }
                    })
                })
                .collect();
            let mut shown = vec![0.0; len * lights];
            // Tally the predictions of series `rows` (of the block) at λ `li` of a ladder
            // that starts at `first_li`, each as a screen shows it; series whose system
            // was not positive definite score an infinite error.
            let tally = |acc: &mut [[f64; SLOTS]],
                         li: usize,
                         first_li: usize,
                         rows: Range<usize>,
                         preds: &mut [f64],
                         shown: &mut [f64],
                         ok: &[bool]| {
                let used = rows.len();
                let (preds, shown) = (&mut preds[..used * lights], &mut shown[..used * lights]);
                match space {
                    MapSpace::Linear => color::linear_to_srgb_tabulated_batch(preds, shown),
                    // Display values are shown as they are; the linear error and the
                    // brightness judge their decoding.
                    MapSpace::Srgb => {
                        for (s, p) in shown.iter_mut().zip(preds.iter()) {
                            *s = p.clamp(0.0, 1.0);
                        }
                        color::srgb_to_linear_tabulated_batch(shown, preds);
                    }
                }
                for (l, b) in rows.enumerate() {
                    if !ok[l] {
                        acc.iter_mut().for_each(|a| a[li] = f64::INFINITY);
                        continue;
                    }
                    for (h, a) in acc.iter_mut().enumerate() {
                        let (o, o_shown) = held_obs[b * lights + h];
                        let pred = preds[l * lights + h];
                        let d = shown[l * lights + h] - o_shown;
                        a[li] += d * d;
                        let d = pred - o;
                        a[LINEAR + li] += d * d;
                        a[LADDER + li] += pred;
                        if li == first_li {
                            a[2 * LADDER] += o;
                        }
                    }
                }
            };
            if let Some(operators) = &shared {
                // The block's series in lane groups, light by light: each group's
                // predictions are its lanes times an operator (`linalg::lane_products_f64`,
                // the sums in the order of a matrix product's).
                let groups: Vec<Vec<Lanes>> = (0..len)
                    .step_by(LANES)
                    .map(|g| {
                        let mut lanes = vec![[0.0; LANES]; nt];
                        series_lanes(&mut lanes, g, LANES.min(len - g), |x| {
                            train_values[first * nt + x] as f64
                        });
                        lanes
                    })
                    .collect();
                let cols = linalg::tiled(lights);
                let mut preds = vec![0.0; len * lights];
                let mut out = vec![[0.0; LANES]; cols];
                for li in span.clone() {
                    for ((acc, operator), own) in acc.iter_mut().zip(&operators[li]).zip(ladders) {
                        let Some(operator) = operator else {
                            continue;
                        };
                        let ok = vec![operator.is_some(); len];
                        if let Some(g) = operator {
                            for (group, lanes) in groups.iter().enumerate() {
                                linalg::lane_products_f64(lanes, g, cols, &mut out);
                                let used = LANES.min(len - group * LANES);
                                let rows = &mut preds[group * LANES * lights..][..used * lights];
                                for (l, row) in rows.chunks_exact_mut(lights).enumerate() {
                                    for (p, o) in row.iter_mut().zip(&out) {
                                        *p = o[l];
                                    }
                                }
                            }
                        }
                        tally(acc, li, own.start, 0..len, &mut preds, &mut shown, &ok);
                    }
                }
                return acc;
            }
            // The perceptual objective, a pixel per lane: a pixel's three channels share
            // one normal matrix, weighted by the mean of their observations' perceptual
            // weights (as the fit's first pass weighs them), so that one factorisation
            // per λ serves all three. Judging each channel by its own weights cost three
            // factorisations a pixel and chose the same on the eight RealRTI items'
            // hold-out fits (26.23 against 26.40 dB on item5, the rest equal:
            // scripts/realrti_table.py, 2026-12-07).
            debug_assert!(first.is_multiple_of(3) && len.is_multiple_of(3));
            let pixels = len / 3;
            let pixel0 = first / 3;
            let ns = summed.len();
            let weights = mean_channel_weights(sub, pixel0..pixel0 + pixels, summed, q);
            let mut group = GroupSums::zeros(t_cols, k_cols);
            let mut scratch = vec![[0.0; LANES]; 2 * ns];
            let (weight_lanes, weighted) = scratch.split_at_mut(ns);
            let mut m = vec![[0.0; LANES]; k * k];
            let mut f = vec![[0.0; LANES]; k * k];
            let mut f2 = vec![[0.0; LANES]; k * k];
            let mut coef = vec![[0.0; LANES]; k];
            let mut coef2 = vec![[0.0; LANES]; k];
            let mut ok = vec![false; 3 * LANES];
            let mut pair_preds = [vec![0.0; 3 * LANES * lights], vec![0.0; 3 * LANES * lights]];
            for g in (0..pixels).step_by(LANES) {
                let used = LANES.min(pixels - g);
                group.sum(
                    sub,
                    pixel0 + g,
                    used,
                    summed,
                    &weights[g * ns..],
                    (&outer, &a_summed_tiled),
                    weight_lanes,
                    weighted,
                );
                if let Some(full) = full {
                    group.taken_from(&full.groups[(pixel0 + g) / LANES], used);
                }
                let (total, rhs) = (group.total, &group.rhs);
                for (&(r, col), sum) in pairs.iter().zip(&group.sums) {
                    m[col * k + r] = *sum;
                }
                // The block's series of these pixels, in order.
                let rows = 3 * g..3 * (g + used);
                // λ two at a time: their solves run side by side
                // (`linalg::cholesky_solve_lanes_pair`), each as it would alone; each
                // size with its leading block of the factors.
                for pair in span.clone().step_by(2) {
                    if !ladders.iter().any(|l| l.contains(&pair)) {
                        continue;
                    }
                    let lis = [pair, pair + 1];
                    let pivots = [
                        factor_lanes(&mut f, &m, penalty, total, VALIDATION_LADDER[pair], k, used),
                        factor_lanes(
                            &mut f2,
                            &m,
                            penalty,
                            total,
                            VALIDATION_LADDER[pair + 1],
                            k,
                            used,
                        ),
                    ];
                    for ((acc, &size), own) in acc.iter_mut().zip(sizes).zip(ladders) {
                        if !own.contains(&pair) {
                            continue;
                        }
                        // Per λ of the pair, the predictions of `rows` at the held-out
                        // lights (series `3·pixel + channel`).
                        for (c, rhs) in rhs.iter().enumerate() {
                            let (coef, coef2) = (&mut coef[..size], &mut coef2[..size]);
                            coef.copy_from_slice(&rhs[..size]);
                            coef2.copy_from_slice(&rhs[..size]);
                            linalg::cholesky_solve_lanes_pair(&f, &f2, size, k, coef, coef2);
                            for (slot, coef) in [&*coef, &*coef2].into_iter().enumerate() {
                                let out = &mut pair_preds[slot];
                                for h in 0..lights {
                                    let mut pred = [0.0; LANES];
                                    for (&a, c) in a_held[h * k..h * k + size].iter().zip(coef) {
                                        for l in 0..LANES {
                                            pred[l] += a * c[l];
                                        }
                                    }
                                    for (l, &p) in pred.iter().enumerate().take(used) {
                                        out[(3 * l + c) * lights + h] = p;
                                    }
                                }
                            }
                        }
                        for (slot, &li) in lis.iter().enumerate() {
                            for (l, &p) in pivots[slot].iter().enumerate().take(used) {
                                ok[3 * l..3 * l + 3].fill(p >= size);
                            }
                            let preds = &mut pair_preds[slot];
                            tally(acc, li, own.start, rows.clone(), preds, &mut shown, &ok);
                        }
                    }
                }
            }
            acc
        })
        .collect::<Vec<_>>()
        .into_iter()
        // Summed in block order: the same scores on every run and every shard (a
        // parallel reduction's order follows the work stealing).
        .fold(vec![vec![[0.0; SLOTS]; lights]; sizes.len()], |mut a, b| {
            for (x, y) in a.iter_mut().flatten().zip(b.into_iter().flatten()) {
                x.iter_mut().zip(y).for_each(|(x, y)| *x += y);
            }
            a
        })
        .into_iter()
        .zip(ladders)
        .map(|(per_light, ladder)| {
            per_light
                .into_iter()
                // λ left out of the ladder score nothing (an infinite error).
                .map(|mut e| {
                    for li in (0..LADDER).filter(|li| !ladder.contains(li)) {
                        e[li] = f64::INFINITY;
                        e[LINEAR + li] = f64::INFINITY;
                    }
                    e
                })
                .collect()
        })
        .collect()
}

/// The held-out predictions of the shared linear fit as a map of a series' training
/// values, transposed (`train × held`): `(A_held F⁻¹ AᵀQ)ᵀ` for the Cholesky factor `f`
/// of the regularised normal matrix (`k×k`), training rows `a_train` (`train × k`) and
/// held-out rows `a_held` (`held × k`), all restricted to the first `size` functions
/// (the factor's leading block).
fn prediction_operator(
    f: &[f64],
    size: usize,
    a_train: &[f64],
    a_held: &[f64],
    q_train: &[f64],
    k: usize,
) -> Vec<f64> {
    let (nt, lights) = (q_train.len(), a_held.len() / k.max(1));
    let mut operator = vec![0.0; nt * lights];
    let mut column = vec![0.0; size];
    for (j, &q) in q_train.iter().enumerate() {
        column
            .iter_mut()
            .zip(&a_train[j * k..j * k + size])
            .for_each(|(c, &a)| *c = q * a);
        linalg::cholesky_solve_leading(f, size, k, &mut column);
        for h in 0..lights {
            operator[j * lights + h] = a_held[h * k..h * k + size]
                .iter()
                .zip(&column)
                .map(|(a, c)| a * c)
                .sum();
        }
    }
    operator
}

/// Series `g..g + used` of a block (series-major, `lights` values each, read by
/// `value(series·lights + light)`) as lanes, light by light; lanes past `used` are zero.
fn series_lanes(dst: &mut [Lanes], g: usize, used: usize, value: impl Fn(usize) -> f64) {
    let lights = dst.len();
    for (j, lanes) in dst.iter_mut().enumerate() {
        for (l, v) in lanes.iter_mut().enumerate() {
            *v = if l < used {
                value((g + l) * lights + j)
            } else {
                0.0
            };
        }
    }
}

/// A row-major matrix of `columns` columns with each row padded with zeros to whole
/// tiles of [`linalg::lane_products_f64`].
fn padded_columns(matrix: &[f64], columns: usize) -> Vec<f64> {
    let cols = linalg::tiled(columns);
    matrix
        .chunks_exact(columns.max(1))
        .flat_map(|row| {
            row.iter()
                .copied()
                .chain(std::iter::repeat_n(0.0, cols - columns))
        })
        .collect()
}

/// The whole λ ladder.
pub(super) const WHOLE_LADDER: Range<usize> = 0..LADDER;

/// The part of the ladder a finalist is validated on, after a screening that found the
/// λ at `best` (an index of [`VALIDATION_LADDER`]): four steps around it, in the pairs
/// the validation solves together, so that `best` and both its neighbours are in.
pub(super) fn ladder_around(best: usize) -> Range<usize> {
    let start = best.saturating_sub(if best.is_multiple_of(2) { 2 } else { 1 });
    let start = start.min(LADDER - 4);
    start..start + 4
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_finalists_ladder_holds_the_screenings_lambda_and_both_neighbours() {
        for best in 0..LADDER {
            let ladder = ladder_around(best);
            assert_eq!(ladder.len(), 4, "λ {best}");
            assert!(
                ladder.end <= LADDER && ladder.start.is_multiple_of(2),
                "λ {best}: {ladder:?}"
            );
            for li in best.saturating_sub(1)..(best + 2).min(LADDER) {
                assert!(ladder.contains(&li), "λ {best}: {ladder:?} lacks {li}");
            }
        }
    }

    /// The perceptual objective's errors in one fold, against a scalar computation of what
    /// they are meant to be: per pixel, the lights weighted by the mean over its channels
    /// of each observation's perceptual weight (times the quadrature), one regularised
    /// system `Σ w aaᵀ + total·(λP + DEFINITENESS·I)` solved for each channel, every
    /// channel predicted at the held-out lights and its squared display error summed.
    #[test]
    fn a_perceptual_fold_solves_each_pixel_once_under_its_channels_mean_weights() {
        let dirs = crate::sphere::hemisphere_fibonacci(30);
        let n = dirs.len();
        // Coloured pixels (channels with different weights), some dark, some over white,
        // and a count that leaves the last lane group part empty.
        let count = 29;
        let values: Vec<f32> = (0..count)
            .flat_map(|p| {
                let dirs = &dirs;
                (0..n).flat_map(move |j| {
                    let d = dirs[j];
                    (0..3).map(move |c| {
                        let albedo = [0.9, 0.25, 0.04][(p + c) % 3] * (1.0 + 0.05 * p as f64);
                        let shine = d.dot(Vec3::new(0.3, 0.1, 0.95).normalized().unwrap());
                        (albedo * d.z.max(0.0) + 0.4 * shine.max(0.0).powi(20)) as f32
                    })
                })
            })
            .collect();
        let q: Vec<f64> = (0..n).map(|j| 0.5 + (j % 4) as f64 / 4.0).collect();
        let sub = Subsample {
            values: &values,
            count,
            n,
        };
        let choice = BasisChoice::parse("sh:9").unwrap();
        let (folds, fold) = (5, 2);
        let ladder = 2..4;
        // The fold's systems summed from its training lights, and taken from the sums
        // over every light less its held-out ones.
        let full = FullSums::new(choice.build(&dirs, None).unwrap().as_ref(), &dirs, &q, &sub);
        let train_dirs: Vec<Vec3> = (0..n)
            .filter(|j| j % folds != fold)
            .map(|j| dirs[j])
            .collect();
        assert!(full.spec == choice.build(&train_dirs, None).unwrap().spec());
        for full in [None, Some(&full)] {
            let (held, errors) = fold_result(
                &choice,
                &[9],
                MapSpace::Linear,
                &[(Objective::Perceptual, vec![ladder.clone()])],
                Regularizer::Roughness,
                &dirs,
                &q,
                &sub,
                folds,
                fold,
                &Penalties::default(),
                full,
            )
            .unwrap();
            let got = &errors[0][0];
            let train: Vec<usize> = (0..n).filter(|j| j % folds != fold).collect();
            let train_dirs: Vec<Vec3> = train.iter().map(|&j| dirs[j]).collect();
            let basis = choice.build(&train_dirs, None).unwrap();
            let k = basis.len();
            let penalty = Regularizer::Roughness.matrix(basis.as_ref());
            let encode = |v: f64| color::linear_to_srgb_tabulated(v as f32) as f64;
            for li in ladder.clone() {
                let lambda = VALIDATION_LADDER[li];
                let mut want = vec![0.0; held.len()];
                for p in 0..count {
                    let v = |j: usize, c: usize| values[(p * n + j) * 3 + c] as f64;
                    let w: Vec<f64> = train
                        .iter()
                        .map(|&j| {
                            let each = |c: usize| {
                                q[j] * perceptual_weight_encoded(v(j, c), encode(v(j, c)))
                            };
                            (each(0) + each(1) + each(2)) / 3.0
                        })
                        .collect();
                    let total: f64 = w.iter().sum();
                    let mut m = vec![0.0; k * k];
                    for (t, &j) in train.iter().enumerate() {
                        let a = basis.values(dirs[j]);
                        for r in 0..k {
                            for c in 0..k {
                                m[r * k + c] += w[t] * a[r] * a[c];
                            }
                        }
                    }
                    for (x, pen) in m.iter_mut().zip(&penalty) {
                        *x += total * lambda * pen;
                    }
                    (0..k).for_each(|i| m[i * k + i] += total * super::super::DEFINITENESS);
                    assert!(linalg::cholesky(&mut m, k));
                    for c in 0..3 {
                        let mut coef = vec![0.0; k];
                        for (t, &j) in train.iter().enumerate() {
                            for (x, a) in coef.iter_mut().zip(basis.values(dirs[j])) {
                                *x += w[t] * v(j, c) * a;
                            }
                        }
                        linalg::cholesky_solve(&m, k, &mut coef);
                        for (h, &j) in held.iter().enumerate() {
                            let pred: f64 = basis
                                .values(dirs[j])
                                .iter()
                                .zip(&coef)
                                .map(|(a, c)| a * c)
                                .sum();
                            let d = srgb_on_screen(pred) - srgb_on_screen(v(j, c));
                            want[h] += d * d;
                        }
                    }
                }
                for (h, want) in want.iter().enumerate() {
                    let err = got[h][li];
                    assert!(
                        (err - want).abs() <= 1e-9 * want.max(1e-12),
                        "λ {lambda}, held-out light {h}: {err} against {want}"
                    );
                }
            }
        }
    }

    /// A nested family's sizes judged together score exactly as each judged alone,
    /// under both objectives, in both spaces, for an analytic and a data-driven family.
    #[test]
    fn nested_sizes_judged_together_score_as_each_alone() {
        let dirs = crate::sphere::hemisphere_fibonacci(48);
        let n = dirs.len();
        let count = 40;
        // Pixels of a diffuse term and a glossy lobe that moves from pixel to pixel.
        let values: Vec<f32> = (0..count)
            .flat_map(|p| {
                let lobe = Vec3::new(0.1 * (p % 5) as f64, 0.15 * (p % 3) as f64, 0.9)
                    .normalized()
                    .unwrap();
                let dirs = &dirs;
                (0..n).flat_map(move |j| {
                    let d = dirs[j];
                    (0..3).map(move |c| {
                        let shine = d.dot(lobe).max(0.0).powi(12 + 4 * c);
                        (0.05 + 0.3 * d.z.max(0.0) * (1.0 + 0.1 * c as f64) + 0.6 * shine) as f32
                    })
                })
            })
            .collect();
        let q = vec![1.0 / n as f64; n];
        let sub = Subsample {
            values: &values,
            count,
            n,
        };
        for family in ["sh", "rbf"] {
            let nested: Vec<BasisChoice> = [4, 9, 16]
                .iter()
                .map(|k| BasisChoice::parse(&format!("{family}:{k}")).unwrap())
                .collect();
            for (space, objectives) in [
                (
                    MapSpace::Linear,
                    vec![Objective::Perceptual, Objective::Linear],
                ),
                (MapSpace::Srgb, vec![Objective::Linear]),
            ] {
                let judge_at = |choices: &[BasisChoice], ladders: &[Vec<Range<usize>>]| {
                    validate(
                        choices,
                        space,
                        &objectives,
                        Regularizer::Roughness,
                        Criterion::Display,
                        &dirs,
                        &q,
                        &sub,
                        folds(n),
                        ladders,
                        &Penalties::default(),
                    )
                    .unwrap()
                };
                let judge = |choices: &[BasisChoice]| {
                    judge_at(
                        choices,
                        &vec![vec![WHOLE_LADDER; choices.len()]; objectives.len()],
                    )
                };
                let together = judge(&nested);
                assert_eq!(together.len(), nested.len());
                for (choice, scores) in nested.iter().zip(&together) {
                    let alone = judge(std::slice::from_ref(choice)).remove(0);
                    assert_eq!(&alone, scores, "{} in {space:?}", choice.name());
                    assert!(scores.iter().all(|s| s.psnr.is_finite() && s.psnr > 10.0));
                }
                // The sizes differ: each was solved with its own functions.
                assert_ne!(together[0][0].psnr, together[2][0].psnr);
                // Each size at its own part of the ladder (a finalist's), one not judged.
                let own = [0..4, 0..0, 2..6];
                let ladders: Vec<Vec<Range<usize>>> =
                    objectives.iter().map(|_| own.to_vec()).collect();
                let together = judge_at(&nested, &ladders);
                for (c, choice) in nested.iter().enumerate().filter(|(c, _)| *c != 1) {
                    let alone_ladders: Vec<Vec<Range<usize>>> =
                        objectives.iter().map(|_| vec![own[c].clone()]).collect();
                    let alone = judge_at(std::slice::from_ref(choice), &alone_ladders).remove(0);
                    assert_eq!(alone, together[c], "{} at {:?}", choice.name(), own[c]);
                    let lambdas = &VALIDATION_LADDER[own[c].clone()];
                    assert!(alone.iter().all(|s| lambdas.contains(&s.lambda)));
                }
            }
        }
    }
}
