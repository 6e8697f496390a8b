//! `--budget N` choosing the basis too: `auto`'s best finalists, each fitted and given
//! its best file within the budget ([`crate::compress::budget::choose`]), and of those
//! the file whose basis' validation score, with the error its compression adds, is
//! highest ([`crate::compress::budget::choose_among`]).
//!
//! The basis `auto` chooses is the best lossless; within a budget another may lose
//! less to compression (its coefficients gather into fewer principal components, or
//! quantise more gently). The validation scores of `auto`'s finalists, measured on the
//! capture's own lights held out, judge the bases; the training lights judge only what
//! each basis' files lose. The evaluation hold-outs are never seen.

use crate::capture::Capture;
use crate::compress::budget::{self, Choice, Estimate, Offer, Sample, SampledOffer, Verdict};
use crate::fit::{self, BasisRequest, FitOptions, FitOutput, FitReport};
use crate::maps::Metadata;
use crate::progress::Progress;
use crate::{Error, ErrorKind, Result};
use std::path::Path;

/// What [`fit_within_budget`] made.
pub struct BudgetFit {
    /// The fit of the basis chosen.
    pub fit: FitOutput,
    /// Its file.
    pub choice: Choice,
    /// Every basis tried and how it was judged, `auto`'s choice first (empty when one
    /// basis only was tried).
    pub estimates: Vec<Estimate>,
}

/// Fit `capture` and choose its file within `bits_per_pixel`, among `auto`'s `bases`
/// best finalists (by validation score; the basis `auto` chooses always among them) when
/// the basis is `auto` and `bases` > 1, else of the one fit.
pub fn fit_within_budget(
    capture: &Capture,
    options: &FitOptions,
    bits_per_pixel: f64,
    bases: usize,
    progress: &dyn Progress,
) -> Result<BudgetFit> {
    let first = fit::fit(capture, options, progress)?;
    let others = others_to_try(&first.report, options, bases);
    if others.is_empty() {
        let choice = budget::choose(&first.image, capture, bits_per_pixel, progress)?;
        return Ok(BudgetFit {
            fit: first,
            choice,
            estimates: Vec::new(),
        });
    }
    let scores = first.report.candidates.clone();
    let mut fits = vec![first];
    for basis in &others {
        fits.push(fit::fit(capture, &alone(options, basis)?, progress)?);
    }
    let offers: Vec<Offer> = fits
        .iter()
        .map(|f| Offer {
            image: &f.image,
            validation: validation_of(&scores, &f.report.basis),
        })
        .collect();
    let (index, choice, estimates) =
        budget::choose_among(&offers, capture, bits_per_pixel, progress)?;
    let fit = fits.swap_remove(index);
    Ok(BudgetFit {
        fit,
        choice,
        estimates,
    })
}

/// What [`fit_to_file_within_budget`] wrote.
pub struct BudgetFile {
    /// The kept fit's metadata and report.
    pub meta: Metadata,
    pub report: FitReport,
    /// Its file.
    pub verdict: Verdict,
    /// Every basis tried ([`BudgetFit::estimates`]).
    pub estimates: Vec<Estimate>,
}

/// Fit `capture` and write to `output` its file within `bits_per_pixel`, chosen as
/// [`fit_within_budget`] chooses it. With `stream`, an image large enough to be judged
/// on a sample ([`Sample::of`]) is never held whole: each basis is fitted to a
/// temporary f32 OpenEXR file beside `output` ([`crate::codec::exr::fit_to_exr`]), its
/// sample read back from that file's windows, the scoring photographs' samples read a
/// few rows at a time, and the files of the best candidates packed from it a band of
/// rows at a time until one fits ([`crate::codec::packed::pack_in_bands`]): the same
/// choice and the same file as holding the maps (but for the fit's own seconds in its
/// metadata), in memory bounded by the sample and a band.
pub fn fit_to_file_within_budget(
    capture: &Capture,
    options: &FitOptions,
    bits_per_pixel: f64,
    bases: usize,
    output: &Path,
    stream: bool,
    progress: &dyn Progress,
) -> Result<BudgetFile> {
    let sample = Sample::of(capture.width, capture.height).filter(|_| stream);
    let Some(sample) = sample else {
        let made = fit_within_budget(capture, options, bits_per_pixel, bases, progress)?;
        crate::codec::packed::write_packed(output, &made.choice.packed)?;
        return Ok(BudgetFile {
            meta: made.fit.image.meta,
            report: made.fit.report,
            verdict: made.choice.verdict(),
            estimates: made.estimates,
        });
    };
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let fit_to_temporary =
        |options: &FitOptions| -> Result<(tempfile::TempPath, Metadata, FitReport)> {
            let path = tempfile::Builder::new()
                .prefix(".relit-budget-")
                .suffix(".exr")
                .tempfile_in(dir)
                .map_err(|e| {
                    Error::new(
                        ErrorKind::Io,
                        format!("cannot create a temporary file in {}", dir.display()),
                    )
                    .with_source(e)
                })?
                .into_temp_path();
            let (meta, report) = crate::codec::exr::fit_to_exr(
                capture,
                options,
                progress,
                &path,
                crate::storage::Precision::F32,
            )?;
            Ok((path, meta, report))
        };
    let mut fits = vec![fit_to_temporary(options)?];
    let others = others_to_try(&fits[0].2, options, bases);
    let scores = fits[0].2.candidates.clone();
    for basis in &others {
        fits.push(fit_to_temporary(&alone(options, basis)?)?);
    }
    let offers = fits
        .iter()
        .map(|(path, _, report)| {
            let (w, h) = sample.side;
            let windows = sample
                .windows
                .iter()
                .map(|&(x, y)| Ok(crate::codec::exr::read_region(path, 0, (x, y, w, h))?.image))
                .collect::<Result<Vec<_>>>()?;
            Ok(SampledOffer {
                sample: sample.image_of_windows(&windows)?,
                validation: validation_of(&scores, &report.basis),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let mut kept: Vec<Option<crate::codec::packed::PackedInBands>> =
        (0..fits.len()).map(|_| None).collect();
    let (index, verdict, estimates) = budget::choose_among_sampled(
        &offers,
        capture,
        &sample,
        bits_per_pixel,
        &mut |offer, settings| {
            let packed = crate::codec::packed::pack_in_bands(&fits[offer].0, settings, progress)?;
            let bytes = packed.bytes();
            kept[offer] = Some(packed);
            Ok(bytes)
        },
        progress,
    )?;
    kept[index]
        .as_ref()
        .ok_or_else(|| Error::invalid("the budget chose a file it had not packed"))?
        .write(output)?;
    let (_, meta, report) = fits.swap_remove(index);
    Ok(BudgetFile {
        meta,
        report,
        verdict,
        // One basis tried: nothing to compare (as `fit_within_budget` reports it).
        estimates: if others.is_empty() {
            Vec::new()
        } else {
            estimates
        },
    })
}

/// The bases besides `auto`'s choice in `report` that a budget over `bases` bases
/// tries: none for a fixed basis or a plan.
fn others_to_try(report: &FitReport, options: &FitOptions, bases: usize) -> Vec<String> {
    if matches!(options.basis, BasisRequest::Auto) && options.plan.is_none() {
        runners_up(report, bases.saturating_sub(1))
    } else {
        Vec::new()
    }
}

/// `options` with `auto` among `basis` alone: the same validation, objective and λ
/// choice as the first fit made for it.
fn alone(options: &FitOptions, basis: &str) -> Result<FitOptions> {
    Ok(FitOptions {
        candidates: vec![crate::basis::BasisChoice::parse(basis)?],
        ..options.clone()
    })
}

/// `basis`' validation score among `scores` (−∞ where it was not judged).
fn validation_of(scores: &[crate::fit::CandidateScore], basis: &str) -> f64 {
    scores
        .iter()
        .find(|c| c.basis == basis)
        .map_or(f64::NEG_INFINITY, |c| c.psnr)
}

/// The `count` finalists of `auto`'s choice in `report` (the candidates judged in full)
/// after the basis it chose, best validation score first.
fn runners_up(report: &FitReport, count: usize) -> Vec<String> {
    let candidates = &report.candidates;
    let full = candidates.iter().map(|c| c.pixels).max().unwrap_or(0);
    let mut finalists: Vec<_> = candidates
        .iter()
        .filter(|c| c.pixels == full && c.basis != report.basis && c.psnr.is_finite())
        .collect();
    finalists.sort_by(|a, b| b.psnr.total_cmp(&a.psnr));
    finalists
        .into_iter()
        .take(count)
        .map(|c| c.basis.clone())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisChoice;
    use crate::progress::Silent;

    #[test]
    fn a_large_budgeted_file_streamed_is_the_file_made_from_the_maps_held_whole() {
        // Above the sample's threshold: judged on a sample either way; streamed, the maps
        // wait in temporary files and the file is packed from one a band at a time.
        let capture = crate::synth::BumpyPlane {
            width: 1100,
            height: 560,
        }
        .capture(&crate::sphere::hemisphere_fibonacci(16));
        let options = FitOptions {
            candidates: ["sh:4", "hsh:4"]
                .iter()
                .map(|b| BasisChoice::parse(b).unwrap())
                .collect(),
            ..FitOptions::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let (held, streamed) = (dir.path().join("held.rlz"), dir.path().join("streamed.rlz"));
        let budget = 6.0;
        let whole = fit_to_file_within_budget(&capture, &options, budget, 2, &held, false, &Silent)
            .unwrap();
        let bands =
            fit_to_file_within_budget(&capture, &options, budget, 2, &streamed, true, &Silent)
                .unwrap();
        assert_eq!(whole.report.basis, bands.report.basis);
        let (a, b) = (&whole.verdict, &bands.verdict);
        assert_eq!(a.settings.describe(), b.settings.describe());
        assert_eq!(
            (a.score, a.within, a.judged_pixels),
            (b.score, b.within, b.judged_pixels)
        );
        // Each file's bits per pixel are its own bytes': the header holds the fit's
        // seconds, whose digits may take a few bytes more or less.
        for (made, path) in [(a, &held), (b, &streamed)] {
            let bytes = std::fs::metadata(path).unwrap().len() as f64;
            assert_eq!(made.bits_per_pixel, 8.0 * bytes / (1100.0 * 560.0));
        }
        assert!((a.bits_per_pixel - b.bits_per_pixel).abs() * 1100.0 * 560.0 / 8.0 <= 16.0);
        assert!(a.bits_per_pixel <= budget && a.judged_pixels < 1100 * 560);
        assert_eq!(whole.estimates.len(), 2, "both bases tried");
        for (a, b) in whole.estimates.iter().zip(&bands.estimates) {
            assert_eq!(
                (&a.basis, a.validation, a.lossless, a.compressed, a.estimate),
                (&b.basis, b.validation, b.lossless, b.compressed, b.estimate)
            );
        }
        // The same file but for the fit's wall time in its metadata.
        let read = |path| {
            let mut packed = crate::codec::packed::read_packed(path).unwrap();
            packed.header.meta.fit.as_mut().unwrap().seconds = 0.0;
            packed
        };
        let (a, b) = (read(&held), read(&streamed));
        assert_eq!(a.header, b.header);
        assert!(a.sections == b.sections, "the same sections");
        // The temporary files are gone.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn the_budget_over_bases_keeps_the_best_expected_file_of_autos_finalists() {
        let capture = crate::synth::BumpyPlane {
            width: 64,
            height: 48,
        }
        .capture(&crate::sphere::hemisphere_fibonacci(40));
        let options = FitOptions {
            candidates: ["sh:9", "sh:16", "hsh:9"]
                .iter()
                .map(|b| BasisChoice::parse(b).unwrap())
                .collect(),
            ..FitOptions::default()
        };
        let budget = 24.0;
        let one = fit_within_budget(&capture, &options, budget, 1, &Silent).unwrap();
        assert!(one.estimates.is_empty());
        let three = fit_within_budget(&capture, &options, budget, 3, &Silent).unwrap();
        let tried: Vec<&str> = three.estimates.iter().map(|e| e.basis.as_str()).collect();
        assert_eq!(tried.len(), 3, "{tried:?}");
        assert_eq!(tried[0], one.fit.report.basis, "auto's choice first");
        for e in &three.estimates {
            let listed = one
                .fit
                .report
                .candidates
                .iter()
                .find(|c| c.basis == e.basis)
                .unwrap();
            assert_eq!(e.validation, listed.psnr, "{}", e.basis);
            let expected = e.estimate.unwrap();
            assert!(expected <= e.validation, "{e:?}");
            assert!(e.compressed <= e.lossless + 1e-9, "{e:?}");
        }
        let kept = three
            .estimates
            .iter()
            .max_by(|a, b| a.estimate.unwrap().total_cmp(&b.estimate.unwrap()))
            .unwrap();
        assert_eq!(kept.basis, three.fit.report.basis);
        assert!(three.choice.bits_per_pixel <= budget);
        // The file of auto's own basis is what one basis gives.
        assert_eq!(three.estimates[0].compressed, one.choice.score);
        // A fixed basis tries no other.
        let fixed = FitOptions {
            basis: crate::fit::BasisRequest::parse("sh:9").unwrap(),
            ..FitOptions::default()
        };
        let alone = fit_within_budget(&capture, &fixed, budget, 3, &Silent).unwrap();
        assert!(alone.estimates.is_empty());
        assert_eq!(alone.fit.report.basis, "sh:9");
    }
}
