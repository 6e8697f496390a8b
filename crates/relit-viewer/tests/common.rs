//! Small relightable images for the tests: pseudo-random coefficients, depth, camera;
//! and a basis of the tests' own that no family registers.

#![allow(dead_code)]

use relit::basis::{Basis, BasisSpec};
use relit::camera::{CameraSpec, Pose, Projection};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::sphere::{fibonacci, Vec3};

/// An SH image of `bands` bands.
pub fn sample_image(width: usize, height: usize, bands: usize) -> RelightableImage {
    let spec = BasisSpec::named(&format!("sh:{}", bands * bands)).unwrap();
    sample_image_of(width, height, spec, bands * bands)
}

/// An image of `k` coefficients per channel in the basis `spec`.
pub fn sample_image_of(width: usize, height: usize, spec: BasisSpec, k: usize) -> RelightableImage {
    let mut maps = CoefficientMaps::zeros(width, height, k);
    let mut state = 0x2545_f491_u32;
    for (i, v) in maps.data.iter_mut().enumerate() {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let r = (state % 10_000) as f32 / 10_000.0 - 0.5;
        let plane = i / (width * height);
        *v = if plane < 3 {
            0.5 + 0.2 * r
        } else {
            0.3 * r / (1 + plane / 3) as f32
        };
    }
    let projection = Projection::Cylindrical { fov_y_deg: None };
    let mut meta = Metadata::new(spec, MapSpace::Linear, projection.clone());
    meta.camera = Some(CameraSpec {
        projection,
        width,
        height,
        pose: Pose::at([0.0, 1.5, 0.0].into()),
        orthographic_height: None,
    });
    let depth = (0..width * height)
        .map(|p| {
            if p % 17 == 0 {
                0.0
            } else {
                1.0 + (p % 7) as f32 * 0.25
            }
        })
        .collect();
    RelightableImage {
        meta,
        maps,
        depth: Some(depth),
    }
}

/// A non-SH basis no family registers: `k` smooth lobes `exp(6 (μ_j·L − 1))` around
/// Fibonacci directions `μ_j`.
#[derive(Debug)]
pub struct Lobes {
    centres: Vec<Vec3>,
}

impl Lobes {
    pub fn new(k: usize) -> Lobes {
        Lobes {
            centres: fibonacci(k),
        }
    }
}

impl Basis for Lobes {
    fn spec(&self) -> BasisSpec {
        BasisSpec::new("test-lobes", serde_json::json!({ "k": self.centres.len() }))
    }
    fn family(&self) -> &'static str {
        "test-lobes"
    }
    fn len(&self) -> usize {
        self.centres.len()
    }
    fn eval(&self, dir: Vec3, out: &mut [f64]) {
        for (o, m) in out.iter_mut().zip(&self.centres) {
            *o = (6.0 * (m.dot(dir) - 1.0)).exp();
        }
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}
