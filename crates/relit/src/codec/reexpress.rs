//! Re-expressing a relightable image in another basis and colour space, for the file
//! formats that hold one fixed basis (`.ptm`: the biquadratic; `.rti`: HSH).
//!
//! When the image already is in the target basis and space its coefficients are taken
//! as they are (exactly). Otherwise each pixel's function is sampled at a fixed set of
//! light directions over the RTI dome's hemisphere, converted to the target space, and
//! fitted by least squares. The directions are the same for every pixel, so the fit is
//! one `K_target × N` pseudo-inverse applied per pixel; when the two spaces agree the
//! whole change is linear and collapses to one `K_target × K_source` matrix.

use crate::basis::Basis;
use crate::color::{linear_to_srgb, srgb_to_linear};
use crate::maps::{CoefficientMaps, MapSpace, RelightableImage};
use crate::sphere::{self, Vec3};
use crate::{Error, Result};
use rayon::prelude::*;

/// Light directions the re-expression samples: the upper hemisphere down to 10° of
/// elevation (where RTI domes stop), nearly uniform.
pub(crate) fn dome_directions() -> Vec<Vec3> {
    sphere::fibonacci(400)
        .into_iter()
        .filter(|d| d.z >= 0.17)
        .collect()
}

/// `image`'s maps expressed in `target` and `space`: coefficient planes `3 * i + c`.
pub fn reexpress(
    image: &RelightableImage,
    target: &dyn Basis,
    space: MapSpace,
) -> Result<CoefficientMaps> {
    let source = image.meta.basis.build()?;
    let maps = &image.maps;
    if maps.data.len() != 3 * maps.k * maps.pixels() {
        return Err(Error::invalid(
            "the image's maps are not loaded (compact planes cannot be re-expressed)",
        ));
    }
    if source.spec() == target.spec() && image.meta.color_space == space {
        return Ok(maps.clone());
    }
    let directions = dome_directions();
    let n = directions.len();
    let (ks, kt) = (source.len(), target.len());
    // Rows: directions; the source's and the target's weights at each.
    let mut source_rows = vec![0.0; n * ks];
    let mut target_rows = vec![0.0; n * kt];
    for (j, &d) in directions.iter().enumerate() {
        source.eval(d, &mut source_rows[j * ks..(j + 1) * ks]);
        target.eval(d, &mut target_rows[j * kt..(j + 1) * kt]);
    }
    let fit = pseudo_inverse(&target_rows, n, kt)?; // kt × n
    let convert = match (image.meta.color_space, space) {
        (a, b) if a == b => None,
        (MapSpace::Linear, MapSpace::Srgb) => Some(linear_to_srgb as fn(f32) -> f32),
        (MapSpace::Srgb, MapSpace::Linear) => Some(srgb_to_linear as fn(f32) -> f32),
        _ => unreachable!("two colour spaces"),
    };
    let pixels = maps.pixels();
    let mut out = CoefficientMaps::zeros(maps.width, maps.height, kt);
    // Pixel-major results, scattered into planes afterwards.
    let per_pixel: Vec<f32> = (0..pixels)
        .into_par_iter()
        .flat_map_iter(|p| {
            let mut values = vec![0.0f64; n];
            let mut result = vec![0.0f32; 3 * kt];
            for c in 0..3 {
                let coefficients: Vec<f64> = (0..ks)
                    .map(|i| maps.data[(3 * i + c) * pixels + p] as f64)
                    .collect();
                for (j, value) in values.iter_mut().enumerate() {
                    let v: f64 = source_rows[j * ks..(j + 1) * ks]
                        .iter()
                        .zip(&coefficients)
                        .map(|(w, c)| w * c)
                        .sum();
                    *value = match convert {
                        Some(f) => f(v.max(0.0) as f32) as f64,
                        None => v,
                    };
                }
                for i in 0..kt {
                    result[c * kt + i] = fit[i * n..(i + 1) * n]
                        .iter()
                        .zip(&values)
                        .map(|(a, b)| a * b)
                        .sum::<f64>() as f32;
                }
            }
            result
        })
        .collect();
    for p in 0..pixels {
        for c in 0..3 {
            for i in 0..kt {
                out.data[(3 * i + c) * pixels + p] = per_pixel[p * 3 * kt + c * kt + i];
            }
        }
    }
    Ok(out)
}

/// `(AᵀA)⁻¹Aᵀ` of the row-major `rows × cols` matrix `a` (`cols × rows`, row-major).
fn pseudo_inverse(a: &[f64], rows: usize, cols: usize) -> Result<Vec<f64>> {
    let mut normal = vec![0.0; cols * cols];
    for r in 0..rows {
        let row = &a[r * cols..(r + 1) * cols];
        for i in 0..cols {
            for j in 0..cols {
                normal[i * cols + j] += row[i] * row[j];
            }
        }
    }
    if !crate::linalg::cholesky(&mut normal, cols) {
        return Err(Error::invalid("the target basis is singular over the dome"));
    }
    let mut out = vec![0.0; cols * rows];
    let mut column = vec![0.0; cols];
    for r in 0..rows {
        column.copy_from_slice(&a[r * cols..(r + 1) * cols]);
        crate::linalg::cholesky_solve(&normal, cols, &mut column);
        for i in 0..cols {
            out[i * rows + r] = column[i];
        }
    }
    Ok(out)
}
