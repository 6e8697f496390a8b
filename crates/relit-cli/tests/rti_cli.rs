//! The RTI tools' files through the command line: `fit`/`convert` write them, `info`,
//! `relight` and `eval --file` read them by their content.

mod common;

use common::relit_ok as relit;

/// A small studio capture of the box in `d/cap`, as 16-bit photographs.
fn capture_box(d: &std::path::Path, lights: &str, size: &str) {
    relit(
        d,
        &[
            "capture", "box", "--lights", lights, "--size", size, "--format", "png16", "--out",
            "cap", "-q",
        ],
    );
}

#[test]
fn ptm_and_rti_files_round_trip_through_the_commands() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    capture_box(d, "hemisphere:24", "40x30");
    relit(
        d,
        &[
            "fit",
            "cap/capture.json",
            "--basis",
            "ptm:6",
            "--space",
            "srgb",
            "-o",
            "ptm.exr",
            "-q",
        ],
    );
    relit(
        d,
        &[
            "fit",
            "cap/capture.json",
            "--basis",
            "hsh:9",
            "--space",
            "srgb",
            "-o",
            "hsh.exr",
            "-q",
        ],
    );
    relit(
        d,
        &["convert", "ptm.exr", "-o", "rgb.ptm", "--ptm-format", "rgb"],
    );
    relit(d, &["convert", "ptm.exr", "-o", "lrgb.ptm"]);
    relit(d, &["convert", "hsh.exr", "-o", "hsh.rti"]);
    // A fit straight to a PTM, re-expressed from the default basis.
    relit(d, &["fit", "cap/capture.json", "-o", "direct.ptm", "-q"]);
    let score = |file: &str| -> f64 {
        let json: serde_json::Value = serde_json::from_str(&relit(
            d,
            &[
                "eval",
                "cap/capture.json",
                "--file",
                file,
                "--holdout",
                "every:4",
                "--json",
            ],
        ))
        .unwrap();
        json["psnr_srgb8_mean"].as_f64().unwrap()
    };
    let (ptm_fit, hsh_fit) = (score("ptm.exr"), score("hsh.exr"));
    for (file, fit) in [
        ("rgb.ptm", ptm_fit),
        ("lrgb.ptm", ptm_fit),
        ("hsh.rti", hsh_fit),
    ] {
        let s = score(file);
        assert!(
            s > fit - 0.5,
            "{file}: {s:.2} dB against its fit's {fit:.2}"
        );
    }
    assert!(score("direct.ptm") > ptm_fit - 3.0);
    assert!(relit(d, &["info", "lrgb.ptm"]).contains("PTM 1.2"));
    assert!(relit(d, &["info", "hsh.rti"]).contains("hsh:9"));
    relit(
        d,
        &[
            "relight",
            "hsh.rti",
            "--light",
            "dir:-0.5,0.2,0.8",
            "--light",
            "dir:0.3,0.3,0.9",
            "-o",
            "lit.png",
        ],
    );
}

#[test]
fn auto_chooses_among_the_rti_families_when_told() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    capture_box(d, "hemisphere:40", "32x24");
    let fit_among = |rest: &[&str]| {
        let head = [
            "fit",
            "cap/capture.json",
            "--candidate",
            "hsh",
            "--candidate",
            "ptm",
        ];
        common::relit(d, &[&head[..], rest].concat())
    };
    let out = fit_among(&["-o", "auto.exr", "--json", "-q"]);
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let judged: Vec<&str> = json["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["basis"].as_str().unwrap())
        .collect();
    let mut sorted = judged.clone();
    sorted.sort_unstable();
    // hsh at the ladder's sizes within 25 coefficients, and ptm's one size.
    assert_eq!(sorted, ["hsh:16", "hsh:25", "hsh:4", "hsh:9", "ptm:6"]);
    let chosen = json["basis"].as_str().unwrap();
    assert_eq!(chosen, judged[0]);
    // The file holds the chosen basis (which `.ptm` or `.rti` then store as they are).
    let info = relit(d, &["info", "auto.exr"]);
    assert!(info.contains(chosen), "{chosen} not in:\n{info}");
    // An unknown family is a usage error naming the known ones.
    let out = common::relit(
        d,
        &[
            "fit",
            "cap/capture.json",
            "--candidate",
            "pca",
            "-o",
            "x.exr",
        ],
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("known: sh, hsh, ptm"));
    assert!(!d.join("x.exr").exists());
    // So is a candidate beside a fixed basis, which would ignore it.
    let out = common::relit(
        d,
        &[
            "fit",
            "cap/capture.json",
            "--basis",
            "sh:9",
            "--candidate",
            "hsh",
            "-o",
            "x.exr",
        ],
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--candidate chooses among bases"));
    assert!(!d.join("x.exr").exists());
    // Within a budget, over auto's two best finalists: each judged, one kept.
    // 768 pixels: the principal components' tables are most of a file.
    let out = fit_among(&["-o", "budget.rlz", "--budget", "400", "--budget-bases", "2"]);
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert_eq!(said.matches(": expected ").count(), 2, "{said}");
    assert_eq!(said.matches("(kept)").count(), 1, "{said}");
    assert!(relit(d, &["info", "budget.rlz"]).contains("storage       compressed"));
    // `--json` says what the budget chose: the file's own bits per pixel, within it.
    let out = fit_among(&["-o", "budget2.rlz", "--budget", "400", "--json", "-q"]);
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let chosen = &json["compression"];
    let bits = chosen["bits_per_pixel"].as_f64().unwrap();
    let bytes = std::fs::metadata(d.join("budget2.rlz")).unwrap().len();
    let pixels = chosen["pixels"].as_f64().unwrap();
    assert!(
        (bits - 8.0 * bytes as f64 / pixels).abs() < 1e-9 && bits <= 400.0,
        "{chosen}"
    );
    assert_eq!(
        chosen["judged_pixels"], chosen["pixels"],
        "a small image judged whole"
    );
    assert!(chosen["within"].as_u64().unwrap() >= 1, "{chosen}");
    assert_eq!(chosen["bases"].as_array().unwrap().len(), 2, "{chosen}");
    assert!(chosen["settings"].as_str().is_some_and(|s| !s.is_empty()));
    let out = common::relit(
        d,
        &[
            "fit",
            "cap/capture.json",
            "-o",
            "y.rlz",
            "--budget-bases",
            "2",
        ],
    );
    assert!(!out.status.success(), "--budget-bases needs --budget");
    assert!(!d.join("y.rlz").exists());
}
