//! `relit capture`: render a synthetic capture with the studio's ray tracer.

use crate::shared::{refuse_overwriting_inputs, scene_inputs, Bars};
use anyhow::Context;
use relit::fsutil::Output;
use relit_studio::capture::{capture_to_folder, ImageFormat};
use relit_studio::plan::LightPlan;
use relit_studio::render::RenderOptions;
use std::path::PathBuf;

/// File format of the reference images.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum FormatArg {
    /// Half-float linear OpenEXR.
    Exr,
    /// 16-bit PNG of linear values clipped to [0, 1] (the manifest says `linear`).
    Png16,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scene: crate::shared::SceneArgs,
    /// Light plan: grid:THETAxPHI, fibonacci:N, hemisphere:N or list:FILE.
    #[arg(long)]
    pub lights: String,
    /// Output folder (created if needed).
    #[arg(long)]
    pub out: PathBuf,
    /// File format of the reference images.
    #[arg(long, value_enum, default_value_t = FormatArg::Exr)]
    pub format: FormatArg,
    /// Samples per pixel along each axis (2 = 2×2 antialiasing).
    #[arg(long, default_value_t = 1)]
    pub supersample: u32,
    /// Bounce rays per sample for one-bounce diffuse indirect light (0 = direct only).
    #[arg(long, default_value_t = 0)]
    pub indirect: u32,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let outputs = [Output::folder(&args.out)];
    refuse_overwriting_inputs(
        &scene_inputs(&args.scene.scene, Some(&args.lights)),
        &outputs,
    )?;
    let plan = LightPlan::parse(&args.lights)?;
    let options = RenderOptions {
        supersample: args.supersample,
        indirect_samples: args.indirect,
    };
    options.validate()?;
    let (scene, camera) = args.scene.open("capture", &outputs)?;
    let directions = plan.directions();
    if !args.json && !args.quiet {
        eprintln!(
            "relit capture: `{}` ({} triangles), {} {}×{}, {}",
            scene.name,
            scene.triangle_count(),
            camera.projection().name(),
            camera.width(),
            camera.height(),
            plan.describe()
        );
    }
    let format = match args.format {
        FormatArg::Exr => ImageFormat::Exr,
        FormatArg::Png16 => ImageFormat::Png16,
    };
    let bars = Bars::new(args.quiet || args.json);
    let result = capture_to_folder(
        &scene,
        &camera,
        &directions,
        &options,
        &args.out,
        format,
        &bars,
    )
    .with_context(|| format!("capturing into {}", args.out.display()))?;
    let s = &result.stats;
    if args.json {
        let mut value = serde_json::to_value(s)?;
        value["manifest"] = serde_json::json!(result.manifest.display().to_string());
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!(
            "wrote {} ({} images, depth, mask, .lp)",
            result.manifest.display(),
            s.lights
        );
        println!(
            "{:.2} s: G-buffer {:.2} s ({} rays), lights {:.2} s ({} shadow rays); {:.2} Mrays/s",
            s.total_seconds,
            s.gbuffer_seconds,
            s.primary_rays,
            s.lighting_seconds,
            s.shadow_rays,
            s.rays_per_second / 1e6
        );
    }
    Ok(())
}
