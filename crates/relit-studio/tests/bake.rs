//! `relit_studio::bake` against closed forms (an open floor's clamped cosine, a plate's
//! solid angle) and against the renderer itself: baked maps under a uniform sky equal
//! the sum of the renderer's images under many directional lights, glossy lobes and
//! one-bounce light included.

use relit::basis::{Basis, SphericalHarmonics};
use relit::camera::{Camera, CameraSpec, Pose, Projection};
use relit::envmap::Window;
use relit::maps::RelightableImage;
use relit::progress::Silent;
use relit::sphere::{self, Vec3};
use relit_studio::bake::{bake, BakeOptions, Transfer};
use relit_studio::material::Material;
use relit_studio::math::{v3, Transform, V3};
use relit_studio::render::{RenderOptions, Renderer};
use relit_studio::scene::{Scene, SceneBuilder};
use relit_studio::shapes;
use relit_studio::texture::Texture;
use std::f64::consts::PI;

const ALBEDO: f32 = 0.5;

/// A 10 m floor at y = 0 and, if `plate`, a 0.4 m square plate 1 m above the origin,
/// seen from straight above.
fn floor_scene(plate: bool) -> (Scene, Camera) {
    let mut b = SceneBuilder::new();
    let floor = b.material(Material::matte(
        "floor",
        Texture::Constant(V3::splat(ALBEDO)),
    ));
    b.add(
        &shapes::quad(v3(-5.0, 0.0, 5.0), v3(10.0, 0.0, 0.0), v3(0.0, 0.0, -10.0)),
        &Transform::IDENTITY,
        floor,
    );
    if plate {
        let grey = b.material(Material::matte("plate", Texture::Constant(V3::splat(0.2))));
        b.add(
            &shapes::quad(v3(-0.2, 1.0, 0.2), v3(0.4, 0.0, 0.0), v3(0.0, 0.0, -0.4)),
            &Transform::IDENTITY,
            grey,
        );
    }
    // Looking straight down from below the plate's height would see the plate; the eye
    // sits between floor and plate, so the centre pixel is the floor under the plate.
    let pose = Pose::look_at(
        Vec3::new(0.0, 0.5, 0.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -1.0),
    )
    .unwrap();
    let spec = CameraSpec {
        projection: Projection::Planar {
            fov_y_deg: Some(40.0),
        },
        width: 9,
        height: 9,
        pose,
        orthographic_height: None,
    };
    let camera = spec.build().unwrap();
    (b.build("floor", spec).unwrap(), camera)
}

/// The coefficients of pixel `(x, y)`, channel `c`.
fn coefficients(image: &RelightableImage, x: usize, y: usize, c: usize) -> Vec<f64> {
    let p = y * image.maps.width + x;
    image
        .maps
        .coefficients(p, c)
        .into_iter()
        .map(f64::from)
        .collect()
}

/// Exact projections (no band window), so that closed forms apply.
fn options(transfer: Transfer, samples: u32) -> BakeOptions {
    BakeOptions {
        transfer,
        samples,
        window: Window::None,
        ..BakeOptions::default()
    }
}

#[test]
fn an_open_lambertian_floor_bakes_to_the_clamped_cosine() {
    let (scene, camera) = floor_scene(false);
    let baked = bake(&scene, &camera, &options(Transfer::Diffuse, 1024), &Silent).unwrap();
    // A band window scales band l by h_l: the Laplacian default keeps band 0 and halves
    // band 4.
    let windowed = bake(
        &scene,
        &camera,
        &BakeOptions {
            samples: 1024,
            ..BakeOptions::default()
        },
        &Silent,
    )
    .unwrap();
    let (exact, halved) = (
        coefficients(&baked.image, 4, 4, 1),
        coefficients(&windowed.image, 4, 4, 1),
    );
    assert!((halved[0] - exact[0]).abs() < 1e-6);
    assert!(
        (halved[20] - 0.5 * exact[20]).abs() < 1e-4,
        "{} {}",
        halved[20],
        exact[20]
    );
    // Ramamoorthi & Hanrahan: the clamped cosine about n has the zonal coefficients
    // Â_l = π, 2π/3, π/4, 0, −π/24 for l = 0..4, so c_lm = a · Â_l · Y_lm(n).
    let a_hat = [PI, 2.0 * PI / 3.0, PI / 4.0, 0.0, -PI / 24.0];
    let sh = SphericalHarmonics::new(5).unwrap();
    let y = sh.values(Vec3::new(0.0, 1.0, 0.0));
    let got = coefficients(&baked.image, 4, 4, 1);
    for (l, a) in a_hat.iter().enumerate() {
        for i in l * l..(l + 1) * (l + 1) {
            let want = ALBEDO as f64 * a * y[i];
            assert!(
                (got[i] - want).abs() < 0.02,
                "coefficient {i} (band {l}): baked {:.4}, closed form {want:.4}",
                got[i]
            );
        }
    }
    assert_eq!(baked.image.depth.as_ref().map(Vec::len), Some(81));
    assert_eq!(baked.image.meta.basis.build().unwrap().name(), "sh:25");
    assert!(baked.stats.relative_noise() < 0.01, "{:?}", baked.stats);
}

#[test]
fn visibility_under_a_plate_misses_its_solid_angle() {
    // The floor point under the centre of a 0.4 m plate 1 m up: the plate covers
    // 4·atan(a² / (d·√(d² + 2a²))) with half-side a = 0.2, d = 1.
    let (a, d) = (0.2f64, 1.0f64);
    let plate = 4.0 * (a * a / (d * (d * d + 2.0 * a * a).sqrt())).atan();
    for (with_plate, want) in [(false, 2.0 * PI), (true, 2.0 * PI - plate)] {
        let (scene, camera) = floor_scene(with_plate);
        let baked = bake(
            &scene,
            &camera,
            &options(Transfer::Visibility, 4096),
            &Silent,
        )
        .unwrap();
        // ∫ V dω = √(4π) c_0.
        let open = (4.0 * PI).sqrt() * coefficients(&baked.image, 4, 4, 0)[0];
        assert!(
            (open - want).abs() < 0.01,
            "plate {with_plate}: open solid angle {open:.4}, expected {want:.4}"
        );
    }
}

/// Per pixel, `∫ f dω` from the baked maps (`√(4π) c_0`) and from the renderer (the
/// capture images under `n` Fibonacci lights, each weighted `4π/n`).
fn white_sky(scene: &Scene, camera: &Camera, bake_options: &BakeOptions) -> (Vec<f64>, Vec<f64>) {
    let baked = bake(scene, camera, bake_options, &Silent).unwrap();
    let n = 20000;
    let renderer = Renderer::new(
        scene,
        camera,
        &RenderOptions {
            supersample: 1,
            indirect_samples: bake_options.indirect,
        },
        &Silent,
    )
    .unwrap();
    let pixels = camera.width() * camera.height();
    let mut rendered = vec![0.0f64; pixels];
    for direction in sphere::fibonacci(n) {
        let image = renderer.render_directional(direction).unwrap().image;
        for (p, sum) in rendered.iter_mut().enumerate() {
            let rgb = &image.data[3 * p..3 * p + 3];
            *sum += 4.0 * PI / n as f64 * rgb.iter().map(|&v| v as f64).sum::<f64>() / 3.0;
        }
    }
    let plane = |c: usize| baked.image.maps.plane(0, c).to_vec();
    let (r, g, b) = (plane(0), plane(1), plane(2));
    let baked_sky = (0..pixels)
        .map(|p| (4.0 * PI).sqrt() * (r[p] + g[p] + b[p]) as f64 / 3.0)
        .collect();
    (baked_sky, rendered)
}

/// PSNR of `a` against `b` with `b`'s maximum as the peak.
fn psnr(a: &[f64], b: &[f64]) -> f64 {
    let peak = b.iter().cloned().fold(0.0, f64::max);
    let mse = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / a.len() as f64;
    10.0 * (peak * peak / mse).log10()
}

fn box_scene() -> (Scene, Camera) {
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
    (scene, camera)
}

#[test]
fn baked_maps_under_a_uniform_sky_equal_the_renderers_light_sum() {
    // The box is glossy and casts a shadow: the glossy lobe's share of the directions
    // and the units must both be right for the two routes to agree.
    let (scene, camera) = box_scene();
    let (baked, rendered) = white_sky(&scene, &camera, &options(Transfer::Diffuse, 1024));
    let score = psnr(&baked, &rendered);
    assert!(
        score > 50.0,
        "white sky: baked against rendered {score:.2} dB"
    );
    // Dropping the lobes loses its light: the Lambertian bake reads darker.
    let lambert = BakeOptions {
        lambert: true,
        ..options(Transfer::Diffuse, 1024)
    };
    let (matte, _) = white_sky(&scene, &camera, &lambert);
    let brighter = baked
        .iter()
        .zip(&matte)
        .filter(|(g, m)| **g > 1.05 * **m)
        .count();
    assert!(brighter >= 5, "{brighter} pixels brighter with the lobes");
    let matte_score = psnr(&matte, &rendered);
    eprintln!("white sky against the renderer: {score:.2} dB, Lambertian only {matte_score:.2} dB");
    assert!(
        matte_score + 5.0 < score,
        "Lambertian {matte_score:.2} dB against glossy {score:.2} dB"
    );
}

#[test]
fn bleeding_adds_the_renderers_one_bounce_light() {
    let (scene, camera) = box_scene();
    let bleeding = BakeOptions {
        indirect: 4,
        bounce_samples: 256,
        ..options(Transfer::Bleeding, 512)
    };
    let (baked, rendered) = white_sky(&scene, &camera, &bleeding);
    let score = psnr(&baked, &rendered);
    assert!(score > 48.0, "bleeding white sky: {score:.2} dB");
    // Without the bounce the same truth is clearly further away.
    let (direct, _) = white_sky(&scene, &camera, &options(Transfer::Diffuse, 512));
    let direct_score = psnr(&direct, &rendered);
    eprintln!(
        "one bounce against the renderer: bleeding {score:.2} dB, diffuse {direct_score:.2} dB"
    );
    assert!(
        direct_score + 10.0 < score,
        "diffuse {direct_score:.2} dB against bleeding {score:.2} dB"
    );
}

#[test]
fn bad_options_are_refused() {
    let (scene, camera) = floor_scene(false);
    for bad in [
        // A basis without bands: no Funk–Hecke form, no windows.
        BakeOptions {
            basis: relit::basis::BasisSpec::named("sg:16").unwrap(),
            ..BakeOptions::default()
        },
        BakeOptions {
            samples: 0,
            ..BakeOptions::default()
        },
        BakeOptions {
            transfer: Transfer::Bleeding,
            indirect: 0,
            ..BakeOptions::default()
        },
        BakeOptions {
            indirect: 4,
            ..BakeOptions::default()
        },
    ] {
        assert!(bake(&scene, &camera, &bad, &Silent).is_err(), "{bad:?}");
    }
}
