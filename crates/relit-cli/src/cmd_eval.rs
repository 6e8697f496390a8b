//! `relit eval`: fidelity against held-out captured lights, or (`--scene`) against the
//! studio's ray-traced truth under every light type.

use crate::shared::{
    mib, parse_basis, refuse_overwriting_inputs, rig_inputs, scene_inputs, Bars, CompressArgs,
    FitArgs,
};
use relit::capture::Capture;
use relit::eval::{evaluate_with, EvalOptions, Holdout};
use relit::fit::BasisRequest;
use relit::storage::Precision;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
#[command(group = clap::ArgGroup::new("rd_source").args(["rd", "rd_report"]))]
pub struct Args {
    /// The capture: an RTI `.lp` file or a relit manifest `.json`.
    #[arg(required_unless_present_any = ["scene", "rd_report"], conflicts_with = "scene")]
    pub capture: Option<PathBuf>,
    /// Instead of a capture: a studio scene (attic, city, box, .obj or scene .json) to
    /// capture, fit, and relight under each light of `--rig` against ray-traced truth.
    #[arg(long)]
    pub scene: Option<String>,
    /// With --scene: the lights to test (rig JSON); default one light of each type.
    #[arg(long, requires = "scene")]
    pub rig: Option<PathBuf>,
    /// With --scene: the captured light plan (`fibonacci:N`, `grid:TxP`, `hemisphere:N`).
    #[arg(long, default_value = "fibonacci:300", requires = "scene")]
    pub lights: String,
    /// With --scene: camera (cylindrical[:FOV], equirect, perspective[:FOV]; default the scene's).
    #[arg(long, requires = "scene")]
    pub camera: Option<String>,
    /// With --scene: image size WIDTHxHEIGHT (default the scene's).
    #[arg(long, requires = "scene")]
    pub size: Option<String>,
    /// With --scene: samples per pixel of an environment light's ray-traced truth.
    #[arg(long, default_value_t = relit_studio::emitter::DEFAULT_ENVIRONMENT_SAMPLES, requires = "scene")]
    pub env_samples: usize,
    /// With --scene: also bake the scene's diffuse transfer (`relit bake`'s defaults, the
    /// fit basis' SH bands or 5) and score the baked maps beside the fitted ones under
    /// every light.
    #[arg(long)]
    pub bake: bool,
    /// Write each held-out (or, with --scene, each light's) captured or true image above
    /// its relit image as one 8-bit sRGB PNG, never scaled, into this folder; with
    /// --scene also `mask.png`, the pixels scored.
    #[arg(long)]
    pub save: Option<PathBuf>,
    /// Score this relightable file (EXR, .rlz, .ptm, .rti) at the captured lights of
    /// --holdout against the photographs, without fitting anything: how well a file from
    /// any tool reproduces the capture (lights it was fitted on score as training).
    #[arg(long)]
    pub file: Option<PathBuf>,
    /// With --file: what a `.ptm`/`.rti` file's values are, srgb (the formats'
    /// convention, the default) or linear (relight-cli's default output).
    #[arg(long, value_enum)]
    pub file_space: Option<crate::shared::SpaceArg>,
    /// Images to hold out: `every:N`, `spread:N` (N evenly spread; `spread:5` is the
    /// RTI peer-baseline protocol) or indices in capture order like `0,12,24,35,47`.
    #[arg(long, default_value = "spread:5")]
    pub holdout: String,
    /// Fit once without all held-out images (default: one fit per held-out image).
    #[arg(long)]
    pub joint: bool,
    /// Mask image (> 0.5 inside) restricting the linear PSNR.
    #[arg(long)]
    pub mask: Option<PathBuf>,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Precision the maps are stored (and scored) at: f16 (alias half) or f32 (alias
    /// float).
    #[arg(long, default_value = "f16")]
    pub storage: Precision,
    /// Store each fit as a compressed .rlz (settings below) instead of EXR: the file is
    /// written, read back and relit, and bits/pixel is its size on disk.
    #[arg(long)]
    pub compressed: bool,
    /// Store each fit compressed with the settings that score best on its own training
    /// lights within this many bits per pixel of the whole file.
    #[arg(long, conflicts_with = "compressed")]
    pub budget: Option<f64>,
    /// With --budget and the basis auto: fit and compress this many of auto's best
    /// finalists and keep the file whose validation score, with the error its
    /// compression adds at the training lights, is highest (1: auto's basis alone; 2,
    /// the default, took −0.04 to +0.34 dB on five RealRTI items, for about twice the
    /// time).
    #[arg(long = "budget-bases", requires = "budget", default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=8))]
    pub budget_bases: u16,
    #[command(flatten)]
    pub compress: CompressArgs,
    /// The rate–distortion curve instead of one evaluation: every --rd-basis fitted once
    /// per hold-out, each fit stored as the lossless EXR (--storage) and with every
    /// compression setting --budget chooses from, each a real file written, read back
    /// and relit; bits/pixel is its size on disk.
    #[arg(long, conflicts_with_all = [
        "scene", "compressed", "budget", "save", "basis",
        "layout", "components", "chroma", "bits", "codec", "tile",
    ])]
    pub rd: bool,
    /// With --rd: a basis of the curve, `auto` or `family:K` (repeat the flag for more;
    /// default sh:25 and rbf:25).
    #[arg(long = "rd-basis", requires = "rd", value_parser = parse_basis)]
    pub rd_basis: Vec<BasisRequest>,
    /// With --rd: at most N compression settings per basis, spread evenly over the grid
    /// (default all of it): a coarser, quicker curve.
    #[arg(long = "rd-settings", requires = "rd",
          value_parser = clap::value_parser!(u16).range(1..))]
    pub rd_settings: Option<u16>,
    /// With --rd or --rd-report: draw the curve (PSNR against bits/pixel, one series
    /// per basis, the Pareto front as a line) into this SVG file.
    #[arg(long, requires = "rd_source")]
    pub plot: Option<PathBuf>,
    /// Instead of computing a curve: show the one a `--rd --json` run stored in this
    /// file (its table, or its plot with --plot).
    #[arg(long, conflicts_with_all = ["capture", "scene"])]
    pub rd_report: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.scene.is_some() {
        return run_scene(args);
    }
    if args.rd || args.rd_report.is_some() {
        return crate::cmd_eval_rd::run(args);
    }
    use relit::fsutil::{Output, StagedFolder};
    let capture_path = args.capture.as_deref().expect("clap requires a capture");
    let outputs: Vec<Output> = args.save.iter().map(Output::folder).collect();
    refuse_overwriting_inputs(&[capture_path.to_path_buf()], &outputs)?;
    let capture = Capture::open(capture_path)?;
    refuse_overwriting_inputs(&capture.input_files(), &outputs)?;
    let holdout: Holdout = args.holdout.parse()?;
    let mask = load_mask(args.mask.as_deref(), &capture)?;
    if let Some(file) = &args.file {
        return score_file(&args, &capture, file, &holdout, mask.as_deref());
    }
    let options = EvalOptions {
        holdout,
        fit: args.fit.to_options()?,
        storage: args
            .storage
            .require(&[Precision::F32, Precision::F16], "--storage (OpenEXR)")?,
        joint: args.joint,
        mask,
        compress: args.compressed.then(|| args.compress.settings()),
        budget: args.budget,
        budget_bases: args.budget_bases.into(),
    };
    let bars = Bars::new(args.quiet || args.json);
    let staged = args.save.as_deref().map(StagedFolder::new).transpose()?;
    let mut save = |h: &relit::eval::HoldoutResult,
                    captured: &relit::image::ImageRgb,
                    relit: &relit::image::ImageRgb|
     -> relit::Result<()> {
        if let Some(staged) = &staged {
            let pair =
                relit::image::contact_sheet(&[captured.clone(), relit.clone()], 1, usize::MAX);
            let stem = std::path::Path::new(&h.image)
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            relit::image::save(&staged.file(format!("{}_{stem}.png", h.index))?, &pair, 0.0)?;
        }
        Ok(())
    };
    let report = evaluate_with(&capture, &options, &bars, Some(&mut save))?;
    if let Some(staged) = staged {
        staged.commit()?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    // Each fit's basis where `auto` chose differently for different hold-outs.
    let bases_differ = report
        .holdouts
        .iter()
        .any(|h| h.basis != report.holdouts[0].basis);
    println!(
        "{}: {} images of {}×{}, {} ({}), {} objective, {} maps, {}",
        report.capture,
        report.images,
        report.width,
        report.height,
        report.basis,
        if bases_differ {
            "each hold-out's below".to_string()
        } else {
            format!("{} coefficients", report.coefficients)
        },
        report.objective,
        report.storage,
        report.protocol
    );
    let basis_column = |b: &str| {
        if bases_differ {
            format!(" {b:>12}")
        } else {
            String::new()
        }
    };
    println!(
        "{:>6}  {:<24} {:>12} {:>12} {:>8} {:>8}{}",
        "index",
        "image",
        "sRGB8 dB",
        "linear dB",
        "λ",
        "fit s",
        basis_column("basis")
    );
    for h in &report.holdouts {
        println!(
            "{:>6}  {:<24} {:>12.2} {:>12.2} {:>8.0e} {:>8.2}{}",
            h.index,
            h.image,
            h.psnr_srgb8,
            h.psnr_linear,
            h.lambda,
            h.fit_seconds,
            basis_column(&h.basis)
        );
    }
    println!(
        "mean    {:<24} {:>12.2} {:>12.2}",
        if report.masked {
            "(linear inside mask)"
        } else {
            ""
        },
        report.psnr_srgb8_mean,
        report.psnr_linear_mean
    );
    println!(
        "stored maps: {:.1} bytes/pixel; fit {:.2} s each; peak memory {}",
        report.bytes_per_pixel,
        report.fit_seconds,
        mib(report.peak_rss_bytes)
    );
    Ok(())
}

/// The `--mask` image, checked against the capture's size.
pub fn load_mask(
    path: Option<&std::path::Path>,
    capture: &Capture,
) -> anyhow::Result<Option<Vec<f32>>> {
    let Some(path) = path else {
        return Ok(None);
    };
    let (w, h, values) = relit::image::load_scalar(path)?;
    anyhow::ensure!(
        (w, h) == (capture.width, capture.height),
        "mask {} is {w}×{h} but the capture is {}×{}",
        path.display(),
        capture.width,
        capture.height
    );
    Ok(Some(values))
}

/// The basis a bake beside a fit of `basis` uses: the fit's own when a bake can project
/// onto it (its coefficients come in bands), else the default.
fn bake_basis(basis: &relit::fit::BasisRequest) -> relit::basis::BasisSpec {
    match basis {
        relit::fit::BasisRequest::Fixed(choice) => relit::basis::BasisSpec::named(&choice.name())
            .ok()
            .filter(|spec| spec.build().is_ok_and(|b| b.coefficient_bands().is_some()))
            .unwrap_or_default(),
        relit::fit::BasisRequest::Auto => relit::basis::BasisSpec::default(),
    }
}

/// `--file`: relight a given file at the held-out lights and compare with the photographs.
fn score_file(
    args: &Args,
    capture: &Capture,
    file: &std::path::Path,
    holdout: &Holdout,
    mask: Option<&[f32]>,
) -> anyhow::Result<()> {
    use relit::light::{Light, LightRig};
    let mut image = relit::codec::read(file)?;
    crate::shared::apply_file_space(file, &mut image, args.file_space)?;
    anyhow::ensure!(
        (image.width(), image.height()) == (capture.width, capture.height),
        "{} is {}×{} but the capture is {}×{}",
        file.display(),
        image.width(),
        image.height(),
        capture.width,
        capture.height
    );
    let relighter = relit::engine::Relighter::new(&image)?;
    let directions = capture.directions();
    let mut rows = Vec::new();
    for index in holdout.indices(capture.len())? {
        let rig = LightRig::new(vec![Light::directional(directions[index], [1.0; 3])]);
        let relit = relighter.relight(&rig, &Default::default())?;
        let photo = capture.load(index)?;
        let score = relit::metrics::compare(&relit.data, &photo.data, mask);
        rows.push(serde_json::json!({
            "index": index,
            "image": capture.image_name(index),
            "psnr_srgb8": score.psnr_srgb8,
            "psnr_linear": score.psnr_linear,
        }));
    }
    let mean = |key: &str| {
        rows.iter()
            .map(|r| r[key].as_f64().unwrap_or(0.0))
            .sum::<f64>()
            / rows.len().max(1) as f64
    };
    let basis = image.meta.basis.build()?.name();
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "file": file.display().to_string(),
                "basis": basis,
                "color_space": image.meta.color_space.name(),
                "lights": rows,
                "psnr_srgb8_mean": mean("psnr_srgb8"),
                "psnr_linear_mean": mean("psnr_linear"),
            }))?
        );
        return Ok(());
    }
    println!(
        "{} ({basis}, {}) at {} captured lights of {}",
        file.display(),
        image.meta.color_space.name(),
        rows.len(),
        args.capture
            .as_deref()
            .unwrap_or(std::path::Path::new(""))
            .display()
    );
    println!(
        "{:>6}  {:<24} {:>12} {:>12}",
        "index", "image", "sRGB8 dB", "linear dB"
    );
    for r in &rows {
        println!(
            "{:>6}  {:<24} {:>12.2} {:>12.2}",
            r["index"].as_u64().unwrap_or(0),
            r["image"].as_str().unwrap_or(""),
            r["psnr_srgb8"].as_f64().unwrap_or(0.0),
            r["psnr_linear"].as_f64().unwrap_or(0.0)
        );
    }
    println!(
        "{:>6}  {:<24} {:>12.2} {:>12.2}",
        "",
        "mean",
        mean("psnr_srgb8"),
        mean("psnr_linear")
    );
    Ok(())
}

fn run_scene(args: Args) -> anyhow::Result<()> {
    use anyhow::Context;
    use relit::fsutil::{Output, StagedFolder};
    use relit_studio::scene_eval::{self, SceneEvalOptions};
    use relit_studio::{plan::LightPlan, render::Renderer, setup};

    let spec = args.scene.as_deref().expect("checked by the caller");
    // Only --save writes (the default rig's slide and sky go to a scratch folder).
    let outputs: Vec<Output> = args.save.iter().map(Output::folder).collect();
    let mut inputs = scene_inputs(spec, Some(&args.lights));
    inputs.extend(args.rig.as_deref().map(rig_inputs).unwrap_or_default());
    inputs.extend(args.mask.clone());
    refuse_overwriting_inputs(&inputs, &outputs)?;
    let scene =
        relit_studio::open_scene(spec).with_context(|| format!("opening scene `{spec}`"))?;
    refuse_overwriting_inputs(&scene.files, &outputs)?;
    let projection = args
        .camera
        .as_deref()
        .map(setup::parse_projection)
        .transpose()?;
    let size = args.size.as_deref().map(setup::parse_size).transpose()?;
    let camera = setup::scene_camera(&scene, projection.as_ref(), size)?;
    let options = SceneEvalOptions {
        plan: LightPlan::parse(&args.lights)?,
        fit: args.fit.to_options()?,
        environment_samples: args.env_samples,
        ..SceneEvalOptions::default()
    };
    let options = SceneEvalOptions {
        bake: args.bake.then(|| relit_studio::bake::BakeOptions {
            basis: bake_basis(&options.fit.basis),
            ..Default::default()
        }),
        ..options
    };
    let bars = Bars::new(args.quiet || args.json);
    // The default rig's slide and sky live in a scratch folder for the run.
    let (_scratch, scratch_path) = scene_eval::scratch_dir()?;
    let (rig, base) = match &args.rig {
        Some(path) => (
            relit::light::LightRig::load(path)
                .with_context(|| format!("reading the rig {}", path.display()))?,
            path.parent()
                .map(|p| p.to_path_buf())
                .unwrap_or_else(|| PathBuf::from(".")),
        ),
        None => {
            let gbuffer =
                Renderer::new(&scene, &camera, &options.render, &relit::progress::Silent)?;
            (
                scene_eval::default_rig(&camera, gbuffer.depth(), &scratch_path)?,
                scratch_path.clone(),
            )
        }
    };
    let staged = args.save.as_deref().map(StagedFolder::new).transpose()?;
    // Each light's truth above its relit image (8-bit sRGB, never scaled, so the reported
    // sRGB PSNR can be recomputed from the file), and the mask the figures are computed
    // over, when asked for.
    let mut save = |i: usize,
                    light: &relit::light::Light,
                    truth: &relit::image::ImageRgb,
                    relit: &relit::image::ImageRgb,
                    mask: &[f32]|
     -> relit::Result<()> {
        if let Some(staged) = &staged {
            let pair = relit::image::contact_sheet(&[truth.clone(), relit.clone()], 1, usize::MAX);
            let path = staged.file(format!("{i}_{}.png", light.kind()))?;
            relit::image::save(&path, &pair, 0.0)?;
            if i == 0 {
                let mut m = relit::image::ImageRgb::new(truth.width, truth.height);
                for (px, &v) in m.data.chunks_exact_mut(3).zip(mask) {
                    px.fill(if v > 0.5 { 1.0 } else { 0.0 });
                }
                relit::image::save(&staged.file("mask.png")?, &m, 0.0)?;
            }
        }
        Ok(())
    };
    let report = scene_eval::evaluate(
        &scene,
        &camera,
        &rig,
        &base,
        &options,
        &bars,
        Some(&mut save),
    )?;
    if let Some(staged) = staged {
        staged.commit()?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}: {}×{} {}, {} captured lights ({}), {} coefficients, {} objective; capture {:.1} s ({:.2} Mrays/s), fit {:.1} s",
        report.scene,
        report.width,
        report.height,
        report.projection,
        report.images,
        report.plan,
        report.coefficients,
        report.fit.objective.name(),
        report.capture_seconds,
        report.capture_rays_per_second / 1e6,
        report.fit.seconds
    );
    if let Some(bake) = &report.bake {
        println!(
            "baked: {} diffuse transfer in {:.1} s ({:.2} Mrays/s), sampling noise {:.2} %",
            bake.basis,
            bake.total_seconds,
            bake.rays_per_second / 1e6,
            100.0 * bake.relative_noise()
        );
    }
    println!(
        "{:<12} {:>10} {:>10} {:>11} {:>9} {:>26}{}",
        "light",
        "linear dB",
        "sRGB8 dB",
        "relight ms",
        "truth s",
        "occlusion: px  in / out dB",
        if report.bake.is_some() {
            "   baked: linear / sRGB8 dB"
        } else {
            ""
        }
    );
    for l in &report.lights {
        let occlusion = match &l.occlusion {
            Some(o) => format!(
                "{:>5.1}%  {} / {}",
                100.0 * o.affected_fraction,
                o.affected
                    .map_or("  -  ".into(), |p| format!("{:5.1}", p.psnr_linear)),
                o.clear
                    .map_or("  -  ".into(), |p| format!("{:5.1}", p.psnr_linear))
            ),
            None => "-".into(),
        };
        println!(
            "{:<12} {:>10.2} {:>10.2} {:>11.1} {:>9.2} {:>26}{}",
            l.kind,
            l.psnr_linear,
            l.psnr_srgb8,
            1e3 * l.relight_seconds,
            l.truth_seconds,
            occlusion,
            l.baked.as_ref().map_or(String::new(), |b| format!(
                "   {:>12.2} / {:.2}",
                b.psnr_linear, b.psnr_srgb8
            ))
        );
    }
    if !report.environment.is_empty() {
        println!("environment: SH relighting against brute force Σ_j w_j I_j over the captured images, linear dB against truth");
        println!(
            "  {:<6} {:<10} {:>7} {:>13} {:>7} {:>10} {:>11}",
            "light", "window", "SH", "brute force", "gap", "raw map", "SH vs raw"
        );
        for e in &report.environment {
            println!(
                "  {:<6} {:<10} {:>7.2} {:>13.2} {:>+7.2} {:>10.2} {:>+11.2}",
                e.light,
                e.window.name(),
                e.relit.psnr_linear,
                e.brute_force.psnr_linear,
                e.gain_linear_db,
                e.brute_force_raw.psnr_linear,
                e.gain_vs_raw_linear_db,
            );
        }
        println!("  (brute force: the same band-limited, windowed environment as the SH relighting; raw map: the full map)");
    }
    if !report.area.is_empty() {
        println!("area lights: emitter sampling error (linear dB against the same light relit with more samples) and against truth");
        println!(
            "  {:<6} {:>8} {:>14} {:>10} {:>11}",
            "light", "samples", "vs converged", "vs truth", "relight ms"
        );
        for a in &report.area {
            println!(
                "  {:<6} {:>8} {:>14.2} {:>10.2} {:>11.1}",
                a.light,
                a.samples,
                a.vs_converged.psnr_linear,
                a.vs_truth.psnr_linear,
                1e3 * a.relight_seconds
            );
        }
        if let Some(a) = report.area.first() {
            println!("  (converged: {} samples per pixel)", a.converged_samples);
        }
    }
    Ok(())
}
