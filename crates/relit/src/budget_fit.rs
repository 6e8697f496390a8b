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
use crate::compress::budget::{self, Choice, Estimate, Offer};
use crate::fit::{self, BasisRequest, FitOptions, FitOutput};
use crate::progress::Progress;
use crate::Result;

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
    let others = if matches!(options.basis, BasisRequest::Auto) && options.plan.is_none() {
        runners_up(&first, bases.saturating_sub(1))
    } else {
        Vec::new()
    };
    if others.is_empty() {
        let choice = budget::choose(&first.image, capture, bits_per_pixel, progress)?;
        return Ok(BudgetFit {
            fit: first,
            choice,
            estimates: Vec::new(),
        });
    }
    let scores = first.report.candidates.clone();
    let validation = |basis: &str| {
        scores
            .iter()
            .find(|c| c.basis == basis)
            .map_or(f64::NEG_INFINITY, |c| c.psnr)
    };
    let mut fits = vec![first];
    for basis in &others {
        // `auto` among this basis alone: the same validation, objective and λ choice as
        // the first fit made for it.
        let alone = FitOptions {
            candidates: vec![crate::basis::BasisChoice::parse(basis)?],
            ..options.clone()
        };
        fits.push(fit::fit(capture, &alone, progress)?);
    }
    let offers: Vec<Offer> = fits
        .iter()
        .map(|f| Offer {
            image: &f.image,
            validation: validation(&f.report.basis),
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

/// The `count` finalists of `auto`'s choice in `fitted` (the candidates judged in full)
/// after the basis it chose, best validation score first.
fn runners_up(fitted: &FitOutput, count: usize) -> Vec<String> {
    let candidates = &fitted.report.candidates;
    let full = candidates.iter().map(|c| c.pixels).max().unwrap_or(0);
    let mut finalists: Vec<_> = candidates
        .iter()
        .filter(|c| c.pixels == full && c.basis != fitted.report.basis && c.psnr.is_finite())
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
