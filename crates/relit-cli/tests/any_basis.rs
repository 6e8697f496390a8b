//! `relit relight` relights every light type on a basis other than SH (issue 13: everything
//! after the fit works through the basis): a studio capture fitted with `hsh:16`,
//! relit with a point light, a spot, an area light and an environment, each frame finite
//! and lit; a band window, which needs SH's bands, is a clear error.

use relit::image::{load_linear, save, ImageRgb};
use std::path::Path;
use std::process::{Command, Output};

fn relit(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relit"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the relit binary runs")
}

fn ok(dir: &Path, args: &[&str]) {
    let out = relit(dir, args);
    assert!(
        out.status.success(),
        "relit {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A 64×32 sky: a blue gradient above a dark ground and a small bright sun.
fn write_sky(path: &Path) {
    let (w, h) = (64, 32);
    let mut sky = ImageRgb::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let sun = (x as i64 - 20).abs() <= 1 && (y as i64 - 8).abs() <= 1;
            let rgb = if sun {
                [20.0, 18.0, 14.0]
            } else if y < h / 2 {
                [0.3, 0.45, 0.8]
            } else {
                [0.1, 0.08, 0.06]
            };
            sky.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&rgb);
        }
    }
    save(path, &sky, 0.0).unwrap();
}

fn assert_lit(path: &Path, what: &str) {
    let frame = load_linear(path, None).unwrap();
    assert!(
        frame.data.iter().all(|v| v.is_finite()),
        "{what}: a value that is not finite"
    );
    let lit = frame.data.iter().filter(|&&v| v > 1e-4).count();
    assert!(
        lit * 10 > frame.data.len(),
        "{what}: only {lit} of {} values lit",
        frame.data.len()
    );
}

#[test]
fn relight_lights_a_non_sh_basis_with_every_light_type() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(
        d,
        &[
            "capture",
            "box",
            "--lights",
            "fibonacci:80",
            "--size",
            "64x48",
            "--out",
            "cap",
            "-q",
        ],
    );
    ok(
        d,
        &[
            "fit",
            "cap/capture.json",
            "--basis",
            "hsh:16",
            "--objective",
            "linear",
            "-o",
            "scene.exr",
            "-q",
        ],
    );
    write_sky(&d.join("sky.exr"));
    let rigs = [
        (
            "point",
            r#"{ "lights": [ { "type": "point", "position": [0, 0.5, 0.5], "intensity": 2 } ] }"#,
        ),
        (
            "spot",
            r#"{ "lights": [ { "type": "spot", "position": [0, 0.8, 0.6], "direction": [0, -0.6, -1], "cone_deg": 40, "softness_deg": 10, "intensity": 3 } ] }"#,
        ),
        (
            "area",
            r#"{ "lights": [ { "type": "area", "shape": { "rect": { "center": [0, 0.9, 0.3], "u": [0.3, 0, 0], "v": [0, 0, 0.25] } }, "intensity": 3, "two_sided": true, "samples": 16 } ] }"#,
        ),
        (
            "environment",
            r#"{ "lights": [ { "type": "environment", "map": "sky.exr", "yaw_deg": 30, "pitch_deg": -10, "intensity": 0.5 } ] }"#,
        ),
    ];
    for (name, rig) in rigs {
        let rig_file = format!("{name}.rig.json");
        std::fs::write(d.join(&rig_file), rig).unwrap();
        let out = format!("{name}.exr");
        ok(d, &["relight", "scene.exr", "--rig", &rig_file, "-o", &out]);
        assert_lit(&d.join(&out), name);
    }
    // The command-line light syntax, and an 8-bit output.
    ok(
        d,
        &[
            "relight",
            "scene.exr",
            "--light",
            "point:0.2,0.5,0.6",
            "-o",
            "point.png",
        ],
    );
    // Band windows need bands: refused on HSH, naming the basis.
    std::fs::write(
        d.join("hann.rig.json"),
        r#"{ "lights": [ { "type": "environment", "map": "sky.exr", "window": { "type": "hann" } } ] }"#,
    )
    .unwrap();
    let out = relit(
        d,
        &[
            "relight",
            "scene.exr",
            "--rig",
            "hann.rig.json",
            "-o",
            "x.exr",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("window") && stderr.contains("hsh:16"),
        "{stderr}"
    );
    assert!(!d.join("x.exr").exists());
}
