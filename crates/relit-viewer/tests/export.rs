//! `export_web`: info.json and planes round trip within their quantisation.

mod common;

use relit_viewer::{export_web, BundleOptions, PlaneStorage};
use serde_json::Value;

fn export(storage: PlaneStorage) -> (tempfile::TempDir, relit::maps::RelightableImage, Value) {
    let dir = tempfile::tempdir().unwrap();
    let image = common::sample_image(40, 10, 3);
    let exr = dir.path().join("scene.exr");
    relit::codec::exr::write(&exr, &image, relit::codec::Storage::Float).unwrap();
    let site = dir.path().join("site");
    let options = BundleOptions {
        storage,
        ..Default::default()
    };
    export_web(&exr, &site, &options).unwrap();
    let info: Value =
        serde_json::from_slice(&std::fs::read(site.join("data/info.json")).unwrap()).unwrap();
    (dir, image, info)
}

/// Decode layer `l` into its four planes of values.
fn decode(site: &std::path::Path, info: &Value, l: usize) -> Vec<[f32; 4]> {
    let layer = &info["layers"][l];
    let path = site.join("data").join(layer["file"].as_str().unwrap());
    let scale: Vec<f64> = layer["scale"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let bias: Vec<f64> = layer["bias"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    match info["storage"].as_str().unwrap() {
        "u8" => {
            let img = image::open(&path).unwrap().into_rgba8();
            img.pixels()
                .map(|p| {
                    std::array::from_fn(|q| (bias[q] + scale[q] * p.0[q] as f64 / 255.0) as f32)
                })
                .collect()
        }
        _ => {
            let bytes = std::fs::read(&path).unwrap();
            bytes
                .chunks_exact(8)
                .map(|c| {
                    std::array::from_fn(|q| {
                        half::f16::from_le_bytes([c[2 * q], c[2 * q + 1]]).to_f32()
                    })
                })
                .collect()
        }
    }
}

fn check(storage: PlaneStorage) {
    let (dir, image, info) = export(storage);
    let site = dir.path().join("site");
    assert_eq!(info["format"], "relit-web");
    assert_eq!(info["width"], 40);
    assert_eq!(info["height"], 10);
    assert_eq!(info["k"], 9);
    assert_eq!(info["bands"], 3);
    assert_eq!(info["layers_per_channel"], 3);
    assert_eq!(info["projection"]["type"], "cylindrical");
    assert_eq!(info["camera"]["pose"]["eye"][1], 1.5);
    assert_eq!(info["source"], "scene.exr");
    let layers = info["layers"].as_array().unwrap();
    assert_eq!(layers.len(), 9);
    for asset in ["index.html", "main.js", "renderer.js", "relight.frag"] {
        assert!(site.join(asset).is_file(), "{asset}");
    }
    let n = 3;
    for (l, layer) in layers.iter().enumerate() {
        let (c, j) = (l / n, l % n);
        assert_eq!(layer["channel"], c);
        let planes = decode(&site, &info, l);
        assert_eq!(planes.len(), 400);
        for q in 0..4 {
            let i = 4 * j + q;
            if i >= 9 {
                assert!(planes.iter().all(|p| p[q] == 0.0));
                continue;
            }
            let original = image.maps.plane(i, c);
            let step = layer["scale"][q].as_f64().unwrap() / 255.0;
            for (p, &v) in original.iter().enumerate() {
                let tolerance = match storage {
                    PlaneStorage::U8 => 0.5 * step + 1e-6,
                    PlaneStorage::F16 => (v.abs() as f64) * 1e-3 + 1e-7,
                };
                let err = (planes[p][q] - v).abs() as f64;
                assert!(
                    err <= tolerance,
                    "layer {l} plane {i}/{c} pixel {p}: {} vs {v}",
                    planes[p][q]
                );
            }
        }
    }
    let depth = std::fs::read(site.join("data/depth.f32")).unwrap();
    let depth: Vec<f32> = depth
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(&depth, image.depth.as_ref().unwrap());
}

#[test]
fn u8_planes_round_trip_within_half_a_step() {
    check(PlaneStorage::U8);
}

#[test]
fn f16_planes_round_trip_within_half_precision() {
    check(PlaneStorage::F16);
}

#[test]
fn export_replaces_an_earlier_export_but_not_other_folders() {
    let (dir, _, _) = export(PlaneStorage::U8);
    let exr = dir.path().join("scene.exr");
    let site = dir.path().join("site");
    // Again over the earlier export: replaced.
    export_web(&exr, &site, &BundleOptions::default()).unwrap();
    let info: Value =
        serde_json::from_slice(&std::fs::read(site.join("data/info.json")).unwrap()).unwrap();
    assert_eq!(info["storage"], "f16");
    // A folder with other things in it is refused and left alone.
    let other = dir.path().join("other");
    std::fs::create_dir(&other).unwrap();
    std::fs::write(other.join("keep.txt"), "x").unwrap();
    assert!(export_web(&exr, &other, &BundleOptions::default()).is_err());
    assert!(other.join("keep.txt").is_file());
    // A missing input is a clear error and leaves nothing behind.
    let err = export_web(
        &dir.path().join("missing.exr"),
        &dir.path().join("x"),
        &BundleOptions::default(),
    )
    .unwrap_err();
    assert!(!dir.path().join("x").exists(), "{err}");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".relit"))
        .collect();
    assert!(leftovers.is_empty());
}

#[test]
fn an_export_never_replaces_a_folder_holding_its_input() {
    let (dir, _, _) = export(PlaneStorage::U8);
    // The maps moved into the earlier export, which a new export would replace whole.
    let site = dir.path().join("site");
    let inside = site.join("scene.exr");
    std::fs::rename(dir.path().join("scene.exr"), &inside).unwrap();
    let before = std::fs::read(&inside).unwrap();
    let err = export_web(&inside, &site, &BundleOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("refusing") && err.contains("scene.exr"),
        "{err}"
    );
    assert_eq!(std::fs::read(&inside).unwrap(), before);
    // An environment map inside the folder.
    let outside = dir.path().join("scene.exr");
    std::fs::rename(&inside, &outside).unwrap();
    let options = BundleOptions {
        environments: vec![site.join("data/info.json")],
        ..Default::default()
    };
    let err = export_web(&outside, &site, &options)
        .unwrap_err()
        .to_string();
    assert!(err.contains("info.json"), "{err}");
    assert!(site.join("data/info.json").is_file());
}
