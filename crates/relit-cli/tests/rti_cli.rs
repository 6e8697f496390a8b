//! The RTI tools' files through the command line: `fit`/`convert` write them, `info`,
//! `relight` and `eval --file` read them by their content.

mod common;

use common::relit_ok as relit;

#[test]
fn ptm_and_rti_files_round_trip_through_the_commands() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    relit(
        d,
        &[
            "capture",
            "box",
            "--lights",
            "hemisphere:24",
            "--size",
            "40x30",
            "--format",
            "png16",
            "--out",
            "cap",
            "-q",
        ],
    );
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
