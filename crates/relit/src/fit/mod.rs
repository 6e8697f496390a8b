//! Fitting: from a capture to coefficient maps, by streaming regularised least squares.
//!
//! For every pixel and colour channel the fit finds coefficients `c` minimising
//!
//! ```text
//!   Σ_j w_j (B(L_j)·c − I_j)²  +  λ · (Σ_j w_j) · cᵀ P c
//! ```
//!
//! over the reference images `j`, where `B(L_j)` are the basis values at image `j`'s
//! light vector, `P` is the basis' smoothness penalty ([`Basis::penalty`]: for SH the
//! mean squared gradient over the sphere, which leaves the constant term free) and the
//! sample weights `w_j` depend on the [`Objective`]:
//!
//! * [`Objective::Linear`]: `w_j = q_j`, the quadrature weight of the direction (1,
//!   or the solid angle of its cell when the directions form a full spherical grid).
//!   Every pixel shares one normal matrix, so the images stream through once, one batch
//!   at a time, accumulating `Σ_j q_j B(L_j) I_j` per pixel in the maps' planar layout
//!   (memory: the maps), and one k×k solve turns the sums into coefficients in place —
//!   the precomputed solver `(BᵀQB+λP)⁻¹BᵀQ` applied in two factors.
//! * [`Objective::Perceptual`]: `w_j = q_j · s(v)²` where `s` is the slope
//!   of the sRGB curve at the sample's radiance `v`, so a linear-space residual counts
//!   as much as the display-space error it causes. `v` is the observation first, then
//!   the prediction (iteratively reweighted, [`FitOptions::reweights`] times), which keeps
//!   a highlight the basis cannot follow from dominating the fit. A pixel's three
//!   channels share their weights (the mean over the channels, each channel's secant
//!   weights first normalised over the lights), so one normal matrix serves all three.
//!   Weights differ per pixel, so every pixel gets its own normal equations. The images are first
//!   rebinned into a piece-major spill file on disk (the seed's rebinning); each piece
//!   (a strip of rows, or part of a tile) of all images is then read at once and solved pixel by pixel with
//!   matrix products (`W · vec(B_j B_jᵀ)`) and a Cholesky factorisation per pixel.
//!
//! * [`Objective::Auto`] (default): one of the two, whichever has the smaller
//!   leave-one-out error of the *displayed* values on the λ subsample: sRGB-encoded,
//!   negative radiance shown as black, as a screen shows it. Captured lights that do not
//!   reach the scene at all (images darker than a thousandth of the brightest) do not
//!   count in that error: without that, a full-sphere capture of a scene on a floor,
//!   half of whose images are black, is judged by how black the prediction stays below
//!   the floor, where the sRGB curve is steepest. On photographs the perceptual
//!   objective wins (dark pixels are noisy but never exactly black). On renders with
//!   hard, exactly black shadows it loses: an exactly black sample weighs
//!   `12.92² ≈ 167`, a lit one (0.3) about 0.8, so a band-limited function that cannot
//!   follow the shadow's edge is pulled toward black on the lit side too (the attic at
//!   1000 lights relit about five times too dark, 5–9 dB below the linear fit against
//!   ray-traced truth), and the linear objective wins. The choices are made on the
//!   subsample before the maps are solved. A fit held in memory reads the subsample
//!   first, so that its images' pass keeps only the chosen objective's state (the spill
//!   file on disk, or the shared sums in memory, the size of the maps); a fit streamed
//!   to a file of a JPEG capture reads every image once, into the subsample and a spill
//!   file of the photographs' 8-bit codes, whose values (linear radiance or display
//!   values, whichever space is chosen) are looked up as each piece is read.
//!
//! Maps stored display-referred ([`MapSpace::Srgb`]) fit sRGB-encoded values with
//! plain (quadrature-weighted) least squares.
//!
//! **λ** is chosen automatically unless fixed: on a deterministic subsample of pixels
//! the exact leave-one-out residual `e_j / (1 − h_jj)` of the weighted fit is computed
//! for a ladder of λ values and the smallest weighted error wins. Because the weights
//! are the squared sRGB slopes, that error estimates the display-space error on lights
//! that were not captured — the quantity users see.

mod per_pixel;
mod select;
mod spill;

pub use spill::Piece;

pub use select::{candidates, parse_candidates, CandidateScore, Criterion, VALIDATION_LADDER};

use crate::basis::{Basis, BasisChoice, BasisSpec, Samples};
use crate::capture::Capture;
use crate::color;
use crate::linalg;
use crate::maps::{CoefficientMaps, FitInfo, MapSpace, Metadata, RelightableImage, ShardInfo};
use crate::metrics;
use crate::progress::Progress;
use crate::sphere;
use crate::sphere::Vec3;
use crate::{Error, ErrorKind, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// What the fit minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Objective {
    /// Whichever of the two below predicts left-out images better in display space,
    /// judged per capture by leave-one-out on the λ subsample (the report names the
    /// objective chosen).
    #[default]
    Auto,
    /// Squared residuals weighted by the squared slope of the sRGB curve (display-space error).
    Perceptual,
    /// Plain squared residuals in linear radiance.
    Linear,
}

impl Objective {
    pub fn name(self) -> &'static str {
        match self {
            Objective::Auto => "auto",
            Objective::Perceptual => "perceptual",
            Objective::Linear => "linear",
        }
    }
}

/// The penalty that regularises the fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Regularizer {
    /// The basis' smoothness penalty (SH: mean squared gradient; the constant term is free).
    #[default]
    Roughness,
    /// Plain ridge: every coefficient shrunk equally.
    Ridge,
}

impl Regularizer {
    pub fn name(self) -> &'static str {
        match self {
            Regularizer::Roughness => "roughness",
            Regularizer::Ridge => "ridge",
        }
    }

    /// The `k×k` penalty matrix of `basis` (row-major).
    pub(crate) fn matrix(self, basis: &dyn Basis) -> Vec<f64> {
        match self {
            Regularizer::Roughness => basis.penalty(),
            Regularizer::Ridge => {
                let k = basis.len();
                let mut p = vec![0.0; k * k];
                (0..k).for_each(|i| p[i * k + i] = 1.0 / (4.0 * std::f64::consts::PI));
                p
            }
        }
    }
}

/// How λ is set.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Lambda {
    /// Chosen per capture by leave-one-out on a pixel subsample.
    #[default]
    Auto,
    /// A fixed value (relative to the total sample weight).
    Fixed(f64),
}

/// Multiply-adds the perceptual objective's leave-one-out may spend (its pixels are
/// thinned beyond): a 60-light RTI capture keeps its whole subsample, a capture of
/// thousands of lights judges on a few hundred pixels rather than for minutes.
const PERCEPTUAL_LOO_BUDGET: f64 = 4e9;

/// The ladder of λ values the automatic choice tries.
pub const LAMBDA_LADDER: [f64; 13] = [
    1e-7, 3e-7, 1e-6, 3e-6, 1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1,
];

/// Which basis to fit.
#[derive(Clone, Debug, PartialEq)]
pub enum BasisRequest {
    /// The basis and size of smallest validation error among every family's sizes up
    /// to [`FitOptions::max_coefficients`], chosen per capture on its own lights.
    Auto,
    /// This one.
    Fixed(BasisChoice),
}

impl BasisRequest {
    /// `auto` or a basis name (`sh:25`).
    pub fn parse(s: &str) -> Result<BasisRequest> {
        if s.trim().eq_ignore_ascii_case("auto") {
            Ok(BasisRequest::Auto)
        } else {
            Ok(BasisRequest::Fixed(BasisChoice::parse(s)?))
        }
    }

    /// The name [`BasisRequest::parse`] reads back: `auto`, `sh:25`,
    /// `sg:25:centres=hemisphere,sharpness=8`.
    pub fn name(&self) -> String {
        match self {
            BasisRequest::Auto => "auto".into(),
            BasisRequest::Fixed(choice) if choice.options.is_empty() => choice.name(),
            BasisRequest::Fixed(choice) => {
                let options: Vec<String> = choice
                    .options
                    .iter()
                    .map(|(k, v)| format!("{k}={v}"))
                    .collect();
                format!("{}:{}", choice.name(), options.join(","))
            }
        }
    }
}

/// `auto`: the basis is chosen per capture, like λ and the objective, because no one
/// basis wins everywhere (on the shared RTI items `auto` averages 0.76 dB above `sh:25`,
/// from −0.19 to +4.35 dB per item; docs/bases.md).
impl Default for BasisRequest {
    fn default() -> Self {
        BasisRequest::Auto
    }
}

/// The default `--max-coefficients` of `auto`: on the shared RTI captures (50–70 lights)
/// a budget of 36 chose larger, overfitting bases on three items and lost 0.2 dB on
/// average (docs/bases.md); 25 is also the size relit stored before.
pub const DEFAULT_MAX_COEFFICIENTS: usize = 25;

/// Options of [`fit`].
#[derive(Clone, Debug)]
pub struct FitOptions {
    pub basis: BasisRequest,
    /// The most coefficients per channel `auto` may choose.
    pub max_coefficients: usize,
    /// The candidates `auto` chooses among; empty: every family at the sizes of the
    /// ladder up to `max_coefficients` ([`select::candidates`]).
    pub candidates: Vec<BasisChoice>,
    pub objective: Objective,
    /// The space the maps store; `None`: chosen per capture with the basis — display
    /// values or linear radiance for photographs with the automatic objective (whichever
    /// validates better), linear radiance otherwise.
    pub color_space: Option<MapSpace>,
    pub regularizer: Regularizer,
    pub lambda: Lambda,
    /// Reweighting passes of the perceptual objective after the first solve.
    pub reweights: usize,
    /// Bytes of one piece (strip of rows, or part of a tile) of all images held in
    /// memory by the perceptual fit (and by a linear one streamed to a file), or those
    /// of one task's pixels a thread if more (a piece is the solve's parallel work).
    /// The default, 3 MiB, still holds thousands of pixels at 60 images (enough
    /// parallel work on a few cores): RealRTI item1's fit peaked at 174 MiB with 64 MiB
    /// strips, 82 MiB with 8 MiB ones, in the same time; once the file was streamed
    /// (maps no longer held), item9's peaked at 35.6 MiB with 4 MiB strips and 31.1 with
    /// 3 MiB ones, again in the same time (1.7 s).
    pub piece_bytes: usize,
    /// Pixels in the subsample used to choose λ and estimate the training residual.
    pub subsample: usize,
    /// How many of the subsample's pixels `auto`'s validation screens and judges on.
    pub halving: Halving,
    /// What `auto`'s validation error is measured in; `None`: from the capture
    /// ([`Criterion::for_capture`]: linear for radiance images, display otherwise).
    pub criterion: Option<Criterion>,
    /// Fit only this part of the image's rows (a shard): every choice (basis, objective,
    /// λ) is still made on the whole image's subsample, so each pixel's coefficients
    /// are those of the whole fit (`relit merge` joins the parts).
    pub shard: Option<(usize, usize)>,
    /// Choices made once for the capture ([`plan`]): the fit skips every choice and
    /// fits the plan's basis with its objective and λ (a shard then costs only its rows).
    pub plan: Option<Plan>,
}

/// A capture's choices, made once on the whole capture and reused by every part of a
/// sharded fit: the built basis (tables included), the objective and λ.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// `relit-plan`, so that other JSON is refused by name.
    pub format: String,
    pub version: u32,
    /// The capture the choices were made on: images and size.
    pub images: usize,
    pub width: usize,
    pub height: usize,
    pub basis: BasisSpec,
    pub objective: Objective,
    pub lambda: f64,
    pub color_space: MapSpace,
    pub regularizer: Regularizer,
    pub reweights: usize,
    /// `auto`'s candidates and their validation scores, best first, for the record
    /// (written, not read back: a score may be infinite, which JSON writes as null).
    #[serde(default, skip_deserializing)]
    pub candidates: Vec<CandidateScore>,
}

impl Plan {
    pub const FORMAT: &'static str = "relit-plan";
    pub const VERSION: u32 = 1;

    /// Whether the plan was made for `capture`, or why not.
    fn check(&self, capture: &Capture, options: &FitOptions) -> Result<()> {
        if self.format != Self::FORMAT || self.version != Self::VERSION {
            return Err(Error::invalid(format!(
                "not a relit plan of version {} (format `{}` version {})",
                Self::VERSION,
                self.format,
                self.version
            )));
        }
        if (self.images, self.width, self.height) != (capture.len(), capture.width, capture.height)
        {
            return Err(Error::invalid(format!(
                "the plan was made for {} images of {}×{}, the capture has {} of {}×{}",
                self.images,
                self.width,
                self.height,
                capture.len(),
                capture.width,
                capture.height
            )));
        }
        if options.color_space.is_some_and(|s| s != self.color_space)
            || (self.regularizer, self.reweights) != (options.regularizer, options.reweights)
        {
            return Err(Error::invalid(
                "the plan was made with another colour space, regulariser or reweighting",
            ));
        }
        if !(self.lambda >= 0.0 && self.lambda.is_finite()) || self.objective == Objective::Auto {
            return Err(Error::invalid(
                "the plan's λ must be a non-negative number and its objective linear or perceptual",
            ));
        }
        Ok(())
    }
}

/// Make `capture`'s choices (basis, objective, λ) as [`fit`] makes them, once: what
/// every part of a sharded fit then reuses (`FitOptions::plan`). It fits one row only,
/// so it costs the choices and one pass over the images.
pub fn plan(capture: &Capture, options: &FitOptions, progress: &dyn Progress) -> Result<Plan> {
    let one_row = FitOptions {
        shard: Some((0, capture.height.max(1))),
        plan: None,
        ..options.clone()
    };
    let out = fit(capture, &one_row, progress)?;
    Ok(Plan {
        format: Plan::FORMAT.into(),
        version: Plan::VERSION,
        images: capture.len(),
        width: capture.width,
        height: capture.height,
        basis: out.image.meta.basis,
        objective: out.report.objective,
        lambda: out.report.lambda,
        color_space: out.report.color_space,
        regularizer: options.regularizer,
        reweights: options.reweights,
        candidates: out.report.candidates,
    })
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            basis: BasisRequest::default(),
            max_coefficients: DEFAULT_MAX_COEFFICIENTS,
            candidates: Vec::new(),
            objective: Objective::default(),
            color_space: None,
            regularizer: Regularizer::default(),
            lambda: Lambda::Auto,
            reweights: 1,
            piece_bytes: 3 << 20,
            subsample: 1024,
            halving: Halving::default(),
            criterion: None,
            shard: None,
            plan: None,
        }
    }
}

/// What a fit measured about itself.
#[derive(Clone, Debug, Serialize)]
pub struct FitReport {
    /// The basis fitted, `family:K`.
    pub basis: String,
    /// The objectives `--objective auto` compared by leave-one-out (empty otherwise).
    pub objective_scores: Vec<ObjectiveScore>,
    /// Every candidate basis `auto` validated (or the one fixed data-driven basis whose
    /// λ was validated), best first; empty otherwise.
    pub candidates: Vec<CandidateScore>,
    pub images: usize,
    pub width: usize,
    pub height: usize,
    pub coefficients: usize,
    pub objective: Objective,
    pub color_space: MapSpace,
    pub lambda: f64,
    /// `(λ, leave-one-out weighted MSE)` for each λ tried by the automatic choice.
    pub lambda_scores: Vec<(f64, f64)>,
    pub seconds: f64,
    /// Wall time per stage, in order: where a fit spends its time.
    pub stages: Vec<Stage>,
    pub images_per_second: f64,
    /// Peak resident memory of the process during the fit, if measurable.
    pub peak_rss_bytes: Option<u64>,
    /// Bytes of the on-disk spill file (perceptual objective), 0 otherwise.
    pub spill_bytes: u64,
    pub rmse_linear: [f64; 3],
    pub psnr_srgb8: f64,
}

/// The wall time of one stage of a fit.
#[derive(Clone, Debug, Serialize)]
pub struct Stage {
    pub name: &'static str,
    pub seconds: f64,
}

/// Records the stages of a fit as they end.
struct Stages {
    last: Instant,
    done: Vec<Stage>,
}

impl Stages {
    fn new() -> Stages {
        Stages {
            last: Instant::now(),
            done: Vec::new(),
        }
    }

    /// The stage `name` ends now.
    fn end(&mut self, name: &'static str) {
        let now = Instant::now();
        self.done.push(Stage {
            name,
            seconds: (now - self.last).as_secs_f64(),
        });
        self.last = now;
    }
}

/// One objective as the automatic choice judged it, at its λ.
#[derive(Clone, Debug, Serialize)]
pub struct ObjectiveScore {
    pub objective: Objective,
    pub lambda: f64,
    /// Leave-one-out mean squared display error (sRGB values, negatives black).
    pub display_mse: f64,
    /// Mean leave-one-out prediction over mean observation, on screen.
    pub mean_bias: f64,
    /// The same in linear radiance.
    pub linear_bias: f64,
}

/// A fitted relightable image and its report.
#[derive(Clone, Debug)]
pub struct FitOutput {
    pub image: RelightableImage,
    pub report: FitReport,
}

/// The multiple of the data weight added to the diagonal of every normal matrix, so
/// that it stays definite when the data leave a coefficient undetermined: far below
/// any λ.
pub(super) const DEFINITENESS: f64 = 1e-10;

/// The sample weights' design: basis values and quadrature weights per image.
struct Design {
    basis: Box<dyn Basis>,
    k: usize,
    n: usize,
    /// N×k basis values, row-major.
    a: Vec<f64>,
    /// Quadrature weight per image (mean 1).
    q: Vec<f64>,
    /// The k×k penalty matrix, as configured.
    penalty: Vec<f64>,
}

impl Design {
    fn new(dirs: &[Vec3], basis: Box<dyn Basis>, regularizer: Regularizer) -> Design {
        let n = dirs.len();
        let k = basis.len();
        let mut a = vec![0.0; n * k];
        for (j, d) in dirs.iter().enumerate() {
            basis.eval(*d, &mut a[j * k..(j + 1) * k]);
        }
        let q = quadrature(dirs);
        let penalty = regularizer.matrix(basis.as_ref());
        Design {
            basis,
            k,
            n,
            a,
            q,
            penalty,
        }
    }

    fn row(&self, j: usize) -> &[f64] {
        &self.a[j * self.k..(j + 1) * self.k]
    }

    /// Add `λ·W·P` (and a tiny multiple of `W·I` so that the system stays definite when
    /// the data leave a coefficient undetermined) to `m`.
    fn regularize(&self, m: &mut [f64], lambda: f64, total_weight: f64) {
        for (v, &p) in m.iter_mut().zip(&self.penalty) {
            *v += total_weight * lambda * p;
        }
        for i in 0..self.k {
            m[i * self.k + i] += total_weight * DEFINITENESS;
        }
    }
}

/// Quadrature weight per captured direction: the solid angles of a full spherical grid,
/// 1 otherwise.
fn quadrature(dirs: &[Vec3]) -> Vec<f64> {
    sphere::grid_quadrature_weights(dirs).unwrap_or_else(|| vec![1.0; dirs.len()])
}

/// Read the subsample pixels of every image (`count × n × 3`), before any basis is
/// known: what `auto` and the data-driven families are chosen and built from.
fn read_subsample(
    capture: &Capture,
    sub_idx: &[usize],
    space: MapSpace,
    progress: &dyn Progress,
) -> Result<Vec<f32>> {
    let n = capture.len();
    progress.begin("sampling images", n as u64);
    let rows: Vec<Vec<f32>> = (0..n)
        .into_par_iter()
        .map(|j| {
            let (_, picked) = capture.load_parts(j, 0..0, sub_idx, target_encoding(space))?;
            progress.advance(1);
            Ok(picked)
        })
        .collect::<Result<_>>()?;
    progress.end();
    Ok(pixel_major(&rows, sub_idx.len()))
}

/// The tiles of the spill file of a fit streamed to `sink` that reads its images before
/// it chooses its K: the narrowest of the output's tiles for any K the fit may choose
/// (`None`, strips of whole rows, where every K's output is in scan lines). The pieces
/// the chosen output takes are then read across the spill file's tiles
/// ([`spill::Spill::pieces_for`]): its own tiles, or whole strips for scan lines, or
/// tiles twice as wide; the tiles' widths are powers of two.
fn one_pass_tiles(
    sink: &dyn PieceSink,
    width: usize,
    height: usize,
    n: usize,
    options: &FitOptions,
) -> Option<(usize, usize)> {
    possible_k(&options.basis, options, n)
        .into_iter()
        .filter_map(|k| sink.tiles(width, height, k))
        .min()
}

/// The coefficients per channel a fit of `request` may end with: the candidates' of
/// `auto`, the basis' own otherwise (what the output's tiles may depend on).
fn possible_k(request: &BasisRequest, options: &FitOptions, n: usize) -> Vec<usize> {
    let mut ks: Vec<usize> = match request {
        BasisRequest::Fixed(choice) => vec![choice.k],
        BasisRequest::Auto if options.candidates.is_empty() => {
            candidates(options.max_coefficients, n)
                .iter()
                .map(|c| c.k)
                .collect()
        }
        BasisRequest::Auto => {
            let train = select::training_lights(n);
            options
                .candidates
                .iter()
                .filter(|c| c.k < train)
                .map(|c| c.k)
                .collect()
        }
    };
    if ks.is_empty() {
        // No candidate: the choice will say so; until then, any K.
        ks.push(options.max_coefficients.max(1));
    }
    ks
}

fn spill_samples(codes: bool) -> spill::Samples {
    if codes {
        spill::Samples::Codes
    } else {
        spill::Samples::Floats
    }
}

/// Bytes of a piece of all `n` images: the option's, or more where each thread's share
/// of the solve would otherwise be less than a chunk.
fn piece_bytes(options: &FitOptions, n: usize) -> usize {
    options
        .piece_bytes
        .max(rayon::current_num_threads() * CHUNK * 3 * 4 * n)
}

/// The spill file of a fit streamed to `sink`: pieces inside the output's tiles for
/// `k` coefficients per channel.
fn create_spill(
    sink: &dyn PieceSink,
    width: usize,
    rows: std::ops::Range<usize>,
    n: usize,
    k: usize,
    options: &FitOptions,
    codes: bool,
) -> Result<spill::Spill> {
    spill::Spill::create(
        width,
        rows.len(),
        n,
        piece_bytes(options, n),
        sink.tiles(width, rows.len(), k),
        spill_samples(codes),
    )
}

/// Every image of `capture` read once: its band `rows` into `spill` (codes), and the
/// subsample pixels `sub_idx` returned as values in `space` (`count × n × 3`), as
/// [`read_subsample`] reads them.
fn spill_images(
    capture: &Capture,
    spill: &spill::Spill,
    rows: std::ops::Range<usize>,
    sub_idx: &[usize],
    space: MapSpace,
    progress: &dyn Progress,
) -> Result<Vec<f32>> {
    let n = capture.len();
    progress.begin("reading images", n as u64);
    let picked: Vec<Vec<f32>> = (0..n)
        .into_par_iter()
        .map(|j| {
            let picked = spill_image_codes(capture, spill, j, rows.clone(), sub_idx, space)?;
            progress.advance(1);
            Ok(picked)
        })
        .collect::<Result<_>>()?;
    progress.end();
    Ok(pixel_major(&picked, sub_idx.len()))
}

/// Each image's samples of `count` pixels (`per_image[j]`: pixel, channel) as the
/// subsample holds them: pixel, image, channel.
fn pixel_major(per_image: &[Vec<f32>], count: usize) -> Vec<f32> {
    let n = per_image.len();
    let mut sub = vec![0f32; count * n * 3];
    for (j, row) in per_image.iter().enumerate() {
        for s in 0..count {
            let o = (s * n + j) * 3;
            sub[o..o + 3].copy_from_slice(&row[3 * s..3 * s + 3]);
        }
    }
    sub
}

/// Image `j`'s band `rows` into `spill` as its codes, and its pixels `pixels` returned
/// as values in `space` (3 each, in the order asked).
fn spill_image_codes(
    capture: &Capture,
    spill: &spill::Spill,
    j: usize,
    rows: std::ops::Range<usize>,
    pixels: &[usize],
    space: MapSpace,
) -> Result<Vec<f32>> {
    let mut writer = spill.image_rows(j);
    let codes =
        capture.read_code_parts(j, rows, pixels, &mut |_, codes| writer.push_codes(codes))?;
    writer.finish()?;
    let values = capture.code_values(j, target_encoding(space));
    Ok(codes
        .iter()
        .enumerate()
        .map(|(i, &c)| values[256 * (i % 3) + c as usize])
        .collect())
}

/// The spill file as a solve reads it: in the pieces of the output's tiles, each
/// piece's samples as values in the maps' space.
struct SpillReader<'a> {
    spill: &'a spill::Spill,
    pieces: Vec<Piece>,
    /// Each image's values of its codes, where the file holds codes.
    values: Option<Vec<Vec<f32>>>,
}

impl<'a> SpillReader<'a> {
    fn new(
        capture: &Capture,
        spill: &'a spill::Spill,
        tiles: Option<(usize, usize)>,
        space: MapSpace,
    ) -> SpillReader<'a> {
        let values = (spill.samples() == spill::Samples::Codes).then(|| {
            (0..capture.len())
                .map(|j| capture.code_values(j, target_encoding(space)))
                .collect()
        });
        SpillReader {
            spill,
            pieces: spill.pieces_for(tiles),
            values,
        }
    }

    /// `piece` of every image, as [`spill::Spill::read_region`] reads it.
    fn read(&self, piece: Piece, buffer: &mut Vec<f32>) -> Result<()> {
        self.spill
            .read_region(piece, buffer, self.values.as_deref())
    }
}

/// How much of the subsample `auto`'s validation spends, by successive halving: every
/// candidate under every variant (space and objective) is first screened on
/// `screening_pixels` pixels and half the folds, and the best `finalists` (candidate,
/// variant) pairs are then validated in full on `pixels` pixels.
///
/// The default comes from the choice's stability against the pixels it spends
/// (`scripts/choice_stability.py`, docs/bases.md "How many pixels the choice needs"):
/// on the 40 fits of the RealRTI peer protocol, a screening on 64 pixels changes no
/// outcome against 128 or 256 (on 32 it drops a winner), and finalists judged on all
/// 1024 pixels choose as judging every candidate in full does in 39 fits, on 512 in
/// 33–35; three to six finalists agree alike, and four cost no more than three.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Halving {
    pub screening_pixels: usize,
    pub finalists: usize,
    pub pixels: usize,
}

impl Default for Halving {
    fn default() -> Self {
        Halving {
            screening_pixels: 64,
            finalists: 4,
            pixels: 1024,
        }
    }
}

/// A built basis, the objective and λ its validation chose (where it was validated),
/// and the candidates' scores.
type ChosenBasis = (
    Box<dyn Basis>,
    Option<(Objective, MapSpace, f64)>,
    Vec<CandidateScore>,
);

/// Whether the basis `request` names is validated on the subsample, which chooses the
/// maps' space, objective and λ with it (those not given): `auto` and the data-driven
/// families always; a fixed analytic basis for photographs, judged on display values,
/// wherever its space, objective or λ is open. Otherwise the exact leave-one-out chooses
/// the objective and λ of linear maps. On display values the validation's λ held out
/// better than the leave-one-out's on every basis measured, and the fit is faster
/// (docs/bases.md, "A fixed basis chooses its space too").
fn is_validated(
    request: &BasisRequest,
    criterion: Criterion,
    objective: Objective,
    spaces: &[MapSpace],
    lambda: Lambda,
) -> bool {
    match request {
        BasisRequest::Auto => true,
        BasisRequest::Fixed(choice) => {
            let open = spaces.len() > 1 || objective == Objective::Auto || lambda == Lambda::Auto;
            choice.needs_samples() || (criterion == Criterion::Display && open)
        }
    }
}

/// The basis `request` names for `capture`, built (data-driven families from the
/// subsample `sub`), with the objective, the maps' space and λ its validation chose
/// where it was validated. `sub` holds linear radiance where `spaces` offers more than
/// one space, the one space's values otherwise.
#[allow(clippy::too_many_arguments)]
fn choose_basis(
    request: &BasisRequest,
    options: &FitOptions,
    criterion: Criterion,
    objective: Objective,
    spaces: &[MapSpace],
    dirs: &[Vec3],
    sub: Option<&[f32]>,
    sub_count: usize,
) -> Result<ChosenBasis> {
    let n = dirs.len();
    let needs_validation = is_validated(request, criterion, objective, spaces, options.lambda);
    let Some(sub) = sub.filter(|_| needs_validation) else {
        let BasisRequest::Fixed(choice) = request else {
            unreachable!("auto always has samples")
        };
        return Ok((choice.build(dirs, None)?, None, Vec::new()));
    };
    let given = if spaces.len() > 1 {
        MapSpace::Linear
    } else {
        spaces[0]
    };
    // Validate on a thinner, evenly spread part of the subsample, in each space.
    let whole = select::Subsample {
        values: sub,
        count: sub_count,
        n,
    };
    let halving = options.halving;
    let keep = halving.pixels.min(sub_count).max(1);
    let screen_keep = halving.screening_pixels.min(keep).max(1);
    let finalists_kept = halving.finalists.max(1);
    let in_space = |values: &[f32], space: MapSpace| {
        let mut v = values.to_vec();
        if space != given {
            to_target_values(&mut v, space);
        }
        v
    };
    let picked = whole.thinned(keep);
    // What building the candidates remembers is forgotten when the choice ends, however
    // it ends.
    struct Forget;
    impl Drop for Forget {
        fn drop(&mut self) {
            crate::basis::forget_remembered();
        }
    }
    let _forget = Forget;
    let views: Vec<(MapSpace, Vec<f32>, Vec<f32>)> = spaces
        .iter()
        .map(|&space| {
            let values = in_space(&picked, space);
            let view = select::Subsample {
                values: &values,
                count: keep,
                n,
            };
            let screened = view.thinned(screen_keep);
            (space, values, screened)
        })
        .collect();
    let q = quadrature(dirs);
    let train = select::training_lights(n);
    let penalties = select::Penalties::default();
    let choices = match request {
        BasisRequest::Auto if options.candidates.is_empty() => {
            candidates(options.max_coefficients, n)
        }
        BasisRequest::Auto => options
            .candidates
            .iter()
            .filter(|c| c.k < train)
            .cloned()
            .collect(),
        BasisRequest::Fixed(choice) => vec![choice.clone()],
    };
    if choices.is_empty() && !options.candidates.is_empty() {
        return Err(Error::invalid(format!(
            "no candidate can be validated on {n} lights: a candidate needs fewer \
             coefficients than the {train} lights a validation fold trains on"
        )));
    }
    if choices.is_empty() {
        return Err(Error::invalid(format!(
            "no basis of 4 to {} coefficients can be validated on {n} lights",
            options.max_coefficients
        )));
    }
    // What is validated: each space with its objectives (display-referred maps only
    // with the plain one), in order.
    let linear_objectives: &[Objective] = match objective {
        Objective::Auto => &[Objective::Perceptual, Objective::Linear],
        Objective::Perceptual => &[Objective::Perceptual],
        Objective::Linear => &[Objective::Linear],
    };
    let objectives_of = |space: MapSpace| match space {
        MapSpace::Linear => linear_objectives,
        MapSpace::Srgb => &[Objective::Linear][..],
    };
    let variants: Vec<(MapSpace, Objective)> = spaces
        .iter()
        .flat_map(|&s| objectives_of(s).iter().map(move |&o| (s, o)))
        .collect();
    // The scores of each candidate of `nested` (one, or sizes of one nested family:
    // `select::validate`) under `which` of the variants (indices into `variants`), in
    // that order, each at the λ of its ladder (`ladders[w][c]`); none where that
    // ladder is empty.
    let judge = |nested: &[BasisChoice],
                 which: &[usize],
                 screening: bool,
                 folds: usize,
                 ladders: &[Vec<std::ops::Range<usize>>]|
     -> Result<Vec<Vec<Option<CandidateScore>>>> {
        let mut scores: Vec<Vec<Option<CandidateScore>>> =
            vec![vec![None; which.len()]; nested.len()];
        for (space, values, screened) in &views {
            let picked: Vec<usize> = (0..which.len())
                .filter(|&w| variants[which[w]].0 == *space)
                .collect();
            // The candidates judged in this space (a nested family's sizes stay one).
            let active: Vec<usize> = (0..nested.len())
                .filter(|&c| picked.iter().any(|&w| !ladders[w][c].is_empty()))
                .collect();
            if active.is_empty() {
                continue;
            }
            let objectives: Vec<Objective> = picked.iter().map(|&w| variants[which[w]].1).collect();
            let own_ladders: Vec<Vec<_>> = picked
                .iter()
                .map(|&w| active.iter().map(|&c| ladders[w][c].clone()).collect())
                .collect();
            let members: Vec<BasisChoice> = active.iter().map(|&c| nested[c].clone()).collect();
            let (values, count) = if screening {
                (screened, screen_keep)
            } else {
                (values, keep)
            };
            let view = select::Subsample { values, count, n };
            let got = select::validate(
                &members,
                *space,
                &objectives,
                options.regularizer,
                criterion,
                dirs,
                &q,
                &view,
                folds,
                &own_ladders,
                &penalties,
            )?;
            for (&c, got) in active.iter().zip(got) {
                for (&w, score) in picked.iter().zip(got) {
                    if !ladders[w][c].is_empty() {
                        scores[c][w] = Some(score);
                    }
                }
            }
        }
        Ok(scores)
    };
    let lambda_index = |score: &CandidateScore| {
        select::VALIDATION_LADDER
            .iter()
            .position(|&l| l == score.lambda)
            .unwrap_or(0)
    };
    let every: Vec<usize> = (0..variants.len()).collect();
    // The candidates that are sizes of one nested family, judged together in both rounds.
    let runs = nested_runs(&choices, n);
    // Successive halving: every candidate under every variant on a few pixels, then the
    // best few (candidate, variant) pairs on all of them, each at the λ around the one
    // its screening found best. A finalist is judged only as the variant that brought it
    // there: on display-referred maps the validation needs no per-pixel systems, so a
    // capture whose best candidates are display-referred costs less to choose for.
    let mut finalists: Vec<(usize, usize, std::ops::Range<usize>)> = (0..choices.len())
        .flat_map(|i| (0..variants.len()).map(move |v| (i, v, select::WHOLE_LADDER)))
        .collect();
    let mut scores = Vec::new();
    if choices.len() > finalists_kept && screen_keep < keep {
        let max_k = choices.iter().map(|c| c.k).max().unwrap_or(0);
        let folds = select::screening_folds(n, max_k);
        // A nested family's sizes together (one basis and one factorisation per fold
        // for all of them: on RealRTI items 23 candidates screen as 9), the runs side
        // by side: each one's folds and blocks are too few to keep both cores busy
        // alone. Collected in candidate order, so the ranking is the same.
        let judged: Vec<Vec<CandidateScore>> = runs
            .par_iter()
            .cloned()
            .map(|run| {
                let whole = vec![vec![select::WHOLE_LADDER; run.len()]; variants.len()];
                judge(&choices[run], &every, true, folds, &whole)
            })
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .flatten()
            .map(|scores| {
                scores
                    .into_iter()
                    .map(|s| s.expect("every candidate screened under every variant"))
                    .collect()
            })
            .collect();
        let mut screening: Vec<(usize, usize, CandidateScore)> = judged
            .into_iter()
            .enumerate()
            .flat_map(|(i, scores)| scores.into_iter().enumerate().map(move |(v, s)| (i, v, s)))
            .collect();
        screening.sort_by(|a, b| order(&a.2, &b.2));

        finalists = screening
            .iter()
            .take(finalists_kept)
            .map(|(i, v, score)| (*i, *v, select::ladder_around(lambda_index(score))))
            .collect();
        // The set-aside candidates, each by its best variant in the screening.
        let mut seen = vec![false; choices.len()];
        finalists.iter().for_each(|f| seen[f.0] = true);
        for (i, _, score) in screening.into_iter().skip(finalists_kept) {
            if !std::mem::replace(&mut seen[i], true) {
                scores.push(score);
            }
        }
    }
    // A candidate's finalist variants are judged together (variants of one space share
    // each fold's basis), and so are finalists that are sizes of one nested family
    // (one basis and factorisation per fold), each under its own variants and λ.
    let is_finalist = |i: usize, v: usize| finalists.iter().find(|f| f.0 == i && f.1 == v);
    let mut final_scores: Vec<Vec<Option<CandidateScore>>> =
        vec![vec![None; variants.len()]; choices.len()];
    for run in runs {
        let members: Vec<usize> = run
            .filter(|&i| finalists.iter().any(|f| f.0 == i))
            .collect();
        if members.is_empty() {
            continue;
        }
        let which: Vec<usize> = (0..variants.len())
            .filter(|&v| members.iter().any(|&i| is_finalist(i, v).is_some()))
            .collect();
        let ladders: Vec<Vec<std::ops::Range<usize>>> = which
            .iter()
            .map(|&v| {
                members
                    .iter()
                    .map(|&i| is_finalist(i, v).map_or(0..0, |f| f.2.clone()))
                    .collect()
            })
            .collect();
        let nested: Vec<BasisChoice> = members.iter().map(|&i| choices[i].clone()).collect();
        let got = judge(&nested, &which, false, select::folds(n), &ladders)?;
        for (&i, got) in members.iter().zip(got) {
            for (&v, score) in which.iter().zip(got) {
                final_scores[i][v] = score;
            }
        }
    }
    let mut best: Option<(usize, (MapSpace, Objective), CandidateScore)> = None;
    let mut contenders: Vec<(usize, (MapSpace, Objective), CandidateScore)> = Vec::new();
    // Candidates in the order they became finalists.
    let mut order_of: Vec<usize> = Vec::new();
    for f in &finalists {
        if !order_of.contains(&f.0) {
            order_of.push(f.0);
        }
    }
    for i in order_of {
        let which: Vec<usize> = finalists.iter().filter(|f| f.0 == i).map(|f| f.1).collect();
        for v in which {
            let score = final_scores[i][v]
                .take()
                .expect("every finalist judged under its variants");
            if !matches!(&best, Some((_, _, b)) if !score.beats(b)) {
                best = Some((i, variants[v], score.clone()));
            }
            contenders.push((i, variants[v], score));
        }
    }
    // The validation cannot tell apart finalists whose lead over one another is within
    // its noise: of those within one standard error of the best, the one cheapest to fit
    // (display-referred maps, then linear ones with the plain objective, then the
    // perceptual objective), the best scored among equals.
    if let Some((_, _, top)) = &best {
        let cost = |v: &(MapSpace, Objective)| match v {
            (MapSpace::Srgb, _) => 0,
            (MapSpace::Linear, Objective::Linear | Objective::Auto) => 1,
            (MapSpace::Linear, Objective::Perceptual) => 2,
        };
        let tied = contenders
            .iter()
            .filter(|(_, _, score)| score.unbiased() || !top.unbiased())
            .filter(|(_, _, score)| within_noise(top, score))
            .min_by(|a, b| {
                cost(&a.1)
                    .cmp(&cost(&b.1))
                    .then(b.2.psnr.total_cmp(&a.2.psnr))
            });
        if let Some(pick) = tied {
            best = Some(pick.clone());
        }
    }
    // Each finalist candidate once, by its best variant.
    let mut judged: Vec<(usize, CandidateScore)> = contenders
        .into_iter()
        .map(|(i, _, score)| (i, score))
        .collect();
    judged.sort_by(|a, b| order(&a.1, &b.1));
    let mut listed = vec![false; choices.len()];
    for (i, score) in judged {
        if !std::mem::replace(&mut listed[i], true) {
            scores.push(score);
        }
    }
    // Finalists first (they were judged on more pixels), each group best first; the
    // chosen one (as the variant chosen) ahead of them all.
    scores.sort_by(|a, b| b.pixels.cmp(&a.pixels).then(order(a, b)));
    let (i, (space, chosen_objective), score) = best.expect("at least one candidate");
    scores.retain(|s| s.basis != score.basis);
    scores.insert(0, score.clone());
    let mut samples: Vec<f32> = (0..sub_count * 3)
        .flat_map(|s| (0..n).map(move |j| sub[((s / 3) * n + j) * 3 + s % 3]))
        .collect();
    if space != given {
        to_target_values(&mut samples, space);
    }
    let basis = choices[i].build(
        dirs,
        Some(Samples {
            values: &samples,
            n,
        }),
    )?;
    Ok((basis, Some((chosen_objective, space, score.lambda)), scores))
}

/// The runs of consecutive `choices` that are sizes of one nested family, ascending
/// ([`BasisChoice::nests_in`] on `lights` directions), as index ranges in order.
fn nested_runs(choices: &[BasisChoice], lights: usize) -> Vec<std::ops::Range<usize>> {
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    for (i, choice) in choices.iter().enumerate() {
        match runs.last_mut() {
            Some(run)
                if choices[run.end - 1].k < choice.k
                    && choices[run.end - 1].nests_in(choice, lights) =>
            {
                run.end = i + 1
            }
            _ => runs.push(i..i + 1),
        }
    }
    runs
}

/// Whether `other`'s validation is within one standard error of `top`'s: the mean
/// over lights of the paired PSNR differences at most their standard error.
fn within_noise(top: &CandidateScore, other: &CandidateScore) -> bool {
    if top.lights.len() != other.lights.len() || top.lights.is_empty() {
        return false;
    }
    let pairs: Vec<(f64, f64)> = top
        .lights
        .iter()
        .zip(&other.lights)
        .filter(|(a, _)| a.0 > 0.0)
        .map(|(a, b)| (a.0, a.1 - b.1))
        .collect();
    let w: f64 = pairs.iter().map(|p| p.0).sum();
    let w2: f64 = pairs.iter().map(|p| p.0 * p.0).sum();
    if w <= 0.0 {
        return false;
    }
    let mean = pairs.iter().map(|p| p.0 * p.1).sum::<f64>() / w;
    let var = pairs
        .iter()
        .map(|p| p.0 * (p.1 - mean).powi(2))
        .sum::<f64>()
        / w;
    let n_eff = w * w / w2;
    mean <= (var / n_eff).sqrt()
}

/// Candidates best first: unbiased ones, then by validation PSNR.
fn order(a: &CandidateScore, b: &CandidateScore) -> std::cmp::Ordering {
    b.unbiased()
        .cmp(&a.unbiased())
        .then(b.psnr.total_cmp(&a.psnr))
}

/// Per-sample weight of the objective for a (linear) radiance `v`.
#[inline]
fn perceptual_weight(v: f64) -> f64 {
    let s = color::srgb_slope_tabulated(v);
    s * s
}

/// [`perceptual_weight`] of `v` given its encoding `encoded = srgb_extended(v)`, bit
/// for bit, without encoding `v` again: the per-pixel solve encodes each observation
/// once for its first weights and its secants.
#[inline]
fn perceptual_weight_encoded(v: f64, encoded: f64) -> f64 {
    if v > 1.0 {
        return perceptual_weight(v); // the slope at white, not the extended line's value
    }
    // Below 0 the encoding is not read: the slope is the linear segment's.
    let s = color::srgb_slope_of_encoded(v, encoded);
    s * s
}

/// The sRGB curve continued by straight lines below 0 and above 1, so that secants
/// between out-of-range values keep a positive slope (a clipped curve would give
/// saturated samples zero weight and leave a fully saturated pixel undetermined).
#[inline]
fn srgb_extended(v: f64) -> f64 {
    if v < 0.0 {
        12.92 * v
    } else if v > 1.0 {
        1.0 + color::srgb_slope(1.0) * (v - 1.0)
    } else {
        color::linear_to_srgb_tabulated(v as f32) as f64
    }
}

/// The sRGB value a screen shows for radiance `v` at exposure 0: clipped to `[0, 1]`,
/// as in an 8-bit image (a prediction above white in a highlight shows as white).
#[inline]
fn srgb_on_screen(v: f64) -> f64 {
    color::linear_to_srgb_tabulated(v as f32) as f64
}

/// The sRGB value a display shows for radiance `v`: negative radiance is black (the
/// curve is continued above 1 as in [`srgb_extended`], so that an exposure change keeps
/// the order of errors). The automatic objective judges fits by this: judged on the
/// extended curve instead, a linear fit's negative ringing inside exactly black shadows
/// — invisible on screen — counted as display error, and a dense full-sphere render
/// (the attic, 1000 lights) chose the perceptual objective, whose relit images came out
/// about five times too dark (the `fit` module docs say why).
#[inline]
fn srgb_shown(v: f64) -> f64 {
    srgb_extended(v.max(0.0))
}

/// Squared secant slope of the sRGB curve between a prediction and an observation:
/// the weight under which the linear residual equals the display-space residual.
#[inline]
fn secant_weight(pred: f64, obs: f64) -> f64 {
    secant_weight_encoded(pred, obs, srgb_extended(pred), srgb_extended(obs))
}

/// Ends of a secant closer than this take the tangent: f32 rounding dominates the secant.
const TANGENT_BELOW: f64 = 1e-5;

/// [`secant_weight`] given both ends' encodings (`srgb_extended`).
#[inline]
fn secant_weight_encoded(pred: f64, obs: f64, pred_encoded: f64, obs_encoded: f64) -> f64 {
    let d = pred - obs;
    if d.abs() < TANGENT_BELOW {
        return perceptual_weight(0.5 * (pred + obs));
    }
    let s = (pred_encoded - obs_encoded) / d;
    s * s
}

/// The reweighted pass's weight of each light from a pixel's channels' secant weights
/// (one slice per channel, per light): each channel's divided by its mean over the
/// lights, then the mean over the channels (`per_pixel::add_normalized`, lane by lane).
/// A channel whose weights are all zero adds nothing.
fn normalized_mean(channels: &[Vec<f64>]) -> Vec<f64> {
    let n = channels.first().map_or(0, Vec::len);
    let mut out = vec![0.0; n];
    for weights in channels {
        let sum: f64 = weights.iter().sum();
        if sum > 0.0 {
            let scale = n as f64 / (channels.len() as f64 * sum);
            for (o, &w) in out.iter_mut().zip(weights) {
                *o += w * scale;
            }
        }
    }
    out
}

/// [`srgb_extended`] of every value of `src`, bit for bit, the curve a batch at a time.
fn srgb_extended_batch(src: &[f64], dst: &mut [f64]) {
    color::linear_to_srgb_tabulated_batch(src, dst);
    for (d, &v) in dst.iter_mut().zip(src) {
        if !(0.0..=1.0).contains(&v) {
            *d = srgb_extended(v);
        }
    }
}

/// Deterministically spread `count` pixel indices over `pixels`.
fn subsample_indices(pixels: usize, count: usize) -> Vec<usize> {
    let count = count.min(pixels).max(1);
    let step = pixels as f64 / count as f64;
    // A fixed pseudo-random offset inside each stride avoids aliasing with image rows.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    (0..count)
        .map(|s| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let jitter = (state % 1_000_003) as f64 / 1_000_003.0;
            (((s as f64 + jitter) * step) as usize).min(pixels - 1)
        })
        .collect()
}

/// The values the fit targets, from a linear image: unchanged for linear maps,
/// sRGB-encoded for display-referred maps (from the table, within 5e-8 of the exact
/// curve, a ten-thousandth of an 8-bit step: the exact curve's `powf` was a twentieth of
/// a display-referred fit's time).
/// What maps each linear value to the values maps in `space` are fitted to (`None`:
/// linear values as they are), as the image readers take it ([`Capture::read_parts`]).
fn target_encoding(space: MapSpace) -> Option<fn(f32) -> f32> {
    (space == MapSpace::Srgb).then_some(color::linear_to_srgb_tabulated as fn(f32) -> f32)
}

/// Linear values turned in place into the values maps in `space` are fitted to.
fn to_target_values(values: &mut [f32], space: MapSpace) {
    if let Some(encode) = target_encoding(space) {
        values.iter_mut().for_each(|v| *v = encode(*v));
    }
}

/// Fit `capture` with `options`.
pub fn fit(capture: &Capture, options: &FitOptions, progress: &dyn Progress) -> Result<FitOutput> {
    let (meta, maps, depth, report) = fit_into(capture, options, progress, None)?;
    Ok(FitOutput {
        image: RelightableImage {
            meta,
            maps: maps.expect("maps are kept when no file is streamed"),
            depth,
        },
        report,
    })
}

/// Where a streamed fit's coefficients go as its pieces are solved (a file being
/// written: `codec::exr::fit_to_exr`).
pub trait PieceSink {
    /// The tiles the sink takes its pixels in, `(width, height)`, for an image of
    /// `width × height` pixels with `k` coefficients per channel, or `None` for strips
    /// of whole rows. Asked before the images are read; the fit's pieces then stay
    /// inside these tiles and come tile by tile.
    fn tiles(&self, width: usize, height: usize, k: usize) -> Option<(usize, usize)>;
    /// Called once, before any pieces, when the fitted image's size and coefficients per
    /// channel are known; `depth` is its depth map, when the capture has one.
    fn begin(
        &mut self,
        width: usize,
        height: usize,
        k: usize,
        depth: Option<Vec<f32>>,
    ) -> Result<()>;
    /// The next piece's coefficients (`maps` is the piece's size), in the order of the
    /// tiles (rows of tiles from the top, each from the left), each tile from its top.
    fn piece(&mut self, piece: Piece, maps: CoefficientMaps) -> Result<()>;
}

/// [`fit`], handing the maps to `sink` as the pieces are solved instead of holding
/// them: the fit's memory is then the piece's, not the maps'. The rows are bit for bit
/// [`fit`]'s maps. The linear objective's sums are taken piece by piece from the spill
/// file too. Returns the metadata and the report ([`fit`]'s, its image aside).
pub fn fit_streamed(
    capture: &Capture,
    options: &FitOptions,
    progress: &dyn Progress,
    sink: &mut dyn PieceSink,
) -> Result<(Metadata, FitReport)> {
    let (meta, _, _, report) = fit_into(capture, options, progress, Some(sink))?;
    Ok((meta, report))
}

/// The coefficients of the subsample pixels inside the fitted band, gathered from the
/// maps or from each piece as it is solved (the training residual needs no more).
struct SubCoefficients {
    k: usize,
    values: Vec<f32>,
    have: Vec<bool>,
}

impl SubCoefficients {
    fn new(count: usize, k: usize) -> Self {
        SubCoefficients {
            k,
            values: vec![0.0; count * 3 * k],
            have: vec![false; count],
        }
    }

    /// Record the subsample pixels in `maps`, the coefficients of `piece` of the band
    /// whose first pixel is image pixel `band_start`, in an image `width` pixels wide.
    fn record(
        &mut self,
        maps: &CoefficientMaps,
        piece: Piece,
        sub_idx: &[usize],
        band_start: usize,
        width: usize,
    ) {
        let k = self.k;
        for (s, &p) in sub_idx.iter().enumerate() {
            let Some(p) = p.checked_sub(band_start) else {
                continue;
            };
            if let Some(local) = piece.local(p % width, p / width) {
                for i in 0..k {
                    for c in 0..3 {
                        self.values[s * 3 * k + 3 * i + c] = maps.plane(i, c)[local];
                    }
                }
                self.have[s] = true;
            }
        }
    }

    /// Subsample pixel `s`'s coefficients (coefficient `i` of channel `c` at `3i + c`),
    /// when it was in the band.
    fn get(&self, s: usize) -> Option<&[f32]> {
        let n = 3 * self.k;
        self.have[s].then_some(&self.values[s * n..(s + 1) * n])
    }
}

/// A fit's metadata, maps (unless streamed to a file), depth band and report.
type Fitted = (
    Metadata,
    Option<CoefficientMaps>,
    Option<Vec<f32>>,
    FitReport,
);

fn fit_into(
    capture: &Capture,
    options: &FitOptions,
    progress: &dyn Progress,
    mut stream: Option<&mut dyn PieceSink>,
) -> Result<Fitted> {
    let start = Instant::now();
    let mut stages = Stages::new();
    if capture.is_empty() {
        return Err(Error::invalid("the capture has no images"));
    }
    let (w, h) = (capture.width, capture.height);
    let pixels = w * h;
    if pixels == 0 {
        return Err(Error::invalid("the capture's images are empty"));
    }
    let shard = options
        .shard
        .map(|(index, count)| ShardInfo::new(index, count, h).map_err(Error::invalid))
        .transpose()?;
    // The rows fitted: all of them, or the shard's band (pixels `band.start..band.end`
    // of the whole image); the subsample and every choice stay those of the whole image.
    let rows = shard.map_or(0..h, |s| s.rows());
    let band = rows.start * w..rows.end * w;
    let criterion = options
        .criterion
        .unwrap_or_else(|| Criterion::for_capture(capture));
    // The spaces the maps may be stored in: the one asked for (or the plan's), or, for
    // photographs with the automatic objective, linear radiance or display values,
    // whichever validates better on the capture's own lights.
    let spaces: Vec<MapSpace> = match (&options.plan, options.color_space) {
        (Some(plan), _) => vec![plan.color_space],
        (None, Some(space)) => vec![space],
        (None, None) if options.objective == Objective::Auto && criterion == Criterion::Display => {
            vec![MapSpace::Linear, MapSpace::Srgb]
        }
        (None, None) => vec![MapSpace::Linear],
    };
    let mut space = spaces[0];
    // Display-referred maps are fitted to display values, so only the plain objective applies.
    let mut objective = match space {
        MapSpace::Srgb => Objective::Linear,
        MapSpace::Linear => options.objective,
    };
    let mut lambda_option = options.lambda;
    let dirs = capture.directions();
    let sub_idx = subsample_indices(pixels, options.subsample);
    // `auto` and data-driven families see the subsample before the basis exists.
    if let Some(plan) = &options.plan {
        plan.check(capture, options)?;
    }
    // The automatic objective is chosen on the subsample too, before the images are
    // read, so that the first pass keeps only the chosen objective's state.
    let early = options.plan.is_none()
        && (objective == Objective::Auto
            || is_validated(
                &options.basis,
                criterion,
                objective,
                &spaces,
                options.lambda,
            ));
    // A fit streamed to a sink always keeps the spill file, and takes the linear
    // objective's sums piece by piece from it too, so that no state the size of the maps
    // is held.
    let streaming = stream.is_some();
    // Photographs are spilled as their codes, whose values are chosen when a piece is
    // read: the images can then be read once, for the subsample and the spill file
    // together, before anything is chosen (`one_pass`: the spill file's tiles).
    let codes = capture.eight_bit_codes();
    let one_pass = if early && codes {
        stream
            .as_ref()
            .map(|sink| one_pass_tiles(&**sink, w, rows.len(), dirs.len(), options))
    } else {
        None
    };
    let mut early_spill = None;
    let mut early_sub = if let Some(tiles) = one_pass {
        let spill = spill::Spill::create(
            w,
            rows.len(),
            dirs.len(),
            piece_bytes(options, dirs.len()),
            tiles,
            spill::Samples::Codes,
        )?;
        let sub = spill_images(capture, &spill, rows.clone(), &sub_idx, space, progress)?;
        stages.end("images");
        early_spill = Some(spill);
        Some(sub)
    } else if early {
        let sub = read_subsample(capture, &sub_idx, space, progress)?;
        stages.end("subsample");
        Some(sub)
    } else {
        None
    };
    let (basis, validated, basis_scores) = match &options.plan {
        Some(plan) => (
            plan.basis.build()?,
            Some((plan.objective, plan.color_space, plan.lambda)),
            Vec::new(),
        ),
        None => choose_basis(
            &options.basis,
            options,
            criterion,
            objective,
            &spaces,
            &dirs,
            early_sub.as_deref(),
            sub_idx.len(),
        )?,
    };
    if let Some((chosen, chosen_space, lambda)) = validated {
        objective = chosen;
        if chosen_space != space {
            if let Some(sub) = early_sub.as_mut() {
                to_target_values(sub, chosen_space);
            }
            space = chosen_space;
        }
        if matches!(lambda_option, Lambda::Auto) || options.plan.is_some() {
            lambda_option = Lambda::Fixed(lambda);
        }
    }
    if early {
        stages.end("basis choice");
    }
    let design = Design::new(&dirs, basis, options.regularizer);
    let have_sub = early_sub.is_some();
    let mut sub = early_sub.unwrap_or_else(|| vec![0f32; sub_idx.len() * design.n * 3]);

    // λ (and the automatic objective): leave-one-out on the subsample, before the
    // images are read where the subsample already is (then the first pass keeps only
    // the chosen objective's state), after them otherwise.
    let requested = objective;
    let choose = |sub: &[f32]| {
        choose_objective(
            &design,
            sub,
            sub_idx.len(),
            requested,
            lambda_option,
            options.reweights,
        )
    };
    let decided = if have_sub {
        let d = choose(&sub)?;
        objective = d.0.objective;
        stages.end("objective and λ");
        Some(d)
    } else {
        None
    };
    // The automatic objective keeps both kinds of pass-1 state until it has chosen.
    let mut accum = None;
    let mut spill = early_spill;
    let read_already = spill.is_some();
    if objective != Objective::Perceptual && !streaming {
        accum = Some(CoefficientMaps::zeros(w, rows.len(), design.k));
    }
    if !read_already && (objective != Objective::Linear || streaming) {
        // Codes where the spill file is the pass's only state (the shared sums take
        // values as the images are decoded).
        let spill_codes = codes && accum.is_none();
        spill = Some(match stream.as_ref() {
            Some(sink) => create_spill(
                &**sink,
                w,
                rows.clone(),
                design.n,
                design.k,
                options,
                spill_codes,
            )?,
            None => spill::Spill::create(
                w,
                rows.len(),
                design.n,
                piece_bytes(options, design.n),
                None,
                spill_samples(spill_codes),
            )?,
        });
    }

    // Pass 1: stream the images, a batch of decoders' worth at a time (unless the
    // images were read before the choices).
    if !read_already {
        progress.begin("reading images", design.n as u64);
    }
    // The shared sums gain from many images a batch; the spill file takes each image
    // alone, so a batch of one image a thread keeps decoded images out of the peak.
    let batch = if accum.is_some() {
        image_batch(DECODE_BATCH_BYTES, pixels * 3 * 4)
    } else {
        rayon::current_num_threads().max(1)
    };
    // The subsample pixels still to read, by their place in the subsample. A part fitted
    // with a plan chooses nothing: it reads only those in its band (for its training
    // residual), so each image is decoded only down to the band's last row.
    let unread: Vec<usize> = if have_sub {
        Vec::new()
    } else {
        (0..sub_idx.len())
            .filter(|&s| options.plan.is_none() || band.contains(&sub_idx[s]))
            .collect()
    };
    let wanted: Vec<usize> = unread.iter().map(|&s| sub_idx[s]).collect();
    let to_read = if read_already { 0 } else { design.n };
    for first in (0..to_read).step_by(batch) {
        let indices: Vec<usize> = (first..(first + batch).min(design.n)).collect();
        // Each image's band of rows, and its subsample pixels where still unread.
        let images: Vec<(Vec<f32>, Vec<f32>)> = indices
            .par_iter()
            .map(|&j| {
                let wanted = wanted.as_slice();
                let (img, samples) = match (&spill, &accum) {
                    // A photograph's codes, converted to the values the pass reads now.
                    (Some(spill), None) if spill.samples() == spill::Samples::Codes => (
                        Vec::new(),
                        spill_image_codes(capture, spill, j, rows.clone(), wanted, space)?,
                    ),
                    // Only the spill file takes the band: it goes there a row at a
                    // time, as the image is decoded, and is never held whole.
                    (Some(spill), None) => {
                        let mut writer = spill.image_rows(j);
                        let samples = capture.read_parts(
                            j,
                            rows.clone(),
                            wanted,
                            target_encoding(space),
                            &mut |_, values| writer.push(values),
                        )?;
                        writer.finish()?;
                        (Vec::new(), samples)
                    }
                    _ => {
                        let (img, samples) =
                            capture.load_parts(j, rows.clone(), wanted, target_encoding(space))?;
                        if let Some(spill) = &spill {
                            spill.write_image(j, &img)?;
                        }
                        (img, samples)
                    }
                };
                progress.advance(1);
                Ok((img, samples))
            })
            .collect::<Result<_>>()?;
        for (&j, (_, samples)) in indices.iter().zip(&images) {
            for (t, &s) in unread.iter().enumerate() {
                let o = (s * design.n + j) * 3;
                sub[o..o + 3].copy_from_slice(&samples[3 * t..3 * t + 3]);
            }
        }
        if let Some(acc) = accum.as_mut() {
            let bands: Vec<&[f32]> = images.iter().map(|(img, _)| img.as_slice()).collect();
            accumulate(acc, &design, &indices, &bands, first == 0);
        }
    }
    if !read_already {
        progress.end();
        stages.end("images");
    }
    let (choice, objective_scores) = match decided {
        Some(d) => d,
        None => choose(&sub)?,
    };
    let Choice {
        objective,
        lambda,
        scores: lambda_scores,
        ..
    } = choice;
    if objective == Objective::Perceptual {
        accum = None;
    } else if !streaming {
        spill = None;
    }
    if !have_sub {
        stages.end("objective and λ");
    }
    let depth = capture
        .depth
        .as_ref()
        .map(|d| d.get(band.clone()).unwrap_or_default().to_vec());
    if let Some(sink) = stream.as_mut() {
        sink.begin(w, rows.len(), design.k, depth.clone())?;
    }
    let mut sub_coefs = SubCoefficients::new(sub_idx.len(), design.k);
    let whole = Piece::sized(w, rows.len());
    let maps = if streaming && objective == Objective::Linear {
        let (spill, stream) = (
            spill.as_ref().expect("a spill file for the pieces"),
            stream.as_mut().expect("a sink to stream to"),
        );
        let indices: Vec<usize> = (0..design.n).collect();
        let mut buffer = Vec::new();
        let reader = SpillReader::new(capture, spill, stream.tiles(w, rows.len(), design.k), space);
        progress.begin("fitting pieces", reader.pieces.len() as u64);
        for &piece in &reader.pieces {
            reader.read(piece, &mut buffer)?;
            let images: Vec<&[f32]> = buffer.chunks_exact(3 * piece.pixels()).collect();
            let mut maps = CoefficientMaps::zeros(piece.width, piece.height, design.k);
            accumulate(&mut maps, &design, &indices, &images, true);
            solve_shared(&mut maps, &design, lambda)?;
            sub_coefs.record(&maps, piece, &sub_idx, band.start, w);
            stream.piece(piece, maps)?;
            progress.advance(1);
        }
        progress.end();
        None
    } else if let Some(mut sums) = accum.take() {
        // Only a fit held whole has the sums in memory.
        solve_shared(&mut sums, &design, lambda)?;
        sub_coefs.record(&sums, whole, &sub_idx, band.start, w);
        Some(sums)
    } else {
        let mut maps = stream
            .is_none()
            .then(|| CoefficientMaps::zeros(w, rows.len(), design.k));
        if let Some(spill) = spill.as_ref() {
            // The pieces of the output's tiles (a fit held whole: the spill file's own).
            let tiles = match stream.as_ref() {
                Some(sink) => sink.tiles(w, rows.len(), design.k),
                None => None,
            };
            per_pixel::solve_per_pixel(
                &SpillReader::new(capture, spill, tiles, space),
                &design,
                lambda,
                options.reweights,
                progress,
                &mut |piece, runs| {
                    match (maps.as_mut(), stream.as_mut()) {
                        (Some(maps), _) => scatter_planar(runs, piece, maps),
                        (None, Some(stream)) => {
                            let mut solved =
                                CoefficientMaps::zeros(piece.width, piece.height, design.k);
                            scatter_planar(
                                runs,
                                Piece::sized(piece.width, piece.height),
                                &mut solved,
                            );
                            sub_coefs.record(&solved, piece, &sub_idx, band.start, w);
                            stream.piece(piece, solved)?;
                        }
                        (None, None) => unreachable!("the maps or a file"),
                    }
                    Ok(())
                },
            )?;
        }
        if let Some(maps) = &maps {
            sub_coefs.record(maps, whole, &sub_idx, band.start, w);
        }
        maps
    };

    stages.end("solve");
    let (rmse_linear, psnr_srgb8) = training_residual(&design, &sub_coefs, &sub, space);
    stages.end("residual");
    let seconds = start.elapsed().as_secs_f64();
    let mut meta = Metadata::new(design.basis.spec(), space, capture.projection.clone());
    meta.camera = capture.camera.clone();
    meta.fit = Some(FitInfo {
        objective: objective.name().into(),
        regularizer: options.regularizer.name().into(),
        lambda,
        lambda_choice: if options.plan.is_some() {
            "plan".into()
        } else if !basis_scores.is_empty() && matches!(options.lambda, Lambda::Auto) {
            "validated".into()
        } else if matches!(options.lambda, Lambda::Auto) {
            "auto".into()
        } else {
            "fixed".into()
        },
        images: design.n,
        rmse_linear,
        psnr_srgb8,
        seconds,
        shard,
    });
    let report = FitReport {
        basis: design.basis.name(),
        objective_scores,
        candidates: basis_scores,
        images: design.n,
        width: w,
        height: h,
        coefficients: design.k,
        objective,
        color_space: space,
        lambda,
        lambda_scores,
        seconds,
        stages: stages.done,
        images_per_second: design.n as f64 / seconds.max(1e-9),
        peak_rss_bytes: crate::memory::peak_rss_bytes(),
        spill_bytes: spill.as_ref().map_or(0, |s| s.bytes()),
        rmse_linear,
        psnr_srgb8,
    };
    Ok((meta, maps, depth, report))
}

/// The objective and λ of a fit (leave-one-out on the subsample `sub`, `count` pixels of
/// `design.n` lights each), with the objectives' scores when there were two to compare.
fn choose_objective(
    design: &Design,
    sub: &[f32],
    count: usize,
    objective: Objective,
    lambda_option: Lambda,
    reweights: usize,
) -> Result<(Choice, Vec<ObjectiveScore>)> {
    let candidates: &[Objective] = match objective {
        Objective::Auto => &[Objective::Perceptual, Objective::Linear],
        Objective::Perceptual => &[Objective::Perceptual],
        Objective::Linear => &[Objective::Linear],
    };
    let relevance = light_relevance(sub, count, design.n);
    // The perceptual leave-one-out solves every pixel's own system (O(n·k²) per pixel
    // and λ): a dense capture judges it on fewer pixels of the subsample.
    let per_pixel =
        3.0 * design.n as f64 * (design.k * design.k) as f64 * LAMBDA_LADDER.len() as f64;
    let loo_count = ((PERCEPTUAL_LOO_BUDGET / per_pixel) as usize)
        .max(64)
        .min(count);
    let loo_sub: Vec<f32> = (0..loo_count)
        .flat_map(|i| {
            let s = i * count / loo_count;
            sub[s * design.n * 3..(s + 1) * design.n * 3]
                .iter()
                .copied()
        })
        .collect();
    // Objectives compared with each other are judged on the same pixels; the linear one
    // alone takes the whole subsample (its leave-one-out is cheap).
    let compared = candidates.len() > 1;
    let loo = |objective: LooObjective, ladder: &[f64]| match objective {
        LooObjective::Linear if !compared => {
            loo_scores(design, sub, count, objective, ladder, &relevance)
        }
        _ => loo_scores(design, &loo_sub, loo_count, objective, ladder, &relevance),
    };
    let mut choice: Option<Choice> = None;
    let mut objective_scores = Vec::new();
    for &candidate in candidates {
        // λ by the leave-one-out of the observation-weighted solve (both objectives).
        let plain = match candidate {
            Objective::Perceptual => LooObjective::Perceptual { reweights: 0 },
            _ => LooObjective::Linear,
        };
        let mut scored = match lambda_option {
            Lambda::Fixed(l) if l >= 0.0 && l.is_finite() => {
                if candidates.len() == 1 {
                    Choice::fixed(candidate, l)
                } else {
                    Choice::score(candidate, &loo(plain, &[l]))
                }
            }
            Lambda::Fixed(l) => {
                return Err(Error::invalid(format!(
                    "λ must be a non-negative number, got {l}"
                )))
            }
            Lambda::Auto => Choice::score(candidate, &loo(plain, &LAMBDA_LADDER)),
        };
        // Choosing between objectives, judge the perceptual one as it is fitted: with
        // its reweighting pass(es), at the chosen λ.
        if candidates.len() > 1 && candidate == Objective::Perceptual && reweights > 0 {
            let reweighted = LooObjective::Perceptual { reweights };
            if let Some(s) = loo(reweighted, &[scored.lambda]).first() {
                scored.display = s.display;
                scored.bias = s.bias;
                scored.linear_bias = s.linear_bias;
            }
        }
        if candidates.len() > 1 {
            objective_scores.push(ObjectiveScore {
                objective: candidate,
                lambda: scored.lambda,
                display_mse: scored.display,
                mean_bias: scored.bias,
                linear_bias: scored.linear_bias,
            });
        }
        if !matches!(&choice, Some(c) if !scored.beats(c)) {
            choice = Some(scored);
        }
    }
    Ok((
        choice.expect("at least one candidate objective"),
        objective_scores,
    ))
}

/// Pixels per parallel task.
const CHUNK: usize = 128;

/// Pixels per block of the planar sums: a block's run of every plane and its pixels of
/// a batch of images stay in cache together while the batch is added.
const SUM_BLOCK: usize = 512;

/// Each block of `SUM_BLOCK` pixels' run of every plane of `data` (planes of `npix`
/// values): disjoint, so that blocks are worked on in parallel.
fn plane_blocks(data: &mut [f32], npix: usize) -> Vec<Vec<&mut [f32]>> {
    let mut blocks: Vec<Vec<&mut [f32]>> =
        (0..npix.div_ceil(SUM_BLOCK)).map(|_| Vec::new()).collect();
    for plane in data.chunks_mut(npix) {
        for (b, run) in plane.chunks_mut(SUM_BLOCK).enumerate() {
            blocks[b].push(run);
        }
    }
    blocks
}

/// Add `q_j B(L_j) I_j` of a batch of images into the sums `acc`, kept in the maps'
/// planar layout (plane `3i + c`) so that the solve turns them into the maps in place:
/// the linear fit holds one image-sized set of planes, not sums and maps. Each sum
/// adds the images in batch order, as a pixel-major loop would.
///
/// `fresh`: `acc` holds zeros that nothing has written yet (freshly allocated maps):
/// the sums start from zero instead of reading them, so each page of the maps is
/// first touched by a write. A read first maps the kernel's shared zero page and the
/// write then copies it and flushes every core's TLB; on RealRTI item3 those faults
/// were a tenth of the fit's processor time.
fn accumulate(
    acc: &mut CoefficientMaps,
    design: &Design,
    indices: &[usize],
    images: &[&[f32]],
    fresh: bool,
) {
    let npix = acc.pixels();
    // Each image's weights, padded with zeros to whole groups of `SUM_ROWS`.
    let stride = summed_rows(design.k);
    let mut rows = vec![0f32; indices.len() * stride];
    for (&j, row) in indices.iter().zip(rows.chunks_exact_mut(stride)) {
        for (w, &v) in row.iter_mut().zip(design.row(j)) {
            *w = (v * design.q[j]) as f32;
        }
    }
    plane_blocks(&mut acc.data, npix)
        .into_par_iter()
        .enumerate()
        .for_each(|(block, mut planes)| {
            SUM_SCRATCH.with_borrow_mut(|channels| {
                add_block(channels, &mut planes, block, images, &rows, fresh)
            })
        });
}

thread_local! {
    /// [`accumulate`]'s de-interleaved block, one a thread, reused: a batch's block is
    /// hundreds of kilobytes, which the allocator would map and unmap (and the kernel
    /// zero) block after block.
    static SUM_SCRATCH: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Weights an image has in [`accumulate`]'s rows: its `k` padded to whole groups.
fn summed_rows(k: usize) -> usize {
    k.div_ceil(SUM_ROWS) * SUM_ROWS
}

/// One block of [`accumulate`]: block `block`'s runs of every plane (`3k` of them),
/// `planes`; `rows` the images' weights, [`summed_rows`] each.
fn add_block(
    channels: &mut Vec<f32>,
    planes: &mut [&mut [f32]],
    block: usize,
    images: &[&[f32]],
    rows: &[f32],
    fresh: bool,
) {
    let k = planes.len() / 3;
    let stride = summed_rows(k);
    let p0 = block * SUM_BLOCK;
    let len = planes[0].len();
    // The block's pixels of every image a channel at a time (image `t`'s
    // channel `c` at `(3t + c)·len`), so that each sum runs over contiguous
    // values (the interleaved samples would be gathered).
    channels.resize(3 * len * images.len(), 0.0);
    for (img, out) in images.iter().zip(channels.chunks_exact_mut(3 * len)) {
        let pixels = &img[3 * p0..3 * (p0 + len)];
        let (r, gb) = out.split_at_mut(len);
        let (g, b) = gb.split_at_mut(len);
        for (p, rgb) in pixels.chunks_exact(3).enumerate() {
            (r[p], g[p], b[p]) = (rgb[0], rgb[1], rgb[2]);
        }
    }
    for c in 0..3 {
        for first in (0..k).step_by(SUM_ROWS) {
            let mut runs: Vec<&mut [f32]> = planes
                .iter_mut()
                .skip(3 * first + c)
                .step_by(3)
                .take(SUM_ROWS)
                .map(|run| &mut **run)
                .collect();
            let weighted = WeightedChannel {
                rows,
                stride,
                first,
                channels: &channels[c * len..],
                len,
                fresh,
            };
            add_weighted(&mut runs, &weighted);
        }
    }
}

/// Planes of one channel summed together by [`accumulate`]: their running sums stay in
/// registers over a whole batch of images, each image's value loaded once for all of
/// them.
const SUM_ROWS: usize = 4;

/// What [`add_weighted`] adds into a group of planes' runs: the images' weights
/// (`stride` a image, the group's from `first`) and their de-interleaved channel
/// (image `t`'s at `channels[3·len·t ..][..len]`).
struct WeightedChannel<'a> {
    rows: &'a [f32],
    stride: usize,
    first: usize,
    channels: &'a [f32],
    len: usize,
    /// The runs hold zeros not yet written: start from zero without reading them.
    fresh: bool,
}

/// `runs[g][p] += Σ_t rows[t·stride + first + g] · channel_t[p]` over the images `t` in
/// order: each sum adds the images one at a time, exactly as a loop over images would
/// (a product, then a sum; never fused).
fn add_weighted(runs: &mut [&mut [f32]], w: &WeightedChannel) {
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2.
        return unsafe { add_weighted_avx2(runs, w) };
    }
    add_weighted_body(runs, w)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn add_weighted_avx2(runs: &mut [&mut [f32]], w: &WeightedChannel) {
    add_weighted_body(runs, w)
}

#[inline(always)]
fn add_weighted_body(runs: &mut [&mut [f32]], w: &WeightedChannel) {
    const LANES: usize = 8;
    let WeightedChannel {
        rows,
        stride,
        first,
        channels,
        len,
        fresh,
    } = *w;
    let images = rows.len() / stride;
    let lanes = |slice: &[f32]| -> [f32; LANES] { slice[..LANES].try_into().expect("8 lanes") };
    let whole = len / LANES * LANES;
    for p in (0..whole).step_by(LANES) {
        let mut sums = [[0f32; LANES]; SUM_ROWS];
        if !fresh {
            for (sum, run) in sums.iter_mut().zip(runs.iter()) {
                *sum = lanes(&run[p..]);
            }
        }
        for t in 0..images {
            let v = lanes(&channels[3 * len * t + p..]);
            let weights = &rows[t * stride + first..t * stride + first + SUM_ROWS];
            for (sum, &a) in sums.iter_mut().zip(weights) {
                for (s, &x) in sum.iter_mut().zip(&v) {
                    *s += a * x;
                }
            }
        }
        for (sum, run) in sums.iter().zip(runs.iter_mut()) {
            run[p..p + LANES].copy_from_slice(sum);
        }
    }
    // The last few pixels, one at a time.
    for p in whole..len {
        for (g, run) in runs.iter_mut().enumerate() {
            let mut s = if fresh { 0.0 } else { run[p] };
            for t in 0..images {
                s += rows[t * stride + first + g] * channels[3 * len * t + p];
            }
            run[p] = s;
        }
    }
}

/// Solve the shared normal equations for every pixel, turning the planar sums of
/// [`accumulate`] into the coefficient maps in place.
fn solve_shared(sums: &mut CoefficientMaps, design: &Design, lambda: f64) -> Result<()> {
    let k = design.k;
    let mut m = vec![0.0; k * k];
    let total: f64 = design.q.iter().sum();
    for j in 0..design.n {
        let row = design.row(j);
        for r in 0..k {
            for c in 0..k {
                m[r * k + c] += design.q[j] * row[r] * row[c];
            }
        }
    }
    design.regularize(&mut m, lambda, total);
    if !linalg::cholesky(&mut m, k) {
        return Err(Error::new(
            ErrorKind::Numerical,
            "the normal equations are singular; use a larger λ",
        ));
    }
    // The inverse, column by column, as an f32 matrix applied per pixel.
    let mut inv = vec![0f32; k * k];
    for col in 0..k {
        let mut e = vec![0.0; k];
        e[col] = 1.0;
        linalg::cholesky_solve(&m, k, &mut e);
        for r in 0..k {
            inv[r * k + col] = e[r] as f32;
        }
    }
    let npix = sums.pixels();
    plane_blocks(&mut sums.data, npix)
        .into_par_iter()
        .for_each(|mut planes| {
            // Plane by plane over the block's pixels (contiguous, so vectorised), each
            // value summed over the sums in the same order as a pixel at a time would.
            let len = planes[0].len();
            let mut solved = vec![0f32; 3 * k * len];
            for (x, out) in solved.chunks_exact_mut(len).enumerate() {
                let (r, c) = (x / 3, x % 3);
                for (i, &v) in inv[r * k..(r + 1) * k].iter().enumerate() {
                    for (o, &b) in out.iter_mut().zip(planes[3 * i + c].iter()) {
                        *o += v * b;
                    }
                }
            }
            for (run, out) in planes.iter_mut().zip(solved.chunks_exact(len)) {
                run.copy_from_slice(out);
            }
        });
    Ok(())
}

/// Decoded images pass 1 holds at once (at most; at least one per thread).
const DECODE_BATCH_BYTES: usize = 32 << 20;

/// Images decoded and accumulated together: enough to keep each pixel's sums in cache
/// over many images, within `budget` bytes of decoded images, and at least one per thread.
fn image_batch(budget: usize, image_bytes: usize) -> usize {
    let threads = rayon::current_num_threads().max(1);
    (budget / image_bytes.max(1)).clamp(threads, 32.max(threads))
}

/// Copy runs of pixel-major coefficients (pixel, i, c), one run after another over the
/// pixels of `piece` row by row, into the planar maps (the runs are the parallel tasks'
/// results, copied without first joining them).
fn scatter_planar<R: AsRef<[f32]> + Sync>(runs: &[R], piece: Piece, maps: &mut CoefficientMaps) {
    let k = maps.k;
    let (npix, width) = (maps.pixels(), maps.width);
    maps.data
        .par_chunks_mut(npix)
        .enumerate()
        .for_each(|(plane, values)| {
            // The piece's pixels row by row: (x, y) walks them without a division.
            let (mut x, mut y) = (0, 0);
            for run in runs {
                for pixel in run.as_ref().chunks_exact(3 * k) {
                    values[(piece.y0 + y) * width + piece.x0 + x] = pixel[plane];
                    x += 1;
                    if x == piece.width {
                        (x, y) = (0, y + 1);
                    }
                }
            }
        });
}

/// Indices of the packed upper triangle of a k×k symmetric matrix, row by row.
pub(super) fn packed_pairs(k: usize) -> Vec<(usize, usize)> {
    (0..k).flat_map(|r| (r..k).map(move |c| (r, c))).collect()
}

/// The objective and λ a fit settles on, with the leave-one-out scores behind them.
struct Choice {
    objective: Objective,
    lambda: f64,
    /// `(λ, weighted leave-one-out MSE)` for each λ tried.
    scores: Vec<(f64, f64)>,
    /// Leave-one-out MSE of the display (sRGB) values at the chosen λ.
    display: f64,
    /// Mean leave-one-out prediction over mean observation, as shown on screen.
    bias: f64,
    /// The same in linear radiance.
    linear_bias: f64,
}

/// The factor by which the mean of a fit's leave-one-out predictions may differ from
/// the mean of what was captured (linear radiance) before `auto` sets the fit aside: a
/// fit that relights the scene at less than half or more than twice its brightness is
/// broken, however small its error on screen. Measured: the perceptual objective on the
/// studio's street canyon (`city`, 300 lights, sh:25) predicts its held-out captured
/// lights at 0.20 of their brightness yet scores better in sRGB than the linear fit
/// (0.93); against ray-traced truth under new lights it is 1.5–4 dB worse on every light
/// type. On the RealRTI photographs the perceptual fit trades a little brightness for
/// what people see (item9 0.77, item3 0.96) and keeps its 4–8 dB lead there.
pub(crate) const MAX_MEAN_BIAS: f64 = 2.0;

/// Whether a mean prediction/observation ratio keeps the scene's brightness.
pub(crate) fn brightness_kept(ratio: f64) -> bool {
    ratio.is_finite() && (1.0 / MAX_MEAN_BIAS..=MAX_MEAN_BIAS).contains(&ratio)
}

impl Choice {
    /// Whether this choice's predictions keep the scene's brightness.
    fn unbiased(&self) -> bool {
        brightness_kept(self.linear_bias)
    }

    /// Whether `self` is the better choice than `other`: unbiased first, then the
    /// smaller display error (among biased ones, the less biased).
    fn beats(&self, other: &Choice) -> bool {
        match (self.unbiased(), other.unbiased()) {
            (true, false) => true,
            (false, true) => false,
            (true, true) => self.display < other.display,
            (false, false) => self.linear_bias.ln().abs() < other.linear_bias.ln().abs(),
        }
    }
    fn fixed(objective: Objective, lambda: f64) -> Choice {
        Choice {
            objective,
            lambda,
            scores: Vec::new(),
            display: 0.0,
            bias: 1.0,
            linear_bias: 1.0,
        }
    }

    /// The λ of smallest weighted error (the fit's own objective) among `scores`.
    fn score(objective: Objective, scores: &[LooScore]) -> Choice {
        let best = scores
            .iter()
            .filter(|s| s.weighted.is_finite())
            .min_by(|a, b| a.weighted.total_cmp(&b.weighted));
        Choice {
            objective,
            lambda: best.map_or(1e-3, |s| s.lambda),
            scores: scores.iter().map(|s| (s.lambda, s.weighted)).collect(),
            display: best.map_or(f64::INFINITY, |s| s.display),
            bias: best.map_or(f64::INFINITY, |s| s.bias),
            linear_bias: best.map_or(f64::INFINITY, |s| s.linear_bias),
        }
    }
}

/// Leave-one-out errors of one λ on the subsample.
#[derive(Clone, Copy, Debug)]
struct LooScore {
    lambda: f64,
    /// Mean squared residual under the fit's own weights.
    weighted: f64,
    /// Mean squared difference of the sRGB-encoded prediction and observation
    /// (quadrature-weighted): what a person sees, comparable across objectives.
    display: f64,
    /// Mean prediction over mean observation as shown on screen (1: unbiased).
    bias: f64,
    /// The same in linear radiance.
    linear_bias: f64,
}

/// Which captured lights light the scene at all, for weighing display errors: 1 for an
/// image whose mean radiance over the subsample `sub` (`count` pixels × `n` images ×
/// RGB) is at least [`DARK_IMAGE`] of the brightest image's, 0 for the others (a light
/// below the floor of a full-sphere capture, say). Grazing lights, dim but the point of
/// a raking-light RTI capture, count in full. All ones when every image is black.
fn light_relevance(sub: &[f32], count: usize, n: usize) -> Vec<f64> {
    let mut mean = vec![0.0f64; n];
    for s in 0..count {
        for (j, m) in mean.iter_mut().enumerate() {
            let o = (s * n + j) * 3;
            *m += sub[o..o + 3]
                .iter()
                .map(|&v| v.max(0.0) as f64)
                .sum::<f64>();
        }
    }
    let peak = mean.iter().cloned().fold(0.0, f64::max);
    if peak > 0.0 && peak.is_finite() {
        mean.iter()
            .map(|&m| if m >= DARK_IMAGE * peak { 1.0 } else { 0.0 })
            .collect()
    } else {
        vec![1.0; n]
    }
}

/// An image with less than this fraction of the brightest image's mean radiance shows
/// a scene its light does not reach: a thousandth is below the noise floor of any
/// photograph and far above a render's exact black.
const DARK_IMAGE: f64 = 1e-3;

/// Exact leave-one-out errors for each λ of `ladder`, on the subsample. The display
/// error weighs captured light `j` by `q_j · relevance[j]`. The perceptual objective's
/// weights are reweighted `reweights` times from the prediction, as the fit does, and
/// the leave-one-out residuals are those of the final weighted solve (its weights held
/// fixed): judged with the observation's weights alone, the perceptual fit would be
/// judged worse than it is.
fn loo_scores(
    design: &Design,
    sub: &[f32],
    count: usize,
    objective: LooObjective,
    ladder: &[f64],
    relevance: &[f64],
) -> Vec<LooScore> {
    if let LooObjective::Linear = objective {
        return loo_scores_shared(design, sub, count, ladder, relevance);
    }
    let (k, n) = (design.k, design.n);
    let reweights = match objective {
        LooObjective::Linear => 0,
        LooObjective::Perceptual { reweights } => reweights,
    };
    // The normal matrix of weights `w` (both triangles) and the weights' total.
    let normal = |w: &[f64]| -> (Vec<f64>, f64) {
        let mut m = vec![0.0; k * k];
        for (j, &wj) in w.iter().enumerate() {
            let row = design.row(j);
            for r in 0..k {
                for cc in r..k {
                    m[r * k + cc] += wj * row[r] * row[cc];
                }
            }
        }
        for r in 0..k {
            for cc in 0..r {
                m[r * k + cc] = m[cc * k + r];
            }
        }
        (m, w.iter().sum())
    };
    // The factor of a normal matrix regularised at λ, if positive definite.
    let factor = |(m, total): &(Vec<f64>, f64), lambda: f64| -> Option<Vec<f64>> {
        let mut f = m.clone();
        design.regularize(&mut f, lambda, *total);
        linalg::cholesky(&mut f, k).then_some(f)
    };
    let solve = |f: &[f64], w: &[f64], obs: &[f64]| -> Vec<f64> {
        let mut b = vec![0.0; k];
        for (j, (&wj, &o)) in w.iter().zip(obs).enumerate() {
            for (b, &a) in b.iter_mut().zip(design.row(j)) {
                *b += wj * a * o;
            }
        }
        linalg::cholesky_solve(f, k, &mut b);
        b
    };
    let predict = |j: usize, coef: &[f64]| -> f64 {
        design.row(j).iter().zip(coef).map(|(a, b)| a * b).sum()
    };
    let totals: Vec<[f64; 8]> = (0..count)
        .into_par_iter()
        .fold(
            || vec![[0.0f64; 8]; ladder.len()],
            |mut acc, s| {
                let obs: [Vec<f64>; 3] = std::array::from_fn(|c| {
                    (0..n).map(|j| sub[(s * n + j) * 3 + c] as f64).collect()
                });
                // The first weights as the fit's first pass has them
                // (`per_pixel::solve_chunk`): each channel its own, or, where they will
                // be reweighted, one set for the three, the mean of theirs. Each set of
                // weights with the channels it weighs.
                let first: Vec<(Vec<f64>, std::ops::Range<usize>)> = if reweights == 0 {
                    (0..3)
                        .map(|c| {
                            let w = (0..n)
                                .map(|j| design.q[j] * perceptual_weight(obs[c][j]))
                                .collect();
                            (w, c..c + 1)
                        })
                        .collect()
                } else {
                    let w = (0..n)
                        .map(|j| {
                            let mean =
                                obs.iter().map(|o| perceptual_weight(o[j])).sum::<f64>() / 3.0;
                            design.q[j] * mean
                        })
                        .collect();
                    vec![(w, 0..3)]
                };
                let first_normal: Vec<(Vec<f64>, f64)> =
                    first.iter().map(|(w, _)| normal(w)).collect();
                let mut z = vec![0.0; k];
                let mut leverage = vec![0.0f64; n];
                for (li, &lambda) in ladder.iter().enumerate() {
                    // The fit's own weights at this λ: the first ones, then reweighted
                    // (the three channels together, as the fit's reweighted passes).
                    let mut sets = first.clone();
                    let mut normals = first_normal.clone();
                    let mut singular = false;
                    for _ in 0..reweights {
                        let Some(f) = factor(&normals[0], lambda) else {
                            singular = true;
                            break;
                        };
                        let w = &sets[0].0;
                        let secants: Vec<Vec<f64>> = obs
                            .iter()
                            .map(|o| {
                                let coef = solve(&f, w, o);
                                (0..n)
                                    .map(|j| design.q[j] * secant_weight(predict(j, &coef), o[j]))
                                    .collect()
                            })
                            .collect();
                        sets[0].0 = normalized_mean(&secants);
                        normals[0] = normal(&sets[0].0);
                    }
                    for ((w, channels), normal) in sets.iter().zip(&normals) {
                        let f = factor(normal, lambda).filter(|_| !singular);
                        let Some(f) = f else {
                            acc[li][0] += f64::INFINITY;
                            acc[li][2] += f64::INFINITY;
                            continue;
                        };
                        for (j, leverage) in leverage.iter_mut().enumerate() {
                            z.copy_from_slice(design.row(j));
                            linalg::forward_solve(&f, k, &mut z);
                            *leverage = w[j] * z.iter().map(|v| v * v).sum::<f64>();
                        }
                        for obs in &obs[channels.clone()] {
                            let coef = solve(&f, w, obs);
                            for j in 0..n {
                                let pred = predict(j, &coef);
                                let e = (obs[j] - pred) / (1.0 - leverage[j]).max(1e-6);
                                let shown = srgb_shown(obs[j]) - srgb_shown(obs[j] - e);
                                acc[li][0] += w[j] * e * e;
                                acc[li][1] += w[j];
                                let seen = design.q[j] * relevance[j];
                                acc[li][2] += seen * shown * shown;
                                acc[li][3] += seen;
                                acc[li][4] += seen * srgb_on_screen(obs[j] - e);
                                acc[li][5] += seen * srgb_on_screen(obs[j]);
                                acc[li][6] += seen * (obs[j] - e);
                                acc[li][7] += seen * obs[j];
                            }
                        }
                    }
                }
                acc
            },
        )
        .reduce(
            || vec![[0.0; 8]; ladder.len()],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| {
                    for (xi, yi) in x.iter_mut().zip(y) {
                        *xi += yi;
                    }
                });
                a
            },
        );
    ladder
        .iter()
        .zip(totals)
        .map(
            |(&lambda, [err, wsum, shown, qsum, pred, obs, lpred, lobs])| LooScore {
                lambda,
                weighted: err / wsum.max(1e-30),
                display: shown / qsum.max(1e-30),
                bias: pred / obs.max(1e-30),
                linear_bias: lpred / lobs.max(1e-30),
            },
        )
        .collect()
}

/// [`loo_scores`] of the linear objective, whose weights (and so its normal matrix,
/// factors and leverages) every pixel shares: factored once per λ, then `O(n·k)` per
/// pixel instead of `O(n·k²)` — what makes a capture of thousands of lights affordable.
fn loo_scores_shared(
    design: &Design,
    sub: &[f32],
    count: usize,
    ladder: &[f64],
    relevance: &[f64],
) -> Vec<LooScore> {
    let (k, n) = (design.k, design.n);
    let mut m = vec![0.0; k * k];
    for j in 0..n {
        let row = design.row(j);
        for r in 0..k {
            for c in 0..k {
                m[r * k + c] += design.q[j] * row[r] * row[c];
            }
        }
    }
    let total: f64 = design.q.iter().sum();
    ladder
        .iter()
        .map(|&lambda| {
            let mut f = m.clone();
            design.regularize(&mut f, lambda, total);
            if !linalg::cholesky(&mut f, k) {
                return LooScore {
                    lambda,
                    weighted: f64::INFINITY,
                    display: f64::INFINITY,
                    bias: f64::INFINITY,
                    linear_bias: f64::INFINITY,
                };
            }
            let leverage: Vec<f64> = (0..n)
                .map(|j| {
                    let mut z = design.row(j).to_vec();
                    linalg::forward_solve(&f, k, &mut z);
                    design.q[j] * z.iter().map(|v| v * v).sum::<f64>()
                })
                .collect();
            let [err, wsum, shown_sum, qsum, pred_sum, obs_sum, lpred, lobs] = (0..count * 3)
                .into_par_iter()
                .map(|item| {
                    let (s, c) = (item / 3, item % 3);
                    let obs = |j: usize| sub[(s * n + j) * 3 + c] as f64;
                    let mut coef = vec![0.0; k];
                    for j in 0..n {
                        let w = design.q[j] * obs(j);
                        for (b, a) in coef.iter_mut().zip(design.row(j)) {
                            *b += w * a;
                        }
                    }
                    linalg::cholesky_solve(&f, k, &mut coef);
                    let mut acc = [0.0f64; 8];
                    for j in 0..n {
                        let pred: f64 = design.row(j).iter().zip(&coef).map(|(a, b)| a * b).sum();
                        let e = (obs(j) - pred) / (1.0 - leverage[j]).max(1e-6);
                        let shown = srgb_shown(obs(j)) - srgb_shown(obs(j) - e);
                        acc[0] += design.q[j] * e * e;
                        acc[1] += design.q[j];
                        let seen = design.q[j] * relevance[j];
                        acc[2] += seen * shown * shown;
                        acc[3] += seen;
                        acc[4] += seen * srgb_on_screen(obs(j) - e);
                        acc[5] += seen * srgb_on_screen(obs(j));
                        acc[6] += seen * (obs(j) - e);
                        acc[7] += seen * obs(j);
                    }
                    acc
                })
                .reduce(
                    || [0.0; 8],
                    |mut a, b| {
                        a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                        a
                    },
                );
            LooScore {
                lambda,
                weighted: err / wsum.max(1e-30),
                display: shown_sum / qsum.max(1e-30),
                bias: pred_sum / obs_sum.max(1e-30),
                linear_bias: lpred / lobs.max(1e-30),
            }
        })
        .collect()
}

/// The objective whose leave-one-out errors [`loo_scores`] computes.
#[derive(Clone, Copy, Debug)]
enum LooObjective {
    Linear,
    Perceptual { reweights: usize },
}

/// Training residual on the subsample: RMSE in linear radiance per channel and 8-bit sRGB PSNR.
fn training_residual(
    design: &Design,
    sub_coefs: &SubCoefficients,
    sub: &[f32],
    space: MapSpace,
) -> ([f64; 3], f64) {
    let (k, n) = (design.k, design.n);
    // Blocks of the subsample in parallel, their sums added in block order (the same
    // figures on every run).
    const BLOCK: usize = 64;
    let blocks: Vec<([f64; 3], f64, usize)> = (0..sub_coefs.have.len().div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let mut sq = [0.0f64; 3];
            let mut sq8 = 0.0f64;
            let mut count = 0usize;
            let end = ((b + 1) * BLOCK).min(sub_coefs.have.len());
            for s in b * BLOCK..end {
                let Some(coefficient) = sub_coefs.get(s) else {
                    continue;
                };
                count += n;
                for c in 0..3 {
                    let coef: Vec<f64> = (0..k).map(|i| coefficient[3 * i + c] as f64).collect();
                    for j in 0..n {
                        let pred: f64 = design.row(j).iter().zip(&coef).map(|(a, b)| a * b).sum();
                        let obs = sub[(s * n + j) * 3 + c] as f64;
                        let (pred_lin, obs_lin) = match space {
                            MapSpace::Linear => (pred, obs),
                            MapSpace::Srgb => (
                                color::srgb_to_linear(pred.clamp(0.0, 1.0) as f32) as f64,
                                color::srgb_to_linear(obs.clamp(0.0, 1.0) as f32) as f64,
                            ),
                        };
                        sq[c] += (pred_lin - obs_lin).powi(2);
                        let d = metrics::srgb8_difference(pred_lin as f32, obs_lin as f32);
                        sq8 += d * d;
                    }
                }
            }
            (sq, sq8, count)
        })
        .collect();
    let mut sq = [0.0f64; 3];
    let mut sq8 = 0.0f64;
    let mut count = 0usize;
    for (block_sq, block_sq8, block_count) in blocks {
        for (total, v) in sq.iter_mut().zip(block_sq) {
            *total += v;
        }
        sq8 += block_sq8;
        count += block_count;
    }
    if count == 0 {
        // A shard narrower than the subsample's spacing: nothing measured (`relit merge`
        // pools the parts that measured theirs).
        return ([0.0; 3], 0.0);
    }
    let count = count as f64;
    let rmse = sq.map(|v| (v / count).sqrt());
    let mse8 = sq8 / (3.0 * count);
    (rmse, metrics::psnr(mse8, 255.0))
}

#[cfg(test)]
mod tests;
