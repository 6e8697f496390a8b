//! `relit bake`: relightable maps from a scene's geometry, without a capture (seed 003).

use crate::shared::{mib, refuse_overwriting_inputs, scene_inputs, Bars, CompressArgs};
use anyhow::Context;
use relit::basis::BasisSpec;
use relit::envmap::Window;
use relit::fsutil::Output;
use relit::storage::Precision;
use relit_studio::bake::{bake, BakeOptions, Transfer};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scene: crate::shared::SceneArgs,
    /// What to project: visibility (V), diffuse (albedo · cos · V) or bleeding (diffuse
    /// plus one-bounce interreflection, as `render-truth --indirect`).
    #[arg(long, default_value = "diffuse", value_parser = |s: &str| Transfer::parse(s).map_err(|e| e.to_string()))]
    pub transfer: Transfer,
    /// Spherical-harmonic bands (1–8), shorthand for `--basis sh:K` with K = bands².
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=8), conflicts_with = "basis")]
    pub bands: Option<u32>,
    /// The basis by its fit name: any whose coefficients come in bands (`sh:K`, K = 1, 4,
    /// 9, …, 64). Default: the fit's default, sh:25.
    #[arg(long, value_parser = |s: &str| BasisSpec::named(s).map_err(|e| e.to_string()))]
    pub basis: Option<BasisSpec>,
    /// Directions traced per camera sample (quasi-Monte Carlo).
    #[arg(long, default_value_t = 256)]
    pub samples: u32,
    /// Bounce rays per camera sample for `bleeding` (as `render-truth --indirect`).
    #[arg(long)]
    pub indirect: Option<u32>,
    /// Directions traced per bounce point for `bleeding`.
    #[arg(long, default_value_t = 64)]
    pub bounce_samples: u32,
    /// Band window applied to the baked coefficients: none, hann, lanczos or
    /// laplacian[:λ] (seed 003 §4.1). The default Laplacian window halves the top band
    /// against ringing around hard shadows; `none` keeps the exact projection.
    #[arg(long, default_value = "laplacian", value_parser = |s: &str| Window::parse(s).map_err(|e| e.to_string()))]
    pub window: Window,
    /// Lambertian surfaces only: drop the materials' glossy lobes (seed 003's diffuse
    /// transfer exactly). By default a surface's transfer is everything the camera sees
    /// it reflect, as a capture would record it.
    #[arg(long)]
    pub lambert: bool,
    /// Camera samples per pixel along each axis (2 = 2×2 antialiasing).
    #[arg(long, default_value_t = 1)]
    pub supersample: u32,
    /// The relightable file to write: OpenEXR, or compressed when it ends in `.rlz`.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub compress: CompressArgs,
    /// Precision of the stored maps: f16 (alias half) or f32 (alias float).
    #[arg(long, default_value = "f16")]
    pub storage: Precision,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    args.storage
        .require(&[Precision::F32, Precision::F16], "--storage (OpenEXR)")?;
    let options = BakeOptions {
        transfer: args.transfer,
        basis: match (args.basis, args.bands) {
            (Some(basis), _) => basis,
            (None, Some(bands)) => BasisSpec::named(&format!("sh:{}", bands * bands))?,
            (None, None) => BasisSpec::default(),
        },
        samples: args.samples,
        indirect: args.indirect.unwrap_or(match args.transfer {
            Transfer::Bleeding => 16,
            _ => 0,
        }),
        bounce_samples: args.bounce_samples,
        supersample: args.supersample,
        window: args.window,
        lambert: args.lambert,
    };
    options.validate()?;
    let outputs = [Output::file(&args.output)];
    refuse_overwriting_inputs(&scene_inputs(&args.scene.scene, None), &outputs)?;
    let (scene, camera) = args.scene.open("bake", &outputs)?;
    if !args.json && !args.quiet {
        eprintln!(
            "relit bake: `{}` ({} triangles), {} {}×{}, {} transfer onto {}, {} directions per sample{}",
            scene.name,
            scene.triangle_count(),
            camera.projection().name(),
            camera.width(),
            camera.height(),
            options.transfer.name(),
            options.basis.build()?.name(),
            options.samples,
            if options.transfer == Transfer::Bleeding {
                format!(
                    ", {} bounce rays × {} directions",
                    options.indirect, options.bounce_samples
                )
            } else {
                String::new()
            }
        );
    }
    let bars = Bars::new(args.quiet || args.json);
    let baked = bake(&scene, &camera, &options, &bars)?;
    relit::codec::write(
        &args.output,
        &baked.image,
        &relit::codec::WriteOptions {
            storage: args.storage,
            compress: args.compress.settings(),
            ..Default::default()
        },
    )
    .with_context(|| format!("writing {}", args.output.display()))?;
    let bytes = std::fs::metadata(&args.output)
        .map(|m| m.len())
        .unwrap_or(0);
    let s = &baked.stats;
    if args.json {
        let mut value = serde_json::to_value(s)?;
        value["output"] = serde_json::json!(args.output.display().to_string());
        value["transfer"] = serde_json::json!(options.transfer.name());
        value["file_bytes"] = serde_json::json!(bytes);
        value["relative_noise"] = serde_json::json!(s.relative_noise());
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!(
            "wrote {} ({}, {:.1} bytes/pixel)",
            args.output.display(),
            mib(Some(bytes)),
            bytes as f64 / (s.width * s.height) as f64
        );
        println!(
            "bake: {:.2} s (G-buffer {:.2} s, transfer {:.2} s), {} rays, {:.2} Mrays/s",
            s.total_seconds,
            s.gbuffer_seconds,
            s.transfer_seconds,
            s.rays,
            s.rays_per_second / 1e6
        );
        println!(
            "sampling noise: {:.2} % of the white-sky image (RMS standard error {:.4} on a mean of {:.4}; an upper estimate)",
            100.0 * s.relative_noise(),
            s.white_sky_noise,
            s.white_sky_mean
        );
    }
    Ok(())
}
