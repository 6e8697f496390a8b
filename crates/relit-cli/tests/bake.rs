//! `relit bake` end to end: the file it writes is an ordinary relightable file (`info`,
//! `relight` under an environment and a point light, `.rlz`), it agrees with the
//! renderer's ground truth under a sky, and bad requests are refused before any work.

mod common;

use common::{relit, relit_ok as ok};
use std::path::Path;

/// A Radiance `.hdr` map, 32×16, brighter toward the top (a soft sky).
fn sky(path: &Path) {
    let (w, h) = (32usize, 16usize);
    let mut bytes = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n").into_bytes();
    for y in 0..h {
        // Mantissa m with exponent 129 encodes m / 128.
        let m = (200 - 10 * y) as u8;
        for _ in 0..w {
            bytes.extend_from_slice(&[m, m, (m as u16 * 9 / 10) as u8, 129]);
        }
    }
    std::fs::write(path, bytes).unwrap();
}

/// `d/sky.hdr` and `d/sky.json`, a rig of that sky as an environment light.
fn sky_rig(d: &Path) {
    sky(&d.join("sky.hdr"));
    std::fs::write(
        d.join("sky.json"),
        r#"{"lights":[{"type":"environment","map":"sky.hdr"}]}"#,
    )
    .unwrap();
}

#[test]
fn a_baked_file_relights_like_the_truth_under_a_sky() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    sky_rig(d);
    let summary = ok(
        d,
        &[
            "bake",
            "box",
            "--size",
            "40x30",
            "--samples",
            "512",
            "-o",
            "box.exr",
            "--json",
            "-q",
        ],
    );
    let summary: serde_json::Value = serde_json::from_str(&summary).unwrap();
    assert_eq!(summary["transfer"], "diffuse");
    assert!(
        summary["relative_noise"].as_f64().unwrap() < 0.05,
        "{summary}"
    );
    let info: serde_json::Value =
        serde_json::from_str(&ok(d, &["info", "box.exr", "--json"])).unwrap();
    assert_eq!(info["bake"]["transfer"], "diffuse");
    assert_eq!(info["bake"]["samples"], 512);
    assert_eq!(info["depth"], true);
    assert_eq!(info["coefficients"], 25);

    ok(
        d,
        &["relight", "box.exr", "--rig", "sky.json", "-o", "baked.exr"],
    );
    ok(
        d,
        &[
            "render-truth",
            "box",
            "--size",
            "40x30",
            "--rig",
            "sky.json",
            "-o",
            "truth.exr",
            "-q",
        ],
    );
    let compare: serde_json::Value =
        serde_json::from_str(&ok(d, &["compare", "baked.exr", "truth.exr", "--json"])).unwrap();
    let psnr = compare["psnr_srgb8"].as_f64().unwrap();
    assert!(
        psnr > 30.0,
        "baked against truth under the sky: {psnr:.2} dB"
    );

    // A point light uses the depth the bake stored; a compressed file works too.
    ok(
        d,
        &[
            "relight",
            "box.exr",
            "--light",
            "point:0,2,1",
            "-o",
            "point.png",
        ],
    );
    ok(
        d,
        &[
            "bake",
            "box",
            "--size",
            "40x30",
            "--samples",
            "32",
            "--window",
            "hann",
            "-o",
            "box.rlz",
            "-q",
        ],
    );
    ok(
        d,
        &["relight", "box.rlz", "--rig", "sky.json", "-o", "rlz.png"],
    );
}

#[test]
fn bleeding_is_closer_to_the_indirect_truth_than_diffuse() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    sky_rig(d);
    ok(
        d,
        &[
            "render-truth",
            "box",
            "--size",
            "32x24",
            "--rig",
            "sky.json",
            "--indirect",
            "4",
            "-o",
            "truth.exr",
            "-q",
        ],
    );
    let mut scores = Vec::new();
    for transfer in ["diffuse", "bleeding"] {
        let file = format!("{transfer}.exr");
        let mut args = vec![
            "bake",
            "box",
            "--size",
            "32x24",
            "--samples",
            "256",
            "--transfer",
            transfer,
        ];
        if transfer == "bleeding" {
            // The same bounce rays as the truth's.
            args.extend(["--indirect", "4"]);
        }
        args.extend(["-o", &file, "-q"]);
        ok(d, &args);
        ok(d, &["relight", &file, "--rig", "sky.json", "-o", "lit.exr"]);
        let compare: serde_json::Value =
            serde_json::from_str(&ok(d, &["compare", "lit.exr", "truth.exr", "--json"])).unwrap();
        scores.push(compare["psnr_linear"].as_f64().unwrap());
    }
    assert!(
        scores[1] > scores[0] + 1.0,
        "against the indirect truth: diffuse {:.2} dB, bleeding {:.2} dB",
        scores[0],
        scores[1]
    );
}

#[test]
fn bad_bake_requests_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (args, says) in [
        (
            vec!["bake", "box", "--transfer", "glow", "-o", "x.exr"],
            "unknown transfer",
        ),
        (
            vec!["bake", "box", "--window", "gauss", "-o", "x.exr"],
            "unknown window",
        ),
        (
            vec!["bake", "box", "--indirect", "4", "-o", "x.exr"],
            "bleeding",
        ),
        (
            vec!["bake", "box", "--samples", "0", "-o", "x.exr"],
            "directions per sample",
        ),
        (vec!["bake", "nowhere", "-o", "x.exr"], "nowhere"),
        (
            vec!["bake", "box", "--basis", "hsh:9", "-o", "x.exr"],
            "hsh:9 has none",
        ),
        (
            vec!["bake", "box", "--basis", "sh:10", "-o", "x.exr"],
            "it offers [1, 4, 9, 16",
        ),
    ] {
        let out = relit(d, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert!(!d.join("x.exr").exists(), "{args:?} left an output");
    }
}
