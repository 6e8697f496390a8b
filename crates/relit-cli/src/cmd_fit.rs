//! `relit fit`: capture in, relightable EXR out.

use crate::shared::{mib, refuse_overwriting_inputs, Bars, CompressArgs, FitArgs};
use anyhow::Context;
use relit::capture::Capture;
use relit::fsutil::Output;
use relit::storage::Precision;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The capture: an RTI `.lp` file or a relit manifest `.json`.
    pub capture: PathBuf,
    /// The relightable file to write: OpenEXR, or compressed when it ends in `.rlz`.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub fit: FitArgs,
    #[command(flatten)]
    pub compress: CompressArgs,
    /// Write the compressed file (`-o X.rlz`) whose settings relight the capture's own
    /// lights best within this many bits per pixel of the whole file.
    #[arg(long)]
    pub budget: Option<f64>,
    /// With --budget and the basis auto: fit and compress this many of auto's best
    /// finalists and keep the file whose validation score, with the error its
    /// compression adds at the training lights, is highest (1: auto's basis alone; 2,
    /// the default, took −0.04 to +0.34 dB on five RealRTI items, for about twice the
    /// time).
    #[arg(long = "budget-bases", requires = "budget", default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=8))]
    pub budget_bases: u16,
    /// Precision of the stored maps: f16 (alias half) or f32 (alias float).
    #[arg(long, default_value = "f16")]
    pub storage: Precision,
    /// Write the EXR tiled (tiles of this side, default 256) with mip levels, as `relit
    /// convert --mip-tiles` does, so that viewers and `relit relight --roi/--level` read
    /// only the tiles and level a view needs: the fit goes to a temporary file beside
    /// the output, which is then made into the pyramid a tile at a time. A `.rlz`
    /// output: tiles of this side with mip levels (`--mip`).
    #[arg(long, num_args = 0..=1, default_missing_value = "256")]
    pub mip_tiles: Option<usize>,
    /// Fit only part I of N (`I/N`, from 0): that band of rows, with the whole capture's
    /// choices, into an EXR that `relit merge` joins with the other parts into the
    /// single fit's file (docs/cluster.md: a Slurm job array).
    #[arg(long = "tile", value_name = "I/N", value_parser = parse_part)]
    pub part: Option<(usize, usize)>,
    /// Reuse the choices (basis, objective, λ) that `relit plan` made once for this
    /// capture instead of making them again: each `--tile` part then costs only its rows.
    #[arg(long, value_name = "PLAN.json")]
    pub plan: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `I/N` of `--tile`.
fn parse_part(s: &str) -> Result<(usize, usize), String> {
    let (i, n) = s
        .split_once('/')
        .ok_or_else(|| format!("expected I/N (part I of N, from 0), got `{s}`"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<usize>()
            .map_err(|_| format!("expected I/N with whole numbers, got `{s}`"))
    };
    let (i, n) = (parse(i)?, parse(n)?);
    if n == 0 || i >= n {
        return Err(format!(
            "part {i} of {n} does not exist: I runs from 0 to N−1"
        ));
    }
    Ok((i, n))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    args.storage
        .require(&[Precision::F32, Precision::F16], "--storage (OpenEXR)")?;
    let mut options = args.fit.to_options()?;
    options.shard = args.part;
    if let Some(path) = &args.plan {
        let plan = crate::cmd_plan::read_plan(path)?;
        // The plan's settings are the fit's: its colour space, regulariser, reweighting.
        options.color_space = Some(plan.color_space);
        options.regularizer = plan.regularizer;
        options.reweights = plan.reweights;
        options.plan = Some(plan);
    }
    anyhow::ensure!(
        args.part.is_none()
            || (args.budget.is_none()
                && relit::codec::FileForm::for_output(&args.output) == relit::codec::FileForm::Exr),
        "--tile writes one part of the lossless file: name the output `*.exr` (compress \
         the merged file, `relit merge … -o X.rlz`)"
    );
    anyhow::ensure!(
        args.budget.is_none()
            || relit::codec::FileForm::for_output(&args.output)
                == relit::codec::FileForm::Compressed,
        "--budget writes a compressed file: name the output `*.rlz`"
    );
    anyhow::ensure!(
        args.mip_tiles.is_none()
            || (args.part.is_none()
                && matches!(
                    relit::codec::FileForm::for_output(&args.output),
                    relit::codec::FileForm::Exr | relit::codec::FileForm::Compressed
                )),
        "--mip-tiles writes a whole EXR or .rlz file: name the output `*.exr` or `*.rlz`, \
         and tile the merged file of parts (`relit convert merged.exr -o X.exr --mip-tiles`)"
    );
    anyhow::ensure!(
        args.budget.is_none() || args.mip_tiles.is_none(),
        "--budget chooses the whole compression: give its file mip levels afterwards \
         (`relit convert X.rlz -o Y.rlz --mip-tiles` with the settings it reports)"
    );
    let outputs = [Output::file(&args.output)];
    let inputs: Vec<PathBuf> = std::iter::once(args.capture.clone())
        .chain(args.plan.clone())
        .collect();
    refuse_overwriting_inputs(&inputs, &outputs)?;
    let capture = Capture::open(&args.capture)?;
    refuse_overwriting_inputs(&capture.input_files(), &outputs)?;
    if !args.json && !args.quiet {
        eprintln!(
            "relit fit: {} images of {}×{} from {}, basis {}, {} objective",
            capture.len(),
            capture.width,
            capture.height,
            args.capture.display(),
            match &options.basis {
                relit::fit::BasisRequest::Auto if !options.candidates.is_empty() => format!(
                    "auto among {}",
                    options
                        .candidates
                        .iter()
                        .map(|c| c.name())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                relit::fit::BasisRequest::Auto =>
                    format!("auto (up to {} coefficients)", options.max_coefficients),
                relit::fit::BasisRequest::Fixed(choice) => choice.name(),
            },
            options.objective.name()
        );
    }
    let bars = Bars::new(args.quiet || args.json);
    let form = relit::codec::FileForm::for_output(&args.output);
    // The lossless file is written as the strips are solved (the maps are never held
    // whole). A compressed file whose settings need no whole-image step is packed a band
    // at a time from the fit's lossless file (f32: the values the fit holds); the other
    // forms need the whole image.
    let compress = relit::compress::Settings {
        directions: Some(capture.directions()),
        ..args.compress.settings_with_mip_tiles(args.mip_tiles)
    };
    let packed_in_bands = form == relit::codec::FileForm::Compressed
        && args.budget.is_none()
        && crate::shared::pack_in_bands(
            &compress,
            (capture.width, capture.height, options.max_coefficients),
        );
    // What `--budget` chose, for `--json`.
    let mut compression = None;
    let (meta, report) = if let (relit::codec::FileForm::Exr, Some(tile)) = (form, args.mip_tiles) {
        let level0 = crate::shared::temporary_beside(&args.output, ".relit-fit-", ".exr")?;
        let made = relit::codec::exr::fit_to_exr(&capture, &options, &bars, &level0, args.storage)
            .with_context(|| format!("writing {}", level0.display()))?;
        relit::codec::exr::write_tiled_from(&level0, &args.output, args.storage, tile)
            .with_context(|| format!("writing {}", args.output.display()))?;
        made
    } else if packed_in_bands {
        let level0 = crate::shared::temporary_beside(&args.output, ".relit-fit-", ".exr")?;
        let made =
            relit::codec::exr::fit_to_exr(&capture, &options, &bars, &level0, Precision::F32)
                .with_context(|| format!("writing {}", level0.display()))?;
        relit::codec::packed::write_in_bands(&level0, &args.output, &compress, &bars)
            .with_context(|| format!("writing {}", args.output.display()))?;
        made
    } else if form == relit::codec::FileForm::Exr {
        relit::codec::exr::fit_to_exr(&capture, &options, &bars, &args.output, args.storage)
            .with_context(|| format!("writing {}", args.output.display()))?
    } else if let (relit::codec::FileForm::Compressed, Some(budget)) = (form, args.budget) {
        // A large image's maps are not held: each basis tried waits in a temporary file
        // and the file chosen is packed from it a band at a time.
        let stream = crate::shared::pack_in_bands(
            &relit::compress::Settings::default(),
            (capture.width, capture.height, options.max_coefficients),
        );
        let made = relit::budget_fit::fit_to_file_within_budget(
            &capture,
            &options,
            budget,
            args.budget_bases.into(),
            &args.output,
            stream,
            &bars,
        )?;
        if !args.json && !args.quiet {
            print_budget(&capture, &made);
        }
        compression = Some(budget_json(&capture, &made));
        (made.meta, made.report)
    } else {
        let output = relit::fit::fit(&capture, &options, &bars)?;
        write_whole(&args, &capture, &output)
            .with_context(|| format!("writing {}", args.output.display()))?;
        (output.image.meta, output.report)
    };
    let bytes = std::fs::metadata(&args.output)
        .map(|m| m.len())
        .unwrap_or(0);
    let r = &report;
    let shard = meta.fit.as_ref().and_then(|f| f.shard);
    if args.json {
        let mut value = serde_json::to_value(r)?;
        value["output"] = serde_json::json!(args.output.display().to_string());
        value["file_bytes"] = serde_json::json!(bytes);
        value["bytes_per_pixel"] = serde_json::json!(bytes as f64 / (r.width * r.height) as f64);
        if let Some(shard) = shard {
            value["shard"] = serde_json::to_value(shard)?;
        }
        if let Some(compression) = compression {
            value["compression"] = compression;
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!(
            "wrote {} ({}, {:.1} bytes/pixel)",
            args.output.display(),
            relit::memory::mib(bytes),
            bytes as f64 / (r.width * r.height) as f64
        );
        match r.candidates.as_slice() {
            // Where the choice was close, say so: the runner-up's score beside it.
            [chosen, next, ..] if next.psnr > chosen.psnr => println!(
                "basis: {} (chosen by validation among {} candidates: {:.2} dB on its own \
                 lights held out, within the validation's noise of {} {:.2} dB and \
                 cheaper to fit)",
                r.basis,
                r.candidates.len(),
                chosen.psnr,
                next.basis,
                next.psnr
            ),
            [best, next, ..] => println!(
                "basis: {} (chosen by validation among {} candidates: {:.2} dB on its own \
                 lights held out; next {} {:.2} dB)",
                r.basis,
                r.candidates.len(),
                best.psnr,
                next.basis,
                next.psnr
            ),
            _ => println!("basis: {}", r.basis),
        }
        let chosen = if r.candidates.is_empty() {
            " (chosen by leave-one-out)"
        } else {
            " (chosen with the basis, by validation)"
        };
        println!(
            "fit: {:.2} s, {:.1} images/s, peak memory {}, {}{}, λ = {:.0e}{}",
            r.seconds,
            r.images_per_second,
            mib(r.peak_rss_bytes),
            match r.color_space {
                // Display-referred maps are fitted with the plain objective only.
                relit::maps::MapSpace::Srgb =>
                    "display-referred maps (sRGB values, plain least squares)".to_string(),
                relit::maps::MapSpace::Linear =>
                    format!("linear maps, {} objective", r.objective.name()),
            },
            // What was chosen: the maps' space and objective, or (linear maps asked
            // for) the objective alone.
            match (options.objective, options.color_space) {
                (relit::fit::Objective::Auto, None | Some(relit::maps::MapSpace::Linear)) => {
                    chosen
                }
                _ => "",
            },
            r.lambda,
            if !r.lambda_scores.is_empty() {
                " (chosen by leave-one-out)"
            } else if !r.candidates.is_empty() {
                " (chosen with the basis, by validation)"
            } else {
                " (fixed)"
            }
        );
        println!(
            "training residual: RMSE (linear) R {:.4} G {:.4} B {:.4}; 8-bit sRGB PSNR {:.2} dB",
            r.rmse_linear[0], r.rmse_linear[1], r.rmse_linear[2], r.psnr_srgb8
        );
        if let Some(shard) = shard {
            println!("{shard} (join the parts with `relit merge`)");
        }
    }
    Ok(())
}

/// What `--budget` chose, for `--json`: the settings, the file's bits per pixel, the
/// score at the capture's lights, the candidates within the budget, the pixels they were
/// judged on, and each basis tried.
fn budget_json(capture: &Capture, made: &relit::budget_fit::BudgetFile) -> serde_json::Value {
    let choice = &made.verdict;
    serde_json::json!({
        "settings": choice.settings.describe(),
        "bits_per_pixel": choice.bits_per_pixel,
        "score_srgb8": choice.score,
        "within": choice.within,
        "judged_pixels": choice.judged_pixels,
        "pixels": capture.width * capture.height,
        "bases": made.estimates,
    })
}

/// What `--budget` chose: the file, and each basis tried.
fn print_budget(capture: &Capture, made: &relit::budget_fit::BudgetFile) {
    let choice = &made.verdict;
    let pixels = capture.width * capture.height;
    let sampled = match choice.judged_pixels < pixels {
        true => format!(
            ", judged on a sample of {} of its {pixels} pixels",
            choice.judged_pixels
        ),
        false => String::new(),
    };
    eprintln!(
        "compression: {} ({:.1} bits/pixel, {:.2} dB on {} captured lights; {} candidates within the budget{sampled})",
        choice.settings.describe(),
        choice.bits_per_pixel,
        choice.score,
        relit::compress::budget::SCORING_LIGHTS.min(capture.len()),
        choice.within
    );
    for e in &made.estimates {
        match e.estimate {
            Some(estimate) => eprintln!(
                "  {}: validation {:.2} dB, training lights {:.2} lossless, {:.2} in its file: expected {:.2} dB{}",
                e.basis,
                e.validation,
                e.lossless,
                e.compressed,
                estimate,
                if e.basis == made.report.basis { " (kept)" } else { "" }
            ),
            None => eprintln!("  {}: no file within the budget", e.basis),
        }
    }
}

/// Write a fit held whole: compressed (by the compression flags), an RTI tool's file or
/// a web folder.
fn write_whole(
    args: &Args,
    capture: &Capture,
    output: &relit::fit::FitOutput,
) -> relit::Result<()> {
    relit::codec::write(
        &args.output,
        &output.image,
        &relit::codec::WriteOptions {
            storage: args.storage,
            compress: relit::compress::Settings {
                directions: Some(capture.directions()),
                ..args.compress.settings_with_mip_tiles(args.mip_tiles)
            },
            ..Default::default()
        },
    )
}
