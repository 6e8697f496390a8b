//! Weight tables: any basis tabulated over the sphere of light directions, for back ends
//! that cannot run the basis' own code (WGSL, GLSL, JavaScript) and for families without
//! a fast kernel of their own.
//!
//! The table is an octahedral map (the sphere folded onto the square `[0, 1]²`, the
//! upper hemisphere `z ≥ 0` in the central diamond) holding the `k` weights at the
//! `(N+1)²` vertices of an `N×N` grid; a direction's weights are the bilinear blend of
//! its cell's four vertices. Vertices (not cell centres) carry the values, so the edges
//! of the square need no wrapping. [`WeightTable::for_basis`] measures the table's error
//! against direct evaluation and takes the coarsest resolution within the tolerance.

use super::Basis;
use crate::sphere::Vec3;

/// `(u, v) ∈ [0, 1]²` of the unit vector `dir` on the octahedral map (z is the pole).
pub fn octahedral_uv(dir: Vec3) -> [f64; 2] {
    let s = dir.x.abs() + dir.y.abs() + dir.z.abs();
    let (mut px, mut py) = (dir.x / s, dir.y / s);
    if dir.z < 0.0 {
        let (ax, ay) = (px.abs(), py.abs());
        px = (1.0 - ay) * sign(px);
        py = (1.0 - ax) * sign(py);
    }
    [0.5 * px + 0.5, 0.5 * py + 0.5]
}

/// The unit vector at `(u, v)` of the octahedral map: the inverse of [`octahedral_uv`].
pub fn octahedral_direction(u: f64, v: f64) -> Vec3 {
    let (mut px, mut py) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    let z = 1.0 - px.abs() - py.abs();
    if z < 0.0 {
        let (ax, ay) = (px.abs(), py.abs());
        px = (1.0 - ay) * sign(px);
        py = (1.0 - ax) * sign(py);
    }
    Vec3::new(px, py, z)
        .normalized()
        .expect("a point of the octahedron")
}

#[inline]
fn sign(v: f64) -> f64 {
    if v < 0.0 {
        -1.0
    } else {
        1.0
    }
}

/// How closely a table reproduces its basis, measured on 4096 Fibonacci directions.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TableAccuracy {
    /// Cells per side.
    pub resolution: usize,
    /// RMS of (table − basis) over RMS of the basis, all weights pooled.
    pub relative_rms: f64,
    /// Largest |table − basis| over the largest |basis|.
    pub relative_max: f64,
}

/// How closely `sample` (any tabulation of `basis`, `resolution` cells a side) follows
/// the basis on 4096 Fibonacci directions.
pub(crate) fn measure_accuracy(
    basis: &dyn Basis,
    resolution: usize,
    mut sample: impl FnMut(Vec3, &mut [f32]),
) -> TableAccuracy {
    let k = basis.len();
    let (mut direct, mut table) = (vec![0.0; k], vec![0f32; k]);
    let (mut sq_err, mut sq, mut max_err, mut max) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for d in crate::sphere::fibonacci(4096) {
        basis.eval(d, &mut direct);
        sample(d, &mut table);
        for (a, &b) in direct.iter().zip(&table) {
            let e = (b as f64 - a).abs();
            sq_err += e * e;
            sq += a * a;
            max_err = max_err.max(e);
            max = max.max(a.abs());
        }
    }
    TableAccuracy {
        resolution,
        relative_rms: (sq_err / sq.max(1e-300)).sqrt(),
        relative_max: max_err / max.max(1e-300),
    }
}

/// `k` weights at each vertex of an `N×N` octahedral grid.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightTable {
    /// Cells per side `N`: the table holds `(N+1)²` vertices.
    pub resolution: usize,
    pub k: usize,
    /// Vertex `(i, j)` (i along u) holds `values[(j·(N+1) + i)·k ..][..k]`.
    pub values: Vec<f32>,
}

/// Resolutions [`WeightTable::for_basis`] tries, coarsest first.
pub const RESOLUTIONS: [usize; 6] = [16, 32, 64, 128, 256, 512];

/// The relative RMS error [`WeightTable::for_basis`] accepts: 1e-3 of the weights, far
/// below what an 8-bit image shows (a relit value off by 0.1 % is 60 dB down).
pub const TABLE_TOLERANCE: f64 = 1e-3;

impl WeightTable {
    /// Tabulate `basis` on an `resolution × resolution` grid.
    pub fn new(basis: &dyn Basis, resolution: usize) -> WeightTable {
        let n = resolution.max(1);
        let k = basis.len();
        let side = n + 1;
        let mut values = vec![0f32; side * side * k];
        let mut w = vec![0.0; k];
        for j in 0..side {
            for i in 0..side {
                let d = octahedral_direction(i as f64 / n as f64, j as f64 / n as f64);
                basis.eval(d, &mut w);
                let o = (j * side + i) * k;
                for (dst, &v) in values[o..o + k].iter_mut().zip(&w) {
                    *dst = v as f32;
                }
            }
        }
        WeightTable {
            resolution: n,
            k,
            values,
        }
    }

    /// The coarsest table of [`RESOLUTIONS`] within [`TABLE_TOLERANCE`] of `basis`
    /// (the finest if none is), with its measured accuracy.
    pub fn for_basis(basis: &dyn Basis) -> (WeightTable, TableAccuracy) {
        let mut last = None;
        for &r in &RESOLUTIONS {
            let table = WeightTable::new(basis, r);
            let accuracy = table.accuracy(basis);
            if accuracy.relative_rms <= TABLE_TOLERANCE {
                return (table, accuracy);
            }
            last = Some((table, accuracy));
        }
        last.expect("at least one resolution")
    }

    /// The table's error against direct evaluation of `basis`.
    pub fn accuracy(&self, basis: &dyn Basis) -> TableAccuracy {
        measure_accuracy(basis, self.resolution, |d, out| self.sample(d, out))
    }

    /// The four vertices around `dir` and their bilinear weights.
    #[inline]
    pub fn corners(&self, dir: Vec3) -> ([usize; 4], [f32; 4]) {
        let n = self.resolution;
        let [u, v] = octahedral_uv(dir);
        let (x, y) = (u * n as f64, v * n as f64);
        let (i, j) = (
            (x.floor().max(0.0) as usize).min(n - 1),
            (y.floor().max(0.0) as usize).min(n - 1),
        );
        let (fx, fy) = ((x - i as f64) as f32, (y - j as f64) as f32);
        let side = n + 1;
        let v00 = j * side + i;
        (
            [v00, v00 + 1, v00 + side, v00 + side + 1],
            [
                (1.0 - fx) * (1.0 - fy),
                fx * (1.0 - fy),
                (1.0 - fx) * fy,
                fx * fy,
            ],
        )
    }

    /// The weights at `dir`, bilinearly interpolated, into `out[..k]`.
    pub fn sample(&self, dir: Vec3, out: &mut [f32]) {
        let k = self.k;
        let (vertices, weights) = self.corners(dir);
        out[..k].fill(0.0);
        for (&v, &w) in vertices.iter().zip(&weights) {
            for (o, &t) in out[..k].iter_mut().zip(&self.values[v * k..(v + 1) * k]) {
                *o += w * t;
            }
        }
    }

    /// This table with every weight rounded to a half float: what every back end reads
    /// (the GPU and browser shaders, the CPU engine's table kernel), so that all of
    /// them relight with the same weights. The rounding stays within the table's
    /// measured accuracy ([`WeightTable::accuracy`] of the rounded table says by how much).
    pub fn rounded_to_half(&self) -> WeightTable {
        WeightTable {
            values: self
                .values
                .iter()
                .map(|&v| half::f16::from_f32(v).to_f32())
                .collect(),
            ..self.clone()
        }
    }

    /// Bytes the table occupies as f32.
    pub fn bytes(&self) -> usize {
        self.values.len() * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::SphericalHarmonics;

    #[test]
    fn octahedral_mapping_round_trips() {
        for d in crate::sphere::fibonacci(500) {
            let [u, v] = octahedral_uv(d);
            assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v));
            let back = octahedral_direction(u, v);
            assert!((back - d).length() < 1e-12, "{d:?} → {back:?}");
        }
        // The camera-facing pole is the centre, the far pole the corners.
        assert_eq!(octahedral_uv(Vec3::new(0.0, 0.0, 1.0)), [0.5, 0.5]);
        let far = octahedral_uv(Vec3::new(0.0, 0.0, -1.0));
        assert!(far.iter().all(|&c| c == 0.0 || c == 1.0));
    }

    #[test]
    fn a_table_reproduces_its_basis_at_vertices_and_converges_between() {
        let sh = SphericalHarmonics::new(5).unwrap();
        let table = WeightTable::new(&sh, 32);
        // Exact at a vertex.
        let d = octahedral_direction(5.0 / 32.0, 17.0 / 32.0);
        let mut t = vec![0f32; 25];
        table.sample(d, &mut t);
        for (a, b) in sh.values(d).iter().zip(&t) {
            assert!((a - *b as f64).abs() < 1e-6);
        }
        // Bilinear interpolation of a smooth function: error ∝ h², a quarter per halving.
        let coarse = WeightTable::new(&sh, 32).accuracy(&sh).relative_rms;
        let fine = WeightTable::new(&sh, 64).accuracy(&sh).relative_rms;
        assert!(
            fine < 0.3 * coarse && fine > 0.15 * coarse,
            "{coarse} {fine}"
        );
        let (chosen, accuracy) = WeightTable::for_basis(&sh);
        assert!(accuracy.relative_rms <= TABLE_TOLERANCE);
        assert_eq!(chosen.resolution, accuracy.resolution);
    }
}
