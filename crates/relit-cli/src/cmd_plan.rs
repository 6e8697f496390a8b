//! `relit plan`: a capture's fit choices made once, for every part of a sharded fit.

use crate::shared::{refuse_overwriting_inputs, Bars, FitArgs};
use anyhow::Context;
use relit::capture::Capture;
use relit::fit::Plan;
use relit::fsutil::Output;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The capture: an RTI `.lp` file or a relit manifest `.json`.
    pub capture: PathBuf,
    /// The plan to write (JSON), for `relit fit --plan PLAN --tile I/N`.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub fit: FitArgs,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

/// The plans this version reads are at most this long (a plan holds a basis' tables:
/// a few hundred kilobytes at most); a larger file is not a plan.
const MAX_PLAN_BYTES: u64 = 64 << 20;

/// Read a plan written by `relit plan`.
pub fn read_plan(path: &Path) -> anyhow::Result<Plan> {
    let bytes = std::fs::metadata(path)
        .with_context(|| format!("reading the plan {}", path.display()))?
        .len();
    anyhow::ensure!(
        bytes <= MAX_PLAN_BYTES,
        "{} is {bytes} bytes: not a relit plan",
        path.display()
    );
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the plan {}", path.display()))?;
    let plan: Plan = serde_json::from_str(&text)
        .with_context(|| format!("{} is not a relit plan", path.display()))?;
    anyhow::ensure!(
        plan.format == Plan::FORMAT && plan.version == Plan::VERSION,
        "{} is not a relit plan of version {} (format `{}`, version {})",
        path.display(),
        Plan::VERSION,
        plan.format,
        plan.version
    );
    Ok(plan)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let options = args.fit.to_options()?;
    let outputs = [Output::file(&args.output)];
    refuse_overwriting_inputs(std::slice::from_ref(&args.capture), &outputs)?;
    let capture = Capture::open(&args.capture)?;
    refuse_overwriting_inputs(&capture.input_files(), &outputs)?;
    let start = std::time::Instant::now();
    let bars = Bars::new(args.quiet || args.json);
    let plan = relit::fit::plan(&capture, &options, &bars)?;
    let text = serde_json::to_string_pretty(&plan)?;
    relit::fsutil::write_bytes_atomically(&args.output, text.as_bytes())
        .with_context(|| format!("writing {}", args.output.display()))?;
    let seconds = start.elapsed().as_secs_f64();
    let basis = plan.basis.build()?.name();
    if args.json {
        let value = serde_json::json!({
            "output": args.output.display().to_string(),
            "basis": basis,
            "objective": plan.objective,
            "lambda": plan.lambda,
            "seconds": seconds,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!(
            "wrote {}: basis {basis}, {} objective, λ = {:.0e} ({:.2} s); fit parts with \
             `relit fit {} --plan {} --tile I/N`",
            args.output.display(),
            plan.objective.name(),
            plan.lambda,
            seconds,
            args.capture.display(),
            args.output.display()
        );
    }
    Ok(())
}
