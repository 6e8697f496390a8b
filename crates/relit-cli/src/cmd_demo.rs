//! `relit demo`: the whole pipeline on a built-in scene, end to end, with timings and
//! fidelity against ground truth.
//!
//! capture (the scene under a few hundred directional lights) → fit → relight frames with
//! a moving light → contact sheet, all under `--out` (default `./relit-demo/`).

use crate::shared::{mib, Bars};
use anyhow::Context;
use relit::engine::{self, RelightOptions};
use relit::fit::{self, FitOptions};
use relit::image::{self, ImageRgb};
use relit::light::{Light, LightRig};
use relit::sphere::{self, Vec3};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder.
    #[arg(long, default_value = "relit-demo")]
    pub out: PathBuf,
    /// Number of captured lights (spread over the upper hemisphere).
    #[arg(long, default_value_t = 300)]
    pub lights: usize,
    /// Frames of the moving-light animation.
    #[arg(long, default_value_t = 24)]
    pub frames: usize,
    /// Spherical-harmonic bands.
    #[arg(long, default_value_t = 5)]
    pub bands: usize,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The scene the demo captures: the analytic bumpy plane until the studio lands.
struct DemoScene(relit::synth::BumpyPlane);

impl DemoScene {
    fn name(&self) -> &'static str {
        "bumpy plane (analytic)"
    }
    fn size(&self) -> (usize, usize) {
        (self.0.width, self.0.height)
    }
    fn capture(&self, dirs: &[Vec3]) -> relit::capture::Capture {
        self.0.capture(dirs)
    }
    fn truth(&self, dir: Vec3) -> ImageRgb {
        self.0.render(dir)
    }
}

/// The animation's light: once around the scene at 35° elevation.
fn moving_light(frame: usize, frames: usize) -> Vec3 {
    let phi = std::f64::consts::TAU * frame as f64 / frames as f64;
    let elevation = 35f64.to_radians();
    Vec3::new(
        elevation.cos() * phi.cos(),
        elevation.cos() * phi.sin(),
        elevation.sin(),
    )
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.lights >= 1 && args.frames >= 1,
        "--lights and --frames must be at least 1"
    );
    let total = Instant::now();
    std::fs::create_dir_all(args.out.join("frames"))
        .with_context(|| format!("creating {}", args.out.display()))?;
    let scene = DemoScene(relit::synth::BumpyPlane {
        width: 512,
        height: 384,
    });
    let (w, h) = scene.size();
    let say = |s: String| {
        if !args.json {
            println!("{s}");
        }
    };
    say(format!(
        "relit demo: {} at {w}×{h}, {} lights, {} frames → {}",
        scene.name(),
        args.lights,
        args.frames,
        args.out.display()
    ));

    let t = Instant::now();
    let dirs = sphere::hemisphere_fibonacci(args.lights);
    let capture = scene.capture(&dirs);
    let capture_s = t.elapsed().as_secs_f64();
    say(format!(
        "  capture   {capture_s:>7.2} s  ({:.0} images/s)",
        args.lights as f64 / capture_s
    ));

    let options = FitOptions {
        basis: relit::basis::BasisSpec::Sh { bands: args.bands },
        ..Default::default()
    };
    let fitted = fit::fit(&capture, &options, &Bars::new(args.json))?;
    let maps_path = args.out.join("scene.exr");
    relit::codec::exr::write(&maps_path, &fitted.image, relit::codec::Storage::Half)?;
    let r = &fitted.report;
    say(format!(
        "  fit       {:>7.2} s  ({:.0} images/s, λ = {:.0e}, peak memory {}) → {}",
        r.seconds,
        r.images_per_second,
        r.lambda,
        mib(r.peak_rss_bytes),
        maps_path.display()
    ));

    let mut frames = Vec::with_capacity(args.frames);
    let mut relight_s = 0.0;
    let mut psnrs = Vec::with_capacity(args.frames);
    for f in 0..args.frames {
        let dir = moving_light(f, args.frames);
        let rig = LightRig::new(vec![Light::directional(dir, [1.0, 0.95, 0.9])]);
        let t = Instant::now();
        let frame = engine::relight(&fitted.image, &rig, &RelightOptions::default())?;
        relight_s += t.elapsed().as_secs_f64();
        let mut truth = scene.truth(dir);
        for px in truth.data.chunks_exact_mut(3) {
            px[1] *= 0.95;
            px[2] *= 0.9;
        }
        psnrs.push(relit::eval::compare(&frame.data, &truth.data, None).0);
        image::save(
            &args.out.join("frames").join(format!("frame_{f:03}.png")),
            &frame,
            0.0,
        )?;
        frames.push(frame);
    }
    let sheet = image::contact_sheet(&frames, 6, 1536);
    let sheet_path = args.out.join("contact-sheet.png");
    image::save(&sheet_path, &sheet, 0.0)?;
    let mean = psnrs.iter().sum::<f64>() / psnrs.len() as f64;
    let worst = psnrs.iter().cloned().fold(f64::INFINITY, f64::min);
    let per_frame_ms = 1e3 * relight_s / args.frames as f64;
    say(format!(
        "  relight   {per_frame_ms:>7.2} ms per frame ({:.0} fps), frames in {}",
        1e3 / per_frame_ms,
        args.out.join("frames").display()
    ));
    say(format!("  fidelity  {mean:>7.2} dB mean 8-bit sRGB PSNR against ground truth (worst frame {worst:.2} dB)"));
    say(format!("  contact sheet {}", sheet_path.display()));
    say(format!(
        "  total     {:>7.2} s",
        total.elapsed().as_secs_f64()
    ));
    if args.json {
        let value = serde_json::json!({
            "scene": scene.name(), "width": w, "height": h, "lights": args.lights, "frames": args.frames,
            "capture_seconds": capture_s, "fit": r, "relight_ms_per_frame": per_frame_ms,
            "psnr_srgb8_mean": mean, "psnr_srgb8_min": worst, "total_seconds": total.elapsed().as_secs_f64(),
            "maps": maps_path, "contact_sheet": sheet_path,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
    }
    Ok(())
}
