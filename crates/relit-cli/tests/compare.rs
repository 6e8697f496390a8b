//! `relit compare`: the figures of two saved images against an independent computation,
//! the difference picture, the mask, and clear errors.

use std::path::Path;
use std::process::Command;

fn relit(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_relit"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn png(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) {
    image::RgbImage::from_fn(w, h, |x, y| image::Rgb(f(x, y)))
        .save(path)
        .unwrap();
}

#[test]
fn compare_reports_what_an_independent_computation_gives() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (40u32, 30u32);
    let texture = |x: u32, y: u32| [(x * 5 + y) as u8 + 20, (y * 6) as u8 + 10, 128];
    png(&d.join("ref.png"), w, h, texture);
    // The test image: the reference with every red code 4 higher on the right half.
    png(&d.join("test.png"), w, h, |x, y| {
        let mut c = texture(x, y);
        if x >= w / 2 {
            c[0] += 4;
        }
        c
    });
    // The mask stops 6 pixels short of the change: SSIM's 11×11 window does not reach it.
    png(&d.join("left.png"), w, h, |x, _| {
        if x < w / 2 - 6 {
            [255; 3]
        } else {
            [0; 3]
        }
    });
    let out = relit(
        d,
        &[
            "compare", "test.png", "ref.png", "--json", "--diff", "diff.png",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Half the pixels differ by 4 codes in one of three channels: MSE = 16 / 6.
    let want = 10.0 * (255.0f64 * 255.0 / (16.0 / 6.0)).log10();
    assert!(
        (r["psnr_srgb8"].as_f64().unwrap() - want).abs() < 1e-9,
        "{r}"
    );
    let ssim = r["ssim"].as_f64().unwrap();
    assert!(ssim < 1.0 && ssim > 0.9, "{ssim}");
    assert_eq!(r["diff_scale"], 4);
    let diff = image::open(d.join("diff.png")).unwrap().to_rgb8();
    assert_eq!(diff.get_pixel(0, 0).0, [0, 0, 0], "no difference: black");
    assert_eq!(diff.get_pixel(w - 1, 0).0, [255, 0, 0], "the largest: red");
    // Inside the mask the images are equal.
    let out = relit(
        d,
        &[
            "compare", "test.png", "ref.png", "--mask", "left.png", "--json",
        ],
    );
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (r["psnr_srgb8"].as_f64(), r["ssim"].as_f64()),
        (Some(100.0), Some(1.0))
    );
    assert_eq!(r["pixels"], ((w / 2 - 6) * h) as u64);
}

#[test]
fn compare_refuses_other_sizes_and_keeps_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    png(&d.join("a.png"), 8, 8, |_, _| [10, 20, 30]);
    png(&d.join("b.png"), 9, 8, |_, _| [10, 20, 30]);
    let out = relit(d, &["compare", "a.png", "b.png"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("8×8") && err.contains("9×8"),
        "{err}"
    );
    let before = std::fs::read(d.join("a.png")).unwrap();
    let out = relit(d, &["compare", "a.png", "a.png", "--diff", "a.png"]);
    assert!(!out.status.success());
    assert_eq!(
        std::fs::read(d.join("a.png")).unwrap(),
        before,
        "the input is untouched"
    );
}
