//! The device's plain read rate: the bound `relit bench` sets a hardware adapter's
//! frames against, as it sets the CPU engine's against the host's (a software adapter
//! reads host memory, so there the host's rate is the bound).

use super::GpuRelighter;
use crate::error::{invalid, GpuError, Result};
use std::time::Instant;

const WORKGROUP: u64 = 256;
/// Host bytes written per upload while the probe buffer is filled.
const FILL_CHUNK: u64 = 64 << 20;
/// Invocations per workgroup-sized share of the buffer: enough loads in flight per
/// invocation to hide the memory latency, few enough that every unit has work.
const VALUES_PER_INVOCATION: u64 = 16;
/// Seconds of untimed reads before the timed batches.
const WARM_UP_SECONDS: f64 = 1.0;

impl GpuRelighter {
    /// The best rate, in bytes per second, at which this device reads a buffer of
    /// `bytes` (capped by the largest buffer it binds) that the probe fills itself, timed
    /// as [`GpuRelighter::resident_read_rate`] times the planes.
    pub fn read_rate(&self, bytes: u64, passes: usize) -> Result<f64> {
        let size = self.bindable(bytes);
        if size == 0 || passes == 0 {
            return Err(invalid(
                "the read probe needs at least 16 bytes and one pass",
            ));
        }
        let source = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relit read probe"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // Values that are not zero, so that no memory system can answer from a
        // compressed or cleared state.
        let pattern: Vec<f32> = (0..FILL_CHUNK.min(size) / 4)
            .map(|i| 1.0 + (i % 251) as f32 * 1e-3)
            .collect();
        let mut at = 0;
        while at < size {
            let n = (size - at).min(FILL_CHUNK);
            self.queue.write_buffer(
                &source,
                at,
                bytemuck::cast_slice(&pattern[..(n / 4) as usize]),
            );
            at += n;
        }
        self.probe(&[(&source, size)], passes)
    }

    /// The best rate, in bytes per second, at which this device reads the engine's own
    /// resident planes (every slab, as a frame reads them, but as plain vec4 loads):
    /// the bound `relit bench` sets frames against, measured on the very bytes the
    /// frames read: the best of three batches each of one, two and `passes` reads of
    /// every slab, after [`WARM_UP_SECONDS`] of untimed reads (`RELIT_PROBE_REPORT=1`
    /// prints every batch).
    pub fn resident_read_rate(&self, passes: usize) -> Result<f64> {
        let buffers: Vec<(&wgpu::Buffer, u64)> = self
            .slabs
            .iter()
            .map(|s| (&s.planes, s.planes.size()))
            .collect();
        self.probe(&buffers, passes)
    }

    /// The bytes of a buffer of `size` the probe binds: whole vec4 values, within the
    /// adapter's binding limit.
    fn bindable(&self, size: u64) -> u64 {
        size.min(self.max_binding).min(u32::MAX as u64) / 16 * 16
    }

    /// Time plain vec4 reads of `buffers` (each bound from its start, [`Self::bindable`]
    /// bytes of `size`).
    fn probe(&self, buffers: &[(&wgpu::Buffer, u64)], passes: usize) -> Result<f64> {
        let device = &self.device;
        let sink = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relit read probe sink"),
            size: 64 * 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("relit read probe"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../../shaders/read_probe.wgsl").into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("relit read probe"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        // One bind group and dispatch size per buffer.
        let mut work = Vec::new();
        let mut total = 0u64;
        for &(buffer, size) in buffers {
            let size = self.bindable(size);
            if size == 0 {
                continue;
            }
            total += size;
            let count = size / 16;
            let groups = count
                .div_ceil(WORKGROUP * VALUES_PER_INVOCATION)
                .clamp(1, self.max_groups as u64);
            let threads = groups * WORKGROUP;
            let params = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("relit read probe parameters"),
                size: 16,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let words = [count as u32, threads as u32, 0, 0];
            self.queue
                .write_buffer(&params, 0, bytemuck::cast_slice(&words));
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("relit read probe"),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer,
                            offset: 0,
                            size: std::num::NonZeroU64::new(size),
                        }),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: sink.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: params.as_entire_binding(),
                    },
                ],
            });
            work.push((group, groups as u32, params));
        }
        if total == 0 || passes == 0 {
            return Err(invalid(
                "the read probe needs at least 16 bytes and one pass",
            ));
        }
        let run = |reads: usize| -> Result<f64> {
            let mut encoder = device.create_command_encoder(&Default::default());
            for _ in 0..reads {
                for (group, groups, _) in &work {
                    let mut pass = encoder.begin_compute_pass(&Default::default());
                    pass.set_pipeline(&pipeline);
                    pass.set_bind_group(0, group, &[]);
                    pass.dispatch_workgroups(*groups, 1, 1);
                }
            }
            let start = Instant::now();
            self.queue.submit([encoder.finish()]);
            self.wait()?;
            Ok(start.elapsed().as_secs_f64())
        };
        run(1)?;
        self.check_errors()?;
        // Reads for a while first: an H200 left idle while the host built the maps
        // answered a short probe at 1.7 TB/s and the same buffers at 4 TB/s once busy
        // (its clocks rise with sustained load, as they do for the timed frames, which
        // `relit bench` warms up for 0.1 s).
        let warm = Instant::now();
        while warm.elapsed().as_secs_f64() < WARM_UP_SECONDS {
            run(passes)?;
        }
        // Batches of one, two and `passes` reads: no single batch size is trusted; the
        // bound is the best of them all.
        let mut best = 0f64;
        let report = std::env::var_os("RELIT_PROBE_REPORT").is_some();
        let mut sizes = vec![1, 2, passes];
        sizes.dedup();
        for &reads in &sizes {
            for _ in 0..3 {
                let seconds = run(reads)?;
                let rate = (total * reads as u64) as f64 / seconds.max(1e-9);
                if report {
                    eprintln!(
                        "read probe: {total} bytes in {} buffer(s) × {reads} reads in {:.3} ms: {:.0} GB/s",
                        work.len(),
                        seconds * 1e3,
                        rate / 1e9
                    );
                }
                best = best.max(rate);
            }
        }
        self.check_errors()?;
        if !best.is_finite() || best <= 0.0 {
            return Err(GpuError::Device("the read probe measured no time".into()));
        }
        Ok(best)
    }
}
