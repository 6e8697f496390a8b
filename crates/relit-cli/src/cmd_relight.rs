//! `relit relight`: a fitted file under new lights, one image or an animated sequence.

use crate::shared::{refuse_overwriting_inputs, rig_inputs, Bars};
use anyhow::{bail, Context};
use relit::engine::lookup::LookupRelighter;
use relit::engine::{RelightOptions, Relighter, Roi};
use relit::fsutil::{Output, StagedFolder};
use relit::image::ImageRgb;
use relit::light::{parse_triple, Light, LightRig, RigFile};
use relit::maps::RelightableImage;
use relit::progress::Progress;
use relit::storage::{CompactPlanes, Precision};
use relit_gpu::{GpuOptions, GpuRelighter};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A relightable file: relit's EXR or .rlz, or the RTI tools' .ptm or .rti.
    pub file: PathBuf,
    /// What a `.ptm`/`.rti` file's values are: srgb (the formats' convention, the
    /// default) or linear (what relight-cli writes by default).
    #[arg(long, value_enum)]
    pub file_space: Option<crate::shared::SpaceArg>,
    /// A light: `dir:x,y,z` (toward the light; x right, y up, z toward the camera),
    /// `point:x,y,z` or `spot:px,py,pz/dx,dy,dz/cone_deg`. Repeatable; lights add up.
    #[arg(long = "light")]
    pub lights: Vec<String>,
    /// RGB colour of the light given at the same position (`--color 1,0.8,0.6`); white
    /// when absent. Repeatable.
    #[arg(long = "color")]
    pub colors: Vec<String>,
    /// A light-rig JSON file, or a keyframed animation (then give --frames and --out).
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Frames to render from an animated rig.
    #[arg(long)]
    pub frames: Option<usize>,
    /// Exposure in stops.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub exposure: f64,
    /// Output image: `.png`/`.jpg`/`.tif` (8-bit sRGB) or `.exr` (linear).
    #[arg(short, long, required_unless_present = "out")]
    pub output: Option<PathBuf>,
    /// Output folder of an animation's frames (`frame_0000.png`, …).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Frame file extension for --out: png or exr.
    #[arg(long, default_value = "png")]
    pub frame_format: String,
    /// Relight only the region `x,y,w,h` (pixels, top-left origin): the output image is
    /// that region alone (`w × h`), equal to the same crop of the full frame.
    #[arg(long)]
    pub roi: Option<String>,
    /// Relight mip level L of a tiled EXR or `.rlz` file with levels (`relit convert
    /// --mip-tiles`): level 0 is the image, each level half the one above (2×2 means);
    /// `--roi` is then in the level's pixels. Only the tiles the frame needs are read
    /// (directional and environment lights).
    #[arg(long)]
    pub level: Option<usize>,
    /// Relight on the GPU (wgpu compute shaders; any Vulkan/Metal/DX12 adapter,
    /// including Mesa's software lavapipe). Every light type runs in the shaders;
    /// environment weights are projected once by the CPU engine.
    #[arg(long)]
    pub gpu: bool,
    /// Precision of the planes the engine reads: f32 (the file's values, no copy), f16
    /// or u8 (per-plane scale and offset; a compact copy is made first).
    #[arg(long, default_value = "f32")]
    pub storage: Precision,
    /// Also relight on the CPU and print the largest absolute difference (with --gpu,
    /// or with --storage f16/u8 against the f32 maps).
    #[arg(long)]
    pub compare: bool,
    /// Print the process's peak memory and the bytes of maps + output image.
    #[arg(long)]
    pub memory: bool,
}

/// The engine that renders frames: the CPU relighter, or the GPU one.
enum Engine<'a> {
    Cpu(Relighter<'a>),
    Gpu {
        gpu: Box<GpuRelighter>,
        /// For environment weights (and --compare).
        cpu: Relighter<'a>,
    },
}

impl Engine<'_> {
    /// Bytes of the coefficient planes held on the host: the f32 maps (empty when the
    /// file was decoded straight into compact planes) and any compact copy.
    fn plane_bytes(&self, image: &RelightableImage) -> usize {
        let f32_maps = image.maps.bytes();
        match self {
            Engine::Cpu(r) if r.precision() != Precision::F32 => f32_maps + r.plane_bytes(),
            _ => f32_maps,
        }
    }

    fn render(
        &self,
        rig: &LightRig,
        options: &RelightOptions,
        roi: Roi,
    ) -> anyhow::Result<ImageRgb> {
        match self {
            Engine::Cpu(r) => Ok(r.relight_roi(rig, options, roi)?),
            Engine::Gpu { gpu, cpu } => {
                let lighting = gpu_lighting(rig, options, cpu, |rest| {
                    gpu.lighting_in(rest, options.exposure, &options.resource_dir)
                })?;
                let roi = relit_gpu::Roi {
                    x: roi.x,
                    y: roi.y,
                    width: roi.width,
                    height: roi.height,
                };
                Ok(gpu.render(&lighting, Some(roi))?)
            }
        }
    }
}

/// A GPU frame's lighting: `lights` builds the rig's lights other than environments,
/// which the CPU engine `cpu` prepares (their weights on linear maps, their median-cut
/// lights on display-referred ones), with the frame's exposure.
fn gpu_lighting(
    rig: &LightRig,
    options: &RelightOptions,
    cpu: &Relighter,
    lights: impl FnOnce(&LightRig) -> relit_gpu::Result<relit_gpu::Lighting>,
) -> anyhow::Result<relit_gpu::Lighting> {
    let (env, rest): (Vec<&Light>, Vec<&Light>) = rig
        .lights
        .iter()
        .partition(|l| matches!(l, Light::Environment(_)));
    let mut lighting = lights(&LightRig::new(rest.into_iter().cloned().collect()))?;
    let scale = 2f64.powf(options.exposure);
    for light in env {
        for prepared in cpu.prepare(light, options)? {
            lighting.add_prepared(cpu.basis(), &prepared, scale)?;
        }
    }
    Ok(lighting)
}

fn max_abs_difference(a: &ImageRgb, b: &ImageRgb) -> (f32, f32) {
    let diff = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y).abs())
        .fold(0f32, f32::max);
    let peak = b.data.iter().map(|v| v.abs()).fold(0f32, f32::max);
    (diff, peak)
}

fn build_engine<'a>(
    image: &'a RelightableImage,
    compact: Option<CompactPlanes>,
    args: &Args,
) -> anyhow::Result<Engine<'a>> {
    let storage = args.storage;
    if let Some(planes) = compact {
        return Ok(Engine::Cpu(Relighter::with_compact(image, planes)?));
    }
    if !args.gpu {
        return Ok(Engine::Cpu(Relighter::with_precision(image, storage)?));
    }
    let gpu = GpuRelighter::with_options(
        image,
        GpuOptions {
            precision: storage,
            ..Default::default()
        },
    )
    .context("--gpu")?;
    eprintln!("relit relight: GPU {} ({})", gpu.adapter(), storage.name());
    Ok(Engine::Gpu {
        gpu: Box::new(gpu),
        cpu: Relighter::new(image)?,
    })
}

/// A codebook file under lights that are the same for every pixel, one frame: relight
/// the codebook once and look every pixel up, without expanding the maps, on the CPU
/// (`relit::engine::lookup`, whole frames) or with `--gpu` on the GPU
/// (`relit_gpu::GpuLookup`, whole frames or `--roi`; `--compare` checks it against the
/// CPU's look-up). `None` when the file or the request is not that.
fn relight_codebook(
    args: &Args,
    rig_file: Option<&RigFile>,
    extra: &[Light],
    options: &RelightOptions,
) -> anyhow::Result<Option<()>> {
    let Some(rig) = single_frame(rig_file, extra) else {
        return Ok(None);
    };
    let plain = !args.gpu && !args.compare && args.roi.is_none() && !args.memory;
    let on_gpu = args.gpu && !args.memory && args.file_space.is_none();
    if !(plain || on_gpu)
        || rig.lights.is_empty()
        || !LookupRelighter::draws(&rig)
        || relit::codec::FileForm::of(&args.file)? != relit::codec::FileForm::Compressed
    {
        return Ok(None);
    }
    // The header tells a codebook file; a file of planes is read by the caller (whole,
    // or the tiles of a region or level).
    if !relit::codec::packed::read_header(&args.file)?.indexed_pixels() {
        return Ok(None);
    }
    let packed = relit::codec::packed::read_packed(&args.file)?;
    let Some(output) = args.output.as_ref() else {
        return Ok(None);
    };
    let indexed = relit::compress::indexed(&packed)?;
    let entries = indexed.entries.maps.pixels();
    if !on_gpu {
        let start = std::time::Instant::now();
        let frame = LookupRelighter::new(&indexed)?.relight(&rig, options)?;
        let seconds = start.elapsed().as_secs_f64();
        let how = format!(" from a codebook of {entries} entries");
        save_frame(output, &frame, &rig, seconds, &how)?;
        return Ok(Some(()));
    }
    let gpu = relit_gpu::GpuLookup::new(
        &indexed,
        GpuOptions {
            precision: args.storage,
            ..Default::default()
        },
    )
    .context("--gpu")?;
    eprintln!(
        "relit relight: GPU {} ({}), codebook of {entries} entries, {} indices",
        gpu.entries().adapter(),
        args.storage.name(),
        indexed.indices.len()
    );
    let start = std::time::Instant::now();
    let cpu = Relighter::new(&indexed.entries)?;
    let lighting = gpu_lighting(&rig, options, &cpu, |rest| {
        gpu.lighting(rest, options.exposure)
    })?;
    let roi = args.roi.as_deref().map(Roi::parse).transpose()?;
    let frame = gpu.render(
        &lighting,
        roi.map(|r| relit_gpu::Roi {
            x: r.x,
            y: r.y,
            width: r.width,
            height: r.height,
        }),
    )?;
    let seconds = start.elapsed().as_secs_f64();
    if args.compare {
        let cpu = LookupRelighter::new(&indexed)?.relight(&rig, options)?;
        let cpu = match roi {
            Some(r) => r.crop(&cpu),
            None => cpu,
        };
        let (diff, peak) = max_abs_difference(&frame, &cpu);
        println!(
            "compare: largest |GPU − CPU| {diff:.3e} (peak {peak:.3e}, {:.2e} of it), codebook look-up",
            diff / peak.max(f32::MIN_POSITIVE)
        );
    }
    let how = format!(" on the GPU from a codebook of {entries} entries");
    save_frame(output, &frame, &rig, seconds, &how)?;
    Ok(Some(()))
}

/// The one frame's lights (`--light` flags and a rig file's), or `None` for an animation.
fn single_frame(rig_file: Option<&RigFile>, extra: &[Light]) -> Option<LightRig> {
    let mut lights = extra.to_vec();
    match rig_file {
        Some(RigFile::Rig(rig)) => lights.extend(rig.lights.iter().cloned()),
        Some(RigFile::Animation(_)) => return None,
        None => {}
    }
    Some(LightRig::new(lights))
}

/// Write the frame and say so (`how` it was drawn, after the time).
fn save_frame(
    output: &Path,
    frame: &ImageRgb,
    rig: &LightRig,
    seconds: f64,
    how: &str,
) -> anyhow::Result<()> {
    relit::image::save(output, frame, 0.0)
        .with_context(|| format!("writing {}", output.display()))?;
    println!(
        "wrote {} ({}×{}, {} light{}, relit in {:.1} ms{how})",
        output.display(),
        frame.width,
        frame.height,
        rig.lights.len(),
        if rig.lights.len() == 1 { "" } else { "s" },
        seconds * 1e3
    );
    Ok(())
}

fn flag_lights(args: &Args) -> anyhow::Result<Vec<Light>> {
    if args.colors.len() > args.lights.len() {
        bail!(
            "{} --color given for {} --light",
            args.colors.len(),
            args.lights.len()
        );
    }
    let mut lights = Vec::new();
    for (i, spec) in args.lights.iter().enumerate() {
        let mut light = Light::parse_spec(spec)?;
        if let Some(color) = args.colors.get(i) {
            let rgb =
                parse_triple(color).map_err(|e| anyhow::anyhow!("bad --color `{color}`: {e}"))?;
            light.set_color(rgb);
        }
        lights.push(light);
    }
    Ok(lights)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let extra = flag_lights(&args)?;
    let resource_dir = args
        .rig
        .as_deref()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let rig_file = args.rig.as_deref().map(RigFile::load).transpose()?;
    let animated = matches!(rig_file, Some(RigFile::Animation(_)));
    let outputs: Vec<Output> = if animated {
        args.out.iter().map(Output::folder).collect()
    } else {
        args.output.iter().map(Output::file).collect()
    };
    let mut inputs = vec![args.file.clone()];
    inputs.extend(args.rig.as_deref().map(rig_inputs).unwrap_or_default());
    refuse_overwriting_inputs(&inputs, &outputs)?;
    let options = RelightOptions {
        exposure: args.exposure,
        resource_dir,
    };
    // Compact CPU planes are decoded straight from the file, so the f32 maps are never
    // held (--compare and --gpu need them).
    let storage = args.storage;
    if let Some(result) = relight_codebook(&args, rig_file.as_ref(), &extra, &options)? {
        return Ok(result);
    }
    let requested = args.roi.as_deref().map(Roi::parse).transpose()?;
    // A relit EXR reads a region of its blocks, a compressed file of its tiles: of any
    // mip level of a file with levels, of level 0 of any other.
    let form = relit::codec::FileForm::of(&args.file)?;
    let tiled = match form {
        relit::codec::FileForm::Exr => Some(relit::codec::exr::levels(&args.file)?),
        relit::codec::FileForm::Compressed => {
            Some(relit::codec::packed::read_header(&args.file)?.level_sizes())
        }
        _ => None,
    };
    // One frame of lights that are the same at every pixel: what region reads serve.
    let uniform = single_frame(rig_file.as_ref(), &extra)
        .is_some_and(|rig| !rig.lights.is_empty() && LookupRelighter::draws(&rig));
    if args.level.is_some() {
        anyhow::ensure!(
            tiled.as_ref().is_some_and(|sizes| sizes.len() > 1),
            "--level needs a file with mip levels (relit convert X -o Y.exr --mip-tiles, or \
             -o Y.rlz --mip-tiles)"
        );
        anyhow::ensure!(
            uniform && args.file_space.is_none(),
            "--level relights one frame of directional and environment lights"
        );
    }
    let (region, region_bytes) = match (requested, &tiled) {
        (roi, Some(sizes))
            if uniform && args.file_space.is_none() && (roi.is_some() || args.level.is_some()) =>
        {
            let level = args.level.unwrap_or(0);
            let &(lw, lh) = sizes.get(level).with_context(|| {
                format!("--level: the file has levels 0 to {}", sizes.len() - 1)
            })?;
            let rect = roi.map_or((0, 0, lw, lh), |r| (r.x, r.y, r.width, r.height));
            let (image, read, total) = if form == relit::codec::FileForm::Exr {
                let read = relit::codec::exr::read_region(&args.file, level, rect);
                read.map(|r| (r.image, r.bytes_read, r.file_bytes))
            } else {
                relit::codec::packed::read_level_region(&args.file, level, rect, false)
            }
            .context("--roi")?;
            (Some(image), Some((read, total)))
        }
        _ => (None, None),
    };
    let (mut image, compact) = if let Some(image) = region {
        (image, None)
    } else if storage != Precision::F32 && !args.gpu && !args.compare {
        let (image, planes) = relit::codec::read_compact(&args.file, storage)?;
        (image, Some(planes))
    } else {
        (relit::codec::read(&args.file)?, None)
    };
    crate::shared::apply_file_space(&args.file, &mut image, args.file_space)?;
    let roi = match requested {
        // The region read is the whole image now.
        _ if region_bytes.is_some() => Roi::full(image.width(), image.height()),
        Some(roi) => {
            roi.validate(image.width(), image.height())
                .context("--roi")?;
            roi
        }
        None => Roi::full(image.width(), image.height()),
    };
    if let Some((read, total)) = region_bytes {
        println!(
            "read {read} of {} bytes of {} ({:.1} %): the tiles of the region only",
            total,
            args.file.display(),
            100.0 * read as f64 / total.max(1) as f64
        );
    }
    let relighter = build_engine(&image, compact, &args)?;

    if let Some(RigFile::Animation(anim)) = &rig_file {
        let frames = args.frames.context("an animated rig needs --frames N")?;
        anyhow::ensure!(frames >= 1, "--frames must be at least 1");
        let out = args
            .out
            .as_ref()
            .context("an animated rig needs --out FOLDER")?;
        anyhow::ensure!(
            args.frame_format == "png" || args.frame_format == "exr",
            "--frame-format is png or exr"
        );
        let rigs = anim.frames(frames)?;
        let staged = StagedFolder::new(out)?;
        let bars = Bars::new(false);
        bars.begin("relighting frames", frames as u64);
        let start = std::time::Instant::now();
        for (f, mut rig) in rigs.into_iter().enumerate() {
            rig.lights.extend(extra.iter().cloned());
            let frame = relighter.render(&rig, &options, roi)?;
            let name = format!("frame_{f:04}.{}", args.frame_format);
            relit::image::save(&staged.file(&name)?, &frame, 0.0)
                .with_context(|| format!("writing {}", out.join(&name).display()))?;
            bars.advance(1);
        }
        bars.end();
        staged.commit()?;
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "wrote {frames} frames to {} in {seconds:.2} s ({:.1} ms per frame, writing included)",
            out.display(),
            1e3 * seconds / frames as f64
        );
        return Ok(());
    }

    let mut lights = extra;
    if let Some(RigFile::Rig(rig)) = rig_file {
        lights.extend(rig.lights);
    }
    if lights.is_empty() {
        bail!("no lights: give --light dir:x,y,z (repeatable) or --rig RIG.json");
    }
    let output = args
        .output
        .as_ref()
        .context("give -o OUTPUT (or --out FOLDER with an animated --rig)")?;
    let rig = LightRig::new(lights);
    let start = std::time::Instant::now();
    let frame = relighter.render(&rig, &options, roi)?;
    let seconds = start.elapsed().as_secs_f64();
    if args.compare {
        let reference = Relighter::new(&image)?.relight_roi(&rig, &options, roi)?;
        let (diff, peak) = max_abs_difference(&frame, &reference);
        println!(
            "largest absolute difference from the CPU engine on f32 maps: {diff:.3e} (peak {peak:.3e}, {:.2e} of it)",
            diff / peak.max(f32::MIN_POSITIVE)
        );
    }
    save_frame(output, &frame, &rig, seconds, "")?;
    if args.memory {
        let maps = relighter.plane_bytes(&image) as u64;
        let out = (frame.data.len() * 4) as u64;
        let peak = relit::memory::peak_rss_bytes().unwrap_or(0);
        println!(
            "peak memory {} for {} of maps + {} of output ({:.3}×)",
            relit::memory::mib(peak),
            relit::memory::mib(maps),
            relit::memory::mib(out),
            peak as f64 / (maps + out) as f64
        );
    }
    Ok(())
}
