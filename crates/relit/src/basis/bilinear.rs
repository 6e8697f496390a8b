//! `bilinear:K` — each pixel's samples resampled to a regular grid over the projected
//! hemisphere of light directions and interpolated bilinearly between its nodes,
//! compressed across pixels to `K` grids by principal components ([`super::pca`]), as
//! the RTI tool relight's bilinear basis does.
//!
//! The grid has `G × G` nodes over a square `(u, v) ∈ [−1, 1]²` that a light vector
//! lands on by a [`GridMap`] (option `map`):
//!
//! - **`octahedral`** (the default, and relight's map): `u = (x + y)/s`, `v = (y − x)/s`
//!   with `s = |x| + |y| + |z|`: the upper half of the octahedral map turned by 45°,
//!   which fills the square exactly (the corners are the horizon at ±x, ±y). Its node
//!   `(i, j)` is the light vector `((u − v)/2, (u + v)/2, 1 − max(|u|, |v|))`
//!   (normalised). Below the horizon `z` is taken as 0, the horizon direction.
//! - **`square`**: `(x, y)` of the light vector, which fills only the unit disc and
//!   crowds low lights into its rim (below the horizon `(x, y)` is normalised). Files
//!   without a `map` are on this grid. On the eight RealRTI items (peer protocol,
//!   `bilinear:25`) the octahedral grid scored higher on seven, by 0.1 to 4.0 dB, and
//!   2.0 dB lower on item7 (docs/bases.md).
//!
//! A pixel's node values are the smoothest grid whose bilinear interpolation meets its
//! samples in the least-squares sense: `min Σ_j (bilerp(g, L_j) − I_j)² + ν
//! Σ_neighbours (g_a − g_b)²`, the second term filling the nodes no light reaches. `G`
//! defaults to about `√N + 2` for `N` lights (a node per light spacing; option `grid`),
//! `ν` to `smooth · N / G²` (option `smooth`, default 0.05: a tenth of the data weight a
//! node gets on average, so measured nodes keep their values).
//!
//! Stored: `G` and the `K` grids of node values, and `map` when the grid is not the
//! square one. The octahedral grid also reads the relight/OpenLIME web format's bilinear
//! functions exactly (`codec/web.rs`).

use super::pca::{self, PcaSpace};
use super::{Basis, BasisSpec, BuildContext, Domain, Family, PlanarGrid};
use crate::sphere::Vec3;
use crate::{Error, Result};

/// The sizes `bilinear:K` offers.
const SIZES: [usize; 11] = [4, 6, 9, 12, 16, 18, 25, 27, 36, 49, 64];

/// Grid sizes accepted (nodes per side).
const GRIDS: std::ops::RangeInclusive<usize> = 3..=64;

pub(super) struct BilinearFamily;

pub(super) static FAMILY: BilinearFamily = BilinearFamily;

impl Family for BilinearFamily {
    fn name(&self) -> &'static str {
        "bilinear"
    }

    fn summary(&self) -> &'static str {
        "light-space samples on a regular grid, interpolated bilinearly, PCA-compressed to K"
    }

    fn sizes(&self, max: usize) -> Vec<usize> {
        SIZES.iter().copied().filter(|&k| k <= max).collect()
    }

    fn needs_samples(&self) -> bool {
        true
    }

    fn option_keys(&self) -> &'static [&'static str] {
        &["grid", "smooth", "pca", "map"]
    }

    fn nested(&self, lights: usize) -> bool {
        // As `rbf`: the grid interpolants of the principal directions in order.
        lights <= crate::linalg::EXACT_PCA_LIGHTS
    }

    fn build(&self, k: usize, context: &BuildContext) -> Result<Box<dyn Basis>> {
        let samples = context
            .samples
            .ok_or_else(|| Error::invalid("a bilinear basis is built from samples"))?;
        let dirs = context.directions;
        let n = dirs.len();
        if samples.n != n {
            return Err(Error::invalid("samples and directions disagree"));
        }
        let default_grid = ((n as f64).sqrt().round() as usize + 2).clamp(4, 32);
        let g: usize = context.option("grid", default_grid)?;
        if !GRIDS.contains(&g) {
            return Err(Error::invalid(format!(
                "a bilinear grid has {} to {} nodes per side, not {g}",
                GRIDS.start(),
                GRIDS.end()
            )));
        }
        let smooth: f64 = context.option("smooth", 0.05)?;
        if !(smooth.is_finite() && smooth > 0.0) {
            return Err(Error::invalid("bilinear smooth must be positive"));
        }
        let space = PcaSpace::parse(&context.option("pca", "srgb".to_string())?)?;
        let map = context.option("map", GridMap::Octahedral.name().to_string())?;
        let map = GridMap::parse(&map)
            .ok_or_else(|| Error::parse(format!("bad bilinear map `{map}`")))?;
        let c = g * g;
        let mut a = vec![0.0; n * c];
        for (j, d) in dirs.iter().enumerate() {
            let (nodes, w) = corners(g, *d, map);
            for (&node, &wt) in nodes.iter().zip(&w) {
                a[j * c + node] += wt;
            }
        }
        let nu = smooth * n as f64 / c as f64;
        let mut laplacian = vec![0.0; c * c];
        for y in 0..g {
            for x in 0..g {
                let i = y * g + x;
                for (dx, dy) in [(1, 0), (0, 1)] {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < g && ny < g {
                        let j = ny * g + nx;
                        laplacian[i * c + i] += nu;
                        laplacian[j * c + j] += nu;
                        laplacian[i * c + j] -= nu;
                        laplacian[j * c + i] -= nu;
                    }
                }
            }
        }
        // The Laplacian leaves a constant free; a whisper of ridge pins it down when no
        // light reaches the grid at all.
        (0..c).for_each(|i| laplacian[i * c + i] += 1e-9 * n as f64);
        let t = pca::least_squares_operator(&a, n, c, &laplacian)?;
        let u = pca::principal_directions(&samples, k, space)?;
        let values = pca::component_parameters(&t, c, &u, n);
        Ok(Box::new(Bilinear {
            grid: g,
            values,
            map,
        }))
    }

    fn rebuild(
        &self,
        params: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Box<dyn Basis>> {
        let bad = |what: &str| Error::parse(format!("bilinear basis: {what}"));
        let g = params
            .get("grid")
            .and_then(|v| v.as_u64())
            .map(|g| g as usize)
            .filter(|g| GRIDS.contains(g))
            .ok_or_else(|| bad("needs `grid`, 3 to 64 nodes per side"))?;
        let values = pca::stored_table(params, "values", "bilinear")?;
        let c = g * g;
        if values.is_empty() || values.len() % c != 0 || values.len() / c > 64 {
            return Err(bad("`values` must hold K × grid² numbers, K ≤ 64"));
        }
        let map = match params.get("map") {
            None => GridMap::Square,
            Some(v) => v
                .as_str()
                .and_then(GridMap::parse)
                .ok_or_else(|| bad("`map` is `square` or `octahedral`"))?,
        };
        if params.len() != 2 + params.contains_key("map") as usize {
            return Err(bad("has only `grid`, `values` and `map`"));
        }
        Ok(Box::new(Bilinear {
            grid: g,
            values,
            map,
        }))
    }
}

/// How a light vector lands on the grid's square (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridMap {
    /// `(x, y)` of the light vector (the horizon normalised onto the unit circle).
    Square,
    /// relight's octahedral diamond, turned 45° to fill the square.
    Octahedral,
}

impl GridMap {
    /// The map's name in option strings and stored parameters.
    pub fn name(self) -> &'static str {
        match self {
            GridMap::Square => "square",
            GridMap::Octahedral => "octahedral",
        }
    }

    /// The map named `name` ([`GridMap::name`]).
    pub fn parse(name: &str) -> Option<GridMap> {
        [GridMap::Square, GridMap::Octahedral]
            .into_iter()
            .find(|map| map.name() == name)
    }

    /// `(u, v) ∈ [−1, 1]²` of the unit vector `dir`.
    fn uv(self, dir: Vec3) -> (f64, f64) {
        match self {
            GridMap::Square => {
                let (mut x, mut y) = (dir.x, dir.y);
                if dir.z < 0.0 {
                    let r = (x * x + y * y).sqrt();
                    if r > 0.0 {
                        x /= r;
                        y /= r;
                    }
                }
                (x, y)
            }
            GridMap::Octahedral => {
                let s = dir.x.abs() + dir.y.abs() + dir.z.max(0.0);
                if s <= 0.0 {
                    return (0.0, 0.0);
                }
                ((dir.x + dir.y) / s, (dir.y - dir.x) / s)
            }
        }
    }

    /// The unit light vector of grid node `(i, j)` of a `g × g` grid.
    pub fn node_direction(self, g: usize, i: usize, j: usize) -> Vec3 {
        let at = |n: usize| 2.0 * n as f64 / (g - 1) as f64 - 1.0;
        let (u, v) = (at(i), at(j));
        let dir = match self {
            GridMap::Square => Vec3::new(u, v, (1.0 - u * u - v * v).max(0.0).sqrt()),
            GridMap::Octahedral => {
                Vec3::new((u - v) / 2.0, (u + v) / 2.0, 1.0 - u.abs().max(v.abs()))
            }
        };
        dir.normalized().unwrap_or(Vec3::new(0.0, 0.0, 1.0))
    }
}

/// `K` grids of `g × g` node values (`K × g²`, node `(i, j)` at `j·g + i`) on `map`.
pub fn grid_basis(g: usize, values: Vec<f64>, map: GridMap) -> Result<Box<dyn Basis>> {
    stored_spec(g, &values, map).build()
}

/// What a bilinear basis stores: `grid`, `values`, and `map` where it is not the square
/// grid (so that files without one read as they were written).
fn stored_spec(g: usize, values: &[f64], map: GridMap) -> BasisSpec {
    let mut params = serde_json::json!({ "grid": g, "values": values });
    if map != GridMap::Square {
        params["map"] = map.name().into();
    }
    BasisSpec::new("bilinear", params)
}

/// The four grid nodes around `dir`'s place on the grid and their bilinear weights.
fn corners(g: usize, dir: Vec3, map: GridMap) -> ([usize; 4], [f64; 4]) {
    let (x, y) = map.uv(dir);
    let scale = (g - 1) as f64 / 2.0;
    let (fx, fy) = (
        ((x + 1.0) * scale).clamp(0.0, (g - 1) as f64),
        ((y + 1.0) * scale).clamp(0.0, (g - 1) as f64),
    );
    let (i, j) = (
        (fx.floor() as usize).min(g - 2),
        (fy.floor() as usize).min(g - 2),
    );
    let (tx, ty) = (fx - i as f64, fy - j as f64);
    let n00 = j * g + i;
    (
        [n00, n00 + 1, n00 + g, n00 + g + 1],
        [
            (1.0 - tx) * (1.0 - ty),
            tx * (1.0 - ty),
            (1.0 - tx) * ty,
            tx * ty,
        ],
    )
}

/// `K` grids of node values, interpolated bilinearly.
#[derive(Clone, Debug)]
pub struct Bilinear {
    grid: usize,
    /// `K × G²`, row-major; node `(x, y)` at `y·G + x`.
    values: Vec<f64>,
    map: GridMap,
}

impl Basis for Bilinear {
    fn spec(&self) -> BasisSpec {
        stored_spec(self.grid, &self.values, self.map)
    }

    fn family(&self) -> &'static str {
        "bilinear"
    }

    fn len(&self) -> usize {
        self.values.len() / (self.grid * self.grid)
    }

    fn domain(&self) -> Domain {
        Domain::UpperHemisphere
    }

    fn eval(&self, dir: Vec3, out: &mut [f64]) {
        let c = self.grid * self.grid;
        let (nodes, w) = corners(self.grid, dir, self.map);
        for (o, grid) in out[..self.len()]
            .iter_mut()
            .zip(self.values.chunks_exact(c))
        {
            *o = nodes.iter().zip(&w).map(|(&n, &wt)| grid[n] * wt).sum();
        }
    }

    fn planar_grid(&self) -> Option<PlanarGrid> {
        let (k, c) = (self.len(), self.grid * self.grid);
        let nodes = (0..c)
            .flat_map(|node| (0..k).map(move |i| self.values[i * c + node]))
            .collect();
        Some(PlanarGrid {
            grid: self.grid,
            nodes,
            map: self.map,
        })
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{BasisChoice, Samples};

    /// Series that are exactly bilinear in a map's `(u, v)` over the whole square are
    /// reproduced by any grid on that map (bilinear interpolation of a bilinear
    /// function), and a stored basis rebuilds to the same functions.
    #[test]
    fn a_grid_interpolates_bilinearly_and_round_trips() {
        for map in [GridMap::Square, GridMap::Octahedral] {
            let name = map.name();
            let dirs = crate::sphere::hemisphere_fibonacci(60);
            let mut values = Vec::new();
            for s in 0..200 {
                let t = s as f64;
                let (a, b, c, d) = (
                    0.3 + 0.001 * t,
                    0.1 * t.sin(),
                    0.05 * (1.3 * t).cos(),
                    0.02 * (0.7 * t).sin(),
                );
                for dir in &dirs {
                    let (u, v) = map.uv(*dir);
                    values.push((a + b * u + c * v + d * u * v) as f32);
                }
            }
            let samples = Samples {
                values: &values,
                n: dirs.len(),
            };
            let spec = format!("bilinear:4:grid=5,pca=linear,smooth=1e-7,map={name}");
            let basis = BasisChoice::parse(&spec)
                .unwrap()
                .build(&dirs, Some(samples))
                .unwrap();
            assert_eq!(basis.len(), 4);
            assert_eq!(basis.planar_grid().unwrap().map, map);
            // The four components span {1, u, v, uv}: a least-squares fit of a new such
            // series at a new direction is exact.
            let probe = |d: Vec3| basis.values(d);
            let k = 4;
            let target = |d: Vec3| {
                let (u, v) = map.uv(d);
                0.5 - 0.2 * u + 0.3 * v + 0.1 * u * v
            };
            let mut m = vec![0.0; k * k];
            let mut rhs = vec![0.0; k];
            for d in &dirs {
                let row = probe(*d);
                for p in 0..k {
                    rhs[p] += row[p] * target(*d);
                    for q in 0..k {
                        m[p * k + q] += row[p] * row[q];
                    }
                }
            }
            assert!(crate::linalg::cholesky(&mut m, k));
            crate::linalg::cholesky_solve(&m, k, &mut rhs);
            let d = Vec3::new(0.3, -0.2, 0.9).normalized().unwrap();
            let got: f64 = probe(d).iter().zip(&rhs).map(|(a, b)| a * b).sum();
            assert!(
                (got - target(d)).abs() < 2e-3,
                "{name}: {got} vs {}",
                target(d)
            );
            let again = basis.spec().build().unwrap();
            assert_eq!(again.values(d), basis.values(d), "{name}");
        }
    }

    /// Each node of the octahedral grid sits at its own direction (a one-hot grid is 1
    /// there), the map fills the square, and light vectors below the horizon take the
    /// horizon's value.
    #[test]
    fn the_octahedral_grid_puts_each_node_at_its_direction() {
        let g = 5;
        let c = g * g;
        let mut values = vec![0.0; c * c];
        (0..c).for_each(|n| values[n * c + n] = 1.0);
        let basis = grid_basis(g, values, GridMap::Octahedral).unwrap();
        assert_eq!(basis.planar_grid().unwrap().map, GridMap::Octahedral);
        for j in 0..g {
            for i in 0..g {
                let d = GridMap::Octahedral.node_direction(g, i, j);
                assert!(d.z >= 0.0);
                let w = basis.values(d);
                assert!(
                    (w[j * g + i] - 1.0).abs() < 1e-9,
                    "node ({i}, {j}) at {d:?}"
                );
            }
        }
        // (u, v) = (1, 1) is +y on the horizon; (1, −1) is +x.
        assert!((GridMap::Octahedral.node_direction(g, g - 1, g - 1).y - 1.0).abs() < 1e-12);
        assert!((GridMap::Octahedral.node_direction(g, g - 1, 0).x - 1.0).abs() < 1e-12);
        let below = Vec3::new(0.6, 0.3, -0.5).normalized().unwrap();
        let horizon = Vec3::new(0.6, 0.3, 0.0).normalized().unwrap();
        assert_eq!(basis.values(below), basis.values(horizon));
        let again = basis.spec().build().unwrap();
        assert_eq!(again.values(below), basis.values(below));
    }
}
