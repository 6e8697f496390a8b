//! End-to-end checks of the capture studio on tiny analytic scenes: depth, shadows,
//! determinism, capture = ground truth, files on disk, OBJ models, and capture → fit
//! → relight at a held-out light.

use relit::camera::{Camera, CameraSpec, Pose, Projection};
use relit::capture::Capture;
use relit::progress::Silent;
use relit::sphere::{self, Vec3};
use relit_studio::capture::{capture_in_memory, capture_to_folder, ImageFormat};
use relit_studio::emitter::Emitter;
use relit_studio::material::Material;
use relit_studio::math::{v3, Transform, V3};
use relit_studio::render::{RenderOptions, Renderer};
use relit_studio::scene::{Scene, SceneBuilder};
use relit_studio::shapes;
use relit_studio::texture::Texture;
use std::path::{Path, PathBuf};

const ALBEDO: f32 = 0.5;

fn any_camera() -> CameraSpec {
    CameraSpec {
        projection: Projection::Equirectangular,
        width: 8,
        height: 4,
        pose: Pose::identity(),
        orthographic_height: None,
    }
}

/// A 200 m square wall in the plane z = −`distance`, facing the origin (wide enough
/// for every ray with a z component below −0.2 to reach it).
fn wall_scene(distance: f32) -> Scene {
    let mut b = SceneBuilder::new();
    let grey = b.material(Material::matte(
        "grey",
        Texture::Constant(V3::splat(ALBEDO)),
    ));
    b.add(
        &shapes::quad(
            v3(-100.0, -100.0, -distance),
            v3(200.0, 0.0, 0.0),
            v3(0.0, 200.0, 0.0),
        ),
        &Transform::IDENTITY,
        grey,
    );
    b.build("wall", any_camera()).unwrap()
}

/// A floor at y = 0 and a 0.4 m square plate at height 1 above the origin, seen from
/// (0, 5, 5); `plate_casts` decides whether the plate blocks light.
fn plate_scene(plate_casts: bool) -> (Scene, Camera) {
    let mut b = SceneBuilder::new();
    let floor = b.material(Material::matte(
        "floor",
        Texture::Constant(V3::splat(ALBEDO)),
    ));
    let mut plate = Material::matte("plate", Texture::Constant(V3::splat(0.2)));
    plate.casts_shadows = plate_casts;
    let plate = b.material(plate);
    b.add(
        &shapes::quad(v3(-5.0, 0.0, 5.0), v3(10.0, 0.0, 0.0), v3(0.0, 0.0, -10.0)),
        &Transform::IDENTITY,
        floor,
    );
    b.add(
        &shapes::quad(v3(-0.2, 1.0, 0.2), v3(0.4, 0.0, 0.0), v3(0.0, 0.0, -0.4)),
        &Transform::IDENTITY,
        plate,
    );
    let pose = Pose::look_at(
        Vec3::new(0.0, 5.0, 5.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    )
    .unwrap();
    let camera = Camera::new(
        &Projection::Planar {
            fov_y_deg: Some(45.0),
        },
        96,
        72,
        pose,
    )
    .unwrap();
    (b.build("plate", any_camera()).unwrap(), camera)
}

fn pixel_value(image: &relit::image::ImageRgb, camera: &Camera, p: Vec3) -> [f32; 3] {
    let [x, y] = camera.pixel(p).expect("the point is in view");
    image.get(x as usize, y as usize)
}

#[test]
fn depth_is_exact_on_a_plane_at_a_known_distance() {
    // f32 tracing of a 5 m distance: a few ulps of 5 (≈ 5e-7 each) plus rounding of the
    // ray direction; 1e-5 relative is far above that and far below any real error.
    const RELATIVE_TOLERANCE: f64 = 1e-5;
    let distance = 5.0;
    let scene = wall_scene(distance as f32);
    let eye = Pose::at(Vec3::new(0.3, -0.2, 0.0));
    for projection in [
        Projection::Planar {
            fov_y_deg: Some(60.0),
        },
        Projection::Cylindrical { fov_y_deg: None },
    ] {
        let camera = Camera::new(&projection, 64, 32, eye).unwrap();
        let renderer = Renderer::new(&scene, &camera, &RenderOptions::default(), &Silent).unwrap();
        let mut checked = 0;
        for y in 0..camera.height() {
            for x in 0..camera.width() {
                let direction = camera.pixel_ray(x, y).direction;
                let depth = renderer.depth()[y * camera.width() + x] as f64;
                if direction.z < -0.2 {
                    let expected = distance / -direction.z;
                    assert!(
                        (depth - expected).abs() < RELATIVE_TOLERANCE * expected,
                        "{projection:?} ({x}, {y}): {depth} vs {expected}"
                    );
                    let p = camera.position(x, y, depth);
                    assert!(
                        (p.z + distance).abs() < 1e-4,
                        "P = E + d·V lies on the wall: {p:?}"
                    );
                    checked += 1;
                } else if direction.z >= 0.0 {
                    assert_eq!(depth, 0.0, "nothing behind the eye");
                    assert_eq!(renderer.mask()[y * camera.width() + x], 0.0);
                }
            }
        }
        assert!(checked > 300, "{checked}");
    }
}

#[test]
fn a_shadow_falls_where_the_geometry_says() {
    let (scene, camera) = plate_scene(true);
    let renderer = Renderer::new(&scene, &camera, &RenderOptions::default(), &Silent).unwrap();
    // Light from straight above: the plate's shadow is the square under it.
    let overhead = renderer
        .render_directional(Vec3::new(0.0, 1.0, 0.0))
        .unwrap()
        .image;
    let lit = pixel_value(&overhead, &camera, Vec3::new(1.5, 0.0, 0.0));
    assert!(
        (lit[0] - ALBEDO).abs() < 1e-6,
        "unit light, normal incidence: the albedo, got {lit:?}"
    );
    // Seen past the plate (the view line clears it), the floor right under it is dark.
    assert_eq!(
        pixel_value(&overhead, &camera, Vec3::new(0.0, 0.0, 0.0)),
        [0.0; 3]
    );
    // Light from 45° toward +x: the shadow moves 1 m toward −x and the floor reads cos 45°.
    let slanted = renderer
        .render_directional(Vec3::new(1.0, 1.0, 0.0))
        .unwrap()
        .image;
    assert_eq!(
        pixel_value(&slanted, &camera, Vec3::new(-1.0, 0.0, 0.0)),
        [0.0; 3]
    );
    let under_plate_now_lit = pixel_value(&slanted, &camera, Vec3::new(1.0, 0.0, 0.1));
    assert!(
        (under_plate_now_lit[0] - ALBEDO * std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-5,
        "{under_plate_now_lit:?}"
    );
    // A point light 1 m above the plate throws a shadow twice its size: the floor
    // 0.3 m from the centre is dark, though the overhead sun lit it.
    let lamp = Emitter::from_light(&relit::light::Light::point([0.0, 2.0, 0.0], [1.0; 3])).unwrap();
    let under_lamp = renderer.render(&[lamp]).image;
    assert_eq!(
        pixel_value(&under_lamp, &camera, Vec3::new(0.3, 0.0, 0.0)),
        [0.0; 3]
    );
    assert!(pixel_value(&overhead, &camera, Vec3::new(0.3, 0.0, 0.0))[0] > 0.4);
    // Elsewhere the floor reads albedo · cos θ / r² (inverse square, unit intensity at
    // 1 m), at the very point the pixel sees (P = E + d·V from the depth map).
    let [x, y] = camera.pixel(Vec3::new(1.5, 0.0, 0.0)).unwrap();
    let (x, y) = (x as usize, y as usize);
    let seen = camera.position(x, y, renderer.depth()[y * camera.width() + x] as f64);
    let r = (Vec3::new(0.0, 2.0, 0.0) - seen).length();
    let expected = ALBEDO as f64 * (2.0 / r) / (r * r);
    let lamp_lit = under_lamp.get(x, y)[0] as f64;
    assert!(
        (lamp_lit - expected).abs() < 1e-4 * expected,
        "{lamp_lit} vs {expected}"
    );
    // A material that lets light through casts nothing.
    let (open_scene, _) = plate_scene(false);
    let open = Renderer::new(&open_scene, &camera, &RenderOptions::default(), &Silent).unwrap();
    let no_shadow = open
        .render_directional(Vec3::new(1.0, 1.0, 0.0))
        .unwrap()
        .image;
    assert!(pixel_value(&no_shadow, &camera, Vec3::new(-1.0, 0.0, 0.0))[0] > 0.3);
}

#[test]
fn renders_are_deterministic_and_capture_equals_ground_truth() {
    let scene = relit_studio::scenes::build("box").unwrap();
    let camera = Camera::new(
        &Projection::Planar {
            fov_y_deg: Some(50.0),
        },
        40,
        30,
        scene.camera.pose,
    )
    .unwrap();
    let options = RenderOptions {
        supersample: 2,
        indirect_samples: 4,
    };
    let direction = Vec3::new(-0.4, 0.8, 0.45);
    let captured = capture_in_memory(&scene, &camera, &[direction], &options, &Silent).unwrap();
    let image = captured.capture.load(0).unwrap();
    let emitter =
        Emitter::from_light(&relit::light::Light::directional(direction, [1.0; 3])).unwrap();
    let truth = relit_studio::render_truth(
        &scene,
        &camera,
        std::slice::from_ref(&emitter),
        &options,
        &Silent,
    )
    .unwrap();
    assert_eq!(image, truth, "capture and ground truth shade identically");
    let again = relit_studio::render_truth(
        &scene,
        &camera,
        std::slice::from_ref(&emitter),
        &options,
        &Silent,
    )
    .unwrap();
    assert_eq!(truth, again, "deterministic");
    // Superposition: two lights together are the sum of each alone (linear radiance).
    let second = Emitter::directional(Vec3::new(0.5, 0.5, -0.2), [0.2, 0.4, 0.9]).unwrap();
    let renderer = Renderer::new(&scene, &camera, &options, &Silent).unwrap();
    let both = renderer.render(&[emitter, second.clone()]).image;
    let alone = renderer.render(&[second]).image;
    for ((b, a), t) in both.data.iter().zip(&alone.data).zip(&truth.data) {
        assert!((b - a - t).abs() < 1e-5);
    }
    assert!(captured.stats.rays_per_second > 0.0 && captured.stats.shadow_rays > 0);
}

#[test]
fn folder_capture_reopens_with_depth_mask_and_linear_png() {
    let scene = relit_studio::scenes::build("box").unwrap();
    let camera = Camera::new(
        &Projection::Planar {
            fov_y_deg: Some(50.0),
        },
        24,
        18,
        scene.camera.pose,
    )
    .unwrap();
    let dirs = sphere::hemisphere_fibonacci(5);
    let memory =
        capture_in_memory(&scene, &camera, &dirs, &RenderOptions::default(), &Silent).unwrap();
    for format in [ImageFormat::Exr, ImageFormat::Png16] {
        let dir = tempfile::tempdir().unwrap();
        let written = capture_to_folder(
            &scene,
            &camera,
            &dirs,
            &RenderOptions::default(),
            dir.path(),
            format,
            &Silent,
        )
        .unwrap();
        for file in ["capture.lp", "depth.exr", "mask.png", "camera.json"] {
            assert!(dir.path().join(file).is_file(), "{file}");
        }
        let reopened = Capture::open(&written.manifest).unwrap();
        assert_eq!(
            (reopened.len(), reopened.width, reopened.height),
            (5, 24, 18)
        );
        assert_eq!(reopened.projection, camera.projection());
        assert_eq!(
            reopened.depth.as_deref(),
            memory.capture.depth.as_deref(),
            "depth is stored as 32-bit float"
        );
        assert_eq!(reopened.mask.as_deref(), memory.capture.mask.as_deref());
        // Half floats keep ~11 bits; 16-bit PNG keeps 1/65535 of [0, 1] (values above
        // 1 are clipped, none in this scene at this light level is close).
        let tolerance = if format == ImageFormat::Exr {
            1e-3
        } else {
            2e-5
        };
        for i in 0..dirs.len() {
            let (a, b) = (reopened.load(i).unwrap(), memory.capture.load(i).unwrap());
            for (x, y) in a.data.iter().zip(&b.data) {
                assert!(
                    (x - y).abs() <= tolerance * y.max(1.0),
                    "{format:?} light {i}: {x} vs {y}"
                );
            }
        }
        let lp = relit::capture::Capture::open(&dir.path().join("capture.lp")).unwrap();
        assert_eq!(lp.directions().len(), 5);
        let spec: CameraSpec =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("camera.json")).unwrap())
                .unwrap();
        let rebuilt = spec.build().unwrap();
        assert_eq!(rebuilt.projection(), camera.projection());
        let (a, b) = (rebuilt.pixel_ray(3, 4), camera.pixel_ray(3, 4));
        assert!(
            (a.origin - b.origin).length() < 1e-12 && (a.direction - b.direction).length() < 1e-12,
            "JSON keeps the pose"
        );
    }
}

#[test]
fn a_small_obj_model_loads_with_its_material() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tri.mtl"),
        "newmtl shiny\nKd 0.8 0.2 0.1\nKs 0.3 0.3 0.3\nNs 50\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("tri.obj"),
        "mtllib tri.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn 0 0 1\nusemtl shiny\nf 1//1 2//1 3//1 4//1\n",
    )
    .unwrap();
    let scene = relit_studio::open_scene(dir.path().join("tri.obj").to_str().unwrap()).unwrap();
    assert_eq!(scene.triangle_count(), 2, "the quad is triangulated");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let m = scene
        .materials()
        .iter()
        .find(|m| m.name == "tri/shiny")
        .unwrap();
    assert!(matches!(m.albedo, Texture::Constant(c) if (c - v3(0.8, 0.2, 0.1)).length() < 1e-6));
    assert!((m.specular - 0.3).abs() < 1e-6 && m.shininess == 50.0);
    // The default camera frames the model from +z: the centre pixel sees it.
    let camera = scene.default_camera().unwrap();
    let renderer = Renderer::new(&scene, &camera, &RenderOptions::default(), &Silent).unwrap();
    assert_eq!(
        renderer.mask()[(camera.height() / 2) * camera.width() + camera.width() / 2],
        1.0
    );
    // A missing MTL file is a warning, not a failure.
    std::fs::write(
        dir.path().join("bare.obj"),
        "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let bare = relit_studio::open_scene(dir.path().join("bare.obj").to_str().unwrap()).unwrap();
    assert_eq!(bare.warnings.len(), 1);
    std::fs::write(dir.path().join("broken.obj"), "v 0 0 0\nf 1 2 7\n").unwrap();
    assert!(relit_studio::open_scene(dir.path().join("broken.obj").to_str().unwrap()).is_err());
}

#[test]
fn a_scene_lists_every_file_it_was_read_from() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let tex = relit::image::ImageRgb::new(2, 2);
    relit::image::save(&d.join("wood.png"), &tex, 0.0).unwrap();
    relit::image::save(&d.join("paint.png"), &tex, 0.0).unwrap();
    std::fs::write(
        d.join("tri.mtl"),
        "newmtl m\nKd 0.5 0.5 0.5\nmap_Kd paint.png\n",
    )
    .unwrap();
    std::fs::write(
        d.join("tri.obj"),
        "mtllib tri.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nusemtl m\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        d.join("scene.json"),
        r#"{"materials":{"wood":{"texture":{"type":"image","file":"wood.png"}}},
            "objects":[{"type":"quad","size":[1,1],"material":"wood"},{"type":"obj","file":"tri.obj"}]}"#,
    )
    .unwrap();
    let scene = relit_studio::open_scene(d.join("scene.json").to_str().unwrap()).unwrap();
    let expected: Vec<PathBuf> = ["scene.json", "wood.png", "tri.obj", "tri.mtl", "paint.png"]
        .iter()
        .map(|n| d.join(n))
        .collect();
    assert_eq!(scene.files, expected);
    let obj = relit_studio::open_scene(d.join("tri.obj").to_str().unwrap()).unwrap();
    assert_eq!(obj.files, expected[2..]);
    assert!(relit_studio::scenes::build("box").unwrap().files.is_empty());
    assert_eq!(
        relit_studio::scene_path("x/scene.JSON"),
        Some(Path::new("x/scene.JSON"))
    );
    assert_eq!(relit_studio::scene_path("box"), None);
    assert_eq!(
        relit_studio::plan::LightPlan::list_file(" List: dirs.txt"),
        Some(Path::new("dirs.txt"))
    );
    assert_eq!(
        relit_studio::plan::LightPlan::list_file("fibonacci:8"),
        None
    );
}

#[test]
fn a_folder_capture_refuses_a_folder_holding_the_scene_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("scene.json"),
        r#"{"materials":{"grey":{}},"objects":[{"type":"quad","size":[1,1],"material":"grey"}]}"#,
    )
    .unwrap();
    let scene = relit_studio::open_scene(d.join("scene.json").to_str().unwrap()).unwrap();
    let camera = Camera::new(
        &Projection::Planar {
            fov_y_deg: Some(50.0),
        },
        8,
        6,
        scene.camera.pose,
    )
    .unwrap();
    let dirs = sphere::hemisphere_fibonacci(2);
    let before = std::fs::read(d.join("scene.json")).unwrap();
    let err = capture_to_folder(
        &scene,
        &camera,
        &dirs,
        &RenderOptions::default(),
        d,
        ImageFormat::Exr,
        &Silent,
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("scene.json"), "{err}");
    assert_eq!(std::fs::read(d.join("scene.json")).unwrap(), before);
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 1, "nothing written");
}

/// The shared models (`../shared/data/models`), when present beside the repository.
fn shared_model(name: &str) -> Option<PathBuf> {
    relit::skip::shared(&format!("data/models/{name}"))
}

#[test]
fn shared_models_load_and_render() {
    for (name, min_triangles) in [("bunny.obj", 4000), ("CornellBox-Original.obj", 30)] {
        let Some(path) = shared_model(name) else {
            continue;
        };
        let scene = relit_studio::open_scene(path.to_str().unwrap()).unwrap();
        assert!(
            scene.triangle_count() >= min_triangles,
            "{name}: {}",
            scene.triangle_count()
        );
        let camera = Camera::new(
            &Projection::Planar {
                fov_y_deg: Some(40.0),
            },
            32,
            24,
            scene.camera.pose,
        )
        .unwrap();
        let renderer = Renderer::new(&scene, &camera, &RenderOptions::default(), &Silent).unwrap();
        let image = renderer
            .render_directional(Vec3::new(0.2, 0.6, 0.8))
            .unwrap()
            .image;
        let hit = renderer.mask().iter().filter(|&&m| m > 0.5).count();
        assert!(
            hit > 50,
            "{name}: the framing camera sees the model ({hit} pixels)"
        );
        assert!(
            image.data.iter().any(|&v| v > 0.05),
            "{name}: something is lit"
        );
    }
}

#[test]
fn capture_fit_relight_beats_the_psnr_floor_at_a_held_out_light() {
    use relit::engine::{relight, RelightOptions};
    use relit::fit::{fit, FitOptions, Lambda, Objective};
    use relit::light::{Light, LightRig};

    let scene = relit_studio::scenes::build("box").unwrap();
    let camera = Camera::new(
        &Projection::Planar {
            fov_y_deg: Some(50.0),
        },
        48,
        36,
        scene.camera.pose,
    )
    .unwrap();
    let dirs = sphere::fibonacci(400);
    let captured =
        capture_in_memory(&scene, &camera, &dirs, &RenderOptions::default(), &Silent).unwrap();
    // Linear least squares: the images are linear radiance and so is the comparison.
    // λ = 1e-3 is what the automatic leave-one-out choice picks here; fixing it keeps
    // the test at a tenth of a second instead of seconds.
    let options = FitOptions {
        basis: relit::fit::BasisRequest::parse("sh:36").unwrap(),
        objective: Objective::Linear,
        lambda: Lambda::Fixed(1e-3),
        ..Default::default()
    };
    let fitted = fit(&captured.capture, &options, &Silent).unwrap();
    // A light between the captured ones, high over the front right of the box.
    let held_out = Vec3::new(0.35, 0.8, 0.45).normalized().unwrap();
    assert!(
        dirs.iter().all(|d| d.dot(held_out) < 0.9995),
        "not one of the captured lights"
    );
    let rig = LightRig::new(vec![Light::directional(held_out, [1.0; 3])]);
    let relit_image = relight(&fitted.image, &rig, &RelightOptions::default()).unwrap();
    let truth = Renderer::new(&scene, &camera, &RenderOptions::default(), &Silent)
        .unwrap()
        .render_directional(held_out)
        .unwrap()
        .image;
    let psnr = relit::metrics::psnr_linear(&relit_image.data, &truth.data, None, 1.0);
    // Floor: 34 dB (linear radiance, peak 1, whole frame). Measured 37.5 dB: 36 SH
    // coefficients cannot follow the hard shadow's edge or the box's glossy highlight
    // (Blinn–Phong exponent 60 needs bands up to ~√60), so the error sits there and
    // cannot vanish. Relighting at the mirror image of the held-out light (a sign slip
    // in x or z of the light frame) measures 25–30 dB against this truth, and the mean
    // of all captured images 13 dB, so the floor catches frame and convention errors
    // while leaving 3.5 dB for λ choices and rounding.
    assert!(psnr > 34.0, "held-out PSNR {psnr:.2} dB");
}

#[test]
fn a_million_triangle_scene_file_builds_and_traces_exactly() {
    // A 1002-segment sphere (a million triangles) of radius 1 at the origin, seen from
    // z = 4 by a pinhole: the centre pixel's depth is 3 up to the tessellation's sag
    // (1 − cos(π/1002) ≈ 5e-6), and a light straight behind the sphere leaves the
    // visible side black.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sphere.json");
    std::fs::write(
        &path,
        r#"{
          "camera": { "projection": { "type": "planar", "fov_y_deg": 30 }, "width": 33, "height": 33,
                      "eye": [0, 0, 4], "look_at": [0, 0, 0] },
          "materials": { "white": { "albedo": [0.8, 0.8, 0.8] } },
          "objects": [ { "type": "sphere", "radius": 1, "segments": 1002, "material": "white" } ]
        }"#,
    )
    .unwrap();
    let scene = relit_studio::open_scene(path.to_str().unwrap()).unwrap();
    assert!(
        scene.triangle_count() >= 1_000_000,
        "{}",
        scene.triangle_count()
    );
    let camera = scene.camera.build().unwrap();
    let renderer = Renderer::new(&scene, &camera, &RenderOptions::default(), &Silent).unwrap();
    let centre = 16 * 33 + 16;
    assert!(
        (renderer.depth()[centre] - 3.0).abs() < 1e-4,
        "{}",
        renderer.depth()[centre]
    );
    let front = renderer
        .render(&[Emitter::directional(Vec3::new(0.0, 0.0, 1.0), [1.0; 3]).unwrap()])
        .image;
    let back = renderer
        .render(&[Emitter::directional(Vec3::new(0.0, 0.0, -1.0), [1.0; 3]).unwrap()])
        .image;
    assert!(
        (front.data[3 * centre] - 0.8).abs() < 1e-3,
        "{}",
        front.data[3 * centre]
    );
    assert_eq!(back.data[3 * centre], 0.0);
}
