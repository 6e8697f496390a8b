//! The CPU engine's inner loops, vectorised: every `unsafe` of the engine lives here.
//!
//! Each kernel has one body, written as plain loops over slices (or, for half floats,
//! with `core::arch` intrinsics on values, no pointers), marked `#[inline(always)]` and
//! compiled twice: once for the baseline target and once inside a
//! `#[target_feature(enable = "avx2,fma,f16c")]` wrapper, where LLVM turns the loops
//! into 8-wide FMA code (checked in the disassembly of the release build: `vfmadd…ps
//! ymm`, `vcvtph2ps ymm`). [`Simd::detect`] checks the CPU once; the public functions
//! call the wrapper only when it said yes, which is the whole safety argument of the
//! `unsafe` blocks below.
//!
//! Measured alternatives (1024×256, k = 16, 2 cores): one plane per pass over a tile
//! (`acc += w·plane`) moves the accumulator through L1 once per plane and reached 70 %
//! of the speed of four planes per pass; a dot product over all planes per 32-pixel
//! block (accumulators in registers) reads k streams at once and was 30 % slower than
//! four planes per pass. [`Simd::axpy`] takes eight planes per pass (every storage;
//! for u8 planes eight were 2–10 % faster than four on this project's Intel machine), and
//! the first pass of a channel writes the accumulator instead of adding to a cleared
//! one ([`Simd::axpy_init`]).
//!
//! Frames larger than the caches are written with non-temporal stores
//! ([`Simd::interleave_stream`]), so that writing the frame neither reads it first nor
//! pushes the planes out of the caches.
//!
//! Positional lights: `pixel_basis` evaluates the basis per pixel and dots it with the
//! coefficients (or projects many light vectors first), by SH's recurrence (`sh`) or any
//! basis' half-float weight table (`table`); `lights` makes each light's per-pixel
//! vectors and weights; all in the same one-body, two-compilations form.

use half::f16;

mod lights;
mod pixel_basis;
mod sh;
mod table;

pub(crate) use lights::{AreaSamples, Cone, Falloff, Projector, Shift};
pub use pixel_basis::BasisEvaluator;
pub(crate) use pixel_basis::PixelBasis;
pub(crate) use sh::Rows;

/// Pixels per block of the per-pixel (positional light) kernels: their scratch
/// arrays, a few per block, stay in L1.
pub(crate) const BLOCK: usize = 64;

/// Whether the CPU runs the AVX2 + FMA + F16C versions (x86-64 only).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Simd {
    avx2: bool,
}

impl Simd {
    /// Check the CPU once per call site (cheap: `is_x86_feature_detected!` caches).
    pub(crate) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            Self {
                avx2: is_x86_feature_detected!("avx2")
                    && is_x86_feature_detected!("fma")
                    && is_x86_feature_detected!("f16c"),
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            Self { avx2: false }
        }
    }

    /// Whether the AVX2/FMA/F16C versions run (for kernels outside this module).
    pub(crate) fn avx2(self) -> bool {
        self.avx2
    }

    /// Which versions run: `avx2+fma+f16c` or `portable`.
    pub(crate) fn name(self) -> &'static str {
        if self.avx2 {
            "avx2+fma+f16c"
        } else {
            "portable"
        }
    }

    /// The portable versions only (tests compare both).
    #[cfg(test)]
    pub(crate) fn baseline() -> Self {
        Self { avx2: false }
    }

    /// `acc[p] += Σ_j w[j]·planes[j][p]` for `N` planes of any stored type.
    pub(crate) fn axpy<T: Stored, const N: usize>(
        self,
        acc: &mut [f32],
        planes: [&[T]; N],
        w: [f32; N],
    ) {
        self.axpy_from::<T, N, false>(acc, planes, w, 0.0)
    }

    /// `acc[p] = init + Σ_j w[j]·planes[j][p]` (the first pass over a tile: `acc` is
    /// written, not read).
    pub(crate) fn axpy_init<T: Stored, const N: usize>(
        self,
        acc: &mut [f32],
        planes: [&[T]; N],
        w: [f32; N],
        init: f32,
    ) {
        self.axpy_from::<T, N, true>(acc, planes, w, init)
    }

    fn axpy_from<T: Stored, const N: usize, const INIT: bool>(
        self,
        acc: &mut [f32],
        planes: [&[T]; N],
        w: [f32; N],
        init: f32,
    ) {
        let n = acc.len();
        let planes = planes.map(|p| &p[..n]);
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `detect` found avx2, fma and f16c on this CPU.
            return unsafe { T::axpy_avx2::<N, INIT>(acc, planes, w, init) };
        }
        axpy_body::<T, N, false, INIT>(acc, planes, w, init)
    }

    /// `out[p] = scale·stored[p] + bias`: values of a plane segment as f32.
    pub(crate) fn decode<T: Stored>(self, out: &mut [f32], stored: &[T], scale: f32, bias: f32) {
        let stored = &stored[..out.len()];
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `axpy`.
            return unsafe { T::decode_avx2(out, stored, scale, bias) };
        }
        for (o, &s) in out.iter_mut().zip(stored) {
            *o = s.to_f32() * scale + bias;
        }
    }

    /// Interleave three channel rows into RGB pixels: `dst[3p + c] = rows[c][p]`.
    pub(crate) fn interleave(self, dst: &mut [f32], rows: [&[f32]; 3]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `axpy`.
            return unsafe { interleave_avx2(dst, rows) };
        }
        interleave_body(dst, rows)
    }
}

/// A stored coefficient type: f32, f16 (as bits) or 8-bit.
pub(crate) trait Stored: Copy + Send + Sync + 'static {
    fn to_f32(self) -> f32;
    /// # Safety
    /// The CPU must support avx2, fma and f16c.
    #[cfg(target_arch = "x86_64")]
    unsafe fn axpy_avx2<const N: usize, const INIT: bool>(
        acc: &mut [f32],
        planes: [&[Self]; N],
        w: [f32; N],
        init: f32,
    );
    /// # Safety
    /// As `axpy_avx2`.
    #[cfg(target_arch = "x86_64")]
    unsafe fn decode_avx2(out: &mut [f32], stored: &[Self], scale: f32, bias: f32);
}

#[inline(always)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

#[inline(always)]
fn axpy_body<T: Stored, const N: usize, const FMA: bool, const INIT: bool>(
    acc: &mut [f32],
    planes: [&[T]; N],
    w: [f32; N],
    init: f32,
) {
    for (p, a) in acc.iter_mut().enumerate() {
        let mut v = if INIT { init } else { *a };
        for j in 0..N {
            v = madd::<FMA>(planes[j][p].to_f32(), w[j], v);
        }
        *a = v;
    }
}

impl Stored for f32 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn axpy_avx2<const N: usize, const INIT: bool>(
        acc: &mut [f32],
        planes: [&[f32]; N],
        w: [f32; N],
        init: f32,
    ) {
        axpy_body::<f32, N, true, INIT>(acc, planes, w, init)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn decode_avx2(out: &mut [f32], stored: &[f32], scale: f32, bias: f32) {
        for (o, &s) in out.iter_mut().zip(stored) {
            *o = s.mul_add(scale, bias);
        }
    }
}

impl Stored for u8 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn axpy_avx2<const N: usize, const INIT: bool>(
        acc: &mut [f32],
        planes: [&[u8]; N],
        w: [f32; N],
        init: f32,
    ) {
        axpy_body::<u8, N, true, INIT>(acc, planes, w, init)
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn decode_avx2(out: &mut [f32], stored: &[u8], scale: f32, bias: f32) {
        for (o, &s) in out.iter_mut().zip(stored) {
            *o = (s as f32).mul_add(scale, bias);
        }
    }
}

/// Half floats, stored as their bits.
impl Stored for u16 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        f16::from_bits(self).to_f32()
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn axpy_avx2<const N: usize, const INIT: bool>(
        acc: &mut [f32],
        planes: [&[u16]; N],
        w: [f32; N],
        init: f32,
    ) {
        use std::arch::x86_64::*;
        let n = acc.len();
        let mut weights = [_mm256_setzero_ps(); N];
        for (v, &x) in weights.iter_mut().zip(&w) {
            *v = _mm256_set1_ps(x);
        }
        let start = _mm256_set1_ps(init);
        let mut p = 0;
        while p + 8 <= n {
            let mut a = if INIT {
                start
            } else {
                let chunk: [f32; 8] = acc[p..p + 8].try_into().expect("8 lanes");
                bytemuck::cast(chunk)
            };
            for j in 0..N {
                let bits: [u16; 8] = planes[j][p..p + 8].try_into().expect("8 lanes");
                let v = _mm256_cvtph_ps(bytemuck::cast::<[u16; 8], __m128i>(bits));
                a = _mm256_fmadd_ps(v, weights[j], a);
            }
            acc[p..p + 8].copy_from_slice(&bytemuck::cast::<__m256, [f32; 8]>(a));
            p += 8;
        }
        axpy_body::<u16, N, true, INIT>(&mut acc[p..], planes.map(|s| &s[p..]), w, init);
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn decode_avx2(out: &mut [f32], stored: &[u16], scale: f32, bias: f32) {
        use std::arch::x86_64::*;
        let n = out.len();
        let (s, b) = (_mm256_set1_ps(scale), _mm256_set1_ps(bias));
        let mut p = 0;
        while p + 8 <= n {
            let bits: [u16; 8] = stored[p..p + 8].try_into().expect("8 lanes");
            let v = _mm256_cvtph_ps(bytemuck::cast::<[u16; 8], __m128i>(bits));
            out[p..p + 8].copy_from_slice(&bytemuck::cast::<__m256, [f32; 8]>(_mm256_fmadd_ps(
                v, s, b,
            )));
            p += 8;
        }
        for (o, &h) in out[p..].iter_mut().zip(&stored[p..]) {
            *o = h.to_f32().mul_add(scale, bias);
        }
    }
}

impl Simd {
    /// [`Simd::interleave`] with non-temporal stores for the 32-byte-aligned runs of 8
    /// pixels (the frame goes to memory without being read first, and leaves the caches
    /// to the planes); the ends are stored as usual. Costs a round trip to memory when
    /// the frame would have stayed in the caches: for frames larger than them.
    pub(crate) fn interleave_stream(self, dst: &mut [f32], rows: [&[f32]; 3]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `axpy`.
            return unsafe { interleave_stream_avx2(dst, rows) };
        }
        interleave_body(dst, rows)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn interleave_stream_avx2(dst: &mut [f32], rows: [&[f32]; 3]) {
    use std::arch::x86_64::__m256;
    let n = dst.len() / 3;
    let rows = rows.map(|r| &r[..n]);
    stream_frame(
        dst,
        |p, out| interleave_body(out, rows.map(|r| &r[p..p + out.len() / 3])),
        |p| {
            let mut px = [0f32; 24];
            interleave_body(&mut px, rows.map(|r| &r[p..p + 8]));
            bytemuck::cast::<[f32; 24], [__m256; 3]>(px)
        },
    );
}

/// Write an RGB frame (3 floats a pixel): its 32-byte-aligned runs of 8 pixels from
/// `run(p)` (the three vectors of pixels `p..p+8`) with non-temporal stores, the pixels
/// before and after them with `plain(p, out)`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
fn stream_frame(
    dst: &mut [f32],
    plain: impl Fn(usize, &mut [f32]),
    run: impl Fn(usize) -> [std::arch::x86_64::__m256; 3],
) {
    use std::arch::x86_64::*;
    let n = dst.len() / 3;
    // Pixel p starts at byte 12p + a of a 32-byte line: aligned where 3p ≡ −a/4 (mod 8),
    // and 3 is its own inverse mod 8.
    let a = (dst.as_ptr() as usize % 32) / 4;
    let first = ((8 - (3 * a) % 8) % 8).min(n);
    let runs = (n - first) / 8;
    let (head, rest) = dst.split_at_mut(3 * first);
    let (body, tail) = rest.split_at_mut(24 * runs);
    plain(0, head);
    for (r, out) in body.chunks_exact_mut(24).enumerate() {
        let [x, y, z] = run(first + 8 * r);
        let at = out.as_mut_ptr();
        debug_assert_eq!(at as usize % 32, 0);
        // SAFETY: `at` points to 24 writable f32s of `out`, 32-byte aligned (above).
        unsafe {
            _mm256_stream_ps(at, x);
            _mm256_stream_ps(at.add(8), y);
            _mm256_stream_ps(at.add(16), z);
        }
    }
    plain(first + 8 * runs, tail);
    // Non-temporal stores are weakly ordered: make them visible before the frame is
    // handed to another thread (what `_mm256_stream_ps` requires).
    _mm_sfence();
}

impl Simd {
    /// Pixel `p` of `dst` (RGB) becomes entry `indices[p]` of `table`, whose entries
    /// take 4 floats (RGB and one unused, so that an entry is one 16-byte load); with
    /// non-temporal stores for the aligned runs of 8 pixels as in
    /// [`Simd::interleave_stream`]. An index past the table panics (as slicing does).
    pub(crate) fn gather_stream(self, dst: &mut [f32], table: &[f32], indices: &[u16]) {
        let n = dst.len() / 3;
        assert!(indices.len() >= n, "an index a pixel");
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `axpy`; every entry is read through a bounds-checked slice.
            return unsafe { gather_stream_avx2(dst, table, &indices[..n]) };
        }
        gather_body(dst, table, indices)
    }
}

#[inline(always)]
fn gather_body(dst: &mut [f32], table: &[f32], indices: &[u16]) {
    for (px, &i) in dst.chunks_exact_mut(3).zip(indices) {
        let e = 4 * i as usize;
        px.copy_from_slice(&table[e..e + 3]);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn gather_stream_avx2(dst: &mut [f32], table: &[f32], indices: &[u16]) {
    use std::arch::x86_64::*;
    stream_frame(
        dst,
        |p, out| gather_body(out, table, &indices[p..p + out.len() / 3]),
        |p| {
            let e: [__m128; 8] = std::array::from_fn(|j| {
                let at = 4 * indices[p + j] as usize;
                let entry: &[f32; 4] = table[at..at + 4].try_into().expect("4 floats");
                // SAFETY: `entry` is 4 readable floats (bounds-checked above).
                unsafe { _mm_loadu_ps(entry.as_ptr()) }
            });
            // Three 8-float vectors of RGB triples, built in registers: [r0 g0 b0 r1 |
            // g1 b1 r2 g2], [b2 r3 g3 b3 | r4 g4 b4 r5], [g5 b5 r6 g6 | b6 r7 g7 b7].
            let first_of = |x: __m128, y: __m128| _mm_blend_ps::<0b1000>(x, _mm_permute_ps::<0>(y));
            let middle = |x: __m128, y: __m128| _mm_shuffle_ps::<0b01_00_10_01>(x, y);
            let last_of = |x: __m128, y: __m128| {
                _mm_blend_ps::<0b0001>(
                    _mm_permute_ps::<0b10_01_00_00>(y),
                    _mm_permute_ps::<0b10_10_10_10>(x),
                )
            };
            [
                _mm256_set_m128(middle(e[1], e[2]), first_of(e[0], e[1])),
                _mm256_set_m128(first_of(e[4], e[5]), last_of(e[2], e[3])),
                _mm256_set_m128(last_of(e[6], e[7]), middle(e[5], e[6])),
            ]
        },
    );
}

#[inline(always)]
fn interleave_body(dst: &mut [f32], rows: [&[f32]; 3]) {
    for (p, px) in dst.chunks_exact_mut(3).enumerate() {
        px[0] = rows[0][p];
        px[1] = rows[1][p];
        px[2] = rows[2][p];
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn interleave_avx2(dst: &mut [f32], rows: [&[f32]; 3]) {
    interleave_body(dst, rows)
}

/// Independent FMA chains of [`Simd::fma_chains`]: more 8-lane registers than the FMA
/// latency (4 cycles) times the FMA pipes (2) needs, so the pipes never wait.
const CHAINS: usize = 12;

impl Simd {
    /// Run `iters × 96` multiply-adds on registers (no memory traffic) and return a sum
    /// that depends on all of them: the compute-bound rate of 8-lane code (AVX2, what
    /// the engine's kernels use).
    pub(crate) fn fma_chains(self, iters: usize, seed: f32) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `axpy`.
            return unsafe { fma_chains_avx2(iters, seed) };
        }
        fma_chains_body::<false>(iters, seed)
    }

    /// Whether the CPU has 16-lane FMAs (AVX-512F), the machine's widest.
    pub(crate) fn has_avx512(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            is_x86_feature_detected!("avx512f")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }

    /// [`Simd::fma_chains`] on 16-lane registers (`iters × 192` multiply-adds); `None`
    /// without AVX-512F.
    pub(crate) fn fma_chains_wide(self, iters: usize, seed: f32) -> Option<f32> {
        #[cfg(target_arch = "x86_64")]
        if self.has_avx512() {
            // SAFETY: `has_avx512` found avx512f on this CPU.
            return Some(unsafe { fma_chains_avx512(iters, seed) });
        }
        let _ = (iters, seed);
        None
    }
}

fn fma_chains_body<const FMA: bool>(iters: usize, seed: f32) -> f32 {
    let mut acc = [[seed; 8]; CHAINS];
    let (a, b) = (0.999_999_9f32, 1e-7f32);
    for _ in 0..iters {
        for r in acc.iter_mut() {
            for v in r.iter_mut() {
                *v = madd::<FMA>(*v, a, b);
            }
        }
    }
    acc.iter().flatten().sum()
}

/// Written with intrinsics: LLVM keeps plain arrays of 96 values on the stack.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn fma_chains_avx2(iters: usize, seed: f32) -> f32 {
    use std::arch::x86_64::*;
    let mut acc = [_mm256_set1_ps(seed); CHAINS];
    let (a, b) = (_mm256_set1_ps(0.999_999_9), _mm256_set1_ps(1e-7));
    for _ in 0..iters {
        for r in acc.iter_mut() {
            *r = _mm256_fmadd_ps(*r, a, b);
        }
    }
    acc.iter()
        .flat_map(|r| bytemuck::cast::<__m256, [f32; 8]>(*r))
        .sum()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn fma_chains_avx512(iters: usize, seed: f32) -> f32 {
    use std::arch::x86_64::*;
    let mut acc = [_mm512_set1_ps(seed); CHAINS];
    let (a, b) = (_mm512_set1_ps(0.999_999_9), _mm512_set1_ps(1e-7));
    for _ in 0..iters {
        for r in acc.iter_mut() {
            *r = _mm512_fmadd_ps(*r, a, b);
        }
    }
    acc.iter().map(|r| _mm512_reduce_add_ps(*r)).sum()
}

/// Multiply-adds per iteration of [`Simd::fma_chains`] (twice that for the wide one).
pub(crate) const FMA_PER_ITER: usize = CHAINS * 8;

impl Simd {
    /// Read `N` byte streams of equal length together, 64 bytes of each per step, and
    /// return the OR of all their 64-bit words: a read with the least work per byte
    /// (one OR per 32 bytes), for the read-bandwidth probe.
    pub(crate) fn or_streams<const N: usize>(self, streams: [&[u8]; N]) -> u64 {
        let n = streams.first().map_or(0, |s| s.len());
        let streams = streams.map(|s| &s[..n]);
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `axpy`.
            return unsafe { or_streams_avx2(streams) };
        }
        or_streams_body(streams, 0)
    }
}

/// The OR of the 64-bit words of the streams from byte `from` on (a tail shorter than
/// a word is read byte by byte).
#[inline(always)]
fn or_streams_body<const N: usize>(streams: [&[u8]; N], from: usize) -> u64 {
    let mut acc = 0u64;
    for s in streams {
        let mut words = s[from..].chunks_exact(8);
        for w in &mut words {
            acc |= u64::from_ne_bytes(w.try_into().expect("8 bytes"));
        }
        acc |= words.remainder().iter().fold(0, |a, &b| a | b as u64);
    }
    acc
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn or_streams_avx2<const N: usize>(streams: [&[u8]; N]) -> u64 {
    use std::arch::x86_64::*;
    let n = streams.first().map_or(0, |s| s.len());
    let mut acc = [_mm256_setzero_si256(); N];
    let mut i = 0;
    while i + 64 <= n {
        for (a, s) in acc.iter_mut().zip(&streams) {
            let lines: [u8; 64] = s[i..i + 64].try_into().expect("64 bytes");
            let [lo, hi] = bytemuck::cast::<[u8; 64], [__m256i; 2]>(lines);
            *a = _mm256_or_si256(*a, _mm256_or_si256(lo, hi));
        }
        i += 64;
    }
    let words = acc
        .iter()
        .flat_map(|a| bytemuck::cast::<__m256i, [u64; 4]>(*a))
        .fold(0, |x, w| x | w);
    words | or_streams_body(streams, i)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn both() -> [Simd; 2] {
        [Simd::baseline(), Simd::detect()]
    }

    #[test]
    fn axpy_adds_weighted_planes_for_every_type_and_count() {
        let n = 37;
        let a: Vec<f32> = (0..n).map(|i| i as f32 * 0.25 - 3.0).collect();
        let b: Vec<f32> = (0..n).map(|i| (i * i % 7) as f32).collect();
        let half_a: Vec<u16> = a.iter().map(|&v| f16::from_f32(v).to_bits()).collect();
        let half_b: Vec<u16> = b.iter().map(|&v| f16::from_f32(v).to_bits()).collect();
        let byte_b: Vec<u8> = b.iter().map(|&v| v as u8).collect();
        for simd in both() {
            let mut acc = vec![1f32; n];
            simd.axpy(&mut acc, [&a[..], &b[..]], [2.0, -1.0]);
            let mut acc16 = vec![1f32; n];
            simd.axpy(&mut acc16, [&half_a[..], &half_b[..]], [2.0, -1.0]);
            let mut acc8 = vec![1f32; n];
            simd.axpy(&mut acc8, [&byte_b[..]], [-1.0]);
            for p in 0..n {
                let want = 1.0 + 2.0 * a[p] - b[p];
                // The values are exact in f16 (quarters below 2048).
                assert_eq!(acc[p], want, "{simd:?} f32 {p}");
                assert_eq!(acc16[p], want, "{simd:?} f16 {p}");
                assert_eq!(acc8[p], 1.0 - b[p], "{simd:?} u8 {p}");
            }
            let mut out = vec![0f32; n];
            simd.decode(&mut out, &byte_b, 0.5, 1.0);
            assert_eq!(out[3], 0.5 * b[3] + 1.0);
            simd.decode(&mut out, &half_a, 1.0, 0.0);
            assert_eq!(out, a);
        }
    }

    #[test]
    fn interleave_makes_rgb_pixels() {
        let rows = [[1f32, 2.0], [3.0, 4.0], [5.0, 6.0]];
        for simd in both() {
            let mut dst = [0f32; 6];
            simd.interleave(&mut dst, [&rows[0], &rows[1], &rows[2]]);
            assert_eq!(dst, [1.0, 3.0, 5.0, 2.0, 4.0, 6.0]);
        }
        // Streaming stores at every alignment of the frame and every length.
        let rows: [Vec<f32>; 3] =
            std::array::from_fn(|c| (0..100).map(|p| (3 * p + c) as f32).collect());
        for simd in both() {
            for skip in 0..8 {
                for n in [0, 1, 7, 8, 9, 30, 100 - skip] {
                    let mut buffer = vec![-1f32; 3 * 100 + 8];
                    let dst = &mut buffer[skip..skip + 3 * n];
                    simd.interleave_stream(dst, [&rows[0][..n], &rows[1][..n], &rows[2][..n]]);
                    let want: Vec<f32> = (0..3 * n).map(|v| v as f32).collect();
                    assert_eq!(dst, &want[..], "{simd:?} skip {skip} n {n}");
                    assert!(buffer[skip + 3 * n..].iter().all(|&v| v == -1.0));
                }
            }
        }
    }

    #[test]
    fn gather_copies_each_pixels_entry_at_every_alignment() {
        let entries = 11;
        let table: Vec<f32> = (0..4 * entries).map(|v| v as f32).collect();
        let indices: Vec<u16> = (0..100).map(|p| ((p * 7) % entries) as u16).collect();
        for simd in both() {
            for skip in 0..8 {
                for n in [0, 1, 7, 8, 9, 30, 100 - skip] {
                    let mut buffer = vec![-1f32; 3 * 100 + 8];
                    let dst = &mut buffer[skip..skip + 3 * n];
                    simd.gather_stream(dst, &table, &indices[..n]);
                    for p in 0..n {
                        let e = 4 * indices[p] as usize;
                        assert_eq!(
                            &dst[3 * p..3 * p + 3],
                            &table[e..e + 3],
                            "{simd:?} {skip} {n} {p}"
                        );
                    }
                    assert!(buffer[skip + 3 * n..].iter().all(|&v| v == -1.0));
                }
            }
        }
    }

    #[test]
    fn axpy_init_starts_from_the_constant() {
        let a: Vec<f32> = (0..21).map(|i| i as f32).collect();
        let h: Vec<u16> = a.iter().map(|&v| f16::from_f32(v).to_bits()).collect();
        for simd in both() {
            let mut acc = vec![f32::NAN; 21];
            simd.axpy_init(&mut acc, [&a[..], &a[..]], [1.0, 2.0], 0.5);
            let mut acc16 = vec![f32::NAN; 21];
            simd.axpy_init(&mut acc16, [&h[..]], [3.0], 0.5);
            for p in 0..21 {
                assert_eq!(acc[p], 0.5 + 3.0 * a[p], "{simd:?}");
                assert_eq!(acc16[p], 0.5 + 3.0 * a[p], "{simd:?}");
            }
        }
    }
}
