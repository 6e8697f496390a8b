//! `relit bench --fit`: a child process per fitter, its own peak memory, the fit's
//! stages, and the ratios to a peer run in the same command.

use std::process::Command;

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
