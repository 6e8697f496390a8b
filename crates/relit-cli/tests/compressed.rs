//! The compressed file end to end through the binary: `convert` both ways, `fit -o
//! X.rlz`, and every reader (`relight`, `info`, `export-web`) on it.

#[allow(dead_code)]
mod common;

use std::path::Path;
use std::process::Command;

fn relit(dir: &Path, args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_relit"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "relit {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn frame(dir: &Path, file: &str, name: &str) -> Vec<f32> {
    let out = format!("{name}.exr");
    relit(
        dir,
        &["relight", file, "--light", "dir:0.3,0.2,0.93", "-o", &out],
    );
    relit::image::load_linear(&dir.join(out), None)
        .unwrap()
        .data
}

/// What `relit info FILE --json` says of its storage, and its coefficients.
fn storage_and_coefficients(d: &Path, file: &str) -> (String, u64) {
    let info = relit(d, &["info", file, "--json"]);
    let info: serde_json::Value = serde_json::from_str(&info).unwrap();
    (
        info["storage"].as_str().unwrap().to_string(),
        info["coefficients"].as_u64().unwrap(),
    )
}

/// The sum of squared differences of two frames.
fn squared_error(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(a, b)| ((a - b) as f64).powi(2)).sum()
}

/// `relit relight FILE --roi 10,2,12,9` equals that crop of `whole`, FILE's 24×16 frame
/// under `frame`'s light.
fn region_relights_as_its_crop(d: &Path, file: &str, whole: &[f32]) {
    relit(
        d,
        &[
            "relight",
            file,
            "--roi",
            "10,2,12,9",
            "--light",
            "dir:0.3,0.2,0.93",
            "-o",
            "part.exr",
        ],
    );
    let part = relit::image::load_linear(&d.join("part.exr"), None).unwrap();
    for y in 0..9 {
        for x in 0..12 {
            for c in 0..3 {
                let a = part.data[3 * (y * 12 + x) + c];
                let b = whole[3 * ((y + 2) * 24 + x + 10) + c];
                assert!(
                    (a - b).abs() <= 1e-6 * b.abs().max(1e-3),
                    "({x},{y}) {a} {b}"
                );
            }
        }
    }
}

/// `relit relight FILE --gpu` matches `cpu`, FILE's frame under `frame`'s light, within
/// f32 rounding of two summation orders (the GPU tests' bound); a skip where no adapter
/// exists.
fn gpu_relights_as_the_cpu(d: &Path, file: &str, cpu: &[f32], what: &str) {
    if let Err(why) = relit_gpu::probe() {
        relit::skip::skipping(&format!("relit relight --gpu on {what}: {why}"));
        return;
    }
    relit(
        d,
        &[
            "relight",
            file,
            "--light",
            "dir:0.3,0.2,0.93",
            "--gpu",
            "-o",
            "gpu.exr",
        ],
    );
    let gpu = relit::image::load_linear(&d.join("gpu.exr"), None)
        .unwrap()
        .data;
    let peak = cpu.iter().fold(0f32, |m, v| m.max(v.abs()));
    let diff = gpu
        .iter()
        .zip(cpu)
        .fold(0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        diff <= 1e-5 * peak.max(1.0),
        "GPU vs CPU {diff} (peak {peak})"
    );
}

#[test]
fn convert_goes_both_ways_and_every_reader_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d);
    let json = relit(
        d,
        &[
            "convert",
            "scene.exr",
            "-o",
            "small.rlz",
            "--bits",
            "14",
            "--json",
        ],
    );
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    let bytes = std::fs::metadata(d.join("small.rlz")).unwrap().len();
    assert_eq!(report["output_bytes"], bytes);
    // Relit from the compressed file as from the EXR, within the quantisation.
    let exr = frame(d, "scene.exr", "a");
    let rlz = frame(d, "small.rlz", "b");
    let peak = exr.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let worst = exr
        .iter()
        .zip(&rlz)
        .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst < 2e-3 * peak, "{worst} of {peak}");
    // And back to EXR: the same frame again.
    relit(
        d,
        &["convert", "small.rlz", "-o", "back.exr", "--storage", "f32"],
    );
    let back = frame(d, "back.exr", "c");
    let again = back
        .iter()
        .zip(&rlz)
        .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(again < 1e-5 * peak, "{again}");
    let info = relit(d, &["info", "small.rlz", "--json"]);
    let info: serde_json::Value = serde_json::from_str(&info).unwrap();
    assert!(
        info["storage"].as_str().unwrap().starts_with("compressed"),
        "{info}"
    );
    assert_eq!(info["coefficients"], 4);
    relit(d, &["export-web", "small.rlz", "site", "--viewer", "relit"]);
    assert!(d.join("site/index.html").exists());
}

#[test]
fn principal_components_per_block_reach_every_reader() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d); // 24×16, 4 coefficients
    let convert = |name: &str, block: &[&str]| {
        let args = [
            &["convert", "scene.exr", "-o", name, "--layout", "ycc"][..],
            &["--components", "2", "--bits", "14", "--tile-size", "16"],
            block,
        ]
        .concat();
        relit(d, &args);
    };
    convert("blocks.rlz", &["--pca-block", "16"]);
    convert("once.rlz", &[]);
    let (storage, coefficients) = storage_and_coefficients(d, "blocks.rlz");
    assert!(
        storage.contains("per block of 16² (2×1 blocks)"),
        "{storage}"
    );
    // The file decodes into the fit's basis, all four coefficients.
    assert_eq!(coefficients, 4);
    let exr = frame(d, "scene.exr", "a");
    let error = |f: &[f32]| squared_error(f, &exr);
    let blocks = frame(d, "blocks.rlz", "b");
    let once = frame(d, "once.rlz", "c");
    assert!(
        error(&blocks) < error(&once),
        "two components a block {} against two for the file {}",
        error(&blocks),
        error(&once)
    );
    // A region across the blocks' border relights as that crop of the whole frame.
    region_relights_as_its_crop(d, "blocks.rlz", &blocks);
    relit(
        d,
        &["export-web", "blocks.rlz", "site", "--viewer", "relit"],
    );
    assert!(d.join("site/index.html").exists());
    // The wgpu engine reads the decoded planes too.
    gpu_relights_as_the_cpu(d, "blocks.rlz", &blocks, "a per-block file");
}

/// A codebook of the PCA residual (`--codebook C --residual R`): the planes keep K′
/// components, the codebook the next R; relight (whole and by region), export-web and
/// the wgpu engine read all K′ + R.
#[test]
fn a_codebook_of_the_residual_reaches_every_reader() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d); // 24×16, 4 coefficients
    let convert = |name: &str, more: &[&str]| {
        let args = [
            &["convert", "scene.exr", "-o", name, "--layout", "ycc"][..],
            &[
                "--components",
                "2",
                "--codec",
                "jpeg:95",
                "--tile-size",
                "16",
            ],
            more,
        ]
        .concat();
        relit(d, &args);
    };
    convert("residual.rlz", &["--codebook", "64", "--residual", "2"]);
    convert("planes.rlz", &[]);
    let (storage, coefficients) = storage_and_coefficients(d, "residual.rlz");
    assert!(
        storage.contains("components 3–4 of each function from a codebook of 64 entries"),
        "{storage}"
    );
    assert_eq!(coefficients, 4);
    let exr = frame(d, "scene.exr", "a");
    let error = |f: &[f32]| squared_error(f, &exr);
    let residual = frame(d, "residual.rlz", "b");
    let planes = frame(d, "planes.rlz", "c");
    assert!(
        error(&residual) < 0.5 * error(&planes),
        "two planes and two components by codebook {} against two planes {}",
        error(&residual),
        error(&planes)
    );
    // Not a look-up file: its pixels keep planes.
    let said = relit(
        d,
        &[
            "relight",
            "residual.rlz",
            "--light",
            "dir:0,0,1",
            "-o",
            "x.exr",
        ],
    );
    assert!(!said.contains("codebook"), "{said}");
    region_relights_as_its_crop(d, "residual.rlz", &residual);
    relit(
        d,
        &["export-web", "residual.rlz", "site", "--viewer", "relit"],
    );
    assert!(d.join("site/index.html").exists());
    gpu_relights_as_the_cpu(d, "residual.rlz", &residual, "a residual codebook file");
}

#[test]
fn a_region_is_read_tile_by_tile_and_relights_as_that_crop() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d); // 24×16
    relit(
        d,
        &[
            "convert",
            "scene.exr",
            "-o",
            "tiled.rlz",
            "--tile-size",
            "16",
        ],
    );
    let whole = frame(d, "tiled.rlz", "whole");
    let light = ["--light", "dir:0.3,0.2,0.93"];
    let said = relit(
        d,
        &[
            &[
                "relight",
                "tiled.rlz",
                "--roi",
                "2,3,10,9",
                "-o",
                "part.exr",
            ][..],
            &light,
        ]
        .concat(),
    );
    let total = std::fs::metadata(d.join("tiled.rlz")).unwrap().len();
    let read: u64 = said
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no bytes read in: {said}"));
    assert!(said.starts_with("read ") && read < total, "{said}");
    let part = relit::image::load_linear(&d.join("part.exr"), None).unwrap();
    assert_eq!((part.width, part.height), (10, 9));
    let peak = whole.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    for y in 0..9 {
        for x in 0..10 {
            for c in 0..3 {
                let a = part.data[3 * (y * 10 + x) + c];
                let b = whole[3 * ((y + 3) * 24 + x + 2) + c];
                assert!((a - b).abs() <= 1e-6 * peak, "({x},{y}) {a} {b}");
            }
        }
    }
}

#[test]
fn a_fit_writes_a_compressed_file_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d);
    relit(
        d,
        &[
            "fit",
            "cap/dirs.lp",
            "-o",
            "fit.rlz",
            "--basis",
            "sh:9",
            "--layout",
            "ycc",
            "--components",
            "4",
            "--codec",
            "jpeg:90",
            "-q",
        ],
    );
    let info: serde_json::Value =
        serde_json::from_str(&relit(d, &["info", "fit.rlz", "--json"])).unwrap();
    assert_eq!(info["coefficients"], 4);
    assert_eq!(info["basis"]["type"], "projected");
    let f = frame(d, "fit.rlz", "f");
    assert!(f.iter().all(|v| v.is_finite()) && f.iter().any(|&v| v > 0.01));
}

#[test]
fn a_codebook_file_relights_by_look_up_as_its_expanded_maps() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d);
    relit(
        d,
        &["convert", "scene.exr", "-o", "vq.rlz", "--codebook", "64"],
    );
    let info = relit(d, &["info", "vq.rlz"]);
    assert!(info.contains("codebook of 64 entries"), "{info}");
    // Directional lights: the codebook relit once and looked up.
    let said = relit(
        d,
        &[
            "relight",
            "vq.rlz",
            "--light",
            "dir:0.3,0.2,0.93",
            "-o",
            "look.exr",
        ],
    );
    assert!(said.contains("from a codebook of 64 entries"), "{said}");
    // --memory takes the ordinary path over the expanded maps: the same frame.
    relit(
        d,
        &[
            "relight",
            "vq.rlz",
            "--light",
            "dir:0.3,0.2,0.93",
            "-o",
            "expanded.exr",
            "--memory",
        ],
    );
    let load = |f: &str| relit::image::load_linear(&d.join(f), None).unwrap().data;
    let (a, b) = (load("look.exr"), load("expanded.exr"));
    let peak = b.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let worst = a
        .iter()
        .zip(&b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
    assert!(peak > 0.0 && worst <= 1e-5 * peak, "{worst} of {peak}");
    // A region is drawn from the expanded maps.
    let said = relit(
        d,
        &[
            "relight",
            "vq.rlz",
            "--light",
            "dir:0.3,0.2,0.93",
            "--roi",
            "0,0,4,4",
            "-o",
            "roi.exr",
        ],
    );
    assert!(!said.contains("codebook"), "{said}");
}

/// A tiled EXR with mip levels: `--roi` reads only the region's tiles and relights as
/// the crop of the whole frame; `--level 1` is the half-size frame; refusals by name.
#[test]
fn a_tiled_exr_is_read_by_region_and_level() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    common::capture_and_fit(d); // 24×16
    let said = relit(
        d,
        &[
            "convert",
            "scene.exr",
            "-o",
            "mip.exr",
            "--mip-tiles",
            "16",
            "--storage",
            "f32",
        ],
    );
    assert!(said.contains("16-pixel tiles, 5 mip levels"), "{said}");
    let whole = frame(d, "scene.exr", "whole");
    assert_eq!(frame(d, "mip.exr", "whole_mip"), whole);
    let light = ["--light", "dir:0.3,0.2,0.93"];
    let said = relit(
        d,
        &[
            &["relight", "mip.exr", "--roi", "17,3,6,9", "-o", "part.exr"][..],
            &light,
        ]
        .concat(),
    );
    let total = std::fs::metadata(d.join("mip.exr")).unwrap().len();
    let read: u64 = said
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap();
    assert!(said.starts_with("read ") && read < total, "{said}");
    let part = relit::image::load_linear(&d.join("part.exr"), None).unwrap();
    assert_eq!((part.width, part.height), (6, 9));
    for y in 0..9 {
        for x in 0..6 {
            let (a, b) = (
                &part.data[3 * (y * 6 + x)..][..3],
                &whole[3 * ((y + 3) * 24 + x + 17)..][..3],
            );
            assert_eq!(a, b, "({x},{y})");
        }
    }
    relit(
        d,
        &[
            &["relight", "mip.exr", "--level", "1", "-o", "half.exr"][..],
            &light,
        ]
        .concat(),
    );
    let half = relit::image::load_linear(&d.join("half.exr"), None).unwrap();
    assert_eq!((half.width, half.height), (12, 8));
    let refused = |args: &[&str], needle: &str| {
        let out = Command::new(env!("CARGO_BIN_EXE_relit"))
            .current_dir(d)
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(needle),
            "{args:?}: {err}"
        );
    };
    refused(
        &[
            &["relight", "scene.exr", "--level", "1", "-o", "x.exr"][..],
            &light,
        ]
        .concat(),
        "mip levels",
    );
    refused(
        &[
            &["relight", "mip.exr", "--level", "9", "-o", "x.exr"][..],
            &light,
        ]
        .concat(),
        "levels 0 to 4",
    );
    refused(
        &[
            "relight",
            "mip.exr",
            "--level",
            "1",
            "--light",
            "point:0,0,1",
            "-o",
            "x.exr",
        ],
        "directional and environment",
    );
    refused(
        &["convert", "scene.exr", "-o", "x.ptm", "--mip-tiles"],
        "EXR and .rlz outputs",
    );
    assert!(!d.join("x.exr").exists() && !d.join("x.ptm").exists());
    // `relit fit --mip-tiles` writes the pyramid itself: the same file as converting the
    // plain fit (levels equal), and no temporary file left beside it.
    let fit = [
        "fit",
        "cap/dirs.lp",
        "--basis",
        "sh:4",
        "--lambda",
        "1e-3",
        "-q",
    ];
    relit(d, &[&fit[..], &["-o", "plain.exr"]].concat());
    relit(
        d,
        &[&fit[..], &["-o", "fitmip.exr", "--mip-tiles", "16"]].concat(),
    );
    relit(
        d,
        &[
            "convert",
            "plain.exr",
            "-o",
            "conv.exr",
            "--mip-tiles",
            "16",
        ],
    );
    let levels = relit::codec::exr::levels(&d.join("fitmip.exr")).unwrap();
    assert_eq!(levels.len(), 5, "{levels:?}");
    // `relit info` names the layout (from the header alone).
    let said = relit(d, &["info", "fitmip.exr"]);
    assert!(
        said.contains("tiles 16×16, 5 mip levels down to 1×1"),
        "{said}"
    );
    let said = relit(d, &["info", "plain.exr"]);
    assert!(said.contains("scan lines (16 a block)"), "{said}");
    for (level, &(w, h)) in levels.iter().enumerate() {
        let read = |f: &str| {
            relit::codec::exr::read_region(&d.join(f), level, (0, 0, w, h))
                .unwrap()
                .image
                .maps
                .data
        };
        assert_eq!(read("fitmip.exr"), read("conv.exr"), "level {level}");
    }
    let left: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".relit"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    refused(
        &[&fit[..], &["-o", "x.ptm", "--mip-tiles"]].concat(),
        "whole EXR or .rlz",
    );
    refused(
        &[&fit[..], &["-o", "x.exr", "--mip-tiles", "--tile", "0/2"]].concat(),
        "whole EXR or .rlz",
    );

    // A `.rlz` file with mip levels (`--mip-tiles` of convert and fit): `--level` relights
    // the file's own level like the EXR's, reading that level's tiles alone, and `--roi`
    // the region's tiles of its level.
    let said = relit(
        d,
        &[
            "convert",
            "scene.exr",
            "-o",
            "mip.rlz",
            "--mip-tiles",
            "16",
            "--bits",
            "16",
        ],
    );
    assert!(said.contains(" mip "), "{said}");
    let said = relit(d, &["info", "mip.rlz"]);
    assert!(said.contains("tiles of 16², 5 mip levels"), "{said}");
    let bytes_read = |said: &str| -> u64 {
        assert!(said.starts_with("read "), "{said}");
        said.split_whitespace().nth(1).unwrap().parse().unwrap()
    };
    let total = std::fs::metadata(d.join("mip.rlz")).unwrap().len();
    let mut read_level = Vec::new();
    for level in ["0", "1", "2"] {
        let relight = |file: &str, out: &str| {
            relit(
                d,
                &[&["relight", file, "--level", level, "-o", out][..], &light].concat(),
            )
        };
        read_level.push(bytes_read(&relight("mip.rlz", "level_rlz.exr")));
        relight("mip.exr", "level_exr.exr");
        let a = relit::image::load_linear(&d.join("level_rlz.exr"), None).unwrap();
        let b = relit::image::load_linear(&d.join("level_exr.exr"), None).unwrap();
        assert_eq!((a.width, a.height), (b.width, b.height));
        let peak = b.data.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let worst = a
            .data
            .iter()
            .zip(&b.data)
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        assert!(worst <= 1e-3 * peak, "level {level}: {worst} of {peak}");
    }
    // Each coarser level reads fewer bytes: its own tiles, not level 0's.
    assert!(
        read_level[2] < read_level[1] && read_level[1] < read_level[0] && read_level[0] < total,
        "{read_level:?} of {total}"
    );
    let said = relit(
        d,
        &[
            &[
                "relight", "mip.rlz", "--level", "0", "--roi", "17,3,5,4", "-o", "p.exr",
            ][..],
            &light,
        ]
        .concat(),
    );
    assert!(bytes_read(&said) < read_level[0], "{said}");
    relit(
        d,
        &[
            &["relight", "mip.rlz", "--level", "0", "-o", "l0.exr"][..],
            &light,
        ]
        .concat(),
    );
    let level_zero = relit::image::load_linear(&d.join("l0.exr"), None).unwrap();
    let part = relit::image::load_linear(&d.join("p.exr"), None).unwrap();
    assert_eq!((part.width, part.height), (5, 4));
    for y in 0..4 {
        for x in 0..5 {
            let want = &level_zero.data[3 * ((y + 3) * level_zero.width + x + 17)..][..3];
            assert_eq!(&part.data[3 * (y * 5 + x)..][..3], want, "({x},{y})");
        }
    }
    relit(
        d,
        &[&fit[..], &["-o", "fitmip.rlz", "--mip-tiles", "16"]].concat(),
    );
    let header = relit::codec::packed::read_header(&d.join("fitmip.rlz")).unwrap();
    assert_eq!((header.levels, header.tile), (5, 16));
    refused(
        &[
            "convert",
            "scene.exr",
            "-o",
            "x.rlz",
            "--mip",
            "--codebook",
            "8",
        ],
        "codebook",
    );
    assert!(!d.join("x.rlz").exists());
}
