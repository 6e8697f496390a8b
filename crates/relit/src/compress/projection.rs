//! Principal components across pixels, measured as the relit image sees them.
//!
//! A pixel's coefficient error `δc` shows as `δc·b(L)` under a light toward `L`; over
//! the lights it shows as `δcᵀ G δc` with `G = mean_L b(L) b(L)ᵀ` (the basis' Gram
//! matrix over the lights). With `G = R Rᵀ` (Cholesky), `z = Rᵀ c` turns that error
//! into the plain squared distance, so principal components of `z` are the best
//! `K′` combinations for the relit image, and their coordinates all weigh the same: one
//! quantiser step serves every plane.
//!
//! With `V` the `K′ × K` leading principal directions of `z` (uncentred, so the mean
//! response comes first), a pixel is stored as `c′ = V Rᵀ c` and relit with the basis
//! `P b(L)` for `P = V R⁻¹` ([`crate::basis::Projected`]): `b·(R⁻ᵀ Vᵀ c′) = (P b)·c′`.

use crate::basis::Basis;
use crate::sphere::Vec3;
use crate::{Error, ErrorKind, Result};

/// Directions the Gram matrix is measured on when the capture's are not known.
const GRAM_DIRECTIONS: usize = 4096;

/// The encoding `E = V Rᵀ` and the projected basis' map `P = V R⁻¹`, both `K′ × K`.
#[derive(Clone)]
pub struct Principal {
    pub k: usize,
    pub components: usize,
    pub encode: Vec<f64>,
    pub basis_map: Vec<f64>,
}

/// The basis' Gram matrix over `directions`, or over its domain when none are given,
/// with a ridge of 1e-9 of its mean diagonal (a function no light sees still gets a
/// finite weight).
pub fn gram(basis: &dyn Basis, directions: Option<&[Vec3]>) -> Vec<f64> {
    let k = basis.len();
    let own;
    let dirs = match directions {
        Some(d) if !d.is_empty() => d,
        _ => {
            own = match basis.domain() {
                crate::basis::Domain::Sphere => crate::sphere::fibonacci(GRAM_DIRECTIONS),
                crate::basis::Domain::UpperHemisphere => {
                    crate::sphere::hemisphere_fibonacci(GRAM_DIRECTIONS)
                }
            };
            &own
        }
    };
    let mut g = vec![0.0; k * k];
    let mut w = vec![0.0; k];
    for &d in dirs {
        basis.eval(d, &mut w);
        for i in 0..k {
            for j in 0..k {
                g[i * k + j] += w[i] * w[j];
            }
        }
    }
    let n = dirs.len() as f64;
    g.iter_mut().for_each(|v| *v /= n);
    let ridge = 1e-9 * (0..k).map(|i| g[i * k + i]).sum::<f64>() / k as f64;
    (0..k).for_each(|i| g[i * k + i] += ridge.max(f64::MIN_POSITIVE));
    g
}

/// The projection onto the `components` principal directions of the coefficient
/// vectors `vectors` (`rows × k`, row-major) in the metric `gram`.
pub fn principal(gram: &[f64], vectors: &[f64], k: usize, components: usize) -> Result<Principal> {
    if components == 0 || components > k {
        return Err(Error::invalid(format!(
            "{components} components of a basis of {k}: choose 1 to {k}"
        )));
    }
    let mut r = gram.to_vec();
    if !crate::linalg::cholesky(&mut r, k) {
        return Err(Error::new(
            ErrorKind::Numerical,
            "the basis' Gram matrix is not positive definite",
        ));
    }
    let rows = vectors.len() / k;
    // z = Rᵀ c for every sampled vector.
    let mut z = vec![0.0; rows * k];
    for (c, zr) in vectors.chunks_exact(k).zip(z.chunks_exact_mut(k)) {
        for i in 0..k {
            zr[i] = (i..k).map(|m| r[m * k + i] * c[m]).sum();
        }
    }
    let v = crate::linalg::principal_directions(&z, rows, k, components);
    let mut encode = vec![0.0; components * k];
    let mut basis_map = vec![0.0; components * k];
    for j in 0..components {
        let vj = &v[j * k..(j + 1) * k];
        // Row j of V Rᵀ is (R v_j)ᵀ.
        for i in 0..k {
            encode[j * k + i] = (0..=i).map(|m| r[i * k + m] * vj[m]).sum();
        }
        // Row j of V R⁻¹ is (R⁻ᵀ v_j)ᵀ: solve Rᵀ x = v_j.
        let row = &mut basis_map[j * k..(j + 1) * k];
        row.copy_from_slice(vj);
        crate::linalg::backward_solve(&r, k, row);
    }
    Ok(Principal {
        k,
        components,
        encode,
        basis_map,
    })
}

impl Principal {
    /// Flip each direction whose angle to `other`'s direction of the same rank is
    /// obtuse (`v·u < 0`; with `E = V Rᵀ` and `P = V R⁻¹` of one metric, `v·u` is the
    /// dot product of a row of `E` with the row of `other`'s `P`). The projection is the
    /// same; its coordinates keep their signs from one projection to the next.
    pub fn orient_like(&mut self, other: &Principal) {
        let k = self.k;
        for j in 0..self.components.min(other.components) {
            let along: f64 = self.encode[j * k..(j + 1) * k]
                .iter()
                .zip(&other.basis_map[j * k..(j + 1) * k])
                .map(|(a, b)| a * b)
                .sum();
            if along < 0.0 {
                self.negate(j);
            }
        }
    }

    /// Direction `j` the other way round (the same projection).
    fn negate(&mut self, j: usize) {
        let k = self.k;
        for v in self.encode[j * k..(j + 1) * k]
            .iter_mut()
            .chain(&mut self.basis_map[j * k..(j + 1) * k])
        {
            *v = -*v;
        }
    }

    /// `out[j] = Σ_i E_ji c[i]` for the first `out.len()` components, each sum in the
    /// order of `i` (so the value is the same however the rows are grouped). Four rows
    /// at a time: four independent sums keep the adder busy where one waits on itself.
    #[inline]
    pub fn apply(&self, c: &[f32], out: &mut [f32]) {
        let k = self.k;
        let (c, e) = (&c[..k], &self.encode);
        let row = |j: usize| &e[j * k..(j + 1) * k];
        let mut j = 0;
        while j + 4 <= out.len() {
            let (r0, r1, r2, r3) = (row(j), row(j + 1), row(j + 2), row(j + 3));
            let mut s = [-0.0f64; 4];
            for (i, &ci) in c.iter().enumerate() {
                let ci = ci as f64;
                s[0] += r0[i] * ci;
                s[1] += r1[i] * ci;
                s[2] += r2[i] * ci;
                s[3] += r3[i] * ci;
            }
            for (o, s) in out[j..j + 4].iter_mut().zip(s) {
                *o = s as f32;
            }
            j += 4;
        }
        for (jj, o) in out.iter_mut().enumerate().skip(j) {
            *o = row(jj)
                .iter()
                .zip(c)
                .fold(-0.0f64, |s, (a, &b)| s + a * b as f64) as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisChoice;

    /// A basis, its Gram matrix over its domain, and `rows` scattered coefficient
    /// vectors.
    fn fixture(name: &str, rows: usize) -> (Box<dyn Basis>, Vec<f64>, Vec<f64>) {
        let basis = BasisChoice::parse(name).unwrap().build(&[], None).unwrap();
        let g = gram(basis.as_ref(), None);
        let vectors: Vec<f64> = (0..rows * basis.len())
            .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect();
        (basis, g, vectors)
    }

    #[test]
    fn all_components_reproduce_every_relit_value() {
        // A non-orthogonal basis (SG lobes overlap): the metric matters.
        let (basis, g, vectors) = fixture("sg:9", 40);
        let k = basis.len();
        let p = principal(&g, &vectors, k, k).unwrap();
        for c in vectors.chunks_exact(k).take(5) {
            let c32: Vec<f32> = c.iter().map(|&v| v as f32).collect();
            let mut y = vec![0.0f32; k];
            p.apply(&c32, &mut y);
            for d in crate::sphere::fibonacci(9) {
                let w = basis.values(d);
                let truth: f64 = w.iter().zip(c).map(|(a, b)| a * b).sum();
                let mapped: f64 = (0..k)
                    .map(|j| {
                        let pw: f64 = (0..k).map(|i| p.basis_map[j * k + i] * w[i]).sum();
                        pw * y[j] as f64
                    })
                    .sum();
                assert!(
                    (truth - mapped).abs() < 1e-4 * (1.0 + truth.abs()),
                    "{truth} vs {mapped}"
                );
            }
        }
    }

    #[test]
    fn oriented_directions_keep_the_projection_and_take_the_others_signs() {
        let (basis, g, vectors) = fixture("sh:9", 60);
        let k = basis.len();
        let reference = principal(&g, &vectors, k, 4).unwrap();
        let mut flipped = principal(&g, &vectors, k, 4).unwrap();
        flipped.negate(0);
        flipped.negate(2);
        assert!(flipped.encode != reference.encode);
        flipped.orient_like(&reference);
        assert_eq!(flipped.encode, reference.encode);
        assert_eq!(flipped.basis_map, reference.basis_map);
    }

    #[test]
    fn vectors_in_a_plane_need_two_components() {
        let basis = BasisChoice::parse("sh:9")
            .unwrap()
            .build(&[], None)
            .unwrap();
        let k = basis.len();
        let g = gram(basis.as_ref(), None);
        let (a, b): (Vec<f64>, Vec<f64>) = (0..k)
            .map(|i| (((i * 3) % 5) as f64 - 2.0, ((i * 5) % 7) as f64 - 3.0))
            .unzip();
        let (a, b) = (&a, &b);
        let vectors: Vec<f64> = (0..50)
            .flat_map(|r| {
                let (s, t) = ((r % 7) as f64 - 3.0, (r % 4) as f64);
                (0..k).map(move |i| s * a[i] + t * b[i]).collect::<Vec<_>>()
            })
            .collect();
        let p = principal(&g, &vectors, k, 2).unwrap();
        for c in vectors.chunks_exact(k).take(6) {
            let c32: Vec<f32> = c.iter().map(|&v| v as f32).collect();
            let mut y = vec![0.0f32; 2];
            p.apply(&c32, &mut y);
            let d = Vec3::new(0.36, 0.48, 0.8);
            let w = basis.values(d);
            let truth: f64 = w.iter().zip(c).map(|(x, y)| x * y).sum();
            let mapped: f64 = (0..2)
                .map(|j| (0..k).map(|i| p.basis_map[j * k + i] * w[i]).sum::<f64>() * y[j] as f64)
                .sum();
            assert!((truth - mapped).abs() < 1e-4 * (1.0 + truth.abs()));
        }
        assert!(principal(&g, &vectors, k, 0).is_err());
        assert!(principal(&g, &vectors, k, k + 1).is_err());
    }
}
