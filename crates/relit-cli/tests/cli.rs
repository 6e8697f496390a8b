//! End-to-end tests of the `relit` binary on captures made by the tests themselves.

use relit::sphere::{hemisphere_fibonacci, Vec3};
use relit::synth::BumpyPlane;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn relit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relit"))
        .args(args)
        .output()
        .expect("the relit binary runs")
}

fn ok(args: &[&str]) -> String {
    let out = relit(args);
    assert!(
        out.status.success(),
        "relit {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Fails with exit code 1 and a message on stderr containing `needle`.
fn fails(args: &[&str], needle: &str) {
    let out = relit(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(1),
        "relit {args:?} should fail; stderr:\n{stderr}"
    );
    assert!(
        stderr.contains(needle),
        "relit {args:?}: expected `{needle}` in:\n{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

struct Fixture {
    dir: tempfile::TempDir,
    lp: PathBuf,
    plane: BumpyPlane,
}

impl Fixture {
    /// A 48-light 8-bit sRGB PNG capture of the analytic bumpy plane, as an `.lp`.
    fn new() -> Fixture {
        let dir = tempfile::tempdir().unwrap();
        let plane = BumpyPlane {
            width: 36,
            height: 24,
        };
        let lp = plane
            .write_lp_capture(dir.path(), &hemisphere_fibonacci(48))
            .unwrap();
        Fixture { dir, lp, plane }
    }
    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }
    fn s(p: &Path) -> &str {
        p.to_str().unwrap()
    }
}

#[test]
fn fit_info_relight_round_trip() {
    let f = Fixture::new();
    let maps = f.path("scene.exr");
    let summary = ok(&[
        "fit",
        Fixture::s(&f.lp),
        "-o",
        Fixture::s(&maps),
        "--basis",
        "sh:16",
        "-q",
    ]);
    assert!(summary.contains("training residual"), "{summary}");

    let info: serde_json::Value =
        serde_json::from_str(&ok(&["info", Fixture::s(&maps), "--json"])).unwrap();
    assert_eq!(info["coefficients"], 16);
    assert_eq!(info["width"], 36);
    assert_eq!(info["color_space"], "linear");
    // The automatic objective records the one it chose.
    let objective = info["fit"]["objective"].as_str().unwrap();
    assert!(["perceptual", "linear"].contains(&objective), "{objective}");
    assert_eq!(info["fit"]["images"], 48);

    // Relight at a light that was not captured and compare with the analytic truth.
    let out = f.path("relit.png");
    ok(&[
        "relight",
        Fixture::s(&maps),
        "--light",
        "dir:0.3,-0.4,0.75",
        "-o",
        Fixture::s(&out),
    ]);
    let got = relit::image::load_linear(&out, None).unwrap();
    let truth = f.plane.render(Vec3::new(0.3, -0.4, 0.75));
    let psnr = relit::metrics::psnr_srgb8(&got.data, &truth.data);
    // 16 SH coefficients on a glossy plane with a terminator kink: ~33 dB; a wrong
    // axis or sign convention drops this below 20 dB.
    assert!(psnr > 30.0, "relit vs truth {psnr:.2} dB");

    // Two coloured lights and a rig file; linear EXR output.
    let rig = f.path("rig.json");
    std::fs::write(
        &rig,
        r#"{"lights":[{"type":"directional","direction":[-1,0,1],"color":[0.2,0.4,1.0]}]}"#,
    )
    .unwrap();
    let exr = f.path("two.exr");
    let msg = ok(&[
        "relight",
        Fixture::s(&maps),
        "--light",
        "dir:1,1,1",
        "--color",
        "1,0.5,0.2",
        "--rig",
        Fixture::s(&rig),
        "--exposure",
        "-1",
        "-o",
        Fixture::s(&exr),
    ]);
    assert!(msg.contains("2 lights"), "{msg}");
    assert!(relit::image::load_linear(&exr, None)
        .unwrap()
        .data
        .iter()
        .all(|v| v.is_finite()));
}

#[test]
fn eval_reports_json_with_the_required_fields() {
    let f = Fixture::new();
    let out = ok(&[
        "eval",
        Fixture::s(&f.lp),
        "--holdout",
        "0,12,24,35,47",
        "--basis",
        "sh:9",
        "--json",
    ]);
    let r: serde_json::Value = serde_json::from_str(&out).unwrap();
    for key in [
        "psnr_srgb8_mean",
        "psnr_linear_mean",
        "bytes_per_pixel",
        "fit_seconds",
    ] {
        assert!(r[key].as_f64().is_some(), "missing {key} in {out}");
    }
    let holdouts = r["holdouts"].as_array().unwrap();
    assert_eq!(holdouts.len(), 5);
    assert_eq!(holdouts[4]["index"], 47);
    assert!(r["psnr_srgb8_mean"].as_f64().unwrap() > 28.0, "{out}");
    // 9 coefficients × 3 colours × 2 bytes of half floats, before compression.
    assert!(r["bytes_per_pixel"].as_f64().unwrap() < 54.0 + 10.0);
    let every = ok(&[
        "eval",
        Fixture::s(&f.lp),
        "--holdout",
        "every:16",
        "--joint",
        "--basis",
        "sh:4",
        "--json",
    ]);
    let r: serde_json::Value = serde_json::from_str(&every).unwrap();
    assert_eq!(r["holdouts"].as_array().unwrap().len(), 3);
    assert_eq!(r["protocol"], "joint");
}

#[test]
fn bad_input_is_a_clear_error_and_leaves_no_partial_file() {
    let f = Fixture::new();
    let out = f.path("out.exr");
    // A missing image, named with its line.
    let lp = f.path("broken.lp");
    std::fs::write(&lp, "2\nlight 000.png 0 0 1\nnot-there.png 0 1 1\n").unwrap();
    fails(&["fit", Fixture::s(&lp), "-o", Fixture::s(&out)], "line 3");
    // A count that disagrees with the lines.
    std::fs::write(&lp, "3\nlight 000.png 0 0 1\nlight 001.png 0 1 1\n").unwrap();
    fails(&["fit", Fixture::s(&lp), "-o", Fixture::s(&out)], "line 1");
    // A truncated image fails during decoding; nothing is written.
    let img = f.path("light 001.png");
    let bytes = std::fs::read(&img).unwrap();
    std::fs::write(&img, &bytes[..bytes.len() / 2]).unwrap();
    fails(
        &["fit", Fixture::s(&f.lp), "-o", Fixture::s(&out)],
        "light 001.png",
    );
    assert!(!out.exists(), "no partial output");
    let leftovers: Vec<_> = std::fs::read_dir(f.dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    // Not a relit file, a bad light, a missing output folder.
    fails(&["info", Fixture::s(&f.lp)], "");
    fails(
        &[
            "relight",
            Fixture::s(&f.path("absent.exr")),
            "--light",
            "dir:0,0,1",
            "-o",
            "x.png",
        ],
        "does not exist",
    );
    std::fs::write(&img, &bytes).unwrap();
    ok(&[
        "fit",
        Fixture::s(&f.lp),
        "-o",
        Fixture::s(&out),
        "--basis",
        "sh:4",
        "-q",
    ]);
    fails(
        &[
            "relight",
            Fixture::s(&out),
            "--light",
            "dir:0,0,0",
            "-o",
            Fixture::s(&f.path("x.png")),
        ],
        "direction",
    );
    fails(
        &[
            "relight",
            Fixture::s(&out),
            "--light",
            "dir:0,0,1",
            "-o",
            Fixture::s(&f.path("nowhere/x.png")),
        ],
        "does not exist",
    );
    fails(
        &["eval", Fixture::s(&f.lp), "--holdout", "3,99"],
        "out of range",
    );
    // Bad flags are usage errors (exit 2).
    assert_eq!(
        relit(&["fit", Fixture::s(&f.lp), "-o", "x.exr", "--basis", "sh:81"])
            .status
            .code(),
        Some(2)
    );
}

#[test]
fn eval_scene_prints_every_light_type_as_json() {
    let out = ok(&[
        "eval",
        "--scene",
        "box",
        "--size",
        "80x60",
        "--lights",
        "fibonacci:80",
        "--basis",
        "sh:9",
        "--env-samples",
        "32",
        "--json",
        "-q",
    ]);
    let r: serde_json::Value = serde_json::from_str(&out).unwrap();
    let lights = r["lights"].as_array().unwrap();
    let kinds: Vec<&str> = lights.iter().map(|l| l["type"].as_str().unwrap()).collect();
    assert_eq!(
        kinds,
        [
            "directional",
            "point",
            "spot",
            "projector",
            "area",
            "environment"
        ]
    );
    for l in lights {
        assert!(l["psnr_linear"].as_f64().unwrap() > 15.0, "{l}");
        assert!(l["psnr_srgb8"].as_f64().unwrap() > 10.0, "{l}");
    }
    assert_eq!(r["environment"].as_array().unwrap().len(), 4);
    // A rig naming a missing map is an error naming it, not a panic.
    let dir = tempfile::tempdir().unwrap();
    let rig = dir.path().join("rig.json");
    std::fs::write(
        &rig,
        r#"{"lights":[{"type":"environment","map":"missing.hdr"}]}"#,
    )
    .unwrap();
    fails(
        &[
            "eval",
            "--scene",
            "box",
            "--size",
            "40x30",
            "--lights",
            "fibonacci:20",
            "--rig",
            rig.to_str().unwrap(),
            "-q",
        ],
        "missing.hdr",
    );
}

/// `relit eval --scene --save`: the sRGB PSNR the report gives for each light is the one
/// recomputed here, independently, from the 8-bit codes of the saved truth/relit pair
/// inside the saved mask (the report once divided by 9 samples a pixel, 4.77 dB high).
#[test]
fn scene_eval_figures_match_the_saved_images() {
    let dir = tempfile::tempdir().unwrap();
    let rig = dir.path().join("rig.json");
    std::fs::write(
        &rig,
        r#"{ "lights": [
            { "type": "directional", "direction": [0.3, 0.8, 0.5] },
            { "type": "point", "position": [0.5, 1.2, 1.0], "intensity": 2 } ] }"#,
    )
    .unwrap();
    let save = dir.path().join("saved");
    let out = ok(&[
        "eval",
        "--scene",
        "box",
        "--size",
        "64x48",
        "--lights",
        "fibonacci:60",
        "--basis",
        "sh:9",
        "--rig",
        Fixture::s(&rig),
        "--save",
        Fixture::s(&save),
        "--json",
        "-q",
    ]);
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    let codes = |path: &Path| {
        let img = relit::image::load_linear(path, None).unwrap();
        (img.width, img.height, img.to_srgb8())
    };
    let (mw, mh, mask) = codes(&save.join("mask.png"));
    assert_eq!((mw, mh), (64, 48));
    let lights = report["lights"].as_array().unwrap();
    assert_eq!(lights.len(), 2);
    for (i, light) in lights.iter().enumerate() {
        let kind = light["type"].as_str().unwrap();
        let (w, h, pair) = codes(&save.join(format!("{i}_{kind}.png")));
        // Truth above relit, each framed by a 2-pixel gutter.
        assert_eq!((w, h), (64 + 4, 2 * (48 + 2) + 2));
        let (mut sq, mut n) = (0.0f64, 0usize);
        for y in 0..48 {
            for x in 0..64 {
                if mask[3 * (y * 64 + x)] < 128 {
                    continue;
                }
                for c in 0..3 {
                    let t = pair[3 * ((y + 2) * w + x + 2) + c] as f64;
                    let r = pair[3 * ((y + 2 + 48 + 2) * w + x + 2) + c] as f64;
                    sq += (t - r) * (t - r);
                    n += 1;
                }
            }
        }
        assert!(n > 0);
        let recomputed = 10.0 * (255.0f64 * 255.0 / (sq / n as f64)).log10();
        let reported = light["psnr_srgb8"].as_f64().unwrap();
        assert!(
            (recomputed - reported).abs() < 0.05,
            "{kind}: reported {reported:.3} dB, recomputed from the saved images {recomputed:.3} dB"
        );
    }
}

/// `relit eval CAPTURE --save`: each hold-out's captured image above its relit one, from
/// which the reported 8-bit sRGB PSNR (whole frame, the peer protocol) is recomputed.
#[test]
fn capture_eval_figures_match_the_saved_images() {
    let f = Fixture::new();
    let save = f.path("saved");
    let out = ok(&[
        "eval",
        Fixture::s(&f.lp),
        "--holdout",
        "3,20",
        "--basis",
        "sh:9",
        "--save",
        Fixture::s(&save),
        "--json",
        "-q",
    ]);
    let report: serde_json::Value = serde_json::from_str(&out).unwrap();
    for h in report["holdouts"].as_array().unwrap() {
        let index = h["index"].as_u64().unwrap();
        let stem = Path::new(h["image"].as_str().unwrap())
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let pair =
            relit::image::load_linear(&save.join(format!("{index}_{stem}.png")), None).unwrap();
        let (w, h_px) = (f.plane.width, f.plane.height);
        assert_eq!((pair.width, pair.height), (w + 4, 2 * (h_px + 2) + 2));
        let codes = pair.to_srgb8();
        let (mut sq, mut n) = (0.0f64, 0usize);
        for y in 0..h_px {
            for x in 0..w {
                for c in 0..3 {
                    let t = codes[3 * ((y + 2) * pair.width + x + 2) + c] as f64;
                    let r = codes[3 * ((y + 4 + h_px) * pair.width + x + 2) + c] as f64;
                    sq += (t - r) * (t - r);
                    n += 1;
                }
            }
        }
        let recomputed = 10.0 * (255.0f64 * 255.0 / (sq / n as f64)).log10();
        let reported = h["psnr_srgb8"].as_f64().unwrap();
        assert!(
            (recomputed - reported).abs() < 0.05,
            "hold-out {index}: reported {reported:.3}, recomputed {recomputed:.3}"
        );
    }
}

/// `relit doctor` reports the CPU kernels and every GPU adapter as JSON, and with
/// nothing on `PATH` says that the viewer's browser test cannot run and what to install.
#[test]
fn doctor_reports_what_the_machine_can_do_and_what_is_missing() {
    let report: serde_json::Value = serde_json::from_str(&ok(&["doctor", "--json"])).unwrap();
    let kernels = report["cpu"]["kernels"].as_str().unwrap();
    assert!(
        ["avx2+fma+f16c", "portable"].contains(&kernels),
        "{kernels}"
    );
    assert!(report["cpu"]["threads"].as_u64().unwrap() >= 1);
    let adapters = report["gpu"]["adapters"].as_array().unwrap();
    // The adapter relit would use is one of those found, or there is none and a reason.
    match report["gpu"]["chosen"].as_object() {
        Some(chosen) => assert!(
            adapters
                .iter()
                .any(|a| a["name"] == chosen["name"] && a["backend"] == chosen["backend"]),
            "{report}"
        ),
        None => assert!(report["gpu"]["error"].is_string(), "{report}"),
    }
    assert_eq!(
        report["can"]["gpu_engine"],
        report["gpu"]["chosen"].is_object()
    );

    let out = Command::new(env!("CARGO_BIN_EXE_relit"))
        .args(["doctor", "--json"])
        .env("PATH", "")
        .output()
        .unwrap();
    assert!(out.status.success());
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["can"]["viewer_browser_test"], false);
    assert!(report["tools"]["chromium"].is_null());
    let advice = report["advice"].to_string();
    assert!(advice.contains("chromium, nodejs, npm"), "{advice}");
}
