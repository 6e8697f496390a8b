//! `relit render-truth`: the studio's ground truth under lights the engine relights with.

use crate::shared::{refuse_overwriting_inputs, rig_inputs, scene_inputs};
use anyhow::Context;
use relit::fsutil::Output;
use relit::light::{parse_triple, Light};
use relit_studio::emitter::Emitter;
use relit_studio::render::{RenderOptions, Renderer};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scene: crate::shared::SceneArgs,
    /// A light: `dir:x,y,z` (toward the light), `point:x,y,z` or
    /// `spot:px,py,pz/dx,dy,dz/cone_deg`; repeat for several.
    #[arg(long = "light")]
    pub lights: Vec<String>,
    /// A light rig JSON file (every light type: area, projector…), added to --light.
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// RGB colour of every --light, `r,g,b` (default white).
    #[arg(long)]
    pub color: Option<String>,
    /// The image to write: .exr (linear) or .png/.jpg/.tif (8-bit sRGB).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Exposure in stops applied when writing.
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f64,
    /// Samples per pixel along each axis (2 = 2×2 antialiasing).
    #[arg(long, default_value_t = 1)]
    pub supersample: u32,
    /// Bounce rays per sample for one-bounce diffuse indirect light (0 = direct only).
    #[arg(long, default_value_t = 0)]
    pub indirect: u32,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.exposure.is_finite(),
        "--exposure must be a finite number of stops"
    );
    let outputs = [Output::file(&args.output)];
    let mut inputs = scene_inputs(&args.scene.scene, None);
    inputs.extend(args.rig.as_deref().map(rig_inputs).unwrap_or_default());
    refuse_overwriting_inputs(&inputs, &outputs)?;
    let color = args
        .color
        .as_deref()
        .map(|c| parse_triple(c).map_err(|e| anyhow::anyhow!("bad --color `{c}`: {e}")))
        .transpose()?;
    let mut emitters = Vec::with_capacity(args.lights.len());
    for spec in &args.lights {
        let mut light = Light::parse_spec(spec)?;
        if let Some(c) = color {
            light.set_color(c);
        }
        emitters.push(Emitter::from_light(&light).with_context(|| format!("light `{spec}`"))?);
    }
    if let Some(rig) = &args.rig {
        emitters.extend(
            Emitter::from_rig_file(rig)
                .with_context(|| format!("reading the rig {}", rig.display()))?,
        );
    }
    anyhow::ensure!(!emitters.is_empty(), "give at least one --light or a --rig");
    let options = RenderOptions {
        supersample: args.supersample,
        indirect_samples: args.indirect,
    };
    options.validate()?;
    let (scene, camera) = args.scene.open("render-truth", &outputs)?;
    let start = std::time::Instant::now();
    let bars = crate::shared::Bars::new(args.quiet);
    let renderer = Renderer::new(&scene, &camera, &options, &bars)?;
    let rendered = renderer.render(&emitters);
    let seconds = start.elapsed().as_secs_f64();
    relit::image::save(&args.output, &rendered.image, args.exposure)
        .with_context(|| format!("writing {}", args.output.display()))?;
    if !args.quiet {
        println!(
            "wrote {} ({}×{} {}, {} light{}) in {:.2} s, {:.2} Mrays/s",
            args.output.display(),
            camera.width(),
            camera.height(),
            camera.projection().name(),
            emitters.len(),
            if emitters.len() == 1 { "" } else { "s" },
            seconds,
            (renderer.primary_rays() + rendered.rays) as f64 / seconds.max(1e-9) / 1e6
        );
    }
    Ok(())
}
