//! The perceptual gain: one per-pixel scale that every function plane is divided by
//! before the principal components and quantisation, and multiplied by on reading.
//!
//! Relit images are judged on screen (8-bit sRGB), where an error `δ` in linear
//! radiance shows as `srgb′(v)·δ`: about 13 at black, 0.44 at white. A plane quantised
//! with one step everywhere therefore spends its precision on bright pixels and shows
//! its steps in dark ones. Dividing a pixel's functions by
//! `m = srgb′(1) / √(mean over lights and channels of srgb′(v)²)` makes one step of the
//! divided planes the same error on screen everywhere, and the principal components of
//! the divided functions are found in that metric too. The gain is a scale, so the
//! stored image still adds lights linearly: a reader multiplies the planes back and
//! relights as usual.
//!
//! `m` is itself a stored plane (quantised like an albedo plane). The writer divides by
//! the gain exactly as a reader decodes it, so the gain's own quantisation error is
//! carried by the function planes rather than added to them.

use super::TileCodec;
use crate::basis::{Basis, Domain};
use crate::maps::CoefficientMaps;
use crate::sphere::Vec3;
use rayon::prelude::*;

/// The channel name of the gain plane.
pub const CHANNEL: &str = "gain";

/// The smallest gain a reader applies (a lossy plane may ring below the gains written,
/// which are at least `srgb′(1)/12.92 ≈ 0.034`).
pub const FLOOR: f32 = 1.0 / 256.0;

/// The JPEG quality of the gain plane at most. Its error is carried by the function
/// planes, so a coarse gain costs them little: ycc 12 components at q80, item1 of the
/// shared RTI set, gain at q30/q50/q75: 35.22/35.26/35.27 dB at 8.8/9.0/9.5 bits/px
/// (item6, 16 components at q95, gain q50/q75/q95: 37.42/37.39/37.42 dB at
/// 22.8/23.2/24.8).
const JPEG_QUALITY: u8 = 50;

/// The most light directions the gain averages over (evenly thinned beyond).
const DIRECTIONS: usize = 64;

/// The gain a reader applies for a decoded gain value.
#[inline]
pub fn applied(decoded: f32) -> f32 {
    if decoded.is_finite() {
        decoded.max(FLOOR)
    } else {
        FLOOR
    }
}

/// The codec of the gain plane's tiles in a file whose planes use `codec` (a JPEG
/// reader needs no quality, so the header's one codec still describes it).
pub fn codec(codec: TileCodec) -> TileCodec {
    match codec {
        TileCodec::Jpeg { quality } => TileCodec::Jpeg {
            quality: quality.min(JPEG_QUALITY),
        },
        TileCodec::Webp { quality } => TileCodec::Webp {
            quality: quality.min(JPEG_QUALITY),
        },
        lossless => lossless,
    }
}

/// The perceptual gain of every pixel of `maps` (in `basis`), averaged over
/// `directions` (the capture's lights) or over the basis' domain.
pub fn perceptual(
    maps: &CoefficientMaps,
    basis: &dyn Basis,
    directions: Option<&[Vec3]>,
) -> Vec<f32> {
    let k = maps.k;
    let own;
    let all = match directions {
        Some(d) if !d.is_empty() => d,
        _ => {
            own = match basis.domain() {
                Domain::Sphere => crate::sphere::fibonacci(DIRECTIONS),
                Domain::UpperHemisphere => crate::sphere::hemisphere_fibonacci(DIRECTIONS),
            };
            &own
        }
    };
    let step = all.len().div_ceil(DIRECTIONS);
    let weights: Vec<f64> = all
        .iter()
        .step_by(step)
        .flat_map(|&d| {
            let mut w = vec![0.0; k];
            basis.eval(d, &mut w);
            w
        })
        .collect();
    let lights = weights.len() / k;
    // Function by function, each light's weight side by side: a pixel's values at every
    // light are then sums that advance together (one light's sum alone waits on each
    // addition in turn), each still over the functions in order.
    let by_function: Vec<f64> = (0..k)
        .flat_map(|i| weights.iter().skip(i).step_by(k).copied())
        .collect();
    let white = crate::color::srgb_slope(1.0);
    let planes: Vec<[&[f32]; 3]> = (0..k)
        .map(|i| [0, 1, 2].map(|ch| maps.plane(i, ch)))
        .collect();
    (0..maps.pixels())
        .into_par_iter()
        .map_init(
            || (vec![0.0f64; 3 * lights], Vec::new()),
            |(values, scratch), p| {
                values.fill(0.0);
                {
                    let (red, rest) = values.split_at_mut(lights);
                    let (green, blue) = rest.split_at_mut(lights);
                    for (w, plane) in by_function.chunks_exact(lights).zip(&planes) {
                        let c = plane.map(|values| values[p] as f64);
                        for (j, &wi) in w.iter().enumerate() {
                            red[j] += wi * c[0];
                            green[j] += wi * c[1];
                            blue[j] += wi * c[2];
                        }
                    }
                }
                crate::color::srgb_slope_tabulated_batch(values, scratch);
                let mut sum = 0.0;
                for j in 0..lights {
                    sum += [values[j], values[lights + j], values[2 * lights + j]]
                        .iter()
                        .map(|s| s.powi(2))
                        .sum::<f64>();
                }
                (white / (sum / (3 * lights) as f64).sqrt()) as f32
            },
        )
        .collect()
}

/// The luminance of a pixel's coefficient `i` (what the gain's averaging sees in a
/// greyscale image), for tests.
#[cfg(test)]
fn luma_of(maps: &CoefficientMaps, i: usize, p: usize) -> f32 {
    super::layout::luma([
        maps.plane(i, 0)[p],
        maps.plane(i, 1)[p],
        maps.plane(i, 2)[p],
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisChoice;

    #[test]
    fn the_gain_follows_the_slope_of_the_display_curve() {
        // A constant function of value v (coefficient of the constant SH term).
        let basis = BasisChoice::parse("sh:1")
            .unwrap()
            .build(&[], None)
            .unwrap();
        let y0 = basis.values(Vec3::new(0.0, 0.0, 1.0))[0] as f32;
        let values = [0.0005f32, 0.002, 0.01, 0.1, 0.5, 1.0];
        let mut maps = CoefficientMaps::zeros(values.len(), 1, 1);
        for (p, &v) in values.iter().enumerate() {
            for ch in 0..3 {
                maps.plane_mut(0, ch)[p] = v / y0;
            }
        }
        let g = perceptual(&maps, basis.as_ref(), None);
        let white = crate::color::srgb_slope(1.0);
        for (p, &v) in values.iter().enumerate() {
            assert!((luma_of(&maps, 0, p) * y0 - v).abs() < 1e-6);
            let want = white / crate::color::srgb_slope(v as f64);
            assert!(
                (g[p] as f64 - want).abs() < 1e-5 * want.max(1.0),
                "{v}: {} against {want}",
                g[p]
            );
        }
        // Black and the linear segment share the largest slope; white has gain 1.
        assert_eq!(g[0], g[1]);
        assert!((g[5] - 1.0).abs() < 1e-6);
        assert!(g[0] >= FLOOR && g[0] < 0.04);
    }

    #[test]
    fn a_decoded_gain_never_divides_by_zero() {
        assert_eq!(applied(0.0), FLOOR);
        assert_eq!(applied(-1.0), FLOOR);
        assert_eq!(applied(f32::NAN), FLOOR);
        assert_eq!(applied(0.5), 0.5);
    }
}
