//! `relit fit --tile I/N`, `relit plan` and `relit merge` from the command line: the
//! joined parts relight exactly as the single fit, and misuse is refused without
//! writing anything (docs/cluster.md).

mod common;
use common::{capture_and_fit, relit, relit_ok, relit_ok_with, snapshot};

#[test]
fn parts_fitted_apart_merge_into_the_single_fit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    capture_and_fit(d);
    let fit = ["--basis", "sh:9"];
    relit_ok(
        d,
        &[&["fit", "cap/dirs.lp", "-o", "single.exr", "-q"][..], &fit].concat(),
    );
    relit_ok(
        d,
        &[&["plan", "cap/dirs.lp", "-o", "plan.json", "-q"][..], &fit].concat(),
    );
    for i in 0..3 {
        let part = format!("{i}/3");
        let out = format!("part{i}.exr");
        let args = ["fit", "cap/dirs.lp", "--tile", &part, "-o", &out, "-q"];
        relit_ok(d, &[&args[..], &fit].concat());
        let out = format!("planned{i}.exr");
        let args = [
            "fit",
            "cap/dirs.lp",
            "--tile",
            &part,
            "--plan",
            "plan.json",
            "-o",
            &out,
        ];
        let printed = relit_ok(d, &[&args[..], &["-q"], &fit].concat());
        assert!(printed.contains(&format!("part {i} of 3")), "{printed}");
    }
    let info = relit_ok(d, &["info", "part1.exr"]);
    assert!(
        info.contains("shard         part 1 of 3: rows 5..10 of 16"),
        "{info}"
    );
    // In any order.
    relit_ok(
        d,
        &[
            "merge",
            "part2.exr",
            "part0.exr",
            "part1.exr",
            "-o",
            "merged.exr",
        ],
    );
    relit_ok(
        d,
        &[
            "merge",
            "planned1.exr",
            "planned0.exr",
            "planned2.exr",
            "-o",
            "planned.exr",
        ],
    );
    // Compressed, a band of rows at a time (what images above 256 MiB of maps get;
    // `RELIT_BANDS_ABOVE_MIB=0` asks for it here): merged parts are byte for byte the
    // merged lossless file converted whole, and a fit relights exactly as the same fit
    // packed whole.
    let in_bands = [("RELIT_BANDS_ABOVE_MIB", "0")];
    relit_ok_with(
        d,
        &[
            "merge",
            "part1.exr",
            "part0.exr",
            "part2.exr",
            "-o",
            "merged.rlz",
            "--mip",
        ],
        &in_bands,
    );
    relit_ok(
        d,
        &["convert", "merged.exr", "-o", "converted.rlz", "--mip"],
    );
    assert!(
        std::fs::read(d.join("merged.rlz")).unwrap()
            == std::fs::read(d.join("converted.rlz")).unwrap()
    );
    // A codebook too (vector quantisation trained on the pixels the whole packer takes).
    let codebook = ["--layout", "ycc", "--components", "3", "--codebook", "24"];
    let merge = [
        "merge",
        "part1.exr",
        "part0.exr",
        "part2.exr",
        "-o",
        "vq.rlz",
    ];
    relit_ok_with(d, &[&merge[..], &codebook].concat(), &in_bands);
    let convert = ["convert", "merged.exr", "-o", "vq_whole.rlz"];
    relit_ok(d, &[&convert[..], &codebook].concat());
    assert!(
        std::fs::read(d.join("vq.rlz")).unwrap() == std::fs::read(d.join("vq_whole.rlz")).unwrap()
    );
    let fit_to = |out: &'static str| [&["fit", "cap/dirs.lp", "-o", out, "-q"][..], &fit].concat();
    relit_ok_with(d, &fit_to("single.rlz"), &in_bands);
    relit_ok(d, &fit_to("whole.rlz"));
    for light in ["dir:0.3,0.4,0.8", "dir:-0.7,0.1,0.4"] {
        relit_ok(
            d,
            &["relight", "single.rlz", "--light", light, "-o", "a.exr"],
        );
        relit_ok(
            d,
            &["relight", "whole.rlz", "--light", light, "-o", "b.exr"],
        );
        let report = relit_ok(d, &["compare", "a.exr", "b.exr", "--json"]);
        let value: serde_json::Value = serde_json::from_str(&report).unwrap();
        assert_eq!(value["max_abs_error"], 0.0, "{report}");
    }
    for light in ["dir:0.3,0.4,0.8", "dir:-0.7,0.1,0.4"] {
        relit_ok(
            d,
            &["relight", "single.exr", "--light", light, "-o", "a.exr"],
        );
        for merged in ["merged.exr", "planned.exr"] {
            relit_ok(d, &["relight", merged, "--light", light, "-o", "b.exr"]);
            let report = relit_ok(d, &["compare", "b.exr", "a.exr", "--json"]);
            let value: serde_json::Value = serde_json::from_str(&report).unwrap();
            assert_eq!(value["max_abs_error"], 0.0, "{merged} at {light}: {report}");
        }
    }
}

#[test]
fn misused_parts_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    capture_and_fit(d);
    for i in 0..2 {
        let part = format!("{i}/2");
        relit_ok(
            d,
            &[
                "fit",
                "cap/dirs.lp",
                "--basis",
                "sh:4",
                "--tile",
                &part,
                "-o",
                &format!("p{i}.exr"),
                "-q",
            ],
        );
    }
    std::fs::write(d.join("not-a-plan.json"), "{\"format\": \"something\"}").unwrap();
    let before = snapshot(d);
    let cases: [(&[&str], &str); 7] = [
        (
            &["merge", "p0.exr", "-o", "m.exr"],
            "p0.exr is part 0 of 2, but 1 part was given",
        ),
        (
            &["merge", "p0.exr", "scene.exr", "-o", "m.exr"],
            "not a part of a sharded fit",
        ),
        (&["merge", "p0.exr", "p1.exr", "-o", "p0.exr"], "p0.exr"),
        (
            &["fit", "cap/dirs.lp", "--tile", "2/2", "-o", "x.exr"],
            "does not exist",
        ),
        (
            &["fit", "cap/dirs.lp", "--tile", "1/2", "-o", "x.rlz"],
            "`*.exr`",
        ),
        (
            &["fit", "cap/dirs.lp", "--tile", "0/17", "-o", "x.exr"],
            "16 rows",
        ),
        (
            &[
                "fit",
                "cap/dirs.lp",
                "--plan",
                "not-a-plan.json",
                "-o",
                "x.exr",
            ],
            "not a relit plan",
        ),
    ];
    for (args, needle) in cases {
        let out = relit(d, args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
        assert_eq!(snapshot(d), before, "{args:?} changed the folder");
    }
}
