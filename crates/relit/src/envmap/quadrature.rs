//! An environment as a few thousand directional lights: how bases other than SH (which
//! has an exact projection, `super`) are lit by an environment, on the CPU engine, and
//! how the browser viewer lights every basis (it ships the quadrature).
//!
//! The map's texels are gathered into at most [`QUADRATURE_WIDTH`] ×
//! [`QUADRATURE_HEIGHT`] coarse texels by their centres (a map no larger keeps its
//! texels). Each coarse texel becomes one directional light: intensity the summed
//! `E·ΔΩ` of its texels per channel (so `∫ E dω` is kept exactly), direction their
//! energy's centroid (the sum of the texel directions weighted by `Σ_c |E_c|·ΔΩ`,
//! normalised; the coarse texel's centre when it has no energy). An environment's
//! weights on a basis `y` are then `e_c = Σ_t I_{t,c} · y(R ω_t)` with the rotation `R`
//! turning the directions ([`quadrature_weights`]): one basis evaluation per light and
//! frame.
//!
//! # Size
//!
//! Measured on the seven shared maps (`shared/data/envmaps`, 1024×512 Radiance HDR,
//! suns included), turned by yaw 30°, pitch −10°, roll 5°: the largest |weight error|
//! of each size against the finest quadrature (1024×512, every texel its own light),
//! relative to the largest weight, worst map per basis:
//!
//! | basis | 32×16 | 64×32 | **128×64** | 256×128 |
//! |---|---|---|---|---|
//! | sh:25 | 1.4e-2 | 2.9e-3 | 8.1e-4 | 2.2e-4 |
//! | sh:64 | 1.9e-2 | 4.9e-3 | 1.5e-3 | 5.1e-4 |
//! | hsh:25 | 8.9e-3 | 3.9e-3 | 1.2e-3 | 1.3e-3 |
//! | sg:25 | 1.5e-3 | 4.9e-4 | 1.3e-4 | 4.3e-5 |
//! | sg:64 | 2.3e-3 | 7.5e-4 | 2.2e-4 | 5.5e-5 |
//! | ptm:6 | 1.9e-2 | 3.8e-3 | 1.1e-3 | 5.9e-4 |
//!
//! 128×64 (8192 lights, one basis evaluation each per frame) keeps every weight within
//! 1.5e-3 of the largest, below an 8-bit step (3.9e-3); halving the error again would
//! cost 4× the evaluations. hsh:25 on `royal_esplanade` (left out above) stays at
//! 1.2–1.4e-2 for every size: its sun sits at the horizon, where the `|m| = 1` HSH
//! functions grow like `√z` (`crate::basis::hsh`), so a texel's energy moved to its
//! centroid is off by the square root of the texel size and the error shrinks only once
//! the texels are finer than the sun; the same √z is why hsh's error stalls at
//! 256×128 on `moonless_golf`.
//!
//! (`quadrature_size_measurement`, an ignored test: `cargo test -p relit --release
//! quadrature_size -- --ignored --nocapture`.)

use super::{latlong_direction, texel_solid_angle};
use crate::basis::{mat3_apply, Basis, Mat3};
use crate::image::ImageRgb;
use crate::sphere::Vec3;

/// Columns of the coarse map a quadrature gathers texels into (at most).
pub const QUADRATURE_WIDTH: usize = 128;
/// Rows of the coarse map a quadrature gathers texels into (at most).
pub const QUADRATURE_HEIGHT: usize = 64;

/// The directional lights standing for the lat-long `map` (module docs): its texels
/// gathered into at most `width × height` coarse texels by their centres, each light the
/// summed `E ΔΩ` of its texels at their energy's centroid (the coarse texel's centre
/// when it has no energy). Light directions are in the light frame, unrotated.
pub fn environment_quadrature(
    map: &ImageRgb,
    width: usize,
    height: usize,
) -> Vec<(Vec3, [f64; 3])> {
    let (fw, fh) = (map.width, map.height);
    let (cw, ch) = (width.clamp(1, fw), height.clamp(1, fh));
    let mut out = Vec::with_capacity(cw * ch);
    for cy in 0..ch {
        let mut sums = vec![[0.0f64; 3]; cw];
        let mut centroid = vec![Vec3::new(0.0, 0.0, 0.0); cw];
        // Fine rows whose centres fall in coarse row cy: y·ch/fh == cy.
        for y in (cy * fh).div_ceil(ch)..((cy + 1) * fh).div_ceil(ch) {
            let solid_angle = texel_solid_angle(fw, fh, y);
            for x in 0..fw {
                let cx = x * cw / fw;
                let d =
                    latlong_direction((x as f64 + 0.5) / fw as f64, (y as f64 + 0.5) / fh as f64);
                let i = map.get(x, y).map(|v| v as f64 * solid_angle);
                for (s, v) in sums[cx].iter_mut().zip(i) {
                    *s += v;
                }
                centroid[cx] = centroid[cx] + d * i.iter().map(|v| v.abs()).sum::<f64>();
            }
        }
        for (cx, (i, c)) in sums.into_iter().zip(centroid).enumerate() {
            let centre =
                || latlong_direction((cx as f64 + 0.5) / cw as f64, (cy as f64 + 0.5) / ch as f64);
            out.push((c.normalized().unwrap_or_else(centre), i));
        }
    }
    out
}

/// The weights of the quadrature `lights` on `basis`, the environment turned by
/// `rotation`: `e_c = Σ_t I_{t,c} · y(R ω_t)` per channel (lights without intensity
/// are skipped).
pub fn quadrature_weights(
    lights: &[(Vec3, [f64; 3])],
    basis: &dyn Basis,
    rotation: &Mat3,
) -> [Vec<f64>; 3] {
    let k = basis.len();
    let mut weights: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; k]);
    let mut y = vec![0.0; k];
    for (d, i) in lights {
        if *i == [0.0; 3] {
            continue;
        }
        basis.eval(mat3_apply(rotation, *d), &mut y);
        for (w, &ic) in weights.iter_mut().zip(i) {
            for (w, &v) in w.iter_mut().zip(&y) {
                *w += ic * v;
            }
        }
    }
    weights
}

/// The quadrature `lights` lumped into at most `count` directional lights by median cut
/// (Debevec, "A median cut algorithm for light probe sampling", 2005): the set is split
/// in two along the axis of its widest spread of directions, at the light whose energy
/// (`Σ_c |I_c|`) brings the first part to half, and again in each part, the part of
/// most energy first, until there are `count` parts or no part has two lights. Each
/// part becomes one light: its summed intensity (so `∫ E dω` is kept exactly) at its
/// energy's centroid.
///
/// This is how an environment lights display-referred maps
/// ([`crate::maps::MapSpace::Srgb`]): there each light's contribution is decoded to
/// radiance before lights add up, so an environment costs one pass per light, not one
/// dot product, and a few lights must stand for the whole map.
pub fn median_cut(lights: &[(Vec3, [f64; 3])], count: usize) -> Vec<(Vec3, [f64; 3])> {
    let coordinate = |d: Vec3, axis: usize| [d.x, d.y, d.z][axis];
    let energy = |l: &(Vec3, [f64; 3])| l.1.iter().map(|v| v.abs()).sum::<f64>();
    let mut parts: Vec<Vec<(Vec3, [f64; 3])>> =
        vec![lights.iter().filter(|l| energy(l) > 0.0).copied().collect()];
    while parts.len() < count.max(1) {
        // The part of most energy that can still be split.
        let Some((at, _)) = parts
            .iter()
            .enumerate()
            .filter(|(_, p)| p.len() > 1)
            .map(|(i, p)| (i, p.iter().map(energy).sum::<f64>()))
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        let mut part = parts.swap_remove(at);
        let spread = |axis: usize| {
            let (lo, hi) = part
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), l| {
                    let v = coordinate(l.0, axis);
                    (lo.min(v), hi.max(v))
                });
            hi - lo
        };
        let axis = (0..3)
            .max_by(|&a, &b| spread(a).total_cmp(&spread(b)))
            .expect("three axes");
        part.sort_by(|a, b| coordinate(a.0, axis).total_cmp(&coordinate(b.0, axis)));
        let total: f64 = part.iter().map(energy).sum();
        let mut running = 0.0;
        let mut cut = part.len() - 1;
        for (i, l) in part.iter().enumerate() {
            running += energy(l);
            if running >= 0.5 * total {
                cut = i + 1;
                break;
            }
        }
        let cut = cut.clamp(1, part.len() - 1);
        let rest = part.split_off(cut);
        parts.push(part);
        parts.push(rest);
    }
    parts
        .into_iter()
        .map(|part| {
            let mut sum = [0.0; 3];
            let mut centroid = Vec3::new(0.0, 0.0, 0.0);
            for l in &part {
                for (s, v) in sum.iter_mut().zip(l.1) {
                    *s += v;
                }
                centroid = centroid + l.0 * energy(l);
            }
            let direction = centroid
                .normalized()
                .unwrap_or_else(|| part.first().map_or(Vec3::new(0.0, 0.0, 1.0), |l| l.0));
            (direction, sum)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{rotation_from_yaw_pitch_roll, BasisSpec, Window};
    use crate::envmap::EnvironmentLight;

    /// A 256×128 sky: a gradient, a warm ground and a small bright sun.
    fn sky() -> ImageRgb {
        let (w, h) = (256, 128);
        let mut map = ImageRgb::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let up = 1.0 - (y as f32 + 0.5) / h as f32;
                let sun = (x as i64 - 90).abs() <= 2 && (y as i64 - 40).abs() <= 2;
                let rgb = if sun {
                    [40.0, 36.0, 30.0]
                } else if up > 0.5 {
                    [0.3 + 0.2 * up, 0.4 + 0.3 * up, 0.6 + 0.4 * up]
                } else {
                    [0.2, 0.15, 0.1]
                };
                map.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&rgb);
            }
        }
        map
    }

    /// The quadrature keeps `∫ E dω` exactly, and a map no larger than it keeps its
    /// texels (at their centres where they are lit evenly).
    #[test]
    fn the_quadrature_keeps_the_integral() {
        let map = sky();
        let lights = environment_quadrature(&map, QUADRATURE_WIDTH, QUADRATURE_HEIGHT);
        assert_eq!(lights.len(), QUADRATURE_WIDTH * QUADRATURE_HEIGHT);
        let mut want = [0.0f64; 3];
        for y in 0..map.height {
            let a = texel_solid_angle(map.width, map.height, y);
            for x in 0..map.width {
                for (w, v) in want.iter_mut().zip(map.get(x, y)) {
                    *w += v as f64 * a;
                }
            }
        }
        for c in 0..3 {
            let got: f64 = lights.iter().map(|(_, i)| i[c]).sum();
            assert!(
                (got - want[c]).abs() < 1e-9 * want[c],
                "{got} vs {}",
                want[c]
            );
        }
        assert_eq!(environment_quadrature(&map, 1000, 1000).len(), 256 * 128);
    }

    /// For SH, the quadrature's weights equal the exact projection of the map (rotated)
    /// within QUADRATURE_SH_TOLERANCE of the largest weight.
    #[test]
    fn sh_weights_of_the_quadrature_equal_the_exact_projection() {
        let map = sky();
        let lights = environment_quadrature(&map, QUADRATURE_WIDTH, QUADRATURE_HEIGHT);
        let rotation = rotation_from_yaw_pitch_roll(40.0, -15.0, 10.0).unwrap();
        for bands in [3, 5, 8] {
            let sh = BasisSpec::named(&format!("sh:{}", bands * bands))
                .unwrap()
                .build()
                .unwrap();
            let got = quadrature_weights(&lights, sh.as_ref(), &rotation);
            let exact = sh
                .environment(&map)
                .expect("an exact projection")
                .unwrap()
                .weights(&rotation, Window::None)
                .unwrap();
            let peak = exact.iter().flatten().fold(0f64, |m, v| m.max(v.abs()));
            let err = got
                .iter()
                .flatten()
                .zip(exact.iter().flatten())
                .fold(0f64, |m, (a, b)| m.max((a - b).abs()));
            eprintln!(
                "sh bands {bands}: max |quadrature − exact| = {:.2e} of the peak",
                err / peak
            );
            assert!(
                err <= QUADRATURE_SH_TOLERANCE * peak,
                "bands {bands}: {err} vs peak {peak}"
            );
        }
    }

    /// |quadrature − exact SH projection| relative to the largest weight, for the test
    /// sky (a 5×5-texel sun) at 3, 5 and 8 bands: measured 1.3e-4, 3.2e-4 and 7.0e-4.
    const QUADRATURE_SH_TOLERANCE: f64 = 2e-3;

    /// The error of each quadrature size against a fine one (every texel its own light)
    /// on the shared environment maps, for several bases: the figures in the module docs.
    #[test]
    #[ignore]
    fn quadrature_size_measurement() {
        let root =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/envmaps");
        let mut paths: Vec<_> = std::fs::read_dir(&root)
            .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
            .unwrap_or_default();
        paths.retain(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("hdr" | "exr")));
        paths.sort();
        let bases: Vec<Box<dyn Basis>> = ["sh:25", "sh:64", "hsh:25", "sg:25", "sg:64", "ptm:6"]
            .iter()
            .map(|n| BasisSpec::named(n).unwrap().build().unwrap())
            .collect();
        let rotation = rotation_from_yaw_pitch_roll(30.0, -10.0, 5.0).unwrap();
        for path in &paths {
            let env = EnvironmentLight::load(path).unwrap();
            let map = env.map();
            let fine = environment_quadrature(map, 1024, 512);
            eprintln!(
                "{} ({}×{}, fine {} lights)",
                path.display(),
                map.width,
                map.height,
                fine.len()
            );
            for basis in &bases {
                let want = quadrature_weights(&fine, basis.as_ref(), &rotation);
                let peak = want.iter().flatten().fold(0f64, |m, v| m.max(v.abs()));
                let mut line = format!("  {:>7}", basis.name());
                for (w, h) in [(32, 16), (64, 32), (128, 64), (256, 128)] {
                    let lights = environment_quadrature(map, w, h);
                    let got = quadrature_weights(&lights, basis.as_ref(), &rotation);
                    let err = got
                        .iter()
                        .flatten()
                        .zip(want.iter().flatten())
                        .fold(0f64, |m, (a, b)| m.max((a - b).abs()));
                    line += &format!("  {w}×{h}: {:.1e}", err / peak);
                }
                eprintln!("{line}");
            }
        }
    }
}
