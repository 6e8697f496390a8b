//! The small dense linear algebra the fit needs: Cholesky factorisation of k×k systems
//! (k ≤ 64) in double precision, and matrix products through `matrixmultiply`.

/// Factor the symmetric positive definite `n×n` row-major matrix `a` in place into its
/// lower Cholesky factor `L` (`a = L Lᵀ`; the upper triangle is left as garbage).
/// Returns `false` if `a` is not numerically positive definite.
pub fn cholesky(a: &mut [f64], n: usize) -> bool {
    cholesky_pivots(a, n) == n
}

/// [`cholesky`], returning how many leading pivots were positive: `n` where `a` is
/// positive definite. The factorisation goes a column at a time and its first `p`
/// columns read only the leading `p×p` block, so for every `p` up to the returned
/// count the factor's leading block is that block's own factor, bit for bit.
pub fn cholesky_pivots(a: &mut [f64], n: usize) -> usize {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d <= 0.0 || !d.is_finite() {
            return j;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        let inv = 1.0 / d;
        for i in (j + 1)..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s * inv;
        }
    }
    n
}

/// Solve `L z = b` in place (forward substitution with the factor from [`cholesky`]).
pub fn forward_solve(l: &[f64], n: usize, b: &mut [f64]) {
    forward_solve_leading(l, n, n, b);
}

/// [`forward_solve`] with the leading `n×n` block of a factor stored `stride` wide.
pub fn forward_solve_leading(l: &[f64], n: usize, stride: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * stride + k] * b[k];
        }
        b[i] = s / l[i * stride + i];
    }
}

/// Solve `Lᵀ x = z` in place (back substitution).
pub fn backward_solve(l: &[f64], n: usize, b: &mut [f64]) {
    backward_solve_leading(l, n, n, b);
}

/// [`backward_solve`] with the leading `n×n` block of a factor stored `stride` wide.
pub fn backward_solve_leading(l: &[f64], n: usize, stride: usize, b: &mut [f64]) {
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in (i + 1)..n {
            s -= l[k * stride + i] * b[k];
        }
        b[i] = s / l[i * stride + i];
    }
}

/// Solve `a x = b` given the Cholesky factor of `a`, in place.
pub fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    cholesky_solve_leading(l, n, n, b);
}

/// [`cholesky_solve`] with the leading `n×n` block of a factor stored `stride` wide:
/// the solve of that block's system where [`cholesky_pivots`] reached `n`.
pub fn cholesky_solve_leading(l: &[f64], n: usize, stride: usize, b: &mut [f64]) {
    forward_solve_leading(l, n, stride, b);
    backward_solve_leading(l, n, stride, b);
}

/// `pub fn NAME(args) -> R = BODY, AVX2;` defines `NAME`, which runs the
/// `#[inline(always)]` function `BODY` compiled for AVX2 where the CPU has it (a lane
/// group in two registers), else as built, and the compiled copy `AVX2`. Both run the
/// same operations in the same order: the results are the same bits. (An AVX-512 copy, a lane group in one register, measured
/// no faster on the shared RTI items: 1–2 %, within this machine's noise.)
macro_rules! dispatched {
    (
        $(#[$doc:meta])*
        pub fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)?
            = $body:ident, $avx2:ident $(,)?;
    ) => {
        $(#[$doc])*
        pub fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            if is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 is present.
                return unsafe { $avx2($($arg),*) };
            }
            $body($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        unsafe fn $avx2($($arg: $ty),*) $(-> $ret)? {
            $body($($arg),*)
        }
    };
}

/// Systems solved together by [`cholesky_lanes`] and [`cholesky_solve_lanes`]: two
/// AVX2 registers of doubles. Eight independent chains rather than four took 5–17 % off
/// the default fit's processor time on the shared RTI items (2026-12-06).
pub const LANES: usize = 8;

/// One value per lane.
pub type Lanes = [f64; LANES];

dispatched! {
    /// [`cholesky`] of [`LANES`] matrices at once, interleaved: entry `(r, c)` of matrix `l`
    /// at `a[r·n + c][l]`. Each lane runs exactly the scalar routine's operations in the
    /// same order, so its factor is the scalar factor bit for bit; the lanes are
    /// independent chains that the processor overlaps (the scalar routine waits on each
    /// subtraction in turn). Per lane, how many leading pivots were positive (as
    /// [`cholesky_pivots`]): beyond them a lane's factor is meaningless; the other lanes
    /// are unaffected.
    pub fn cholesky_lanes_pivots(a: &mut [Lanes], n: usize) -> [usize; LANES]
        = cholesky_lanes_body, cholesky_lanes_avx2;
}

/// [`cholesky_lanes_pivots`]: which lanes' matrices were positive definite.
pub fn cholesky_lanes(a: &mut [Lanes], n: usize) -> [bool; LANES] {
    cholesky_lanes_pivots(a, n).map(|p| p == n)
}

/// Rows below the diagonal that [`cholesky_lanes_body`] updates together.
const ROWS: usize = 4;

#[inline(always)]
fn cholesky_lanes_body(a: &mut [Lanes], n: usize) -> [usize; LANES] {
    let mut pivots = [n; LANES];
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            let x = a[j * n + k];
            for l in 0..LANES {
                d[l] -= x[l] * x[l];
            }
        }
        let mut inv = [0.0; LANES];
        for l in 0..LANES {
            if d[l] <= 0.0 || !d[l].is_finite() {
                pivots[l] = pivots[l].min(j);
                d[l] = 1.0;
            }
            d[l] = d[l].sqrt();
            inv[l] = 1.0 / d[l];
        }
        a[j * n + j] = d;
        // `ROWS` rows at a time: their sums are independent chains, each still
        // subtracting its terms in the scalar order (one row's chain alone waits on
        // every subtraction).
        let mut i = j + 1;
        while i + ROWS <= n {
            let mut s: [Lanes; ROWS] = std::array::from_fn(|r| a[(i + r) * n + j]);
            for k in 0..j {
                let y = a[j * n + k];
                for (r, sr) in s.iter_mut().enumerate() {
                    let x = a[(i + r) * n + k];
                    for l in 0..LANES {
                        sr[l] -= x[l] * y[l];
                    }
                }
            }
            for (r, sr) in s.iter_mut().enumerate() {
                for l in 0..LANES {
                    sr[l] *= inv[l];
                }
                a[(i + r) * n + j] = *sr;
            }
            i += ROWS;
        }
        for i in i..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                let (x, y) = (a[i * n + k], a[j * n + k]);
                for l in 0..LANES {
                    s[l] -= x[l] * y[l];
                }
            }
            for l in 0..LANES {
                s[l] *= inv[l];
            }
            a[i * n + j] = s;
        }
    }
    pivots
}

dispatched! {
    /// [`cholesky_solve`] for the [`LANES`] interleaved factors of [`cholesky_lanes`] and
    /// right-hand sides `b[i][l]`, in place; bit for bit the scalar solves.
    pub fn cholesky_solve_lanes(f: &[Lanes], n: usize, b: &mut [Lanes])
        = cholesky_solve_lanes_body, cholesky_solve_lanes_avx2;
}

#[inline(always)]
fn cholesky_solve_lanes_body(f: &[Lanes], n: usize, b: &mut [Lanes]) {
    for i in 0..n {
        b[i] = substitute(b[i], (0..i).map(|k| (f[i * n + k], b[k])), f[i * n + i]);
    }
    for i in (0..n).rev() {
        b[i] = substitute(b[i], (i + 1..n).map(|k| (f[k * n + i], b[k])), f[i * n + i]);
    }
}

dispatched! {
    /// [`cholesky_solve_lanes`] of two systems side by side, `(fa, ba)` and `(fb, bb)` (the
    /// factors may be the same), each bit for bit its own solve: a substitution waits on
    /// every subtraction in turn, and two independent ones fill each other's waits. The
    /// factors are stored `stride` wide and their leading `n×n` blocks solve (as
    /// [`cholesky_solve_leading`]).
    pub fn cholesky_solve_lanes_pair(
        fa: &[Lanes],
        fb: &[Lanes],
        n: usize,
        stride: usize,
        ba: &mut [Lanes],
        bb: &mut [Lanes],
    ) = cholesky_solve_lanes_pair_body, cholesky_solve_lanes_pair_avx2;
}

#[inline(always)]
fn cholesky_solve_lanes_pair_body(
    fa: &[Lanes],
    fb: &[Lanes],
    n: usize,
    stride: usize,
    ba: &mut [Lanes],
    bb: &mut [Lanes],
) {
    // One step of both substitutions: `(s − Σ x·y) / d` for each, terms in order.
    #[inline(always)]
    fn step(
        (mut sa, mut sb): (Lanes, Lanes),
        terms: impl Iterator<Item = (Lanes, Lanes, Lanes, Lanes)>,
        da: Lanes,
        db: Lanes,
    ) -> (Lanes, Lanes) {
        for (xa, ya, xb, yb) in terms {
            for l in 0..LANES {
                sa[l] -= xa[l] * ya[l];
                sb[l] -= xb[l] * yb[l];
            }
        }
        for l in 0..LANES {
            sa[l] /= da[l];
            sb[l] /= db[l];
        }
        (sa, sb)
    }
    for i in 0..n {
        let (a, b) = step(
            (ba[i], bb[i]),
            (0..i).map(|k| (fa[i * stride + k], ba[k], fb[i * stride + k], bb[k])),
            fa[i * stride + i],
            fb[i * stride + i],
        );
        (ba[i], bb[i]) = (a, b);
    }
    for i in (0..n).rev() {
        let (a, b) = step(
            (ba[i], bb[i]),
            (i + 1..n).map(|k| (fa[k * stride + i], ba[k], fb[k * stride + i], bb[k])),
            fa[i * stride + i],
            fb[i * stride + i],
        );
        (ba[i], bb[i]) = (a, b);
    }
}

/// `(s − Σ x·y) / d` lane by lane, subtracting the terms in order: one step of forward
/// or back substitution.
#[inline(always)]
fn substitute(mut s: Lanes, terms: impl Iterator<Item = (Lanes, Lanes)>, d: Lanes) -> Lanes {
    for (x, y) in terms {
        for l in 0..LANES {
            s[l] -= x[l] * y[l];
        }
    }
    for l in 0..LANES {
        s[l] /= d[l];
    }
    s
}

/// One single-precision value per lane.
pub type LanesF32 = [f32; LANES];

/// `m[l] as f64` lane by lane (exact), two lanes an instruction: with [`plus_scaled`], a
/// lane group's regularised normal-matrix entry from its single-precision sum. LLVM
/// compiled the plain loop one lane at a time (per lane a conversion, a product, a sum
/// and a store: 8 % of a large perceptual fit's processor time, 2026-12-07).
#[inline(always)]
pub fn widened(m: &LanesF32) -> Lanes {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let mut out = [0.0; LANES];
        // SAFETY: SSE2 is part of x86_64; each quad of lanes is read, and each pair
        // written, inside its array of eight.
        unsafe {
            for h in (0..LANES).step_by(4) {
                let narrow = _mm_loadu_ps(m.as_ptr().add(h));
                _mm_storeu_pd(out.as_mut_ptr().add(h), _mm_cvtps_pd(narrow));
                let high = _mm_cvtps_pd(_mm_movehl_ps(narrow, narrow));
                _mm_storeu_pd(out.as_mut_ptr().add(h + 2), high);
            }
        }
        out
    }
    #[cfg(not(target_arch = "x86_64"))]
    m.map(|v| v as f64)
}

/// `m[l] + scale[l]·p` lane by lane: the product, then the sum, as the scalar expression
/// rounds them, two lanes an instruction.
#[inline(always)]
pub fn plus_scaled(m: &Lanes, scale: &Lanes, p: f64) -> Lanes {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let mut out = [0.0; LANES];
        // SAFETY: SSE2 is part of x86_64; each pair of lanes is read and written inside
        // its array of eight.
        unsafe {
            let p = _mm_set1_pd(p);
            for at in (0..LANES).step_by(2) {
                let s = _mm_mul_pd(_mm_loadu_pd(scale.as_ptr().add(at)), p);
                let sum = _mm_add_pd(_mm_loadu_pd(m.as_ptr().add(at)), s);
                _mm_storeu_pd(out.as_mut_ptr().add(at), sum);
            }
        }
        out
    }
    #[cfg(not(target_arch = "x86_64"))]
    std::array::from_fn(|l| m[l] + scale[l] * p)
}

/// `w[l] · (o[l] as f32)` lane by lane (an observation rounded to single precision,
/// then weighted), four lanes an instruction.
#[inline(always)]
pub fn times_narrowed(w: &LanesF32, o: &Lanes) -> LanesF32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let mut out = [0.0f32; LANES];
        // SAFETY: SSE2 is part of x86_64; each quad of lanes is read and written inside
        // its array of eight.
        unsafe {
            for h in (0..LANES).step_by(4) {
                let low = _mm_cvtpd_ps(_mm_loadu_pd(o.as_ptr().add(h)));
                let high = _mm_cvtpd_ps(_mm_loadu_pd(o.as_ptr().add(h + 2)));
                let narrow = _mm_movelh_ps(low, high);
                let product = _mm_mul_ps(_mm_loadu_ps(w.as_ptr().add(h)), narrow);
                _mm_storeu_ps(out.as_mut_ptr().add(h), product);
            }
        }
        out
    }
    #[cfg(not(target_arch = "x86_64"))]
    std::array::from_fn(|l| w[l] * o[l] as f32)
}

/// The columns of a [`lane_products`] table come in tiles of this many (a tile's sums
/// stay in registers while the table's rows go by).
pub const PRODUCT_TILE: usize = 12;

/// `columns` rounded up to whole tiles of [`lane_products`]: how wide its tables' rows are
/// stored.
pub fn tiled(columns: usize) -> usize {
    columns.next_multiple_of(PRODUCT_TILE)
}

/// `out[x][l] = Σ_j lanes[j][l] · table[j·cols + x]` for each of the `cols` columns of a
/// row-major table of `lanes.len()` rows (`cols` a multiple of [`PRODUCT_TILE`]): per
/// lane, a row vector times a matrix shared by the lanes. Each sum runs over `j` in
/// order from zero, by fused multiply-adds where the CPU has them (as matrixmultiply's
/// kernels compute a matrix product; products and sums otherwise, as its kernels for
/// processors without FMA do). The per-pixel fit forms eight pixels' normal matrices and
/// right-hand sides so, lane-major as the lane factorisation reads them, without
/// packing the shared table again for each product.
pub fn lane_products(lanes: &[LanesF32], table: &[f32], cols: usize, out: &mut [LanesF32]) {
    check_lane_products(lanes.len(), table.len(), cols, out.len());
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        // SAFETY: AVX2 and FMA are present; the lengths were checked above.
        unsafe { lane_products_fma(lanes, table, cols, out) };
        return;
    }
    lane_products_portable(lanes, table, cols, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn lane_products_fma(lanes: &[LanesF32], table: &[f32], cols: usize, out: &mut [LanesF32]) {
    use std::arch::x86_64::*;
    for x0 in (0..cols).step_by(PRODUCT_TILE) {
        let mut acc = [_mm256_setzero_ps(); PRODUCT_TILE];
        for (j, w) in lanes.iter().enumerate() {
            // SAFETY: row j's tile lies inside the table (checked by the caller).
            let row = unsafe { table.as_ptr().add(j * cols + x0) };
            let w = unsafe { _mm256_loadu_ps(w.as_ptr()) };
            for (i, a) in acc.iter_mut().enumerate() {
                *a = _mm256_fmadd_ps(w, unsafe { _mm256_broadcast_ss(&*row.add(i)) }, *a);
            }
        }
        for (o, a) in out[x0..x0 + PRODUCT_TILE].iter_mut().zip(acc) {
            // SAFETY: eight floats are written to a lane array of eight.
            unsafe { _mm256_storeu_ps(o.as_mut_ptr(), a) };
        }
    }
}

/// [`lane_products`] in double precision: `out[x][l] = Σ_j lanes[j][l] · table[j·cols +
/// x]`, each sum over `j` in order from zero, fused where the CPU has FMA. The per-pixel
/// fit predicts eight pixels' samples from their coefficients so.
pub fn lane_products_f64(lanes: &[Lanes], table: &[f64], cols: usize, out: &mut [Lanes]) {
    check_lane_products(lanes.len(), table.len(), cols, out.len());
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        // SAFETY: AVX2 and FMA are present; the lengths were checked above.
        unsafe { lane_products_f64_fma(lanes, table, cols, out) };
        return;
    }
    lane_products_portable(lanes, table, cols, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn lane_products_f64_fma(lanes: &[Lanes], table: &[f64], cols: usize, out: &mut [Lanes]) {
    use std::arch::x86_64::*;
    // Half a tile of columns at a time: a lane vector is two registers of doubles.
    const HALF: usize = PRODUCT_TILE / 2;
    for x0 in (0..cols).step_by(HALF) {
        let mut acc = [[_mm256_setzero_pd(); 2]; HALF];
        for (j, w) in lanes.iter().enumerate() {
            // SAFETY: row j's half tile lies inside the table (checked by the caller).
            let row = unsafe { table.as_ptr().add(j * cols + x0) };
            let w = unsafe {
                [
                    _mm256_loadu_pd(w.as_ptr()),
                    _mm256_loadu_pd(w.as_ptr().add(4)),
                ]
            };
            for (i, a) in acc.iter_mut().enumerate() {
                let t = unsafe { _mm256_broadcast_sd(&*row.add(i)) };
                a[0] = _mm256_fmadd_pd(w[0], t, a[0]);
                a[1] = _mm256_fmadd_pd(w[1], t, a[1]);
            }
        }
        for (o, a) in out[x0..x0 + HALF].iter_mut().zip(acc) {
            // SAFETY: eight doubles are written to a lane array of eight.
            unsafe {
                _mm256_storeu_pd(o.as_mut_ptr(), a[0]);
                _mm256_storeu_pd(o.as_mut_ptr().add(4), a[1]);
            }
        }
    }
}

/// The lengths [`lane_products`] and [`lane_products_f64`] need.
fn check_lane_products(rows: usize, table: usize, cols: usize, out: usize) {
    assert!(cols.is_multiple_of(PRODUCT_TILE) && table >= rows * cols && out >= cols);
}

/// [`lane_products`] without fused multiply-adds, in either precision.
fn lane_products_portable<T>(lanes: &[[T; LANES]], table: &[T], cols: usize, out: &mut [[T; LANES]])
where
    T: Copy + Default + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    for x0 in (0..cols).step_by(PRODUCT_TILE) {
        let mut acc = [[T::default(); LANES]; PRODUCT_TILE];
        for (j, w) in lanes.iter().enumerate() {
            let row = &table[j * cols + x0..j * cols + x0 + PRODUCT_TILE];
            for (a, &t) in acc.iter_mut().zip(row) {
                for l in 0..LANES {
                    a[l] = a[l] + w[l] * t;
                }
            }
        }
        out[x0..x0 + PRODUCT_TILE].copy_from_slice(&acc);
    }
}

/// `c = a · b` for row-major `a` (m×k), `b` (k×n), `c` (m×n), overwriting `c`.
pub fn matmul(m: usize, k: usize, n: usize, a: &[f64], b: &[f64], c: &mut [f64]) {
    assert!(a.len() >= m * k && b.len() >= k * n && c.len() >= m * n);
    dgemm(m, k, n, (a, k, 1), (b, n, 1), c);
}

/// `c = a · bᵀ` for row-major `a` (m×k), `b` (n×k), `c` (m×n), overwriting `c`.
pub fn matmul_bt(m: usize, k: usize, n: usize, a: &[f64], b: &[f64], c: &mut [f64]) {
    assert!(a.len() >= m * k && b.len() >= n * k && c.len() >= m * n);
    // b is read through transposed strides that stay inside its n×k extent.
    dgemm(m, k, n, (a, k, 1), (b, 1, k), c);
}

/// `c = aᵀ · b` for row-major `a` (k×m), `b` (k×n), `c` (m×n), overwriting `c`.
pub fn matmul_at(m: usize, k: usize, n: usize, a: &[f64], b: &[f64], c: &mut [f64]) {
    assert!(a.len() >= k * m && b.len() >= k * n && c.len() >= m * n);
    // a is read through transposed strides that stay inside its k×m extent.
    dgemm(m, k, n, (a, 1, m), (b, n, 1), c);
}

/// `c = a · b` (m×k by k×n into row-major m×n) with `a` and `b` given as (slice, row
/// stride, column stride); the callers check that the strides stay inside the slices.
fn dgemm(
    m: usize,
    k: usize,
    n: usize,
    (a, rsa, csa): (&[f64], usize, usize),
    (b, rsb, csb): (&[f64], usize, usize),
    c: &mut [f64],
) {
    if m == 0 || n == 0 {
        return;
    }
    // SAFETY: the public wrappers assert that every element addressed by these strides
    // (at most (rows−1)·rs + (cols−1)·cs) lies inside its slice, and c is m×n.
    unsafe {
        matrixmultiply::dgemm(
            m,
            k,
            n,
            1.0,
            a.as_ptr(),
            rsa as isize,
            csa as isize,
            b.as_ptr(),
            rsb as isize,
            csb as isize,
            0.0,
            c.as_mut_ptr(),
            n as isize,
            1,
        );
    }
}

/// Eigen-decomposition of the symmetric `n×n` row-major matrix `a` (n up to a few
/// hundred): eigenvalues in descending order and the matching unit eigenvectors,
/// vector `i` at `vectors[i·n..(i+1)·n]`.
///
/// Householder reduction to tridiagonal form, then the implicit QL algorithm (as in
/// EISPACK's `tred2`/`tql2`): about `9n³` operations against cyclic Jacobi's `3n³` per
/// sweep over six to ten sweeps, with rows rather than columns in the inner loops.
/// Measured on the basis choice of RealRTI item1 (≈120 decompositions of 54×54), it
/// took the eigen-decompositions from 13 % of the choice's time to under 2 %.
/// A matrix with a non-finite entry gives non-finite results rather than a hang.
pub fn symmetric_eigen(a: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(a.len(), n * n, "an n×n matrix");
    if n == 0 {
        return (Vec::new(), Vec::new());
    }
    if a.iter().any(|v| !v.is_finite()) {
        return (vec![f64::NAN; n], vec![f64::NAN; n * n]);
    }
    // `z` holds the transformations transposed (row i of z is column i of the
    // eigenvector matrix), so the rotations of the QL sweeps run along rows.
    let mut z = a.to_vec();
    let mut d = vec![0.0; n];
    let mut e = vec![0.0; n];
    tridiagonalize(&mut z, n, &mut d, &mut e);
    if !tridiagonal_ql(&mut z, n, &mut d, &mut e) {
        return (vec![f64::NAN; n], vec![f64::NAN; n * n]);
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| d[j].total_cmp(&d[i]));
    let values = order.iter().map(|&i| d[i]).collect();
    let mut vectors = vec![0.0; n * n];
    for (r, &i) in order.iter().enumerate() {
        vectors[r * n..(r + 1) * n].copy_from_slice(&z[i * n..(i + 1) * n]);
    }
    (values, vectors)
}

/// Householder reduction of the symmetric `z` (n×n) to a tridiagonal matrix with
/// diagonal `d` and sub-diagonal `e[1..]`; on return row `i` of `z` is column `i` of
/// the orthogonal transformation (`A = Q T Qᵀ`, `z = Qᵀ`).
fn tridiagonalize(z: &mut [f64], n: usize, d: &mut [f64], e: &mut [f64]) {
    // Work on the lower triangle with `v[r][c] = z[r·n + c]`; the accumulated
    // transformation is built in place, then transposed at the end.
    let at = |r: usize, c: usize| r * n + c;
    d.copy_from_slice(&z[at(n - 1, 0)..at(n - 1, 0) + n]);
    for i in (1..n).rev() {
        let scale: f64 = d[..i].iter().map(|v| v.abs()).sum();
        let mut h = 0.0;
        if scale == 0.0 {
            e[i] = d[i - 1];
            for j in 0..i {
                d[j] = z[at(i - 1, j)];
                z[at(i, j)] = 0.0;
                z[at(j, i)] = 0.0;
            }
        } else {
            for v in &mut d[..i] {
                *v /= scale;
                h += *v * *v;
            }
            let f = d[i - 1];
            let g = if f > 0.0 { -h.sqrt() } else { h.sqrt() };
            e[i] = scale * g;
            h -= f * g;
            d[i - 1] = f - g;
            e[..i].fill(0.0);
            for j in 0..i {
                let f = d[j];
                z[at(j, i)] = f;
                let mut g = e[j] + z[at(j, j)] * f;
                for k in j + 1..i {
                    g += z[at(k, j)] * d[k];
                    e[k] += z[at(k, j)] * f;
                }
                e[j] = g;
            }
            let mut f = 0.0;
            for j in 0..i {
                e[j] /= h;
                f += e[j] * d[j];
            }
            let hh = f / (h + h);
            for j in 0..i {
                e[j] -= hh * d[j];
            }
            for j in 0..i {
                let (f, g) = (d[j], e[j]);
                for k in j..i {
                    z[at(k, j)] -= f * e[k] + g * d[k];
                }
                d[j] = z[at(i - 1, j)];
                z[at(i, j)] = 0.0;
            }
        }
        d[i] = h;
    }
    // Accumulate the transformations.
    for i in 0..n - 1 {
        z[at(n - 1, i)] = z[at(i, i)];
        z[at(i, i)] = 1.0;
        let h = d[i + 1];
        if h != 0.0 {
            for k in 0..=i {
                d[k] = z[at(k, i + 1)] / h;
            }
            for j in 0..=i {
                let mut g = 0.0;
                for k in 0..=i {
                    g += z[at(k, i + 1)] * z[at(k, j)];
                }
                for k in 0..=i {
                    z[at(k, j)] -= g * d[k];
                }
            }
        }
        for k in 0..=i {
            z[at(k, i + 1)] = 0.0;
        }
    }
    for j in 0..n {
        d[j] = z[at(n - 1, j)];
        z[at(n - 1, j)] = 0.0;
    }
    z[at(n - 1, n - 1)] = 1.0;
    e[0] = 0.0;
    // Columns are the transformation's vectors: transpose so rows are.
    for r in 0..n {
        for c in r + 1..n {
            z.swap(at(r, c), at(c, r));
        }
    }
}

/// Implicit QL iterations on the tridiagonal (`d`, `e[1..]`), rotating the rows of `z`
/// along: on return `d` holds the eigenvalues and row `i` of `z` the unit eigenvector
/// of `d[i]`. False if an eigenvalue does not converge within 60 iterations.
fn tridiagonal_ql(z: &mut [f64], n: usize, d: &mut [f64], e: &mut [f64]) -> bool {
    const MAX_ITERATIONS: usize = 60;
    for i in 1..n {
        e[i - 1] = e[i];
    }
    e[n - 1] = 0.0;
    let (mut f, mut tst1) = (0.0f64, 0.0f64);
    let eps = f64::EPSILON;
    for l in 0..n {
        tst1 = tst1.max(d[l].abs() + e[l].abs());
        let mut m = l;
        while m < n - 1 && e[m].abs() > eps * tst1 {
            m += 1;
        }
        if m > l {
            let mut iterations = 0;
            loop {
                iterations += 1;
                if iterations > MAX_ITERATIONS {
                    return false;
                }
                let g = d[l];
                let mut p = (d[l + 1] - g) / (2.0 * e[l]);
                let mut r = p.hypot(1.0);
                if p < 0.0 {
                    r = -r;
                }
                d[l] = e[l] / (p + r);
                d[l + 1] = e[l] * (p + r);
                let dl1 = d[l + 1];
                let h = g - d[l];
                for v in &mut d[l + 2..n] {
                    *v -= h;
                }
                f += h;
                p = d[m];
                let (mut c, mut c2, mut c3) = (1.0, 1.0, 1.0);
                let el1 = e[l + 1];
                let (mut s, mut s2) = (0.0, 0.0);
                for i in (l..m).rev() {
                    c3 = c2;
                    c2 = c;
                    s2 = s;
                    let g = c * e[i];
                    let h = c * p;
                    r = p.hypot(e[i]);
                    e[i + 1] = s * r;
                    s = e[i] / r;
                    c = p / r;
                    p = c * d[i] - s * g;
                    d[i + 1] = h + s * (c * g + s * d[i]);
                    let (lo, hi) = z.split_at_mut((i + 1) * n);
                    let (zi, zi1) = (&mut lo[i * n..], &mut hi[..n]);
                    for (a, b) in zi.iter_mut().zip(zi1.iter_mut()) {
                        let h = *b;
                        *b = s * *a + c * h;
                        *a = c * *a - s * h;
                    }
                }
                p = -s * s2 * c3 * el1 * e[l] / dl1;
                e[l] = s * p;
                d[l] = c * p;
                if e[l].abs() <= eps * tst1 {
                    break;
                }
            }
        }
        d[l] += f;
        e[l] = 0.0;
    }
    true
}

/// Up to this many values a row, [`principal_directions`] finds them all by a symmetric
/// eigendecomposition (and its first `k` do not depend on `k`); above, the first `k`
/// by subspace iteration.
pub const EXACT_PCA_LIGHTS: usize = 400;

/// The `k` leading principal directions (uncentred: of the second-moment matrix) of
/// `rows` row vectors of length `n` (row-major `x`), vector `i` at `[i·n..(i+1)·n]`.
/// Exact (Gram matrix and [`symmetric_eigen`]) up to n = [`EXACT_PCA_LIGHTS`]; beyond,
/// randomised subspace iteration with Rayleigh–Ritz, which costs `O(rows·n·k)` per step.
pub fn principal_directions(x: &[f64], rows: usize, n: usize, k: usize) -> Vec<f64> {
    use rayon::prelude::*;
    assert_eq!(x.len(), rows * n, "rows of n values");
    let k = k.min(n);
    let gram_times = |q: &[f64], cols: usize| -> Vec<f64> {
        // (Xᵀ X) Q for Q n×cols stored column-major (column j at q[j·n..]), i.e. the
        // row-major cols×n matrix Qᵀ; the result likewise: Qᵀ XᵀX = (X Q)ᵀ X, summed
        // over blocks of rows (two GEMMs each). The blocks are summed in a fixed order
        // (in at most GROUPS groups of consecutive blocks, then the groups in order):
        // a parallel reduction's order follows the work stealing, and a fit's basis
        // tables, a sharded fit's parts and a compressed file's bytes must not.
        const BLOCK: usize = 256;
        const GROUPS: usize = 32;
        let per_group = rows.div_ceil(BLOCK).div_ceil(GROUPS).max(1);
        let add = |mut a: Vec<f64>, b: &[f64]| {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
            a
        };
        x.par_chunks(n * BLOCK * per_group)
            .map(|group| {
                let mut acc = vec![0.0; cols * n];
                let mut part = vec![0.0; cols * n];
                for block in group.chunks(n * BLOCK) {
                    let r = block.len() / n;
                    let mut xq = vec![0.0; r * cols];
                    matmul_bt(r, n, cols, block, q, &mut xq);
                    matmul_at(cols, r, n, &xq, block, &mut part);
                    acc = add(acc, &part);
                }
                acc
            })
            .collect::<Vec<_>>()
            .iter()
            .fold(vec![0.0; n * cols], |a, b| add(a, b))
    };
    if n <= EXACT_PCA_LIGHTS {
        let mut identity = vec![0.0; n * n];
        (0..n).for_each(|i| identity[i * n + i] = 1.0);
        let gram = gram_times(&identity, n); // symmetric: column-major = row-major
        let (_, vectors) = symmetric_eigen(&gram, n);
        return vectors[..k * n].to_vec();
    }
    let cols = (k + 10).min(n);
    // A fixed pseudo-random start keeps fits deterministic.
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut q: Vec<f64> = (0..n * cols)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect();
    orthonormalize(&mut q, n, cols);
    for _ in 0..6 {
        q = gram_times(&q, cols);
        orthonormalize(&mut q, n, cols);
    }
    // Rayleigh–Ritz in the subspace.
    let gq = gram_times(&q, cols);
    let mut small = vec![0.0; cols * cols];
    for i in 0..cols {
        for j in 0..cols {
            small[i * cols + j] = q[i * n..(i + 1) * n]
                .iter()
                .zip(&gq[j * n..(j + 1) * n])
                .map(|(a, b)| a * b)
                .sum();
        }
    }
    let (_, vectors) = symmetric_eigen(&small, cols);
    let mut out = vec![0.0; k * n];
    for r in 0..k {
        for j in 0..cols {
            let w = vectors[r * cols + j];
            for (o, &v) in out[r * n..(r + 1) * n]
                .iter_mut()
                .zip(&q[j * n..(j + 1) * n])
            {
                *o += w * v;
            }
        }
    }
    out
}

/// Orthonormalise the `cols` column vectors (each `n` long, contiguous) in place by
/// modified Gram–Schmidt, twice (enough for full double precision).
fn orthonormalize(q: &mut [f64], n: usize, cols: usize) {
    for _ in 0..2 {
        for j in 0..cols {
            for i in 0..j {
                let (head, tail) = q.split_at_mut(j * n);
                let qi = &head[i * n..(i + 1) * n];
                let qj = &mut tail[..n];
                let d: f64 = qi.iter().zip(qj.iter()).map(|(a, b)| a * b).sum();
                qj.iter_mut().zip(qi).for_each(|(b, a)| *b -= d * a);
            }
            let qj = &mut q[j * n..(j + 1) * n];
            let norm = qj.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
            qj.iter_mut().for_each(|v| *v /= norm);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each column's lane sums as a chain over the rows in order from zero, one `step(acc,
    /// w, t)` a row.
    fn lane_chains<T: Copy>(
        lanes: &[[T; LANES]],
        table: &[T],
        cols: usize,
        zero: T,
        step: impl Fn(T, T, T) -> T,
    ) -> Vec<[T; LANES]> {
        (0..cols)
            .map(|x| {
                std::array::from_fn(|l| {
                    (lanes.iter().enumerate())
                        .fold(zero, |acc, (j, w)| step(acc, w[l], table[j * cols + x]))
                })
            })
            .collect()
    }

    #[test]
    fn lane_entries_are_the_scalar_expressions_bit_for_bit() {
        // Values over many decades and both signs, zeros, a subnormal, infinities and
        // NaN, in every lane position, against the expressions written a lane at a time.
        let specials = [
            0.0,
            -0.0,
            1e-310,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        let value = |i: usize| -> f64 {
            match i % 11 {
                0..=5 => specials[i % 6],
                _ => (i as f64 * 0.7311).sin() * 10f64.powi((i % 23) as i32 - 11),
            }
        };
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for t in 0..200 {
            let wide: Lanes = std::array::from_fn(|l| value(t * 8 + l));
            let scale: Lanes = std::array::from_fn(|l| value(t * 13 + 3 * l + 1));
            let narrow: LanesF32 = std::array::from_fn(|l| value(t * 17 + 5 * l + 2) as f32);
            let p = value(t * 7 + 4);
            let got = plus_scaled(&widened(&narrow), &scale, p);
            let plus = plus_scaled(&wide, &scale, p);
            let times = times_narrowed(&narrow, &wide);
            for l in 0..LANES {
                let want = narrow[l] as f64 + scale[l] * p;
                assert!(same(got[l], want), "{t}/{l}: {} against {want}", got[l]);
                let want = wide[l] + scale[l] * p;
                assert!(same(plus[l], want), "{t}/{l}: {} against {want}", plus[l]);
                let want = narrow[l] * wide[l] as f32;
                assert!(
                    same(times[l] as f64, want as f64),
                    "{t}/{l}: {} against {want}",
                    times[l]
                );
            }
        }
    }

    #[test]
    fn lane_products_are_each_lanes_sums_in_order() {
        // Each output a chain over the rows in order from zero: fused where the CPU
        // fuses (the dispatched kernel), products then sums otherwise (the portable
        // loop, tested on every machine).
        #[cfg(target_arch = "x86_64")]
        let fused = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
        #[cfg(not(target_arch = "x86_64"))]
        let fused = false;
        let mut state = 7u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32 - 0.3
        };
        for (rows, cols) in [(1, PRODUCT_TILE), (49, 48), (300, 2 * PRODUCT_TILE)] {
            let lanes: Vec<LanesF32> = (0..rows).map(|_| std::array::from_fn(|_| next())).collect();
            let table: Vec<f32> = (0..rows * cols).map(|_| next()).collect();
            let plain = lane_chains(&lanes, &table, cols, 0.0, |a, w, t| a + w * t);
            let dispatched = if fused {
                lane_chains(&lanes, &table, cols, 0.0, |a, w, t| w.mul_add(t, a))
            } else {
                plain.clone()
            };
            let mut out = vec![[f32::NAN; LANES]; cols];
            lane_products(&lanes, &table, cols, &mut out);
            assert_eq!(out, dispatched, "{rows}×{cols}");
            lane_products_portable(&lanes, &table, cols, &mut out);
            assert_eq!(out, plain, "{rows}×{cols}");
            // The same in double precision.
            let lanes: Vec<Lanes> = lanes.iter().map(|w| w.map(|v| v as f64 / 3.0)).collect();
            let table: Vec<f64> = table.iter().map(|&v| v as f64 / 7.0).collect();
            let plain = lane_chains(&lanes, &table, cols, 0.0, |a, w, t| a + w * t);
            let dispatched = if fused {
                lane_chains(&lanes, &table, cols, 0.0, |a, w, t| w.mul_add(t, a))
            } else {
                plain.clone()
            };
            let mut out = vec![[f64::NAN; LANES]; cols];
            lane_products_f64(&lanes, &table, cols, &mut out);
            assert_eq!(out, dispatched, "f64 {rows}×{cols}");
            lane_products_portable(&lanes, &table, cols, &mut out);
            assert_eq!(out, plain, "f64 {rows}×{cols}");
            if fused && rows > 1 {
                assert_ne!(
                    plain, dispatched,
                    "fused chains round differently ({rows} rows)"
                );
            }
        }
    }

    #[test]
    fn principal_directions_are_the_same_bits_on_any_number_of_threads() {
        // Enough rows for many blocks, exact (n ≤ 400) and randomised (n > 400) paths.
        for (rows, n) in [(20_000, 12), (3_000, 420)] {
            let x: Vec<f64> = (0..rows * n)
                .map(|i| ((i * 7919) % 1009) as f64 / 1009.0 - 0.5)
                .collect();
            let on = |threads: usize| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| principal_directions(&x, rows, n, 4))
            };
            let one = on(1);
            for threads in [2, 3, 7] {
                assert!(
                    on(threads) == one,
                    "{threads} threads, {rows}×{n}: other directions than on one"
                );
            }
        }
    }

    #[test]
    fn principal_directions_are_the_leading_eigenvectors() {
        // Rows drawn along three known orthogonal directions with falling energy, plus a
        // little of everything: both the exact and the randomised path find them.
        for n in [12usize, 450] {
            let dir = |d: usize| -> Vec<f64> {
                (0..n)
                    .map(|i| ((i * (d + 3) + d) as f64 * 0.7).sin())
                    .collect()
            };
            let mut basis = [dir(0), dir(1), dir(2)];
            let mut flat = basis.concat();
            orthonormalize(&mut flat, n, 3);
            for (d, b) in basis.iter_mut().enumerate() {
                b.copy_from_slice(&flat[d * n..(d + 1) * n]);
            }
            let rows = 600;
            let mut x = vec![0.0; rows * n];
            for r in 0..rows {
                for (d, b) in basis.iter().enumerate() {
                    let a = [9.0, 4.0, 2.0][d] * ((r * (d + 1)) as f64 * 1.3).cos();
                    for i in 0..n {
                        x[r * n + i] += a * b[i];
                    }
                }
                x[r * n + r % n] += 0.01;
            }
            let u = principal_directions(&x, rows, n, 3);
            for d in 0..3 {
                let dot: f64 = u[d * n..(d + 1) * n]
                    .iter()
                    .zip(&basis[d])
                    .map(|(a, b)| a * b)
                    .sum();
                assert!(dot.abs() > 0.999, "n {n}: direction {d}: {dot}");
            }
        }
    }

    #[test]
    fn eigen_decomposition_reconstructs_the_matrix() {
        // Random symmetric matrices of many sizes, a diagonal one with repeated values,
        // the zero matrix and a rank-one one: A v = λ v, unit orthogonal vectors,
        // descending values.
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut cases: Vec<(usize, Vec<f64>)> = Vec::new();
        for n in [1usize, 2, 3, 5, 17, 54, 90] {
            let mut a = vec![0.0; n * n];
            for r in 0..n {
                for c in r..n {
                    let v = next();
                    a[r * n + c] = v;
                    a[c * n + r] = v;
                }
            }
            cases.push((n, a));
        }
        let mut diag = vec![0.0; 16];
        for (i, v) in [2.0, 2.0, -1.0, 0.0].iter().enumerate() {
            diag[i * 4 + i] = *v;
        }
        cases.push((4, diag));
        cases.push((6, vec![0.0; 36]));
        let u: Vec<f64> = (0..7).map(|i| i as f64 - 3.0).collect();
        cases.push((7, (0..49).map(|i| u[i / 7] * u[i % 7]).collect()));
        for (n, a) in cases {
            let (values, vectors) = symmetric_eigen(&a, n);
            let scale = a.iter().map(|v| v.abs()).fold(1.0, f64::max);
            for i in 0..n {
                if i > 0 {
                    assert!(values[i - 1] >= values[i], "n {n}: order");
                }
                let v = &vectors[i * n..(i + 1) * n];
                for r in 0..n {
                    let av: f64 = (0..n).map(|c| a[r * n + c] * v[c]).sum();
                    assert!((av - values[i] * v[r]).abs() < 1e-10 * scale, "n {n}, {i}");
                }
                for j in 0..n {
                    let dot: f64 = v
                        .iter()
                        .zip(&vectors[j * n..(j + 1) * n])
                        .map(|(x, y)| x * y)
                        .sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((dot - want).abs() < 1e-10, "n {n}: vectors {i}, {j}: {dot}");
                }
            }
        }
        let (values, _) = symmetric_eigen(&[1.0, f64::NAN, f64::NAN, 1.0], 2);
        assert!(
            values.iter().all(|v| !v.is_finite()),
            "non-finite in, non-finite out"
        );
    }

    #[test]
    fn symmetric_eigen_diagonalises() {
        let a = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 1.0];
        let (values, vectors) = symmetric_eigen(&a, 3);
        assert!(values[0] >= values[1] && values[1] >= values[2]);
        for i in 0..3 {
            let v = &vectors[i * 3..i * 3 + 3];
            for r in 0..3 {
                let av: f64 = (0..3).map(|c| a[r * 3 + c] * v[c]).sum();
                assert!((av - values[i] * v[r]).abs() < 1e-10);
            }
        }
    }

    /// `M Mᵀ + ridge·I` (symmetric positive definite) for an `n×n` matrix `M` of small
    /// integers modulo `modulus`, scaled.
    fn spd(n: usize, modulus: usize, ridge: f64) -> Vec<f64> {
        let m: Vec<f64> = (0..n * n)
            .map(|i| ((i * 7 % modulus) as f64 - (modulus / 2) as f64) / 3.0)
            .collect();
        let mut a = vec![0.0; n * n];
        matmul_bt(n, n, n, &m, &m, &mut a);
        (0..n).for_each(|i| a[i * n + i] += ridge);
        a
    }

    /// What lets a validation judge every size of a nested basis from the largest one's
    /// systems: the leading block of a factor is the factor of the leading block, and a
    /// solve with it is that block's solve, bit for bit (scalar and lanes), also for a
    /// matrix whose later pivots fail.
    #[test]
    fn a_leading_block_of_a_factor_solves_as_its_own_system() {
        let n = 25;
        let whole = spd(n, 13, 0.1);
        let mut failing = whole.clone();
        failing[17 * n + 17] = -1.0;
        for (a, positive) in [(&whole, n), (&failing, 17)] {
            let mut f = a.clone();
            assert_eq!(cholesky_pivots(&mut f, n), positive);
            let mut lanes: Vec<Lanes> = a.iter().map(|&v| [v; LANES]).collect();
            assert_eq!(cholesky_lanes_pivots(&mut lanes, n), [positive; LANES]);
            for p in [4, 9, 16, 17, 25].into_iter().filter(|&p| p <= positive) {
                let mut own: Vec<f64> = (0..p * p).map(|x| a[(x / p) * n + x % p]).collect();
                assert!(cholesky(&mut own, p));
                for r in 0..p {
                    for c in 0..=r {
                        assert_eq!(f[r * n + c].to_bits(), own[r * p + c].to_bits());
                        assert_eq!(lanes[r * n + c][3].to_bits(), own[r * p + c].to_bits());
                    }
                }
                let rhs: Vec<f64> = (0..p).map(|i| i as f64 - 1.5).collect();
                let (mut leading, mut alone) = (rhs.clone(), rhs.clone());
                cholesky_solve_leading(&f, p, n, &mut leading);
                cholesky_solve(&own, p, &mut alone);
                let mut first: Vec<Lanes> = rhs.iter().map(|&v| [v; LANES]).collect();
                let mut second = first.clone();
                cholesky_solve_lanes_pair(&lanes, &lanes, p, n, &mut first, &mut second);
                for i in 0..p {
                    assert_eq!(leading[i].to_bits(), alone[i].to_bits());
                    assert_eq!(first[i][5].to_bits(), alone[i].to_bits());
                    assert_eq!(second[i][0].to_bits(), alone[i].to_bits());
                }
            }
        }
    }

    #[test]
    fn lanes_factor_and_solve_as_the_scalar_routines_do() {
        // Four different SPD systems and one that is not: each lane equals the scalar
        // result bit for bit, and the failing lane does not disturb the others; sizes
        // with and without rows left over from the four-row groups.
        for n in [7, 12, 25] {
            lanes_match_the_scalar_routines(n);
        }
    }

    fn lanes_match_the_scalar_routines(n: usize) {
        let mut mats = Vec::new();
        for lane in 0..LANES {
            let m: Vec<f64> = (0..n * n)
                .map(|i| (((i + 3 * lane) * 7 % 13) as f64 - 6.0) / (3.0 + lane as f64))
                .collect();
            let mut a = vec![0.0; n * n];
            matmul_bt(n, n, n, &m, &m, &mut a);
            (0..n).for_each(|i| a[i * n + i] += 0.1);
            if lane == 2 {
                a[3 * n + 3] = -1.0;
            }
            mats.push(a);
        }
        let mut packed = vec![[0.0; LANES]; n * n];
        let mut rhs = vec![[0.0; LANES]; n];
        for (l, a) in mats.iter().enumerate() {
            for (x, v) in a.iter().enumerate() {
                packed[x][l] = *v;
            }
            for (i, r) in rhs.iter_mut().enumerate() {
                r[l] = i as f64 - 2.5 + l as f64;
            }
        }
        // The plain build and the dispatched one (AVX2 where present) agree too.
        let (mut plain, mut plain_rhs) = (packed.clone(), rhs.clone());
        let plain_ok = cholesky_lanes_body(&mut plain, n);
        cholesky_solve_lanes_body(&plain, n, &mut plain_rhs);
        let pivots = cholesky_lanes_pivots(&mut packed, n);
        let ok = pivots.map(|p| p == n);
        let (mut first, mut second) = (
            rhs.clone(),
            rhs.iter().map(|r| r.map(|v| -2.0 * v)).collect::<Vec<_>>(),
        );
        cholesky_solve_lanes(&packed, n, &mut rhs);
        assert_eq!(plain_ok, pivots);
        // Two systems side by side (here one factor twice, the second right-hand side
        // scaled): each as it is alone.
        let mut second_alone = second.clone();
        cholesky_solve_lanes(&packed, n, &mut second_alone);
        cholesky_solve_lanes_pair(&packed, &packed, n, n, &mut first, &mut second);
        for (p, q) in first
            .iter()
            .zip(&rhs)
            .chain(second.iter().zip(&second_alone))
        {
            for l in 0..LANES {
                assert_eq!(p[l].to_bits(), q[l].to_bits());
            }
        }
        for (p, q) in plain.iter().zip(&packed).chain(plain_rhs.iter().zip(&rhs)) {
            for l in 0..LANES {
                assert_eq!(p[l].to_bits(), q[l].to_bits());
            }
        }
        for (l, a) in mats.iter().enumerate() {
            let mut f = a.clone();
            let scalar_pivots = cholesky_pivots(&mut f.clone(), n);
            assert_eq!(pivots[l], scalar_pivots, "lane {l}");
            let scalar_ok = cholesky(&mut f, n);
            assert_eq!(ok[l], scalar_ok, "lane {l}");
            assert_eq!(scalar_ok, l != 2);
            if !scalar_ok {
                continue;
            }
            let mut b: Vec<f64> = (0..n).map(|i| i as f64 - 2.5 + l as f64).collect();
            cholesky_solve(&f, n, &mut b);
            for x in 0..n * n {
                assert_eq!(packed[x][l].to_bits(), f[x].to_bits(), "lane {l} factor");
            }
            for i in 0..n {
                assert_eq!(rhs[i][l].to_bits(), b[i].to_bits(), "lane {l} solution");
            }
        }
    }

    #[test]
    fn cholesky_solves_an_spd_system() {
        let n = 5;
        let a = spd(n, 11, 1.0);
        let x_true: Vec<f64> = (0..n).map(|i| i as f64 - 1.5).collect();
        let mut b = vec![0.0; n];
        matmul_bt(1, n, n, &x_true, &a, &mut b); // a is symmetric: x·aᵀ = a·x
        let mut l = a.clone();
        assert!(cholesky(&mut l, n));
        cholesky_solve(&l, n, &mut b);
        for (x, t) in b.iter().zip(&x_true) {
            assert!((x - t).abs() < 1e-10);
        }
        let mut not_pd = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky(&mut not_pd, 2));
    }
}
