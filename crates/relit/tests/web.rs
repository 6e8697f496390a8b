//! The relight/OpenLIME web format against real relight output (shared data):
//! `shared/data/rti-fitted/openlime/{ptm,hsh,bln,ybln}`, one capture (116 lights,
//! 1024×1024) fitted by relight four ways.

use relit::codec;
use relit::image::ImageRgb;
use relit::light::{Light, LightRig};
use relit::maps::RelightableImage;
use relit::sphere::Vec3;
use std::path::PathBuf;

fn fixture(name: &str) -> Option<PathBuf> {
    let info = relit::skip::shared(&format!("data/rti-fitted/openlime/{name}/info.json"))?;
    Some(info.parent()?.to_path_buf())
}

/// The captured light directions listed in a folder's `info.json`.
fn lights(dir: &std::path::Path) -> Vec<Vec3> {
    let info: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("info.json")).unwrap()).unwrap();
    info["lights"]
        .as_array()
        .unwrap()
        .chunks(3)
        .map(|l| {
            Vec3::new(
                l[0].as_f64().unwrap(),
                l[1].as_f64().unwrap(),
                l[2].as_f64().unwrap(),
            )
            .normalized()
            .unwrap()
        })
        .collect()
}

fn relight(image: &RelightableImage, dir: Vec3) -> ImageRgb {
    let rig = LightRig::new(vec![Light::directional(dir, [1.0; 3])]);
    relit::engine::relight(image, &rig, &Default::default()).unwrap()
}

fn flipped(image: &ImageRgb) -> ImageRgb {
    let mut out = image.clone();
    let row = 3 * image.width;
    for y in 0..image.height {
        let from = (image.height - 1 - y) * row;
        out.data[y * row..(y + 1) * row].copy_from_slice(&image.data[from..from + row]);
    }
    out
}

/// Each fixture reads into the basis its type maps to.
#[test]
fn relight_folders_read_in_every_layout() {
    for (name, family, k) in [
        ("ptm", "ptm", 6),
        ("hsh", "hsh", 9),
        ("bln", "bilinear", 0),
        ("ybln", "bilinear", 0),
    ] {
        let Some(dir) = fixture(name) else {
            return;
        };
        let image = codec::read(&dir).unwrap();
        assert_eq!((image.width(), image.height()), (1024, 1024), "{name}");
        assert_eq!(image.meta.basis.family, family, "{name}");
        assert_eq!(
            image.meta.color_space,
            relit::maps::MapSpace::Srgb,
            "{name}"
        );
        if k > 0 {
            assert_eq!(image.maps.k, k, "{name}");
        }
        assert!(image.maps.data.iter().all(|v| v.is_finite()), "{name}");
    }
}

/// The capture these four folders were fitted from (116 lights, 1024×1024, a gold
/// coin) is not among shared/data/realrti's items (none has 116 lights or that size),
/// so there is no photo to compare with. What is left without a browser: the four
/// fits of one capture, read four ways (single images, Deep Zoom, tarzoom, itarzoom;
/// ptm, hsh, bilinear mrgb, bilinear mycc), agree at its captured lights far better
/// than any of them agrees with an upside-down reading. Measured (lights 0, 40, 80,
/// 115; 8-bit sRGB PSNR): hsh–bln 23.3/29.4/31.7/26.1 dB, ptm–hsh 19.3–20.9,
/// the weakest pair ptm–ybln 16.2–20.6 dB; a flipped image against ptm 11.9–16.1 dB.
/// The exact check is OpenLIME's own canvas (crates/relit-cli/tests/web.rs: 37 dB).
#[test]
fn the_four_fits_of_one_capture_agree_at_its_lights() {
    let names = ["ptm", "hsh", "bln", "ybln"];
    let Some(dirs) = names.iter().map(|n| fixture(n)).collect::<Option<Vec<_>>>() else {
        return;
    };
    let captured = lights(&dirs[0]);
    assert_eq!(captured.len(), 116);
    let images: Vec<RelightableImage> = dirs.iter().map(|d| codec::read(d).unwrap()).collect();
    for i in [0, 40, 80, 115] {
        let frames: Vec<ImageRgb> = images.iter().map(|im| relight(im, captured[i])).collect();
        let psnr = |a: &ImageRgb, b: &ImageRgb| relit::metrics::psnr_srgb8(&a.data, &b.data);
        let hsh_bln = psnr(&frames[1], &frames[2]);
        assert!(hsh_bln > 21.0, "light {i}: hsh against bln {hsh_bln:.2} dB");
        for a in 0..4 {
            for b in a + 1..4 {
                let p = psnr(&frames[a], &frames[b]);
                assert!(
                    p > 14.5,
                    "light {i}: {} against {} {p:.2} dB",
                    names[a],
                    names[b]
                );
            }
            let upside_down = psnr(&flipped(&frames[a]), &frames[if a == 1 { 2 } else { 1 }]);
            let upright = psnr(&frames[a], &frames[if a == 1 { 2 } else { 1 }]);
            assert!(
                upright > upside_down + 3.0,
                "light {i}: {} upright {upright:.2} dB, flipped {upside_down:.2} dB",
                names[a]
            );
        }
    }
}

/// relit's own fit of a real capture, published in the web format and read back,
/// against the photos: RealRTI item9 (48 lights, 279×289, a coin), the default fit, the
/// default export (bilinear mrgb, 18 planes, 12×12 grid, JPEG 95), five captured
/// lights. The photos are training lights, so this measures what the export loses, not
/// how well the fit generalises. The default fit picks sg:25 for this specular coin,
/// whose sharp lobes a 12×12 grid of light directions blurs. Measured (8-bit sRGB PSNR
/// against the photo, EXR → web): lights 0, 12, 24, 35, 47: 32.0 → 27.7, 33.8 → 26.4,
/// 30.0 → 27.8, 25.2 → 24.6, 18.6 → 18.3 dB (36 planes gain 1–2 dB; relight's 8×8 grid
/// loses up to 2 dB more at some lights). Floors about 2 dB under the web figures.
#[test]
fn a_relit_fit_published_on_the_web_stays_close_to_the_photos() {
    let Some(lp) = relit::skip::shared("data/realrti/item9/dirs.lp") else {
        return;
    };
    let capture = relit::capture::Capture::open(&lp).unwrap();
    let fitted = relit::fit::fit(&capture, &Default::default(), &relit::progress::Silent)
        .unwrap()
        .image;
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("item9");
    codec::web::write(&folder, &fitted, &Default::default()).unwrap();
    let web = codec::read(&folder).unwrap();
    let directions = capture.directions();
    let mut report = Vec::new();
    for (index, floor) in [(0, 25.5), (12, 24.5), (24, 25.5), (35, 22.5), (47, 16.0)] {
        let photo = capture.load(index).unwrap();
        let exr =
            relit::metrics::psnr_srgb8(&relight(&fitted, directions[index]).data, &photo.data);
        let ours = relit::metrics::psnr_srgb8(&relight(&web, directions[index]).data, &photo.data);
        report.push(format!("light {index}: {exr:.2} → {ours:.2} dB"));
        assert!(ours > floor, "{report:?}");
    }
    eprintln!("{report:?}");
}
