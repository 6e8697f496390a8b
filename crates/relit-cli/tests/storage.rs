//! One storage description: the CPU engine's planes, the GPU upload and the browser
//! viewer's layers decode to the same values for the same plane, in every precision
//! each back end stores (`relit::storage`; the conventions' *Stored numbers*).

use relit::basis::BasisSpec;
use relit::camera::Projection;
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::storage::{CompactPlanes, PlaneCoding, Precision};
use relit_viewer::{BundleOptions, WebBundle, PRECISIONS};
use serde_json::Value;

/// Planes of 9 SH coefficients over magnitudes from 1e-6 to 1e3, both signs, with a
/// constant plane, a plane with NaN and one with infinities.
fn image() -> RelightableImage {
    let (w, h, k) = (13, 7, 9);
    let mut maps = CoefficientMaps::zeros(w, h, k);
    let n = maps.pixels();
    for (i, v) in maps.data.iter_mut().enumerate() {
        let t = (i * 7919 % 1009) as f32 / 1009.0 - 0.4;
        *v = t * [1.0, 1e-6, 1e3, 0.01][(i / n) % 4];
    }
    maps.data[5 * n..6 * n].fill(0.375);
    maps.data[7 * n + 3] = f32::NAN;
    maps.data[8 * n + 1] = f32::INFINITY;
    maps.data[8 * n + 2] = f32::NEG_INFINITY;
    let meta = Metadata::new(
        BasisSpec::named("sh:9").unwrap(),
        MapSpace::Linear,
        Projection::default(),
    );
    RelightableImage {
        meta,
        maps,
        depth: None,
    }
}

/// The values the CPU engine reads, plane by plane.
fn cpu(maps: &CoefficientMaps, p: Precision) -> Vec<f32> {
    if p == Precision::F32 {
        return maps.data.clone();
    }
    let planes = CompactPlanes::from_maps(maps, p).unwrap();
    let n = maps.pixels();
    (0..maps.data.len())
        .map(|i| planes.value(i / n, i % n))
        .collect()
}

/// The values the viewer's layers hold, plane by plane, decoded with `info.json`'s
/// codings as the browser does.
fn viewer(image: &RelightableImage, p: Precision) -> Vec<f32> {
    let options = BundleOptions {
        precision: p,
        ..Default::default()
    };
    let bundle = WebBundle::build(image, &options).unwrap();
    let info: Value = serde_json::from_slice(bundle.info()).unwrap();
    assert_eq!(info["storage"], p.name());
    let n = image.maps.pixels();
    let mut out = vec![f32::NAN; image.maps.data.len()];
    for layer in info["layers"].as_array().unwrap() {
        let bytes = &bundle.files[&format!("data/{}", layer["file"].as_str().unwrap())];
        let texels: Vec<u8> = match p {
            Precision::U8 => image::load_from_memory(bytes)
                .unwrap()
                .into_rgba8()
                .into_raw(),
            _ => bytes.clone(),
        };
        let c = layer["channel"].as_u64().unwrap() as usize;
        let b = p.bytes_per_value();
        for (q, i) in layer["coefficients"].as_array().unwrap().iter().enumerate() {
            let i = i.as_u64().unwrap() as usize;
            let coding = PlaneCoding {
                scale: layer["scale"][q].as_f64().unwrap() as f32,
                offset: layer["offset"][q].as_f64().unwrap() as f32,
            };
            let plane: Vec<u8> = (0..n)
                .flat_map(|px| texels[(4 * px + q) * b..(4 * px + q + 1) * b].to_vec())
                .collect();
            let mut values = Vec::new();
            p.decode(&plane, coding, &mut values);
            let j = 3 * i + c;
            out[j * n..(j + 1) * n].copy_from_slice(&values);
        }
    }
    out
}

fn same(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x == y || (x.is_nan() && y.is_nan()))
}

#[test]
fn every_back_end_decodes_the_same_values() {
    let image = image();
    for p in Precision::ALL {
        let cpu = cpu(&image.maps, p);
        let gpu = relit_gpu::stored_maps(&image.maps, p).data;
        assert!(same(&cpu, &gpu), "{p}: CPU and GPU planes differ");
        let mut shared = image.maps.data.clone();
        for plane in shared.chunks_mut(image.maps.pixels()) {
            p.round_trip(plane);
        }
        assert!(
            same(&cpu, &shared),
            "{p}: CPU planes and relit::storage differ"
        );
        if PRECISIONS.contains(&p) {
            assert!(
                same(&cpu, &viewer(&image, p)),
                "{p}: CPU planes and viewer layers differ"
            );
        } else {
            let options = BundleOptions {
                precision: p,
                ..Default::default()
            };
            assert!(WebBundle::build(&image, &options).is_err());
        }
    }
}
