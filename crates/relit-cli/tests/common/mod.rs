//! What the CLI's file-level tests share: a small capture with its fitted maps, and a
//! snapshot of a folder to compare before and after a command.

use relit::sphere::{hemisphere_fibonacci, Vec3};
use relit::synth::BumpyPlane;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Writes `d/cap/dirs.lp` with 12 PNGs of a 24×16 bumpy plane (`cap/light 000.png`…)
/// and `d/scene.exr`, sh:4 maps fitted from them; returns the plane, to render more.
#[allow(dead_code)]
pub fn capture_and_fit(d: &Path) -> BumpyPlane {
    std::fs::create_dir_all(d.join("cap")).unwrap();
    let plane = BumpyPlane {
        width: 24,
        height: 16,
    };
    let dirs = hemisphere_fibonacci(12);
    plane.write_lp_capture(&d.join("cap"), &dirs).unwrap();
    let options = relit::fit::FitOptions {
        basis: relit::fit::BasisRequest::parse("sh:4").unwrap(),
        lambda: relit::fit::Lambda::Fixed(1e-3),
        ..Default::default()
    };
    let fitted =
        relit::fit::fit(&plane.capture(&dirs), &options, &relit::progress::Silent).unwrap();
    relit::codec::exr::write(
        &d.join("scene.exr"),
        &fitted.image,
        relit::storage::Precision::F16,
    )
    .unwrap();
    plane
}

/// A picture of the plane lit from above, for slides and environment maps.
#[allow(dead_code)]
pub fn picture(plane: &BumpyPlane) -> relit::image::ImageRgb {
    plane.render(Vec3::new(0.2, 0.3, 0.9))
}

/// Every file and link under `dir` with its bytes (a link: where it points), hidden
/// files included: a comparison before and after finds changed inputs, new outputs and
/// left-over temporary files alike.
#[allow(dead_code)]
pub fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(folder) = pending.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            let meta = std::fs::symlink_metadata(&path).unwrap();
            let rel = path.strip_prefix(dir).unwrap().to_path_buf();
            if meta.file_type().is_symlink() {
                let target = std::fs::read_link(&path).unwrap();
                files.insert(rel, format!("-> {}", target.display()).into_bytes());
            } else if meta.is_dir() {
                files.insert(rel, b"<folder>".to_vec());
                pending.push(path);
            } else {
                files.insert(rel, std::fs::read(&path).unwrap());
            }
        }
    }
    files
}

/// Run the `relit` binary in `dir`.
#[allow(dead_code)]
pub fn relit(dir: &Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_relit"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

/// [`relit_ok`] with the environment variables `env` set.
#[allow(dead_code)]
pub fn relit_ok_with(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_relit"))
        .current_dir(dir)
        .args(args)
        .envs(env.iter().copied())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "relit {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Run the `relit` binary in `dir`, require success, and return its standard output.
#[allow(dead_code)]
pub fn relit_ok(dir: &Path, args: &[&str]) -> String {
    relit_ok_with(dir, args, &[])
}
