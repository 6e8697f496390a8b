//! `relit normals` end to end: from a capture and from the file fitted to it, PNG and
//! EXR outputs, the albedo, and inputs never overwritten.

mod common;

use common::{relit, relit_ok as ok};
use std::path::Path;

fn normals_png(path: &Path) -> Vec<[f64; 3]> {
    let image = image::open(path).unwrap().to_rgb8();
    image
        .pixels()
        .map(|p| p.0.map(|c| c as f64 / 127.5 - 1.0))
        .collect()
}

#[test]
fn normals_from_a_capture_and_from_its_fit_agree() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(
        d,
        &[
            "capture",
            "box",
            "--lights",
            "hemisphere:40",
            "--size",
            "40x30",
            "--out",
            "cap",
            "-q",
        ],
    );
    ok(
        d,
        &[
            "normals",
            "cap/capture.json",
            "-o",
            "from-capture.png",
            "--albedo",
            "albedo.png",
            "-q",
        ],
    );
    ok(
        d,
        &[
            "fit",
            "cap/capture.json",
            "--basis",
            "sh:16",
            "-o",
            "fit.exr",
            "-q",
        ],
    );
    ok(d, &["normals", "fit.exr", "-o", "from-fit.png", "-q"]);
    ok(
        d,
        &[
            "normals",
            "fit.exr",
            "-o",
            "from-fit.exr",
            "--method",
            "ls",
            "-q",
        ],
    );
    let (a, b) = (
        normals_png(&d.join("from-capture.png")),
        normals_png(&d.join("from-fit.png")),
    );
    assert_eq!(a.len(), 40 * 30);
    let mean_angle: f64 = a
        .iter()
        .zip(&b)
        .map(|(u, v)| {
            let dot: f64 = (0..3).map(|i| u[i] * v[i]).sum();
            let norm = |w: &[f64; 3]| w.iter().map(|x| x * x).sum::<f64>().sqrt();
            (dot / (norm(u) * norm(v)).max(1e-9))
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees()
        })
        .sum::<f64>()
        / a.len() as f64;
    assert!(
        mean_angle < 12.0,
        "capture and fit normals differ by {mean_angle:.1}° on average"
    );
    assert!(d.join("albedo.png").is_file() && d.join("from-fit.exr").is_file());
    // The output may not replace an input.
    let out = relit(d, &["normals", "fit.exr", "-o", "fit.exr"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("fit.exr"));
}
