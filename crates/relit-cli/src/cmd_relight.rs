//! `relit relight`: a fitted file under new lights.

use anyhow::{bail, Context};
use relit::codec::exr;
use relit::engine::{self, RelightOptions};
use relit::light::{parse_triple, Light, LightRig};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable EXR written by `relit fit`.
    pub file: PathBuf,
    /// A light, e.g. `dir:0.3,0.5,0.8` (toward the light; x right, y up, z toward the
    /// camera). Repeatable; lights add up.
    #[arg(long = "light")]
    pub lights: Vec<String>,
    /// RGB colour of the light given at the same position (`--color 1,0.8,0.6`); white
    /// when absent. Repeatable.
    #[arg(long = "color")]
    pub colors: Vec<String>,
    /// A light-rig JSON file (its lights are added to any --light).
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Exposure in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f64,
    /// Output image: `.png`/`.jpg`/`.tif` (8-bit sRGB) or `.exr` (linear).
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.colors.len() > args.lights.len() {
        bail!("{} --color given for {} --light", args.colors.len(), args.lights.len());
    }
    let mut lights = Vec::new();
    for (i, spec) in args.lights.iter().enumerate() {
        let mut light = Light::parse_spec(spec)?;
        if let Some(color) = args.colors.get(i) {
            let rgb = parse_triple(color).map_err(|e| anyhow::anyhow!("bad --color `{color}`: {e}"))?;
            light.set_color(rgb);
        }
        lights.push(light);
    }
    if let Some(rig) = &args.rig {
        lights.extend(LightRig::load(rig)?.lights);
    }
    if lights.is_empty() {
        bail!("no lights: give --light dir:x,y,z (repeatable) or --rig RIG.json");
    }
    let rig = LightRig::new(lights);
    let image = exr::read(&args.file)?;
    let start = std::time::Instant::now();
    let frame = engine::relight(&image, &rig, &RelightOptions { exposure: args.exposure })?;
    let seconds = start.elapsed().as_secs_f64();
    relit::image::save(&args.output, &frame, 0.0).with_context(|| format!("writing {}", args.output.display()))?;
    println!(
        "wrote {} ({}×{}, {} light{}, relit in {:.1} ms)",
        args.output.display(),
        frame.width,
        frame.height,
        rig.lights.len(),
        if rig.lights.len() == 1 { "" } else { "s" },
        seconds * 1e3
    );
    Ok(())
}
