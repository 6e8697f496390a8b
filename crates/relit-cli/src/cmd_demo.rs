//! `relit demo`: the whole pipeline on a built-in scene, end to end, with timings and
//! fidelity against ground truth.
//!
//! capture (the attic panorama under a few hundred directional lights, ray traced by the
//! studio) → fit → relight frames with a moving directional light (compared with the
//! ray-traced truth) and a point light passing under the hanging chair (seed 000,
//! figure 13) → contact sheet, all under `--out` (default `./relit-demo/`).

use crate::shared::{mib, Bars};
use anyhow::Context;
use relit::camera::CameraSpec;
use relit::engine::{RelightOptions, Relighter};
use relit::fit::{self, FitOptions};
use relit::image::{self, ImageRgb};
use relit::light::{Light, LightRig};
use relit::sphere::{self, Vec3};
use relit_studio::render::{RenderOptions, Renderer};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder.
    #[arg(long, default_value = "relit-demo")]
    pub out: PathBuf,
    /// Built-in scene (attic, city, box), .obj or scene .json.
    #[arg(long, default_value = "attic")]
    pub scene: String,
    /// Number of captured lights (uniform over the sphere).
    #[arg(long, default_value_t = 300)]
    pub lights: usize,
    /// Frames of each animation.
    #[arg(long, default_value_t = 12)]
    pub frames: usize,
    /// Spherical-harmonic bands.
    #[arg(long, default_value_t = 5)]
    pub bands: usize,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The directional animation: once around the scene at 40° elevation.
fn moving_sun(frame: usize, frames: usize) -> Vec3 {
    let phi = std::f64::consts::TAU * frame as f64 / frames as f64;
    let elevation = 40f64.to_radians();
    Vec3::new(
        elevation.cos() * phi.cos(),
        elevation.sin(),
        elevation.cos() * phi.sin(),
    )
}

/// The point-light animation: from one side of the hanging chair to the other, below it.
fn moving_lamp(frame: usize, frames: usize) -> Vec3 {
    let s = if frames <= 1 {
        0.5
    } else {
        frame as f64 / (frames - 1) as f64
    };
    Vec3::new(0.3 + 2.4 * s, 0.35, -1.1)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.lights >= 1 && args.frames >= 1,
        "--lights and --frames must be at least 1"
    );
    let total = Instant::now();
    let frames_dir = args.out.join("frames");
    std::fs::create_dir_all(&frames_dir)
        .with_context(|| format!("creating {}", frames_dir.display()))?;
    let say = |s: String| {
        if !args.json {
            println!("{s}");
        }
    };
    let bars = Bars::new(args.json);

    let scene = relit_studio::open_scene(&args.scene)?;
    let camera = scene.camera.build()?;
    let (w, h) = (camera.width(), camera.height());
    say(format!(
        "relit demo: `{}` ({}) at {w}×{h}, {} captured lights, {} frames per animation → {}",
        scene.name,
        camera.projection().name(),
        args.lights,
        args.frames,
        args.out.display()
    ));

    let dirs = sphere::fibonacci(args.lights);
    let captured = relit_studio::capture::capture_in_memory(
        &scene,
        &camera,
        &dirs,
        &RenderOptions::default(),
        &bars,
    )?;
    let stats = &captured.stats;
    say(format!(
        "  capture   {:>7.2} s  ({:.1} M rays/s, {:.0} images/s)",
        stats.total_seconds,
        stats.rays_per_second / 1e6,
        args.lights as f64 / stats.total_seconds
    ));
    let mut capture = captured.capture;
    capture.camera = Some(CameraSpec::from(&camera));

    let options = FitOptions {
        basis: relit::basis::BasisSpec::Sh { bands: args.bands },
        ..Default::default()
    };
    let fitted = fit::fit(&capture, &options, &bars)?;
    drop(capture);
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

    let relighter = Relighter::new(&fitted.image)?;
    let truth = Renderer::new(
        &scene,
        &camera,
        &RenderOptions::default(),
        &relit::progress::Silent,
    )?;
    let relight_options = RelightOptions::default();
    let mut sheet_frames: Vec<ImageRgb> = Vec::new();
    let (mut sun_s, mut lamp_s) = (0.0, 0.0);
    let mut psnrs = Vec::with_capacity(args.frames);
    for f in 0..args.frames {
        let dir = moving_sun(f, args.frames);
        let rig = LightRig::new(vec![Light::directional(dir, [1.0, 0.95, 0.85])]);
        let t = Instant::now();
        let frame = relighter.relight(&rig, &relight_options)?;
        sun_s += t.elapsed().as_secs_f64();
        let mut reference = truth.render_directional(dir)?.image;
        for px in reference.data.chunks_exact_mut(3) {
            px[1] *= 0.95;
            px[2] *= 0.85;
        }
        psnrs.push(relit::eval::compare(&frame.data, &reference.data, None).0);
        image::save(&frames_dir.join(format!("sun_{f:03}.png")), &frame, 0.0)?;
        sheet_frames.push(frame);
    }
    for f in 0..args.frames {
        let lamp = Light::Point(relit::light::PointLight {
            position: moving_lamp(f, args.frames),
            color: [1.0, 0.8, 0.55],
            intensity: 1.5,
            attenuation: Default::default(),
        });
        let t = Instant::now();
        let frame = relighter.relight(&LightRig::new(vec![lamp]), &relight_options)?;
        lamp_s += t.elapsed().as_secs_f64();
        image::save(&frames_dir.join(format!("lamp_{f:03}.png")), &frame, 0.0)?;
        sheet_frames.push(frame);
    }
    let sheet = image::contact_sheet(&sheet_frames, 4, 2048);
    let sheet_path = args.out.join("contact-sheet.png");
    image::save(&sheet_path, &sheet, 0.0)?;
    let mean = psnrs.iter().sum::<f64>() / psnrs.len() as f64;
    let worst = psnrs.iter().cloned().fold(f64::INFINITY, f64::min);
    let sun_ms = 1e3 * sun_s / args.frames as f64;
    let lamp_ms = 1e3 * lamp_s / args.frames as f64;
    say(format!("  relight   {sun_ms:>7.2} ms per directional frame, {lamp_ms:.2} ms per point-light frame → {}", frames_dir.display()));
    say(format!("  fidelity  {mean:>7.2} dB mean 8-bit sRGB PSNR of the moving sun against ray-traced truth (worst {worst:.2} dB)"));
    say(format!(
        "  contact sheet {} (top rows: moving sun; bottom rows: lamp under the chair)",
        sheet_path.display()
    ));
    say(format!(
        "  total     {:>7.2} s",
        total.elapsed().as_secs_f64()
    ));
    if args.json {
        let value = serde_json::json!({
            "scene": scene.name, "width": w, "height": h, "lights": args.lights, "frames": args.frames,
            "capture": {"seconds": stats.total_seconds, "rays_per_second": stats.rays_per_second},
            "fit": r, "relight_ms_per_directional_frame": sun_ms, "relight_ms_per_point_frame": lamp_ms,
            "psnr_srgb8_mean": mean, "psnr_srgb8_min": worst, "total_seconds": total.elapsed().as_secs_f64(),
            "maps": maps_path, "contact_sheet": sheet_path,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
    }
    Ok(())
}
