//! `cargo bench -p relit --bench engine`: the CPU engine's frame time at the seed size
//! (1024×256, k = 16) for every plane storage, and per-pixel SH evaluation.
//!
//! A plain timing harness (no criterion, so `cargo test` builds nothing extra): each
//! case runs for about half a second after a warm-up frame and prints the median of
//! five batches. `relit bench` is the full benchmark (sizes, k, GPU, bandwidth and FMA
//! bounds); this one is for quick before/after comparisons of kernel changes.

use relit::basis::BasisSpec;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::engine::{PlaneStorage, Relighter, Roi, ShEvaluator};
use relit::image::ImageRgb;
use relit::light::{Light, PreparedLight};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use std::hint::black_box;
use std::time::Instant;

fn synthetic(width: usize, height: usize, bands: usize) -> RelightableImage {
    let k = bands * bands;
    let n = width * height;
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let data = (0..3 * k * n)
        .map(|i| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let r = (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
            if i < 3 * n {
                0.5 + 0.1 * r
            } else {
                0.3 * r
            }
        })
        .collect();
    let projection = Projection::Cylindrical { fov_y_deg: None };
    let mut meta = Metadata::new(
        BasisSpec::Sh { bands },
        MapSpace::Linear,
        projection.clone(),
    );
    meta.camera = Some(CameraSpec {
        projection,
        width,
        height,
        pose: Pose::default(),
        orthographic_height: None,
    });
    RelightableImage {
        meta,
        maps: CoefficientMaps {
            width,
            height,
            k,
            data,
        },
        depth: Some(vec![2.0; n]),
    }
}

/// Median seconds per call over five batches of about 0.1 s.
fn time(mut f: impl FnMut()) -> f64 {
    f();
    let t = Instant::now();
    f();
    let per_batch = ((0.1 / t.elapsed().as_secs_f64().max(1e-6)) as usize).max(1);
    let mut batches: Vec<f64> = (0..5)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..per_batch {
                f();
            }
            t.elapsed().as_secs_f64() / per_batch as f64
        })
        .collect();
    batches.sort_by(f64::total_cmp);
    batches[2]
}

fn main() {
    let (width, height, bands) = (1024, 256, 4);
    let image = synthetic(width, height, bands);
    let k = bands * bands;
    let here = std::path::Path::new("");
    let env = PreparedLight::Weights(std::array::from_fn(|c| {
        (0..k)
            .map(|i| 0.2 * (c + 1) as f64 / (1 + i) as f64)
            .collect()
    }));
    let cases = [
        (
            "directional",
            vec![Light::directional([-0.4, 0.7, 0.6], [1.0; 3])
                .prepare(here)
                .unwrap()],
        ),
        ("environment", vec![env]),
        (
            "point",
            vec![Light::point([0.3, 0.5, 0.2], [1.0; 3])
                .prepare(here)
                .unwrap()],
        ),
    ];
    println!(
        "{width}×{height}, k = {k}, {} threads",
        rayon::current_num_threads()
    );
    let full = Roi::full(width, height);
    for storage in PlaneStorage::ALL {
        let r = Relighter::with_storage(&image, storage).unwrap();
        let mut out = ImageRgb::new(0, 0);
        for (name, lights) in &cases {
            let s = time(|| {
                r.relight_prepared_into(lights, 0.0, full, &mut out)
                    .unwrap();
                black_box(&out);
            });
            println!(
                "{name:<12} {:<4} {:>8.3} ms  {:>7.1} fps  ({})",
                storage.name(),
                s * 1e3,
                1.0 / s,
                r.kernels()
            );
        }
    }
    let eval = ShEvaluator::new(bands).unwrap();
    let n = 1 << 16;
    let dirs = relit::sphere::fibonacci(n);
    let coords: [Vec<f32>; 3] = [
        dirs.iter().map(|d| d.x as f32).collect(),
        dirs.iter().map(|d| d.y as f32).collect(),
        dirs.iter().map(|d| d.z as f32).collect(),
    ];
    let mut out = vec![0f32; k * 4096];
    let s = time(|| {
        for b in (0..n).step_by(4096) {
            eval.eval(
                &coords[0][b..b + 4096],
                &coords[1][b..b + 4096],
                &coords[2][b..b + 4096],
                &mut out,
            );
        }
        black_box(&out);
    });
    println!(
        "sh_eval      one thread {:>8.1} Mpixel/s (k = {k})",
        n as f64 / s / 1e6
    );
}
