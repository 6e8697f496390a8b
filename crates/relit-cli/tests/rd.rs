//! `relit eval --rd`: the rate–distortion curve of a tiny capture through the binary —
//! real files behind every point, a monotone Pareto front, the plot (again from the
//! stored report), and the refusals.

#[allow(dead_code)]
mod common;

use std::path::Path;
use std::process::{Command, Output};

fn relit(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relit"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

/// Two bases, four settings each and three hold-outs of 12 images of 24×16: seconds.
const CHEAP: &[&str] = &[
    "eval",
    "cap/dirs.lp",
    "--rd",
    "--rd-basis",
    "sh:4",
    "--rd-basis",
    "sh:9",
    "--rd-settings",
    "4",
    "--holdout",
    "spread:3",
    "--lambda",
    "1e-3",
    "--objective",
    "linear",
];

#[test]
fn the_curve_is_made_of_real_files_and_its_front_rises() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d);
    let mut args = CHEAP.to_vec();
    args.extend(["--plot", "rd.svg", "--json"]);
    let out = relit(d, &args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["holdouts"], serde_json::json!([0, 6, 11]));
    let points = report["points"].as_array().unwrap();
    assert_eq!(
        points.len(),
        2 * (1 + 4),
        "the EXR and four settings per basis"
    );
    let pixels = 24.0 * 16.0;
    let mut previous_bits = 0.0;
    for p in points {
        let bytes: Vec<u64> = p["file_bytes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| b.as_u64().unwrap())
            .collect();
        assert_eq!(bytes.len(), 3, "one file per fit: {p}");
        assert!(bytes.iter().all(|&b| b > 100), "{p}");
        let bits = p["bits_per_pixel"].as_f64().unwrap();
        let expected = 8.0 * bytes.iter().sum::<u64>() as f64 / 3.0 / pixels;
        assert!((bits - expected).abs() < 1e-9, "{p}");
        assert!(bits >= previous_bits, "sorted by bits");
        previous_bits = bits;
        let psnr = p["psnr_srgb8"].as_f64().unwrap();
        assert!(psnr.is_finite() && psnr > 15.0, "{p}");
        assert!(p["psnr_linear"].as_f64().unwrap().is_finite());
        assert_eq!(p["holdout_psnr_srgb8"].as_array().unwrap().len(), 3);
    }
    assert_eq!(points.iter().filter(|p| p["lossless"] == true).count(), 2);
    assert!(points
        .iter()
        .filter(|p| p["lossless"] == true)
        .all(|p| p["storage"] == "exr f16"));
    // The front rises, starts at the smallest file, and no point beats any of its points
    // at as few bits.
    let front: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p["pareto"] == true)
        .map(|p| {
            (
                p["bits_per_pixel"].as_f64().unwrap(),
                p["psnr_srgb8"].as_f64().unwrap(),
            )
        })
        .collect();
    assert!(!front.is_empty());
    assert_eq!(front[0].0, points[0]["bits_per_pixel"].as_f64().unwrap());
    assert!(front.windows(2).all(|w| w[0].0 < w[1].0 && w[0].1 < w[1].1));
    for p in points {
        let (bits, psnr) = (
            p["bits_per_pixel"].as_f64().unwrap(),
            p["psnr_srgb8"].as_f64().unwrap(),
        );
        assert!(
            front.iter().all(|&(b, q)| !(bits <= b && psnr > q)),
            "{p} beats the front"
        );
    }

    let svg = std::fs::read_to_string(d.join("rd.svg")).unwrap();
    assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"));
    assert!(svg.trim_end().ends_with("</svg>"));
    for series in [
        "data-basis=\"sh:4\"",
        "data-basis=\"sh:9\"",
        "class=\"pareto\"",
    ] {
        assert!(svg.contains(series), "{series} missing from the plot");
    }
    assert!(svg.contains("bits per pixel") && svg.contains("PSNR"));
    assert_eq!(svg.matches("<circle").count(), 8 + 2, "points and legend");

    // A stored report draws the same plot again.
    std::fs::write(d.join("rd.json"), &out.stdout).unwrap();
    let again = relit(
        d,
        &["eval", "--rd-report", "rd.json", "--plot", "again.svg"],
    );
    assert!(again.status.success());
    assert_eq!(std::fs::read_to_string(d.join("again.svg")).unwrap(), svg);

    // The table: every point, the front starred.
    let out = relit(d, &[CHEAP, &["-q"]].concat());
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(out.status.success());
    assert!(
        table.contains("bits/px") && table.contains("exr f16"),
        "{table}"
    );
    assert_eq!(
        table.lines().filter(|l| l.ends_with('*')).count(),
        front.len()
    );
}

#[test]
fn bad_combinations_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d);
    let usage = |extra: &[&str], mentions: &str| {
        let out = relit(d, &[CHEAP, extra].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(mentions), "{extra:?}: {stderr}");
    };
    usage(&["--compressed"], "--compressed");
    usage(&["--budget", "24"], "--budget");
    usage(&["--basis", "sh:9"], "--basis");
    usage(&["--codec", "jpeg:90"], "--codec");
    let out = relit(d, &["eval", "cap/dirs.lp", "--rd-basis", "sh:4"]);
    assert_eq!(out.status.code(), Some(2));
    let out = relit(d, &["eval", "cap/dirs.lp", "--plot", "rd.svg"]);
    assert_eq!(out.status.code(), Some(2));

    let before = common::snapshot(d);
    let fails = |extra: &[&str], mentions: &str| {
        let out = relit(d, &[CHEAP, extra].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{extra:?}: {stderr}");
        assert!(stderr.contains(mentions), "{extra:?}: {stderr}");
    };
    fails(&["--plot", "cap/dirs.lp"], "refusing");
    fails(&["--plot", "cap/light 000.png"], "refusing");
    fails(&["--plot", "missing/rd.svg"], "does not exist");
    fails(&["--rd-basis", "sh:4"], "twice");
    let out = relit(d, &["eval", "--rd-report", "scene.exr"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("is not the JSON"));
    assert_eq!(before, common::snapshot(d), "nothing was written");
}
