//! The CPU relighting engine: coefficient maps + lights → linear images.
//!
//! A directional light has one light vector for the whole image, so its effect is a
//! weighted sum of the coefficient planes with the basis values `B_i(L)` as weights
//! (seed 000, figure 6). Several lights on linear maps fold into one weight per plane
//! before any pixel is touched, so the cost is one pass over the planes whatever the
//! number of directional lights. Display-referred maps are evaluated per light and
//! decoded to linear before adding.

use crate::color;
use crate::image::ImageRgb;
use crate::light::{Light, LightRig};
use crate::maps::{MapSpace, RelightableImage};
use crate::{Error, Result};
use rayon::prelude::*;

/// Options of [`relight`].
#[derive(Clone, Debug, Default)]
pub struct RelightOptions {
    /// Exposure in stops applied to the result (each +1 doubles it).
    pub exposure: f64,
}

/// Pixels per task: small enough that a chunk of every plane stays in cache.
const CHUNK: usize = 4096;

/// Relight `image` with `rig`.
pub fn relight(image: &RelightableImage, rig: &LightRig, options: &RelightOptions) -> Result<ImageRgb> {
    let basis = image.meta.basis.build()?;
    let k = basis.len();
    if k != image.maps.k {
        return Err(Error::invalid(format!("the maps hold {} coefficients but the basis has {k}", image.maps.k)));
    }
    let scale = 2f64.powf(options.exposure);
    // One weight vector per channel and "pass": linear maps fold every light into one
    // pass; display-referred maps need one pass per light.
    let mut passes: Vec<([Vec<f32>; 3], [f32; 3])> = Vec::new();
    let mut folded: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; k]);
    for light in &rig.lights {
        light.validate()?;
        let Light::Directional(dl) = light;
        let dir = dl.direction.normalized().expect("validated");
        let y = basis.values(dir);
        let rgb = light.rgb();
        match image.meta.color_space {
            MapSpace::Linear => {
                for c in 0..3 {
                    for i in 0..k {
                        folded[c][i] += rgb[c] * scale * y[i];
                    }
                }
            }
            MapSpace::Srgb => {
                let w: Vec<f32> = y.iter().map(|&v| v as f32).collect();
                passes.push(([w.clone(), w.clone(), w], rgb.map(|v| (v * scale) as f32)));
            }
        }
    }
    if image.meta.color_space == MapSpace::Linear {
        passes.push((folded.map(|w| w.iter().map(|&v| v as f32).collect()), [1.0; 3]));
    }
    let maps = &image.maps;
    let n = maps.pixels();
    let mut out = ImageRgb::new(maps.width, maps.height);
    let display = image.meta.color_space == MapSpace::Srgb;
    out.data.par_chunks_mut(3 * CHUNK).enumerate().for_each(|(chunk, dst)| {
        let p0 = chunk * CHUNK;
        let len = dst.len() / 3;
        let mut acc = [vec![0f32; len], vec![0f32; len], vec![0f32; len]];
        for (weights, tint) in &passes {
            for a in acc.iter_mut() {
                a.iter_mut().for_each(|v| *v = 0.0);
            }
            for i in 0..k {
                for c in 0..3 {
                    let w = weights[c][i];
                    let plane = &maps.data[(3 * i + c) * n + p0..(3 * i + c) * n + p0 + len];
                    for (a, &v) in acc[c].iter_mut().zip(plane) {
                        *a += w * v;
                    }
                }
            }
            for p in 0..len {
                for c in 0..3 {
                    let v = if display { color::srgb_to_linear(acc[c][p].clamp(0.0, 1.0)) } else { acc[c][p] };
                    dst[3 * p + c] += tint[c] * v;
                }
            }
        }
    });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::{Basis, BasisSpec};
    use crate::camera::Projection;
    use crate::maps::{CoefficientMaps, Metadata};
    use crate::sphere::Vec3;

    fn one_pixel(coef: &[f32], space: MapSpace) -> RelightableImage {
        let mut maps = CoefficientMaps::zeros(1, 1, coef.len());
        for (i, &v) in coef.iter().enumerate() {
            for c in 0..3 {
                maps.plane_mut(i, c)[0] = v;
            }
        }
        RelightableImage {
            meta: Metadata::new(BasisSpec::Sh { bands: 2 }, space, Projection::default()),
            maps,
            depth: None,
        }
    }

    #[test]
    fn lights_superpose_and_colours_scale() {
        let img = one_pixel(&[0.5, 0.1, 0.3, -0.2], MapSpace::Linear);
        let a = Light::directional([0.0, 1.0, 1.0], [1.0, 0.5, 0.0]);
        let b = Light::directional([1.0, 0.0, 0.2], [0.0, 0.5, 2.0]);
        let opts = RelightOptions::default();
        let ra = relight(&img, &LightRig::new(vec![a.clone()]), &opts).unwrap();
        let rb = relight(&img, &LightRig::new(vec![b.clone()]), &opts).unwrap();
        let both = relight(&img, &LightRig::new(vec![a, b]), &opts).unwrap();
        for c in 0..3 {
            assert!((both.data[c] - ra.data[c] - rb.data[c]).abs() < 1e-6);
        }
        // White light from the pole: Σ c_i Y_i(0,0,1).
        let sh = BasisSpec::Sh { bands: 2 }.build().unwrap();
        let y = sh.values(Vec3::new(0.0, 0.0, 1.0));
        let want = 0.5 * y[0] + 0.3 * y[2];
        let pole = relight(&img, &LightRig::new(vec![Light::directional([0.0, 0.0, 1.0], [1.0; 3])]), &opts).unwrap();
        assert!((pole.data[0] as f64 - want).abs() < 1e-6);
        let brighter =
            relight(&img, &LightRig::new(vec![Light::directional([0.0, 0.0, 1.0], [1.0; 3])]), &RelightOptions { exposure: 1.0 })
                .unwrap();
        assert!((brighter.data[0] - 2.0 * pole.data[0]).abs() < 1e-6);
    }

    #[test]
    fn display_maps_decode_each_light() {
        // Display value 0.5 from the constant term alone: Y_00 = 0.2821.
        let img = one_pixel(&[0.5 / 0.282_094_79, 0.0, 0.0, 0.0], MapSpace::Srgb);
        let rig = LightRig::new(vec![
            Light::directional([0.0, 0.0, 1.0], [1.0; 3]),
            Light::directional([1.0, 0.0, 0.0], [1.0; 3]),
        ]);
        let out = relight(&img, &rig, &RelightOptions::default()).unwrap();
        let want = 2.0 * color::srgb_to_linear(0.5);
        assert!((out.data[0] - want).abs() < 1e-4, "{} vs {want}", out.data[0]);
    }
}
