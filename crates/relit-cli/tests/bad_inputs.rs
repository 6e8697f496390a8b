//! The bad-input matrix: every kind of input relit reads, broken in the ways files break
//! (empty, truncated, wrong magic, wrong counts, non-finite or zero light vectors,
//! mixed sizes, missing or unreadable images, header sizes of 2³⁰, deeply nested or
//! wrongly typed JSON, impossible options, output equal to input).
//!
//! Each case runs the binary on a fresh copy of a small valid fixture with one thing
//! broken, under an address-space limit of 1 GiB, and checks: exit code 1 (no panic, no
//! abort), a message naming the file (and, where the case says, the line or field),
//! every file in the folder byte-identical afterwards and nothing new left behind.
//! A full disk and a read-only output folder have a test of their own
//! (`a_full_disk_and_a_read_only_folder_fail_cleanly`): the disk is a file-size limit
//! (`ulimit -f`, its signal ignored, so a write past it fails as on a full disk), the
//! folder a mode of 0555 with the command run as `nobody` when the tests run as root.

mod common;

use common::snapshot;
use relit::sphere::Vec3;
use relit::synth::BumpyPlane;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A folder with a valid capture (`cap/dirs.lp`, 12 PNGs of 24×16), fitted maps
/// `scene.exr`, a picture `sky.exr`, a valid rig `rig.json`, an OBJ `model.obj` and a
/// studio scene `scene.json`: each case breaks one of them (or adds a broken file).
fn fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let plane = common::capture_and_fit(d);
    relit::image::save(&d.join("sky.exr"), &common::picture(&plane), 0.0).unwrap();
    std::fs::write(
        d.join("rig.json"),
        r#"{"lights":[{"type":"directional","direction":[0,0,1]}]}"#,
    )
    .unwrap();
    std::fs::write(
        d.join("model.obj"),
        "v -0.5 0 0\nv 0.5 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        d.join("scene.json"),
        r#"{"camera":{"projection":{"type":"planar","fov_y_deg":45},"width":24,"height":16,
            "eye":[0,1,4],"look_at":[0,0.3,0]},
            "objects":[{"type":"quad","size":[4,4],"transform":{"rotate_deg":[-90,0,0]}}]}"#,
    )
    .unwrap();
    dir
}

/// One case: break the fixture with `setup`, run `args` in it, and expect a refusal whose
/// message contains every one of `needles`.
struct Case {
    name: &'static str,
    setup: fn(&Path),
    args: &'static [&'static str],
    needles: &'static [&'static str],
}

fn write(d: &Path, name: &str, bytes: impl AsRef<[u8]>) {
    std::fs::write(d.join(name), bytes).unwrap();
}

/// `cap/dirs.lp` with its lines replaced by `body`.
fn lp(d: &Path, body: &str) {
    write(d, "cap/dirs.lp", body);
}

/// The first `n` lines of the valid `.lp` (its count line included).
fn lp_lines(d: &Path) -> Vec<String> {
    std::fs::read_to_string(d.join("cap/dirs.lp"))
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect()
}

/// The valid `.lp` with image line `i` (1-based after the count) replaced by `f(line)`.
fn lp_edit(d: &Path, i: usize, f: impl Fn(&str) -> String) {
    let mut lines = lp_lines(d);
    lines[i] = f(&lines[i]);
    lp(d, &(lines.join("\n") + "\n"));
}

/// The image file named on `.lp` line `i`.
fn lp_image(d: &Path, i: usize) -> PathBuf {
    let line = &lp_lines(d)[i];
    let name = line.rsplitn(4, ' ').last().unwrap().trim_matches('"');
    d.join("cap").join(name)
}

fn with_direction(line: &str, xyz: &str) -> String {
    let mut parts: Vec<&str> = line.rsplitn(4, ' ').collect();
    parts.reverse();
    format!("{} {xyz}", parts[0])
}

/// The fitted file with the 16 bytes after `dataWindow\0box2i\0` + size set to a window
/// of 2³⁰ × 2³⁰ pixels.
fn huge_window(d: &Path) {
    let mut bytes = std::fs::read(d.join("scene.exr")).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("a dataWindow attribute")
        + key.len()
        + 4;
    let max = (1i32 << 30) - 1;
    let window = [0i32, 0, max, max];
    for (j, v) in window.iter().enumerate() {
        bytes[at + 4 * j..at + 4 * j + 4].copy_from_slice(&v.to_le_bytes());
    }
    write(d, "huge.exr", bytes);
}

/// A valid compressed file of the fixture's maps.
fn rlz_bytes(d: &Path) -> Vec<u8> {
    let image = relit::codec::read(&d.join("scene.exr")).unwrap();
    let settings = relit::compress::Settings {
        components: Some(3),
        tile: 16,
        ..Default::default()
    };
    relit::codec::packed::to_bytes(&relit::compress::pack(&image, &settings).unwrap()).unwrap()
}

const CASES: &[Case] = &[
    // ---- .lp captures (fit) ----
    Case {
        name: "empty .lp",
        setup: |d| lp(d, ""),
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["dirs.lp"],
    },
    Case {
        name: ".lp count larger than its lines",
        setup: |d| {
            let mut l = lp_lines(d);
            l[0] = "40".into();
            lp(d, &(l.join("\n") + "\n"))
        },
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["dirs.lp"],
    },
    Case {
        name: ".lp count of 2^30",
        setup: |d| {
            let mut l = lp_lines(d);
            l[0] = "1073741824".into();
            lp(d, &(l.join("\n") + "\n"))
        },
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["dirs.lp"],
    },
    Case {
        name: ".lp count not a number",
        setup: |d| {
            let mut l = lp_lines(d);
            l[0] = "twelve".into();
            lp(d, &(l.join("\n") + "\n"))
        },
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["dirs.lp", "line 1"],
    },
    Case {
        name: ".lp NaN light vector",
        setup: |d| lp_edit(d, 3, |l| with_direction(l, "nan 0 1")),
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["dirs.lp", "line 4"],
    },
    Case {
        name: ".lp infinite light vector",
        setup: |d| lp_edit(d, 2, |l| with_direction(l, "inf 0 1")),
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["dirs.lp", "line 3"],
    },
    Case {
        name: ".lp zero light vector",
        setup: |d| lp_edit(d, 5, |l| with_direction(l, "0 0 0")),
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["dirs.lp", "line 6"],
    },
    Case {
        name: ".lp light vector with two numbers",
        setup: |d| lp_edit(d, 1, |l| with_direction(l, "0.1 0.2")),
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["dirs.lp", "line 2"],
    },
    Case {
        name: ".lp image missing",
        setup: |d| std::fs::remove_file(lp_image(d, 4)).unwrap(),
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["light 003"],
    },
    Case {
        name: ".lp image empty",
        setup: |d| std::fs::write(lp_image(d, 2), b"").unwrap(),
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["light 001"],
    },
    Case {
        name: ".lp image truncated",
        setup: |d| {
            let p = lp_image(d, 6);
            let b = std::fs::read(&p).unwrap();
            std::fs::write(&p, &b[..b.len() / 2]).unwrap()
        },
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["light 005"],
    },
    Case {
        name: ".lp image with wrong magic",
        setup: |d| std::fs::write(lp_image(d, 1), b"GIF89a not a png at all").unwrap(),
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["light 000"],
    },
    Case {
        name: ".lp images of mixed sizes",
        setup: |d| {
            let small = BumpyPlane {
                width: 12,
                height: 8,
            }
            .render(Vec3::new(0.0, 0.0, 1.0));
            relit::image::save(&lp_image(d, 7), &small, 0.0).unwrap()
        },
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["light 006"],
    },
    Case {
        name: ".lp image is a folder",
        setup: |d| {
            let p = lp_image(d, 2);
            std::fs::remove_file(&p).unwrap();
            std::fs::create_dir(&p).unwrap()
        },
        args: &["fit", "cap/dirs.lp", "-o", "out.exr"],
        needles: &["light 001"],
    },
    Case {
        name: "capture file missing",
        setup: |_| {},
        args: &["fit", "cap/none.lp", "-o", "out.exr"],
        needles: &["none.lp"],
    },
    Case {
        name: "eval hold-out beyond the capture",
        setup: |_| {},
        args: &["eval", "cap/dirs.lp", "--holdout", "12"],
        needles: &["12"],
    },
    // ---- manifests ----
    Case {
        name: "manifest empty",
        setup: |d| write(d, "cap/capture.json", ""),
        args: &["fit", "cap/capture.json", "-o", "out.exr"],
        needles: &["capture.json"],
    },
    Case {
        name: "manifest truncated",
        setup: |d| {
            write(
                d,
                "cap/capture.json",
                r#"{"images": [{"file": "light 000.png", "dir"#,
            )
        },
        args: &["fit", "cap/capture.json", "-o", "out.exr"],
        needles: &["capture.json", "line 1"],
    },
    Case {
        name: "manifest nested 100000 deep",
        setup: |d| write(d, "cap/capture.json", "[".repeat(100_000)),
        args: &["fit", "cap/capture.json", "-o", "out.exr"],
        needles: &["capture.json"],
    },
    Case {
        name: "manifest of the wrong shape",
        setup: |d| write(d, "cap/capture.json", r#"{"images": 7}"#),
        args: &["fit", "cap/capture.json", "-o", "out.exr"],
        needles: &["capture.json", "column 12"],
    },
    // ---- fitted files (info, relight, view, export-web) ----
    Case {
        name: "fitted file empty",
        setup: |d| write(d, "bad.exr", ""),
        args: &["info", "bad.exr"],
        needles: &["bad.exr"],
    },
    Case {
        name: "fitted file truncated",
        setup: |d| {
            let b = std::fs::read(d.join("scene.exr")).unwrap();
            write(d, "bad.exr", &b[..b.len() / 2])
        },
        args: &["info", "bad.exr"],
        needles: &["bad.exr"],
    },
    Case {
        name: "fitted file truncated in its header",
        setup: |d| {
            let b = std::fs::read(d.join("scene.exr")).unwrap();
            write(d, "bad.exr", &b[..40])
        },
        args: &[
            "relight",
            "bad.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "out.png",
        ],
        needles: &["bad.exr"],
    },
    Case {
        name: "fitted file with wrong magic",
        setup: |d| write(d, "bad.exr", b"\x89PNG\r\n\x1a\n........"),
        args: &["info", "bad.exr"],
        needles: &["bad.exr"],
    },
    Case {
        name: "fitted file of 2^30 x 2^30 pixels",
        setup: huge_window,
        args: &["info", "huge.exr"],
        needles: &["huge.exr"],
    },
    Case {
        name: "relight a 2^30 x 2^30 file",
        setup: huge_window,
        args: &[
            "relight",
            "huge.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "out.png",
        ],
        needles: &["huge.exr"],
    },
    Case {
        name: "an EXR picture, not fitted maps",
        setup: |_| {},
        args: &[
            "relight",
            "sky.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "out.png",
        ],
        needles: &["sky.exr"],
    },
    Case {
        name: "view a broken file",
        setup: |d| write(d, "bad.exr", "not an exr"),
        args: &["view", "bad.exr"],
        needles: &["bad.exr"],
    },
    Case {
        name: "export-web a broken file",
        setup: |d| write(d, "bad.exr", "not an exr"),
        args: &["export-web", "bad.exr", "site"],
        needles: &["bad.exr"],
    },
    // ---- compressed files (.rlz) ----
    Case {
        name: "compressed file truncated",
        setup: |d| {
            let b = rlz_bytes(d);
            write(d, "bad.rlz", &b[..b.len() * 2 / 3])
        },
        args: &["info", "bad.rlz"],
        needles: &["bad.rlz", "truncated"],
    },
    Case {
        name: "compressed file with one bit flipped in a tile",
        setup: |d| {
            let mut b = rlz_bytes(d);
            let at = b.len() - 10;
            b[at] ^= 0x04;
            write(d, "bad.rlz", &b)
        },
        args: &[
            "relight",
            "bad.rlz",
            "--light",
            "dir:0,0,1",
            "-o",
            "out.png",
        ],
        needles: &["bad.rlz", "checksum"],
    },
    Case {
        name: "compressed header claiming 65536×65536 pixels",
        setup: |d| {
            let image = relit::codec::read(&d.join("scene.exr")).unwrap();
            let mut packed = relit::compress::pack(&image, &Default::default()).unwrap();
            packed.header.width = 1 << 16;
            packed.header.height = 1 << 16;
            write(
                d,
                "bad.rlz",
                relit::codec::packed::to_bytes(&packed).unwrap(),
            )
        },
        args: &["convert", "bad.rlz", "-o", "out.exr"],
        needles: &["bad.rlz", "sections"],
    },
    Case {
        name: "convert onto its own input",
        setup: |_| {},
        args: &["convert", "scene.exr", "-o", "scene.exr"],
        needles: &["scene.exr"],
    },
    Case {
        name: "output equal to input",
        setup: |_| {},
        args: &[
            "relight",
            "scene.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "scene.exr",
        ],
        needles: &["scene.exr"],
    },
    Case {
        name: "output into a missing folder",
        setup: |_| {},
        args: &[
            "relight",
            "scene.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "nowhere/out.png",
        ],
        needles: &["nowhere"],
    },
    Case {
        name: "output of an unknown format",
        setup: |_| {},
        args: &[
            "relight",
            "scene.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "out.xyz",
        ],
        needles: &["out.xyz"],
    },
    Case {
        name: "region outside the image",
        setup: |_| {},
        args: &[
            "relight",
            "scene.exr",
            "--light",
            "dir:0,0,1",
            "--roi",
            "20,10,10,10",
            "-o",
            "out.png",
        ],
        needles: &["roi"],
    },
    // ---- lights on the command line ----
    Case {
        name: "zero light vector",
        setup: |_| {},
        args: &[
            "relight",
            "scene.exr",
            "--light",
            "dir:0,0,0",
            "-o",
            "out.png",
        ],
        needles: &["dir:0,0,0"],
    },
    Case {
        name: "NaN light vector",
        setup: |_| {},
        args: &[
            "relight",
            "scene.exr",
            "--light",
            "dir:nan,0,1",
            "-o",
            "out.png",
        ],
        needles: &["dir:nan,0,1"],
    },
    Case {
        name: "light of an unknown kind",
        setup: |_| {},
        args: &[
            "relight",
            "scene.exr",
            "--light",
            "laser:0,0,1",
            "-o",
            "out.png",
        ],
        needles: &["laser:0,0,1"],
    },
    // ---- light rigs ----
    Case {
        name: "rig empty",
        setup: |d| write(d, "bad.json", ""),
        args: &["relight", "scene.exr", "--rig", "bad.json", "-o", "out.png"],
        needles: &["bad.json"],
    },
    Case {
        name: "rig truncated",
        setup: |d| write(d, "bad.json", r#"{"lights":[{"type":"directional","#),
        args: &["relight", "scene.exr", "--rig", "bad.json", "-o", "out.png"],
        needles: &["bad.json", "line 1"],
    },
    Case {
        name: "rig nested 100000 deep",
        setup: |d| {
            write(
                d,
                "bad.json",
                "{\"lights\":".to_string() + &"[".repeat(100_000),
            )
        },
        args: &["relight", "scene.exr", "--rig", "bad.json", "-o", "out.png"],
        needles: &["bad.json"],
    },
    Case {
        name: "rig light of an unknown type",
        setup: |d| {
            write(
                d,
                "bad.json",
                r#"{"lights":[{"type":"laser","direction":[0,0,1]}]}"#,
            )
        },
        args: &["relight", "scene.exr", "--rig", "bad.json", "-o", "out.png"],
        needles: &["bad.json", "laser"],
    },
    Case {
        name: "rig zero direction",
        setup: |d| {
            write(
                d,
                "bad.json",
                r#"{"lights":[{"type":"directional","direction":[0,0,0]}]}"#,
            )
        },
        args: &["relight", "scene.exr", "--rig", "bad.json", "-o", "out.png"],
        needles: &["bad.json", "direction"],
    },
    Case {
        name: "rig environment map missing",
        setup: |d| {
            write(
                d,
                "bad.json",
                r#"{"lights":[{"type":"environment","map":"none.hdr"}]}"#,
            )
        },
        args: &["relight", "scene.exr", "--rig", "bad.json", "-o", "out.png"],
        needles: &["none.hdr"],
    },
    Case {
        name: "rig environment map garbage",
        setup: |d| {
            write(
                d,
                "sky.hdr",
                "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1073741824 +X 1073741824\n\x02\x02",
            );
            write(
                d,
                "bad.json",
                r#"{"lights":[{"type":"environment","map":"sky.hdr"}]}"#,
            )
        },
        args: &["relight", "scene.exr", "--rig", "bad.json", "-o", "out.png"],
        needles: &["sky.hdr"],
    },
    Case {
        name: "rig environment map truncated",
        setup: |d| {
            let b = std::fs::read(d.join("sky.exr")).unwrap();
            write(d, "cut.exr", &b[..b.len() / 3]);
            write(
                d,
                "bad.json",
                r#"{"lights":[{"type":"environment","map":"cut.exr"}]}"#,
            )
        },
        args: &["relight", "scene.exr", "--rig", "bad.json", "-o", "out.png"],
        needles: &["cut.exr"],
    },
    // ---- scenes, models and light plans (capture) ----
    Case {
        name: "OBJ empty",
        setup: |d| write(d, "model.obj", ""),
        args: &[
            "capture",
            "model.obj",
            "--lights",
            "fibonacci:4",
            "--out",
            "out",
        ],
        needles: &["model.obj"],
    },
    Case {
        name: "OBJ face index out of range",
        setup: |d| write(d, "model.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
        args: &[
            "capture",
            "model.obj",
            "--lights",
            "fibonacci:4",
            "--out",
            "out",
        ],
        needles: &["model.obj", "line 4"],
    },
    Case {
        name: "OBJ NaN vertex",
        setup: |d| write(d, "model.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"),
        args: &[
            "capture",
            "model.obj",
            "--lights",
            "fibonacci:4",
            "--out",
            "out",
        ],
        needles: &["model.obj", "line 2"],
    },
    Case {
        name: "scene truncated",
        setup: |d| write(d, "scene.json", r#"{"camera":{"#),
        args: &[
            "capture",
            "scene.json",
            "--lights",
            "fibonacci:4",
            "--out",
            "out",
        ],
        needles: &["scene.json"],
    },
    Case {
        name: "scene object of an unknown type",
        setup: |d| write(d, "scene.json", r#"{"objects":[{"type":"teapot"}]}"#),
        args: &[
            "capture",
            "scene.json",
            "--lights",
            "fibonacci:4",
            "--out",
            "out",
        ],
        needles: &["scene.json", "teapot"],
    },
    Case {
        name: "light plan of no lights",
        setup: |_| {},
        args: &["capture", "box", "--lights", "fibonacci:0", "--out", "out"],
        needles: &["fibonacci:0"],
    },
    Case {
        name: "light plan file missing",
        setup: |_| {},
        args: &[
            "capture",
            "box",
            "--lights",
            "list:none.txt",
            "--out",
            "out",
        ],
        needles: &["none.txt"],
    },
    Case {
        name: "image size of zero",
        setup: |_| {},
        args: &[
            "capture",
            "box",
            "--lights",
            "fibonacci:4",
            "--size",
            "0x0",
            "--out",
            "out",
        ],
        needles: &["0x0"],
    },
    Case {
        name: "image size of 2^20 squared",
        setup: |_| {},
        args: &[
            "capture",
            "box",
            "--lights",
            "fibonacci:4",
            "--size",
            "1048576x1048576",
            "--out",
            "out",
        ],
        needles: &["1048576"],
    },
];

#[test]
fn every_bad_input_gets_one_clear_error_and_changes_nothing() {
    assert!(CASES.len() >= 40, "{} cases", CASES.len());
    let mut failures = Vec::new();
    for case in CASES {
        let dir = fixture();
        let d = dir.path();
        (case.setup)(d);
        let before = snapshot(d);
        // 1 GiB of address space: an allocation sized from a header value aborts.
        let out = Command::new("sh")
            .arg("-c")
            .arg("ulimit -v 1048576 && exec \"$0\" \"$@\"")
            .arg(env!("CARGO_BIN_EXE_relit"))
            .args(case.args)
            .current_dir(d)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let wrong = refusal_faults(&out, case.needles, d, &before);
        if !wrong.is_empty() {
            failures.push(format!(
                "{}: {}\n    relit {}\n    {}",
                case.name,
                wrong.join("; "),
                case.args.join(" "),
                stderr.trim().replace('\n', "\n    ")
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases:\n{}",
        failures.len(),
        CASES.len(),
        failures.join("\n")
    );
}

/// Commands that write, run where writing fails: past a file-size limit of 2 KiB (a
/// full disk as the writer sees it: the write fails) and into a folder it may not
/// write. Each must exit 1 naming what it could not write, and leave every file as it
/// was, no partial output included.
#[test]
fn a_full_disk_and_a_read_only_folder_fail_cleanly() {
    let root = running_as_root();
    let writers: [&[&str]; 4] = [
        &[
            "relight",
            "scene.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "OUT/frame.exr",
        ],
        &["fit", "cap/dirs.lp", "--basis", "sh:9", "-o", "OUT/fit.exr"],
        &["convert", "scene.exr", "-o", "OUT/scene.rlz"],
        &["export-web", "scene.exr", "OUT/site"],
    ];
    let mut failures = Vec::new();
    for (limit, wrapper) in [
        (
            "full disk",
            "trap '' XFSZ; ulimit -f 4 && exec \"$0\" \"$@\"",
        ),
        ("read-only folder", "exec \"$0\" \"$@\""),
    ] {
        for args in writers {
            let dir = fixture();
            let d = dir.path();
            std::fs::create_dir(d.join("OUT")).unwrap();
            let mut command = Command::new("sh");
            if limit == "read-only folder" {
                use std::os::unix::fs::PermissionsExt;
                let mode = |p: &Path, m: u32| {
                    std::fs::set_permissions(p, std::fs::Permissions::from_mode(m)).unwrap()
                };
                for path in snapshot(d).keys() {
                    let folder = d.join(path).is_dir();
                    mode(&d.join(path), if folder { 0o755 } else { 0o644 });
                }
                mode(d, 0o755);
                mode(&d.join("OUT"), 0o555);
                if root {
                    command = Command::new("setpriv");
                    command.args(["--reuid=65534", "--regid=65534", "--clear-groups", "sh"]);
                }
            }
            let before = snapshot(d);
            let out = command
                .arg("-c")
                .arg(wrapper)
                .arg(env!("CARGO_BIN_EXE_relit"))
                .args(args)
                .current_dir(d)
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&out.stderr);
            // What could not be written: the output, or the fit's spill file, which
            // the disk refuses first.
            let spill = args[0] == "fit" && limit == "full disk";
            let named = if spill { "spill file in" } else { "OUT" };
            let wrong = refusal_faults(&out, &[named], d, &before);
            if !wrong.is_empty() {
                failures.push(format!(
                    "{limit}: relit {}: {}\n    {}",
                    args.join(" "),
                    wrong.join("; "),
                    stderr.trim().replace('\n', "\n    ")
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// What is wrong with a refusal: not exit 1, a panic or failed allocation, a needle
/// missing from the message, files under `d` changed from `before`.
fn refusal_faults(
    out: &std::process::Output,
    needles: &[&str],
    d: &Path,
    before: &BTreeMap<PathBuf, Vec<u8>>,
) -> Vec<String> {
    let stderr = String::from_utf8_lossy(&out.stderr);
    let mut wrong = Vec::new();
    if out.status.code() != Some(1) {
        wrong.push(format!("exit {:?}", out.status.code()));
    }
    if stderr.contains("panicked") || stderr.contains("memory allocation") {
        wrong.push("a panic or failed allocation".to_string());
    }
    for needle in needles {
        if !stderr.contains(needle) {
            wrong.push(format!("no `{needle}` in the message"));
        }
    }
    if snapshot(d) != *before {
        wrong.push("files changed or left behind".to_string());
    }
    wrong
}

/// Whether this process runs as root (whom file modes do not stop).
fn running_as_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false)
}
