//! `relit bench --fit`: a child process per fitter, its own peak memory, the fit's
//! stages, and the ratios to a peer run in the same command.

use std::process::Command;

#[allow(dead_code)]
mod common;

#[test]
fn bench_fit_times_relit_and_a_peer_as_processes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let relit = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_relit"))
            .current_dir(d)
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    relit(&[
        "capture",
        "box",
        "--lights",
        "hemisphere:12",
        "--size",
        "24x18",
        "--out",
        "cap",
        "-q",
    ]);
    // A stand-in peer: a script that takes relight-cli's arguments and writes its output.
    let peer = d.join("peer.sh");
    std::fs::write(
        &peer,
        "#!/bin/sh\n# -b hsh -p 27 FOLDER OUT\necho done > \"$6\"\n",
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&peer, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let json: serde_json::Value = serde_json::from_str(&relit(&[
        "bench",
        "--fit",
        "cap/capture.json",
        "--peer",
        peer.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    let relit_rss = json["relit"]["peak_rss_bytes"].as_u64().unwrap();
    assert!(relit_rss > 1 << 20, "{json}");
    assert!(json["relit"]["wall_seconds"].as_f64().unwrap() > 0.0);
    assert!(json["relit"]["output_bytes"].as_u64().unwrap() > 0);
    let stages = json["relit_fit"]["stages"].as_array().unwrap();
    assert!(stages.iter().any(|s| s["name"] == "solve"), "{stages:?}");
    let stage_sum: f64 = stages.iter().map(|s| s["seconds"].as_f64().unwrap()).sum();
    assert!(stage_sum <= json["relit_fit"]["seconds"].as_f64().unwrap() + 1e-6);
    assert!(json["peer"]["wall_seconds"].as_f64().unwrap() > 0.0);
    assert_eq!(json["peer"]["output_bytes"], 5);
    assert!(json["wall_ratio"].as_f64().is_some() && json["memory_ratio"].as_f64().is_some());
}

/// `relit bench --fit … --fit-args ARGS` times the fit those options ask for, and a fit
/// that fails says why (the child's own error), not only that it failed.
#[test]
fn bench_fit_times_the_fit_its_arguments_ask_for() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d); // cap/: 24×16, 12 lights
    let bench = |fit_args: &str| {
        Command::new(env!("CARGO_BIN_EXE_relit"))
            .current_dir(d)
            .args([
                "bench",
                "--fit",
                "cap/dirs.lp",
                "--json",
                "--fit-args",
                fit_args,
            ])
            .output()
            .unwrap()
    };
    let out = bench("--basis sh:4 --lambda 1e-3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["relit_fit"]["basis"], "sh:4", "{json}");
    let command = json["relit"]["command"].as_str().unwrap();
    assert!(command.ends_with("--basis sh:4 --lambda 1e-3"), "{command}");
    let failed = bench("--basis nope:3");
    assert!(!failed.status.success());
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(stderr.contains("unknown basis `nope`"), "{stderr}");
}

/// `relit bench --write-capture`: a capture repeated (mirrored, jittered) over a larger
/// size, with an `.lp` of the same lights, that fits; the source folder is refused as
/// the output.
#[test]
fn a_big_capture_is_written_from_a_small_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d); // cap/: 24×16, 12 lights
    let bin = env!("CARGO_BIN_EXE_relit");
    let out = std::process::Command::new(bin)
        .current_dir(d)
        .args([
            "bench",
            "--write-capture",
            "big",
            "--capture-from",
            "cap/dirs.lp",
            "--size",
            "60x40",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let big = relit::capture::Capture::open(&d.join("big/dirs.lp")).unwrap();
    let small = relit::capture::Capture::open(&d.join("cap/dirs.lp")).unwrap();
    assert_eq!((big.width, big.height, big.len()), (60, 40, small.len()));
    for (a, b) in big.directions().iter().zip(small.directions()) {
        assert!((*a - b).length() < 1e-5);
    }
    // The first copy is the source image within the jitter and JPEG's error; the second
    // copy across is its mirror image.
    let (s, b) = (small.load(3).unwrap(), big.load(3).unwrap());
    let px =
        |img: &relit::image::ImageRgb, x: usize, y: usize| img.data[3 * (y * img.width + x) + 1];
    for (x, y) in [(2, 3), (20, 10)] {
        let want = px(&s, x, y);
        for got in [px(&b, x, y), px(&b, 47 - x, y)] {
            assert!(
                (got - want).abs() <= 0.05 * want + 0.02,
                "({x},{y}): {got} vs {want}"
            );
        }
    }
    let fit = std::process::Command::new(bin)
        .current_dir(d)
        .args(["fit", "big/dirs.lp", "--basis", "sh:4", "-o", "big.exr"])
        .output()
        .unwrap();
    assert!(
        fit.status.success(),
        "{}",
        String::from_utf8_lossy(&fit.stderr)
    );
    let refused = std::process::Command::new(bin)
        .current_dir(d)
        .args([
            "bench",
            "--write-capture",
            "cap",
            "--capture-from",
            "cap/dirs.lp",
            "--size",
            "60x40",
        ])
        .output()
        .unwrap();
    assert!(!refused.status.success());
}
