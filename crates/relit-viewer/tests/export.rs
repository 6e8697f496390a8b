//! `export_web`: info.json, planes within their quantisation, the weight table, SH
//! windows, environments as radiance.

mod common;

use relit::basis::{Basis, WeightTable};
use relit::envmap::{latlong_direction, texel_solid_angle, Window};
use relit::image::ImageRgb;
use relit::storage::Precision;
use relit_viewer::bundle::{environment_quadrature, shipped_table};
use relit_viewer::{export_web, BundleOptions, WebBundle};
use serde_json::Value;

fn export(storage: Precision) -> (tempfile::TempDir, relit::maps::RelightableImage, Value) {
    let dir = tempfile::tempdir().unwrap();
    let image = common::sample_image(40, 10, 3);
    let exr = dir.path().join("scene.exr");
    relit::codec::exr::write(&exr, &image, Precision::F32).unwrap();
    let site = dir.path().join("site");
    let options = BundleOptions {
        precision: storage,
        ..Default::default()
    };
    export_web(&exr, &site, &options).unwrap();
    let info: Value =
        serde_json::from_slice(&std::fs::read(site.join("data/info.json")).unwrap()).unwrap();
    (dir, image, info)
}

/// The values of little-endian half floats.
fn halves(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(2)
        .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
        .collect()
}

/// Decode layer `l` into its four planes of values: `offset + scale · q`.
fn decode(site: &std::path::Path, info: &Value, l: usize) -> Vec<[f32; 4]> {
    let layer = &info["layers"][l];
    let path = site.join("data").join(layer["file"].as_str().unwrap());
    let scale: Vec<f64> = layer["scale"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let offset: Vec<f64> = layer["offset"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    match info["storage"].as_str().unwrap() {
        "u8" => {
            let img = image::open(&path).unwrap().into_rgba8();
            img.pixels()
                .map(|p| std::array::from_fn(|q| (offset[q] + scale[q] * p.0[q] as f64) as f32))
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

fn check(storage: Precision) {
    let (dir, image, info) = export(storage);
    let site = dir.path().join("site");
    assert_eq!(info["format"], "relit-web");
    assert_eq!(info["width"], 40);
    assert_eq!(info["height"], 10);
    assert_eq!(info["k"], 9);
    assert_eq!(info["version"], 2);
    assert_eq!(info["basis"]["name"], "sh:9");
    assert_eq!(info["basis"]["spec"]["type"], "sh");
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
            let step = layer["scale"][q].as_f64().unwrap();
            for (p, &v) in original.iter().enumerate() {
                let tolerance = match storage {
                    Precision::U8 => 0.5 * step + 1e-6,
                    _ => (v.abs() as f64) * 1e-3 + 1e-7,
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
    // The weight table: WeightTable::for_basis of the file's basis, as half floats.
    let basis = image.meta.basis.build().unwrap();
    let (table, _) = WeightTable::for_basis(basis.as_ref());
    assert_eq!(info["weights"]["resolution"], table.resolution);
    assert_eq!(info["weights"]["format"], "f16le");
    let bytes = std::fs::read(
        site.join("data")
            .join(info["weights"]["file"].as_str().unwrap()),
    )
    .unwrap();
    let values = halves(&bytes);
    let table = shipped_table(&table);
    assert_eq!(values, table.values);
}

/// 8-bit layers code each plane as the CPU engine does: its least value and one step of
/// its range in 255 steps, the nearest code.
#[test]
fn u8_layers_use_the_engines_coding() {
    let (dir, image, info) = export(Precision::U8);
    let site = dir.path().join("site");
    let layer = &info["layers"][0];
    let plane = image.maps.plane(0, 0);
    let lo = plane.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = plane.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    assert_eq!(layer["offset"][0].as_f64().unwrap() as f32, lo);
    assert_eq!(
        layer["scale"][0].as_f64().unwrap() as f32,
        (hi - lo) / 255.0
    );
    let img = image::open(site.join("data").join(layer["file"].as_str().unwrap()))
        .unwrap()
        .into_rgba8();
    let inv = 1.0 / ((hi - lo) / 255.0);
    for (p, px) in img.pixels().enumerate() {
        let q = ((plane[p] - lo) * inv).round().clamp(0.0, 255.0) as u8;
        assert_eq!(px.0[0], q, "pixel {p}");
    }
}

#[test]
fn u8_planes_round_trip_within_half_a_step() {
    check(Precision::U8);
}

#[test]
fn f16_planes_round_trip_within_half_precision() {
    check(Precision::F16);
}

#[test]
fn export_replaces_an_earlier_export_but_not_other_folders() {
    let (dir, _, _) = export(Precision::U8);
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
    let (dir, _, _) = export(Precision::U8);
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

/// SH files carry each coefficient's factor of every band window (and the eigenvalue a
/// Laplacian window of the rig's own λ needs); other bases carry none.
#[test]
fn sh_files_carry_their_band_windows_and_other_bases_none() {
    let image = common::sample_image(24, 8, 3);
    let bundle = WebBundle::build(&image, &BundleOptions::default()).unwrap();
    let info: Value = serde_json::from_slice(bundle.info()).unwrap();
    let windows = &info["basis"]["windows"];
    for (name, window) in [
        ("none", Window::None),
        ("hann", Window::Hann),
        ("lanczos", Window::Lanczos),
        ("laplacian", Window::Laplacian { lambda: None }),
    ] {
        let h = window.factors(3).unwrap();
        let got: Vec<f64> = windows["factors"][name]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        // Flat index l(l+1) + m: band 0 is coefficient 0, band 1 are 1–3, band 2 are 4–8.
        let want: Vec<f64> = [0, 1, 1, 1, 2, 2, 2, 2, 2].iter().map(|&l| h[l]).collect();
        assert_eq!(got, want, "{name}");
    }
    assert_eq!(
        windows["laplacian_eigenvalues"],
        serde_json::json!([0, 2, 2, 2, 6, 6, 6, 6, 6])
    );

    let lobes = common::Lobes::new(7);
    let image = common::sample_image_of(24, 8, lobes.spec(), 7);
    let bundle = WebBundle::build_in(
        &image,
        Box::new(common::Lobes::new(7)),
        &BundleOptions::default(),
    )
    .unwrap();
    let info: Value = serde_json::from_slice(bundle.info()).unwrap();
    assert_eq!(info["basis"]["name"], "test-lobes:7");
    assert!(info["basis"].get("windows").is_none());
    let (table, _) = WeightTable::for_basis(&lobes);
    assert_eq!(
        halves(&bundle.files["data/weights.f16"]),
        shipped_table(&table).values
    );
    // The shipped table's accuracy is its own, measured after rounding.
    let shipped = shipped_table(&table).accuracy(&lobes);
    assert_eq!(
        info["weights"]["relative_rms_error"].as_f64(),
        Some(shipped.relative_rms)
    );
    // A basis of another size than the maps is refused.
    assert!(WebBundle::build_in(
        &image,
        Box::new(common::Lobes::new(9)),
        &BundleOptions::default()
    )
    .is_err());
}

/// Environments are shipped as their quadrature: at most 128×64 directional lights of
/// unit direction whose intensities add up to the map's integral `∫ E dω`, each at the
/// energy centroid of the texels it gathers.
#[test]
fn environments_ship_a_quadrature_that_keeps_their_integral() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (600, 300);
    let mut map = ImageRgb::new(w, h);
    for (i, v) in map.data.iter_mut().enumerate() {
        *v = ((i * 7919) % 1000) as f32 / 100.0;
    }
    let path = dir.path().join("sky.exr");
    relit::image::save(&path, &map, 0.0).unwrap();
    let image = common::sample_image(24, 8, 2);
    let options = BundleOptions {
        environments: vec![path.clone()],
        ..Default::default()
    };
    let bundle = WebBundle::build(&image, &options).unwrap();
    let info: Value = serde_json::from_slice(bundle.info()).unwrap();
    let env = &info["environments"][0];
    assert_eq!(
        (env["width"].as_u64(), env["height"].as_u64()),
        (Some(600), Some(300))
    );
    assert_eq!(env["lights"].as_u64(), Some(128 * 64));
    let values: Vec<f32> = bundle.files[&format!("data/{}", env["file"].as_str().unwrap())]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(values.len(), 6 * 128 * 64);
    // The map as loaded (EXR stores half floats).
    let loaded = relit::image::load_linear(&path, None).unwrap();
    for c in 0..3 {
        let want: f64 = (0..h)
            .map(|y| {
                texel_solid_angle(w, h, y)
                    * (0..w)
                        .map(|x| loaded.data[3 * (y * w + x) + c] as f64)
                        .sum::<f64>()
            })
            .sum();
        let got: f64 = values.chunks_exact(6).map(|l| l[3 + c] as f64).sum();
        assert!(
            (got - want).abs() <= 1e-5 * want,
            "channel {c}: {got} vs {want}"
        );
    }
    for l in values.chunks_exact(6) {
        let n = (l[0] as f64).hypot(l[1] as f64).hypot(l[2] as f64);
        assert!((n - 1.0).abs() < 1e-6, "{l:?}");
    }
    // A map no larger than the quadrature keeps its texels, at their centres.
    let small = environment_quadrature(&loaded, 1000, 1000);
    assert_eq!(small.len(), w * h);
    let d = latlong_direction(3.5 / w as f64, 7.5 / h as f64);
    assert!((small[7 * w + 3].0 - d).length() < 1e-12);
}

/// A codebook image ships its entries (256 a row, the last row padded with the last
/// entry) and one 16-bit index a pixel; the entries' layers decode to the entries, and a
/// bad index is refused.
#[test]
fn codebook_images_ship_entries_and_indices() {
    use relit::engine::lookup::IndexedImage;
    let image = common::sample_image(6, 5, 3);
    let k = image.maps.k;
    let c = 300;
    let mut entries = relit::maps::CoefficientMaps::zeros(c, 1, k);
    for (i, v) in entries.data.iter_mut().enumerate() {
        *v = ((i * 37) % 101) as f32 / 200.0 - 0.1;
    }
    let n = 6 * 5;
    let indexed = IndexedImage {
        entries: relit::maps::RelightableImage {
            meta: image.meta.clone(),
            maps: entries,
            depth: None,
        },
        indices: (0..n).map(|p| ((p * 53) % c) as u16).collect(),
        width: 6,
        height: 5,
    };
    let options = BundleOptions {
        precision: Precision::F16,
        ..Default::default()
    };
    let bundle = WebBundle::build_indexed(&indexed, &options).unwrap();
    let info: Value = serde_json::from_slice(bundle.info()).unwrap();
    assert_eq!(info["width"], 6);
    assert_eq!(info["codebook"]["entries"], c);
    assert_eq!(
        (
            info["codebook"]["width"].as_u64(),
            info["codebook"]["height"].as_u64()
        ),
        (Some(256), Some(2))
    );
    let indices = &bundle.files["data/indices.u16"];
    let read: Vec<u16> = indices
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    assert_eq!(read, indexed.indices);
    // Layer 0 of channel 0 holds coefficients 0–3 of each entry, 256 × 2 texels.
    let layer = &bundle.files[&format!("data/{}", info["layers"][0]["file"].as_str().unwrap())];
    let values = halves(layer);
    assert_eq!(values.len(), 4 * 256 * 2);
    for e in [0, 255, 256, 299, 300, 511] {
        let want = indexed.entries.maps.plane(0, 0)[e.min(c - 1)];
        assert!(
            (values[4 * e] - want).abs() < 1e-3,
            "entry {e}: {} vs {want}",
            values[4 * e]
        );
    }
    let mut bad = indexed.clone();
    bad.indices[3] = c as u16;
    assert!(WebBundle::build_indexed(&bad, &options).is_err());
}
