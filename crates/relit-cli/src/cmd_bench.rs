//! `relit bench`: relighting speed on this machine, and how close it gets to the limit.
//!
//! For each size and coefficient count the command builds synthetic maps (random
//! coefficients, a depth map, a cylindrical camera at the origin) and times three cases:
//!
//! * `directional` — one directional light: one weight per plane, one pass over the maps;
//! * `environment` — a synthetic lat-long sky (blue gradient and a small sun), given to
//!   both engines as its SH projection (`EnvironmentLight::light_weights`, the
//!   `PreparedLight::Weights` a rig's environment light becomes): one folded weight
//!   vector per channel, one pass over the maps like `directional`;
//! * `point` — one point light near the eye: per-pixel light vector and SH evaluation;
//! * `sh_eval` (CPU) — the per-pixel SH basis alone (`relit::engine::ShEvaluator`, the
//!   f32 recurrence of the point case) at every pixel's light vector, reported in
//!   pixels per second (`pixels_per_s`); no coefficient is read.
//!
//! on the CPU engine (`relit::engine::Relighter`, rayon over all cores) for each plane
//! storage (`f32`, `f16`, `u8`) and on the GPU engine (`relit-gpu`, skipped with the
//! reason when no adapter exists) for each GPU storage type. GPU frames are timed
//! without readback.
//!
//! Before the cases it measures the machine's f32 multiply-add rate on registers
//! (`relit::engine::fma_throughput`, all threads); every CPU uniform case reports
//! `fma_fraction`, the share of that rate its `3·k·pixels` multiply-adds per frame reach.
//!
//! In the same run it measures the memory read bandwidth over the maps' own bytes (a
//! multithreaded sum of the f32 buffer, best of three) and reports, for every case, the
//! fraction of the bandwidth bound achieved: `fps × bytes of the maps in that storage ÷
//! bandwidth`. A streaming case at 1.0 reads the maps as fast as the machine can read
//! anything. On a software adapter (lavapipe) GPU memory is host memory, so the same
//! bound applies; for a discrete GPU the host's bandwidth says nothing and the fraction
//! is left out (`null`).
//!
//! Memory and time: 8192×2048 maps are 3.2 GB (k = 16) and 5.0 GB (k = 25) in f32, which
//! the CPU engine reads as they are. A software adapter holds its copy in RAM too and
//! needs seconds per frame at that size, so there the GPU gets f16 only by default
//! (`--gpu-storage` overrides), which keeps the run near 2 minutes and under ~8 GB; a
//! hardware adapter gets every storage type.

use anyhow::{bail, Context};
use rayon::prelude::*;
use relit::basis::BasisSpec;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::engine::{PlaneStorage, Relighter, ShEvaluator};
use relit::envmap::EnvironmentLight;
use relit::image::ImageRgb;
use relit::light::{Light, PreparedLight};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit_gpu::{GpuError, GpuOptions, GpuRelighter, Lighting, Storage};
use serde::Serialize;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Smoke run for CI: 1024×256, k = 16, a few frames per case.
    #[arg(long)]
    pub quick: bool,
    /// Print the results as a JSON list of objects.
    #[arg(long)]
    pub json: bool,
    /// Sizes to run, `WxH` (repeatable; default 1024x256 and 8192x2048).
    #[arg(long = "size")]
    pub sizes: Vec<String>,
    /// Coefficient counts to run (perfect squares; repeatable; default 16 and 25).
    #[arg(long = "k")]
    pub ks: Vec<usize>,
    /// Seconds of timed frames per case (at least one frame after a warm-up frame).
    #[arg(long, default_value_t = 0.5)]
    pub seconds: f64,
    /// GPU storage types (`f32`, `f16`, `u8`; repeatable). Default: all three, except
    /// f16 alone above 64 Mpixel·k on a software adapter (see the module docs).
    #[arg(long = "gpu-storage")]
    pub gpu_storage: Vec<String>,
    /// Skip the GPU engine.
    #[arg(long)]
    pub no_gpu: bool,
    /// Skip the CPU engine.
    #[arg(long)]
    pub no_cpu: bool,
    /// Cases to run (`directional`, `environment`, `point`, `sh_eval`; repeatable).
    /// Default: all.
    #[arg(long = "case")]
    pub cases: Vec<String>,
    /// CPU plane storage types (`f32`, `f16`, `u8`; repeatable). Default: all three.
    #[arg(long = "cpu-storage")]
    pub cpu_storage: Vec<String>,
    /// Write the synthetic maps of the first --size and --k to this relightable EXR
    /// (f16, with depth and camera) and exit: a large test file for `relit relight`.
    #[arg(long)]
    pub write_maps: Option<std::path::PathBuf>,
}

/// One measured case; also the JSON form.
#[derive(Serialize, Debug, Clone)]
struct Row {
    case: &'static str,
    width: usize,
    height: usize,
    k: usize,
    storage: &'static str,
    /// `cpu` or `gpu`.
    device: &'static str,
    /// CPU threads, or the GPU adapter.
    engine: String,
    fps: f64,
    /// Pixels relit (or, for `sh_eval`, basis evaluations) per second.
    pixels_per_s: f64,
    ms_per_frame: f64,
    frames: usize,
    /// Bytes of the maps in this storage: what one streaming frame must read.
    map_bytes: u64,
    /// Memory read bandwidth measured over the f32 maps, GB/s.
    read_bandwidth_gbs: f64,
    /// `fps × map_bytes ÷ bandwidth`; null where host bandwidth does not bound the device.
    bandwidth_fraction: Option<f64>,
    /// `fps × 3·k·pixels ÷ peak multiply-add rate` (CPU uniform cases).
    fma_fraction: Option<f64>,
}

const CASES: [&str; 3] = ["directional", "environment", "point"];

pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        bail!("--seconds must be a positive number");
    }
    let seconds = if args.quick {
        args.seconds.min(0.2)
    } else {
        args.seconds
    };
    let sizes: Vec<(usize, usize)> = if !args.sizes.is_empty() {
        args.sizes
            .iter()
            .map(|s| parse_size(s))
            .collect::<anyhow::Result<_>>()?
    } else if args.quick {
        vec![(1024, 256)]
    } else {
        vec![(1024, 256), (8192, 2048)]
    };
    let ks: Vec<usize> = if !args.ks.is_empty() {
        args.ks.clone()
    } else if args.quick {
        vec![16]
    } else {
        vec![16, 25]
    };
    let bands_of = |k: usize| {
        let b = (k as f64).sqrt().round() as usize;
        (b * b == k && (1..=8).contains(&b)).then_some(b)
    };
    if let Some(&bad) = ks.iter().find(|&&k| bands_of(k).is_none()) {
        bail!("--k {bad}: k must be a square of 1..8 bands (1, 4, 9, …, 64)");
    }
    let gpu_storage: Option<Vec<Storage>> = if args.gpu_storage.is_empty() {
        None
    } else {
        Some(
            args.gpu_storage
                .iter()
                .map(|s| {
                    Storage::parse(s)
                        .with_context(|| format!("--gpu-storage `{s}`: expected f32, f16 or u8"))
                })
                .collect::<anyhow::Result<_>>()?,
        )
    };
    let adapter = if args.no_gpu {
        Err("--no-gpu".to_string())
    } else {
        relit_gpu::probe().map_err(|e| e.to_string())
    };
    let gpu_skip = adapter.as_ref().err().cloned();
    let software = adapter.as_ref().is_ok_and(|a| a.device_type == "Cpu");
    if let Some(why) = &gpu_skip {
        eprintln!("relit bench: GPU skipped: {why}");
    }

    let cpu_storage: Vec<PlaneStorage> = if args.cpu_storage.is_empty() {
        PlaneStorage::ALL.to_vec()
    } else {
        args.cpu_storage
            .iter()
            .map(|s| {
                PlaneStorage::parse(s)
                    .with_context(|| format!("--cpu-storage `{s}`: expected f32, f16 or u8"))
            })
            .collect::<anyhow::Result<_>>()?
    };
    if let Some(path) = &args.write_maps {
        let (width, height) = sizes[0];
        let bands = bands_of(ks[0]).expect("checked");
        let image = synthetic_image(width, height, bands)?;
        relit::codec::exr::write(path, &image, relit::codec::Storage::Half)?;
        println!(
            "wrote {} ({width}×{height}, k = {}, {} of f32 maps)",
            path.display(),
            ks[0],
            relit::memory::mib(image.maps.bytes() as u64)
        );
        return Ok(());
    }

    let known = ["directional", "environment", "point", "sh_eval"];
    if let Some(bad) = args.cases.iter().find(|c| !known.contains(&c.as_str())) {
        bail!("--case `{bad}`: expected one of {}", known.join(", "));
    }
    let wanted = |case: &str| args.cases.is_empty() || args.cases.iter().any(|c| c == case);
    let threads = rayon::current_num_threads();
    let fma_peak = if args.no_cpu {
        f64::NAN
    } else {
        let peak = relit::engine::fma_throughput(if args.quick { 0.05 } else { 0.3 });
        eprintln!(
            "relit bench: peak f32 multiply-add rate {:.1} G/s ({threads} threads)",
            peak / 1e9
        );
        peak
    };
    let mut rows = Vec::new();
    for &(width, height) in &sizes {
        for &k in &ks {
            let bands = bands_of(k).expect("checked");
            eprintln!("relit bench: {width}×{height}, k = {k}: building synthetic maps…");
            let image = synthetic_image(width, height, bands)?;
            let bandwidth = read_bandwidth(&image.maps.data);
            eprintln!(
                "relit bench: memory read bandwidth over the {} of maps: {:.1} GB/s ({threads} threads)",
                relit::memory::mib(image.maps.bytes() as u64),
                bandwidth / 1e9
            );
            let env = Environment::new(bands)?;
            let n = (width * height) as u64;
            let row = |case,
                       storage: &'static str,
                       bytes_per_value: usize,
                       device,
                       engine: String,
                       secs: f64,
                       frames| {
                let fps = 1.0 / secs;
                let map_bytes = 3 * k as u64 * n * bytes_per_value as u64;
                Row {
                    case,
                    width,
                    height,
                    k,
                    storage,
                    device,
                    engine,
                    fps,
                    pixels_per_s: fps * n as f64,
                    ms_per_frame: secs * 1e3,
                    frames,
                    map_bytes,
                    read_bandwidth_gbs: bandwidth / 1e9,
                    bandwidth_fraction: Some(fps * map_bytes as f64 / bandwidth),
                    fma_fraction: None,
                }
            };

            if !args.no_cpu {
                for &storage in &cpu_storage {
                    let relighter = Relighter::with_storage(&image, storage)?;
                    let engine = format!("{threads} threads, {}", relighter.kernels());
                    let mut frame = ImageRgb::new(0, 0);
                    let full = relit::engine::Roi::full(width, height);
                    for case in CASES.into_iter().filter(|c| wanted(c)) {
                        let lights = cpu_lights(case, &env)?;
                        let (secs, frames) = time_cpu(seconds, || {
                            relighter.relight_prepared_into(&lights, 0.0, full, &mut frame)?;
                            black_box(&frame);
                            Ok(())
                        })?;
                        let mut r = row(
                            case,
                            storage.name(),
                            storage.bytes_per_value(),
                            "cpu",
                            engine.clone(),
                            secs,
                            frames,
                        );
                        if case != "point" {
                            r.fma_fraction = Some(r.fps * (3 * k) as f64 * n as f64 / fma_peak);
                        }
                        report(&r, args.json);
                        rows.push(r);
                    }
                }
            }
            if !args.no_cpu && wanted("sh_eval") {
                let (secs, frames) = time_sh_eval(&image, bands, seconds)?;
                let mut r = row(
                    "sh_eval",
                    "-",
                    0,
                    "cpu",
                    format!("{threads} threads"),
                    secs,
                    frames,
                );
                r.bandwidth_fraction = None;
                report(&r, args.json);
                rows.push(r);
            }

            if gpu_skip.is_none() {
                let storages = gpu_storage.clone().unwrap_or_else(|| {
                    if software && n * k as u64 > 64 << 20 {
                        vec![Storage::F16]
                    } else {
                        Storage::ALL.to_vec()
                    }
                });
                for storage in storages {
                    let options = GpuOptions {
                        storage,
                        ..Default::default()
                    };
                    let gpu = match GpuRelighter::with_options(&image, options) {
                        Ok(g) => g,
                        Err(e @ (GpuError::TooLarge(_) | GpuError::Device(_))) => {
                            eprintln!("relit bench: GPU {} skipped: {e}", storage.name());
                            continue;
                        }
                        Err(e) => return Err(e.into()),
                    };
                    let host_bound = gpu.adapter().device_type == "Cpu";
                    for case in CASES.into_iter().filter(|c| wanted(c)) {
                        let lighting = gpu_lighting(&gpu, case, &env)?;
                        let (secs, frames) = time_gpu(&gpu, &lighting, seconds)?;
                        let mut r = row(
                            case,
                            storage.name(),
                            storage.bytes_per_value(),
                            "gpu",
                            gpu.adapter().to_string(),
                            secs,
                            frames,
                        );
                        if !host_bound {
                            r.bandwidth_fraction = None;
                        }
                        report(&r, args.json);
                        rows.push(r);
                    }
                }
            }
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print_summary(&rows);
    }
    Ok(())
}

fn parse_size(s: &str) -> anyhow::Result<(usize, usize)> {
    let (w, h) = s
        .split_once(['x', 'X', '×'])
        .with_context(|| format!("--size `{s}`: expected WxH, e.g. 1024x256"))?;
    let w: usize = w.trim().parse().with_context(|| format!("--size `{s}`"))?;
    let h: usize = h.trim().parse().with_context(|| format!("--size `{s}`"))?;
    if w == 0 || h == 0 {
        bail!("--size `{s}`: width and height must be positive");
    }
    Ok((w, h))
}

/// Maps of `bands²` coefficients with random values (a brighter constant term), depth
/// 1.5–2.5 everywhere, seen by a cylindrical panorama camera at the origin.
fn synthetic_image(width: usize, height: usize, bands: usize) -> anyhow::Result<RelightableImage> {
    let k = bands * bands;
    let n = width * height;
    let values = 3usize
        .checked_mul(k)
        .and_then(|v| v.checked_mul(n))
        .context("the maps are too large to address")?;
    let mut data = Vec::new();
    data.try_reserve_exact(values).with_context(|| {
        format!(
            "cannot allocate {} of maps",
            relit::memory::mib(values as u64 * 4)
        )
    })?;
    data.resize(values, 0f32);
    const CHUNK: usize = 1 << 16;
    data.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, chunk)| {
            let mut s = (c as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let constant = c * CHUNK < 3 * n;
            for v in chunk {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                let r = (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
                *v = if constant { 0.5 + 0.1 * r } else { 0.3 * r };
            }
        });
    let mut depth = vec![0f32; n];
    depth
        .par_iter_mut()
        .enumerate()
        .for_each(|(p, d)| *d = 2.0 + 0.5 * ((p * 7919 % 1000) as f32 / 1000.0 - 0.5));
    let projection = Projection::Cylindrical { fov_y_deg: None };
    let mut meta = Metadata::new(
        BasisSpec::Sh { bands },
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
    Ok(RelightableImage {
        meta,
        maps: CoefficientMaps {
            width,
            height,
            k,
            data,
        },
        depth: Some(depth),
    })
}

/// A synthetic sky as both engines take it: SH light weights per channel.
struct Environment {
    weights: [Vec<f64>; 3],
}

impl Environment {
    fn new(bands: usize) -> anyhow::Result<Self> {
        let sky = EnvironmentLight::from_image(sky())?;
        Ok(Self {
            weights: sky.light_weights(bands)?,
        })
    }
}

/// A blue gradient from the horizon up and a small bright sun, 128×64 lat-long.
fn sky() -> ImageRgb {
    let (w, h) = (128, 64);
    let mut map = ImageRgb::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let up = 1.0 - (y as f32 + 0.5) / h as f32;
            let mut rgb = [0.3 + 0.2 * up, 0.4 + 0.3 * up, 0.6 + 0.4 * up];
            if (x as i64 - 40).abs() <= 1 && (y as i64 - 20).abs() <= 1 {
                rgb = [50.0, 45.0, 40.0];
            }
            map.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&rgb);
        }
    }
    map
}

/// The point light of the `point` case: inside the cylinder, above and behind the eye.
fn point_light() -> Light {
    Light::point([0.3, 0.5, 0.2], [1.0, 0.9, 0.8])
}

fn directional_light() -> Light {
    Light::directional([-0.4, 0.7, 0.6], [1.0, 0.95, 0.9])
}

fn cpu_lights(case: &str, env: &Environment) -> anyhow::Result<Vec<PreparedLight>> {
    let lights = match case {
        "directional" => vec![directional_light()],
        "environment" => return Ok(vec![PreparedLight::Weights(env.weights.clone())]),
        _ => vec![point_light()],
    };
    Ok(lights
        .iter()
        .map(|l| l.prepare(Path::new("")))
        .collect::<relit::Result<_>>()?)
}

fn gpu_lighting(gpu: &GpuRelighter, case: &str, env: &Environment) -> anyhow::Result<Lighting> {
    let rig = |l: Light| relit::light::LightRig::new(vec![l]);
    Ok(match case {
        "directional" => gpu.lighting(&rig(directional_light()), 0.0)?,
        "environment" => {
            let mut lighting = gpu.empty_lighting();
            lighting.add_uniform(env.weights.clone(), [1.0; 3])?;
            lighting
        }
        _ => gpu.lighting(&rig(point_light()), 0.0)?,
    })
}

/// Seconds per frame and frames timed: one warm-up frame, then enough frames to fill
/// `seconds` (at least one).
fn time_cpu(
    seconds: f64,
    mut frame: impl FnMut() -> relit::Result<()>,
) -> anyhow::Result<(f64, usize)> {
    let t = Instant::now();
    frame()?;
    let warm = t.elapsed().as_secs_f64();
    let frames = ((seconds / warm.max(1e-6)) as usize).clamp(1, 100_000);
    let t = Instant::now();
    for _ in 0..frames {
        frame()?;
    }
    Ok((t.elapsed().as_secs_f64() / frames as f64, frames))
}

fn time_gpu(gpu: &GpuRelighter, lighting: &Lighting, seconds: f64) -> anyhow::Result<(f64, usize)> {
    let first = gpu.time_frames(lighting, None, 1)?.as_secs_f64();
    let frames = ((seconds / first.max(1e-6)) as usize).min(100_000);
    if frames <= 1 {
        return Ok((first, 1));
    }
    Ok((
        gpu.time_frames(lighting, None, frames)?.as_secs_f64(),
        frames,
    ))
}

/// Seconds per evaluation of the SH basis at every pixel's light vector (toward the
/// `point` case's light), and the number of timed passes: rayon over chunks of 4096
/// pixels, each evaluated into a per-thread buffer (no coefficient read, nothing
/// written to memory beyond L2).
fn time_sh_eval(
    image: &RelightableImage,
    bands: usize,
    seconds: f64,
) -> anyhow::Result<(f64, usize)> {
    const CHUNK: usize = 4096;
    let eval = ShEvaluator::new(bands)?;
    let camera = Relighter::new(image)?.camera()?;
    let depth = image.depth.as_ref().context("synthetic maps have depth")?;
    let Light::Point(light) = point_light() else {
        unreachable!()
    };
    let w = image.width();
    let n = depth.len();
    let mut dirs: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0f32; n]);
    {
        let [xs, ys, zs] = &mut dirs;
        xs.par_iter_mut()
            .zip(ys.par_iter_mut())
            .zip(zs.par_iter_mut())
            .enumerate()
            .for_each(|(p, ((x, y), z))| {
                let s = camera.position(p % w, p / w, depth[p] as f64);
                let l = (light.position - s)
                    .normalized()
                    .unwrap_or(relit::sphere::Vec3::new(0.0, 0.0, 1.0));
                (*x, *y, *z) = (l.x as f32, l.y as f32, l.z as f32);
            });
    }
    let k = eval.len();
    time_cpu(seconds, || {
        dirs[0]
            .par_chunks(CHUNK)
            .zip(dirs[1].par_chunks(CHUNK))
            .zip(dirs[2].par_chunks(CHUNK))
            .for_each_init(
                || vec![0f32; k * CHUNK],
                |out, ((x, y), z)| {
                    eval.eval(x, y, z, &mut out[..k * x.len()]);
                    black_box(&out);
                },
            );
        Ok(())
    })
}

/// Bytes per second of a multithreaded read of `data` (best of three): the bound for
/// any pass that streams these bytes once.
fn read_bandwidth(data: &[f32]) -> f64 {
    let bytes = std::mem::size_of_val(data) as f64;
    (0..3)
        .map(|_| {
            let t = Instant::now();
            let s: f32 = data.par_chunks(1 << 16).map(sum).sum();
            black_box(s);
            bytes / t.elapsed().as_secs_f64()
        })
        .fold(0.0, f64::max)
}

/// A sum with 16 independent accumulators, which the compiler vectorises.
fn sum(chunk: &[f32]) -> f32 {
    let mut acc = [0f32; 16];
    let mut it = chunk.chunks_exact(16);
    for c in &mut it {
        for (a, v) in acc.iter_mut().zip(c) {
            *a += v;
        }
    }
    acc.iter().sum::<f32>() + it.remainder().iter().sum::<f32>()
}

fn report(row: &Row, json: bool) {
    if !json {
        eprintln!(
            "  {:<11} {:>4}  {:<3} {:>9.1} fps  {:>8.1} Mpx/s  {}{}",
            row.case,
            row.device,
            row.storage,
            row.fps,
            row.pixels_per_s / 1e6,
            row.bandwidth_fraction
                .map(|f| format!("{:.0} % of bandwidth", f * 100.0))
                .unwrap_or_default(),
            row.fma_fraction
                .map(|f| format!(", {:.0} % of FMA peak", f * 100.0))
                .unwrap_or_default()
        );
    }
}

fn print_summary(rows: &[Row]) {
    println!(
        "{:<11} {:>10} {:>3} {:<4} {:<4} {:>10} {:>10} {:>10} {:>8} {:>9} {:>8}  engine",
        "case", "size", "k", "stor", "dev", "fps", "Mpx/s", "ms/frame", "GB/s", "of bw", "of FMA"
    );
    let pct = |f: Option<f64>| {
        f.map(|f| format!("{:.1} %", f * 100.0))
            .unwrap_or_else(|| "-".into())
    };
    for r in rows {
        println!(
            "{:<11} {:>10} {:>3} {:<4} {:<4} {:>10.1} {:>10.1} {:>10.3} {:>8.1} {:>9} {:>8}  {}",
            r.case,
            format!("{}×{}", r.width, r.height),
            r.k,
            r.storage,
            r.device,
            r.fps,
            r.pixels_per_s / 1e6,
            r.ms_per_frame,
            r.read_bandwidth_gbs,
            pct(r.bandwidth_fraction),
            pct(r.fma_fraction),
            r.engine
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("1024x256").unwrap(), (1024, 256));
        assert_eq!(parse_size("8192×2048").unwrap(), (8192, 2048));
        assert!(parse_size("1024").is_err());
        assert!(parse_size("0x5").is_err());
    }

    #[test]
    fn the_sum_reads_every_value() {
        let v: Vec<f32> = (0..1000).map(|i| i as f32).collect();
        assert_eq!(sum(&v), 499_500.0);
    }

    #[test]
    fn synthetic_maps_relight_on_the_cpu() {
        let image = synthetic_image(64, 16, 2).unwrap();
        let relighter = Relighter::new(&image).unwrap();
        let env = Environment::new(2).unwrap();
        for case in CASES {
            let frame = relighter
                .relight_prepared(&cpu_lights(case, &env).unwrap(), 0.0)
                .unwrap();
            assert!(frame.data.iter().all(|v| v.is_finite()), "{case}");
            assert!(frame.data.iter().any(|&v| v > 0.0), "{case}");
        }
    }
}
