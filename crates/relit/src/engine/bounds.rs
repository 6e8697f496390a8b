//! What the machine can do at best, measured in the same process as the frames they
//! bound: the read rate of a relighter's own planes and the peak multiply-add rate.
//!
//! **Read bandwidth** ([`Relighter::plane_read_rate`]). A uniform frame must read every
//! stored byte of the planes once, so no frame can be faster than the fastest plain
//! read of those bytes; the probe is that read. It reads the relighter's own planes
//! (the same bytes at the same addresses, already touched: the f32 maps or the f16/u8
//! copy), does one OR per 32 bytes with AVX2 loads where the CPU has them (so it waits
//! on memory, not on arithmetic: an OR per load is cheaper than anything a frame does
//! with a value), on every rayon thread, in two patterns, and keeps the best:
//!
//! * the engine's own: rayon over tiles of [`TILE`] pixels, each tile reading the
//!   planes eight at a time (eight streams per thread, as the uniform passes read
//!   them), and
//! * contiguous: each thread reads one share of the planes' bytes as four streams.
//!
//! A single stream per thread (the earlier probe: rayon over 256 KiB chunks, an f32 sum
//! without AVX2) read 25–40 % slower than both on this project's machine, slower than
//! the engine itself, which then reported 116–158 % "of the bound"; several streams per
//! thread let the prefetchers keep more lines in flight. 16-lane (AVX-512) loads were
//! no faster in either pattern (measured), so the probe does not use them. The caller
//! keeps the best of several calls (interleaved with the frames it bounds, so both see
//! the same load from other processes): a bound is the best the machine did.
//!
//! **Multiply-add peak** ([`fma_peak`]). Register-only FMA chains on every rayon
//! thread: twelve independent 8-lane chains (more than latency × pipes), and, where
//! the CPU has AVX-512F, the same on 16-lane registers, which the machine's peak is
//! then (the engine's kernels use 8 lanes, so 8-lane code cannot exceed half of it).

use super::kernels::{Simd, FMA_PER_ITER};
use super::tiles::TILE;
use super::Relighter;
use crate::storage::Planes;
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;

impl Relighter<'_> {
    /// Bytes per second at which this machine reads this relighter's planes (all rayon
    /// threads, the better of the two patterns in the module docs), best of `reps`
    /// reads of every plane: the bound of any frame that streams the planes once.
    pub fn plane_read_rate(&self, reps: usize) -> f64 {
        let planes = &self.planes;
        let n = self.image.maps.pixels();
        let bytes = planes.bytes();
        if bytes == 0 {
            return f64::INFINITY;
        }
        let simd = self.simd;
        let mut best = 0f64;
        for _ in 0..reps.max(1) {
            for pattern in [read_tiles, read_contiguous] {
                let t = Instant::now();
                black_box(pattern(simd, planes, n));
                best = best.max(bytes as f64 / t.elapsed().as_secs_f64());
            }
        }
        best
    }
}

/// The planes' bytes as one slice, plane `j` at `j · n · bytes_per_value`.
fn plane_bytes<'p>(planes: &'p Planes) -> &'p [u8] {
    match planes {
        Planes::F32(d) => bytemuck::cast_slice(d),
        Planes::F16(d) => bytemuck::cast_slice(d),
        Planes::U8 { data, .. } => data,
    }
}

/// The engine's pattern: rayon over tiles, eight plane segments read together.
fn read_tiles(simd: Simd, planes: &Planes, n: usize) -> u64 {
    let data = plane_bytes(planes);
    let b = planes.precision().bytes_per_value();
    let count = data.len() / (n * b).max(1);
    let tiles = n.div_ceil(TILE);
    (0..tiles)
        .into_par_iter()
        .map(|t| {
            let (p0, p1) = (t * TILE, ((t + 1) * TILE).min(n));
            let segment = |j: usize| &data[(j * n + p0) * b..(j * n + p1) * b];
            let mut acc = 0;
            let mut j = 0;
            while j + 8 <= count {
                acc |= simd.or_streams(std::array::from_fn::<_, 8, _>(|d| segment(j + d)));
                j += 8;
            }
            for j in j..count {
                acc |= simd.or_streams([segment(j)]);
            }
            acc
        })
        .reduce(|| 0, |a, b| a | b)
}

/// Each thread reads one share of the bytes as four streams.
fn read_contiguous(simd: Simd, planes: &Planes, _n: usize) -> u64 {
    let data = plane_bytes(planes);
    let threads = rayon::current_num_threads().max(1);
    // Shares of whole 256-byte blocks, so that the four streams of each are equal.
    let share = data.len().div_ceil(threads).div_ceil(256) * 256;
    data.par_chunks(share.max(256))
        .map(|part| {
            let q = part.len() / 4;
            let head = simd.or_streams([0, 1, 2, 3].map(|i| &part[i * q..(i + 1) * q]));
            head | simd.or_streams([&part[4 * q..]])
        })
        .reduce(|| 0, |a, b| a | b)
}

/// Peak f32 multiply-add rates (per second, all rayon threads at once) of
/// register-only FMA chains.
#[derive(Clone, Copy, Debug)]
pub struct FmaPeak {
    /// 8-lane code (AVX2 + FMA where the CPU has it, else the portable loop): the
    /// widest the engine's kernels use.
    pub lanes8: f64,
    /// 16-lane code (AVX-512F), where the CPU has it.
    pub lanes16: Option<f64>,
}

impl FmaPeak {
    /// The machine's peak: the faster of the two.
    pub fn best(&self) -> f64 {
        self.lanes16.map_or(self.lanes8, |w| w.max(self.lanes8))
    }

    /// `avx512f` or `avx2+fma` (or `portable`): the code the peak was measured with.
    pub fn isa(&self) -> &'static str {
        match self.lanes16 {
            Some(w) if w > self.lanes8 => "avx512f",
            _ => Simd::detect().name(),
        }
    }
}

/// Measure [`FmaPeak`]: each width best of three runs of about `seconds / 3`.
pub fn fma_peak(seconds: f64) -> FmaPeak {
    let simd = Simd::detect();
    let narrow = |iters, seed| Some(simd.fma_chains(iters, seed));
    let wide = |iters, seed| simd.fma_chains_wide(iters, seed);
    let lanes8 = chain_rate(seconds / 3.0, FMA_PER_ITER, &narrow).unwrap_or(0.0);
    let lanes16 = chain_rate(seconds / 3.0, 2 * FMA_PER_ITER, &wide);
    FmaPeak { lanes8, lanes16 }
}

/// The machine's peak f32 multiply-add rate: [`FmaPeak::best`] of [`fma_peak`].
pub fn fma_throughput(seconds: f64) -> f64 {
    fma_peak(seconds).best()
}

/// Multiply-adds per second of `chains(iters, seed)` (`per_iter` per iteration) on all
/// rayon threads at once, best of three runs of about `seconds`.
fn chain_rate(
    seconds: f64,
    per_iter: usize,
    chains: &(dyn Fn(usize, f32) -> Option<f32> + Sync),
) -> Option<f64> {
    // Calibrate on one thread.
    let mut iters = 1 << 14;
    loop {
        let t = Instant::now();
        black_box(chains(iters, 1.0)?);
        let dt = t.elapsed().as_secs_f64();
        if dt > 0.01 || iters > 1 << 30 {
            iters = ((iters as f64) * seconds.max(0.003) / dt.max(1e-9)) as usize;
            break;
        }
        iters *= 4;
    }
    let iters = iters.max(1);
    let mut best = 0f64;
    for _ in 0..3 {
        let start = Instant::now();
        // The seed is not a constant, so the chains cannot be folded away.
        let sums: Vec<Option<f32>> = rayon::broadcast(|ctx| chains(iters, ctx.index() as f32));
        let elapsed = start.elapsed().as_secs_f64();
        black_box(&sums);
        best = best.max((sums.len() * iters * per_iter) as f64 / elapsed);
    }
    Some(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::Precision;

    #[test]
    fn the_or_of_streams_reads_every_byte() {
        for simd in [Simd::baseline(), Simd::detect()] {
            for len in [0usize, 5, 64, 200, 1000] {
                for at in (0..len).step_by(3) {
                    let mut a = vec![0u8; len];
                    let b = vec![0u8; len];
                    a[at] = 0x80;
                    let want = 0x80u64 << (8 * (at % 8));
                    let got = simd.or_streams([&a[..], &b[..]]);
                    // A tail shorter than a word is folded byte by byte, into the low byte.
                    let tail = at >= len / 8 * 8;
                    assert_eq!(got, if tail { 0x80 } else { want }, "{simd:?} {len} {at}");
                }
            }
        }
    }

    #[test]
    fn probes_measure_something() {
        let img = crate::maps::CoefficientMaps::zeros(70, 30, 9);
        let image = crate::maps::RelightableImage {
            meta: crate::maps::Metadata::new(
                crate::basis::BasisSpec::named("sh:9").unwrap(),
                crate::maps::MapSpace::Linear,
                Default::default(),
            ),
            maps: img,
            depth: None,
        };
        for storage in Precision::ALL {
            let r = Relighter::with_precision(&image, storage).unwrap();
            let rate = r.plane_read_rate(2);
            assert!(rate.is_finite() && rate > 0.0, "{storage:?}");
        }
        let peak = fma_peak(0.01);
        assert!(peak.lanes8 > 1e6 && peak.best() >= peak.lanes8);
    }
}
