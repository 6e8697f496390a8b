//! Fidelity on a real RTI capture from the shared data set, when it is present.

use relit::capture::Capture;
use relit::eval::{evaluate, EvalOptions, Holdout};
use std::path::PathBuf;

fn shared_item(name: &str) -> Option<PathBuf> {
    relit::skip::shared(&format!("data/realrti/{name}/dirs.lp"))
}

/// The peer protocol (five hold-outs at round(i·(N−1)/4), half-float maps): one fit per
/// hold-out, or one `joint` fit without all five.
fn peer_protocol(fit: relit::fit::FitOptions, joint: bool) -> EvalOptions {
    EvalOptions {
        holdout: Holdout::Spread(5),
        fit,
        storage: relit::storage::Precision::F16,
        joint,
        mask: None,
        compress: None,
        budget: None,
        budget_bases: 1,
    }
}

/// `item` evaluated under the peer protocol, one fit per hold-out, at the fixed basis
/// `basis` and the maps' space `space` (`None`: chosen); `None` where the shared data
/// is absent.
fn fixed_basis_eval(
    item: &str,
    basis: &str,
    space: Option<relit::maps::MapSpace>,
) -> Option<relit::eval::EvalReport> {
    let capture = Capture::open(&shared_item(item)?).unwrap();
    let fit = relit::fit::FitOptions {
        basis: relit::fit::BasisRequest::Fixed(relit::basis::BasisChoice::parse(basis).unwrap()),
        color_space: space,
        ..Default::default()
    };
    let options = peer_protocol(fit, false);
    Some(evaluate(&capture, &options, &relit::progress::Silent).unwrap())
}

/// item1 (60 lights, 487×439, a painted wooden door) under the peer protocol: five
/// hold-outs at round(i·(N−1)/4), one fit each on the other 59, the default fit
/// (`--basis auto`, ≤ 25 coefficients), 8-bit sRGB PSNR over the whole frame.
///
/// Floor: 34.04 dB, the best figure the RTI tool relight-cli reaches on this item with
/// any basis (HSH, 27 coefficients, fitted in sRGB; shared/reference/peer_baseline.md).
/// relit measures ~37.0 dB here; falling under the peer's best means a regression.
#[test]
fn item1_beats_the_best_peer_figure() {
    let Some(lp) = shared_item("item1") else {
        return;
    };
    let capture = Capture::open(&lp).unwrap();
    assert_eq!(
        (capture.len(), capture.width, capture.height),
        (60, 487, 439)
    );
    let options = peer_protocol(Default::default(), false);
    let report = evaluate(&capture, &options, &relit::progress::Silent).unwrap();
    let indices: Vec<usize> = report.holdouts.iter().map(|h| h.index).collect();
    assert_eq!(indices, vec![0, 15, 30, 44, 59]);
    assert!(
        report.psnr_srgb8_mean > 34.04,
        "item1: {:.2} dB",
        report.psnr_srgb8_mean
    );
    assert!(
        report.psnr_linear_mean > 38.0,
        "item1 linear: {:.2} dB",
        report.psnr_linear_mean
    );
}

/// The default objective never loses to a plain linear fit by more than 0.1 dB against
/// the captured truth (issue 19): item9 (48 lights, 279×289, the smallest item), the five
/// peer hold-outs left out of one joint fit, 8-bit sRGB and linear PSNR. Measured:
/// default 24.18 / 28.23 dB, linear 21.19 / 27.02.
#[test]
fn the_default_fit_never_loses_to_a_linear_fit_on_a_real_capture() {
    let Some(lp) = shared_item("item9") else {
        return;
    };
    let capture = Capture::open(&lp).unwrap();
    let run = |objective| {
        let fit = relit::fit::FitOptions {
            objective,
            ..Default::default()
        };
        let options = peer_protocol(fit, true);
        evaluate(&capture, &options, &relit::progress::Silent).unwrap()
    };
    let default = run(relit::fit::FitOptions::default().objective);
    let linear = run(relit::fit::Objective::Linear);
    for (what, d, l) in [
        ("sRGB8", default.psnr_srgb8_mean, linear.psnr_srgb8_mean),
        ("linear", default.psnr_linear_mean, linear.psnr_linear_mean),
    ] {
        assert!(
            d >= l - 0.1,
            "item9 {what}: default {d:.2} dB, linear {l:.2} dB"
        );
    }
}

/// A fixed analytic basis chooses its maps' space on a real capture, as `auto` does:
/// item6 (48 lights, 321×321) at `--basis hsh:9`, relight-cli's HSH-27, under the peer
/// protocol. Until 2026-12-07 a fixed analytic basis kept linear maps (37.65 dB: the
/// perceptual objective at the λ of its leave-one-out); its display-referred maps score
/// 39.49 dB, above relight-cli's 39.44 dB with the same basis fitted in sRGB
/// (shared/reference/peer_baseline.md).
#[test]
fn a_fixed_analytic_basis_chooses_its_maps_space_on_a_real_capture() {
    let Some(report) = fixed_basis_eval("item6", "hsh:9", None) else {
        return;
    };
    assert_eq!(report.basis, "hsh:9");
    assert!(
        report.color_space.contains("srgb"),
        "item6 hsh:9 maps: {}",
        report.color_space
    );
    assert!(
        report.psnr_srgb8_mean > 39.0,
        "item6 hsh:9: {:.2} dB",
        report.psnr_srgb8_mean
    );
}

/// Display-referred maps asked for (`--space srgb`) with a fixed basis take the λ of the
/// validation `auto` uses: item9 at `sh:25`. The exact leave-one-out chose λ = 1e-7
/// there, which extrapolated badly to the grazing hold-outs (21.54 dB); the validation's
/// 1e-3 gives 24.74 (relight-cli's best on this item: 24.20, RBF-27).
#[test]
fn display_referred_maps_of_a_fixed_basis_take_the_validations_lambda() {
    let Some(report) = fixed_basis_eval("item9", "sh:25", Some(relit::maps::MapSpace::Srgb)) else {
        return;
    };
    assert!(
        report.psnr_srgb8_mean > 23.5,
        "item9 sh:25 display-referred: {:.2} dB",
        report.psnr_srgb8_mean
    );
}
