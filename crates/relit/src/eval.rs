//! Fidelity against real held-out captures.
//!
//! Hold out some reference images, fit on the rest, relight at each held-out light and
//! compare with the real image. Two figures per hold-out:
//!
//! * **8-bit sRGB PSNR over the whole frame**: `20·log10(255) − 10·log10(MSE)` over all
//!   `W×H×3` samples of the 8-bit sRGB encodings — the protocol of
//!   `shared/reference/peer_baseline.md`, so relit's numbers sit beside relight-cli's.
//! * **Linear PSNR inside the mask** (the whole frame without one): peak 1, the white of
//!   8/16-bit inputs.
//!
//! By default each held-out image gets its own fit on the other N−1 images, as the peer
//! baseline was made; `joint` fits once without all held-out images. Every fit is
//! written as a real file (EXR at the storage precision, or `.rlz`), read back and
//! relit, so the figures are those of the stored file and its size on disk.
//!
//! [`rd`] scores many files per fit: the rate–distortion curve.

use crate::capture::Capture;
use crate::engine::{self, RelightOptions};
use crate::fit::{self, FitOptions};
use crate::light::{Light, LightRig};
use crate::metrics;
use crate::progress::Progress;
use crate::storage::Precision;
use crate::{Error, Result};
use serde::Serialize;
use std::str::FromStr;

pub mod rd;

/// Which images to hold out.
#[derive(Clone, Debug, PartialEq)]
pub enum Holdout {
    /// Every n-th image: 0, n, 2n, …
    Every(usize),
    /// These indices (in capture order).
    List(Vec<usize>),
    /// `n` indices spread evenly: `round(i·(N−1)/(n−1))`; `spread:5` is the peer protocol.
    Spread(usize),
}

impl FromStr for Holdout {
    type Err = Error;
    fn from_str(s: &str) -> Result<Holdout> {
        let s = s.trim();
        let bad = || {
            Error::parse(format!(
                "bad hold-out `{s}`: expected `every:N`, `spread:N` or indices like `0,12,24`"
            ))
        };
        if let Some(n) = s.strip_prefix("every:") {
            let n: usize = n.trim().parse().map_err(|_| bad())?;
            return if n == 0 {
                Err(bad())
            } else {
                Ok(Holdout::Every(n))
            };
        }
        if let Some(n) = s.strip_prefix("spread:") {
            let n: usize = n.trim().parse().map_err(|_| bad())?;
            return if n == 0 {
                Err(bad())
            } else {
                Ok(Holdout::Spread(n))
            };
        }
        let list: Vec<usize> = s
            .split(',')
            .map(|p| p.trim().parse().map_err(|_| bad()))
            .collect::<Result<_>>()?;
        if list.is_empty() {
            return Err(bad());
        }
        Ok(Holdout::List(list))
    }
}

impl Holdout {
    /// The held-out indices for a capture of `n` images (sorted, distinct).
    pub fn indices(&self, n: usize) -> Result<Vec<usize>> {
        let mut idx: Vec<usize> = match self {
            Holdout::Every(step) => (0..n).step_by(*step).collect(),
            Holdout::List(list) => {
                if let Some(&bad) = list.iter().find(|&&i| i >= n) {
                    return Err(Error::invalid(format!(
                        "hold-out index {bad} is out of range: the capture has {n} images"
                    )));
                }
                list.clone()
            }
            Holdout::Spread(count) => {
                let count = (*count).min(n);
                if count == 1 {
                    vec![0]
                } else {
                    (0..count)
                        .map(|i| ((i * (n - 1)) as f64 / (count - 1) as f64).round() as usize)
                        .collect()
                }
            }
        };
        idx.sort_unstable();
        idx.dedup();
        if idx.len() >= n {
            return Err(Error::invalid(format!(
                "holding out {} of {n} images leaves nothing to fit",
                idx.len()
            )));
        }
        Ok(idx)
    }
}

/// Options of [`evaluate`].
#[derive(Clone, Debug)]
pub struct EvalOptions {
    pub holdout: Holdout,
    pub fit: FitOptions,
    /// The precision of the file's maps (f32 or f16).
    pub storage: Precision,
    /// Fit once without all held-out images instead of once per held-out image.
    pub joint: bool,
    /// Mask (> 0.5 inside) for the linear PSNR; overrides the capture's own mask.
    pub mask: Option<Vec<f32>>,
    /// Store each fit as a compressed `.rlz` file with these settings instead of EXR:
    /// the file is written, read back and relit, and its size on disk is the figure.
    pub compress: Option<crate::compress::Settings>,
    /// Store each fit compressed with the settings that score best on its own training
    /// lights within this many bits per pixel ([`crate::compress::budget`]).
    pub budget: Option<f64>,
    /// With `budget` and the basis `auto`: how many of `auto`'s best finalists are each
    /// fitted and compressed, the file chosen among them ([`crate::budget_fit`]); 1:
    /// `auto`'s basis alone.
    pub budget_bases: usize,
}

/// The result for one held-out image.
#[derive(Clone, Debug, Serialize)]
pub struct HoldoutResult {
    pub index: usize,
    pub image: String,
    pub direction: [f64; 3],
    pub psnr_srgb8: f64,
    pub psnr_linear: f64,
    pub fit_seconds: f64,
    pub lambda: f64,
    /// The basis this hold-out's fit used.
    pub basis: String,
    /// The candidates this hold-out's fit validated (`--basis auto`), best first.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub candidates: Vec<crate::fit::CandidateScore>,
    /// With `--budget` over several bases: each basis fitted and how its best file was
    /// judged, `auto`'s choice first.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub budget_bases: Vec<crate::compress::budget::Estimate>,
}

/// The evaluation of a capture.
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    pub capture: String,
    pub images: usize,
    pub width: usize,
    pub height: usize,
    pub basis: String,
    pub coefficients: usize,
    /// The candidate bases the first fit validated (`--basis auto`), best first
    /// (each hold-out lists its own fit's).
    pub candidates: Vec<crate::fit::CandidateScore>,
    pub objective: String,
    pub color_space: String,
    pub storage: String,
    pub protocol: String,
    pub psnr_srgb8_mean: f64,
    pub psnr_linear_mean: f64,
    pub masked: bool,
    /// The fits' files on disk, bytes per pixel (mean over the fits).
    pub bytes_per_pixel: f64,
    /// Mean wall time of one fit.
    pub fit_seconds: f64,
    pub peak_rss_bytes: Option<u64>,
    pub holdouts: Vec<HoldoutResult>,
}

/// Receives each held-out image's result, the captured image and the relit one.
pub type HoldoutSink<'a> =
    dyn FnMut(&HoldoutResult, &crate::image::ImageRgb, &crate::image::ImageRgb) -> Result<()> + 'a;

/// Hold out, fit, relight and compare.
pub fn evaluate(
    capture: &Capture,
    options: &EvalOptions,
    progress: &dyn Progress,
) -> Result<EvalReport> {
    evaluate_with(capture, options, progress, None)
}

/// [`evaluate`], showing `sink` every held-out pair of images.
pub fn evaluate_with(
    capture: &Capture,
    options: &EvalOptions,
    progress: &dyn Progress,
    mut sink: Option<&mut HoldoutSink>,
) -> Result<EvalReport> {
    let n = capture.len();
    let protocol = Protocol::new(capture, &options.holdout, options.joint, &options.mask)?;
    let scratch = Scratch::new()?;
    crate::memory::reset_peak_rss();
    let mut results = Vec::new();
    let mut fit_seconds = Vec::new();
    let mut chosen: Vec<&'static str> = Vec::new();
    let mut spaces: Vec<&'static str> = Vec::new();
    let mut bases: Vec<String> = Vec::new();
    let mut coefficients = 0;
    let mut candidates = Vec::new();
    let mut file_bytes: Vec<f64> = Vec::new();
    let mut chosen_settings: Vec<String> = Vec::new();
    for group in &protocol.groups {
        let train_capture = capture.subset(&protocol.training(group));
        let (mut fitted, budgeted) = match options.budget {
            Some(budget) => {
                let made = crate::budget_fit::fit_within_budget(
                    &train_capture,
                    &options.fit,
                    budget,
                    options.budget_bases,
                    progress,
                )?;
                (made.fit, Some((made.choice, made.estimates)))
            }
            None => (fit::fit(&train_capture, &options.fit, progress)?, None),
        };
        let budget_estimates = budgeted
            .as_ref()
            .map(|(_, e)| e.clone())
            .unwrap_or_default();
        fit_seconds.push(fitted.report.seconds);
        coefficients = fitted.report.coefficients;
        if candidates.is_empty() {
            candidates = fitted.report.candidates.clone();
        }
        if !bases.contains(&fitted.report.basis) {
            bases.push(fitted.report.basis.clone());
        }
        if !chosen.contains(&fitted.report.objective.name()) {
            chosen.push(fitted.report.objective.name());
        }
        if !spaces.contains(&fitted.report.color_space.name()) {
            spaces.push(fitted.report.color_space.name());
        }
        let (image, bytes) = if let Some((choice, _)) = budgeted {
            if !chosen_settings.contains(&choice.settings.describe()) {
                chosen_settings.push(choice.settings.describe());
            }
            scratch.packed_round_trip(&choice.packed, "maps")?
        } else if let Some(settings) = &options.compress {
            let settings = for_training(settings, &train_capture);
            scratch.compressed_round_trip(&fitted.image, &settings, "maps")?
        } else {
            scratch.exr_round_trip(&fitted.image, options.storage, "maps")?
        };
        fitted.image = image;
        file_bytes.push(bytes as f64);
        for &index in group {
            let reference = capture.load_raw(index)?;
            let (relit, psnr_srgb8, psnr_linear) =
                relight_and_score(&fitted.image, capture, index, &reference, protocol.mask())?;
            let result = HoldoutResult {
                index,
                image: capture.image_name(index),
                direction: capture.lights[index].direction.into(),
                psnr_srgb8,
                psnr_linear,
                fit_seconds: fitted.report.seconds,
                lambda: fitted.report.lambda,
                basis: fitted.report.basis.clone(),
                candidates: fitted.report.candidates.clone(),
                budget_bases: budget_estimates.clone(),
            };
            if let Some(sink) = sink.as_mut() {
                sink(&result, &reference, &relit)?;
            }
            results.push(result);
        }
    }
    let bytes_per_pixel = file_bytes.iter().sum::<f64>()
        / file_bytes.len() as f64
        / (capture.width * capture.height) as f64;
    let mean = |f: &dyn Fn(&HoldoutResult) -> f64| {
        results.iter().map(f).sum::<f64>() / results.len() as f64
    };
    Ok(EvalReport {
        capture: capture.origin.clone(),
        images: n,
        width: capture.width,
        height: capture.height,
        basis: bases.join(", "),
        coefficients,
        candidates,
        objective: match options.fit.objective {
            fit::Objective::Auto
                if options.fit.color_space != Some(crate::maps::MapSpace::Srgb) =>
            {
                format!("auto ({})", chosen.join(", "))
            }
            _ => chosen.join(", "),
        },
        color_space: match options.fit.color_space {
            Some(space) => space.name().into(),
            None => format!("auto ({})", spaces.join(", ")),
        },
        storage: match (&options.compress, options.budget) {
            (_, Some(budget)) => format!("rlz ≤ {budget} bits/px: {}", chosen_settings.join("; ")),
            (Some(settings), None) => format!("rlz {}", settings.describe()),
            (None, None) => options.storage.name().into(),
        },
        protocol: protocol.name().into(),
        psnr_srgb8_mean: mean(&|r| r.psnr_srgb8),
        psnr_linear_mean: mean(&|r| r.psnr_linear),
        masked: protocol.mask.is_some(),
        bytes_per_pixel,
        fit_seconds: fit_seconds.iter().sum::<f64>() / fit_seconds.len() as f64,
        peak_rss_bytes: crate::memory::peak_rss_bytes(),
        holdouts: results,
    })
}

/// Which images each fit leaves out, and where the linear figure is taken: what
/// [`evaluate`] and [`rd::curve`] share, so both score the same protocol.
struct Protocol {
    images: usize,
    joint: bool,
    /// One group per fit: the images it leaves out and is scored on.
    groups: Vec<Vec<usize>>,
    mask: Option<Vec<f32>>,
}

impl Protocol {
    fn new(
        capture: &Capture,
        holdout: &Holdout,
        joint: bool,
        mask: &Option<Vec<f32>>,
    ) -> Result<Protocol> {
        let n = capture.len();
        let held = holdout.indices(n)?;
        let mask = match mask {
            Some(m) => Some(m.clone()),
            None => capture.mask.as_ref().map(|m| m.as_ref().clone()),
        };
        if let Some(m) = &mask {
            if m.len() != capture.width * capture.height {
                return Err(Error::invalid("the mask's size differs from the capture's"));
            }
        }
        let groups = if joint {
            vec![held]
        } else {
            held.iter().map(|&i| vec![i]).collect()
        };
        Ok(Protocol {
            images: n,
            joint,
            groups,
            mask,
        })
    }

    /// The images a fit that leaves out `group` is fitted on.
    fn training(&self, group: &[usize]) -> Vec<usize> {
        (0..self.images).filter(|i| !group.contains(i)).collect()
    }

    fn mask(&self) -> Option<&[f32]> {
        self.mask.as_deref()
    }

    fn name(&self) -> &'static str {
        if self.joint {
            "joint"
        } else {
            "one fit per hold-out"
        }
    }
}

/// Compression settings for maps fitted on `training`: its light directions weigh the
/// principal components, as a file made by `relit fit` from that capture would be.
fn for_training(
    settings: &crate::compress::Settings,
    training: &Capture,
) -> crate::compress::Settings {
    crate::compress::Settings {
        directions: Some(training.directions()),
        ..settings.clone()
    }
}

/// Relight `image` at captured light `index` and score it against `reference` (that
/// image as captured): (the relit image, 8-bit sRGB PSNR, linear PSNR).
fn relight_and_score(
    image: &crate::maps::RelightableImage,
    capture: &Capture,
    index: usize,
    reference: &crate::image::ImageRgb,
    mask: Option<&[f32]>,
) -> Result<(crate::image::ImageRgb, f64, f64)> {
    let light = &capture.lights[index];
    let color = light.intensity.map(|v| v as f64);
    let rig = LightRig::new(vec![Light::directional(light.direction, color)]);
    let relit = engine::relight(image, &rig, &RelightOptions::default())?;
    let (psnr_srgb8, psnr_linear) = protocol_scores(&relit.data, &reference.data, mask);
    Ok((relit, psnr_srgb8, psnr_linear))
}

/// A temporary folder the scored files are written to and read back from: every figure
/// is that of a real file, its bytes on disk and what a reader of it relights. Files are
/// named by a stem, so that several can be in flight at once.
struct Scratch {
    dir: tempfile::TempDir,
}

impl Scratch {
    fn new() -> Result<Scratch> {
        let dir = tempfile::tempdir()
            .map_err(|e| Error::io(std::path::Path::new("."), "create a temporary folder in", e))?;
        Ok(Scratch { dir })
    }

    fn measured(&self, path: &std::path::Path) -> Result<(crate::maps::RelightableImage, u64)> {
        let bytes = std::fs::metadata(path)
            .map_err(|e| Error::io(path, "measure", e))?
            .len();
        Ok((crate::codec::read(path)?, bytes))
    }

    /// Write `image` as an EXR of `storage` precision and read it back: the image a
    /// reader of that file relights, and the file's size on disk.
    fn exr_round_trip(
        &self,
        image: &crate::maps::RelightableImage,
        storage: Precision,
        stem: &str,
    ) -> Result<(crate::maps::RelightableImage, u64)> {
        let path = self.dir.path().join(format!("{stem}.exr"));
        crate::codec::exr::write(&path, image, storage)?;
        self.measured(&path)
    }

    /// The same for `image` compressed with `settings` into a `.rlz`.
    fn compressed_round_trip(
        &self,
        image: &crate::maps::RelightableImage,
        settings: &crate::compress::Settings,
        stem: &str,
    ) -> Result<(crate::maps::RelightableImage, u64)> {
        self.packed_round_trip(&crate::compress::pack(image, settings)?, stem)
    }

    /// The same for an image already packed.
    fn packed_round_trip(
        &self,
        packed: &crate::compress::Packed,
        stem: &str,
    ) -> Result<(crate::maps::RelightableImage, u64)> {
        let path = self.dir.path().join(format!("{stem}.rlz"));
        crate::codec::packed::write_packed(&path, packed)?;
        self.measured(&path)
    }
}

/// The protocol's two figures of `test` against `reference`: (8-bit sRGB PSNR over the
/// whole frame, linear PSNR (peak 1) inside `mask`).
fn protocol_scores(test: &[f32], reference: &[f32], mask: Option<&[f32]>) -> (f64, f64) {
    let srgb8 = metrics::psnr_srgb8(test, reference);
    let linear = metrics::psnr_linear(test, reference, mask, 1.0);
    (srgb8, linear)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holdout_specs() {
        assert_eq!(
            "every:10".parse::<Holdout>().unwrap().indices(25).unwrap(),
            vec![0, 10, 20]
        );
        assert_eq!(
            "0,12,24,35,47"
                .parse::<Holdout>()
                .unwrap()
                .indices(60)
                .unwrap(),
            vec![0, 12, 24, 35, 47]
        );
        // The peer protocol: round(i·(N−1)/4).
        assert_eq!(
            "spread:5".parse::<Holdout>().unwrap().indices(60).unwrap(),
            vec![0, 15, 30, 44, 59]
        );
        assert_eq!(
            "spread:5".parse::<Holdout>().unwrap().indices(47).unwrap(),
            vec![0, 12, 23, 35, 46]
        );
        assert!("every:0".parse::<Holdout>().is_err());
        assert!("1,x".parse::<Holdout>().is_err());
        assert!("3,99".parse::<Holdout>().unwrap().indices(10).is_err());
        assert!("every:1".parse::<Holdout>().unwrap().indices(10).is_err());
    }

    #[test]
    fn psnr_follows_the_protocol() {
        let a = vec![0.5f32; 30];
        assert_eq!(protocol_scores(&a, &a, None), (100.0, 100.0));
        // One 8-bit step in every sample: MSE 1 → 48.13 dB.
        let t8 = crate::color::srgb8_table();
        let x: Vec<f32> = vec![t8[100]; 30];
        let y: Vec<f32> = vec![t8[101]; 30];
        assert!((protocol_scores(&x, &y, None).0 - 48.1308).abs() < 1e-3);
        // The mask restricts the linear figure only.
        let mut z = x.clone();
        z[0] = 1.0;
        let mask = vec![0.0f32, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        assert_eq!(protocol_scores(&z, &x, Some(&mask)).1, 100.0);
        assert!(protocol_scores(&z, &x, None).1 < 100.0);
    }
}
