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
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/rti-fitted/openlime")
        .join(name);
    if dir.join("info.json").is_file() {
        Some(dir)
    } else {
        relit::skip::skipping(&format!("{} is not present", dir.display()));
        None
    }
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

#[test]
fn the_four_fixtures_agree_at_captured_lights() {
    let names = ["ptm", "hsh", "bln", "ybln"];
    let Some(dirs) = names.iter().map(|n| fixture(n)).collect::<Option<Vec<_>>>() else {
        return;
    };
    let captured = lights(&dirs[0]);
    let images: Vec<RelightableImage> = dirs
        .iter()
        .map(|d| {
            let t = std::time::Instant::now();
            let im = codec::read(d).unwrap();
            eprintln!(
                "{}: {} k={} {:.2}s",
                d.display(),
                im.meta.basis.family,
                im.maps.k,
                t.elapsed().as_secs_f64()
            );
            im
        })
        .collect();
    for i in [0, 40, 80, 115] {
        let frames: Vec<ImageRgb> = images.iter().map(|im| relight(im, captured[i])).collect();
        if let Some(out) = std::env::var_os("WEB_DEBUG") {
            for (f, n) in frames.iter().zip(names) {
                relit::image::save(&PathBuf::from(&out).join(format!("{n}_{i}.png")), f, 0.0)
                    .unwrap();
            }
        }
        for a in 0..4 {
            for b in a + 1..4 {
                let p = relit::metrics::psnr_srgb8(&frames[a].data, &frames[b].data);
                eprintln!("light {i}: {} vs {}: {p:.2} dB", names[a], names[b]);
            }
            let p = relit::metrics::psnr_srgb8(&flipped(&frames[a]).data, &frames[0].data);
            eprintln!("light {i}: flipped {} vs ptm: {p:.2} dB", names[a]);
        }
    }
}
