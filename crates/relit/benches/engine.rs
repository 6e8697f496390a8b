//! `cargo bench -p relit --bench engine`: criterion benchmarks of the CPU engine at the
//! seed size (1024×256, k = 16): directional, environment, point, area (a rectangle,
//! 16 samples) and projector frames for every plane storage, and per-pixel SH
//! evaluation.
//!
//! Criterion reports time per frame and pixels per second (throughput in elements =
//! pixels), with its confidence intervals and the change from the last run, which makes
//! it the tool for before/after comparisons of kernel changes. `relit bench` is the full
//! benchmark (both sizes, k = 16 and 25, the GPU, and the bandwidth and FMA bounds
//! measured in the same run). `cargo bench … -- --quick` for a short run.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use relit::basis::BasisSpec;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::engine::{BasisEvaluator, Relighter, Roi};
use relit::image::ImageRgb;
use relit::light::{AreaLight, AreaShape, Light, PreparedLight, ProjectorLight};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::storage::Precision;
use std::hint::black_box;
use std::time::Duration;

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
        BasisSpec::named(&format!("sh:{}", bands * bands)).unwrap(),
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

/// A one-sided square above every surface point (all pixels take 16 samples).
fn area() -> Light {
    Light::Area(AreaLight {
        shape: AreaShape::Rect {
            center: [0.1, 2.0, -0.2].into(),
            u: [0.4, 0.0, 0.0].into(),
            v: [0.0, 0.0, 0.4].into(),
        },
        color: [1.0; 3],
        intensity: 2.0,
        two_sided: false,
        samples: 16,
    })
}

/// A projector of 90° field beside the eye (about a third of the panorama in its
/// frustum) with a 128×64 gradient slide.
fn projector() -> PreparedLight {
    let light = ProjectorLight {
        position: [0.2, 0.3, 0.1].into(),
        direction: [0.0, -0.2, -1.0].into(),
        up: [0.0, 1.0, 0.0].into(),
        fov_deg: 90.0,
        slide: String::new(),
        color: [1.0; 3],
        intensity: 3.0,
        attenuation: Default::default(),
    };
    let (w, h) = (128, 64);
    let mut slide = ImageRgb::new(w, h);
    for (p, v) in slide.data.iter_mut().enumerate() {
        *v = (p % 97) as f32 / 97.0;
    }
    PreparedLight::Projector(
        Box::new(light.with_slide(std::sync::Arc::new(slide))),
        [3.0; 3],
    )
}

const WIDTH: usize = 1024;
const HEIGHT: usize = 256;
const BANDS: usize = 4;

fn frames(c: &mut Criterion) {
    let image = synthetic(WIDTH, HEIGHT, BANDS);
    let k = BANDS * BANDS;
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
        ("area", vec![area().prepare(here).unwrap()]),
        ("projector", vec![projector()]),
    ];
    let full = Roi::full(WIDTH, HEIGHT);
    for (name, lights) in &cases {
        let mut group = c.benchmark_group(format!("{name} {WIDTH}x{HEIGHT} k{k}"));
        group.throughput(Throughput::Elements((WIDTH * HEIGHT) as u64));
        group.sample_size(30);
        group.measurement_time(Duration::from_secs(2));
        for storage in Precision::ALL {
            let r = Relighter::with_precision(&image, storage).unwrap();
            let mut out = ImageRgb::new(0, 0);
            group.bench_function(BenchmarkId::from_parameter(storage.name()), |b| {
                b.iter(|| {
                    r.relight_prepared_into(lights, 0.0, full, &mut out)
                        .unwrap();
                    black_box(&out);
                })
            });
        }
        group.finish();
    }
}

/// The SH basis at 65536 directions (one thread, blocks of 4096 directions).
fn sh_eval(c: &mut Criterion) {
    let n = 1 << 16;
    let dirs = relit::sphere::fibonacci(n);
    let coords: [Vec<f32>; 3] = [
        dirs.iter().map(|d| d.x as f32).collect(),
        dirs.iter().map(|d| d.y as f32).collect(),
        dirs.iter().map(|d| d.z as f32).collect(),
    ];
    let mut group = c.benchmark_group("sh_eval");
    group.throughput(Throughput::Elements(n as u64));
    for bands in [4, 5] {
        let sh = relit::basis::SphericalHarmonics::new(bands).unwrap();
        let eval = BasisEvaluator::new(&sh);
        let mut out = vec![0f32; eval.len() * 4096];
        group.bench_function(BenchmarkId::new("k", bands * bands), |b| {
            b.iter(|| {
                for at in (0..n).step_by(4096) {
                    eval.eval(
                        &coords[0][at..at + 4096],
                        &coords[1][at..at + 4096],
                        &coords[2][at..at + 4096],
                        &mut out,
                    );
                }
                black_box(&out);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, frames, sh_eval);
criterion_main!(benches);
