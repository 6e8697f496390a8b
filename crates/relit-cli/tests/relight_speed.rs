//! `relit relight --roi / --storage / --gpu` and `relit bench --write-maps`, end to end.

use relit::image::{load_linear, ImageRgb};
use std::path::Path;
use std::process::{Command, Output};

fn relit(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_relit"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("run relit");
    assert!(
        out.status.success(),
        "relit {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// |GPU − CPU| allowed for lights with a position, relative to the frame's peak. The
/// GPU reads the basis' weight table (`WeightTable::for_basis`, in half floats) where
/// the CPU's SH kernel evaluates the basis itself, so frames differ by the table's
/// error (relative RMS error ≤ 1e-3 of the weights; crates/relit-gpu/tests holds the
/// GPU to the table itself at 1e-5), and the output is written in half floats
/// (2⁻¹¹ relative). Measured here: 7.5e-4 of the peak for the point light, 7.8e-4 for
/// the point + projector + area rig.
const TABLE_BOUND: f32 = 2e-3;

fn load(path: &Path) -> ImageRgb {
    load_linear(path, None).expect("read the output")
}

fn max_abs(a: &ImageRgb, b: &ImageRgb) -> f32 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn region_storage_and_gpu_frames_agree_with_the_full_cpu_frame() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("maps.exr");
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    relit(&[
        "bench",
        "--write-maps",
        file.to_str().unwrap(),
        "--size",
        "70x20",
        "--k",
        "9",
    ]);
    let file = file.to_str().unwrap();
    for light in ["dir:0.3,0.5,0.8", "point:0.3,0.5,0.2"] {
        relit(&["relight", file, "--light", light, "-o", &p("full.exr")]);
        relit(&[
            "relight",
            file,
            "--light",
            light,
            "--roi",
            "11,3,40,9",
            "-o",
            &p("roi.exr"),
        ]);
        let full = load(Path::new(&p("full.exr")));
        let roi = load(Path::new(&p("roi.exr")));
        let crop = relit::engine::Roi {
            x: 11,
            y: 3,
            width: 40,
            height: 9,
        }
        .crop(&full);
        assert_eq!(max_abs(&roi, &crop), 0.0, "{light}: region vs crop");
        relit(&[
            "relight",
            file,
            "--light",
            light,
            "--storage",
            "u8",
            "-o",
            &p("u8.exr"),
        ]);
        let peak = full.data.iter().fold(0f32, |m, v| m.max(v.abs()));
        assert!(max_abs(&load(Path::new(&p("u8.exr"))), &full) < 0.05 * peak);

        if let Err(why) = relit_gpu::probe() {
            relit::skip::skipping(&format!("relit relight --gpu: {why}"));
            continue;
        }
        let out = relit(&[
            "relight",
            file,
            "--light",
            light,
            "--gpu",
            "--compare",
            "--roi",
            "11,3,40,9",
            "-o",
            &p("gpu.exr"),
        ]);
        assert!(String::from_utf8_lossy(&out.stdout).contains("largest absolute difference"));
        let gpu = load(Path::new(&p("gpu.exr")));
        let diff = max_abs(&gpu, &crop);
        eprintln!("{light}: relit relight --gpu vs CPU: {diff:.2e} (peak {peak:.3})");
        let bound = if light.starts_with("dir:") {
            // f32 rounding of two summation orders: the GPU tests' bound (1e-5 of the
            // peak, here at least 1e-5 absolute).
            1e-5 * peak.max(1.0)
        } else {
            TABLE_BOUND * peak
        };
        assert!(diff <= bound, "{light}: GPU vs CPU {diff}");
    }
}

#[test]
fn gpu_frames_with_projector_and_area_lights_match_the_cpu() {
    if let Err(why) = relit_gpu::probe() {
        relit::skip::skipping(&format!(
            "relit relight --gpu with projector and area lights: {why}"
        ));
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    relit(&[
        "bench",
        "--write-maps",
        &p("maps.exr"),
        "--size",
        "64x24",
        "--k",
        "9",
    ]);
    let mut slide = ImageRgb::new(8, 4);
    for (i, v) in slide.data.iter_mut().enumerate() {
        *v = (i % 7) as f32 / 6.0;
    }
    relit::image::save(Path::new(&p("slide.png")), &slide, 0.0).unwrap();
    std::fs::write(
        p("rig.json"),
        r#"{ "lights": [
  { "type": "point", "position": [0.3, 0.5, 0.2] },
  { "type": "projector", "position": [0, 0.2, 0], "direction": [0, 0, -1], "up": [0, 1, 0], "fov_deg": 60, "slide": "slide.png" },
  { "type": "area", "shape": { "rect": { "center": [0, 0.6, -0.5], "u": [0.2, 0, 0], "v": [0, 0, 0.2] } }, "samples": 8 }
] }"#,
    )
    .unwrap();
    let rig = p("rig.json");
    relit(&[
        "relight",
        &p("maps.exr"),
        "--rig",
        &rig,
        "-o",
        &p("cpu.exr"),
    ]);
    relit(&[
        "relight",
        &p("maps.exr"),
        "--rig",
        &rig,
        "--gpu",
        "-o",
        &p("gpu.exr"),
    ]);
    let (cpu, gpu) = (
        load(Path::new(&p("cpu.exr"))),
        load(Path::new(&p("gpu.exr"))),
    );
    let peak = cpu.data.iter().fold(0f32, |m, v| m.max(v.abs()));
    // The projector and the area light add much to the point light's frame: a GPU frame
    // that dropped or misplaced them could not match the CPU's.
    relit(&[
        "relight",
        &p("maps.exr"),
        "--light",
        "point:0.3,0.5,0.2",
        "-o",
        &p("point.exr"),
    ]);
    let point = load(Path::new(&p("point.exr")));
    let added = max_abs(&point, &cpu);
    assert!(
        added > 0.05 * peak,
        "the rig's projector and area add light: {added}"
    );
    let diff = max_abs(&gpu, &cpu);
    eprintln!("rig of point + projector + area: relit relight --gpu vs CPU: {diff:.2e} (peak {peak:.3}, projector + area add up to {added:.3})");
    assert!(diff <= TABLE_BOUND * peak, "GPU vs CPU {diff}");
}
