//! `relit bench`: relighting speed on this machine, and how close it gets to the limit.
//!
//! For each size and basis (`--basis FAMILY:K`, any registered family; `--k K` is
//! `sh:K`) the command builds synthetic maps (random coefficients, a depth map, a
//! cylindrical camera at the origin) and times these cases:
//!
//! * `directional` — one directional light: one weight per plane, one pass over the maps;
//! * `environment` — a synthetic lat-long sky (blue gradient and a small sun), given to
//!   both engines as its weights on the basis (`EnvironmentLight::for_basis`: SH's
//!   projection or the quadrature, the `PreparedLight::Weights` a rig's environment
//!   light becomes): one folded weight vector per channel, one pass over the maps like
//!   `directional`;
//! * `point` — one point light near the eye: per-pixel light vector and basis
//!   evaluation (SH's recurrence, or the basis' half-float weight table);
//! * `area` — a one-sided rectangular area light above the scene, 16 emitter samples
//!   per pixel: 16 light vectors and weights per pixel (every pixel is lit);
//! * `projector` — a slide projector (fov 90°, a 2:1 synthetic slide) beside the eye,
//!   its frustum covering about a third of the panorama: per-pixel light vector and
//!   slide colour, basis evaluation where the slide reaches;
//! * `vq` storage (CPU, directional and environment): the maps as a codebook of
//!   `--codebook` entries (default 4096) and one 16-bit index a pixel (seed 004's
//!   vector quantisation, `relit::engine::lookup`): a frame relights the codebook once
//!   and copies one entry a pixel. `uncompressed_bound_fps` beside it is the most
//!   frames any reader of the same maps as u8 planes could reach at this run's u8 read
//!   bound;
//! * `basis_eval` (CPU) — the per-pixel basis alone (`relit::engine::BasisEvaluator`,
//!   the evaluation of the point case) at every pixel's light vector, reported in
//!   pixels per second (`pixels_per_s`); no coefficient is read.
//!
//! Families built from a capture's samples (`rbf`, `bilinear`) are built here from a
//! synthetic capture: 2K directions (48 at least) over the upper hemisphere, 200 pixel
//! series each a mixture of eight smooth lobes (as the GPU tests build them).
//!
//! Positional cases also report `basis_evals_per_s`: the (pixel, light vector) pairs of
//! non-zero weight per frame (counted once with the lights' own per-pixel definition,
//! `PreparedLight::illuminate`) times fps, the rate comparable across them and with
//! `basis_eval`.
//!
//! on the CPU engine (`relit::engine::Relighter`, rayon over all cores) for each plane
//! storage (`f32`, `f16`, `u8`) and on the GPU engine (`relit-gpu`, skipped with the
//! reason when no adapter exists) for each GPU storage type. GPU frames are timed
//! without readback.
//!
//! Timing: a warm-up frame, then five batches filling `--seconds` together; `fps` is the
//! fastest batch, `fps_median` the median one. Other processes on the machine slow some
//! batches (on this project's shared 2-core machine by up to 2×); the fastest batch is
//! the one least disturbed, and it is compared with bounds taken the same way.
//!
//! Bounds, measured in the same run (`relit::engine`'s `bounds` module says how and why
//! they bound):
//!
//! * **read bandwidth** — for each size, k and storage, the best plain read of the
//!   planes' own bytes (`Relighter::plane_read_rate`: AVX2 loads, one OR per 32 bytes,
//!   the engine's tile pattern and a contiguous one, every thread), measured three
//!   times before the storage's cases and once before every batch of a uniform case
//!   (each time as many reads as make 256 MiB, 1 to 16),
//!   so that probe and frames see the same load; the bound is the best of all of
//!   them. `bandwidth_fraction = fps × map_bytes ÷ bound`: a streaming case at 1.0
//!   reads the planes as fast as the machine reads anything. It also has to write the
//!   frame (12 bytes a pixel), which the bound leaves out, so u8 and f16 planes, with
//!   few bytes read per byte written, cannot quite reach 1.0. On a software adapter
//!   (lavapipe) GPU memory is host memory, so the rate of planes of the same type and
//!   size applies; a discrete GPU's frames are set against its own plain read of the
//!   resident planes themselves (`GpuRelighter::resident_read_rate`, a grid-strided
//!   vec4 sum over every slab, best of three batches each of 1, 2 and as many reads as
//!   make 16 GiB (8 to 256) after 1 s of untimed reads, once before the storage's
//!   cases), which the frame's write (12 bytes a pixel) is again left out of. (Without
//!   the warm-up an H200 that had idled while the host built the maps read them at
//!   1.7 TB/s, and at 4 TB/s when busy.)
//! * **multiply-add peak** — `relit::engine::fma_peak` at the start and at the end of
//!   the run (best of both): register-only FMA chains on every thread, 16-lane
//!   (AVX-512F) where the CPU has it, which is then the machine's peak (`fma_peak_gs`);
//!   the engine's 8-lane kernels can reach half of it at most. Every CPU uniform case
//!   reports `fma_fraction`, the share of that peak its `3·k·pixels` multiply-adds per
//!   frame reach.
//!
//! Memory and time: 8192×2048 maps are 3.2 GB (k = 16) and 5.0 GB (k = 25) in f32, which
//! the CPU engine reads as they are. A software adapter holds its copy in RAM too and
//! needs seconds per frame at that size, so there the GPU gets f16 only by default
//! (`--gpu-storage` overrides) and no area or projector case unless `--case` names it,
//! which keeps the run near 2 minutes and under ~8 GB; a hardware adapter gets every
//! storage type and case.

use anyhow::{bail, Context};
use rayon::prelude::*;
use relit::basis::{Basis, BasisChoice, Samples};
use relit::camera::{CameraSpec, Pose, Projection};
use relit::engine::lookup::{IndexedImage, LookupRelighter};
use relit::engine::{BasisEvaluator, Relighter};
use relit::envmap::EnvironmentLight;
use relit::image::ImageRgb;
use relit::light::{Light, PreparedLight};
use relit::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use relit::storage::Precision;
use relit_gpu::{GpuError, GpuOptions, GpuRelighter, Lighting};
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
    /// SH coefficient counts to run (perfect squares; repeatable; `--k K` is `--basis
    /// sh:K`). Default, without `--basis`: 16 and 25.
    #[arg(long = "k")]
    pub ks: Vec<usize>,
    /// Bases to run, `FAMILY:K` (any family: `sh:25`, `hsh:25`, `sg:25`, `ptm:6`,
    /// `rbf:25`, `bilinear:25`; repeatable). rbf and bilinear are built from a
    /// synthetic capture.
    #[arg(long = "basis")]
    pub bases: Vec<String>,
    /// Seconds of timed frames per case (at least one frame after a warm-up frame).
    #[arg(long, default_value_t = 0.5)]
    pub seconds: f64,
    /// GPU storage types (`f32`, `f16`, `u8`; repeatable). Default: all three, except
    /// f16 alone above 64 Mpixel·k on a software adapter (see the module docs).
    #[arg(long = "gpu-storage")]
    pub gpu_storage: Vec<Precision>,
    /// Skip the GPU engine.
    #[arg(long)]
    pub no_gpu: bool,
    /// Skip the CPU engine.
    #[arg(long)]
    pub no_cpu: bool,
    /// Cases to run (`directional`, `environment`, `point`, `area`, `projector`,
    /// `basis_eval`; repeatable). Default: all (the GPU runs all but `basis_eval`).
    #[arg(long = "case")]
    pub cases: Vec<String>,
    /// CPU plane storage types (`f32`, `f16`, `u8`; repeatable). Default: all three.
    #[arg(long = "cpu-storage")]
    pub cpu_storage: Vec<Precision>,
    /// Entries of the codebook the `vq` rows look pixels up in (their directional and
    /// environment frames relight the codebook, then copy an entry a pixel).
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(2..=65536))]
    pub codebook: u32,
    /// Write the synthetic maps of the first --size and --k to this relightable EXR
    /// (f16, with depth and camera) and exit: a large test file for `relit relight`.
    #[arg(long)]
    pub write_maps: Option<std::path::PathBuf>,
    /// With --write-maps: fill the size with this fitted file's maps (repeated, every
    /// other copy mirrored so that no seam is a step) instead of random values: a large
    /// file with the statistics of a real capture, for compression and load times.
    #[arg(long, requires = "write_maps")]
    pub tile_from: Option<std::path::PathBuf>,
    /// Write a capture of the first --size to this folder and exit: every image of
    /// --capture-from repeated over the size, every other copy mirrored, each copy's
    /// brightness jittered by up to ±3 % (so that no two copies are equal), as 8-bit
    /// JPEG (quality 95) with an `.lp` of the same lights: a big capture for fit time and
    /// memory, made in seconds.
    #[arg(long, requires = "capture_from")]
    pub write_capture: Option<std::path::PathBuf>,
    /// The capture --write-capture repeats (`.lp` or manifest).
    #[arg(long)]
    pub capture_from: Option<std::path::PathBuf>,
    /// Time loading each file and drawing its first frame (one directional light) and
    /// exit: EXR files into u8 planes, compressed files into their planes, or into a
    /// codebook and indices (repeatable).
    #[arg(long)]
    pub load: Vec<std::path::PathBuf>,
    /// Time the default fit of this capture, process start to file written, with its
    /// peak memory and its stages, and exit (see --peer).
    #[arg(long)]
    pub fit: Option<std::path::PathBuf>,
    /// With --fit: also run this RTI fitter (e.g. relight-cli) on the capture's folder in
    /// the same run, and print the ratios.
    #[arg(long)]
    pub peer: Option<std::path::PathBuf>,
    /// With --peer: the peer's options before the input folder and output path.
    #[arg(long, default_value = "-b hsh -p 27", allow_hyphen_values = true)]
    pub peer_args: String,
    /// With --fit: `relit fit` options for the timed fit instead of the default one
    /// (e.g. `--basis hsh:9`, relight-cli's HSH-27).
    #[arg(long, default_value = "", allow_hyphen_values = true)]
    pub fit_args: String,
}

/// One measured case; also the JSON form.
#[derive(Serialize, Debug, Clone)]
struct Row {
    case: &'static str,
    width: usize,
    height: usize,
    /// The basis, `family:K`.
    basis: String,
    k: usize,
    storage: &'static str,
    /// `cpu` or `gpu`.
    device: &'static str,
    /// CPU threads and kernels, or the GPU adapter.
    engine: String,
    /// Frames per second of the fastest batch (see the module docs).
    fps: f64,
    /// Frames per second of the median batch.
    fps_median: f64,
    /// Pixels relit (or, for `basis_eval`, basis evaluations) per second, at `fps`.
    pixels_per_s: f64,
    /// Positional CPU cases: the per-pixel light vectors of non-zero weight one frame
    /// evaluates the basis at (area lights: every sample of every lit pixel).
    basis_evals_per_frame: Option<u64>,
    /// `fps × basis_evals_per_frame`.
    basis_evals_per_s: Option<f64>,
    ms_per_frame: f64,
    /// Frames timed, over all batches.
    frames: usize,
    batches: usize,
    /// Bytes of the maps in this storage: what one streaming frame must read.
    map_bytes: u64,
    /// The read bandwidth bound, GB/s: the best plain read of these bytes measured in
    /// this run (`Relighter::plane_read_rate`).
    read_bandwidth_gbs: f64,
    /// `fps × map_bytes ÷ bandwidth`; null where no bound was measured (`basis_eval`).
    bandwidth_fraction: Option<f64>,
    /// Peak multiply-add rate of this machine measured in this run, G/s.
    fma_peak_gs: f64,
    /// `fps × 3·k·pixels ÷ peak multiply-add rate` (CPU uniform cases).
    fma_fraction: Option<f64>,
    /// Whether host memory bounds the device (the CPU, a software adapter).
    #[serde(skip)]
    host_bound: bool,
    /// `vq` rows: the most frames per second any reader of the same maps as u8 planes
    /// could reach (this size's u8 read bound ÷ the planes' bytes).
    #[serde(skip_serializing_if = "Option::is_none")]
    uncompressed_bound_fps: Option<f64>,
}

const CASES: [&str; 5] = ["directional", "environment", "point", "area", "projector"];

/// The cases the GPU engine runs: all of them (`basis_eval` is a CPU measurement).
const GPU_CASES: [&str; 5] = CASES;

/// Cases with one weight per plane (a frame streams the planes once).
fn uniform(case: &str) -> bool {
    matches!(case, "directional" | "environment")
}

/// Width, height, k and storage of the maps a read bound belongs to.
type BoundKey = (usize, usize, usize, &'static str);

/// Timed batches per case; the read probe runs once before each batch of a uniform case.
const BATCHES: usize = 5;

pub fn run(args: Args) -> anyhow::Result<()> {
    let json = args.json;
    let Some(rows) = measure(args)? else {
        return Ok(());
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print_summary(&rows);
    }
    Ok(())
}

/// Run the benchmark (or, with `--write-maps`, write the maps and return `None`).
fn measure(args: Args) -> anyhow::Result<Option<Vec<Row>>> {
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
    let mut bases: Vec<String> = args.bases.clone();
    for k in &args.ks {
        let b = (*k as f64).sqrt().round() as usize;
        if b * b != *k || !(1..=8).contains(&b) {
            bail!("--k {k}: k must be a square of 1..8 bands (1, 4, 9, …, 64)");
        }
        bases.push(format!("sh:{k}"));
    }
    if bases.is_empty() {
        bases = if args.quick {
            vec!["sh:16".into()]
        } else {
            vec!["sh:16".into(), "sh:25".into()]
        };
    }
    for name in &bases {
        BasisChoice::parse(name).with_context(|| format!("--basis `{name}`"))?;
    }
    let gpu_storage: Option<Vec<Precision>> =
        (!args.gpu_storage.is_empty()).then(|| args.gpu_storage.clone());
    let cpu_storage: Vec<Precision> = if args.cpu_storage.is_empty() {
        Precision::ALL.to_vec()
    } else {
        args.cpu_storage.clone()
    };
    if let Some(capture) = &args.fit {
        crate::fit_bench::run(
            capture,
            &args.fit_args,
            args.peer.as_deref(),
            &args.peer_args,
            args.json,
        )?;
        return Ok(None);
    }
    if !args.load.is_empty() {
        load_times(&args.load, args.json)?;
        return Ok(None);
    }
    if let Some(dir) = &args.write_capture {
        let from = args.capture_from.as_ref().expect("clap requires it");
        let (width, height) = sizes[0];
        write_big_capture(from, dir, width, height)?;
        return Ok(None);
    }
    if let Some(path) = &args.write_maps {
        let inputs: Vec<std::path::PathBuf> = args.tile_from.iter().cloned().collect();
        crate::shared::refuse_overwriting_inputs(&inputs, &[relit::fsutil::Output::file(path)])?;
        let (width, height) = sizes[0];
        let (basis, image) = match &args.tile_from {
            Some(from) => {
                let source = relit::codec::read(from)?;
                let image = tiled_image(&source, width, height);
                (source.meta.basis.build()?, image)
            }
            None => {
                let basis = bench_basis(&bases[0])?;
                let image = synthetic_image(width, height, basis.as_ref())?;
                (basis, image)
            }
        };
        relit::codec::exr::write(path, &image, Precision::F16)?;
        println!(
            "wrote {} ({width}×{height}, {}, {} of f32 maps)",
            path.display(),
            basis.name(),
            relit::memory::mib(image.maps.bytes() as u64)
        );
        return Ok(None);
    }

    let known = [
        "directional",
        "environment",
        "point",
        "area",
        "projector",
        "basis_eval",
    ];
    if let Some(bad) = args.cases.iter().find(|c| !known.contains(&c.as_str())) {
        bail!("--case `{bad}`: expected one of {}", known.join(", "));
    }
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
    let wanted = |case: &str| args.cases.is_empty() || args.cases.iter().any(|c| c == case);
    let threads = rayon::current_num_threads();
    let fma_seconds = if args.quick { 0.05 } else { 0.3 };
    let mut fma = (!args.no_cpu).then(|| {
        let peak = relit::engine::fma_peak(fma_seconds);
        report_fma(&peak, threads);
        peak
    });
    let mut rows = Vec::new();
    // The read bound of each size, k and storage: the best probe so far.
    let mut bounds: Vec<(BoundKey, f64)> = Vec::new();
    fn raise(bounds: &mut Vec<(BoundKey, f64)>, key: BoundKey, rate: f64) {
        match bounds.iter_mut().find(|(k, _)| *k == key) {
            Some((_, r)) => *r = r.max(rate),
            None => bounds.push((key, rate)),
        }
    }
    for &(width, height) in &sizes {
        for name in &bases {
            let basis = bench_basis(name)?;
            let k = basis.len();
            let basis_name = basis.name();
            eprintln!("relit bench: {width}×{height}, {basis_name}: building synthetic maps…");
            let image = synthetic_image(width, height, basis.as_ref())?;
            let env = Environment::new(basis.as_ref())?;
            if let Some(t) = BasisEvaluator::new(basis.as_ref()).table_accuracy() {
                let vertices = (t.resolution + 1) * (t.resolution + 1);
                eprintln!(
                    "relit bench: {basis_name} per pixel: half-float weight table of {} cells a side ({}), relative RMS error {:.1e}",
                    t.resolution,
                    relit::memory::mib((vertices * k.div_ceil(8) * 16) as u64),
                    t.relative_rms
                );
            }
            let n = (width * height) as u64;
            let row = |case,
                       storage: &'static str,
                       bytes_per_value: usize,
                       device,
                       engine: String,
                       t: &Timing| {
                let fps = 1.0 / t.best;
                Row {
                    case,
                    width,
                    height,
                    basis: basis_name.clone(),
                    k,
                    storage,
                    device,
                    engine,
                    fps,
                    fps_median: 1.0 / t.median,
                    pixels_per_s: fps * n as f64,
                    basis_evals_per_frame: None,
                    basis_evals_per_s: None,
                    ms_per_frame: t.best * 1e3,
                    frames: t.frames,
                    batches: t.batches,
                    map_bytes: 3 * k as u64 * n * bytes_per_value as u64,
                    read_bandwidth_gbs: f64::NAN,
                    bandwidth_fraction: None,
                    fma_peak_gs: f64::NAN,
                    fma_fraction: None,
                    host_bound: true,
                    uncompressed_bound_fps: None,
                }
            };

            // Light vectors per frame of each positional case (the same for every storage).
            let mut evals: std::collections::HashMap<&str, u64> = Default::default();
            if !args.no_cpu {
                for &storage in &cpu_storage {
                    let relighter = Relighter::with_precision(&image, storage)?;
                    let key = (width, height, k, storage.name());
                    let reps = probe_reps(relighter.plane_bytes());
                    raise(&mut bounds, key, relighter.plane_read_rate(3 * reps));
                    let engine = format!("{threads} threads, {}", relighter.kernels());
                    let mut frame = ImageRgb::new(0, 0);
                    let full = relit::engine::Roi::full(width, height);
                    for case in CASES.into_iter().filter(|c| wanted(c)) {
                        let lights = cpu_lights(case, &env)?;
                        // Uniform cases are bandwidth-bound: probe between their batches.
                        let mut probe = || {
                            if uniform(case) {
                                raise(&mut bounds, key, relighter.plane_read_rate(reps));
                            }
                        };
                        let t = time_batches(seconds, &mut probe, || {
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
                            &t,
                        );
                        if !uniform(case) {
                            let evals = *evals
                                .entry(case)
                                .or_insert_with(|| basis_evals(&relighter, &lights));
                            r.basis_evals_per_frame = Some(evals);
                            r.basis_evals_per_s = Some(r.fps * evals as f64);
                        }
                        report(&r, args.json);
                        rows.push(r);
                    }
                }
            }
            // Vector quantisation: the same frames from a codebook and an index a pixel.
            let vq_cases: Vec<&str> = CASES
                .into_iter()
                .filter(|c| uniform(c) && wanted(c))
                .collect();
            if !args.no_cpu && !vq_cases.is_empty() {
                let indexed = synthetic_indexed(&image, args.codebook as usize);
                let lookup = LookupRelighter::new(&indexed)?;
                let mut frame = ImageRgb::new(0, 0);
                for case in vq_cases {
                    let lights = cpu_lights(case, &env)?;
                    let t = time_batches(seconds, &mut || {}, || {
                        lookup.relight_prepared_into(&lights, 0.0, &mut frame)?;
                        black_box(&frame);
                        Ok(())
                    })?;
                    let mut r = row(
                        case,
                        "vq",
                        0,
                        "cpu",
                        format!(
                            "{threads} threads, look-up in a codebook of {} entries",
                            args.codebook
                        ),
                        &t,
                    );
                    r.map_bytes = lookup.index_bytes() as u64;
                    report(&r, args.json);
                    rows.push(r);
                }
            }
            if !args.no_cpu && wanted("basis_eval") {
                let t = time_basis_eval(&image, basis.as_ref(), seconds)?;
                let mut r = row(
                    "basis_eval",
                    "-",
                    0,
                    "cpu",
                    format!("{threads} threads"),
                    &t,
                );
                r.basis_evals_per_frame = Some(n);
                r.basis_evals_per_s = Some(r.pixels_per_s);
                report(&r, args.json);
                rows.push(r);
            }

            if gpu_skip.is_none() {
                let storages = gpu_storage.clone().unwrap_or_else(|| {
                    if software && n * k as u64 > 64 << 20 {
                        vec![Precision::F16]
                    } else {
                        Precision::ALL.to_vec()
                    }
                });
                let mut last_device_bound = None;
                for storage in storages {
                    let options = GpuOptions {
                        precision: storage,
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
                    // A software adapter reads host memory: bound it by the host's read
                    // rate of planes of the same type and size.
                    let host_bound = gpu.adapter().device_type == "Cpu";
                    let key = (width, height, k, storage.name());
                    if host_bound && !bounds.iter().any(|(k, _)| *k == key) {
                        let relighter = Relighter::with_precision(&image, storage)?;
                        let reps = probe_reps(relighter.plane_bytes());
                        let rate = relighter.plane_read_rate(3 * reps);
                        raise(&mut bounds, key, rate);
                    }
                    let device_bound = if host_bound {
                        None
                    } else {
                        let bytes = gpu.resident_bytes();
                        let passes = ((16u64 << 30) / bytes.max(1)).clamp(8, 256) as usize;
                        Some(gpu.resident_read_rate(passes)?)
                    };
                    // Area and projector frames take tens of seconds each on a software
                    // adapter at this size: there they run only when asked for by name.
                    let large_on_software = software && n * k as u64 > 64 << 20;
                    let skip_by_default = |c: &str| {
                        large_on_software
                            && args.cases.is_empty()
                            && matches!(c, "area" | "projector")
                    };
                    for case in GPU_CASES
                        .into_iter()
                        .filter(|c| wanted(c) && !skip_by_default(c))
                    {
                        let lighting = gpu_lighting(&gpu, case, &env)?;
                        let t = time_gpu(&gpu, &lighting, seconds)?;
                        let mut r = row(
                            case,
                            storage.name(),
                            storage.bytes_per_value(),
                            "gpu",
                            gpu.adapter().to_string(),
                            &t,
                        );
                        r.host_bound = host_bound;
                        if let Some(rate) = device_bound {
                            r.read_bandwidth_gbs = rate / 1e9;
                            r.bandwidth_fraction = Some(r.fps * r.map_bytes as f64 / rate);
                        }
                        report(&r, args.json);
                        rows.push(r);
                    }
                    last_device_bound = device_bound.or(last_device_bound);
                }
                // Vector quantisation on the GPU: relight the codebook, gather a colour
                // a pixel (2 bytes of index read per pixel).
                let vq_cases: Vec<&str> = ["directional", "environment"]
                    .into_iter()
                    .filter(|c| wanted(c))
                    .collect();
                if !vq_cases.is_empty() {
                    let indexed = synthetic_indexed(&image, args.codebook as usize);
                    match relit_gpu::GpuLookup::new(&indexed, GpuOptions::default()) {
                        Err(e @ (GpuError::TooLarge(_) | GpuError::Device(_))) => {
                            eprintln!("relit bench: GPU codebook skipped: {e}");
                        }
                        Err(e) => return Err(e.into()),
                        Ok(lookup) => {
                            for case in vq_cases {
                                let lighting = gpu_lighting(lookup.entries(), case, &env)?;
                                let t = time_gpu_frames(
                                    &|n| lookup.time_frames(&lighting, None, n),
                                    seconds,
                                )?;
                                let mut r = row(
                                    case,
                                    "vq",
                                    0,
                                    "gpu",
                                    format!(
                                        "{}, look-up in a codebook of {} entries",
                                        lookup.entries().adapter(),
                                        args.codebook
                                    ),
                                    &t,
                                );
                                r.map_bytes = 2 * n;
                                r.host_bound = lookup.entries().adapter().device_type == "Cpu";
                                if let Some(rate) = last_device_bound {
                                    r.read_bandwidth_gbs = rate / 1e9;
                                    r.bandwidth_fraction = Some(r.fps * r.map_bytes as f64 / rate);
                                }
                                report(&r, args.json);
                                rows.push(r);
                            }
                        }
                    }
                }
            }
        }
    }
    // The peak again at the end, so that a quiet moment at either end sets it.
    if let Some(first) = fma {
        let again = relit::engine::fma_peak(fma_seconds);
        let best = |a: f64, b: f64| a.max(b);
        let peak = relit::engine::FmaPeak {
            lanes8: best(first.lanes8, again.lanes8),
            lanes16: first.lanes16.zip(again.lanes16).map(|(a, b)| a.max(b)),
        };
        report_fma(&peak, threads);
        fma = Some(peak);
    }
    for r in &mut rows {
        let bound = bounds
            .iter()
            .find(|(key, _)| *key == (r.width, r.height, r.k, r.storage))
            .map(|(_, b)| *b);
        if let (Some(b), true, false) = (bound, r.host_bound, r.case == "basis_eval") {
            r.read_bandwidth_gbs = b / 1e9;
            r.bandwidth_fraction = Some(r.fps * r.map_bytes as f64 / b);
        }
        if r.storage == "vq" && r.device == "cpu" {
            let u8_bound = bounds
                .iter()
                .find(|(key, _)| *key == (r.width, r.height, r.k, "u8"))
                .map(|(_, b)| *b);
            r.uncompressed_bound_fps = u8_bound.map(|b| b / (3 * r.k * r.width * r.height) as f64);
            if let Some(fps) = r.uncompressed_bound_fps {
                r.engine += &format!("; u8 planes could reach {fps:.1} fps at most");
            }
        }
        if let Some(peak) = &fma {
            r.fma_peak_gs = peak.best() / 1e9;
            if r.device == "cpu" && uniform(r.case) && r.storage != "vq" {
                let madds = (3 * r.k * r.width * r.height) as f64;
                r.fma_fraction = Some(r.fps * madds / peak.best());
            }
        }
    }
    for ((w, h, k, storage), b) in &bounds {
        eprintln!(
            "relit bench: read bound {w}×{h} k = {k} {storage}: {:.1} GB/s (best plain read of the planes' bytes, {threads} threads)",
            b / 1e9
        );
    }
    Ok(Some(rows))
}

/// Reads of the planes per probe: enough for 256 MiB (small maps are read in a few
/// milliseconds, and a few more chances to meet a quiet moment keep the bound from
/// being set by a disturbed one), at most 16.
fn probe_reps(bytes: usize) -> usize {
    ((256usize << 20) / bytes.max(1)).clamp(1, 16)
}

fn report_fma(peak: &relit::engine::FmaPeak, threads: usize) {
    eprintln!(
        "relit bench: peak f32 multiply-add rate {:.1} G/s ({}, {threads} threads; 8-lane code {:.1} G/s)",
        peak.best() / 1e9,
        peak.isa(),
        peak.lanes8 / 1e9
    );
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

/// The basis named `name`: analytic families by name, families built from a capture's
/// samples from a synthetic capture (module docs).
fn bench_basis(name: &str) -> anyhow::Result<Box<dyn Basis>> {
    let choice = BasisChoice::parse(name).with_context(|| format!("--basis `{name}`"))?;
    if !choice.needs_samples() {
        return Ok(choice.build(&[], None)?);
    }
    // Twice as many lights as components, 48 at least (a PCA to K needs K lights).
    let dirs = relit::sphere::hemisphere_fibonacci((2 * choice.k).max(48));
    let lobes = relit::sphere::fibonacci(8);
    let series = 200;
    let mut values = Vec::with_capacity(series * dirs.len());
    for s in 0..series {
        for d in &dirs {
            let v: f64 = lobes
                .iter()
                .enumerate()
                .map(|(i, l)| {
                    let weight = 1.0 + ((s * 8 + i) * 7919 % 1000) as f64 / 1000.0;
                    weight * (4.0 * (d.dot(*l) - 1.0)).exp()
                })
                .sum();
            values.push(v as f32);
        }
    }
    let samples = Samples {
        values: &values,
        n: dirs.len(),
    };
    Ok(choice.build(&dirs, Some(samples))?)
}

/// The source pixel of `(x, y)` when a `sw × sh` image is repeated over a larger one,
/// every other copy mirrored across and down (neighbouring copies meet at equal
/// pixels), and which copy it lies in.
fn mirrored(x: usize, y: usize, sw: usize, sh: usize) -> (usize, (usize, usize)) {
    let (cx, cy) = (x / sw, y / sh);
    let (mut u, mut v) = (x % sw, y % sh);
    if cx % 2 == 1 {
        u = sw - 1 - u;
    }
    if cy % 2 == 1 {
        v = sh - 1 - v;
    }
    (v * sw + u, (cx, cy))
}

/// `relit bench --write-capture`: `from`'s images repeated over `width × height` (see
/// the flag), written to `dir` with an `.lp`.
fn write_big_capture(
    from: &std::path::Path,
    dir: &std::path::Path,
    width: usize,
    height: usize,
) -> anyhow::Result<()> {
    use relit::capture::Capture;
    let capture = Capture::open(from)?;
    crate::shared::refuse_overwriting_inputs(
        &capture.input_files(),
        &[relit::fsutil::Output::folder(dir)],
    )?;
    std::fs::create_dir_all(dir)?;
    let (sw, sh) = (capture.width, capture.height);
    let start = std::time::Instant::now();
    let names: Vec<String> = (0..capture.len())
        .into_par_iter()
        .map(|j| -> anyhow::Result<String> {
            let source = capture.load_raw(j)?;
            let mut big = ImageRgb::new(width, height);
            big.data
                .par_chunks_mut(3 * width)
                .enumerate()
                .for_each(|(y, row)| {
                    for x in 0..width {
                        let (p, (cx, cy)) = mirrored(x, y, sw, sh);
                        // A gain per copy and image, ±3 %, from a small integer hash.
                        let h = (cx as u64 * 73_856_093)
                            ^ (cy as u64 * 19_349_663)
                            ^ (j as u64 * 83_492_791);
                        let gain = 1.0 + 0.03 * ((h % 2001) as f32 / 1000.0 - 1.0);
                        for c in 0..3 {
                            row[3 * x + c] = source.data[3 * p + c] * gain;
                        }
                    }
                });
            let name = format!("image{j:04}.jpg");
            relit::image::save(&dir.join(&name), &big, 0.0)?;
            Ok(name)
        })
        .collect::<anyhow::Result<_>>()?;
    let mut lp = format!("{}\n", names.len());
    for (name, d) in names.iter().zip(capture.directions()) {
        lp += &format!("{name} {} {} {}\n", d.x, d.y, d.z);
    }
    std::fs::write(dir.join("dirs.lp"), lp)?;
    println!(
        "wrote {} ({} images of {width}×{height} from {sw}×{sh}, {:.1} s)",
        dir.join("dirs.lp").display(),
        names.len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `source`'s maps and depth repeated over `width × height`, every other copy mirrored
/// (across and down) so that neighbouring copies meet at equal pixels.
fn tiled_image(source: &RelightableImage, width: usize, height: usize) -> RelightableImage {
    let (sw, sh) = (source.width(), source.height());
    let at = |x: usize, y: usize| mirrored(x, y, sw, sh).0;
    let n = width * height;
    let k = source.maps.k;
    let mut maps = CoefficientMaps::zeros(width, height, k);
    let sn = sw * sh;
    maps.data
        .par_chunks_mut(n)
        .enumerate()
        .for_each(|(plane, out)| {
            let src = &source.maps.data[plane * sn..(plane + 1) * sn];
            for (p, o) in out.iter_mut().enumerate() {
                *o = src[at(p % width, p / width)];
            }
        });
    let depth = source
        .depth
        .as_ref()
        .map(|d| (0..n).map(|p| d[at(p % width, p / width)]).collect());
    let mut meta = source.meta.clone();
    meta.camera = None;
    RelightableImage { meta, maps, depth }
}

/// One file's load and first frame.
#[derive(Serialize)]
struct LoadTime {
    file: String,
    bytes: u64,
    /// How the frame was drawn: `u8 planes`, `f32 planes` or `codebook look-up`.
    path: &'static str,
    /// Fastest of three runs (the file in the page cache each time), seconds.
    seconds: f64,
    seconds_median: f64,
}

/// Time [`LOAD_RUNS`] loads and first frames of each file.
fn load_times(files: &[std::path::PathBuf], json: bool) -> anyhow::Result<()> {
    const LOAD_RUNS: usize = 3;
    let light = [PreparedLight::Directional {
        direction: relit::sphere::Vec3::new(0.3, 0.4, 0.866),
        rgb: [1.0; 3],
    }];
    let mut rows = Vec::new();
    for file in files {
        let bytes = std::fs::metadata(file)
            .with_context(|| format!("cannot read {}", file.display()))?
            .len();
        let mut times = Vec::new();
        let mut path = "";
        for _ in 0..LOAD_RUNS {
            let start = Instant::now();
            let frame = match relit::codec::FileForm::of(file)? {
                relit::codec::FileForm::Exr => {
                    path = "u8 planes";
                    let (image, planes) = relit::codec::read_compact(file, Precision::U8)?;
                    Relighter::with_compact(&image, planes)?.relight_prepared(&light, 0.0)?
                }
                relit::codec::FileForm::Ptm | relit::codec::FileForm::Rti => {
                    path = "f32 maps";
                    let image = relit::codec::read(file)?;
                    Relighter::new(&image)?.relight_prepared(&light, 0.0)?
                }
                relit::codec::FileForm::Compressed => {
                    let packed = relit::codec::packed::read_packed(file)?;
                    if packed.header.indexed_pixels() {
                        path = "codebook look-up";
                        let indexed = relit::compress::indexed(&packed)?;
                        let mut frame = ImageRgb::new(0, 0);
                        LookupRelighter::new(&indexed)?
                            .relight_prepared_into(&light, 0.0, &mut frame)?;
                        frame
                    } else {
                        path = "f32 planes";
                        let image = relit::compress::unpack(&packed)?;
                        Relighter::new(&image)?.relight_prepared(&light, 0.0)?
                    }
                }
                relit::codec::FileForm::Web => {
                    path = "f32 planes (web folder)";
                    let image = relit::codec::read(file)?;
                    Relighter::new(&image)?.relight_prepared(&light, 0.0)?
                }
            };
            black_box(&frame);
            times.push(start.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        let row = LoadTime {
            file: file.display().to_string(),
            bytes,
            path,
            seconds: times[0],
            seconds_median: times[LOAD_RUNS / 2],
        };
        if !json {
            println!(
                "{}: {} MiB, load + first frame ({}) {:.3} s (median {:.3} s)",
                row.file,
                bytes >> 20,
                row.path,
                row.seconds,
                row.seconds_median
            );
        }
        rows.push(row);
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else if rows.len() > 1 {
        for r in &rows[1..] {
            println!(
                "{} / {}: {:.2}×",
                r.file,
                rows[0].file,
                r.seconds / rows[0].seconds
            );
        }
    }
    Ok(())
}

/// Maps of `basis` with random values (a brighter first coefficient), depth 1.5–2.5
/// everywhere, seen by a cylindrical panorama camera at the origin.
fn synthetic_image(
    width: usize,
    height: usize,
    basis: &dyn Basis,
) -> anyhow::Result<RelightableImage> {
    let k = basis.len();
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
            for (j, v) in chunk.iter_mut().enumerate() {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                let r = (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
                // The first coefficient's three planes come first.
                let first = c * CHUNK + j < 3 * n;
                *v = if first { 0.5 + 0.1 * r } else { 0.3 * r };
            }
        });
    let mut depth = vec![0f32; n];
    depth
        .par_iter_mut()
        .enumerate()
        .for_each(|(p, d)| *d = 2.0 + 0.5 * ((p * 7919 % 1000) as f32 / 1000.0 - 0.5));
    let projection = Projection::Cylindrical { fov_y_deg: None };
    let mut meta = Metadata::new(basis.spec(), MapSpace::Linear, projection.clone());
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

/// The maps as a codebook of `entries` of their pixels and an index a pixel, constant
/// over 8×8 blocks (a real codebook file's indices are coherent too; the look-up's speed
/// depends on neither the entries' values nor the indices, as long as the table stays
/// in the caches: 12 bytes an entry).
fn synthetic_indexed(image: &RelightableImage, entries: usize) -> IndexedImage {
    let (w, h, k) = (image.width(), image.height(), image.maps.k);
    let n = w * h;
    let entries = entries.min(n);
    let mut table = CoefficientMaps::zeros(entries, 1, k);
    for plane in 0..3 * k {
        let src = &image.maps.data[plane * n..plane * n + entries];
        table.data[plane * entries..(plane + 1) * entries].copy_from_slice(src);
    }
    let indices = (0..n)
        .into_par_iter()
        .map(|p| {
            let block = ((p % w) / 8) as u64 * 0x9E37_79B9 + ((p / w) / 8) as u64 * 0x85EB_CA6B;
            ((block ^ (block >> 13)) % entries as u64) as u16
        })
        .collect();
    IndexedImage {
        entries: RelightableImage {
            meta: image.meta.clone(),
            maps: table,
            depth: None,
        },
        indices,
        width: w,
        height: h,
    }
}

/// A synthetic sky as both engines take it: its light weights on the basis per channel.
struct Environment {
    weights: [Vec<f64>; 3],
}

impl Environment {
    fn new(basis: &dyn Basis) -> anyhow::Result<Self> {
        let sky = EnvironmentLight::from_image(sky())?;
        Ok(Self {
            weights: sky.for_basis(basis)?.weights(
                basis,
                relit::basis::MAT3_IDENTITY,
                relit::envmap::Window::None,
            )?,
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

/// The area light of the `area` case: a 0.8 × 0.8 square at height 2 facing down,
/// above every surface point of the synthetic maps (depth ≤ 2.5 within ±38° of the
/// horizon), so that every pixel takes all its samples.
fn area_light() -> Light {
    Light::Area(relit::light::AreaLight {
        shape: relit::light::AreaShape::Rect {
            center: [0.1, 2.0, -0.2].into(),
            u: [0.4, 0.0, 0.0].into(),
            v: [0.0, 0.0, 0.4].into(),
        },
        color: [1.0, 0.9, 0.8],
        intensity: 2.0,
        two_sided: false,
        samples: 16,
    })
}

/// The projector of the `projector` case, prepared.
fn projector_light() -> PreparedLight {
    let (light, slide) = projector_parts();
    let rgb = Light::Projector(light.clone()).rgb();
    PreparedLight::Projector(Box::new(light.with_slide(slide)), rgb)
}

/// The projector of the `projector` case and its slide (a synthetic 128×64 pattern).
fn projector_parts() -> (relit::light::ProjectorLight, std::sync::Arc<ImageRgb>) {
    let light = relit::light::ProjectorLight {
        position: [0.2, 0.3, 0.1].into(),
        direction: [0.0, -0.2, -1.0].into(),
        up: [0.0, 1.0, 0.0].into(),
        fov_deg: 90.0,
        slide: "synthetic".into(),
        color: [1.0, 0.95, 0.9],
        intensity: 3.0,
        attenuation: Default::default(),
    };
    let (w, h) = (128, 64);
    let mut slide = ImageRgb::new(w, h);
    for (p, px) in slide.data.chunks_exact_mut(3).enumerate() {
        let (x, y) = ((p % w) as f32 / w as f32, (p / w) as f32 / h as f32);
        let check = ((p % w) / 16 + (p / w) / 16) % 2 == 0;
        px.copy_from_slice(&[x, y, if check { 1.0 } else { 0.2 }]);
    }
    (light, std::sync::Arc::new(slide))
}

/// The light vectors of non-zero weight one frame of `lights` evaluates the basis at:
/// every pixel's contributions by the lights' own per-pixel (f64) definition.
fn basis_evals(relighter: &Relighter, lights: &[PreparedLight]) -> u64 {
    let Ok(points) = relighter.surface_points() else {
        return 0;
    };
    points
        .par_iter()
        .enumerate()
        .map(|(p, s)| {
            let mut count = 0u64;
            if let Some(s) = s {
                for light in lights {
                    light.illuminate(*s, p, &mut |_, rgb| {
                        count += rgb.iter().any(|&c| c != 0.0) as u64
                    });
                }
            }
            count
        })
        .sum()
}

fn cpu_lights(case: &str, env: &Environment) -> anyhow::Result<Vec<PreparedLight>> {
    let lights = match case {
        "directional" => vec![directional_light()],
        "environment" => return Ok(vec![PreparedLight::Weights(env.weights.clone())]),
        "area" => vec![area_light()],
        "projector" => return Ok(vec![projector_light()]),
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
        "area" => gpu.lighting(&rig(area_light()), 0.0)?,
        "projector" => {
            let (light, slide) = projector_parts();
            let mut lighting = gpu.empty_lighting();
            lighting.add_projector(&light, slide, Light::Projector(light.clone()).rgb())?;
            lighting
        }
        _ => gpu.lighting(&rig(point_light()), 0.0)?,
    })
}

/// Seconds per frame of the fastest and the median of [`BATCHES`] batches.
struct Timing {
    best: f64,
    median: f64,
    frames: usize,
    batches: usize,
}

impl Timing {
    fn of(mut per_frame: Vec<f64>, frames: usize) -> Self {
        per_frame.sort_by(f64::total_cmp);
        Self {
            best: per_frame[0],
            median: per_frame[per_frame.len() / 2],
            frames,
            batches: per_frame.len(),
        }
    }
}

/// One warm-up frame, then [`BATCHES`] batches of frames filling `seconds` together
/// (at least one frame each), `between` run before each batch (not timed).
fn time_batches(
    seconds: f64,
    between: &mut dyn FnMut(),
    mut frame: impl FnMut() -> relit::Result<()>,
) -> anyhow::Result<Timing> {
    let t = Instant::now();
    frame()?;
    let warm = t.elapsed().as_secs_f64();
    let frames = ((seconds / BATCHES as f64 / warm.max(1e-6)) as usize).clamp(1, 100_000);
    let mut per_frame = Vec::with_capacity(BATCHES);
    for _ in 0..BATCHES {
        between();
        let t = Instant::now();
        for _ in 0..frames {
            frame()?;
        }
        per_frame.push(t.elapsed().as_secs_f64() / frames as f64);
    }
    Ok(Timing::of(per_frame, frames * BATCHES))
}

fn time_gpu(gpu: &GpuRelighter, lighting: &Lighting, seconds: f64) -> anyhow::Result<Timing> {
    time_gpu_frames(&|n| gpu.time_frames(lighting, None, n), seconds)
}

/// [`time_gpu`] for any engine's `time_frames(n)`.
fn time_gpu_frames(
    time_frames: &dyn Fn(usize) -> relit_gpu::Result<std::time::Duration>,
    seconds: f64,
) -> anyhow::Result<Timing> {
    // Warm up for a tenth of a second, doubling the frames per submission: the first
    // frame pays for buffers made on first use, one frame alone is mostly the
    // submission's round trip on a fast GPU, and on an H200 the first case after an
    // upload ran at a third of the later ones' rate until the device had run a while.
    let (mut spent, mut n, mut each) = (0.0, 1, 0.0);
    while spent < 0.1 && n <= 4096 {
        each = time_frames(n)?.as_secs_f64();
        spent += each * n as f64;
        n *= 2;
    }
    let frames = ((seconds / BATCHES as f64 / each.max(1e-6)) as usize).clamp(1, 100_000);
    let per_frame = (0..BATCHES)
        .map(|_| Ok(time_frames(frames)?.as_secs_f64()))
        .collect::<anyhow::Result<Vec<f64>>>()?;
    Ok(Timing::of(per_frame, frames * BATCHES))
}

/// Seconds per evaluation of the basis at every pixel's light vector (toward the
/// `point` case's light), as the engine evaluates it, and the number of timed passes:
/// rayon over chunks of 4096 pixels, each evaluated into a per-thread buffer (no
/// coefficient read, nothing written to memory beyond L2).
fn time_basis_eval(
    image: &RelightableImage,
    basis: &dyn Basis,
    seconds: f64,
) -> anyhow::Result<Timing> {
    const CHUNK: usize = 4096;
    let eval = BasisEvaluator::new(basis);
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
    time_batches(seconds, &mut || {}, || {
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

fn report(row: &Row, json: bool) {
    if !json {
        let evals = row
            .basis_evals_per_s
            .map(|e| format!("  {:>8.1} M basis evaluations/s", e / 1e6))
            .unwrap_or_default();
        eprintln!(
            "  {:<11} {:>4}  {:<3} {:>9.1} fps (median {:.1})  {:>8.1} Mpx/s{evals}",
            row.case,
            row.device,
            row.storage,
            row.fps,
            row.fps_median,
            row.pixels_per_s / 1e6,
        );
    }
}

fn print_summary(rows: &[Row]) {
    println!(
        "{:<11} {:>10} {:<12} {:<4} {:<4} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7} {:>8} {:>7}  engine",
        "case",
        "size",
        "basis",
        "stor",
        "dev",
        "fps",
        "median",
        "Mpx/s",
        "Meval/s",
        "ms/frame",
        "GB/s",
        "of bw",
        "of FMA"
    );
    let pct = |f: Option<f64>| {
        f.map(|f| format!("{:.1} %", f * 100.0))
            .unwrap_or_else(|| "-".into())
    };
    for r in rows {
        let gbs = if r.read_bandwidth_gbs.is_finite() {
            format!("{:.1}", r.read_bandwidth_gbs)
        } else {
            "-".into()
        };
        let evals = r
            .basis_evals_per_s
            .map(|e| format!("{:.1}", e / 1e6))
            .unwrap_or_else(|| "-".into());
        println!(
            "{:<11} {:>10} {:<12} {:<4} {:<4} {:>9.1} {:>9.1} {:>9.1} {:>9} {:>9.3} {:>7} {:>8} {:>7}  {}",
            r.case,
            format!("{}×{}", r.width, r.height),
            r.basis,
            r.storage,
            r.device,
            r.fps,
            r.fps_median,
            r.pixels_per_s / 1e6,
            evals,
            r.ms_per_frame,
            gbs,
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

    /// A tiny CPU run: every case and storage gets a row with the JSON fields the issue
    /// asks for, its bound and fractions filled in (no timing is asserted).
    #[test]
    fn a_tiny_run_reports_every_case_with_its_bounds() {
        let args = Args {
            quick: false,
            json: true,
            sizes: vec!["64x16".into()],
            ks: vec![4],
            bases: vec![],
            seconds: 0.01,
            gpu_storage: vec![],
            no_gpu: true,
            no_cpu: false,
            cases: vec![],
            cpu_storage: vec![],
            codebook: 16,
            write_maps: None,
            tile_from: None,
            write_capture: None,
            capture_from: None,
            load: vec![],
            fit: None,
            peer: None,
            peer_args: String::new(),
            fit_args: String::new(),
        };
        let rows = measure(args).unwrap().unwrap();
        // Three storages, the uniform cases again from a codebook, the basis alone.
        assert_eq!(rows.len(), CASES.len() * 3 + 2 + 1);
        for r in &rows {
            let json = serde_json::to_value(r).unwrap();
            for field in [
                "case",
                "width",
                "height",
                "k",
                "storage",
                "device",
                "fps",
                "bandwidth_fraction",
            ] {
                assert!(json.get(field).is_some(), "{field}");
            }
            assert!(r.fps > 0.0 && r.fps_median <= r.fps && r.batches == BATCHES);
            assert!(r.fma_peak_gs > 0.0);
            if r.storage == "vq" {
                assert!(uniform(r.case) && r.bandwidth_fraction.is_none());
                assert!(r.uncompressed_bound_fps.is_some_and(|f| f > 0.0));
                assert_eq!(r.map_bytes, 2 * 64 * 16);
            } else if r.case == "basis_eval" {
                assert!(r.bandwidth_fraction.is_none());
            } else {
                assert!(r.read_bandwidth_gbs > 0.0);
                assert!(r.bandwidth_fraction.is_some_and(|f| f > 0.0));
                assert_eq!(r.fma_fraction.is_some(), uniform(r.case));
                assert_eq!(r.basis_evals_per_s.is_some(), !uniform(r.case));
            }
        }
    }

    #[test]
    fn synthetic_maps_relight_on_the_cpu() {
        for name in ["sh:4", "hsh:9", "sg:9", "ptm:6", "rbf:9", "bilinear:9"] {
            let basis = bench_basis(name).unwrap();
            let image = synthetic_image(64, 16, basis.as_ref()).unwrap();
            let relighter = Relighter::new(&image).unwrap();
            let env = Environment::new(basis.as_ref()).unwrap();
            for case in CASES {
                let frame = relighter
                    .relight_prepared(&cpu_lights(case, &env).unwrap(), 0.0)
                    .unwrap();
                assert!(frame.data.iter().all(|v| v.is_finite()), "{name} {case}");
                assert!(frame.data.iter().any(|&v| v > 0.0), "{name} {case}");
            }
        }
    }
}
