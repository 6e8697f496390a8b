//! No command writes over its own inputs, and a command that fails leaves no partial
//! output. Every writing subcommand is pointed at its inputs by the same path, another
//! spelling, a hard link, a symbolic link either way, and an output folder that holds
//! an input; each must exit 1 naming both paths and leave every file as it was.

mod common;

use common::snapshot;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run the binary in `dir`, so that relative spellings resolve there.
fn relit_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relit"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the relit binary runs")
}

/// Runs `args` in `dir` and checks the refusal: exit code 1, a message naming each of
/// `named`, and every file under `dir` exactly as before.
fn refused(dir: &Path, args: &[&str], named: &[&str]) {
    let before = snapshot(dir);
    let out = relit_in(dir, args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(1),
        "relit {args:?} should be refused; stderr:\n{stderr}"
    );
    assert!(stderr.contains("refusing"), "relit {args:?}:\n{stderr}");
    for name in named {
        assert!(
            stderr.contains(name),
            "relit {args:?}: expected `{name}` in:\n{stderr}"
        );
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    let after = snapshot(dir);
    assert_same_files(&before, &after, args);
}

fn assert_same_files(
    before: &BTreeMap<PathBuf, Vec<u8>>,
    after: &BTreeMap<PathBuf, Vec<u8>>,
    args: &[&str],
) {
    let added: Vec<_> = after.keys().filter(|k| !before.contains_key(*k)).collect();
    let removed: Vec<_> = before.keys().filter(|k| !after.contains_key(*k)).collect();
    let changed: Vec<_> = before
        .iter()
        .filter(|(k, v)| after.get(*k).is_some_and(|w| w != *v))
        .map(|(k, _)| k)
        .collect();
    assert!(
        added.is_empty() && removed.is_empty() && changed.is_empty(),
        "relit {args:?}: added {added:?}, removed {removed:?}, changed {changed:?}"
    );
}

/// Runs `args` in `dir` and checks that it fails (exit 1, `needle` in the message)
/// without adding, removing or changing any file under `dir`.
fn fails_cleanly(dir: &Path, args: &[&str], needle: &str) {
    let before = snapshot(dir);
    let out = relit_in(dir, args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(1),
        "relit {args:?} should fail; stderr:\n{stderr}"
    );
    assert!(
        stderr.contains(needle),
        "relit {args:?}: expected `{needle}` in:\n{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_same_files(&before, &snapshot(dir), args);
}

fn succeeds(dir: &Path, args: &[&str]) -> String {
    let out = relit_in(dir, args);
    assert!(
        out.status.success(),
        "relit {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[cfg(unix)]
fn symlink(target: impl AsRef<Path>, link: impl AsRef<Path>) {
    std::os::unix::fs::symlink(target, link).unwrap();
}

/// The inputs every test points commands at, all under one temporary folder:
///
/// * `cap/dirs.lp` and its 12 PNGs (`cap/light 000.png`…): a capture;
/// * `scene.exr`: maps fitted from it;
/// * `rig/slide.png` and `rig/projector.json`, a projector showing it;
///   `rig/sky.exr` and `rig/anim.json`, two keyframes of an environment light of it
///   (the maps have no depth, which positional lights need to render);
/// * `env/sky.exr`: an environment map;
/// * `studio/scene.json`: a tiny studio scene with an image texture `studio/tex.png`
///   and an OBJ `studio/model.obj` whose `studio/model.mtl` names `studio/mtex.png`;
///   `studio/dirs.txt`: a `list:` light plan.
struct Fixture {
    dir: tempfile::TempDir,
}

impl Fixture {
    fn new() -> Fixture {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for sub in ["rig", "env", "studio"] {
            std::fs::create_dir(d.join(sub)).unwrap();
        }
        let plane = common::capture_and_fit(d);

        let small = common::picture(&plane);
        relit::image::save(&d.join("rig/slide.png"), &small, 0.0).unwrap();
        relit::image::save(&d.join("rig/sky.exr"), &small, 0.0).unwrap();
        relit::image::save(&d.join("env/sky.exr"), &small, 0.0).unwrap();
        relit::image::save(&d.join("studio/tex.png"), &small, 0.0).unwrap();
        relit::image::save(&d.join("studio/mtex.png"), &small, 0.0).unwrap();
        std::fs::write(
            d.join("rig/projector.json"),
            r#"{"lights":[{"type":"projector","position":[0,0,2],"direction":[0,0,-1],"up":[0,1,0],"fov_deg":40,"slide":"slide.png"}]}"#,
        )
        .unwrap();
        std::fs::write(d.join("rig/anim.json"), animation("sky.exr")).unwrap();

        std::fs::write(
            d.join("studio/scene.json"),
            r#"{
  "camera": { "projection": { "type": "planar", "fov_y_deg": 45 }, "width": 24, "height": 16,
              "eye": [0, 1, 4], "look_at": [0, 0.3, 0] },
  "materials": { "wood": { "texture": { "type": "image", "file": "tex.png" } } },
  "objects": [
    { "type": "quad", "size": [4, 4], "material": "wood", "transform": { "rotate_deg": [-90, 0, 0] } },
    { "type": "obj", "file": "model.obj" }
  ]
}"#,
        )
        .unwrap();
        std::fs::write(
            d.join("studio/model.obj"),
            "mtllib model.mtl\nv -0.5 0 0\nv 0.5 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0.5 1\nusemtl m\nf 1/1 2/2 3/3\n",
        )
        .unwrap();
        std::fs::write(
            d.join("studio/model.mtl"),
            "newmtl m\nKd 0.5 0.5 0.5\nmap_Kd mtex.png\n",
        )
        .unwrap();
        std::fs::write(d.join("studio/dirs.txt"), "0 0 1\n0 1 1\n1 1 1\n").unwrap();
        Fixture { dir }
    }

    fn d(&self) -> &Path {
        self.dir.path()
    }

    /// The fixture folder's own name, for `../NAME/…` spellings.
    fn name(&self) -> String {
        self.d().file_name().unwrap().to_string_lossy().into_owned()
    }
}

/// Two keyframes of an environment light, the second with the map `second`.
fn animation(second: &str) -> String {
    format!(
        r#"{{"keyframes":[{{"time":0,"lights":[{{"type":"environment","map":"sky.exr"}}]}},
                         {{"time":1,"lights":[{{"type":"environment","map":"{second}","yaw_deg":90}}]}}]}}"#
    )
}

#[test]
fn fit_refuses_to_write_over_its_capture() {
    let f = Fixture::new();
    let d = f.d();
    let fit = |out: &str| ["fit", "cap/dirs.lp", "-o", out, "-q"].map(String::from);
    let run = |out: &str, named: &[&str]| {
        let args = fit(out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(d, &args, named);
    };
    run("cap/dirs.lp", &["cap/dirs.lp"]);
    run(
        "./cap/../cap/dirs.lp",
        &["./cap/../cap/dirs.lp", "cap/dirs.lp"],
    );
    let other = format!("../{}/cap/dirs.lp", f.name());
    run(&other, &[&other, "cap/dirs.lp"]);
    // An image the .lp names.
    run("cap/light 007.png", &["cap/light 007.png"]);
    #[cfg(unix)]
    {
        std::fs::hard_link(d.join("cap/light 003.png"), d.join("hard.png")).unwrap();
        run("hard.png", &["hard.png", "cap/light 003.png"]);
        symlink("cap/dirs.lp", d.join("link.lp"));
        run("link.lp", &["link.lp", "cap/dirs.lp"]);
        // The capture given through a link, the output its target.
        symlink(d.join("cap/dirs.lp"), d.join("cap/alias.lp"));
        refused(
            d,
            &["fit", "cap/alias.lp", "-o", "cap/dirs.lp", "-q"],
            &["cap/alias.lp", "cap/dirs.lp"],
        );
    }
}

#[test]
fn relight_refuses_to_write_over_its_maps_rig_or_slide() {
    let f = Fixture::new();
    let d = f.d();
    // The data-loss bug of issue 17 as reported.
    refused(
        d,
        &[
            "relight",
            "scene.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "scene.exr",
        ],
        &["scene.exr"],
    );
    refused(
        d,
        &[
            "relight",
            "scene.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            "./scene.exr",
        ],
        &["./scene.exr"],
    );
    let other = format!("../{}/scene.exr", f.name());
    refused(
        d,
        &[
            "relight",
            "./scene.exr",
            "--light",
            "dir:0,0,1",
            "-o",
            &other,
        ],
        &[&other, "./scene.exr"],
    );
    // The rig and the slide it names.
    refused(
        d,
        &[
            "relight",
            "scene.exr",
            "--rig",
            "rig/projector.json",
            "-o",
            "rig/projector.json",
        ],
        &["rig/projector.json"],
    );
    refused(
        d,
        &[
            "relight",
            "scene.exr",
            "--rig",
            "rig/projector.json",
            "-o",
            "rig/./slide.png",
        ],
        &["rig/./slide.png", "rig/slide.png"],
    );
    #[cfg(unix)]
    {
        std::fs::hard_link(d.join("scene.exr"), d.join("hard.exr")).unwrap();
        refused(
            d,
            &[
                "relight",
                "scene.exr",
                "--light",
                "dir:0,0,1",
                "-o",
                "hard.exr",
            ],
            &["hard.exr", "scene.exr"],
        );
        refused(
            d,
            &[
                "relight",
                "hard.exr",
                "--light",
                "dir:0,0,1",
                "-o",
                "scene.exr",
            ],
            &["hard.exr", "scene.exr"],
        );
        symlink("scene.exr", d.join("link.exr"));
        refused(
            d,
            &[
                "relight",
                "scene.exr",
                "--light",
                "dir:0,0,1",
                "-o",
                "link.exr",
            ],
            &["link.exr", "scene.exr"],
        );
        refused(
            d,
            &[
                "relight",
                "link.exr",
                "--light",
                "dir:0,0,1",
                "-o",
                "scene.exr",
            ],
            &["link.exr", "scene.exr"],
        );
    }
}

#[test]
fn relight_frames_refuse_a_folder_holding_an_input() {
    let f = Fixture::new();
    let d = f.d();
    let frames = |out: &str| {
        [
            "relight",
            "scene.exr",
            "--rig",
            "rig/anim.json",
            "--frames",
            "2",
            "--out",
            out,
        ]
        .map(String::from)
    };
    let run = |out: &str, named: &[&str]| {
        let args = frames(out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(d, &args, named);
    };
    // The rig's own folder, the maps' folder, another spelling of it.
    run("rig/", &["rig/", "rig/anim.json"]);
    run(".", &["scene.exr"]);
    run("rig/../rig", &["rig/../rig"]);
    #[cfg(unix)]
    {
        // The folder through a link; an input linking into the folder; a hard link of
        // the slide among earlier frames.
        symlink("rig", d.join("rig-link"));
        run("rig-link", &["rig-link", "rig/anim.json"]);
        std::fs::create_dir(d.join("frames")).unwrap();
        symlink("../scene.exr", d.join("frames/maps.exr"));
        refused(
            d,
            &[
                "relight",
                "frames/maps.exr",
                "--rig",
                "rig/anim.json",
                "--frames",
                "2",
                "--out",
                "frames",
            ],
            &["frames", "frames/maps.exr"],
        );
        std::fs::remove_file(d.join("frames/maps.exr")).unwrap();
        std::fs::hard_link(d.join("rig/sky.exr"), d.join("frames/frame_0000.png")).unwrap();
        run("frames", &["frames", "rig/sky.exr", "hard link"]);
    }
    // Elsewhere the frames are written, into a new folder and an existing empty one,
    // with no temporary files left.
    std::fs::create_dir(d.join("empty")).unwrap();
    for out in ["new/frames", "empty"] {
        let args = frames(out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        succeeds(d, &args);
        let names: Vec<_> = std::fs::read_dir(d.join(out))
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        let mut names = names;
        names.sort();
        assert_eq!(names, ["frame_0000.png", "frame_0001.png"], "{out}");
    }
}

#[test]
fn render_truth_refuses_to_write_over_its_scene_files() {
    let f = Fixture::new();
    let d = f.d();
    let run = |out: &str, named: &[&str]| {
        refused(
            d,
            &[
                "render-truth",
                "studio/scene.json",
                "--light",
                "dir:0,1,1",
                "-o",
                out,
                "-q",
            ],
            named,
        );
    };
    run("studio/scene.json", &["studio/scene.json"]);
    run(
        "./studio/model.obj",
        &["./studio/model.obj", "studio/model.obj"],
    );
    // Named by the scene file, by the OBJ, by its MTL.
    run("studio/tex.png", &["studio/tex.png"]);
    run("studio/model.mtl", &["studio/model.mtl"]);
    run("studio/mtex.png", &["studio/mtex.png"]);
    // A rig and its slide.
    refused(
        d,
        &[
            "render-truth",
            "box",
            "--rig",
            "rig/projector.json",
            "-o",
            "rig/slide.png",
            "-q",
        ],
        &["rig/slide.png"],
    );
    #[cfg(unix)]
    {
        std::fs::hard_link(d.join("studio/mtex.png"), d.join("hard.png")).unwrap();
        run("hard.png", &["hard.png", "studio/mtex.png"]);
        symlink("studio/tex.png", d.join("link.png"));
        run("link.png", &["link.png", "studio/tex.png"]);
        symlink("studio/scene.json", d.join("scene-link.json"));
        refused(
            d,
            &[
                "render-truth",
                "scene-link.json",
                "--light",
                "dir:0,1,1",
                "-o",
                "studio/scene.json",
                "-q",
            ],
            &["scene-link.json", "studio/scene.json"],
        );
    }
}

#[test]
fn capture_refuses_a_folder_holding_its_scene_files() {
    let f = Fixture::new();
    let d = f.d();
    let run = |scene: &str, lights: &str, out: &str, named: &[&str]| {
        refused(
            d,
            &["capture", scene, "--lights", lights, "--out", out, "-q"],
            named,
        );
    };
    run(
        "studio/scene.json",
        "fibonacci:4",
        "studio",
        &["studio", "studio/scene.json"],
    );
    run(
        "studio/scene.json",
        "fibonacci:4",
        "./studio/.",
        &["./studio/."],
    );
    // The OBJ (and its MTL and texture) inside the folder, the scene file outside.
    std::fs::write(
        d.join("outer.json"),
        r#"{"objects":[{"type":"obj","file":"studio/model.obj"}]}"#,
    )
    .unwrap();
    run(
        "outer.json",
        "fibonacci:4",
        "studio",
        &["studio", "studio/model.obj"],
    );
    // A `list:` light plan inside the folder.
    run(
        "box",
        "list:studio/dirs.txt",
        "studio",
        &["studio", "studio/dirs.txt"],
    );
    // The folder is the scene file.
    run(
        "studio/scene.json",
        "fibonacci:4",
        "studio/scene.json",
        &["studio/scene.json"],
    );
    #[cfg(unix)]
    {
        symlink("studio", d.join("studio-link"));
        run(
            "studio/scene.json",
            "fibonacci:4",
            "studio-link",
            &["studio-link"],
        );
        std::fs::create_dir(d.join("old")).unwrap();
        std::fs::hard_link(d.join("studio/mtex.png"), d.join("old/light_0000.png")).unwrap();
        run(
            "studio/scene.json",
            "fibonacci:4",
            "old",
            &["old", "studio/mtex.png", "hard link"],
        );
    }
}

#[test]
fn eval_save_refuses_a_folder_holding_its_inputs() {
    let f = Fixture::new();
    let d = f.d();
    let run = |extra: &[&str], save: &str, named: &[&str]| {
        let mut args = vec!["eval", "--save", save, "--basis", "sh:4", "-q"];
        args.extend_from_slice(extra);
        refused(d, &args, named);
    };
    run(
        &["--scene", "studio/scene.json"],
        "studio",
        &["studio", "studio/scene.json"],
    );
    run(
        &["--scene", "box", "--rig", "rig/projector.json"],
        "rig",
        &["rig", "rig/projector.json"],
    );
    run(
        &["--scene", "box", "--lights", "list:studio/dirs.txt"],
        "studio/..",
        &["studio/dirs.txt"],
    );
    run(
        &["--scene", "studio/scene.json"],
        ".",
        &["studio/scene.json"],
    );
    #[cfg(unix)]
    {
        symlink("rig", d.join("rig-link"));
        run(
            &["--scene", "box", "--rig", "rig/projector.json"],
            "rig-link",
            &["rig-link", "rig/projector.json"],
        );
        std::fs::create_dir(d.join("saved")).unwrap();
        std::fs::hard_link(d.join("studio/tex.png"), d.join("saved/0_directional.png")).unwrap();
        run(
            &["--scene", "studio/scene.json"],
            "saved",
            &["saved", "studio/tex.png"],
        );
    }
}

#[test]
fn demo_refuses_a_folder_holding_its_scene_files() {
    let f = Fixture::new();
    let d = f.d();
    let run = |scene: &str, out: &str, named: &[&str]| {
        refused(
            d,
            &[
                "demo", "--scene", scene, "--lights", "4", "--frames", "1", "--out", out,
            ],
            named,
        );
    };
    run(
        "studio/scene.json",
        "studio",
        &["studio", "studio/scene.json"],
    );
    run("studio/scene.json", ".", &["studio/scene.json"]);
    std::fs::write(
        d.join("outer.json"),
        r#"{"objects":[{"type":"obj","file":"studio/model.obj"}]}"#,
    )
    .unwrap();
    run("outer.json", "studio", &["studio", "studio/model.obj"]);
    #[cfg(unix)]
    {
        symlink("studio", d.join("studio-link"));
        run("studio/scene.json", "studio-link", &["studio-link"]);
        std::fs::create_dir(d.join("old")).unwrap();
        std::fs::hard_link(d.join("studio/model.obj"), d.join("old/scene.exr")).unwrap();
        run(
            "studio/scene.json",
            "old",
            &["old", "studio/model.obj", "hard link"],
        );
    }
}

#[test]
fn export_web_refuses_a_folder_holding_its_inputs() {
    let f = Fixture::new();
    let d = f.d();
    refused(d, &["export-web", "scene.exr", "."], &["scene.exr"]);
    refused(d, &["export-web", "scene.exr", "scene.exr"], &["scene.exr"]);
    refused(
        d,
        &["export-web", "scene.exr", "env", "--env", "env/sky.exr"],
        &["env", "env/sky.exr"],
    );
    let other = format!("../{}", f.name());
    refused(
        d,
        &["export-web", "./scene.exr", &other],
        &[&other, "./scene.exr"],
    );
    #[cfg(unix)]
    {
        symlink(".", d.join("here"));
        refused(
            d,
            &["export-web", "scene.exr", "here"],
            &["here", "scene.exr"],
        );
        // An earlier export (replaced whole) holding a hard link of the maps.
        succeeds(d, &["export-web", "scene.exr", "site"]);
        std::fs::hard_link(d.join("scene.exr"), d.join("site/scene.exr")).unwrap();
        refused(
            d,
            &["export-web", "scene.exr", "site"],
            &["site", "hard link"],
        );
    }
}

#[test]
fn bench_write_maps_refuses_to_replace_the_program() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let program = Path::new(env!("CARGO_BIN_EXE_relit"));
    // Only links to the program: were the guard broken, the rename would replace the
    // link and not the program the other tests run.
    #[cfg(unix)]
    {
        symlink(program, d.join("relit-link"));
        refused(
            d,
            &[
                "bench",
                "--size",
                "8x8",
                "--k",
                "1",
                "--write-maps",
                "relit-link",
            ],
            &["relit-link", "relit program"],
        );
        if std::fs::hard_link(program, d.join("relit-hard")).is_ok() {
            refused(
                d,
                &[
                    "bench",
                    "--size",
                    "8x8",
                    "--k",
                    "1",
                    "--write-maps",
                    "relit-hard",
                ],
                &["relit-hard", "relit program"],
            );
        }
    }
    succeeds(
        d,
        &[
            "bench",
            "--size",
            "8x8",
            "--k",
            "1",
            "--write-maps",
            "maps.exr",
        ],
    );
    assert!(d.join("maps.exr").is_file());
    let _ = program;
}

#[test]
fn a_failing_command_leaves_no_partial_output() {
    let f = Fixture::new();
    let d = f.d();
    // An animation whose last keyframe names a missing map: the first frames render,
    // the last fails. A new folder never appears; an existing one keeps its old files.
    std::fs::write(d.join("rig/broken.json"), animation("missing.exr")).unwrap();
    std::fs::create_dir(d.join("old")).unwrap();
    std::fs::write(d.join("old/frame_0000.png"), b"an earlier frame").unwrap();
    for out in ["new", "old"] {
        fails_cleanly(
            d,
            &[
                "relight",
                "scene.exr",
                "--rig",
                "rig/broken.json",
                "--frames",
                "3",
                "--out",
                out,
            ],
            "missing.exr",
        );
    }
    // A capture with an image truncated part-way: no maps.
    let img = d.join("cap/light 006.png");
    let bytes = std::fs::read(&img).unwrap();
    std::fs::write(&img, &bytes[..bytes.len() / 2]).unwrap();
    fails_cleanly(
        d,
        &["fit", "cap/dirs.lp", "-o", "maps.exr", "-q"],
        "light 006.png",
    );
    std::fs::write(&img, &bytes).unwrap();
    // A capture whose last file cannot be put in place (a folder in the way of its
    // manifest): rendered and written in full, then nothing of it appears.
    std::fs::create_dir_all(d.join("cap2/capture.json")).unwrap();
    fails_cleanly(
        d,
        &[
            "capture",
            "box",
            "--lights",
            "fibonacci:3",
            "--size",
            "16x12",
            "--out",
            "cap2",
            "-q",
        ],
        "capture.json",
    );
    // An evaluation whose rig names a missing map (found before the capture).
    std::fs::write(
        d.join("rig/env.json"),
        r#"{"lights":[{"type":"directional","direction":[0,1,1]},{"type":"environment","map":"missing.hdr"}]}"#,
    )
    .unwrap();
    fails_cleanly(
        d,
        &[
            "eval",
            "--scene",
            "box",
            "--size",
            "16x12",
            "--lights",
            "fibonacci:12",
            "--basis",
            "sh:4",
            "--rig",
            "rig/env.json",
            "--save",
            "saved",
            "-q",
        ],
        "missing.hdr",
    );
    // An export whose environment map is missing.
    fails_cleanly(
        d,
        &[
            "export-web",
            "scene.exr",
            "site",
            "--viewer",
            "relit",
            "--env",
            "env/missing.exr",
        ],
        "missing.exr",
    );
    // And the same commands succeed into an existing empty folder, leaving no
    // temporary files.
    std::fs::remove_dir(d.join("cap2/capture.json")).unwrap();
    succeeds(
        d,
        &[
            "capture",
            "box",
            "--lights",
            "fibonacci:3",
            "--size",
            "16x12",
            "--out",
            "cap2",
            "-q",
        ],
    );
    let mut names: Vec<_> = std::fs::read_dir(d.join("cap2"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "camera.json",
            "capture.json",
            "capture.lp",
            "depth.exr",
            "light_0000.exr",
            "light_0001.exr",
            "light_0002.exr",
            "mask.png"
        ]
    );
}
