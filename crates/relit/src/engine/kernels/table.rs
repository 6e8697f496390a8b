//! Any basis at a block of per-pixel light vectors, from its weight table: the
//! octahedral [`WeightTable`] of `crate::basis::table` in half floats, the same numbers
//! the GPU and browser shaders read, so that every back end relights with the same
//! weights. A pixel's weights are the bilinear blend of the four vertices around its
//! light vector ([`WeightTable::sample`], in f32), written out as rows of the block
//! ([`TableKernel::values`]) or added up over many weighted light vectors
//! ([`TableKernel::project`]); a dot with the block's coefficients is then
//! [`Simd::rows_dot`], as for SH.
//!
//! Speed: each vertex's weights are stored contiguously, padded to a multiple of eight
//! halves, so a pixel reads four runs of `k` halves (neighbouring pixels mostly read the
//! same vertices: the table stays in the caches) and blends them eight weights at a time
//! with F16C conversions and FMAs; eight pixels' blends are transposed in registers
//! into the block's rows.

use super::{Rows, Simd, BLOCK};
use crate::basis::table::measure_accuracy;
use crate::basis::{Basis, GridMap, PlanarGrid, TableAccuracy, WeightTable};
use half::f16;

/// A basis' weight table in half floats, laid out for the block kernels.
#[derive(Clone, Debug)]
pub(crate) struct TableKernel {
    /// How a light vector finds its cell.
    layout: Layout,
    /// Cells per side `N` (the table has `(N+1)²` vertices).
    resolution: usize,
    k: usize,
    /// Halves per vertex: `k` rounded up to a multiple of 8, zero past `k`.
    stride: usize,
    /// Vertex `v`'s weights at `bits[v·stride ..][..k]`, as half-float bits.
    bits: Vec<u16>,
    accuracy: TableAccuracy,
}

/// Where the table's vertices lie on the sphere of light vectors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Layout {
    /// The octahedral map of every back end ([`WeightTable`]).
    Octahedral,
    /// The basis' own grid over the square its map lands light vectors on
    /// ([`Basis::planar_grid`]): the basis exactly, up to half-float rounding.
    Planar(GridMap),
}

impl TableKernel {
    /// For a basis that is a planar grid, that grid; for any other, the table
    /// [`WeightTable::for_basis`] picks, rounded to half floats as every back end holds
    /// it. Either with its measured accuracy (of the rounded values).
    pub(crate) fn for_basis(basis: &dyn Basis) -> Self {
        if let Some(PlanarGrid { grid, nodes, map }) = basis.planar_grid().filter(|p| p.grid >= 2) {
            let nodes: Vec<f32> = nodes.iter().map(|&v| v as f32).collect();
            let mut kernel = Self::new(Layout::Planar(map), grid - 1, basis.len(), &nodes, None);
            let simd = Simd::detect();
            kernel.accuracy = measure_accuracy(basis, grid - 1, |d, out| {
                let mut dir = [[0f32; BLOCK]; 3];
                (dir[0][0], dir[1][0], dir[2][0]) = (d.x as f32, d.y as f32, d.z as f32);
                let mut rows = vec![[0f32; BLOCK]; out.len()];
                kernel.values(simd, &dir, &mut rows);
                out.iter_mut().zip(&rows).for_each(|(o, r)| *o = r[0]);
            });
            return kernel;
        }
        let (table, _) = WeightTable::for_basis(basis);
        let table = table.rounded_to_half();
        let accuracy = table.accuracy(basis);
        Self::new(
            Layout::Octahedral,
            table.resolution,
            table.k,
            &table.values,
            Some(accuracy),
        )
    }

    /// `values`: `k` weights per vertex, `(resolution + 1)²` vertices.
    fn new(
        layout: Layout,
        resolution: usize,
        k: usize,
        values: &[f32],
        accuracy: Option<TableAccuracy>,
    ) -> Self {
        let stride = k.div_ceil(8) * 8;
        let mut bits = Vec::with_capacity(values.len() / k.max(1) * stride);
        for vertex in values.chunks_exact(k) {
            bits.extend(vertex.iter().map(|&v| f16::from_f32(v).to_bits()));
            bits.resize(bits.len() + stride - k, 0);
        }
        Self {
            layout,
            resolution,
            k,
            stride,
            bits,
            accuracy: accuracy.unwrap_or(TableAccuracy {
                resolution,
                relative_rms: 0.0,
                relative_max: 0.0,
            }),
        }
    }

    /// How a light vector finds its cell.
    pub(crate) fn layout(&self) -> Layout {
        self.layout
    }

    pub(crate) fn len(&self) -> usize {
        self.k
    }

    /// The table's resolution and measured error against its basis.
    pub(crate) fn accuracy(&self) -> TableAccuracy {
        self.accuracy
    }

    /// `out[i][p] = y_i(dir_p)` for `i < k`, from the table. A zero vector (a pixel a
    /// light does not reach) gets weights 0.
    pub(crate) fn values(&self, simd: Simd, dir: &[[f32; BLOCK]; 3], out: &mut [[f32; BLOCK]]) {
        let corners = self.corners(simd, dir, None);
        self.blend::<false>(simd, &corners, &mut out[..self.k]);
    }

    /// `out[i][p] += w[p]·y_i(dir_p)` for `i < k` (pixels of zero weight add nothing).
    pub(crate) fn project(
        &self,
        simd: Simd,
        dir: &[[f32; BLOCK]; 3],
        w: &[f32; BLOCK],
        out: &mut [[f32; BLOCK]],
    ) {
        let corners = self.corners(simd, dir, Some(w));
        self.blend::<true>(simd, &corners, &mut out[..self.k]);
    }

    /// `out[c][p] = Σ_i y_i(dir_p)·v(3i + c)[p]`, through `rows` (at least `k` rows of
    /// scratch).
    pub(crate) fn dot(
        &self,
        simd: Simd,
        dir: &[[f32; BLOCK]; 3],
        values: Rows,
        out: &mut [[f32; BLOCK]; 3],
        rows: &mut [[f32; BLOCK]],
    ) {
        let rows = &mut rows[..self.k];
        self.values(simd, dir, rows);
        simd.rows_dot(rows, values, out);
    }

    /// Each pixel's first vertex and the bilinear weights of its four vertices
    /// (`v`, `v + 1`, `v + N + 1`, `v + N + 2`), times `w[p]` when given.
    fn corners(&self, simd: Simd, dir: &[[f32; BLOCK]; 3], w: Option<&[f32; BLOCK]>) -> Corners {
        let mut c = Corners {
            vertex: [0; BLOCK],
            weight: [[0.0; BLOCK]; 4],
        };
        if let Layout::Planar(map) = self.layout {
            #[cfg(target_arch = "x86_64")]
            if simd.avx2() {
                // SAFETY: `Simd::detect` found avx2, fma and f16c on this CPU.
                unsafe { planar_corners_avx2(map, self.resolution, dir, w, &mut c) };
                return c;
            }
            planar_corners(map, self.resolution, dir, w, &mut c);
            return c;
        }
        #[cfg(target_arch = "x86_64")]
        if simd.avx2() {
            // SAFETY: `Simd::detect` found avx2, fma and f16c on this CPU.
            unsafe { corners_avx2(self.resolution, dir, w, &mut c) };
            return c;
        }
        let _ = simd;
        corners_body(self.resolution, dir, w, &mut c);
        c
    }

    fn blend<const ADD: bool>(&self, simd: Simd, c: &Corners, out: &mut [[f32; BLOCK]]) {
        #[cfg(target_arch = "x86_64")]
        if simd.avx2() {
            // SAFETY: `Simd::detect` found avx2, fma and f16c on this CPU.
            return unsafe { blend_avx2::<ADD>(self, c, out) };
        }
        let _ = simd;
        blend_portable::<ADD>(self, c, out)
    }
}

/// Per pixel of a block: its cell's first vertex and the four bilinear weights.
struct Corners {
    vertex: [u32; BLOCK],
    weight: [[f32; BLOCK]; 4],
}

impl Corners {
    /// Pixel `p`'s bilinear weights at `(fx, fy)` in its cell, times `w[p]` when given;
    /// all 0 when its light vector is not `valid` (zero or not finite).
    #[inline(always)]
    fn set_weights(&mut self, p: usize, valid: bool, w: Option<&[f32; BLOCK]>, fx: f32, fy: f32) {
        let scale = match w {
            Some(w) if valid => w[p],
            Some(_) => 0.0,
            None if valid => 1.0,
            None => 0.0,
        };
        self.weight[0][p] = scale * ((1.0 - fx) * (1.0 - fy));
        self.weight[1][p] = scale * (fx * (1.0 - fy));
        self.weight[2][p] = scale * ((1.0 - fx) * fy);
        self.weight[3][p] = scale * (fx * fy);
    }
}

/// `WeightTable::corners` in f32 for a block (vectorises: no branches, only selects).
#[inline(always)]
// Lane p of three coordinate rows and of the outputs: an index loop vectorises.
#[allow(clippy::needless_range_loop)]
fn corners_body(n: usize, dir: &[[f32; BLOCK]; 3], w: Option<&[f32; BLOCK]>, c: &mut Corners) {
    let nf = n as f32;
    let side = (n + 1) as u32;
    let sign = |v: f32| if v < 0.0 { -1.0 } else { 1.0 };
    for p in 0..BLOCK {
        let (x, y, z) = (dir[0][p], dir[1][p], dir[2][p]);
        let s = x.abs() + y.abs() + z.abs();
        // A zero vector (or one that is not finite) gets no weight at all.
        let valid = s > 0.0 && s < f32::INFINITY;
        let inv = if valid { 1.0 / s } else { 0.0 };
        let (mut px, mut py) = (x * inv, y * inv);
        if z < 0.0 {
            let (ax, ay) = (px.abs(), py.abs());
            px = (1.0 - ay) * sign(px);
            py = (1.0 - ax) * sign(py);
        }
        let u = (0.5 * px + 0.5) * nf;
        let v = (0.5 * py + 0.5) * nf;
        let i = u.floor().clamp(0.0, nf - 1.0);
        let j = v.floor().clamp(0.0, nf - 1.0);
        let (fx, fy) = (u - i, v - j);
        c.vertex[p] = j as u32 * side + i as u32;
        c.set_weights(p, valid, w, fx, fy);
    }
}

/// The cell of each light vector on a planar grid of `n` cells a side over the square
/// `[−1, 1]²` that `map` lands it on, as [`GridMap`] defines it: on the square map,
/// `(x, y)`, normalised below the horizon; on the octahedral one, `((x + y)/s, (y − x)/s)`
/// with `s = |x| + |y| + max(z, 0)`. A zero (or non-finite) vector gets no weight.
#[inline(always)]
// Lane p of three coordinate rows and of the outputs: an index loop vectorises.
#[allow(clippy::needless_range_loop)]
fn planar_corners(
    map: GridMap,
    n: usize,
    dir: &[[f32; BLOCK]; 3],
    w: Option<&[f32; BLOCK]>,
    c: &mut Corners,
) {
    let nf = n as f32;
    let side = (n + 1) as u32;
    for p in 0..BLOCK {
        let (x, y, z) = (dir[0][p], dir[1][p], dir[2][p]);
        let s = x.abs() + y.abs() + z.abs();
        let valid = s > 0.0 && s < f32::INFINITY;
        // Selects, not branches, so that the loop vectorises.
        let (px, py) = match map {
            GridMap::Square => {
                let r = (x * x + y * y).sqrt();
                let inv = if z < 0.0 && r > 0.0 { 1.0 / r } else { 1.0 };
                (x * inv, y * inv)
            }
            GridMap::Octahedral => {
                let h = x.abs() + y.abs() + z.max(0.0);
                let inv = if h > 0.0 { 1.0 / h } else { 0.0 };
                ((x + y) * inv, (y - x) * inv)
            }
        };
        let u = ((px + 1.0) * 0.5 * nf).clamp(0.0, nf);
        let v = ((py + 1.0) * 0.5 * nf).clamp(0.0, nf);
        let u = if valid { u } else { 0.0 };
        let v = if valid { v } else { 0.0 };
        let i = u.floor().min(nf - 1.0);
        let j = v.floor().min(nf - 1.0);
        let (fx, fy) = (u - i, v - j);
        c.vertex[p] = j as u32 * side + i as u32;
        c.set_weights(p, valid, w, fx, fy);
    }
}

/// [`planar_corners`] in 8-lane code.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn planar_corners_avx2(
    map: GridMap,
    n: usize,
    dir: &[[f32; BLOCK]; 3],
    w: Option<&[f32; BLOCK]>,
    c: &mut Corners,
) {
    planar_corners(map, n, dir, w, c)
}

/// [`corners_body`] in 8-lane code (the floors become `vroundps`, not calls to libm).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn corners_avx2(
    n: usize,
    dir: &[[f32; BLOCK]; 3],
    w: Option<&[f32; BLOCK]>,
    c: &mut Corners,
) {
    corners_body(n, dir, w, c)
}

/// The four vertices of pixel `p`: offsets into `bits` and their weights.
#[inline(always)]
fn pixel_corners(t: &TableKernel, c: &Corners, p: usize) -> ([usize; 4], [f32; 4]) {
    let side = t.resolution + 1;
    let v = c.vertex[p] as usize;
    let at = [v, v + 1, v + side, v + side + 1].map(|v| v * t.stride);
    (at, std::array::from_fn(|q| c.weight[q][p]))
}

fn blend_portable<const ADD: bool>(t: &TableKernel, c: &Corners, out: &mut [[f32; BLOCK]]) {
    let mut y = vec![0f32; t.stride];
    for p in 0..BLOCK {
        let (at, w) = pixel_corners(t, c, p);
        if ADD && w == [0.0; 4] {
            continue;
        }
        y.fill(0.0);
        for (a, wq) in at.iter().zip(w) {
            for (yi, &b) in y.iter_mut().zip(&t.bits[*a..*a + t.stride]) {
                *yi += wq * f16::from_bits(b).to_f32();
            }
        }
        for (row, &v) in out.iter_mut().zip(&y) {
            if ADD {
                row[p] += v;
            } else {
                row[p] = v;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
unsafe fn blend_avx2<const ADD: bool>(t: &TableKernel, c: &Corners, out: &mut [[f32; BLOCK]]) {
    use std::arch::x86_64::*;
    let groups = t.stride / 8;
    // Eight pixels at a time: each pixel's blend of eight weights is one register; the
    // 8×8 block of them is transposed in registers into eight weights' rows of eight
    // pixels, stored whole (scattering them one value at a time cost as much as the
    // blend).
    for q in (0..BLOCK).step_by(8) {
        let pixels: [([usize; 4], [f32; 4]); 8] =
            std::array::from_fn(|e| pixel_corners(t, c, q + e));
        if ADD && pixels.iter().all(|(_, w)| *w == [0.0; 4]) {
            continue;
        }
        for g in 0..groups {
            let mut lanes = [_mm256_setzero_ps(); 8];
            for (lane, (at, w)) in lanes.iter_mut().zip(&pixels) {
                for v in 0..4 {
                    let o = at[v] + 8 * g;
                    let bits: [u16; 8] = t.bits[o..o + 8].try_into().expect("8 halves");
                    let h = _mm256_cvtph_ps(bytemuck::cast::<[u16; 8], __m128i>(bits));
                    *lane = _mm256_fmadd_ps(h, _mm256_set1_ps(w[v]), *lane);
                }
            }
            let rows = transpose8(lanes);
            for (d, row) in rows.iter().enumerate() {
                let i = 8 * g + d;
                if i >= t.k {
                    break;
                }
                let dst: &mut [f32; 8] = (&mut out[i][q..q + 8]).try_into().expect("8 lanes");
                let v = if ADD {
                    _mm256_add_ps(bytemuck::cast::<[f32; 8], __m256>(*dst), *row)
                } else {
                    *row
                };
                *dst = bytemuck::cast::<__m256, [f32; 8]>(v);
            }
        }
    }
}

/// The 8×8 transpose of eight registers: lane `d` of result `e` is lane `e` of input `d`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
#[inline]
fn transpose8(r: [std::arch::x86_64::__m256; 8]) -> [std::arch::x86_64::__m256; 8] {
    use std::arch::x86_64::*;
    let t0 = _mm256_unpacklo_ps(r[0], r[1]);
    let t1 = _mm256_unpackhi_ps(r[0], r[1]);
    let t2 = _mm256_unpacklo_ps(r[2], r[3]);
    let t3 = _mm256_unpackhi_ps(r[2], r[3]);
    let t4 = _mm256_unpacklo_ps(r[4], r[5]);
    let t5 = _mm256_unpackhi_ps(r[4], r[5]);
    let t6 = _mm256_unpacklo_ps(r[6], r[7]);
    let t7 = _mm256_unpackhi_ps(r[6], r[7]);
    let u0 = _mm256_shuffle_ps::<0x44>(t0, t2);
    let u1 = _mm256_shuffle_ps::<0xEE>(t0, t2);
    let u2 = _mm256_shuffle_ps::<0x44>(t1, t3);
    let u3 = _mm256_shuffle_ps::<0xEE>(t1, t3);
    let u4 = _mm256_shuffle_ps::<0x44>(t4, t6);
    let u5 = _mm256_shuffle_ps::<0xEE>(t4, t6);
    let u6 = _mm256_shuffle_ps::<0x44>(t5, t7);
    let u7 = _mm256_shuffle_ps::<0xEE>(t5, t7);
    [
        _mm256_permute2f128_ps::<0x20>(u0, u4),
        _mm256_permute2f128_ps::<0x20>(u1, u5),
        _mm256_permute2f128_ps::<0x20>(u2, u6),
        _mm256_permute2f128_ps::<0x20>(u3, u7),
        _mm256_permute2f128_ps::<0x31>(u0, u4),
        _mm256_permute2f128_ps::<0x31>(u1, u5),
        _mm256_permute2f128_ps::<0x31>(u2, u6),
        _mm256_permute2f128_ps::<0x31>(u3, u7),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisSpec;
    use crate::sphere::{fibonacci, Vec3};

    fn both() -> [Simd; 2] {
        [Simd::baseline(), Simd::detect()]
    }

    fn block_of(dirs: &[Vec3]) -> [[f32; BLOCK]; 3] {
        let mut dir = [[0f32; BLOCK]; 3];
        for (p, d) in dirs.iter().enumerate() {
            dir[0][p] = d.x as f32;
            dir[1][p] = d.y as f32;
            dir[2][p] = d.z as f32;
        }
        dir
    }

    /// The kernels place a vector on the map in f32 (`WeightTable::sample` in f64): its
    /// position in the cell is off by up to `N·2⁻²⁴` (1.5e-5 at N = 256), times a
    /// weight's change across the cell (below 1).
    const F32_POSITION_TOLERANCE: f32 = 2e-5;

    /// The block kernels give `WeightTable::sample` of the half-rounded table, for a
    /// basis whose k is not a multiple of 8; zero vectors get 0; the projection adds
    /// weighted values.
    #[test]
    fn the_block_kernels_sample_the_half_table() {
        let basis = BasisSpec::named("hsh:9").unwrap().build().unwrap();
        let kernel = TableKernel::for_basis(basis.as_ref());
        let (table, _) = WeightTable::for_basis(basis.as_ref());
        let table = table.rounded_to_half();
        let mut dirs = fibonacci(BLOCK - 3);
        dirs.extend([
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
        ]);
        let dir = block_of(&dirs);
        let w: [f32; BLOCK] = std::array::from_fn(|p| (p % 5) as f32 * 0.5);
        for simd in both() {
            let mut rows = vec![[f32::NAN; BLOCK]; 9];
            kernel.values(simd, &dir, &mut rows);
            let mut projection = vec![[1f32; BLOCK]; 9];
            kernel.project(simd, &dir, &w, &mut projection);
            let mut want = vec![0f32; 9];
            for (p, d) in dirs.iter().enumerate() {
                if p == BLOCK - 1 {
                    want.fill(0.0);
                } else {
                    table.sample(*d, &mut want);
                }
                for i in 0..9 {
                    assert!(
                        (rows[i][p] - want[i]).abs() < F32_POSITION_TOLERANCE,
                        "{simd:?} y{i} at {d:?}: {} vs {}",
                        rows[i][p],
                        want[i]
                    );
                    let projected = 1.0 + w[p] * want[i];
                    assert!(
                        (projection[i][p] - projected).abs() < 2.0 * F32_POSITION_TOLERANCE,
                        "{simd:?}"
                    );
                }
            }
        }
    }
}
