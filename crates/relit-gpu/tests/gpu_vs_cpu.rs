//! The GPU engine against the CPU: for every basis (each registered family, those built
//! from a capture's samples from a synthetic one, and a non-SH basis of the test's own
//! that no family registers) and every light type, on small synthetic maps. Without a GPU adapter every test prints
//! why it skipped and passes.
//!
//! Three references:
//!
//! * the CPU engine (`relit::engine::relight`), for registered families;
//! * a per-pixel evaluation here, `P = O + d·V` from camera and depth, each light's own
//!   `PreparedLight::illuminate` at `P`, weighted by the basis' weights at each light
//!   vector, in f64: with the weights from the same `WeightTable` the GPU reads (in half
//!   floats; [`Weights::Table`]: what the GPU computes, to f32 rounding), and from the
//!   basis itself ([`Weights::Exact`]: what the table costs);
//! * for uniform lights (directional, environment), whose weights the CPU computes per
//!   frame, the CPU engine or the exact evaluation alone.

use relit::basis::{Basis, BasisChoice, BasisSpec, Samples, WeightTable, FAMILIES};
use relit::camera::{CameraSpec, Pose, Projection};
use relit::engine::{relight, RelightOptions, Relighter};
use relit::image::ImageRgb;
use relit::light::{
    AreaLight, AreaShape, Attenuation, EnvironmentMapLight, Light, LightRig, PointLight,
    PreparedLight, ProjectorLight, SpotLight,
};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::sphere::{fibonacci, Vec3};
use relit::storage::Precision;
use relit_gpu::{GpuError, GpuOptions, GpuRelighter, Lighting, Roi};
use std::path::{Path, PathBuf};

/// Largest |GPU − reference| allowed, relative to the largest |reference| value of the
/// frame, where GPU and reference use the same weights (uniform lights against the CPU
/// engine; lights with a position against the evaluation with the GPU's table). The GPU
/// sums k·3 products in f32 and computes light vectors from f32 surface points: a few
/// ulps of the terms. Measured on lavapipe: at most 7.6e-7 of the peak (3.4e-5 on a
/// peak of 45, a point light close to the surface); the bound leaves room for GPUs
/// whose `pow` (sRGB decode) is coarser.
const MAX_RELATIVE_TO_PEAK: f64 = 1e-5;

/// GPU against the CPU engine where both read the same weight table (lights with a
/// position on bases other than SH): their light vectors differ in the last f32 bits
/// (surface points, area samples), which a steep basis (HSH near the horizon) and the
/// sRGB decode of display-referred maps amplify: measured on lavapipe at most 1.6e-5
/// of the peak (hsh:25, display-referred, a two-sided area light among the surface
/// points), 1e-6 elsewhere; the CPU engine's own reference test allows 1e-4.
const SAME_TABLE_RELATIVE_TO_PEAK: f64 = 1e-4;

/// Against the basis itself, lights with a position may be off by what the table costs:
/// per pixel, Σ over light vectors of |rgb| · Σ_i |c_i| · ε, with ε the table's largest
/// weight error. ε is measured on 4096 Fibonacci directions; the factor 2 covers light
/// vectors between them, and sRGB decoding (display-referred maps) multiplies an error
/// by at most its slope at 1, 2.3.
const TABLE_ERROR_MARGIN: f64 = 2.0;
const SRGB_MAX_SLOPE: f64 = 2.3;

// ---- bases -----------------------------------------------------------------------------

/// A non-SH basis no family registers: `k` smooth lobes `exp(s (μ_j·L − 1))` around
/// Fibonacci directions `μ_j`, of sharpness `s`. Positive, overlapping, not band-limited:
/// unlike SH in every way that could hide a lookup that only works for SH.
#[derive(Debug)]
struct Lobes {
    centres: Vec<Vec3>,
    sharpness: f64,
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
            *o = (self.sharpness * (m.dot(dir) - 1.0)).exp();
        }
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

fn lobes(k: usize) -> Box<dyn Basis> {
    Box::new(Lobes {
        centres: fibonacci(k),
        sharpness: 6.0,
    })
}

/// A basis to test with; `registered` ones (every family's) are compared with the CPU
/// engine too, which relights every light on every basis.
struct Case {
    basis: Box<dyn Basis>,
    registered: bool,
}

impl Case {
    /// The basis again (for the GPU engine, which owns its basis): rebuilt from its
    /// spec where a family knows it, else the test's own lobes.
    fn rebuild(&self) -> Box<dyn Basis> {
        match relit::basis::family(self.basis.family()) {
            Ok(_) => self.basis.spec().build().unwrap(),
            Err(_) => lobes(self.basis.len()),
        }
    }
}

/// Every registered family that needs no samples, at its smallest size above 1, the
/// sizes nearest 16 and 25 and its largest up to 64 (so families merged later are
/// covered), and the test's own lobes.
fn bases() -> Vec<Case> {
    let mut out = Vec::new();
    for family in FAMILIES.iter().filter(|f| !f.needs_samples()) {
        let sizes = family.sizes(64);
        let nearest = |n: usize| sizes.iter().copied().min_by_key(|&k| k.abs_diff(n));
        let mut picked: Vec<usize> = Vec::new();
        for k in [
            sizes.iter().copied().find(|&k| k > 1),
            nearest(16),
            nearest(25),
            sizes.last().copied(),
        ]
        .into_iter()
        .flatten()
        {
            if !picked.contains(&k) {
                picked.push(k);
            }
        }
        for k in picked {
            let spec = BasisSpec::named(&format!("{}:{k}", family.name())).unwrap();
            out.push(Case {
                basis: spec.build().unwrap(),
                registered: true,
            });
        }
    }
    // Families built from a capture's samples, from a synthetic one, at two sizes: the
    // CPU engine rebuilds them from their spec like any other family.
    let dirs = relit::sphere::hemisphere_fibonacci(48);
    let values = capture_samples(&dirs, 200);
    let samples = Samples {
        values: &values,
        n: dirs.len(),
    };
    for family in FAMILIES.iter().filter(|f| f.needs_samples()) {
        let sizes = family.sizes(16);
        for k in [sizes.first().copied(), sizes.last().copied()]
            .into_iter()
            .flatten()
        {
            let choice = BasisChoice::parse(&format!("{}:{k}", family.name())).unwrap();
            out.push(Case {
                basis: choice.build(&dirs, Some(samples)).unwrap(),
                registered: true,
            });
        }
    }
    // What compressed files relight with: K′ fixed combinations of a fitted basis.
    let inner = sh(16);
    let matrix: Vec<f64> = (0..6 * 16)
        .map(|i| ((i * 7919) % 13) as f64 / 13.0 - 0.4)
        .collect();
    out.push(Case {
        basis: Box::new(relit::basis::Projected::new(inner, matrix).unwrap()),
        registered: true,
    });
    for k in [5, 12] {
        out.push(Case {
            basis: lobes(k),
            registered: false,
        });
    }
    out
}

/// `series` pixel series at the captured directions `dirs`: mixtures of eight fixed
/// lobes with weights varying by series, as a capture's pixels would be.
fn capture_samples(dirs: &[Vec3], series: usize) -> Vec<f32> {
    let lobes = fibonacci(8);
    let mut out = Vec::with_capacity(series * dirs.len());
    for s in 0..series {
        for d in dirs {
            let v: f64 = lobes
                .iter()
                .enumerate()
                .map(|(i, l)| (1.2 + noise(s * 8 + i) as f64) * (4.0 * (d.dot(*l) - 1.0)).exp())
                .sum();
            out.push(v as f32);
        }
    }
    out
}

fn sh(k: usize) -> Box<dyn Basis> {
    BasisSpec::named(&format!("sh:{k}"))
        .unwrap()
        .build()
        .unwrap()
}

// ---- maps, lights --------------------------------------------------------------------

/// Deterministic pseudo-random numbers in [-0.5, 0.5).
fn noise(i: usize) -> f32 {
    let mut x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5DEE_CE66;
    x ^= x >> 29;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 32;
    (x % 10_000) as f32 / 10_000.0 - 0.5
}

/// `w×h` maps of `basis`: a bright first coefficient plus noise, a pinhole camera
/// standing off the origin, depths between 1.5 and 3.
fn image(w: usize, h: usize, basis: &dyn Basis, space: MapSpace) -> RelightableImage {
    let k = basis.len();
    let mut maps = CoefficientMaps::zeros(w, h, k);
    let n = w * h;
    for (j, v) in maps.data.iter_mut().enumerate() {
        *v = if j < 3 * n { 0.8 } else { 0.25 * noise(j) };
    }
    let projection = Projection::Planar {
        fov_y_deg: Some(60.0),
    };
    let mut meta = Metadata::new(basis.spec(), space, projection.clone());
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

/// A folder of its own for test `name`, holding `slide.png`: a 7×5 slide of saturated,
/// varying colours (8-bit sRGB, so loading it decodes sRGB as the CPU engine does), a
/// larger `big.png`, and `sky.exr`, a 32×16 environment with a bright spot.
fn resource_dir(name: &str) -> PathBuf {
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
    let (w, h) = (32, 16);
    let mut sky = ImageRgb::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let i = 3 * (y * w + x);
            let sun = (x as i32 - 20).abs() <= 1 && (y as i32 - 5).abs() <= 1;
            let rgb = if sun {
                [6.0, 5.0, 3.0]
            } else if y < h / 2 {
                [0.3, 0.45, 0.8]
            } else {
                [0.12, 0.1, 0.08]
            };
            sky.data[i..i + 3].copy_from_slice(&rgb);
        }
    }
    relit::image::save(&dir.join("sky.exr"), &sky, 0.0).unwrap();
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

/// Every light of one type at a time, then all together.
fn every_light() -> Vec<(String, LightRig)> {
    let mut all = rig().lights;
    all.extend(projectors());
    all.extend(areas());
    let mut out: Vec<(String, LightRig)> = all
        .iter()
        .enumerate()
        .map(|(i, l)| {
            (
                format!("light {i} ({})", l.kind()),
                LightRig::new(vec![l.clone()]),
            )
        })
        .collect();
    out.push(("every light".into(), LightRig::new(all)));
    out
}

// ---- references --------------------------------------------------------------------------

/// Where the per-pixel reference takes the weights of lights with a position (uniform
/// lights always take the basis', as both engines do).
#[derive(Clone, Copy)]
enum Weights<'a> {
    /// The basis itself, in f64.
    Exact,
    /// The table the GPU reads (`WeightTable::sample`).
    Table(&'a WeightTable),
}

/// A frame evaluated pixel by pixel, and per pixel and channel the bound on what the
/// table may cost there (see [`TABLE_ERROR_MARGIN`]) for a table of largest error `eps`.
struct Direct {
    image: ImageRgb,
    table_bound: Vec<f64>,
}

fn direct(
    img: &RelightableImage,
    basis: &dyn Basis,
    weights: Weights,
    eps: f64,
    rig: &LightRig,
    exposure: f64,
    dir: &Path,
) -> Direct {
    let (w, h, k) = (img.width(), img.height(), img.maps.k);
    let display = img.meta.color_space == MapSpace::Srgb;
    let camera = img.meta.camera.as_ref().unwrap().build().unwrap();
    let depth = img.depth.as_ref().unwrap();
    let scale = 2f64.powf(exposure);
    let lights: Vec<PreparedLight> = rig
        .lights
        .iter()
        .map(|l| match l {
            Light::Projector(p) => {
                let slide = relit::image::load_linear(&dir.join(&p.slide), None).unwrap();
                PreparedLight::Projector(
                    Box::new(p.with_slide(std::sync::Arc::new(slide))),
                    l.rgb(),
                )
            }
            _ => l.prepare(dir).unwrap(),
        })
        .collect();
    let mut out = Direct {
        image: ImageRgb::new(w, h),
        table_bound: vec![0.0; 3 * w * h],
    };
    let mut b = vec![0.0; k];
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            let d = depth[p];
            let point = (d > 0.0).then(|| camera.position(x, y, d as f64));
            let c: Vec<[f64; 3]> = (0..k)
                .map(|i| std::array::from_fn(|ch| img.maps.plane(i, ch)[p] as f64))
                .collect();
            let abs_sum: [f64; 3] = std::array::from_fn(|ch| c.iter().map(|c| c[ch].abs()).sum());
            let mut value = [0.0; 3];
            let mut bound = [0.0; 3];
            for light in &lights {
                let uniform = light.is_uniform();
                let mut emit = |l: Vec3, rgb: [f64; 3]| {
                    match weights {
                        Weights::Table(t) if !uniform => {
                            let mut w = vec![0f32; k];
                            t.sample(l, &mut w);
                            b.iter_mut().zip(w).for_each(|(b, w)| *b = w as f64);
                        }
                        _ => basis.eval(l, &mut b),
                    }
                    for ch in 0..3 {
                        if rgb[ch] == 0.0 {
                            continue;
                        }
                        let v: f64 = c.iter().zip(&b).map(|(c, b)| c[ch] * b).sum();
                        let (v, slope) = if display {
                            let v = v.clamp(0.0, 1.0) as f32;
                            (relit::color::srgb_to_linear(v) as f64, SRGB_MAX_SLOPE)
                        } else {
                            (v, 1.0)
                        };
                        value[ch] += rgb[ch] * v;
                        if !uniform {
                            bound[ch] += rgb[ch].abs() * slope * abs_sum[ch] * eps;
                        }
                    }
                };
                match (light, point) {
                    (PreparedLight::Directional { .. }, _) => {
                        light.illuminate(Vec3::new(0.0, 0.0, 0.0), p, &mut emit)
                    }
                    (_, Some(at)) => light.illuminate(at, p, &mut emit),
                    _ => {}
                }
            }
            for ch in 0..3 {
                out.image.data[3 * p + ch] = (value[ch] * scale) as f32;
                out.table_bound[3 * p + ch] = TABLE_ERROR_MARGIN * bound[ch] * scale;
            }
        }
    }
    out
}

/// `table` in half floats, as every back end holds it.
fn half_rounded(table: &WeightTable) -> WeightTable {
    let mut rounded = table.clone();
    for v in &mut rounded.values {
        *v = half::f16::from_f32(*v).to_f32();
    }
    rounded
}

/// The largest error of `table` against `basis` over 4096 Fibonacci directions.
fn table_error(basis: &dyn Basis, table: &WeightTable) -> f64 {
    let k = basis.len();
    let (mut b, mut t) = (vec![0.0; k], vec![0f32; k]);
    let mut most = 0f64;
    for d in fibonacci(4096) {
        basis.eval(d, &mut b);
        table.sample(d, &mut t);
        for (b, t) in b.iter().zip(&t) {
            most = most.max((b - *t as f64).abs());
        }
    }
    most
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

fn assert_close(label: &str, gpu: &ImageRgb, want: &ImageRgb) {
    let (diff, peak) = difference(gpu, want);
    eprintln!("{label}: max |GPU - reference| = {diff:.3e} (peak {peak:.3})");
    assert!(
        diff <= MAX_RELATIVE_TO_PEAK * peak,
        "{label}: max |GPU - reference| = {diff:e}, peak {peak}"
    );
}

/// Every pixel within its table bound (plus the f32 allowance of the frame's peak).
fn assert_within_table_error(label: &str, gpu: &ImageRgb, want: &Direct) {
    let (_, peak) = difference(gpu, &want.image);
    let mut worst: f64 = 0.0;
    let mut largest: f64 = 0.0;
    for ((g, r), bound) in gpu.data.iter().zip(&want.image.data).zip(&want.table_bound) {
        let err = (g - r).abs() as f64;
        largest = largest.max(err);
        let allowed = bound + MAX_RELATIVE_TO_PEAK * peak;
        worst = worst.max(err / allowed);
        assert!(
            err <= allowed,
            "{label}: |GPU - reference| = {err:e} > {allowed:e} (GPU {g}, reference {r})"
        );
    }
    eprintln!(
        "{label}: max |GPU - reference| = {largest:.3e} (peak {peak:.3}), at most {:.0} % of the table's bound",
        100.0 * worst
    );
}

fn cpu_in(img: &RelightableImage, rig: &LightRig, exposure: f64, dir: &Path) -> ImageRgb {
    let options = RelightOptions {
        exposure,
        resource_dir: dir.to_path_buf(),
    };
    relight(img, rig, &options).unwrap()
}

fn cpu(img: &RelightableImage, rig: &LightRig, exposure: f64) -> ImageRgb {
    cpu_in(img, rig, exposure, Path::new(""))
}

fn gpu_or_skip(
    img: &RelightableImage,
    basis: Box<dyn Basis>,
    options: GpuOptions,
) -> Option<GpuRelighter> {
    match GpuRelighter::with_basis(img, basis, options) {
        Ok(g) => Some(g),
        Err(GpuError::NoAdapter(why)) => {
            relit::skip::skipping(&format!("no GPU adapter: {why}"));
            None
        }
        Err(e) => panic!("GPU engine failed: {e}"),
    }
}

fn relight_in(gpu: &GpuRelighter, rig: &LightRig, exposure: f64, dir: &Path) -> ImageRgb {
    let lighting = gpu.lighting_in(rig, exposure, dir).unwrap();
    gpu.render(&lighting, None).unwrap()
}

/// The GPU's frame of `rig` against every reference that applies (module docs).
#[allow(clippy::too_many_arguments)]
fn check(
    label: &str,
    gpu: &GpuRelighter,
    img: &RelightableImage,
    basis: &dyn Basis,
    registered: bool,
    rig: &LightRig,
    exposure: f64,
    dir: &Path,
) {
    let got = relight_in(gpu, rig, exposure, dir);
    let (table, _) = WeightTable::for_basis(basis);
    let table = half_rounded(&table);
    let eps = table_error(basis, &table);
    let uniform = rig.lights.iter().all(Light::is_uniform);
    let exact = direct(img, basis, Weights::Exact, eps, rig, exposure, dir);
    if uniform {
        // The CPU computes a uniform light's weights from the basis: no table involved.
        assert_close(&format!("{label} vs basis"), &got, &exact.image);
    } else {
        let tabled = direct(img, basis, Weights::Table(&table), eps, rig, exposure, dir);
        assert_close(&format!("{label} vs its table"), &got, &tabled.image);
        assert_within_table_error(&format!("{label} vs basis"), &got, &exact);
    }
    if registered {
        let want = cpu_in(img, rig, exposure, dir);
        let cpu_reads_the_table =
            relit::engine::BasisEvaluator::new(basis).path() == "weight table";
        if uniform {
            assert_close(&format!("{label} vs CPU engine"), &got, &want);
        } else if cpu_reads_the_table {
            // The same half-float table: the engines differ only by their f32 light
            // vectors and sums.
            let (diff, peak) = difference(&got, &want);
            eprintln!("{label} vs CPU engine: max |GPU - CPU| = {diff:.3e} (peak {peak:.3})");
            assert!(
                diff <= SAME_TABLE_RELATIVE_TO_PEAK * peak,
                "{label} vs CPU engine: {diff:e}, peak {peak}"
            );
        } else {
            // The CPU evaluates the basis itself (SH's recurrence, a planar grid), the
            // GPU its table.
            let engine = Direct {
                image: want,
                table_bound: exact.table_bound,
            };
            assert_within_table_error(&format!("{label} vs CPU engine"), &got, &engine);
        }
    }
}

// ---- tests -------------------------------------------------------------------------------

#[test]
fn every_light_type_matches_the_references_for_every_basis() {
    let dir = resource_dir("every-basis");
    for case in bases() {
        let name = case.basis.name();
        for space in [MapSpace::Linear, MapSpace::Srgb] {
            let img = image(37, 23, case.basis.as_ref(), space);
            let Some(gpu) = gpu_or_skip(&img, case.rebuild(), GpuOptions::default()) else {
                return;
            };
            let accuracy = gpu.table_accuracy();
            eprintln!(
                "{name} {space:?}: table of {} cells a side, relative RMS error {:.1e}, max {:.1e}",
                accuracy.resolution, accuracy.relative_rms, accuracy.relative_max
            );
            for (label, rig) in every_light() {
                check(
                    &format!("{name} {space:?}, {label}"),
                    &gpu,
                    &img,
                    case.basis.as_ref(),
                    case.registered,
                    &rig,
                    0.5,
                    &dir,
                );
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Environment weights come from the library (`Relighter::environment_weights`), added
/// as a uniform light: the GPU frame equals the CPU engine's for every registered basis
/// (SH's exact projection, the quadrature for the others).
#[test]
fn environment_lights_match_the_cpu_engine() {
    let dir = resource_dir("environment");
    let env: EnvironmentMapLight = serde_json::from_str(
        r#"{ "map": "sky.exr", "yaw_deg": 40, "pitch_deg": -15, "roll_deg": 10, "intensity": 0.7 }"#,
    )
    .unwrap();
    let rig = LightRig::new(vec![Light::Environment(env.clone())]);
    for case in bases().into_iter().filter(|c| c.registered) {
        let name = case.basis.name();
        for space in [MapSpace::Linear, MapSpace::Srgb] {
            let img = image(37, 23, case.basis.as_ref(), space);
            let weights = Relighter::new(&img)
                .unwrap()
                .environment_weights(&env, &dir)
                .unwrap();
            let Some(gpu) = gpu_or_skip(&img, img.meta.basis.build().unwrap(), Default::default())
            else {
                return;
            };
            let mut lighting: Lighting = gpu.empty_lighting();
            let scale = 2f64.powf(0.5);
            // The weights on linear maps, the median-cut lights (a pass each) on
            // display-referred ones, as the CPU engine prepares the environment.
            let options = RelightOptions {
                resource_dir: dir.clone(),
                ..Default::default()
            };
            let prepared = Relighter::new(&img)
                .unwrap()
                .prepare(&Light::Environment(env.clone()), &options)
                .unwrap();
            assert_eq!(
                prepared.len(),
                match space {
                    MapSpace::Linear => 1,
                    MapSpace::Srgb => relit::engine::DISPLAY_ENVIRONMENT_LIGHTS,
                }
            );
            if space == MapSpace::Linear {
                assert!(matches!(&prepared[0], PreparedLight::Weights(w) if *w == weights));
            }
            for light in &prepared {
                gpu.add_prepared(&mut lighting, light, scale).unwrap();
            }
            assert_close(
                &format!("{name} {space:?}, environment"),
                &gpu.render(&lighting, None).unwrap(),
                &cpu_in(&img, &rig, 0.5, &dir),
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Frames whose slides change upload them again (into a larger buffer when needed).
#[test]
fn changing_slides_are_uploaded_again() {
    let dir = resource_dir("slides");
    let basis = sh(9);
    let img = image(37, 23, basis.as_ref(), MapSpace::Linear);
    let Some(gpu) = gpu_or_skip(&img, sh(9), GpuOptions::default()) else {
        return;
    };
    let small = LightRig::new(projectors());
    let mut big = projectors();
    if let Light::Projector(p) = &mut big[1] {
        p.slide = "big.png".into();
    }
    let big = LightRig::new(big);
    for (label, rig) in [("small", &small), ("big", &big), ("small again", &small)] {
        check(
            &format!("slides: {label}"),
            &gpu,
            &img,
            basis.as_ref(),
            true,
            rig,
            0.0,
            &dir,
        );
    }
    assert!(
        difference(
            &relight_in(&gpu, &small, 0.0, &dir),
            &relight_in(&gpu, &big, 0.0, &dir)
        )
        .0 > 0.01
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The strata shift is seeded by the full image's pixel index: a region (and slabs)
/// gives the full frame's pixels.
#[test]
fn area_light_regions_use_the_image_pixel_index() {
    let img = image(45, 31, sh(16).as_ref(), MapSpace::Linear);
    let Some(whole) = gpu_or_skip(&img, sh(16), GpuOptions::default()) else {
        return;
    };
    let sliced = GpuRelighter::with_options(
        &img,
        GpuOptions {
            precision: Precision::F32,
            max_slab_bytes: Some(4 * 48 * 45 * 4),
        },
    )
    .unwrap();
    let rig = LightRig::new(areas());
    check(
        "area lights, full frame",
        &whole,
        &img,
        sh(16).as_ref(),
        true,
        &rig,
        0.0,
        Path::new(""),
    );
    let full = whole.relight(&rig, 0.0).unwrap();
    let roi = Roi {
        x: 7,
        y: 5,
        width: 23,
        height: 19,
    };
    for (name, engine) in [("one slab", &whole), ("slabs", &sliced)] {
        let part = engine.relight_roi(&rig, 0.0, roi).unwrap();
        for y in 0..roi.height {
            for x in 0..roi.width {
                assert_eq!(part.get(x, y), full.get(roi.x + x, roi.y + y), "{name}");
            }
        }
    }
}

/// f16 storage equals the GPU's f32 frame on the maps as f16 rounds them, and 8-bit
/// storage the CPU engine's own 8-bit planes: both engines read
/// `value = offset + scale · q` with the same codes, scales and offsets.
#[test]
fn compact_storage_matches_the_cpu_on_the_same_stored_numbers() {
    let basis = sh(25);
    let img = image(40, 21, basis.as_ref(), MapSpace::Linear);
    let rig = rig();
    let uniform = LightRig::new(rig.lights[..2].to_vec());
    for storage in [Precision::F16, Precision::U8] {
        let options = GpuOptions {
            precision: storage,
            ..Default::default()
        };
        let Some(gpu) = gpu_or_skip(&img, sh(25), options) else {
            return;
        };
        let mut rounded = img.clone();
        rounded.maps = relit_gpu::stored_maps(&img.maps, storage);
        check(
            &format!("{} storage", storage.name()),
            &gpu,
            &rounded,
            basis.as_ref(),
            true,
            &rig,
            0.0,
            Path::new(""),
        );
        let cpu_storage = Precision::parse(storage.name()).unwrap();
        let engine = Relighter::with_precision(&img, cpu_storage).unwrap();
        assert_close(
            &format!(
                "{} storage, uniform lights vs the CPU engine's {} planes",
                storage.name(),
                cpu_storage.name()
            ),
            &gpu.relight(&uniform, 0.0).unwrap(),
            &engine
                .relight(&uniform, &RelightOptions::default())
                .unwrap(),
        );
    }
}

/// Regions and slabs change which pixels a dispatch covers, never their values.
#[test]
fn regions_and_slabs_give_the_same_pixels() {
    let img = image(45, 31, sh(16).as_ref(), MapSpace::Linear);
    let Some(whole) = gpu_or_skip(&img, sh(16), GpuOptions::default()) else {
        return;
    };
    let sliced = GpuRelighter::with_options(
        &img,
        GpuOptions {
            precision: Precision::F32,
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
    let mut img = image(8, 6, sh(9).as_ref(), MapSpace::Linear);
    let Some(gpu) = gpu_or_skip(&img, sh(9), GpuOptions::default()) else {
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
    // Maps whose coefficient count is not the basis'.
    let err = GpuRelighter::with_basis(&img, sh(16), GpuOptions::default())
        .err()
        .expect("a basis of another size is refused");
    assert!(err.to_string().contains("16"), "{err}");
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

#[test]
fn the_read_probe_measures_a_rate_and_refuses_nothing_to_read() {
    let img = image(8, 6, sh(4).as_ref(), MapSpace::Linear);
    let Some(gpu) = gpu_or_skip(&img, sh(4), GpuOptions::default()) else {
        return;
    };
    // An odd size: the probe reads whole vec4 values, rounding down.
    let rate = gpu.read_rate((4 << 20) + 7, 2).unwrap();
    assert!(rate.is_finite() && rate > 1e6, "{rate} bytes/s");
    assert!(gpu.read_rate(15, 1).is_err());
    assert!(gpu.read_rate(1 << 20, 0).is_err());
    // The engine's own planes, in several slabs.
    let img = image(64, 48, sh(9).as_ref(), MapSpace::Linear);
    let options = GpuOptions {
        max_slab_bytes: Some(64 * 9 * 3 * 4 * 10),
        ..Default::default()
    };
    let Some(gpu) = gpu_or_skip(&img, sh(9), options) else {
        return;
    };
    assert!(gpu.slab_count() > 1);
    let rate = gpu.resident_read_rate(3).unwrap();
    assert!(rate.is_finite() && rate > 1e6, "{rate} bytes/s");
    assert!(gpu.resident_read_rate(0).is_err());
}

/// One process opens many engines in turn (a viewer serving many files, these tests):
/// each must find the adapter as the first did.
#[test]
fn many_engines_in_one_process_each_find_the_adapter() {
    let img = image(4, 3, sh(4).as_ref(), MapSpace::Linear);
    for i in 0..48 {
        let Some(gpu) = gpu_or_skip(&img, sh(4), GpuOptions::default()) else {
            assert_eq!(i, 0, "the adapter went away after {i} engines");
            return;
        };
        drop(gpu);
    }
}

/// A codebook image (seed 004's vector quantisation) relit on the GPU without expanding
/// it: for every registered family, linear and display-referred, f32/f16/u8 entries,
/// directional and environment light, whole frame and a region, against the CPU's
/// look-up engine over the same entries; lights with a position refused.
#[test]
fn codebook_frames_match_the_cpu_lookup() {
    use relit::engine::lookup::{IndexedImage, LookupRelighter};
    use relit_gpu::GpuLookup;
    let dir = resource_dir("codebook");
    let env: EnvironmentMapLight =
        serde_json::from_str(r#"{ "map": "sky.exr", "yaw_deg": 40, "intensity": 0.7 }"#).unwrap();
    let (w, h, entries) = (41, 29, 37);
    for case in bases().into_iter().filter(|c| c.registered) {
        let name = case.basis.name();
        for space in [MapSpace::Linear, MapSpace::Srgb] {
            let mut table = image(entries, 1, case.basis.as_ref(), space);
            table.depth = None;
            let indexed = IndexedImage {
                entries: table,
                indices: (0..w * h)
                    .map(|p| ((p * 7 + p / w) % entries) as u16)
                    .collect(),
                width: w,
                height: h,
            };
            for precision in [Precision::F32, Precision::F16, Precision::U8] {
                let options = GpuOptions {
                    precision,
                    ..Default::default()
                };
                let gpu = match GpuLookup::new(&indexed, options) {
                    Ok(g) => g,
                    Err(GpuError::NoAdapter(why)) => {
                        relit::skip::skipping(&format!("no GPU adapter: {why}"));
                        return;
                    }
                    Err(e) => panic!("GPU look-up engine failed: {e}"),
                };
                // The CPU over the same stored entries: the GPU engine's own plain path
                // over them is what each frame's colours come from.
                let plain = GpuRelighter::with_options(&indexed.entries, options).unwrap();
                let rigs = [
                    LightRig::new(vec![
                        Light::directional([-0.4, 0.7, 0.6], [1.0, 0.8, 0.6]),
                        Light::directional([0.5, -0.2, 0.8], [0.1, 0.3, 0.9]),
                    ]),
                    LightRig::new(vec![Light::Environment(env.clone())]),
                ];
                for (r, rig) in rigs.iter().enumerate() {
                    let label = format!("{name} {space:?} {precision:?} rig {r}");
                    let mut lighting = gpu.entries().empty_lighting();
                    let mut rest = Vec::new();
                    for light in &rig.lights {
                        if let Light::Environment(_) = light {
                            let options = RelightOptions {
                                resource_dir: dir.clone(),
                                ..Default::default()
                            };
                            for l in Relighter::new(&indexed.entries)
                                .unwrap()
                                .prepare(light, &options)
                                .unwrap()
                            {
                                plain.add_prepared(&mut lighting, &l, 1.0).unwrap();
                            }
                        } else {
                            rest.push(light.clone());
                        }
                    }
                    if !rest.is_empty() {
                        lighting = gpu.lighting(&LightRig::new(rest), 0.0).unwrap();
                    }
                    let colours = plain.render(&lighting, None).unwrap();
                    let frame = gpu.render(&lighting, None).unwrap();
                    // Exactly the entries' colours, each pixel its own.
                    for (p, &i) in indexed.indices.iter().enumerate() {
                        let i = i as usize;
                        assert_eq!(
                            &frame.data[3 * p..3 * p + 3],
                            &colours.data[3 * i..3 * i + 3],
                            "{label}: pixel {p}"
                        );
                    }
                    // And the CPU's look-up engine within f32 rounding (f32 entries).
                    if precision == Precision::F32 {
                        let options = RelightOptions {
                            resource_dir: dir.clone(),
                            ..Default::default()
                        };
                        let cpu = LookupRelighter::new(&indexed)
                            .unwrap()
                            .relight(rig, &options)
                            .unwrap();
                        assert_close(&label, &frame, &cpu);
                    }
                    let roi = Roi {
                        x: 5,
                        y: 3,
                        width: 17,
                        height: 11,
                    };
                    let part = gpu.render(&lighting, Some(roi)).unwrap();
                    for y in 0..roi.height {
                        let a = &part.data[3 * y * roi.width..3 * (y + 1) * roi.width];
                        let start = 3 * ((roi.y + y) * w + roi.x);
                        assert_eq!(a, &frame.data[start..start + 3 * roi.width], "{label}: roi");
                    }
                }
                let point = LightRig::new(vec![Light::point([0.3, 1.0, -1.0], [1.0; 3])]);
                let refused = gpu.lighting(&point, 0.0).unwrap_err().to_string();
                assert!(refused.contains("expanded maps"), "{refused}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
