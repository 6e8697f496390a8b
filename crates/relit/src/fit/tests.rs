use super::*;
use crate::basis::BasisSpec;
use crate::camera::Projection;
use crate::image::ImageRgb;
use crate::progress::Silent;
use crate::sphere::{fibonacci, grid, hemisphere_fibonacci, Vec3};

/// Pseudo-random coefficients for `pixels` pixels of a `bands`-band SH function, made
/// positive enough on the sphere that sRGB weights stay moderate.
fn known_coefficients(pixels: usize, k: usize) -> Vec<f64> {
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 33) as f64 / (1u64 << 31) as f64) - 0.5
    };
    (0..pixels * k * 3)
        .map(|x| {
            if (x / 3) % k == 0 {
                1.2 + 0.2 * next()
            } else {
                0.08 * next()
            }
        })
        .collect()
}

/// Images of the band-limited function with coefficients `coef` (pixel, i, c).
fn capture_of(coef: &[f64], w: usize, h: usize, bands: usize, dirs: &[Vec3]) -> Capture {
    let sh = BasisSpec::named(&format!("sh:{}", bands * bands))
        .unwrap()
        .build()
        .unwrap();
    let k = sh.len();
    let images = dirs
        .iter()
        .map(|&d| {
            let y = sh.values(d);
            let mut img = ImageRgb::new(w, h);
            for p in 0..w * h {
                for c in 0..3 {
                    img.data[3 * p + c] = (0..k)
                        .map(|i| coef[(p * k + i) * 3 + c] * y[i])
                        .sum::<f64>() as f32;
                }
            }
            img
        })
        .collect();
    Capture::from_memory(images, dirs, Projection::default()).unwrap()
}

fn max_coefficient_error(maps: &CoefficientMaps, coef: &[f64]) -> f64 {
    let k = maps.k;
    let mut worst = 0.0f64;
    for p in 0..maps.pixels() {
        for i in 0..k {
            for c in 0..3 {
                worst = worst.max((maps.plane(i, c)[p] as f64 - coef[(p * k + i) * 3 + c]).abs());
            }
        }
    }
    worst
}

fn options(bands: usize, objective: Objective, lambda: f64) -> FitOptions {
    FitOptions {
        basis: crate::fit::BasisRequest::parse(&format!("sh:{}", bands * bands)).unwrap(),
        objective,
        lambda: Lambda::Fixed(lambda),
        ..Default::default()
    }
}

/// f32 images and f32 maps bound how exactly coefficients come back.
const RECOVERY_TOLERANCE: f64 = 2e-4;

#[test]
fn recovers_known_coefficients_from_scattered_directions() {
    let (w, h, bands) = (5, 4, 4);
    let coef = known_coefficients(w * h, bands * bands);
    let capture = capture_of(&coef, w, h, bands, &fibonacci(200));
    for objective in [Objective::Linear, Objective::Perceptual] {
        let out = fit(&capture, &options(bands, objective, 1e-9), &Silent).unwrap();
        let err = max_coefficient_error(&out.image.maps, &coef);
        assert!(err < RECOVERY_TOLERANCE, "{objective:?}: max error {err}");
    }
}

#[test]
fn recovers_known_coefficients_from_the_upper_hemisphere() {
    // Hemisphere-only data determine a band-limited function only up to a badly
    // conditioned system (cond ~1e5 for 25 coefficients), so λ must be tiny and the
    // tolerance is looser; the point is that the solver does not break down.
    let (w, h, bands) = (4, 3, 3);
    let coef = known_coefficients(w * h, bands * bands);
    let capture = capture_of(&coef, w, h, bands, &hemisphere_fibonacci(120));
    let out = fit(&capture, &options(bands, Objective::Linear, 1e-10), &Silent).unwrap();
    let err = max_coefficient_error(&out.image.maps, &coef);
    assert!(err < 5e-3, "max error {err}");
}

#[test]
fn grid_quadrature_fit_equals_projection() {
    // On a full θ×φ grid the weighted fit of a band-limited function is exact as well.
    let (w, h, bands) = (3, 2, 3);
    let coef = known_coefficients(w * h, bands * bands);
    let capture = capture_of(&coef, w, h, bands, &grid(12, 24));
    let out = fit(&capture, &options(bands, Objective::Linear, 1e-9), &Silent).unwrap();
    assert!(max_coefficient_error(&out.image.maps, &coef) < RECOVERY_TOLERANCE);
}

#[test]
fn strips_do_not_change_the_perceptual_fit() {
    let plane = crate::synth::BumpyPlane {
        width: 24,
        height: 17,
    };
    let capture = plane.capture(&hemisphere_fibonacci(40));
    let mut opts = options(3, Objective::Perceptual, 1e-4);
    let whole = fit(&capture, &opts, &Silent).unwrap();
    opts.piece_bytes = 1; // one row per piece
    let strips = fit(&capture, &opts, &Silent).unwrap();
    assert!(strips.report.spill_bytes > 0);
    assert_eq!(whole.image.maps, strips.image.maps);
}

#[test]
fn fit_then_relight_reproduces_captured_and_new_lights() {
    let plane = crate::synth::BumpyPlane {
        width: 40,
        height: 30,
    };
    let dirs = hemisphere_fibonacci(80);
    let capture = plane.capture(&dirs);
    let sh25 = FitOptions {
        basis: BasisRequest::parse("sh:25").unwrap(),
        ..FitOptions::default()
    };
    let out = fit(&capture, &sh25, &Silent).unwrap();
    let check = |out: &FitOutput, d: Vec3| {
        let truth = plane.render(d);
        let relit = crate::engine::relight(
            &out.image,
            &crate::light::LightRig::new(vec![crate::light::Light::directional(d, [1.0; 3])]),
            &Default::default(),
        )
        .unwrap();
        crate::metrics::psnr_srgb8(&relit.data, &truth.data)
    };
    // The scene is a glossy surface whose shading has a kink at the terminator
    // (max(0, n·L)), which 25 SH coefficients round off: they follow it to ~35 dB.
    // 32 dB (~6 8-bit steps RMS) leaves margin; a broken fit gives < 20 dB.
    let captured = check(&out, dirs[17]);
    assert!(captured > 32.0, "captured light: {captured:.2} dB");
    let novel = check(&out, Vec3::new(0.3, -0.4, 0.75));
    assert!(novel > 32.0, "novel light: {novel:.2} dB");
    assert!(out.report.lambda > 0.0 && !out.report.lambda_scores.is_empty());
    // The default chooses its basis among the candidates and does at least as well.
    let auto = fit(&capture, &FitOptions::default(), &Silent).unwrap();
    assert!(
        auto.report.candidates.len() > 5,
        "{:?}",
        auto.report.candidates
    );
    assert_eq!(auto.report.basis, auto.report.candidates[0].basis);
    for d in [dirs[17], Vec3::new(0.3, -0.4, 0.75)] {
        let psnr = check(&auto, d);
        assert!(psnr > 32.0, "{}: {psnr:.2} dB", auto.report.basis);
    }
}

#[test]
fn display_maps_reproduce_srgb_values() {
    let plane = crate::synth::BumpyPlane {
        width: 20,
        height: 10,
    };
    let dirs = hemisphere_fibonacci(60);
    let capture = plane.capture(&dirs);
    let opts = FitOptions {
        color_space: Some(MapSpace::Srgb),
        ..Default::default()
    };
    let out = fit(&capture, &opts, &Silent).unwrap();
    assert_eq!(out.image.meta.color_space, MapSpace::Srgb);
    let d = dirs[5];
    let relit = crate::engine::relight(
        &out.image,
        &crate::light::LightRig::new(vec![crate::light::Light::directional(d, [1.0; 3])]),
        &Default::default(),
    )
    .unwrap();
    let psnr = crate::metrics::psnr_srgb8(&relit.data, &plane.render(d).data);
    assert!(psnr > 33.0, "{psnr}");
}

#[test]
fn fewer_images_than_coefficients_still_fit_with_ridge() {
    let plane = crate::synth::BumpyPlane {
        width: 8,
        height: 8,
    };
    let capture = plane.capture(&hemisphere_fibonacci(10));
    let out = fit(&capture, &FitOptions::default(), &Silent).unwrap();
    assert!(out.image.maps.data.iter().all(|v| v.is_finite()));
}

#[test]
fn below_the_horizon_stays_bounded() {
    // Unregularised hemisphere fits explode below the horizon; the automatic λ must
    // keep the extrapolation within a small multiple of the observed range.
    let plane = crate::synth::BumpyPlane {
        width: 16,
        height: 12,
    };
    let capture = plane.capture(&hemisphere_fibonacci(60));
    let out = fit(&capture, &FitOptions::default(), &Silent).unwrap();
    // Evaluated in the basis the fit chose (whatever `auto` picked).
    let basis = out.image.meta.basis.build().unwrap();
    let k = basis.len();
    let mut worst = 0.0f64;
    for d in fibonacci(200).into_iter().filter(|d| d.z < -0.2) {
        let y = basis.values(d);
        for p in 0..out.image.maps.pixels() {
            let v: f64 = (0..k)
                .map(|i| out.image.maps.plane(i, 1)[p] as f64 * y[i])
                .sum();
            worst = worst.max(v.abs());
        }
    }
    assert!(
        worst < 3.0,
        "below-horizon magnitude {worst} ({})",
        out.report.basis
    );
}

#[test]
fn the_automatic_objective_is_the_better_of_the_two_and_fits_exactly_as_it() {
    let plane = crate::synth::BumpyPlane {
        width: 24,
        height: 18,
    };
    let capture = plane.capture(&hemisphere_fibonacci(50));
    let with = |objective| {
        fit(
            &capture,
            &FitOptions {
                basis: crate::fit::BasisRequest::parse("sh:9").unwrap(),
                objective,
                ..Default::default()
            },
            &Silent,
        )
        .unwrap()
    };
    let auto = with(Objective::Auto);
    assert_ne!(auto.report.objective, Objective::Auto);
    let chosen = with(auto.report.objective);
    // Same objective, same λ, same maps: the pass-1 state kept for the other objective
    // changes nothing.
    assert_eq!(auto.report.lambda, chosen.report.lambda);
    assert_eq!(auto.image.maps, chosen.image.maps);
    assert_eq!(
        auto.report.spill_bytes > 0,
        auto.report.objective == Objective::Perceptual
    );

    // The choice is the one of smaller leave-one-out display error.
    let options = FitOptions {
        basis: crate::fit::BasisRequest::parse("sh:9").unwrap(),
        ..Default::default()
    };
    let sh9 = crate::basis::BasisChoice::parse("sh:9").unwrap();
    let design = Design::new(
        &capture.directions(),
        sh9.build(&[], None).unwrap(),
        options.regularizer,
    );
    let sub_idx = subsample_indices(capture.width * capture.height, options.subsample);
    let mut sub = vec![0f32; sub_idx.len() * design.n * 3];
    for j in 0..design.n {
        let img = capture.load(j).unwrap();
        for (s, &p) in sub_idx.iter().enumerate() {
            let o = (s * design.n + j) * 3;
            sub[o..o + 3].copy_from_slice(&img.data[3 * p..3 * p + 3]);
        }
    }
    let relevance = light_relevance(&sub, sub_idx.len(), design.n);
    let scores = |objective, ladder: &[f64]| {
        loo_scores(&design, &sub, sub_idx.len(), objective, ladder, &relevance)
    };
    // λ from the observation-weighted leave-one-out; the perceptual objective's display
    // error then with its reweighting pass, at that λ.
    let best = |objective| {
        *scores(objective, &LAMBDA_LADDER)
            .iter()
            .filter(|s| s.weighted.is_finite())
            .min_by(|a, b| a.weighted.total_cmp(&b.weighted))
            .unwrap()
    };
    let linear = best(LooObjective::Linear).display;
    let lambda = best(LooObjective::Perceptual { reweights: 0 }).lambda;
    let perceptual = scores(
        LooObjective::Perceptual {
            reweights: options.reweights,
        },
        &[lambda],
    )[0]
    .display;
    assert!(perceptual.is_finite() && linear.is_finite() && perceptual != linear);
    let expected = if perceptual < linear {
        Objective::Perceptual
    } else {
        Objective::Linear
    };
    assert_eq!(auto.report.objective, expected);
}

#[test]
fn black_images_do_not_count_in_the_objective_choice_but_dim_ones_do() {
    // Three images of two pixels: bright, grazing (a hundredth as bright) and black.
    let (count, n) = (2, 3);
    let mut sub = vec![0f32; count * n * 3];
    for s in 0..count {
        for c in 0..3 {
            sub[(s * n) * 3 + c] = 0.8;
            sub[(s * n + 1) * 3 + c] = 0.008;
        }
    }
    assert_eq!(light_relevance(&sub, count, n), vec![1.0, 1.0, 0.0]);
    // Nothing lit at all: every light counts (there is nothing better to go by).
    assert_eq!(
        light_relevance(&vec![0.0; count * n * 3], count, n),
        vec![1.0; 3]
    );
}

/// A render-like capture: every pixel a Lambertian surface (its own normal and albedo)
/// under a hard cast shadow — a wall whose edge crosses the sphere of light directions
/// at a per-pixel place — so that many samples are exactly black, as in the studio's
/// scenes.
fn hard_shadow_capture(w: usize, h: usize, dirs: &[Vec3]) -> Capture {
    let surface = |p: usize| {
        let (u, v) = ((p % w) as f64 / w as f64, (p / w) as f64 / h as f64);
        let normal = Vec3::new(0.4 * (u - 0.5), 0.8, 0.3 + 0.4 * v)
            .normalized()
            .unwrap();
        let wall = Vec3::new((6.0 * u).cos(), 0.3, (6.0 * u).sin())
            .normalized()
            .unwrap();
        let albedo = [0.2 + 0.6 * u, 0.5, 0.8 - 0.5 * v];
        (normal, wall, 0.5 * v - 0.25, albedo)
    };
    let images = dirs
        .iter()
        .map(|&d| {
            let mut img = ImageRgb::new(w, h);
            for p in 0..w * h {
                let (normal, wall, edge, albedo) = surface(p);
                let lit = if d.dot(wall) > edge {
                    normal.dot(d).max(0.0)
                } else {
                    0.0
                };
                for (dst, a) in img.data[3 * p..3 * p + 3].iter_mut().zip(albedo) {
                    *dst = (a * lit) as f32;
                }
            }
            img
        })
        .collect();
    Capture::from_memory(images, dirs, Projection::default()).unwrap()
}

/// Mean squared difference of the 8-bit sRGB codes of `fitted` relit at the lights
/// `held` of `capture` and the captured images there: what a person sees of a fit on
/// lights it did not see.
fn display_error_at(fitted: &FitOutput, capture: &Capture, held: &[usize]) -> f64 {
    let mut sum = crate::metrics::SquaredErrors::default();
    for &j in held {
        let rig = crate::light::LightRig::new(vec![crate::light::Light::directional(
            capture.lights[j].direction,
            [1.0; 3],
        )]);
        let relit = crate::engine::relight(&fitted.image, &rig, &Default::default()).unwrap();
        let e =
            crate::metrics::SquaredErrors::of(&relit.data, &capture.load(j).unwrap().data, None);
        sum.srgb8 += e.srgb8;
        sum.samples += e.samples;
    }
    sum.mse_srgb8()
}

/// The automatic objective decides on the capture's own training lights (leave-one-out);
/// on lights held out of the fit altogether it must not lose to either objective alone,
/// on a render with exactly black hard shadows (a dense full-sphere capture, where the
/// perceptual objective once won the choice and darkened the result several times) and
/// on a photograph-like capture.
#[test]
fn the_automatic_objective_is_never_worse_than_either_on_validation_lights() {
    let plane = crate::synth::BumpyPlane {
        width: 24,
        height: 18,
    };
    let cases = [
        ("render", hard_shadow_capture(24, 16, &fibonacci(400)), 4),
        ("photograph", plane.capture(&hemisphere_fibonacci(60)), 3),
    ];
    for (name, capture, bands) in cases {
        let held: Vec<usize> = (3..capture.len()).step_by(9).collect();
        let train: Vec<usize> = (0..capture.len()).filter(|j| !held.contains(j)).collect();
        let training = capture.subset(&train);
        let error = |objective| {
            let options = FitOptions {
                basis: crate::fit::BasisRequest::parse(&format!("sh:{}", bands * bands)).unwrap(),
                objective,
                ..Default::default()
            };
            let fitted = fit(&training, &options, &Silent).unwrap();
            (
                fitted.report.objective,
                display_error_at(&fitted, &capture, &held),
            )
        };
        let (chosen, auto) = error(Objective::Auto);
        let (_, linear) = error(Objective::Linear);
        let (_, perceptual) = error(Objective::Perceptual);
        let best = linear.min(perceptual);
        // 0.1 dB of display PSNR.
        assert!(
            auto <= best * 10f64.powf(0.01),
            "{name}: auto ({chosen:?}) {auto:.3} against linear {linear:.3}, perceptual {perceptual:.3}"
        );
    }
}

/// The linear objective's leave-one-out shares one factorisation across pixels; on
/// observations so dim that the perceptual weights are one constant (the sRGB curve's
/// linear toe), the per-pixel perceptual path solves the same weighted problem, so the
/// two must agree.
#[test]
fn shared_leave_one_out_equals_the_per_pixel_one() {
    let dirs = hemisphere_fibonacci(30);
    let sh = crate::basis::BasisChoice::parse("sh:9").unwrap();
    let design = Design::new(&dirs, sh.build(&[], None).unwrap(), Regularizer::Roughness);
    let count = 7;
    let sub: Vec<f32> = (0..count * dirs.len() * 3)
        .map(|i| 0.0005 + 0.002 * ((i * 37 % 101) as f32 / 101.0))
        .collect();
    let relevance = vec![1.0; dirs.len()];
    let ladder = [1e-5, 1e-3, 1e-1];
    let shared = loo_scores(
        &design,
        &sub,
        count,
        LooObjective::Linear,
        &ladder,
        &relevance,
    );
    let general = loo_scores(
        &design,
        &sub,
        count,
        LooObjective::Perceptual { reweights: 0 },
        &ladder,
        &relevance,
    );
    for (a, b) in shared.iter().zip(&general) {
        assert!(
            (a.display - b.display).abs() <= 1e-9 * b.display,
            "{a:?} {b:?}"
        );
        // Weighted errors are normalised by the total weight: the constant cancels.
        assert!(
            (a.weighted - b.weighted).abs() <= 1e-9 * b.weighted,
            "{a:?} {b:?}"
        );
    }
}

/// The reweighted perceptual leave-one-out, against refitting without each light in
/// turn: the pixel's weights as the fit makes them (the channels' mean observation
/// weights, then one pass of their normalised secant weights, shared), then held fixed
/// while each light is left out, the regularisation's total kept.
#[test]
fn the_reweighted_leave_one_out_is_each_light_refitted_without_it() {
    let dirs = hemisphere_fibonacci(24);
    let (n, k) = (dirs.len(), 9);
    let sh = crate::basis::BasisChoice::parse("sh:9").unwrap();
    let design = Design::new(&dirs, sh.build(&[], None).unwrap(), Regularizer::Roughness);
    let count = 3;
    // Channels of different brightness, well inside the curved part of the sRGB curve.
    let sub: Vec<f32> = (0..count * n * 3)
        .map(|i| (0.02 + 0.5 * ((i * 37 % 101) as f32 / 101.0)) * [1.0, 0.4, 0.1][i % 3])
        .collect();
    let relevance = vec![1.0; n];
    let lambda = 1e-3;
    let got = loo_scores(
        &design,
        &sub,
        count,
        LooObjective::Perceptual { reweights: 1 },
        &[lambda],
        &relevance,
    )[0];
    let solve = |w: &[f64], obs: &[f64], skip: Option<usize>, total: f64| -> Vec<f64> {
        let (mut m, mut b) = (vec![0.0; k * k], vec![0.0; k]);
        for j in (0..n).filter(|&j| Some(j) != skip) {
            let row = design.row(j);
            for r in 0..k {
                b[r] += w[j] * row[r] * obs[j];
                for c in 0..k {
                    m[r * k + c] += w[j] * row[r] * row[c];
                }
            }
        }
        design.regularize(&mut m, lambda, total);
        assert!(linalg::cholesky(&mut m, k));
        linalg::cholesky_solve(&m, k, &mut b);
        b
    };
    let predict = |j: usize, coef: &[f64]| -> f64 {
        design.row(j).iter().zip(coef).map(|(a, b)| a * b).sum()
    };
    let (mut weighted, mut weights, mut shown, mut seen) = (0.0, 0.0, 0.0, 0.0);
    for p in 0..count {
        let obs: Vec<Vec<f64>> = (0..3)
            .map(|c| (0..n).map(|j| sub[(p * n + j) * 3 + c] as f64).collect())
            .collect();
        let first: Vec<f64> = (0..n)
            .map(|j| design.q[j] * (0..3).map(|c| perceptual_weight(obs[c][j])).sum::<f64>() / 3.0)
            .collect();
        let total: f64 = first.iter().sum();
        let secants: Vec<Vec<f64>> = obs
            .iter()
            .map(|o| {
                let coef = solve(&first, o, None, total);
                (0..n)
                    .map(|j| design.q[j] * secant_weight(predict(j, &coef), o[j]))
                    .collect()
            })
            .collect();
        let w: Vec<f64> = (0..n)
            .map(|j| {
                secants
                    .iter()
                    .map(|s| s[j] / (s.iter().sum::<f64>() / n as f64))
                    .sum::<f64>()
                    / 3.0
            })
            .collect();
        let total: f64 = w.iter().sum();
        for o in &obs {
            for j in 0..n {
                let e = o[j] - predict(j, &solve(&w, o, Some(j), total));
                weighted += w[j] * e * e;
                weights += w[j];
                let d = srgb_shown(o[j]) - srgb_shown(o[j] - e);
                shown += design.q[j] * d * d;
                seen += design.q[j];
            }
        }
    }
    let (weighted, display) = (weighted / weights, shown / seen);
    assert!(
        (got.weighted - weighted).abs() <= 1e-9 * weighted,
        "{got:?}: refitted {weighted}"
    );
    assert!(
        (got.display - display).abs() <= 1e-9 * display,
        "{got:?}: refitted {display}"
    );
}

#[test]
fn the_basis_choice_judges_radiance_captures_in_linear_and_photographs_on_screen() {
    let plane = crate::synth::BumpyPlane {
        width: 16,
        height: 12,
    };
    let dirs = hemisphere_fibonacci(40);
    let few = |criterion| FitOptions {
        max_coefficients: 9,
        criterion,
        ..FitOptions::default()
    };
    // Rendered in memory: radiance.
    let rendered = plane.capture(&dirs);
    assert!(rendered.radiance_images());
    let linear = fit(&rendered, &few(None), &Silent).unwrap();
    assert!(linear
        .report
        .candidates
        .iter()
        .all(|c| c.criterion == Criterion::Linear));
    // The same candidates judged on screen score other PSNRs.
    let display = fit(&rendered, &few(Some(Criterion::Display)), &Silent).unwrap();
    assert!(display
        .report
        .candidates
        .iter()
        .all(|c| c.criterion == Criterion::Display));
    let psnr_of = |out: &FitOutput, name: &str| {
        out.report
            .candidates
            .iter()
            .find(|c| c.basis == name)
            .map(|c| c.psnr)
            .unwrap()
    };
    let name = &linear.report.candidates[0].basis;
    assert!((psnr_of(&linear, name) - psnr_of(&display, name)).abs() > 0.1);
    // 8-bit photographs of the same scene: judged on screen.
    let dir = tempfile::tempdir().unwrap();
    let lp = plane.write_lp_capture(dir.path(), &dirs).unwrap();
    let photos = Capture::open(&lp).unwrap();
    assert!(!photos.radiance_images());
    let judged = fit(&photos, &few(None), &Silent).unwrap();
    assert!(judged
        .report
        .candidates
        .iter()
        .all(|c| c.criterion == Criterion::Display));
}

#[test]
fn auto_chooses_among_the_candidates_it_is_given_and_scores_every_light() {
    let plane = crate::synth::BumpyPlane {
        width: 16,
        height: 12,
    };
    let dirs = hemisphere_fibonacci(40);
    let capture = plane.capture(&dirs);
    let given = ["ptm:6", "sh:9"];
    let options = FitOptions {
        candidates: given
            .iter()
            .map(|s| BasisChoice::parse(s).unwrap())
            .collect(),
        ..FitOptions::default()
    };
    let out = fit(&capture, &options, &Silent).unwrap();
    let mut judged: Vec<&str> = out
        .report
        .candidates
        .iter()
        .map(|c| c.basis.as_str())
        .collect();
    judged.sort_unstable();
    assert_eq!(judged, given);
    assert_eq!(out.report.basis, out.report.candidates[0].basis);
    for c in &out.report.candidates {
        assert_eq!(c.lights.len(), dirs.len());
        // The score is the weighted mean of the per-light PSNRs.
        let total: f64 = c.lights.iter().map(|l| l.0).sum();
        let mean = c.lights.iter().map(|l| l.0 * l.1).sum::<f64>() / total;
        assert!((mean - c.psnr).abs() < 1e-6 * c.psnr.abs(), "{c:?}");
    }
    // A candidate with as many coefficients as the folds leave lights is refused.
    let too_big = FitOptions {
        candidates: vec![BasisChoice::parse("sh:64").unwrap()],
        ..FitOptions::default()
    };
    assert!(fit(&capture, &too_big, &Silent).is_err());
}

#[test]
fn the_choice_screens_every_candidate_and_validates_only_its_finalists_in_full() {
    let plane = crate::synth::BumpyPlane {
        width: 24,
        height: 20,
    };
    let dirs = hemisphere_fibonacci(40);
    let capture = plane.capture(&dirs);
    let candidates: Vec<BasisChoice> = ["sh:4", "sh:9", "hsh:9", "ptm:6", "sg:9", "rbf:9"]
        .iter()
        .map(|s| BasisChoice::parse(s).unwrap())
        .collect();
    let with = |halving: Halving| {
        let options = FitOptions {
            candidates: candidates.clone(),
            halving,
            ..FitOptions::default()
        };
        fit(&capture, &options, &Silent).unwrap().report
    };
    let halving = Halving {
        screening_pixels: 32,
        finalists: 2,
        pixels: 256,
    };
    let report = with(halving);
    assert_eq!(report.candidates.len(), candidates.len());
    let full: Vec<&str> = report
        .candidates
        .iter()
        .filter(|c| c.pixels == 256)
        .map(|c| c.basis.as_str())
        .collect();
    // Two (candidate, variant) pairs reach the final round: one or two candidates.
    assert!((1..=2).contains(&full.len()), "{full:?}");
    assert!(report
        .candidates
        .iter()
        .all(|c| c.pixels == 256 || c.pixels == 32));
    assert_eq!(
        report.candidates[0].pixels, 256,
        "the chosen one is a finalist"
    );
    // Without a screening every candidate is validated in full.
    let report = with(Halving {
        screening_pixels: 256,
        ..halving
    });
    assert!(report.candidates.iter().all(|c| c.pixels == 256));
}

/// The perceptual fit's passes, written out plainly for one pixel at a time: the first
/// solve weighted by the mean over the channels of their observation weights
/// (`shared_first`), or by each channel's own; then one pass weighted by the mean over
/// the channels of the secants to each channel's prediction, each channel's secants
/// first divided by their mean over the lights (`shared_reweight`), or each channel by
/// its own secants.
fn plain_perceptual_fit(
    design: &Design,
    images: &[ImageRgb],
    lambda: f64,
    shared_first: bool,
    shared_reweight: bool,
) -> Vec<f64> {
    let (k, n) = (design.k, design.n);
    let pixels = images[0].width * images[0].height;
    let solve = |w: &[f64], obs: &[f64]| -> Vec<f64> {
        let (mut m, mut b) = (vec![0.0; k * k], vec![0.0; k]);
        for j in 0..n {
            let row = design.row(j);
            for r in 0..k {
                b[r] += w[j] * row[r] * obs[j];
                for c in 0..k {
                    m[r * k + c] += w[j] * row[r] * row[c];
                }
            }
        }
        design.regularize(&mut m, lambda, w.iter().sum());
        assert!(linalg::cholesky(&mut m, k));
        linalg::cholesky_solve(&m, k, &mut b);
        b
    };
    let mut out = vec![0.0; pixels * k * 3];
    for p in 0..pixels {
        let obs: Vec<Vec<f64>> = (0..3)
            .map(|c| images.iter().map(|im| im.data[3 * p + c] as f64).collect())
            .collect();
        let secants: Vec<Vec<f64>> = (0..3)
            .map(|c| {
                let first: Vec<f64> = (0..n)
                    .map(|j| match shared_first {
                        true => (0..3).map(|c| perceptual_weight(obs[c][j])).sum::<f64>() / 3.0,
                        false => perceptual_weight(obs[c][j]),
                    })
                    .collect();
                let coef = solve(&first, &obs[c]);
                (0..n)
                    .map(|j| {
                        let pred: f64 = design.row(j).iter().zip(&coef).map(|(a, b)| a * b).sum();
                        secant_weight(pred, obs[c][j])
                    })
                    .collect()
            })
            .collect();
        let mean_over_lights = |w: &[f64]| w.iter().sum::<f64>() / n as f64;
        let shared: Vec<f64> = (0..n)
            .map(|j| {
                (0..3)
                    .map(|c| secants[c][j] / mean_over_lights(&secants[c]))
                    .sum::<f64>()
                    / 3.0
            })
            .collect();
        for c in 0..3 {
            let weights = if shared_reweight {
                &shared
            } else {
                &secants[c]
            };
            for (i, v) in solve(weights, &obs[c]).into_iter().enumerate() {
                out[(p * k + i) * 3 + c] = v;
            }
        }
    }
    out
}

#[test]
fn the_perceptual_fit_weighs_a_pixels_channels_alike_in_every_pass() {
    // Four bands of data fitted with three, so that the weights matter, in colours whose
    // channels differ by 20× in radiance, so that their sRGB weights differ too.
    let (w, h) = (6, 4);
    let dirs = fibonacci(60);
    let data = capture_of(&known_coefficients(w * h, 16), w, h, 4, &dirs);
    let images: Vec<ImageRgb> = (0..dirs.len())
        .map(|j| {
            let mut img = data.load(j).unwrap();
            for px in img.data.chunks_exact_mut(3) {
                px[1] *= 0.3;
                px[2] *= 0.05;
            }
            img
        })
        .collect();
    let capture = Capture::from_memory(images.clone(), &dirs, Projection::default()).unwrap();
    let lambda = 1e-3;
    let opts = options(3, Objective::Perceptual, lambda);
    assert_eq!(opts.reweights, 1);
    let fitted = fit(&capture, &opts, &Silent).unwrap();
    let design = Design::new(
        &dirs,
        BasisSpec::named("sh:9").unwrap().build().unwrap(),
        opts.regularizer,
    );
    let error = |want: &[f64]| {
        let maps = &fitted.image.maps;
        let mut worst = 0f64;
        for p in 0..maps.pixels() {
            for i in 0..9 {
                for c in 0..3 {
                    let got = maps.plane(i, c)[p] as f64;
                    worst = worst.max((got - want[(p * 9 + i) * 3 + c]).abs());
                }
            }
        }
        worst
    };
    let shared = error(&plain_perceptual_fit(&design, &images, lambda, true, true));
    assert!(shared < 2e-5, "{shared}");
    // Either pass weighted per channel instead is far from the fit.
    for (first, reweight) in [(false, true), (true, false)] {
        let other = error(&plain_perceptual_fit(
            &design, &images, lambda, first, reweight,
        ));
        assert!(
            other > 10.0 * shared,
            "shared first pass {first}, shared reweight {reweight}: {other} against {shared}"
        );
    }
}
