//! `relit relight`: a fitted file under new lights, one image or an animated sequence.

use crate::shared::Bars;
use anyhow::{bail, Context};
use relit::codec::exr;
use relit::engine::{RelightOptions, Relighter};
use relit::light::{parse_triple, Light, LightRig, RigFile};
use relit::progress::Progress;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable EXR written by `relit fit`.
    pub file: PathBuf,
    /// A light: `dir:x,y,z` (toward the light; x right, y up, z toward the camera),
    /// `point:x,y,z` or `spot:px,py,pz/dx,dy,dz/cone_deg`. Repeatable; lights add up.
    #[arg(long = "light")]
    pub lights: Vec<String>,
    /// RGB colour of the light given at the same position (`--color 1,0.8,0.6`); white
    /// when absent. Repeatable.
    #[arg(long = "color")]
    pub colors: Vec<String>,
    /// A light-rig JSON file, or a keyframed animation (then give --frames and --out).
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Frames to render from an animated rig.
    #[arg(long)]
    pub frames: Option<usize>,
    /// Exposure in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f64,
    /// Output image: `.png`/`.jpg`/`.tif` (8-bit sRGB) or `.exr` (linear).
    #[arg(short, long, required_unless_present = "out")]
    pub output: Option<PathBuf>,
    /// Output folder of an animation's frames (`frame_0000.png`, …).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Frame file extension for --out: png or exr.
    #[arg(long, default_value = "png")]
    pub frame_format: String,
}

fn flag_lights(args: &Args) -> anyhow::Result<Vec<Light>> {
    if args.colors.len() > args.lights.len() {
        bail!(
            "{} --color given for {} --light",
            args.colors.len(),
            args.lights.len()
        );
    }
    let mut lights = Vec::new();
    for (i, spec) in args.lights.iter().enumerate() {
        let mut light = Light::parse_spec(spec)?;
        if let Some(color) = args.colors.get(i) {
            let rgb =
                parse_triple(color).map_err(|e| anyhow::anyhow!("bad --color `{color}`: {e}"))?;
            light.set_color(rgb);
        }
        lights.push(light);
    }
    Ok(lights)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let extra = flag_lights(&args)?;
    let resource_dir = args
        .rig
        .as_deref()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let rig_file = args.rig.as_deref().map(RigFile::load).transpose()?;
    let options = RelightOptions {
        exposure: args.exposure,
        resource_dir,
    };
    let image = exr::read(&args.file)?;
    let relighter = Relighter::new(&image)?;

    if let Some(RigFile::Animation(anim)) = &rig_file {
        let frames = args.frames.context("an animated rig needs --frames N")?;
        anyhow::ensure!(frames >= 1, "--frames must be at least 1");
        let out = args
            .out
            .as_ref()
            .context("an animated rig needs --out FOLDER")?;
        anyhow::ensure!(
            args.frame_format == "png" || args.frame_format == "exr",
            "--frame-format is png or exr"
        );
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        let rigs = anim.frames(frames)?;
        let bars = Bars::new(false);
        bars.begin("relighting frames", frames as u64);
        let start = std::time::Instant::now();
        for (f, mut rig) in rigs.into_iter().enumerate() {
            rig.lights.extend(extra.iter().cloned());
            let frame = relighter.relight(&rig, &options)?;
            let path = out.join(format!("frame_{f:04}.{}", args.frame_format));
            relit::image::save(&path, &frame, 0.0)
                .with_context(|| format!("writing {}", path.display()))?;
            bars.advance(1);
        }
        bars.end();
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "wrote {frames} frames to {} in {seconds:.2} s ({:.1} ms per frame, writing included)",
            out.display(),
            1e3 * seconds / frames as f64
        );
        return Ok(());
    }

    let mut lights = extra;
    if let Some(RigFile::Rig(rig)) = rig_file {
        lights.extend(rig.lights);
    }
    if lights.is_empty() {
        bail!("no lights: give --light dir:x,y,z (repeatable) or --rig RIG.json");
    }
    let output = args
        .output
        .as_ref()
        .context("give -o OUTPUT (or --out FOLDER with an animated --rig)")?;
    let rig = LightRig::new(lights);
    let start = std::time::Instant::now();
    let frame = relighter.relight(&rig, &options)?;
    let seconds = start.elapsed().as_secs_f64();
    relit::image::save(output, &frame, 0.0)
        .with_context(|| format!("writing {}", output.display()))?;
    println!(
        "wrote {} ({}×{}, {} light{}, relit in {:.1} ms)",
        output.display(),
        frame.width,
        frame.height,
        rig.lights.len(),
        if rig.lights.len() == 1 { "" } else { "s" },
        seconds * 1e3
    );
    Ok(())
}
