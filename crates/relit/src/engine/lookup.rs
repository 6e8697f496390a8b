//! Relighting an image whose pixels index a table of coefficient vectors (a codebook,
//! seed 004's vector quantisation) without expanding it.
//!
//! A light that is the same for every pixel (directional, environment) gives every
//! pixel with the same entry the same colour, so a frame relights the `C` entries once
//! (the ordinary engine over a `C × 1` image) and then costs one table look-up and one
//! 12-byte store a pixel: it reads 2 bytes a pixel where planes read `3·K·b`. Lights
//! that differ per pixel (point, spot, projector, area) need the surface point and are
//! refused here; their frames come from the expanded maps.

use super::kernels::Simd;
use super::{RelightOptions, Relighter, STREAM_BYTES};
use crate::image::ImageRgb;
use crate::light::{Light, LightRig, PreparedLight};
use crate::maps::RelightableImage;
use crate::{Error, Result};
use rayon::prelude::*;

/// An image as indices into a table of entries.
#[derive(Clone, Debug)]
pub struct IndexedImage {
    /// The entries as a `C × 1` relightable image (its basis and colour space are the
    /// image's; its depth, when it has one, is the whole image's, one value a pixel).
    pub entries: RelightableImage,
    /// One entry per pixel, row-major.
    pub indices: Vec<u16>,
    pub width: usize,
    pub height: usize,
}

impl IndexedImage {
    /// The ordinary maps: every pixel's entry copied out.
    pub fn expand(&self) -> RelightableImage {
        let k = self.entries.maps.k;
        let c = self.entries.maps.pixels();
        let n = self.width * self.height;
        let mut maps = crate::maps::CoefficientMaps::zeros(self.width, self.height, k);
        maps.data
            .par_chunks_mut(n)
            .enumerate()
            .for_each(|(plane, out)| {
                let table = &self.entries.maps.data[plane * c..(plane + 1) * c];
                for (o, &i) in out.iter_mut().zip(&self.indices) {
                    *o = table[i as usize];
                }
            });
        RelightableImage {
            meta: self.entries.meta.clone(),
            maps,
            depth: self.entries.depth.clone().filter(|d| d.len() == n),
        }
    }
}

/// Relights an [`IndexedImage`] by relighting its entries once a frame.
pub struct LookupRelighter<'a> {
    image: &'a IndexedImage,
    entries: Relighter<'a>,
    simd: Simd,
}

/// Pixels gathered per step before they are written out.
const RUN: usize = 4096;

impl<'a> LookupRelighter<'a> {
    pub fn new(image: &'a IndexedImage) -> Result<Self> {
        let c = image.entries.maps.pixels();
        if image.entries.height() != 1 || c == 0 {
            return Err(Error::invalid("a codebook is a non-empty C × 1 image"));
        }
        if image.indices.len() != image.width * image.height {
            return Err(Error::invalid("an indexed image needs one index per pixel"));
        }
        if image.indices.iter().any(|&i| i as usize >= c) {
            return Err(Error::invalid(format!(
                "an index points past the codebook's {c} entries"
            )));
        }
        Ok(Self {
            image,
            entries: Relighter::new(&image.entries)?,
            simd: Simd::detect(),
        })
    }

    /// Bytes one frame reads: the indices.
    pub fn index_bytes(&self) -> usize {
        2 * self.image.indices.len()
    }

    /// Whether every light of `rig` is the same for every pixel (directional or
    /// environment), which is what this relighter draws.
    pub fn draws(rig: &LightRig) -> bool {
        rig.lights
            .iter()
            .all(|l| matches!(l, Light::Directional(_) | Light::Environment(_)))
    }

    /// Relight under `rig` (see [`LookupRelighter::draws`]).
    pub fn relight(&self, rig: &LightRig, options: &RelightOptions) -> Result<ImageRgb> {
        let lights = self.entries.prepare_rig(rig, options)?;
        let mut out = ImageRgb::new(0, 0);
        self.relight_prepared_into(&lights, options.exposure, &mut out)?;
        Ok(out)
    }

    /// Relight every pixel under `lights` (all of them uniform) into `out`, which
    /// becomes `width × height` and reuses its buffer.
    pub fn relight_prepared_into(
        &self,
        lights: &[PreparedLight],
        exposure: f64,
        out: &mut ImageRgb,
    ) -> Result<()> {
        if let Some(l) = lights.iter().find(|l| !l.is_uniform()) {
            return Err(Error::invalid(format!(
                "a {} light differs per pixel: relight the expanded maps instead of the codebook",
                light_kind(l)
            )));
        }
        let relit = self.entries.relight_prepared(lights, exposure)?;
        // Four floats an entry: one 16-byte load a pixel.
        let table: Vec<f32> = relit
            .data
            .chunks_exact(3)
            .flat_map(|rgb| [rgb[0], rgb[1], rgb[2], 0.0])
            .collect();
        let n = self.image.indices.len();
        out.width = self.image.width;
        out.height = self.image.height;
        out.data.resize(3 * n, 0.0);
        let stream = 12 * n >= STREAM_BYTES;
        let simd = self.simd;
        out.data
            .par_chunks_mut(3 * RUN)
            .zip(self.image.indices.par_chunks(RUN))
            .for_each(|(dst, indices)| {
                if stream {
                    simd.gather_stream(dst, &table, indices);
                } else {
                    for (px, &i) in dst.chunks_exact_mut(3).zip(indices) {
                        let e = 4 * i as usize;
                        px.copy_from_slice(&table[e..e + 3]);
                    }
                }
            });
        Ok(())
    }
}

fn light_kind(light: &PreparedLight) -> &'static str {
    match light {
        PreparedLight::Directional { .. } => "directional",
        PreparedLight::Weights(_) => "environment",
        PreparedLight::Point(..) => "point",
        PreparedLight::Spot(..) => "spot",
        PreparedLight::Projector(..) => "projector",
        PreparedLight::Area(..) => "area",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::BasisChoice;
    use crate::camera::Projection;
    use crate::maps::{CoefficientMaps, MapSpace, Metadata};

    fn indexed(w: usize, h: usize) -> IndexedImage {
        let basis = BasisChoice::parse("sh:9")
            .unwrap()
            .build(&[], None)
            .unwrap();
        let entries = 37;
        let mut maps = CoefficientMaps::zeros(entries, 1, 9);
        for (i, v) in maps.data.iter_mut().enumerate() {
            *v = ((i * 7919) % 101) as f32 / 101.0 - 0.3;
        }
        let meta = Metadata::new(
            basis.spec(),
            MapSpace::Linear,
            Projection::Cylindrical { fov_y_deg: None },
        );
        IndexedImage {
            entries: RelightableImage {
                meta,
                maps,
                depth: None,
            },
            indices: (0..w * h).map(|p| ((p * 31) % entries) as u16).collect(),
            width: w,
            height: h,
        }
    }

    #[test]
    fn look_ups_match_relighting_the_expanded_maps() {
        let image = indexed(53, 7);
        let expanded = image.expand();
        let lights = vec![
            PreparedLight::Directional {
                direction: crate::sphere::Vec3::new(0.3, 0.8, 0.5)
                    .normalized()
                    .unwrap(),
                rgb: [1.0, 0.5, 0.25],
            },
            PreparedLight::Weights(std::array::from_fn(|c| {
                (0..9).map(|i| 0.1 * (i + c) as f64).collect()
            })),
        ];
        let want = Relighter::new(&expanded)
            .unwrap()
            .relight_prepared(&lights, 0.5)
            .unwrap();
        let lookup = LookupRelighter::new(&image).unwrap();
        let mut got = ImageRgb::new(0, 0);
        lookup
            .relight_prepared_into(&lights, 0.5, &mut got)
            .unwrap();
        assert_eq!((got.width, got.height), (53, 7));
        for (a, b) in got.data.iter().zip(&want.data) {
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1.0), "{a} vs {b}");
        }
    }

    #[test]
    fn per_pixel_lights_and_bad_indices_are_refused() {
        let image = indexed(8, 2);
        let lookup = LookupRelighter::new(&image).unwrap();
        let point: crate::light::PointLight =
            serde_json::from_str(r#"{"position": [0, 0, 1]}"#).unwrap();
        let prepared = vec![PreparedLight::Point(point, [1.0; 3])];
        let err = lookup
            .relight_prepared_into(&prepared, 0.0, &mut ImageRgb::new(0, 0))
            .unwrap_err();
        assert!(err.to_string().contains("point"), "{err}");
        let mut bad = indexed(8, 2);
        bad.indices[3] = 999;
        assert!(LookupRelighter::new(&bad).is_err());
        bad.indices.pop();
        assert!(LookupRelighter::new(&bad).is_err());
    }
}
