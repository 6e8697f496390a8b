//! The GPU engine against the CPU engine (`relit::engine::relight`) on small synthetic
//! maps. Without a GPU adapter every test prints why it skipped and passes.

use relit::basis::BasisSpec;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::engine::{relight, RelightOptions};
use relit::image::ImageRgb;
use relit::light::{
    AreaLight, AreaShape, Attenuation, Light, LightRig, PointLight, ProjectorLight, SpotLight,
};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::sphere::Vec3;
use relit_gpu::{GpuError, GpuOptions, GpuRelighter, Roi, Storage};
use std::path::{Path, PathBuf};

/// Largest |GPU − CPU| allowed, relative to the largest |CPU| value of the frame. The
/// GPU sums k·3 products in f32 (the CPU in f32 for uniform lights, f64 for positional
/// ones) and computes light vectors from f32 surface points: a few ulps of the terms,
/// amplified by at most ~l² in the derivatives of band-l harmonics. Measured on
/// lavapipe: at most 7.6e-7 of the peak (3.4e-5 on a peak of 45, a point light close
/// to the surface); the bound leaves room for GPUs whose `pow` (sRGB decode) is coarser.
const MAX_RELATIVE_TO_PEAK: f64 = 1e-5;

trait RelightIn {
    fn relight_in(&self, rig: &LightRig, exposure: f64, dir: &Path) -> ImageRgb;
}

impl RelightIn for GpuRelighter {
    fn relight_in(&self, rig: &LightRig, exposure: f64, dir: &Path) -> ImageRgb {
        let lighting = self.lighting_in(rig, exposure, dir).unwrap();
        self.render(&lighting, None).unwrap()
    }
}

fn gpu_or_skip(image: &RelightableImage, options: GpuOptions) -> Option<GpuRelighter> {
    match GpuRelighter::with_options(image, options) {
        Ok(g) => Some(g),
        Err(GpuError::NoAdapter(why)) => {
            eprintln!("skipping GPU test: {why}");
            None
        }
        Err(e) => panic!("GPU engine failed: {e}"),
    }
}

/// Deterministic pseudo-random numbers in [-0.5, 0.5).
fn noise(i: usize) -> f32 {
    let mut x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5DEE_CE66;
    x ^= x >> 29;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 32;
    (x % 10_000) as f32 / 10_000.0 - 0.5
}

/// `w×h` maps of `bands²` coefficients: a bright constant term plus noise, a pinhole
/// camera standing off the origin, depths between 1.5 and 3.
fn image(w: usize, h: usize, bands: usize, space: MapSpace) -> RelightableImage {
    let k = bands * bands;
    let mut maps = CoefficientMaps::zeros(w, h, k);
    let n = w * h;
    for (j, v) in maps.data.iter_mut().enumerate() {
        *v = if j < 3 * n { 0.8 } else { 0.25 * noise(j) };
    }
    let projection = Projection::Planar {
        fov_y_deg: Some(60.0),
    };
    let mut meta = Metadata::new(
        BasisSpec::named(&format!("sh:{}", bands * bands)).unwrap(),
        space,
        projection.clone(),
    );
    meta.camera = Some(CameraSpec {
        projection,
        width: w,
        height: h,
        pose: Pose::look_at(
            Vec3::new(0.2, 0.5, 1.0),
            Vec3::new(0.0, 0.0, -2.0),
            Vec3::new(0.0, 1.0, 0.0),
        )
        .unwrap(),
        orthographic_height: None,
    });
    let depth = (0..n)
        .map(|p| {
            if p % 97 == 5 {
                0.0
            } else {
                2.25 + 1.5 * noise(p + 7)
            }
        })
        .collect();
    RelightableImage {
        meta,
        maps,
        depth: Some(depth),
    }
}

fn rig() -> LightRig {
    LightRig::new(vec![
        Light::directional([-0.4, 0.7, 0.6], [1.0, 0.8, 0.6]),
        Light::directional([0.5, -0.2, 0.8], [0.1, 0.3, 0.9]),
        Light::point([0.3, 1.0, -1.0], [1.0, 1.0, 0.8]),
        Light::Point(PointLight {
            position: Vec3::new(-1.0, -0.5, 0.5),
            color: [0.4, 0.6, 1.0],
            intensity: 2.0,
            attenuation: Attenuation::InverseDistance(0.7),
        }),
        Light::Spot(SpotLight {
            position: Vec3::new(0.0, 2.0, -1.0),
            direction: Vec3::new(0.0, -1.0, -0.8),
            cone_deg: 35.0,
            softness_deg: 10.0,
            color: [1.0, 0.5, 0.2],
            intensity: 3.0,
            attenuation: Attenuation::None,
        }),
    ])
}

/// max |a − b| and max |b|.
fn difference(a: &ImageRgb, b: &ImageRgb) -> (f64, f64) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.data
        .iter()
        .zip(&b.data)
        .fold((0.0, 0.0), |(d, m), (x, y)| {
            (
                f64::max(d, (x - y).abs() as f64),
                f64::max(m, y.abs() as f64),
            )
        })
}

fn assert_close(label: &str, gpu: &ImageRgb, cpu: &ImageRgb) {
    let (diff, peak) = difference(gpu, cpu);
    eprintln!("{label}: max |GPU - CPU| = {diff:.3e} (peak |CPU| {peak:.3})");
    assert!(
        diff <= MAX_RELATIVE_TO_PEAK * peak,
        "{label}: max |GPU - CPU| = {diff:e}, peak {peak}"
    );
}

fn cpu(image: &RelightableImage, rig: &LightRig, exposure: f64) -> ImageRgb {
    cpu_in(image, rig, exposure, Path::new(""))
}

fn cpu_in(image: &RelightableImage, rig: &LightRig, exposure: f64, dir: &Path) -> ImageRgb {
    let options = RelightOptions {
        exposure,
        resource_dir: dir.to_path_buf(),
    };
    relight(image, rig, &options).unwrap()
}

/// A folder of its own for test `name`, holding `slide.png`: a 7×5 slide of saturated,
/// varying colours (8-bit sRGB, so loading it decodes sRGB as the CPU engine does).
fn slide_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("relit-gpu-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (w, h) = (7, 5);
    let mut slide = ImageRgb::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let i = 3 * (y * w + x);
            slide.data[i] = x as f32 / (w - 1) as f32;
            slide.data[i + 1] = y as f32 / (h - 1) as f32;
            slide.data[i + 2] = 0.5 + 0.5 * noise(i) * 1.8;
        }
    }
    relit::image::save(&dir.join("slide.png"), &slide, 0.0).unwrap();
    let (w, h) = (40, 30);
    let mut big = ImageRgb::new(w, h);
    for (i, v) in big.data.iter_mut().enumerate() {
        *v = 0.5 + noise(i + 1000);
    }
    relit::image::save(&dir.join("big.png"), &big, 0.0).unwrap();
    dir
}

/// A projector aimed across the surface (part of the image lies outside its frustum)
/// and the same with a `1/d` falloff, seen from elsewhere.
fn projectors() -> Vec<Light> {
    vec![
        Light::Projector(ProjectorLight {
            position: Vec3::new(0.6, 1.0, 0.5),
            direction: Vec3::new(-0.6, -1.0, -2.5),
            up: Vec3::new(0.0, 1.0, 0.0),
            fov_deg: 35.0,
            slide: "slide.png".into(),
            color: [1.0, 0.9, 0.8],
            intensity: 4.0,
            attenuation: Attenuation::InverseSquare,
        }),
        Light::Projector(ProjectorLight {
            position: Vec3::new(-0.8, 0.3, 0.2),
            direction: Vec3::new(0.7, -0.3, -2.0),
            up: Vec3::new(0.2, 1.0, 0.0),
            fov_deg: 50.0,
            slide: "slide.png".into(),
            color: [0.5, 1.0, 0.7],
            intensity: 1.5,
            attenuation: Attenuation::InverseDistance(0.8),
        }),
    ]
}

/// A one-sided rectangle above the surface facing down, and a two-sided disk standing
/// among the surface points (lighting those on either side).
fn areas() -> Vec<Light> {
    vec![
        Light::Area(AreaLight {
            shape: AreaShape::Rect {
                center: Vec3::new(0.1, 1.5, -1.2),
                u: Vec3::new(0.5, 0.0, 0.1),
                v: Vec3::new(0.0, 0.1, 0.4),
            },
            color: [1.0, 0.8, 0.6],
            intensity: 3.0,
            two_sided: false,
            samples: 16,
        }),
        Light::Area(AreaLight {
            shape: AreaShape::Disk {
                center: Vec3::new(-0.3, 0.1, -2.0),
                normal: Vec3::new(1.0, 0.3, 0.2),
                radius: 0.35,
            },
            color: [0.4, 0.7, 1.0],
            intensity: 2.0,
            two_sided: true,
            samples: 10,
        }),
    ]
}

#[test]
fn projectors_match_the_cpu_engine() {
    let dir = slide_dir("projectors");
    for (bands, space) in [
        (1, MapSpace::Linear),
        (3, MapSpace::Linear),
        (5, MapSpace::Linear),
        (4, MapSpace::Srgb),
    ] {
        let img = image(37, 23, bands, space);
        let Some(gpu) = gpu_or_skip(&img, GpuOptions::default()) else {
            return;
        };
        let lights = projectors();
        for (i, light) in lights.iter().enumerate() {
            let one = LightRig::new(vec![light.clone()]);
            let want = cpu_in(&img, &one, 0.5, &dir);
            assert!(want.data.contains(&0.0), "some pixels unlit");
            assert!(want.data.iter().any(|v| *v > 0.0), "some pixels lit");
            let got = gpu.relight_in(&one, 0.5, &dir);
            assert_close(
                &format!("{bands} bands {space:?}, projector {i}"),
                &got,
                &want,
            );
        }
        let mut all = rig().lights;
        all.extend(lights);
        let all = LightRig::new(all);
        assert_close(
            &format!("{bands} bands {space:?}, projectors with the rig"),
            &gpu.relight_in(&all, -1.0, &dir),
            &cpu_in(&img, &all, -1.0, &dir),
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Frames whose slides change upload them again (into a larger buffer when needed).
#[test]
fn changing_slides_are_uploaded_again() {
    let dir = slide_dir("slides");
    let img = image(37, 23, 3, MapSpace::Linear);
    let Some(gpu) = gpu_or_skip(&img, GpuOptions::default()) else {
        return;
    };
    let small = LightRig::new(projectors());
    let mut big = projectors();
    if let Light::Projector(p) = &mut big[1] {
        p.slide = "big.png".into();
    }
    let big = LightRig::new(big);
    for (label, rig) in [("small", &small), ("big", &big), ("small again", &small)] {
        assert_close(
            &format!("slides: {label}"),
            &gpu.relight_in(rig, 0.0, &dir),
            &cpu_in(&img, rig, 0.0, &dir),
        );
    }
    assert!(
        max_abs(
            &gpu.relight_in(&small, 0.0, &dir),
            &gpu.relight_in(&big, 0.0, &dir)
        ) > 0.01
    );
    std::fs::remove_dir_all(&dir).ok();
}

fn max_abs(a: &ImageRgb, b: &ImageRgb) -> f64 {
    difference(a, b).0
}

#[test]
fn area_lights_match_the_cpu_engine() {
    for (bands, space) in [
        (1, MapSpace::Linear),
        (3, MapSpace::Linear),
        (5, MapSpace::Linear),
        (8, MapSpace::Linear),
        (4, MapSpace::Srgb),
    ] {
        let img = image(37, 23, bands, space);
        let Some(gpu) = gpu_or_skip(&img, GpuOptions::default()) else {
            return;
        };
        let lights = areas();
        for (i, light) in lights.iter().enumerate() {
            let one = LightRig::new(vec![light.clone()]);
            let want = cpu(&img, &one, 0.5);
            assert!(want.data.iter().any(|v| *v > 0.0), "some pixels lit");
            let label = format!(
                "{bands} bands {space:?}, area {i} ({})",
                ["rect, one-sided", "disk, two-sided"][i]
            );
            assert_close(&label, &gpu.relight(&one, 0.5).unwrap(), &want);
        }
        let mut all = rig().lights;
        all.extend(lights);
        let all = LightRig::new(all);
        assert_close(
            &format!("{bands} bands {space:?}, area lights with the rig"),
            &gpu.relight(&all, -1.0).unwrap(),
            &cpu(&img, &all, -1.0),
        );
    }
}

/// The strata shift is seeded by the full image's pixel index: a region (and slabs)
/// gives the full frame's pixels.
#[test]
fn area_light_regions_use_the_image_pixel_index() {
    let img = image(45, 31, 4, MapSpace::Linear);
    let Some(whole) = gpu_or_skip(&img, GpuOptions::default()) else {
        return;
    };
    let sliced = GpuRelighter::with_options(
        &img,
        GpuOptions {
            storage: Storage::F32,
            max_slab_bytes: Some(4 * 48 * 45 * 4),
        },
    )
    .unwrap();
    let rig = LightRig::new(areas());
    let want = cpu(&img, &rig, 0.0);
    let full = whole.relight(&rig, 0.0).unwrap();
    assert_close("area lights, full frame", &full, &want);
    let roi = Roi {
        x: 7,
        y: 5,
        width: 23,
        height: 19,
    };
    let mut crop = ImageRgb::new(roi.width, roi.height);
    for y in 0..roi.height {
        for x in 0..roi.width {
            let v = want.get(roi.x + x, roi.y + y);
            let i = 3 * (y * roi.width + x);
            crop.data[i..i + 3].copy_from_slice(&v);
        }
    }
    for (name, engine) in [("one slab", &whole), ("slabs", &sliced)] {
        let part = engine.relight_roi(&rig, 0.0, roi).unwrap();
        assert_close(&format!("area lights, region, {name}"), &part, &crop);
        for y in 0..roi.height {
            for x in 0..roi.width {
                assert_eq!(part.get(x, y), full.get(roi.x + x, roi.y + y), "{name}");
            }
        }
    }
}

#[test]
fn every_light_type_matches_the_cpu_engine_for_1_to_8_bands() {
    for bands in [1, 3, 4, 5, 8] {
        let img = image(37, 23, bands, MapSpace::Linear);
        let Some(gpu) = gpu_or_skip(&img, GpuOptions::default()) else {
            return;
        };
        let rig = rig();
        for (i, light) in rig.lights.iter().enumerate() {
            let one = LightRig::new(vec![light.clone()]);
            let got = gpu.relight(&one, 0.5).unwrap();
            assert_close(
                &format!("{bands} bands, light {i} ({})", light.kind()),
                &got,
                &cpu(&img, &one, 0.5),
            );
        }
        assert_close(
            &format!("{bands} bands, whole rig"),
            &gpu.relight(&rig, -1.0).unwrap(),
            &cpu(&img, &rig, -1.0),
        );
    }
}

#[test]
fn display_referred_maps_decode_each_light() {
    let img = image(29, 17, 4, MapSpace::Srgb);
    let Some(gpu) = gpu_or_skip(&img, GpuOptions::default()) else {
        return;
    };
    let rig = rig();
    assert_close(
        "sRGB maps, whole rig",
        &gpu.relight(&rig, 0.0).unwrap(),
        &cpu(&img, &rig, 0.0),
    );
}

/// f16 and 8-bit storage equal the CPU engine on the maps as that storage rounds them.
#[test]
fn compact_storage_matches_the_cpu_on_the_rounded_maps() {
    let img = image(40, 21, 5, MapSpace::Linear);
    for storage in [Storage::F16, Storage::Unorm8] {
        let options = GpuOptions {
            storage,
            ..Default::default()
        };
        let Some(gpu) = gpu_or_skip(&img, options) else {
            return;
        };
        let mut rounded = img.clone();
        rounded.maps = storage.round_trip(&img.maps);
        let rig = rig();
        assert_close(
            &format!("{} storage", storage.name()),
            &gpu.relight(&rig, 0.0).unwrap(),
            &cpu(&rounded, &rig, 0.0),
        );
    }
}

/// Regions and slabs change which pixels a dispatch covers, never their values.
#[test]
fn regions_and_slabs_give_the_same_pixels() {
    let img = image(45, 31, 4, MapSpace::Linear);
    let Some(whole) = gpu_or_skip(&img, GpuOptions::default()) else {
        return;
    };
    let sliced = GpuRelighter::with_options(
        &img,
        GpuOptions {
            storage: Storage::F32,
            max_slab_bytes: Some(4 * 48 * 45 * 4),
        },
    )
    .unwrap();
    assert!(sliced.slab_count() > 5, "{} slabs", sliced.slab_count());
    let rig = rig();
    let full = whole.relight(&rig, 0.0).unwrap();
    assert_eq!(sliced.relight(&rig, 0.0).unwrap(), full);
    for roi in [
        Roi {
            x: 3,
            y: 2,
            width: 17,
            height: 11,
        },
        Roi {
            x: 0,
            y: 29,
            width: 45,
            height: 2,
        },
        Roi {
            x: 44,
            y: 0,
            width: 1,
            height: 31,
        },
    ] {
        for engine in [&whole, &sliced] {
            let part = engine.relight_roi(&rig, 0.0, roi).unwrap();
            assert_eq!((part.width, part.height), (roi.width, roi.height));
            for y in 0..roi.height {
                for x in 0..roi.width {
                    assert_eq!(part.get(x, y), full.get(roi.x + x, roi.y + y), "{roi:?}");
                }
            }
        }
    }
}

#[test]
fn bad_requests_are_clear_errors() {
    let mut img = image(8, 6, 3, MapSpace::Linear);
    let Some(gpu) = gpu_or_skip(&img, GpuOptions::default()) else {
        return;
    };
    let rig = rig();
    let outside = Roi {
        x: 4,
        y: 0,
        width: 5,
        height: 2,
    };
    assert!(gpu.relight_roi(&rig, 0.0, outside).is_err());
    assert!(gpu.relight(&rig, f64::NAN).is_err());
    let dir = Light::parse_spec("dir:0,0,1").unwrap();
    let mut env_rig: LightRig =
        serde_json::from_str(r#"{ "lights": [ { "type": "environment", "map": "sky.exr" } ] }"#)
            .unwrap();
    env_rig.lights.push(dir);
    let err = gpu.relight(&env_rig, 0.0).unwrap_err();
    assert!(matches!(err, GpuError::Unsupported(_)), "{err}");
    let missing = LightRig::new(projectors());
    let err = gpu.relight(&missing, 0.0).unwrap_err();
    assert!(err.to_string().contains("slide.png"), "{err}");
    img.depth = None;
    let flat = GpuRelighter::new(&img).unwrap();
    let err = flat.relight(&rig, 0.0).unwrap_err();
    assert!(err.to_string().contains("depth"), "{err}");
    let dir_only = LightRig::new(vec![rig.lights[0].clone()]);
    assert_close(
        "no depth, directional",
        &flat.relight(&dir_only, 0.0).unwrap(),
        &cpu(&img, &dir_only, 0.0),
    );
}
