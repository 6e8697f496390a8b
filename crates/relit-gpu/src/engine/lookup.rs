//! [`GpuLookup`]: a codebook file (seed 004's vector quantisation) relit on a GPU
//! without expanding it, as `relit::engine::lookup` does on the CPU.
//!
//! The `C` entries live in an ordinary [`GpuRelighter`] over a `C × 1` image; the pixels
//! are 16-bit indices, two to a word. A frame under lights that are the same at every
//! pixel (directional, environment) relights the entries (one dispatch over `C` texels)
//! and then gathers each pixel's colour (`shaders/lookup.wgsl`): 2 bytes read a pixel
//! instead of `3·K` stored values. Lights with a position differ per pixel and are
//! refused; their frames come from the expanded maps.

use super::{buffer_entry, GpuRelighter, Target, OUT_BYTES, WORKGROUP};
use crate::error::{invalid, GpuError, Result};
use crate::lighting::Lighting;
use crate::roi::Roi;
use crate::GpuOptions;
use relit::engine::lookup::IndexedImage;
use relit::image::ImageRgb;
use relit::light::LightRig;
use std::sync::Mutex;
use std::time::{Duration, Instant};
use wgpu::util::DeviceExt;

/// A codebook image resident on a GPU (see the module docs).
pub struct GpuLookup {
    entries: GpuRelighter,
    indices: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    width: usize,
    height: usize,
    index_bytes: u64,
    target: Mutex<Option<LookupTarget>>,
}

/// A region's lookup pass, kept while the region stays the same.
struct LookupTarget {
    roi: Roi,
    /// The entries' output buffer the bind group reads.
    colours: wgpu::Buffer,
    bind: wgpu::BindGroup,
    out: wgpu::Buffer,
    staging: wgpu::Buffer,
    groups: [u32; 2],
    bytes: u64,
}

impl GpuLookup {
    /// Upload `image`'s entries (stored as `options` says) and its indices.
    pub fn new(image: &IndexedImage, options: GpuOptions) -> Result<Self> {
        let c = image.entries.maps.pixels();
        if image.entries.height() != 1 || c == 0 || c > 1 << 16 {
            return Err(invalid("a codebook is a C × 1 image of 1 to 65536 entries"));
        }
        let n = image.width * image.height;
        if image.indices.len() != n || n == 0 {
            return Err(invalid("an indexed image needs one index per pixel"));
        }
        if image.indices.iter().any(|&i| i as usize >= c) {
            return Err(invalid(format!(
                "an index points past the codebook's {c} entries"
            )));
        }
        let entries = GpuRelighter::with_options(&image.entries, options)?;
        let index_bytes = 4 * n.div_ceil(2) as u64;
        if index_bytes > entries.max_binding {
            return Err(GpuError::TooLarge(format!(
                "{n} indices take {index_bytes} bytes; {} binds at most {}",
                entries.adapter, entries.max_binding
            )));
        }
        let words: Vec<u32> = image
            .indices
            .chunks(2)
            .map(|pair| pair[0] as u32 | (pair.get(1).copied().unwrap_or(0) as u32) << 16)
            .collect();
        let device = &entries.device;
        let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("relit indices"),
            contents: bytemuck::cast_slice(&words),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let entry = buffer_entry;
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relit lookup"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Uniform),
                entry(1, read),
                entry(2, read),
                entry(3, wgpu::BufferBindingType::Storage { read_only: false }),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("relit lookup"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("relit lookup"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../../shaders/lookup.wgsl").into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("relit lookup"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        entries.check_errors()?;
        Ok(Self {
            entries,
            indices,
            pipeline,
            layout,
            width: image.width,
            height: image.height,
            index_bytes,
            target: Mutex::new(None),
        })
    }

    /// The engine holding the entries (its adapter, precision, basis).
    pub fn entries(&self) -> &GpuRelighter {
        &self.entries
    }

    /// Bytes resident on the GPU: the entries' planes and the indices.
    pub fn resident_bytes(&self) -> u64 {
        self.entries.resident_bytes() + self.index_bytes
    }

    /// The lighting of `rig`, refused where a light differs per pixel.
    pub fn lighting(&self, rig: &LightRig, exposure: f64) -> Result<Lighting> {
        let lighting = self.entries.lighting(rig, exposure)?;
        self.check(&lighting)?;
        Ok(lighting)
    }

    fn check(&self, lighting: &Lighting) -> Result<()> {
        if lighting.has_positional() || lighting.has_projectors_or_areas() {
            return Err(invalid(
                "lights with a position differ per pixel: relight the expanded maps",
            ));
        }
        Ok(())
    }

    /// Relight the whole image with `rig`.
    pub fn relight(&self, rig: &LightRig, exposure: f64) -> Result<ImageRgb> {
        self.render(&self.lighting(rig, exposure)?, None)
    }

    /// Render `lighting` over `roi` (the whole image when `None`) and read it back.
    pub fn render(&self, lighting: &Lighting, roi: Option<Roi>) -> Result<ImageRgb> {
        let e = &self.entries;
        let (roi, mut entries_slot) = self.prepare(lighting, roi)?;
        let mut guard = self.target.lock().unwrap_or_else(|p| p.into_inner());
        let entries_target = e.target_for(&mut entries_slot, Roi::full(e.width, 1))?;
        let target = self.target_for(&mut guard, roi, entries_target)?;
        let mut encoder = e.device.create_command_encoder(&Default::default());
        self.encode(&mut encoder, entries_target, target);
        encoder.copy_buffer_to_buffer(&target.out, 0, &target.staging, 0, target.bytes);
        e.queue.submit([encoder.finish()]);
        let image = e.read_back(&target.staging, roi)?;
        drop(guard);
        self.restore(entries_slot);
        e.check_errors()?;
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
        let e = &self.entries;
        let (roi, mut entries_slot) = self.prepare(lighting, roi)?;
        let mut guard = self.target.lock().unwrap_or_else(|p| p.into_inner());
        let entries_target = e.target_for(&mut entries_slot, Roi::full(e.width, 1))?;
        let target = self.target_for(&mut guard, roi, entries_target)?;
        let frame = || {
            let mut encoder = e.device.create_command_encoder(&Default::default());
            self.encode(&mut encoder, entries_target, target);
            e.queue.submit([encoder.finish()]);
        };
        frame();
        e.wait()?;
        let start = Instant::now();
        for _ in 0..frames {
            frame();
        }
        e.wait()?;
        let elapsed = start.elapsed();
        drop(guard);
        self.restore(entries_slot);
        e.check_errors()?;
        Ok(elapsed / frames.max(1) as u32)
    }

    /// Check the frame, write the entries' lights, and take the entries' target out of
    /// its engine for this frame.
    fn prepare(&self, lighting: &Lighting, roi: Option<Roi>) -> Result<(Roi, Option<Target>)> {
        self.check(lighting)?;
        let roi = roi.unwrap_or(Roi::full(self.width, self.height));
        roi.validate(self.width, self.height)?;
        let e = &self.entries;
        e.upload(lighting, None)?;
        let slot = e.target.lock().unwrap_or_else(|p| p.into_inner()).take();
        Ok((roi, slot))
    }

    /// Put the entries' target back for the next frame.
    fn restore(&self, slot: Option<Target>) {
        *self
            .entries
            .target
            .lock()
            .unwrap_or_else(|p| p.into_inner()) = slot;
    }

    fn encode(&self, encoder: &mut wgpu::CommandEncoder, entries: &Target, target: &LookupTarget) {
        self.entries.encode(encoder, entries, false);
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &target.bind, &[]);
        pass.dispatch_workgroups(target.groups[0], target.groups[1], 1);
    }

    /// The region's lookup buffers, rebuilt when the region (or the entries' output,
    /// which the bind group reads) changes.
    fn target_for<'g>(
        &self,
        slot: &'g mut Option<LookupTarget>,
        roi: Roi,
        entries: &Target,
    ) -> Result<&'g LookupTarget> {
        let [part] = entries.parts.as_slice() else {
            return Err(GpuError::Device(
                "the codebook's entries did not fit one slab".into(),
            ));
        };
        if slot
            .as_ref()
            .is_some_and(|t| t.roi == roi && t.colours == part.out)
        {
            return Ok(slot.as_ref().expect("checked"));
        }
        *slot = None;
        let e = &self.entries;
        let threads = roi.pixels() as u64;
        let bytes = threads * OUT_BYTES;
        if bytes > e.max_buffer || bytes > e.max_binding {
            return Err(GpuError::TooLarge(format!(
                "a {}×{} region needs a {bytes}-byte output buffer; {} allows {}: relight a smaller region",
                roi.width,
                roi.height,
                e.adapter,
                e.max_binding.min(e.max_buffer)
            )));
        }
        let groups = threads.div_ceil(WORKGROUP);
        let gx = groups.min(e.max_groups as u64);
        let gy = groups.div_ceil(gx);
        let span: [u32; 8] = [
            roi.x as u32,
            roi.y as u32,
            roi.width as u32,
            roi.height as u32,
            self.width as u32,
            (gx * WORKGROUP) as u32,
            0,
            0,
        ];
        let span = e
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("relit lookup span"),
                contents: bytemuck::bytes_of(&span),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let out = e.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relit lookup out"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = e.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relit lookup readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind = e.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("relit lookup"),
            layout: &self.layout,
            entries: &[&span, &part.out, &self.indices, &out]
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect::<Vec<_>>(),
        });
        e.check_errors()?;
        Ok(slot.insert(LookupTarget {
            roi,
            colours: part.out.clone(),
            bind,
            out,
            staging,
            groups: [gx as u32, gy as u32],
            bytes,
        }))
    }
}
