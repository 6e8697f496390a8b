//! `relit demo`: the whole pipeline on a built-in scene, end to end, with timings and
//! fidelity against ground truth.
//!
//! capture (the attic panorama under a few hundred directional lights, ray traced by the
//! studio) → fit → relight frames with a moving directional light and a point light
//! passing under the hanging chair (seed 000, figure 13), each compared with the
//! ray-traced truth → contact sheet, all under `--out` (default `./relit-demo/`). The
//! lamp's path is written as a keyframed rig (`lamp-animation.json`) and the frames are
//! rendered from it, so `relit relight --rig` replays it at any frame count. The
//! folder's files appear when the demo has finished (`relit::fsutil::StagedFolder`).

use crate::shared::{mib, refuse_overwriting_inputs, scene_inputs, Bars};
use relit::camera::CameraSpec;
use relit::engine::{RelightOptions, Relighter};
use relit::fit::{self, FitOptions};
use relit::fsutil::{Output, StagedFolder};
use relit::image::{self, ImageRgb};
use relit::light::{Animation, Keyframe, Light, LightRig};
use relit::sphere::{self, Vec3};
use relit_studio::emitter::Emitter;
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
    /// The basis: `auto` (chosen per capture by validation) or `family:K` (`sh:25`, …).
    #[arg(long, default_value = "auto", value_parser = crate::shared::parse_basis)]
    pub basis: relit::fit::BasisRequest,
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

/// The point-light animation: a warm lamp from one side of the hanging chair to the
/// other, below it, as two keyframes.
fn lamp_animation() -> Animation {
    let lamp = |x: f64| {
        Light::Point(relit::light::PointLight {
            position: Vec3::new(x, 0.35, -1.1),
            color: [1.0, 0.8, 0.55],
            intensity: 1.5,
            attenuation: Default::default(),
        })
    };
    Animation {
        keyframes: vec![
            Keyframe {
                time: 0.0,
                lights: vec![lamp(0.3)],
            },
            Keyframe {
                time: 1.0,
                lights: vec![lamp(2.7)],
            },
        ],
    }
}

/// Mean and worst PSNR (linear, 8-bit sRGB) of a sequence.
#[derive(Default)]
struct Fidelity {
    linear: Vec<f64>,
    srgb8: Vec<f64>,
}

impl Fidelity {
    fn add(&mut self, frame: &ImageRgb, truth: &ImageRgb) {
        let score = relit::metrics::compare(&frame.data, &truth.data, None);
        self.srgb8.push(score.psnr_srgb8);
        self.linear.push(score.psnr_linear);
    }
    fn mean(v: &[f64]) -> f64 {
        v.iter().sum::<f64>() / v.len().max(1) as f64
    }
    fn worst(v: &[f64]) -> f64 {
        v.iter().cloned().fold(f64::INFINITY, f64::min)
    }
    fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "psnr_srgb8_mean": Self::mean(&self.srgb8), "psnr_srgb8_min": Self::worst(&self.srgb8),
            "psnr_linear_mean": Self::mean(&self.linear), "psnr_linear_min": Self::worst(&self.linear),
        })
    }
    fn describe(&self) -> String {
        format!(
            "{:.2} dB linear, {:.2} dB 8-bit sRGB (worst {:.2} / {:.2})",
            Self::mean(&self.linear),
            Self::mean(&self.srgb8),
            Self::worst(&self.linear),
            Self::worst(&self.srgb8)
        )
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.lights >= 1 && args.frames >= 1,
        "--lights and --frames must be at least 1"
    );
    let total = Instant::now();
    let outputs = [Output::folder(&args.out)];
    refuse_overwriting_inputs(&scene_inputs(&args.scene, None), &outputs)?;
    let frames_dir = args.out.join("frames");
    let say = |s: String| {
        if !args.json {
            println!("{s}");
        }
    };
    let bars = Bars::new(args.json);

    let scene = relit_studio::open_scene(&args.scene)?;
    refuse_overwriting_inputs(&scene.files, &outputs)?;
    let staged = StagedFolder::new(&args.out)?;
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
        basis: args.basis.clone(),
        ..Default::default()
    };
    let fitted = fit::fit(&capture, &options, &bars)?;
    drop(capture);
    let maps_path = args.out.join("scene.exr");
    relit::codec::exr::write(
        &staged.file("scene.exr")?,
        &fitted.image,
        relit::storage::Precision::F16,
    )?;
    let r = &fitted.report;
    say(format!(
        "  fit       {:>7.2} s  ({}, {:.0} images/s, λ = {:.0e}, peak memory {}) → {}",
        r.seconds,
        r.basis,
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
    let (mut sun_fidelity, mut lamp_fidelity) = (Fidelity::default(), Fidelity::default());
    for f in 0..args.frames {
        let dir = moving_sun(f, args.frames);
        let sun = Light::directional(dir, [1.0, 0.95, 0.85]);
        let t = Instant::now();
        let frame = relighter.relight(&LightRig::new(vec![sun.clone()]), &relight_options)?;
        sun_s += t.elapsed().as_secs_f64();
        let reference = truth.render(&[Emitter::from_light(&sun)?]).image;
        sun_fidelity.add(&frame, &reference);
        image::save(&staged.file(format!("frames/sun_{f:03}.png"))?, &frame, 0.0)?;
        sheet_frames.push(frame);
    }
    let animation = lamp_animation();
    let animation_path = args.out.join("lamp-animation.json");
    relit::fsutil::write_bytes_atomically(
        &staged.file("lamp-animation.json")?,
        serde_json::to_string_pretty(&serde_json::json!({ "keyframes": &animation.keyframes }))?
            .as_bytes(),
    )?;
    for (f, rig) in animation.frames(args.frames)?.into_iter().enumerate() {
        let t = Instant::now();
        let frame = relighter.relight(&rig, &relight_options)?;
        lamp_s += t.elapsed().as_secs_f64();
        let emitters = rig
            .lights
            .iter()
            .map(Emitter::from_light)
            .collect::<Result<Vec<_>, _>>()?;
        lamp_fidelity.add(&frame, &truth.render(&emitters).image);
        image::save(
            &staged.file(format!("frames/lamp_{f:03}.png"))?,
            &frame,
            0.0,
        )?;
        sheet_frames.push(frame);
    }
    let sheet = image::contact_sheet(&sheet_frames, 4, 2048);
    let sheet_path = args.out.join("contact-sheet.png");
    image::save(&staged.file("contact-sheet.png")?, &sheet, 0.0)?;
    staged.commit()?;
    let sun_ms = 1e3 * sun_s / args.frames as f64;
    let lamp_ms = 1e3 * lamp_s / args.frames as f64;
    say(format!("  relight   {sun_ms:>7.2} ms per directional frame, {lamp_ms:.2} ms per point-light frame → {}", frames_dir.display()));
    say(format!(
        "  fidelity  moving sun against ray-traced truth: {}",
        sun_fidelity.describe()
    ));
    say(format!(
        "            lamp under the chair against ray-traced truth: {}",
        lamp_fidelity.describe()
    ));
    say(format!(
        "  contact sheet {} (top rows: moving sun; bottom rows: lamp under the chair)",
        sheet_path.display()
    ));
    say(format!(
        "  total     {:>7.2} s",
        total.elapsed().as_secs_f64()
    ));
    say("next:".into());
    say(format!(
        "  relit view {}                      # relight it interactively in the browser",
        maps_path.display()
    ));
    say(format!(
        "  relit relight {} --rig {} --frames 120 --out {}/lamp120   # the lamp at 120 frames",
        maps_path.display(),
        animation_path.display(),
        args.out.display()
    ));
    if args.json {
        let value = serde_json::json!({
            "scene": scene.name, "width": w, "height": h, "lights": args.lights, "frames": args.frames,
            "capture": {"seconds": stats.total_seconds, "rays_per_second": stats.rays_per_second},
            "fit": r, "relight_ms_per_directional_frame": sun_ms, "relight_ms_per_point_frame": lamp_ms,
            "sun": sun_fidelity.json(), "lamp": lamp_fidelity.json(),
            "psnr_srgb8_mean": Fidelity::mean(&sun_fidelity.srgb8), "psnr_srgb8_min": Fidelity::worst(&sun_fidelity.srgb8),
            "total_seconds": total.elapsed().as_secs_f64(),
            "maps": maps_path, "contact_sheet": sheet_path, "lamp_animation": animation_path,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
    }
    Ok(())
}
