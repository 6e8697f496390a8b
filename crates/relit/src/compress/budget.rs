//! `--budget N`: the compression settings that relight the capture's own lights best
//! within N bits per pixel of the whole file.
//!
//! Every candidate of a grid (layouts × components × codec settings, and codebooks) is packed into the
//! exact bytes of its file; those over the budget are dropped, the rest are relit at up
//! to [`SCORING_LIGHTS`] of the capture's lights (spread over its order) and scored by
//! the 8-bit sRGB PSNR against those photographs — the training images only: the basis
//! and the maps are already chosen (by leave-one-out, in the fit), so what is compared
//! here is only what each compression loses, and evaluation hold-outs are never seen.

use super::{pack_with_gain, unpack, JpegRange, Layout, Packed, Settings, TileCodec};
use crate::capture::Capture;
use crate::engine::{self, RelightOptions};
use crate::light::{Light, LightRig};
use crate::maps::RelightableImage;
use crate::progress::Progress;
use crate::{Error, Result};

/// Captured lights a candidate is scored at.
pub const SCORING_LIGHTS: usize = 8;

/// Codebook sizes tried.
const VQ_ENTRIES: [usize; 2] = [1024, 4096];

/// The candidates for a basis of `k` functions.
pub fn grid(k: usize) -> Vec<Settings> {
    let mut components: Vec<usize> = [k, 16, 12, 9, 6, 4]
        .into_iter()
        .filter(|&c| c <= k)
        .collect();
    components.dedup();
    let jpeg = |quality| TileCodec::Jpeg { quality };
    let codecs = [
        (jpeg(95), 8, JpegRange::Shared),
        (jpeg(90), 8, JpegRange::Shared),
        (jpeg(80), 8, JpegRange::Shared),
        (jpeg(70), 8, JpegRange::Shared),
        (jpeg(90), 8, JpegRange::PerPlane),
        (jpeg(75), 8, JpegRange::PerPlane),
        (TileCodec::Zstd { level: 12 }, 8, JpegRange::Shared),
        (TileCodec::Zstd { level: 12 }, 6, JpegRange::Shared),
    ];
    let mut out = Vec::new();
    // Vector quantisation: pixels of a capture crowd into few functions, so a codebook
    // of a few thousand entries keeps most of them at a third of JPEG's bits (item1
    // of the shared RTI set, hsh:25, ycc 9/3: 4096 entries 35.53 dB at 12.8 bits/px,
    // JPEG q90 35.57 dB at 34.7).
    let mut vq_components = vec![k.min(16), k.min(9)];
    vq_components.dedup();
    for &c in &vq_components {
        for entries in VQ_ENTRIES {
            out.push(Settings {
                layout: Layout::Ycc,
                components: Some(c),
                chroma: None,
                bits: 10,
                codec: TileCodec::Zstd { level: 12 },
                codebook: Some(entries),
                ..Settings::default()
            });
        }
    }
    for layout in [Layout::Ycc, Layout::Lrgb] {
        for &c in &components {
            for &(codec, bits, jpeg_range) in &codecs {
                let plain = Settings {
                    layout,
                    components: Some(c),
                    chroma: None,
                    bits,
                    codec,
                    jpeg_range,
                    ..Settings::default()
                };
                // The perceptual gain with the image codecs where their fronts meet the
                // budgets of the web (ycc with the shared step, lrgb per plane): at
                // equal bits/px +0.2–0.5 dB on items 1, 3 and 6 of the shared set, none
                // on items 2 and 9 (docs/rd.md).
                let gained = codec.is_image()
                    && matches!(
                        (layout, jpeg_range),
                        (Layout::Ycc, JpegRange::Shared) | (Layout::Lrgb, JpegRange::PerPlane)
                    );
                if gained {
                    out.push(Settings {
                        gain: true,
                        ..plain.clone()
                    });
                }
                out.push(plain);
            }
        }
    }
    out
}

/// What [`choose`] found.
#[derive(Clone, Debug)]
pub struct Choice {
    pub settings: Settings,
    pub packed: Packed,
    /// The file's bits per pixel.
    pub bits_per_pixel: f64,
    /// Mean 8-bit sRGB PSNR at the scoring lights.
    pub score: f64,
    /// Candidates within the budget.
    pub within: usize,
}

/// The best candidate of [`grid`] for `image` (fitted from `capture`) within
/// `bits_per_pixel`.
pub fn choose(
    image: &RelightableImage,
    capture: &Capture,
    bits_per_pixel: f64,
    progress: &dyn Progress,
) -> Result<Choice> {
    if !(bits_per_pixel.is_finite() && bits_per_pixel > 0.0) {
        return Err(Error::invalid(
            "the budget must be a positive number of bits per pixel",
        ));
    }
    let n = capture.len();
    let lights: Vec<usize> = if n <= SCORING_LIGHTS {
        (0..n).collect()
    } else {
        (0..SCORING_LIGHTS)
            .map(|i| (i as f64 * (n - 1) as f64 / (SCORING_LIGHTS - 1) as f64).round() as usize)
            .collect()
    };
    let photos: Vec<_> = lights
        .iter()
        .map(|&i| capture.load_raw(i))
        .collect::<Result<_>>()?;
    let pixels = (image.width() * image.height()) as f64;
    let candidates = grid(image.maps.k);
    let directions = capture.directions();
    let gain = super::gain::perceptual(
        &image.maps,
        image.meta.basis.build()?.as_ref(),
        Some(&directions),
    );
    progress.begin("choosing compression", candidates.len() as u64);
    let mut best: Option<Choice> = None;
    let mut within = 0;
    for candidate in candidates {
        let settings = Settings {
            directions: Some(directions.clone()),
            ..candidate
        };
        let packed = pack_with_gain(image, &settings, Some(&gain))?;
        let bytes = super::container::to_bytes(&packed)?.len();
        let bpp = 8.0 * bytes as f64 / pixels;
        progress.advance(1);
        if bpp > bits_per_pixel {
            continue;
        }
        within += 1;
        let decoded = unpack(&packed)?;
        let relighter = engine::Relighter::new(&decoded)?;
        let mut score = 0.0;
        for (&i, photo) in lights.iter().zip(&photos) {
            let light = &capture.lights[i];
            let color = light.intensity.map(|v| v as f64);
            let rig = LightRig::new(vec![Light::directional(light.direction, color)]);
            let relit = relighter.relight(&rig, &RelightOptions::default())?;
            score += crate::metrics::psnr_srgb8(&relit.data, &photo.data);
        }
        score /= lights.len() as f64;
        if best.as_ref().is_none_or(|b| score > b.score) {
            best = Some(Choice {
                settings,
                packed,
                bits_per_pixel: bpp,
                score,
                within: 0,
            });
        }
    }
    progress.end();
    let mut best = best.ok_or_else(|| {
        Error::invalid(format!(
            "no compression fits in {bits_per_pixel} bits/pixel (the smallest candidate is larger)"
        ))
    })?;
    best.within = within;
    Ok(best)
}
