//! The basis at per-pixel light vectors, whatever the basis: SH by its vectorised
//! recurrence (`sh`, exact to f32 rounding: the fast path), every other basis from its
//! half-float weight table (`table`, within the table's measured error, the weights
//! the GPU and the browser viewer read), or from its own planar grid where it is one
//! (`bilinear`: exact up to half-float rounding). The positional lights of the engine ask
//! [`PixelBasis`] only, and never name a basis.

use super::sh::ShKernel;
use super::table::{Layout, TableKernel};
use super::{Rows, Simd, BLOCK};
use crate::basis::{Basis, TableAccuracy};

/// How the engine evaluates a basis per pixel (module docs). Each method forwards to
/// the variant's own kernel.
// One per relighter: SH's constants (776 bytes) stay inline, read by the hot loop
// without an indirection.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub(crate) enum PixelBasis {
    Sh(ShKernel),
    Table(TableKernel),
}

impl PixelBasis {
    /// SH's recurrence for the real SH basis, the weight table for any other.
    pub(crate) fn new(basis: &dyn Basis) -> Self {
        match ShKernel::of(basis) {
            Some(sh) => PixelBasis::Sh(sh),
            None => PixelBasis::Table(TableKernel::for_basis(basis)),
        }
    }

    /// Whether `basis` has a kernel of its own that evaluates it exactly (to f32
    /// rounding), so that [`Self::new`] builds no table for it.
    #[cfg(test)]
    pub(crate) fn evaluates_exactly(basis: &dyn Basis) -> bool {
        ShKernel::of(basis).is_some()
    }

    /// Coefficients per colour channel `k`.
    pub(crate) fn len(&self) -> usize {
        match self {
            PixelBasis::Sh(b) => b.len(),
            PixelBasis::Table(b) => b.len(),
        }
    }

    /// The table's accuracy against the basis (`None`: evaluated exactly).
    pub(crate) fn table_accuracy(&self) -> Option<TableAccuracy> {
        match self {
            PixelBasis::Sh(_) => None,
            PixelBasis::Table(b) => Some(b.accuracy()),
        }
    }

    /// `sh recurrence`, `hsh recurrence`, `weight table` (octahedral, as the GPU's) or
    /// `planar grid` (the basis' own).
    pub(crate) fn name(&self) -> &'static str {
        match self {
            PixelBasis::Sh(b) => b.name(),
            PixelBasis::Table(b) => match b.layout() {
                Layout::Octahedral => "weight table",
                Layout::Planar(_) => "planar grid",
            },
        }
    }

    /// `out[i][p] = y_i(dir_p)` for `i < k`.
    pub(crate) fn values(&self, simd: Simd, dir: &[[f32; BLOCK]; 3], out: &mut [[f32; BLOCK]]) {
        match self {
            PixelBasis::Sh(b) => b.values(simd, dir, out),
            PixelBasis::Table(b) => b.values(simd, dir, out),
        }
    }

    /// `out[i][p] += w[p]·y_i(dir_p)` for `i < k`: weighted light vectors added up into
    /// their projection on the basis (an area light's samples).
    pub(crate) fn project(
        &self,
        simd: Simd,
        dir: &[[f32; BLOCK]; 3],
        w: &[f32; BLOCK],
        out: &mut [[f32; BLOCK]],
    ) {
        match self {
            PixelBasis::Sh(b) => b.project(simd, dir, w, out),
            PixelBasis::Table(b) => b.project(simd, dir, w, out),
        }
    }

    /// `out[c][p] = Σ_i y_i(dir_p)·v(3i + c)[p]`: the basis at the light vectors dotted
    /// with the block's coefficient values (row `j` of `values` is plane `3i + c`);
    /// `rows` is scratch of at least `k` rows.
    pub(crate) fn dot(
        &self,
        simd: Simd,
        dir: &[[f32; BLOCK]; 3],
        values: Rows,
        out: &mut [[f32; BLOCK]; 3],
        rows: &mut [[f32; BLOCK]],
    ) {
        match self {
            PixelBasis::Sh(b) => b.dot(simd, dir, values, out),
            PixelBasis::Table(b) => b.dot(simd, dir, values, out, rows),
        }
    }
}

/// A basis evaluated at many light vectors as the CPU engine evaluates it per pixel for
/// lights with a position, 64 vectors at a time: a basis with a kernel of its own by
/// that kernel's f32 recurrence (AVX2/FMA where the CPU has it; within 2e-5 of
/// [`Basis::eval`]), any other basis from its weight table in half floats (within the
/// table's measured error, [`BasisEvaluator::table_accuracy`]).
#[derive(Clone, Debug)]
pub struct BasisEvaluator {
    basis: PixelBasis,
    simd: Simd,
}

impl BasisEvaluator {
    /// The evaluator of `basis` (building its weight table when it is not SH).
    pub fn new(basis: &dyn Basis) -> Self {
        Self {
            basis: PixelBasis::new(basis),
            simd: Simd::detect(),
        }
    }

    /// Coefficients per direction.
    pub fn len(&self) -> usize {
        self.basis.len()
    }

    /// Never true.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// How the basis is evaluated: `sh recurrence`, `hsh recurrence` or `weight table`.
    pub fn path(&self) -> &'static str {
        self.basis.name()
    }

    /// The weight table's resolution and error against the basis; `None` for SH
    /// (no table).
    pub fn table_accuracy(&self) -> Option<TableAccuracy> {
        self.basis.table_accuracy()
    }

    /// `out[i · n + p] = y_i(x_p, y_p, z_p)` for the `n` unit vectors given as three
    /// coordinate slices of equal length (`out` holds `len() · n` values, one row per
    /// basis function).
    pub fn eval(&self, x: &[f32], y: &[f32], z: &[f32], out: &mut [f32]) {
        let n = x.len();
        assert!(y.len() == n && z.len() == n, "x, y and z differ in length");
        assert_eq!(out.len(), self.len() * n, "out must hold len() × n values");
        let mut dir = [[0f32; BLOCK]; 3];
        let mut rows = vec![[0f32; BLOCK]; self.len()];
        for b in (0..n).step_by(BLOCK) {
            let bl = BLOCK.min(n - b);
            for (d, src) in dir.iter_mut().zip([x, y, z]) {
                d[..bl].copy_from_slice(&src[b..b + bl]);
                d[bl..].fill(0.0);
            }
            self.basis.values(self.simd, &dir, &mut rows);
            for (i, row) in rows.iter().enumerate() {
                out[i * n + b..i * n + b + bl].copy_from_slice(&row[..bl]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{BasisSpec, WeightTable};
    use crate::sphere::{fibonacci, Vec3};

    fn coordinates(dirs: &[Vec3]) -> [Vec<f32>; 3] {
        let f = |a: fn(&Vec3) -> f64| dirs.iter().map(|d| a(d) as f32).collect::<Vec<_>>();
        [f(|d| d.x), f(|d| d.y), f(|d| d.z)]
    }

    /// The recurrence path equals the basis' own evaluation to f32 rounding, for SH and
    /// for hemispherical harmonics (SH at the stretched hemisphere), at every size and on
    /// both sides of the horizon.
    #[test]
    fn the_recurrence_path_equals_the_basis() {
        let dirs = fibonacci(150);
        let [x, y, z] = coordinates(&dirs);
        for (name, path) in [
            ("sh:1", "sh recurrence"),
            ("sh:25", "sh recurrence"),
            ("sh:64", "sh recurrence"),
            ("hsh:4", "hsh recurrence"),
            ("hsh:16", "hsh recurrence"),
            ("hsh:25", "hsh recurrence"),
        ] {
            let basis = BasisSpec::named(name).unwrap().build().unwrap();
            let e = BasisEvaluator::new(basis.as_ref());
            assert_eq!((e.path(), e.table_accuracy()), (path, None), "{name}");
            let mut out = vec![0f32; e.len() * dirs.len()];
            e.eval(&x, &y, &z, &mut out);
            for (p, d) in dirs.iter().enumerate() {
                for (i, want) in basis.values(*d).into_iter().enumerate() {
                    let got = out[i * dirs.len() + p] as f64;
                    assert!(
                        (got - want).abs() < 4e-5,
                        "{name} y{i} at {d:?}: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// The table path equals the basis within the table's measured largest error (its
    /// `relative_max` of the largest |weight|, measured on 4096 directions; twice that
    /// between them), for every registered family that needs no capture.
    #[test]
    fn the_table_path_equals_the_basis_within_the_tables_error() {
        let dirs = fibonacci(997);
        let [x, y, z] = coordinates(&dirs);
        for name in ["ptm:6", "sg:25"] {
            let basis = BasisSpec::named(name).unwrap().build().unwrap();
            let e = BasisEvaluator::new(basis.as_ref());
            let accuracy = e.table_accuracy().expect("a table");
            assert_eq!(e.path(), "weight table");
            let (table, _) = WeightTable::for_basis(basis.as_ref());
            assert_eq!(accuracy.resolution, table.resolution);
            let peak = fibonacci(4096)
                .into_iter()
                .flat_map(|d| basis.values(d))
                .fold(0f64, |m, v| m.max(v.abs()));
            let bound = 2.0 * accuracy.relative_max * peak;
            let mut out = vec![0f32; e.len() * dirs.len()];
            e.eval(&x, &y, &z, &mut out);
            for (p, d) in dirs.iter().enumerate() {
                for (i, want) in basis.values(*d).into_iter().enumerate() {
                    let got = out[i * dirs.len() + p] as f64;
                    assert!(
                        (got - want).abs() <= bound,
                        "{name} y{i} at {d:?}: {got} vs {want} (bound {bound:e})"
                    );
                }
            }
        }
    }
}
