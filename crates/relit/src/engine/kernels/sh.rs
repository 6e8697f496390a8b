//! The real SH basis in f32 at a block of per-pixel light vectors, and what the
//! positional lights do with it: dot it with the block's coefficients
//! ([`Simd::sh_dot`]), or add it up over many weighted light vectors first (the SH
//! projection of an area light's samples, [`Simd::sh_project`]) and dot that once
//! ([`Simd::rows_dot`]); [`Simd::add_weighted`] then weighs a dot by each pixel's RGB
//! and adds it to the block's sum. One recurrence ([`sh_lanes`]) feeds all of them.

use super::{madd, Simd, BLOCK};
use crate::color;

/// The SH fast path of the per-pixel kernels: the real SH basis of `bands` bands by
/// the vectorised recurrence below, exact to f32 rounding (no table). Hemispherical
/// harmonics are defined as `√2·Y_lm` at the hemisphere stretched over the sphere
/// ([`crate::basis::HemisphericalHarmonics`]), so the same recurrence serves them
/// after that stretch ([`Warp::Hemisphere`]).
#[derive(Clone, Debug)]
pub(crate) struct ShKernel {
    bands: usize,
    norms: ShNorms,
    warp: Warp,
}

/// What the kernel does to the light vectors before the recurrence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Warp {
    /// The real SH basis itself.
    None,
    /// Hemispherical harmonics: `z` clamped to `[0, 1]`, `(x, y, z)` sent to
    /// `(a·x, a·y, 2z − 1)` with `a = 2·√(z/(1+z))`, every function times `√2`.
    Hemisphere,
}

impl ShKernel {
    /// The kernel of `basis` if it is the real SH basis or hemispherical harmonics;
    /// other bases take the weight-table path.
    pub(crate) fn of(basis: &dyn crate::basis::Basis) -> Option<Self> {
        let any = basis.as_any();
        if let Some(sh) = any.downcast_ref::<crate::basis::SphericalHarmonics>() {
            return Self::new(sh.bands(), Warp::None);
        }
        let hsh = any.downcast_ref::<crate::basis::HemisphericalHarmonics>()?;
        Self::new(hsh.order(), Warp::Hemisphere)
    }

    /// The kernel of `bands` bands (1 to 8).
    pub(crate) fn new(bands: usize, warp: Warp) -> Option<Self> {
        let mut norms = ShNorms::new();
        if warp == Warp::Hemisphere {
            norms
                .k
                .iter_mut()
                .for_each(|k| *k *= std::f32::consts::SQRT_2);
        }
        (1..=8)
            .contains(&bands)
            .then_some(Self { bands, norms, warp })
    }

    pub(crate) fn len(&self) -> usize {
        self.bands * self.bands
    }

    /// `sh recurrence` or `hsh recurrence`.
    pub(crate) fn name(&self) -> &'static str {
        match self.warp {
            Warp::None => "sh recurrence",
            Warp::Hemisphere => "hsh recurrence",
        }
    }

    /// `f` of the light vectors the recurrence reads: `dir` itself, or (HSH) `dir`
    /// stretched over the sphere into a buffer that only this case fills.
    #[inline]
    fn with_dirs<R>(&self, dir: &[[f32; BLOCK]; 3], f: impl FnOnce(&[[f32; BLOCK]; 3]) -> R) -> R {
        match self.warp {
            Warp::None => f(dir),
            Warp::Hemisphere => {
                let mut stretched = [[0.0; BLOCK]; 3];
                for p in 0..BLOCK {
                    let z = dir[2][p].clamp(0.0, 1.0);
                    let a = 2.0 * (z / (1.0 + z)).sqrt();
                    stretched[0][p] = a * dir[0][p];
                    stretched[1][p] = a * dir[1][p];
                    stretched[2][p] = 2.0 * z - 1.0;
                }
                f(&stretched)
            }
        }
    }

    /// [`Simd::sh_values`].
    pub(crate) fn values(&self, simd: Simd, dir: &[[f32; BLOCK]; 3], out: &mut [[f32; BLOCK]]) {
        self.with_dirs(dir, |d| simd.sh_values(self.bands, &self.norms, d, out))
    }

    /// [`Simd::sh_project`].
    pub(crate) fn project(
        &self,
        simd: Simd,
        dir: &[[f32; BLOCK]; 3],
        w: &[f32; BLOCK],
        out: &mut [[f32; BLOCK]],
    ) {
        self.with_dirs(dir, |d| simd.sh_project(self.bands, &self.norms, d, w, out))
    }

    /// [`Simd::sh_dot`]: the recurrence feeds the dot directly, no rows in between.
    pub(crate) fn dot(
        &self,
        simd: Simd,
        dir: &[[f32; BLOCK]; 3],
        values: Rows,
        out: &mut [[f32; BLOCK]; 3],
    ) {
        self.with_dirs(dir, |d| {
            simd.sh_dot(self.bands, &self.norms, d, values, out)
        })
    }
}

/// Rows of [`BLOCK`] values at a stride: row `j` is `data[j·stride + offset ..][..BLOCK]`.
#[derive(Clone, Copy)]
pub(crate) struct Rows<'a> {
    pub data: &'a [f32],
    pub stride: usize,
    pub offset: usize,
}

impl Rows<'_> {
    #[inline(always)]
    fn row(&self, j: usize) -> &[f32; BLOCK] {
        let at = j * self.stride + self.offset;
        self.data[at..at + BLOCK].try_into().expect("a block")
    }
}

/// `K_lm` (m = 0) and `√2·K_lm` (m > 0) at `l · 8 + m`: the normalisation of
/// `basis::sh`, and the recurrence's `(2l − 1)/(l − m)`, `(l + m − 1)/(l − m)`.
#[derive(Clone, Debug)]
pub(crate) struct ShNorms {
    k: [f32; 64],
    a: [f32; 64],
    b: [f32; 64],
}

impl ShNorms {
    pub(crate) fn new() -> Self {
        let mut out = Self {
            k: [0.0; 64],
            a: [0.0; 64],
            b: [0.0; 64],
        };
        for l in 0..8usize {
            for m in 0..=l {
                let j = l * 8 + m;
                out.k[j] = crate::basis::sh::normalisation(l, m) as f32;
                if l > m + 1 {
                    out.a[j] = ((2 * l - 1) as f64 / (l - m) as f64) as f32;
                    out.b[j] = ((l + m - 1) as f64 / (l - m) as f64) as f32;
                }
            }
        }
        out
    }
}

/// Eight f32 lanes: one AVX2 register inside the `avx2` wrappers (LLVM maps each
/// lane-wise operation to one instruction), two SSE registers elsewhere.
#[derive(Clone, Copy)]
struct F8([f32; 8]);

impl F8 {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        F8([v; 8])
    }
    #[inline(always)]
    fn load(s: &[f32]) -> Self {
        F8(s[..8].try_into().expect("8 lanes"))
    }
    #[inline(always)]
    fn store(self, s: &mut [f32]) {
        s[..8].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        F8(std::array::from_fn(|i| self.0[i] + o.0[i]))
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        F8(std::array::from_fn(|i| self.0[i] * o.0[i]))
    }
    #[inline(always)]
    fn scale(self, k: f32) -> Self {
        F8(self.0.map(|v| v * k))
    }
    /// `self · a + b`
    #[inline(always)]
    fn madd<const FMA: bool>(self, a: Self, b: Self) -> Self {
        F8(std::array::from_fn(|i| {
            madd::<FMA>(self.0[i], a.0[i], b.0[i])
        }))
    }
    /// `self · a − b`
    #[inline(always)]
    fn msub<const FMA: bool>(self, a: Self, b: Self) -> Self {
        F8(std::array::from_fn(|i| {
            madd::<FMA>(self.0[i], a.0[i], -b.0[i])
        }))
    }
}

/// What [`sh_lanes`] hands the basis values to, as it makes them. Implementations are
/// structs with `#[inline(always)]` methods, not closures: closures do not inherit the
/// caller's target features, and `mul_add` outside them is a call to the C library
/// (10× slower, measured).
trait ShSink {
    /// `Y_i` at the eight pixels.
    fn put(&mut self, i: usize, y: F8);
    /// One `(l, m)` step of the recurrence is done (its one or two values were put).
    #[inline(always)]
    fn step(&mut self) {}
}

/// The SH basis of `B` bands at eight unit vectors, the recurrence of `basis::sh`
/// in f32, wholly in registers: each value goes to `sink` as it is made and is never
/// stored by the recurrence. The block-wide version before it kept `cos mφ`, `sin mφ`,
/// the Legendre rows and the sums in 64-lane arrays in L1 and was bound by their
/// stores: point-light frames (1024×256, k = 16) are 1.05–1.2× faster this way.
/// `B` is a constant (see [`with_bands`]) so that the loops unroll and the integer
/// work of the recurrence (indices, `2m ± 1` as floats, bounds) folds away: with
/// `bands` a variable it was as many instructions as the vector work.
#[inline(always)]
fn sh_lanes<const FMA: bool, const B: usize>(
    norm: &ShNorms,
    [x, y, z]: [F8; 3],
    sink: &mut impl ShSink,
) {
    let (mut cm, mut sm) = (F8::splat(1.0), F8::splat(0.0));
    let mut pmm = 1f32;
    for m in 0..B {
        if m > 0 {
            (cm, sm) = (x.msub::<FMA>(cm, y.mul(sm)), x.madd::<FMA>(sm, y.mul(cm)));
            pmm *= -((2 * m - 1) as f32);
        }
        let mut p_prev = F8::splat(0.0);
        let mut p_cur = F8::splat(pmm);
        for l in m..B {
            let j = l * 8 + m;
            if l == m + 1 {
                p_prev = p_cur;
                p_cur = z.scale((2 * m + 1) as f32 * pmm);
            } else if l > m + 1 {
                let next = z
                    .scale(norm.a[j])
                    .msub::<FMA>(p_cur, p_prev.scale(norm.b[j]));
                p_prev = p_cur;
                p_cur = next;
            }
            let kp = p_cur.scale(norm.k[j]);
            let base = l * (l + 1);
            if m == 0 {
                sink.put(base, kp);
            } else {
                sink.put(base - m, kp.mul(sm));
                sink.put(base + m, kp.mul(cm));
            }
            sink.step();
        }
    }
}

/// `sum[c] += y · row(j + c)[q..q + 8]` for the three channels.
#[inline(always)]
fn add3<const FMA: bool>(sum: &mut [F8; 3], y: F8, values: &Rows, j: usize, q: usize) {
    for (c, s) in sum.iter_mut().enumerate() {
        *s = y.madd::<FMA>(F8::load(&values.row(j + c)[q..]), *s);
    }
}

/// `Σ_i Y_i · row(3i + c)` per channel, in two sums per channel taking turns at each
/// step: half as long a chain of dependent multiply-adds (latency, not throughput,
/// bounded a single sum).
struct Dot<'v, const FMA: bool> {
    sum: [F8; 3],
    other: [F8; 3],
    values: Rows<'v>,
    q: usize,
}

impl<'v, const FMA: bool> Dot<'v, FMA> {
    #[inline(always)]
    fn new(values: Rows<'v>, q: usize) -> Self {
        let zero = [F8::splat(0.0); 3];
        Self {
            sum: zero,
            other: zero,
            values,
            q,
        }
    }
    /// Store the three channel sums at `out[c][q..q + 8]`.
    #[inline(always)]
    fn store(&self, out: &mut [[f32; BLOCK]; 3]) {
        for ((o, s), t) in out.iter_mut().zip(self.sum).zip(self.other) {
            s.add(t).store(&mut o[self.q..]);
        }
    }
}

impl<const FMA: bool> ShSink for Dot<'_, FMA> {
    #[inline(always)]
    fn put(&mut self, i: usize, y: F8) {
        add3::<FMA>(&mut self.sum, y, &self.values, 3 * i, self.q);
    }
    #[inline(always)]
    fn step(&mut self) {
        std::mem::swap(&mut self.sum, &mut self.other);
    }
}

/// `out[i][q..q + 8] += w · Y_i`.
struct Project<'o, const FMA: bool> {
    w: F8,
    out: &'o mut [[f32; BLOCK]],
    q: usize,
}

impl<const FMA: bool> ShSink for Project<'_, FMA> {
    #[inline(always)]
    fn put(&mut self, i: usize, y: F8) {
        let o = &mut self.out[i][self.q..];
        y.madd::<FMA>(self.w, F8::load(o)).store(o);
    }
}

/// `out[i][q..q + 8] = Y_i`.
struct Store<'o> {
    out: &'o mut [[f32; BLOCK]],
    q: usize,
}

impl ShSink for Store<'_> {
    #[inline(always)]
    fn put(&mut self, i: usize, y: F8) {
        y.store(&mut self.out[i][self.q..]);
    }
}

#[inline(always)]
fn lanes(dir: &[[f32; BLOCK]; 3], q: usize) -> [F8; 3] {
    dir.each_ref().map(|d| F8::load(&d[q..]))
}

/// `f::<B>(args)` for `B = bands` (1 to 8): the kernels' band count as a constant.
macro_rules! with_bands {
    ($bands:expr, $f:ident::<$fma:literal>($($arg:expr),*)) => {
        match $bands {
            1 => $f::<$fma, 1>($($arg),*),
            2 => $f::<$fma, 2>($($arg),*),
            3 => $f::<$fma, 3>($($arg),*),
            4 => $f::<$fma, 4>($($arg),*),
            5 => $f::<$fma, 5>($($arg),*),
            6 => $f::<$fma, 6>($($arg),*),
            7 => $f::<$fma, 7>($($arg),*),
            8 => $f::<$fma, 8>($($arg),*),
            b => panic!("SH kernels take 1 to 8 bands, not {b}"),
        }
    };
}

#[inline(always)]
fn sh_dot_body<const FMA: bool, const B: usize>(
    norm: &ShNorms,
    dir: &[[f32; BLOCK]; 3],
    values: Rows,
    out: &mut [[f32; BLOCK]; 3],
) {
    for q in (0..BLOCK).step_by(8) {
        let mut dot = Dot::<FMA>::new(values, q);
        sh_lanes::<FMA, B>(norm, lanes(dir, q), &mut dot);
        dot.store(out);
    }
}

#[inline(always)]
fn sh_project_body<const FMA: bool, const B: usize>(
    norm: &ShNorms,
    dir: &[[f32; BLOCK]; 3],
    w: &[f32; BLOCK],
    out: &mut [[f32; BLOCK]],
) {
    let out = &mut out[..B * B];
    for q in (0..BLOCK).step_by(8) {
        let w = F8::load(&w[q..]);
        if w.0 == [0.0; 8] {
            continue;
        }
        let mut sink = Project::<FMA> { w, out, q };
        sh_lanes::<FMA, B>(norm, lanes(dir, q), &mut sink);
    }
}

#[inline(always)]
fn rows_dot_body<const FMA: bool>(
    basis: &[[f32; BLOCK]],
    values: Rows,
    out: &mut [[f32; BLOCK]; 3],
) {
    for q in (0..BLOCK).step_by(8) {
        let mut dot = Dot::<FMA>::new(values, q);
        for (i, row) in basis.iter().enumerate() {
            dot.put(i, F8::load(&row[q..]));
            dot.step();
        }
        dot.store(out);
    }
}

#[inline(always)]
fn sh_values_body<const FMA: bool, const B: usize>(
    norm: &ShNorms,
    dir: &[[f32; BLOCK]; 3],
    out: &mut [[f32; BLOCK]],
) {
    let out = &mut out[..B * B];
    for q in (0..BLOCK).step_by(8) {
        sh_lanes::<FMA, B>(norm, lanes(dir, q), &mut Store { out, q });
    }
}

#[inline(always)]
fn add_weighted_body(
    display: bool,
    dot: &[[f32; BLOCK]; 3],
    w: &[[f32; BLOCK]; 3],
    acc: &mut [[f32; BLOCK]; 3],
) {
    for ((a, d), w) in acc.iter_mut().zip(dot).zip(w) {
        for p in 0..BLOCK {
            let v = if display {
                color::srgb_to_linear(d[p].clamp(0.0, 1.0))
            } else {
                d[p]
            };
            // Pixels the light does not reach add nothing, even where their
            // coefficients are not finite.
            a[p] += if w[p] != 0.0 { w[p] * v } else { 0.0 };
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;

    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn sh_dot(
        bands: usize,
        norm: &ShNorms,
        dir: &[[f32; BLOCK]; 3],
        values: Rows,
        out: &mut [[f32; BLOCK]; 3],
    ) {
        with_bands!(bands, sh_dot_body::<true>(norm, dir, values, out))
    }

    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn sh_project(
        bands: usize,
        norm: &ShNorms,
        dir: &[[f32; BLOCK]; 3],
        w: &[f32; BLOCK],
        out: &mut [[f32; BLOCK]],
    ) {
        with_bands!(bands, sh_project_body::<true>(norm, dir, w, out))
    }

    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn rows_dot(
        basis: &[[f32; BLOCK]],
        values: Rows,
        out: &mut [[f32; BLOCK]; 3],
    ) {
        rows_dot_body::<true>(basis, values, out)
    }

    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn sh_values(
        bands: usize,
        norm: &ShNorms,
        dir: &[[f32; BLOCK]; 3],
        out: &mut [[f32; BLOCK]],
    ) {
        with_bands!(bands, sh_values_body::<true>(norm, dir, out))
    }

    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn add_weighted(
        display: bool,
        dot: &[[f32; BLOCK]; 3],
        w: &[[f32; BLOCK]; 3],
        acc: &mut [[f32; BLOCK]; 3],
    ) {
        add_weighted_body(display, dot, w, acc)
    }
}

impl Simd {
    /// `out[c][p] = Σ_i Y_i(dir_p)·v(3i + c)[p]` over one block: the SH basis of
    /// `bands` bands at the unit vectors `dir` dotted with the block's coefficient
    /// values, row `j` of `values` being plane `j` (plane order, `3i + c`).
    pub(crate) fn sh_dot(
        self,
        bands: usize,
        norm: &ShNorms,
        dir: &[[f32; BLOCK]; 3],
        values: Rows,
        out: &mut [[f32; BLOCK]; 3],
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `detect` found avx2, fma and f16c on this CPU.
            return unsafe { avx2::sh_dot(bands, norm, dir, values, out) };
        }
        with_bands!(bands, sh_dot_body::<false>(norm, dir, values, out))
    }

    /// `out[i][p] += w[p]·Y_i(dir_p)` for `i < bands²`: adds weighted light vectors
    /// into their SH projection (eight pixels of zero weight are skipped).
    pub(crate) fn sh_project(
        self,
        bands: usize,
        norm: &ShNorms,
        dir: &[[f32; BLOCK]; 3],
        w: &[f32; BLOCK],
        out: &mut [[f32; BLOCK]],
    ) {
        let out = &mut out[..bands * bands];
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `sh_dot`.
            return unsafe { avx2::sh_project(bands, norm, dir, w, out) };
        }
        with_bands!(bands, sh_project_body::<false>(norm, dir, w, out))
    }

    /// `out[c][p] = Σ_i basis[i][p]·v(3i + c)[p]`: [`Simd::sh_dot`] with the basis
    /// values given (a projection made by [`Simd::sh_project`]).
    pub(crate) fn rows_dot(
        self,
        basis: &[[f32; BLOCK]],
        values: Rows,
        out: &mut [[f32; BLOCK]; 3],
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `sh_dot`.
            return unsafe { avx2::rows_dot(basis, values, out) };
        }
        rows_dot_body::<false>(basis, values, out)
    }

    /// The SH basis of `bands` bands at a block of unit vectors: `out[i][p] = Y_i(dir_p)`
    /// (`out` holds at least `bands²` rows), the recurrence of [`Simd::sh_dot`].
    pub(crate) fn sh_values(
        self,
        bands: usize,
        norm: &ShNorms,
        dir: &[[f32; BLOCK]; 3],
        out: &mut [[f32; BLOCK]],
    ) {
        let out = &mut out[..bands * bands];
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `sh_dot`.
            return unsafe { avx2::sh_values(bands, norm, dir, out) };
        }
        with_bands!(bands, sh_values_body::<false>(norm, dir, out))
    }

    /// `acc[c][p] += w[c][p]·f(dot[c][p])` where `w[c][p] ≠ 0` (nothing elsewhere),
    /// `f` the sRGB decode of display-referred maps (clamped to `[0, 1]` first) or
    /// the identity: one light vector's contribution to a block.
    pub(crate) fn add_weighted(
        self,
        display: bool,
        dot: &[[f32; BLOCK]; 3],
        w: &[[f32; BLOCK]; 3],
        acc: &mut [[f32; BLOCK]; 3],
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `sh_dot`.
            return unsafe { avx2::add_weighted(display, dot, w, acc) };
        }
        add_weighted_body(display, dot, w, acc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{Basis, SphericalHarmonics};
    use crate::sphere::{fibonacci, Vec3};

    fn both() -> [Simd; 2] {
        [Simd::baseline(), Simd::detect()]
    }

    /// |Y| ≤ 1.2 for 8 bands; the f32 recurrence keeps ~1e-6 relative accuracy.
    const F32_SH_TOLERANCE: f64 = 2e-5;

    fn block_of(dirs: &[Vec3]) -> [[f32; BLOCK]; 3] {
        let mut dir = [[0f32; BLOCK]; 3];
        for (p, d) in dirs.iter().enumerate() {
            dir[0][p] = d.x as f32;
            dir[1][p] = d.y as f32;
            dir[2][p] = d.z as f32;
        }
        dir
    }

    /// The fast f32 dot equals `SphericalHarmonics::eval` for every band count and every
    /// (l, m): each coefficient plane is a one-hot, so the dot is `Y_i` itself; so is
    /// the dot of the projection of one unit-weight vector per pixel.
    #[test]
    fn f32_sh_equals_the_basis_for_every_band() {
        let dirs: Vec<Vec3> = fibonacci(BLOCK - 2)
            .into_iter()
            .chain([Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -1.0)])
            .collect();
        let dir = block_of(&dirs);
        let norm = ShNorms::new();
        for simd in both() {
            for bands in 1..=8 {
                let sh = SphericalHarmonics::new(bands).unwrap();
                let k = bands * bands;
                let mut projection = vec![[0f32; BLOCK]; k];
                simd.sh_project(bands, &norm, &dir, &[1.0; BLOCK], &mut projection);
                for i in 0..k {
                    // Channel c of coefficient i holds c + 1, every other value 0.
                    let mut values = vec![0f32; 3 * k * BLOCK];
                    for c in 0..3 {
                        values[(3 * i + c) * BLOCK..(3 * i + c + 1) * BLOCK].fill((c + 1) as f32);
                    }
                    let rows = Rows {
                        data: &values,
                        stride: BLOCK,
                        offset: 0,
                    };
                    let mut acc = [[f32::NAN; BLOCK]; 3];
                    simd.sh_dot(bands, &norm, &dir, rows, &mut acc);
                    let mut from_projection = [[f32::NAN; BLOCK]; 3];
                    simd.rows_dot(&projection, rows, &mut from_projection);
                    for (p, d) in dirs.iter().enumerate() {
                        let want = sh.values(*d)[i];
                        for c in 0..3 {
                            for got in [acc[c][p], from_projection[c][p]] {
                                let got = got as f64 / (c + 1) as f64;
                                assert!(
                                    (got - want).abs() < F32_SH_TOLERANCE,
                                    "{simd:?} bands {bands} Y{i} at {d:?}: {got} vs {want}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn f32_sh_values_equal_the_basis() {
        let dirs = fibonacci(BLOCK);
        let dir = block_of(&dirs);
        let norm = ShNorms::new();
        for simd in both() {
            for bands in 1..=8 {
                let sh = SphericalHarmonics::new(bands).unwrap();
                let mut out = vec![[0f32; BLOCK]; bands * bands];
                simd.sh_values(bands, &norm, &dir, &mut out);
                for (p, d) in dirs.iter().enumerate() {
                    for (i, want) in sh.values(*d).into_iter().enumerate() {
                        assert!(
                            (out[i][p] as f64 - want).abs() < F32_SH_TOLERANCE,
                            "{simd:?} bands {bands} Y{i}"
                        );
                    }
                }
            }
        }
    }

    /// The projection of weighted vectors is the weighted sum of their basis values;
    /// zero weights add nothing; the weighted sum skips unreached pixels even where
    /// the dot is not finite, and decodes display-referred values.
    #[test]
    fn projections_add_up_and_weights_mask() {
        let norm = ShNorms::new();
        let a = block_of(&fibonacci(BLOCK));
        let b = block_of(&fibonacci(BLOCK + 7)[7..]);
        let w: [f32; BLOCK] = std::array::from_fn(|p| if p < 8 { 0.0 } else { p as f32 / 9.0 });
        for simd in both() {
            let (mut ya, mut yb) = (vec![[0f32; BLOCK]; 16], vec![[0f32; BLOCK]; 16]);
            simd.sh_values(4, &norm, &a, &mut ya);
            simd.sh_values(4, &norm, &b, &mut yb);
            let mut projection = vec![[0f32; BLOCK]; 16];
            simd.sh_project(4, &norm, &a, &[0.5; BLOCK], &mut projection);
            simd.sh_project(4, &norm, &b, &w, &mut projection);
            for i in 0..16 {
                for p in 0..BLOCK {
                    let want = 0.5 * ya[i][p] + w[p] * yb[i][p];
                    assert!((projection[i][p] - want).abs() < 1e-6, "{simd:?} Y{i} {p}");
                }
            }
            let dot = [[f32::INFINITY; BLOCK], [0.5; BLOCK], [2.0; BLOCK]];
            let weights = [[0.0; BLOCK], [2.0; BLOCK], [1.0; BLOCK]];
            for display in [false, true] {
                let mut acc = [[1f32; BLOCK]; 3];
                simd.add_weighted(display, &dot, &weights, &mut acc);
                let half = if display {
                    color::srgb_to_linear(0.5)
                } else {
                    0.5
                };
                let two = if display { 1.0 } else { 2.0 };
                assert_eq!(acc[0], [1.0; BLOCK]);
                assert_eq!(acc[1], [1.0 + 2.0 * half; BLOCK]);
                assert_eq!(acc[2], [1.0 + two; BLOCK]);
            }
        }
    }
}
