//! Photometric stereo (`relit::normals`) against the studio's exact geometry: a glossy
//! sphere beside a box that shadows it, captured under a dome of lights. The robust
//! estimator must beat plain least squares, which shadows and highlights bend.

use relit::normals::{self, Method};
use relit::progress::Silent;
use relit_studio::capture::capture_in_memory;
use relit_studio::plan::LightPlan;
use relit_studio::render::RenderOptions;

const SCENE: &str = r#"{
  "camera": { "projection": { "type": "planar", "fov_y_deg": 30 }, "width": 96, "height": 72,
              "eye": [0, 0, 6], "look_at": [0, 0, 0] },
  "materials": {
    "clay":  { "albedo": [0.7, 0.5, 0.4], "specular": 0.3, "shininess": 60 },
    "stone": { "albedo": [0.5, 0.5, 0.5] }
  },
  "objects": [
    { "type": "sphere", "radius": 1, "segments": 96, "material": "clay" },
    { "type": "box", "size": [0.6, 2.4, 0.6], "material": "stone", "transform": { "translate": [1.45, 0, 0.6] } }
  ]
}"#;

/// Mean angular error in degrees over the sphere's pixels.
fn sphere_error(map: &normals::NormalMap, camera: &relit::camera::Camera, depth: &[f32]) -> f64 {
    let (mut sum, mut count) = (0.0, 0);
    for y in 0..map.height {
        for x in 0..map.width {
            let p = y * map.width + x;
            if depth[p] <= 0.0 {
                continue;
            }
            let ray = camera.ray(x as f64 + 0.5, y as f64 + 0.5);
            let d = ray.direction.normalized().unwrap();
            let hit = ray.origin + d * depth[p] as f64;
            // Points on the unit sphere only (not the box).
            if (hit.length() - 1.0).abs() > 0.01 || hit.z < 0.05 {
                continue;
            }
            let truth = hit.normalized().unwrap();
            let n = map.normals[p];
            let cos = (n[0] as f64 * truth.x + n[1] as f64 * truth.y + n[2] as f64 * truth.z)
                .clamp(-1.0, 1.0);
            sum += cos.acos().to_degrees();
            count += 1;
        }
    }
    assert!(count > 1000, "{count} sphere pixels");
    sum / count as f64
}

#[test]
fn robust_photometric_stereo_beats_least_squares_on_shadows_and_highlights() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.json");
    std::fs::write(&path, SCENE).unwrap();
    let scene = relit_studio::open_scene(path.to_str().unwrap()).unwrap();
    let camera = scene.default_camera().unwrap();
    let lights = LightPlan::parse("hemisphere:64").unwrap().directions();
    let captured =
        capture_in_memory(&scene, &camera, &lights, &RenderOptions::default(), &Silent).unwrap();
    let depth = captured.capture.depth.clone().unwrap();
    let ls = normals::from_capture(&captured.capture, Method::Ls, &Silent).unwrap();
    let robust = normals::from_capture(&captured.capture, Method::Robust, &Silent).unwrap();
    let (e_ls, e_robust) = (
        sphere_error(&ls, &camera, &depth),
        sphere_error(&robust, &camera, &depth),
    );
    eprintln!("mean angular error on the sphere: least squares {e_ls:.2}°, robust {e_robust:.2}°");
    assert!(
        e_robust < 0.7 * e_ls,
        "robust {e_robust:.2}° against {e_ls:.2}°"
    );
    assert!(e_robust < 3.0, "robust {e_robust:.2}°");
    // The albedo of the clay comes back where the sphere faces the camera.
    let centre = (ls.height / 2) * ls.width + ls.width / 2;
    let a = robust.albedo[centre];
    assert!(
        (a[0] - 0.7).abs() < 0.05 && (a[2] - 0.4).abs() < 0.05,
        "albedo {a:?}"
    );
}
