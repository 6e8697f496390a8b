//! Lat-long maps for tests: functions of the light vector sampled at texel centres.

use super::ImageRgb;
use crate::sphere::{latlong_direction, Vec3};

/// A map whose texel centres sample `f` (RGB).
pub(crate) fn sampled_map(width: usize, height: usize, f: impl Fn(Vec3) -> [f64; 3]) -> ImageRgb {
    let mut map = ImageRgb::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let d = latlong_direction(
                (x as f64 + 0.5) / width as f64,
                (y as f64 + 0.5) / height as f64,
            );
            let i = 3 * (y * width + x);
            map.data[i..i + 3].copy_from_slice(&f(d).map(|v| v as f32));
        }
    }
    map
}

/// A smooth, positive, coloured environment: a soft "sky" lobe and a broad fill.
pub(crate) fn smooth_sky(d: Vec3) -> [f64; 3] {
    let sun = Vec3::new(0.4, 0.7, -0.6).normalized().unwrap();
    let lobe = (3.0 * (d.dot(sun) - 1.0)).exp();
    [
        2.0 * lobe + 0.3,
        1.5 * lobe + 0.2 + 0.1 * d.y,
        lobe + 0.4 - 0.1 * d.x,
    ]
}

/// The HDR environment maps of the shared data (`../shared/data/envmaps`), sorted; `None`
/// where that folder is not beside the repository.
pub(crate) fn shared_envmaps() -> Option<Vec<std::path::PathBuf>> {
    let dir =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/envmaps");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "hdr"))
        .collect();
    paths.sort();
    (!paths.is_empty()).then_some(paths)
}
