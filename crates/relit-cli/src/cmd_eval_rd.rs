//! `relit eval CAPTURE --rd`: the rate–distortion curve (`relit::eval::rd`) as a table,
//! JSON, and an SVG plot.

use crate::cmd_eval::{load_mask, Args};
use crate::shared::{refuse_overwriting_inputs, Bars};
use anyhow::Context;
use relit::capture::Capture;
use relit::eval::rd::{curve, RdOptions, RdReport};
use relit::fit::BasisRequest;
use relit::fsutil::Output;
use relit::storage::Precision;

pub fn run(args: Args) -> anyhow::Result<()> {
    let outputs: Vec<Output> = args.plot.iter().map(Output::file).collect();
    if let Some(stored) = &args.rd_report {
        refuse_overwriting_inputs(std::slice::from_ref(stored), &outputs)?;
        let bytes =
            std::fs::read(stored).with_context(|| format!("reading {}", stored.display()))?;
        let report: RdReport = serde_json::from_slice(&bytes).with_context(|| {
            format!(
                "{} is not the JSON of `relit eval --rd --json`",
                stored.display()
            )
        })?;
        return show(&args, &report);
    }
    let capture_path = args.capture.as_deref().expect("clap requires a capture");
    let mut inputs = vec![capture_path.to_path_buf()];
    inputs.extend(args.mask.clone());
    refuse_overwriting_inputs(&inputs, &outputs)?;
    // The curve takes minutes to hours: a plot that cannot be written is refused first.
    if let Some(plot) = &args.plot {
        let folder = match plot.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => std::path::Path::new("."),
        };
        anyhow::ensure!(
            folder.is_dir(),
            "cannot write the plot {}: the folder {} does not exist",
            plot.display(),
            folder.display()
        );
    }
    let capture = Capture::open(capture_path)?;
    refuse_overwriting_inputs(&capture.input_files(), &outputs)?;
    let defaults = RdOptions::default();
    let options = RdOptions {
        holdout: args.holdout.parse()?,
        joint: args.joint,
        fit: args.fit.to_options()?,
        bases: if args.rd_basis.is_empty() {
            defaults.bases
        } else {
            args.rd_basis.clone()
        },
        lossless: args
            .storage
            .require(&[Precision::F32, Precision::F16], "--storage (OpenEXR)")?,
        max_settings: args.rd_settings.map(usize::from),
        mask: load_mask(args.mask.as_deref(), &capture)?,
    };
    let mut seen: Vec<String> = Vec::new();
    for basis in options.bases.iter().map(BasisRequest::name) {
        anyhow::ensure!(!seen.contains(&basis), "--rd-basis {basis} is given twice");
        seen.push(basis);
    }
    let bars = Bars::new(args.quiet || args.json);
    let report = curve(&capture, &options, &bars)?;
    show(&args, &report)
}

/// The plot (with --plot), then the table or the JSON.
fn show(args: &Args, report: &RdReport) -> anyhow::Result<()> {
    if let Some(path) = &args.plot {
        relit::fsutil::write_bytes_atomically(path, crate::rd_plot::svg(report).as_bytes())?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(report)?);
    } else {
        print_table(report);
    }
    Ok(())
}

fn print_table(report: &RdReport) {
    println!(
        "{}: {} images of {}×{}, {}, held out {:?}; {} points in {:.0} s",
        report.capture,
        report.images,
        report.width,
        report.height,
        report.protocol,
        report.holdouts,
        report.points.len(),
        report.seconds
    );
    for fit in &report.fits {
        println!(
            "  {}: fitted {} ({} coefficients), {:.2} s a fit, {} compression settings",
            fit.basis,
            fit.fitted.join(", "),
            fit.coefficients,
            fit.fit_seconds,
            fit.settings
        );
    }
    println!(
        "{:<14} {:<24} {:>10} {:>10} {:>10}  pareto",
        "basis",
        "storage",
        "bits/px",
        "sRGB8 dB",
        if report.masked {
            "linear dB (mask)"
        } else {
            "linear dB"
        }
    );
    for p in &report.points {
        println!(
            "{:<14} {:<24} {:>10.2} {:>10.2} {:>10.2}  {}",
            p.basis,
            p.storage,
            p.bits_per_pixel,
            p.psnr_srgb8,
            p.psnr_linear,
            if p.pareto { "*" } else { "" }
        );
    }
}
