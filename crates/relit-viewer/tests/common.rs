//! A small relightable image for the tests: pseudo-random coefficients, depth, camera.

use relit::basis::BasisSpec;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};

pub fn sample_image(width: usize, height: usize, bands: usize) -> RelightableImage {
    let k = bands * bands;
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
    let mut meta = Metadata::new(
        BasisSpec::named(&format!("sh:{}", bands * bands)).unwrap(),
        MapSpace::Linear,
        projection.clone(),
    );
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
