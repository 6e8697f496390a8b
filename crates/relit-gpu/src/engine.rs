//! [`GpuRelighter`]: coefficient maps resident on a GPU, relit by a compute shader.
//!
//! The maps are cut into *slabs* of whole rows so that no buffer exceeds the adapter's
//! binding limit; each slab holds its `3k` planes (padded to a common stride) in the
//! chosen [`Precision`], and, when the file has depth, the surface point of every pixel
//! (computed once from camera and depth, as the CPU engine does). A frame is one
//! dispatch per slab that meets the region of interest, each writing its rows of the
//! region into its own output buffer; a readback copies them, in order, into one
//! staging buffer, which is the region's interleaved RGB image. Projector slides live
//! in one more buffer, rewritten only when a frame's slides change.
//!
//! The shader knows no basis. Uniform lights arrive as weights computed here per frame
//! ([`Basis::values`] for a directional light; an environment's weights from the
//! library); lights with a position read the basis' [`WeightTable`] in half floats (as
//! the CPU engine and the viewer hold it), uploaded once with the maps as a storage
//! buffer (four weights a 64-bit load) and blended by hand: float textures are not
//! filterable everywhere, and a hand blend is exactly `WeightTable::sample`'s.

use crate::error::{invalid, GpuError, Result};
use crate::lighting::{Lighting, MAX_K};
use crate::roi::Roi;
use crate::storage::{encode, shader_fetch, STRIDE_ALIGN};
use bytemuck::{Pod, Zeroable};
use relit::basis::{Basis, TableAccuracy, WeightTable};
use relit::camera::Camera;
use relit::image::ImageRgb;
use relit::light::{Light, LightRig, PreparedLight};
use relit::maps::{MapSpace, RelightableImage};
use relit::storage::{PlaneCoding, Precision};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};
use wgpu::util::DeviceExt;

mod lookup;
mod read_probe;

pub use lookup::GpuLookup;

/// Invocations per workgroup (`@workgroup_size` in relight.wgsl).
const WORKGROUP: u64 = 256;
/// The largest buffer a slab uses unless the adapter allows less: large enough that
/// a frame is a handful of dispatches, small enough for any desktop GPU's allocator.
const DEFAULT_SLAB_BYTES: u64 = 1 << 30;
/// Bytes per pixel of a slab's surface points (`vec4<f32>`: xyz, w = 1 where hit).
const POSITION_BYTES: u64 = 16;
/// Bytes per pixel of the output (RGB `f32`).
const OUT_BYTES: u64 = 12;

/// How a [`GpuRelighter`] stores its maps.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuOptions {
    /// The precision of the planes on the GPU.
    pub precision: Precision,
    /// Cap on the bytes of one slab buffer (the adapter's limit applies anyway); small
    /// values force many slabs, which tests use.
    pub max_slab_bytes: Option<u64>,
}

/// What the GPU engine runs on, for reports.
#[derive(Clone, Debug)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
    pub driver: String,
}

impl std::fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({}, {}", self.name, self.backend, self.device_type)?;
        if !self.driver.is_empty() {
            write!(f, ", {}", self.driver)?;
        }
        write!(f, ")")
    }
}

impl From<&wgpu::AdapterInfo> for AdapterSummary {
    fn from(info: &wgpu::AdapterInfo) -> Self {
        Self {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: [info.driver.as_str(), info.driver_info.as_str()]
                .iter()
                .filter(|s| !s.is_empty())
                .copied()
                .collect::<Vec<_>>()
                .join(" "),
        }
    }
}

/// `Setup` in relight.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct SetupGpu {
    dims: [u32; 4],
    scale: [[f32; 4]; MAX_K],
    offset: [[f32; 4]; MAX_K],
}

/// Whole rows of the maps on the GPU.
struct Slab {
    row0: usize,
    rows: usize,
    /// Pixels between consecutive planes (`rows · width` rounded up to [`STRIDE_ALIGN`]).
    stride: usize,
    planes: wgpu::Buffer,
    positions: Option<wgpu::Buffer>,
}

/// One slab's share of a region: its dispatch and output.
struct Part {
    bind: wgpu::BindGroup,
    out: wgpu::Buffer,
    groups: [u32; 2],
    bytes: u64,
    offset: u64,
}

/// Everything a region needs per frame, kept while the region stays the same.
struct Target {
    roi: Roi,
    /// The [`SlideStore::generation`] its bind groups were made with.
    slides: u64,
    parts: Vec<Part>,
    staging: wgpu::Buffer,
}

/// The projector slides on the GPU: the buffer, what it holds, in order.
struct SlideStore {
    buffer: wgpu::Buffer,
    capacity: u64,
    held: Vec<Arc<ImageRgb>>,
    /// Bumped whenever `buffer` is replaced (bind groups refer to it).
    generation: u64,
}

/// Coefficient maps on a GPU, relit by a compute shader (see the module docs).
pub struct GpuRelighter {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: AdapterSummary,
    errors: Arc<Mutex<Vec<String>>>,
    pipeline: wgpu::ComputePipeline,
    /// The pipeline for frames without projector or area lights.
    basic_pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    setup: wgpu::Buffer,
    frame: wgpu::Buffer,
    no_positions: wgpu::Buffer,
    slabs: Vec<Slab>,
    /// The basis' weight table in half floats, for lights with a position.
    table: wgpu::Buffer,
    table_accuracy: TableAccuracy,
    width: usize,
    height: usize,
    basis: Box<dyn Basis>,
    display: bool,
    precision: Precision,
    coding: Vec<PlaneCoding>,
    /// Why positional lights cannot be used (no depth, bad camera), if so.
    no_positions_reason: Option<String>,
    max_groups: u32,
    max_buffer: u64,
    max_binding: u64,
    resident_bytes: u64,
    target: Mutex<Option<Target>>,
    slides: Mutex<SlideStore>,
    /// Slides loaded from files, by path.
    slide_files: Mutex<HashMap<PathBuf, Arc<ImageRgb>>>,
}

/// The adapter relit would use, without opening a device: `Err(NoAdapter)` tells a
/// caller (a test, the benchmark) to skip GPU work, with the reason.
pub fn probe() -> Result<AdapterSummary> {
    let adapter = request_adapter(instance())?;
    Ok(AdapterSummary::from(&adapter.get_info()))
}

/// Every adapter wgpu finds on this machine, on any backend (what `probe` chooses from).
pub fn adapters() -> Vec<AdapterSummary> {
    pollster::block_on(instance().enumerate_adapters(wgpu::Backends::all()))
        .iter()
        .map(|a| AdapterSummary::from(&a.get_info()))
        .collect()
}

/// The process' one wgpu instance. A new instance per engine made NVIDIA's Vulkan
/// driver (580, an H200) refuse the 25th in one process ("vulkan drivers/libraries
/// could not be loaded"); engines and probes now share this one.
fn instance() -> &'static wgpu::Instance {
    static INSTANCE: std::sync::OnceLock<wgpu::Instance> = std::sync::OnceLock::new();
    INSTANCE.get_or_init(|| {
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env())
    })
}

fn request_adapter(instance: &wgpu::Instance) -> Result<wgpu::Adapter> {
    let options = wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: None,
        ..Default::default()
    };
    pollster::block_on(instance.request_adapter(&options)).map_err(|e| {
        GpuError::NoAdapter(format!(
            "{e} (install a Vulkan, Metal or DX12 driver; on Debian `mesa-vulkan-drivers` gives a software one)"
        ))
    })
}

impl GpuRelighter {
    /// Upload `image` with `f32` planes.
    pub fn new(image: &RelightableImage) -> Result<Self> {
        Self::with_options(image, GpuOptions::default())
    }

    /// Upload `image` with `options`, in the basis its metadata names.
    pub fn with_options(image: &RelightableImage, options: GpuOptions) -> Result<Self> {
        let basis = image.meta.basis.build()?;
        Self::with_basis(image, basis, options)
    }

    /// Upload `image` with `options`, relighting it in `basis` instead of the one its
    /// metadata names: maps of a basis no family rebuilds (tests, experiments).
    pub fn with_basis(
        image: &RelightableImage,
        basis: Box<dyn Basis>,
        options: GpuOptions,
    ) -> Result<Self> {
        let (width, height, k) = (image.maps.width, image.maps.height, image.maps.k);
        if basis.len() != k {
            return Err(invalid(format!(
                "the maps hold {k} coefficients but the basis {} has {}",
                basis.name(),
                basis.len()
            )));
        }
        if k > MAX_K {
            return Err(GpuError::Unsupported(format!(
                "{k} coefficients per channel (the GPU engine relights at most {MAX_K})"
            )));
        }
        if width == 0 || height == 0 || image.maps.data.len() != 3 * k * width * height {
            return Err(invalid(format!(
                "{width}×{height} maps of {k} coefficients need {} values, got {}",
                3 * k * width * height,
                image.maps.data.len()
            )));
        }
        let (camera, no_positions_reason) = match positions_source(image) {
            Ok(c) => (Some(c), None),
            Err(why) => (None, Some(why)),
        };

        let adapter = request_adapter(instance())?;
        let summary = AdapterSummary::from(&adapter.get_info());
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("relit"),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device(format!("{summary}: {e}")))?;
        let errors: Arc<Mutex<Vec<String>>> = Arc::default();
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            sink.lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(e.to_string());
        }));

        let precision = options.precision;
        let bpv = precision.bytes_per_value() as u64;
        let limit = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size)
            .min(options.max_slab_bytes.unwrap_or(DEFAULT_SLAB_BYTES))
            .min(u32::MAX as u64);
        let plane_bytes = |rows: usize| {
            let stride = (rows * width).div_ceil(STRIDE_ALIGN) * STRIDE_ALIGN;
            3 * k as u64 * stride as u64 * bpv
        };
        let per_pixel = (3 * k as u64 * bpv).max(POSITION_BYTES).max(OUT_BYTES);
        let mut rows_per_slab = ((limit / (per_pixel * width as u64)) as usize).min(height);
        while rows_per_slab > 0 && plane_bytes(rows_per_slab) > limit {
            rows_per_slab -= 1;
        }
        if rows_per_slab == 0 {
            return Err(GpuError::TooLarge(format!(
                "one row of {width} pixels × {k} coefficients needs more than the {limit}-byte buffer limit of {summary}"
            )));
        }

        let coding = precision.codings(&image.maps);
        let mut slabs = Vec::new();
        let mut resident_bytes = 0;
        let mut scratch = Vec::new();
        let n = width * height;
        for row0 in (0..height).step_by(rows_per_slab) {
            let rows = rows_per_slab.min(height - row0);
            let stride = (rows * width).div_ceil(STRIDE_ALIGN) * STRIDE_ALIGN;
            let size = plane_bytes(rows);
            let planes = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("relit planes"),
                size,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: true,
            });
            {
                let mut view = planes
                    .slice(..)
                    .get_mapped_range_mut()
                    .map_err(|e| GpuError::Device(e.to_string()))?;
                for (j, &plane_coding) in coding.iter().enumerate() {
                    let src = &image.maps.data[j * n + row0 * width..j * n + (row0 + rows) * width];
                    scratch.clear();
                    encode(precision, src, plane_coding, &mut scratch);
                    let at = j * stride * bpv as usize;
                    view.slice(at..at + scratch.len()).copy_from_slice(&scratch);
                }
            }
            planes.unmap();
            resident_bytes += size;
            let positions = match (&camera, &image.depth) {
                (Some(camera), Some(depth)) => {
                    let mut points = vec![[0f32; 4]; rows * width];
                    for (q, point) in points.iter_mut().enumerate() {
                        let (x, y) = (q % width, row0 + q / width);
                        let d = depth[y * width + x];
                        if d.is_finite() && d > 0.0 {
                            let p = camera.position(x, y, d as f64);
                            *point = [p.x as f32, p.y as f32, p.z as f32, 1.0];
                        }
                    }
                    resident_bytes += (points.len() * 16) as u64;
                    Some(
                        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                            label: Some("relit surface points"),
                            contents: bytemuck::cast_slice(&points),
                            usage: wgpu::BufferUsages::STORAGE,
                        }),
                    )
                }
                _ => None,
            };
            slabs.push(Slab {
                row0,
                rows,
                stride,
                planes,
                positions,
            });
        }

        let (table, _) = WeightTable::for_basis(basis.as_ref());
        // Half floats, as the shader reads them and as the CPU table kernel and the
        // viewer use them: every back end relights with the same weights. Half the
        // bytes are also faster (lavapipe, 1024×256, k = 25: 95 ms of CPU per point-light
        // frame against 106 with the table in f32, `examples/frame_cpu.rs`).
        let table = table.rounded_to_half();
        let table_accuracy = table.accuracy(basis.as_ref());
        let table_bytes = (table.values.len() / k.max(1) * k.div_ceil(4) * 8) as u64;
        let binding_limit = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if table_bytes > binding_limit {
            return Err(GpuError::TooLarge(format!(
                "the weight table of {} ({} cells a side, {table_bytes} bytes) exceeds the {binding_limit}-byte buffer limit of {summary}",
                basis.name(),
                table.resolution
            )));
        }
        let table_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("relit weight table"),
            contents: bytemuck::cast_slice(&table_groups(&table)),
            usage: wgpu::BufferUsages::STORAGE,
        });
        resident_bytes += table_buffer.size();

        let mut setup = SetupGpu::zeroed();
        let display = image.meta.color_space == MapSpace::Srgb;
        setup.dims = [
            width as u32,
            k as u32,
            table.resolution as u32,
            display as u32,
        ];
        for i in 0..k {
            for c in 0..3 {
                setup.scale[i][c] = coding[3 * i + c].scale;
                setup.offset[i][c] = coding[3 * i + c].offset;
            }
        }
        let setup = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("relit setup"),
            contents: bytemuck::bytes_of(&setup),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relit frame"),
            size: std::mem::size_of::<crate::lighting::FrameGpu>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let no_positions = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relit no surface points"),
            size: POSITION_BYTES,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let module = |extra: bool| {
            let source = format!(
                "const EXTRA_LIGHTS: bool = {extra};\n{}\n{}",
                shader_fetch(precision),
                include_str!("../shaders/relight.wgsl")
            );
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("relit relight"),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
        };
        // One explicit layout (bindings of relight.wgsl and fetch_*.wgsl) for both
        // pipelines, so that one bind group serves either.
        let entry = buffer_entry;
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relit relight"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Uniform),
                entry(1, wgpu::BufferBindingType::Uniform),
                entry(2, read),
                entry(3, read),
                entry(4, read),
                entry(5, wgpu::BufferBindingType::Storage { read_only: false }),
                entry(6, read),
                entry(7, read),
            ],
        });
        let shared = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("relit relight"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("relit relight"),
            layout: Some(&shared),
            module: &module(true),
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let basic_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("relit relight, no projector or area lights"),
            layout: Some(&shared),
            module: &module(false),
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let slides = SlideStore {
            buffer: slide_buffer(&device, 16),
            capacity: 16,
            held: Vec::new(),
            generation: 0,
        };
        let engine = Self {
            device,
            queue,
            adapter: summary,
            errors,
            pipeline,
            basic_pipeline,
            layout,
            setup,
            frame,
            no_positions,
            slabs,
            table: table_buffer,
            table_accuracy,
            width,
            height,
            basis,
            display,
            precision,
            coding,
            no_positions_reason,
            max_groups: limits.max_compute_workgroups_per_dimension.max(1),
            max_buffer: limits.max_buffer_size,
            max_binding: limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size),
            resident_bytes,
            target: Mutex::new(None),
            slides: Mutex::new(slides),
            slide_files: Mutex::default(),
        };
        engine.wait()?;
        engine.check_errors()?;
        Ok(engine)
    }

    /// The adapter in use.
    pub fn adapter(&self) -> &AdapterSummary {
        &self.adapter
    }

    /// The precision of the planes.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// Bytes resident on the GPU for the maps, the surface points and the weight table.
    pub fn resident_bytes(&self) -> u64 {
        self.resident_bytes
    }

    /// Slabs the maps were cut into.
    pub fn slab_count(&self) -> usize {
        self.slabs.len()
    }

    /// The basis the maps are relit in.
    pub fn basis(&self) -> &dyn Basis {
        self.basis.as_ref()
    }

    /// How closely the weight table that lights with a position read reproduces the
    /// basis (`WeightTable::for_basis`, in half floats: its resolution and measured
    /// error).
    pub fn table_accuracy(&self) -> TableAccuracy {
        self.table_accuracy
    }

    /// An empty lighting for this engine, to which uniform lights (environment
    /// weights) can be added with [`Lighting::add_uniform`].
    pub fn empty_lighting(&self) -> Lighting {
        Lighting::new(self.basis.len(), self.display)
    }

    /// The lighting of `rig` at `exposure` stops, projector slides relative to the
    /// working directory ([`GpuRelighter::lighting_in`]).
    pub fn lighting(&self, rig: &LightRig, exposure: f64) -> Result<Lighting> {
        self.lighting_in(rig, exposure, Path::new(""))
    }

    /// The lighting of `rig` at `exposure` stops, projector slides relative to
    /// `resource_dir` (as `RelightOptions::resource_dir`; each file is loaded once).
    /// The GPU relights directional, point, spot, projector and area lights;
    /// environment lights are [`GpuError::Unsupported`] here (add their weights with
    /// [`Lighting::add_uniform`]).
    pub fn lighting_in(
        &self,
        rig: &LightRig,
        exposure: f64,
        resource_dir: &Path,
    ) -> Result<Lighting> {
        if !exposure.is_finite() {
            return Err(invalid("the exposure must be finite"));
        }
        let scale = 2f64.powf(exposure);
        let mut lighting = self.empty_lighting();
        for (i, light) in rig.lights.iter().enumerate() {
            match light {
                Light::Directional(_) | Light::Point(_) | Light::Spot(_) | Light::Area(_) => {}
                Light::Projector(p) => {
                    light
                        .validate()
                        .map_err(|e| invalid(format!("lights[{i}] (projector): {e}")))?;
                    let slide = self.slide_file(&resource_dir.join(&p.slide)).map_err(|e| {
                        invalid(format!("lights[{i}] (projector): slide {}: {e}", p.slide))
                    })?;
                    lighting.add_projector(p, slide, light.rgb().map(|v| v * scale))?;
                    continue;
                }
                other => {
                    return Err(GpuError::Unsupported(format!(
                        "lights[{i}] is a {} light; the GPU engine relights directional, point, spot, projector and area lights",
                        other.kind()
                    )))
                }
            }
            let prepared = light
                .prepare(Path::new(""))
                .map_err(|e| invalid(format!("lights[{i}] ({}): {e}", light.kind())))?;
            self.add_prepared(&mut lighting, &prepared, scale)?;
        }
        Ok(lighting)
    }

    /// Add a light prepared by the CPU engine ([`relit::engine::Relighter::prepare`],
    /// which loads environments: their weights on linear maps, their median-cut lights
    /// on display-referred ones) to `lighting`, its colour times `scale`.
    pub fn add_prepared(
        &self,
        lighting: &mut Lighting,
        light: &PreparedLight,
        scale: f64,
    ) -> Result<()> {
        lighting.add_prepared(self.basis.as_ref(), light, scale)
    }

    /// A slide file, linearised (as `ProjectorLight::prepare` loads it), cached.
    fn slide_file(&self, path: &Path) -> std::result::Result<Arc<ImageRgb>, String> {
        let mut cache = self.slide_files.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(s) = cache.get(path) {
            return Ok(s.clone());
        }
        let slide = Arc::new(relit::image::load_linear(path, None).map_err(|e| e.to_string())?);
        cache.insert(path.to_path_buf(), slide.clone());
        Ok(slide)
    }

    /// Relight the whole image with `rig`.
    pub fn relight(&self, rig: &LightRig, exposure: f64) -> Result<ImageRgb> {
        self.render(&self.lighting(rig, exposure)?, None)
    }

    /// Relight only `roi`: the result is `roi.width × roi.height`.
    pub fn relight_roi(&self, rig: &LightRig, exposure: f64, roi: Roi) -> Result<ImageRgb> {
        self.render(&self.lighting(rig, exposure)?, Some(roi))
    }

    /// Render `lighting` over `roi` (the whole image when `None`) and read it back.
    pub fn render(&self, lighting: &Lighting, roi: Option<Roi>) -> Result<ImageRgb> {
        let roi = self.upload(lighting, roi)?;
        let mut guard = self.target.lock().unwrap_or_else(|p| p.into_inner());
        let target = self.target_for(&mut guard, roi)?;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.encode(&mut encoder, target, lighting.has_projectors_or_areas());
        for part in &target.parts {
            encoder.copy_buffer_to_buffer(&part.out, 0, &target.staging, part.offset, part.bytes);
        }
        self.queue.submit([encoder.finish()]);
        let image = self.read_back(&target.staging, roi)?;
        self.check_errors()?;
        Ok(image)
    }

    /// Wait for the submitted work and copy `staging` (the region's RGB `f32`, mapped
    /// for reading) into an image.
    fn read_back(&self, staging: &wgpu::Buffer, roi: Roi) -> Result<ImageRgb> {
        let slice = staging.slice(..);
        let (tx, rx) = mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        rx.recv()
            .map_err(|_| GpuError::Device("the readback was dropped".into()))?
            .map_err(|e| GpuError::Device(format!("readback: {e}")))?;
        let mut image = ImageRgb::new(roi.width, roi.height);
        {
            let view = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Device(format!("readback: {e}")))?;
            bytemuck::cast_slice_mut::<f32, u8>(&mut image.data).copy_from_slice(&view);
        }
        staging.unmap();
        Ok(image)
    }

    /// Run `frames` frames of `lighting` over `roi` without reading them back and return
    /// the mean wall time per frame (after one warm-up frame), for benchmarks.
    pub fn time_frames(
        &self,
        lighting: &Lighting,
        roi: Option<Roi>,
        frames: usize,
    ) -> Result<Duration> {
        let roi = self.upload(lighting, roi)?;
        let mut guard = self.target.lock().unwrap_or_else(|p| p.into_inner());
        let target = self.target_for(&mut guard, roi)?;
        let extra = lighting.has_projectors_or_areas();
        let frame = |engine: &Self| {
            let mut encoder = engine.device.create_command_encoder(&Default::default());
            engine.encode(&mut encoder, target, extra);
            engine.queue.submit([encoder.finish()]);
        };
        frame(self);
        self.wait()?;
        let start = Instant::now();
        for _ in 0..frames {
            frame(self);
        }
        self.wait()?;
        let elapsed = start.elapsed();
        self.check_errors()?;
        Ok(elapsed / frames.max(1) as u32)
    }

    /// Check `lighting` and `roi` against this engine and write the frame's lights.
    fn upload(&self, lighting: &Lighting, roi: Option<Roi>) -> Result<Roi> {
        let roi = roi.unwrap_or(Roi::full(self.width, self.height));
        roi.validate(self.width, self.height)?;
        if lighting.k() != self.basis.len() || lighting.display() != self.display {
            return Err(invalid("the lighting was built for other maps"));
        }
        if lighting.has_positional() {
            if let Some(why) = &self.no_positions_reason {
                return Err(invalid(why.clone()));
            }
        }
        let frame = lighting.to_gpu(&self.coding)?;
        let wanted = lighting.slides();
        let mut store = self.slides.lock().unwrap_or_else(|p| p.into_inner());
        let same = store.held.len() == wanted.len()
            && store
                .held
                .iter()
                .zip(&wanted)
                .all(|(a, b)| Arc::ptr_eq(a, b));
        if !same {
            let bytes: u64 = wanted.iter().map(|s| 4 * s.data.len() as u64).sum();
            if bytes > self.max_binding {
                return Err(GpuError::TooLarge(format!(
                    "projector slides of {bytes} bytes; {} binds at most {}",
                    self.adapter, self.max_binding
                )));
            }
            if bytes > store.capacity {
                let capacity = bytes.next_power_of_two().min(self.max_binding).max(bytes);
                store.buffer = slide_buffer(&self.device, capacity);
                store.capacity = capacity;
                store.generation += 1;
            }
            let mut at = 0;
            for s in &wanted {
                if !s.data.is_empty() {
                    self.queue
                        .write_buffer(&store.buffer, at, bytemuck::cast_slice(&s.data));
                }
                at += 4 * s.data.len() as u64;
            }
            store.held = wanted;
        }
        drop(store);
        self.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(frame.as_ref()));
        Ok(roi)
    }

    /// The cached per-region buffers, rebuilt when the region changes.
    fn target_for<'g>(&self, slot: &'g mut Option<Target>, roi: Roi) -> Result<&'g Target> {
        let (slides, generation) = {
            let store = self.slides.lock().unwrap_or_else(|p| p.into_inner());
            (store.buffer.clone(), store.generation)
        };
        if slot
            .as_ref()
            .is_some_and(|t| t.roi == roi && t.slides == generation)
        {
            return Ok(slot.as_ref().expect("checked"));
        }
        *slot = None;
        let total = roi.pixels() as u64 * OUT_BYTES;
        if total > self.max_buffer {
            return Err(GpuError::TooLarge(format!(
                "a {}×{} region needs a {total}-byte readback buffer; {} allows {}: relight a smaller region",
                roi.width, roi.height, self.adapter, self.max_buffer
            )));
        }
        let mut parts = Vec::new();
        let mut offset = 0;
        for slab in &self.slabs {
            let lo = slab.row0.max(roi.y);
            let hi = (slab.row0 + slab.rows).min(roi.y + roi.height);
            if lo >= hi {
                continue;
            }
            let rows = hi - lo;
            let threads = (roi.width * rows) as u64;
            let span: [u32; 8] = [
                slab.row0 as u32,
                slab.stride as u32,
                roi.x as u32,
                lo as u32,
                roi.width as u32,
                rows as u32,
                0,
                0,
            ];
            let span = self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("relit span"),
                    contents: bytemuck::bytes_of(&span),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let bytes = threads * OUT_BYTES;
            let out = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("relit out"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let positions = slab.positions.as_ref().unwrap_or(&self.no_positions);
            let buffers = [
                &self.setup,
                &span,
                &self.frame,
                &slab.planes,
                positions,
                &out,
                &slides,
                &self.table,
            ];
            let entries: Vec<wgpu::BindGroupEntry> = buffers
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect();
            let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("relit slab"),
                layout: &self.layout,
                entries: &entries,
            });
            let groups = threads.div_ceil(WORKGROUP);
            let gx = groups.min(self.max_groups as u64);
            let gy = groups.div_ceil(gx);
            parts.push(Part {
                bind,
                out,
                groups: [gx as u32, gy as u32],
                bytes,
                offset,
            });
            offset += bytes;
        }
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relit readback"),
            size: total,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.check_errors()?;
        Ok(slot.insert(Target {
            roi,
            slides: generation,
            parts,
            staging,
        }))
    }

    fn encode(&self, encoder: &mut wgpu::CommandEncoder, target: &Target, extra: bool) {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(if extra {
            &self.pipeline
        } else {
            &self.basic_pipeline
        });
        for part in &target.parts {
            pass.set_bind_group(0, &part.bind, &[]);
            pass.dispatch_workgroups(part.groups[0], part.groups[1], 1);
        }
    }

    fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Device(e.to_string()))
    }

    fn check_errors(&self) -> Result<()> {
        let errors = std::mem::take(&mut *self.errors.lock().unwrap_or_else(|p| p.into_inner()));
        if errors.is_empty() {
            Ok(())
        } else {
            Err(GpuError::Device(errors.join("; ")))
        }
    }
}

/// The table as relight.wgsl reads it: each vertex's weights in groups of four half
/// floats (two `u32`, the lower half first), zero past `k`, so that one load fetches
/// four weights.
fn table_groups(table: &WeightTable) -> Vec<[u32; 2]> {
    let k = table.k;
    let half = |w: &[f32], q: usize| {
        half::f16::from_f32(w.get(q).copied().unwrap_or(0.0)).to_bits() as u32
    };
    let mut out = Vec::with_capacity(table.values.len() / k.max(1) * k.div_ceil(4));
    for vertex in table.values.chunks_exact(k) {
        out.extend(
            vertex
                .chunks(4)
                .map(|w| [half(w, 0) | half(w, 1) << 16, half(w, 2) | half(w, 3) << 16]),
        );
    }
    out
}

/// A compute shader's buffer binding `binding` of type `ty`.
fn buffer_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A buffer for `bytes` of projector slides.
fn slide_buffer(device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("relit slides"),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The camera that turns depth into surface points, or why there is none.
fn positions_source(image: &RelightableImage) -> std::result::Result<Camera, String> {
    let depth = image.depth.as_ref().ok_or_else(|| {
        "lights with a position need a depth map: fit a capture that has one (a manifest `depth`, or `relit capture`)".to_string()
    })?;
    // The stored camera, or the projection at the default pose (Relighter::camera); not
    // through a Relighter, which would rebuild the basis from the metadata.
    let meta = &image.meta;
    let camera = meta
        .camera
        .clone()
        .unwrap_or(relit::camera::CameraSpec {
            projection: meta.projection.clone(),
            width: image.width(),
            height: image.height(),
            pose: Default::default(),
            orthographic_height: None,
        })
        .build()
        .map_err(|e| e.to_string())?;
    if depth.len() != camera.width() * camera.height()
        || camera.width() != image.width()
        || camera.height() != image.height()
    {
        return Err(format!(
            "the depth map has {} values and the camera is {}×{}, but the maps are {}×{}",
            depth.len(),
            camera.width(),
            camera.height(),
            image.width(),
            image.height()
        ));
    }
    Ok(camera)
}
