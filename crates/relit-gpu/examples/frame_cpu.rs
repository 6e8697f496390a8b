//! CPU time per GPU frame on a software adapter (lavapipe), for A/B comparisons of the
//! shader on a shared machine: the process's user + system time counts lavapipe's
//! worker threads and nothing else running there, unlike wall time. Linux only
//! (`/proc/self/stat`).
//!
//! `cargo run --release -p relit-gpu --example frame_cpu [FRAMES]` relights 1024×256
//! synthetic SH maps (k = 16 and 25, f32) with a directional light, a point light and a
//! 16-sample rectangular area light, and prints CPU and wall milliseconds per frame.

use relit::basis::BasisSpec;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::light::{AreaLight, AreaShape, Light, LightRig};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::sphere::Vec3;
use relit_gpu::GpuRelighter;

/// User + system CPU seconds of this process so far.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").expect("/proc/self/stat");
    // Fields after the command name (which may hold spaces): utime and stime are the
    // 12th and 13th, in clock ticks of 1/100 s.
    let fields: Vec<&str> = stat
        .rsplit(')')
        .next()
        .unwrap_or_default()
        .split_whitespace()
        .collect();
    let ticks = |i: usize| fields[i].parse::<f64>().expect("a tick count");
    (ticks(11) + ticks(12)) / 100.0
}

/// `w×h` maps of `k` SH coefficients: pseudo-random values, a cylindrical camera, depth.
fn image(w: usize, h: usize, k: usize) -> RelightableImage {
    let mut maps = CoefficientMaps::zeros(w, h, k);
    let mut x = 0x2545_f491_u32;
    for v in maps.data.iter_mut() {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *v = (x % 10_000) as f32 / 10_000.0 - 0.3;
    }
    let projection = Projection::Cylindrical { fov_y_deg: None };
    let spec = BasisSpec::named(&format!("sh:{k}")).expect("an SH size");
    let mut meta = Metadata::new(spec, MapSpace::Linear, projection.clone());
    meta.camera = Some(CameraSpec {
        projection,
        width: w,
        height: h,
        pose: Pose::at([0.0, 1.5, 0.0].into()),
        orthographic_height: None,
    });
    let depth = (0..w * h).map(|p| 2.0 + (p % 13) as f32 * 0.1).collect();
    RelightableImage {
        meta,
        maps,
        depth: Some(depth),
    }
}

fn main() -> Result<(), relit_gpu::GpuError> {
    let frames: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let area = Light::Area(AreaLight {
        shape: AreaShape::Rect {
            center: Vec3::new(0.0, 2.5, 0.0),
            u: Vec3::new(0.5, 0.0, 0.0),
            v: Vec3::new(0.0, 0.0, 0.5),
        },
        color: [1.0; 3],
        intensity: 2.0,
        two_sided: false,
        samples: 16,
    });
    let cases = [
        (
            "directional",
            Light::directional([-0.4, 0.7, 0.6], [1.0; 3]),
        ),
        ("point", Light::point([0.3, 1.6, -0.5], [1.0; 3])),
        ("area (16 samples)", area),
    ];
    for k in [16, 25] {
        let gpu = GpuRelighter::new(&image(1024, 256, k))?;
        println!("{} (k = {k})", gpu.adapter());
        for (name, light) in &cases {
            let lighting = gpu.lighting(&LightRig::new(vec![light.clone()]), 0.0)?;
            let start = cpu_seconds();
            let wall = gpu.time_frames(&lighting, None, frames)?;
            // time_frames also runs one warm-up frame.
            let cpu = (cpu_seconds() - start) / (frames + 1) as f64;
            println!(
                "  {name}: {:.0} ms CPU, {:.0} ms wall per frame",
                1e3 * cpu,
                1e3 * wall.as_secs_f64()
            );
        }
    }
    Ok(())
}
