//! `--budget N`: the compression settings that relight the capture's own lights best
//! within N bits per pixel of the whole file.
//!
//! Every candidate of a grid (layouts × components × codec settings, and codebooks) is packed into the
//! exact bytes of its file; those over the budget are dropped, the rest are relit at up
//! to [`SCORING_LIGHTS`] of the capture's lights (spread over its order) and scored by
//! the 8-bit sRGB PSNR against those photographs — the training images only: the basis
//! and the maps are already chosen (by leave-one-out, in the fit), so what is compared
//! here is only what each compression loses, and evaluation hold-outs are never seen.
//!
//! A large image is judged on a sample ([`Sample`]): windows spread over it, put side by
//! side into one small image that every candidate is packed and scored on; the best
//! candidates in turn are then packed from the whole image until one fits the budget.
//! The grid holds 196 candidates at K = 25, each a pack, an unpack and eight frames:
//! on a whole megapixel image that took many minutes, and would take hours on a
//! panorama.

use super::{pack_with_gain, unpack, JpegRange, Layout, Packed, Settings, TileCodec};
use crate::capture::Capture;
use crate::engine::{self, RelightOptions};
use crate::light::{Light, LightRig};
use crate::maps::RelightableImage;
use crate::progress::Progress;
use crate::{Error, Result};
use rayon::prelude::*;

/// Captured lights a candidate is scored at.
pub const SCORING_LIGHTS: usize = 8;

/// Codebook sizes tried.
const VQ_ENTRIES: [usize; 2] = [1024, 4096];

/// Block sides of the candidates with principal components per block. On items 1 and
/// 3 of the shared RTI set (ycc, K′ 6–12, JPEG q90, peer protocol) 128 and 256 were
/// within 0.1 dB of each other and 0.7–1.0 dB above one projection for the file at
/// equal bits; on item9 (279×289, where 256 leaves one whole block) 128 was 0.2–0.4 dB
/// above 256. So both are candidates and the capture's own lights choose.
pub const PCA_BLOCKS: [usize; 2] = [128, 256];

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
                // Principal components per block where the budgets of the web are won
                // (ycc with the shared JPEG step, q80 and above): each block's own
                // functions, and its own chroma projection, at a few hundred bytes a
                // block (item1, K′ 6: 34.58 → 35.60 dB at 8 bits/px).
                let per_block = layout == Layout::Ycc
                    && jpeg_range == JpegRange::Shared
                    && matches!(codec, TileCodec::Jpeg { quality } if quality >= 80);
                if per_block {
                    for block in PCA_BLOCKS {
                        for gain in [false, true] {
                            // The gain where it helps one projection (q90 and q80).
                            if gain && matches!(codec, TileCodec::Jpeg { quality: 95 }) {
                                continue;
                            }
                            out.push(Settings {
                                gain,
                                pca_block: Some(block),
                                ..plain.clone()
                            });
                        }
                    }
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
    /// Mean 8-bit sRGB PSNR at the scoring lights (over the sample's pixels where the
    /// image was judged on one).
    pub score: f64,
    /// Candidates within the budget (on the sample, where there is one).
    pub within: usize,
    /// The pixels the candidates were judged on: the image's, or its sample's.
    pub judged_pixels: usize,
}

/// The best candidate of [`grid`] for `image` (fitted from `capture`) within
/// `bits_per_pixel`.
pub fn choose(
    image: &RelightableImage,
    capture: &Capture,
    bits_per_pixel: f64,
    progress: &dyn Progress,
) -> Result<Choice> {
    let judges = Judges::of(capture)?;
    let sampled = Sample::of(image.width(), image.height()).map(|s| judges.sampled(s));
    choose_with(image, &judges, sampled.as_ref(), bits_per_pixel, progress)
}

/// [`choose`] with the scoring lights' photographs already loaded: on the whole image,
/// or on its sample (`sampled`, the sample and its photographs, for a large one).
fn choose_with(
    image: &RelightableImage,
    judges: &Judges,
    sampled: Option<&(Sample, Judges)>,
    bits_per_pixel: f64,
    progress: &dyn Progress,
) -> Result<Choice> {
    let Some((sample, sample_judges)) = sampled else {
        let side_by_side = (image.width() * image.height()) as f64 <= PARALLEL_PIXELS;
        let ranked = judge_grid(image, judges, bits_per_pixel, 1.0, progress, side_by_side)?;
        return Ok(best_of(ranked));
    };
    let small = sample.image(image);
    let directions = judges.capture.directions();
    let basis = image.meta.basis.build()?;
    let mut gain: Option<Vec<f32>> = None;
    let mut kept = None;
    let pixels = image.width() * image.height();
    let verdict = choose_on_sample(
        &small,
        sample_judges,
        pixels,
        bits_per_pixel,
        progress,
        |settings| {
            if settings.gain && gain.is_none() {
                let whole = super::gain::perceptual(&image.maps, basis.as_ref(), Some(&directions));
                gain = Some(whole);
            }
            let gain = gain.as_deref().filter(|_| settings.gain);
            let packed = pack_with_gain(image, settings, gain)?;
            let bytes = super::container::to_bytes(&packed)?.len();
            kept = Some(packed);
            Ok(bytes as u64)
        },
    )?;
    let packed = kept.ok_or_else(|| Error::invalid("the budget chose a file it had not packed"))?;
    Ok(Choice {
        settings: verdict.settings,
        packed,
        bits_per_pixel: verdict.bits_per_pixel,
        score: verdict.score,
        within: verdict.within,
        judged_pixels: verdict.judged_pixels,
    })
}

/// Every candidate judged on the sample `small` (with the photographs' sample
/// `sample_judges`), then the best whose whole file of `pixels` pixels, as `pack` makes
/// it, fits: its sample's verdict with the whole file's bits per pixel, and the
/// candidates within the budget on the sample.
fn choose_on_sample(
    small: &RelightableImage,
    sample_judges: &Judges,
    pixels: usize,
    bits_per_pixel: f64,
    progress: &dyn Progress,
    pack: impl FnMut(&Settings) -> Result<u64>,
) -> Result<Verdict> {
    let ranked = judge_grid(
        small,
        sample_judges,
        bits_per_pixel,
        SAMPLE_ALLOWANCE,
        progress,
        true,
    )?;
    let (at, bpp) = first_whole_that_fits(&ranked, pixels, bits_per_pixel, progress, pack)?;
    let within = ranked
        .iter()
        .filter(|j| j.choice.bits_per_pixel <= bits_per_pixel)
        .count();
    Ok(Verdict {
        bits_per_pixel: bpp,
        within,
        ..ranked[at].choice.verdict()
    })
}

/// The best of `ranked` (judged on a sample) whose whole file of `pixels` pixels, as
/// `pack` makes it (returning its bytes), fits in the budget — a file's bits per pixel
/// differ from its sample's, either way: its index in `ranked` and its bits per pixel.
/// `pack` is called for each candidate in turn until one fits.
fn first_whole_that_fits(
    ranked: &[Judged],
    pixels: usize,
    bits_per_pixel: f64,
    progress: &dyn Progress,
    mut pack: impl FnMut(&Settings) -> Result<u64>,
) -> Result<(usize, f64)> {
    progress.begin("packing the best candidates whole", ranked.len() as u64);
    for (at, judged) in ranked.iter().enumerate() {
        let bpp = 8.0 * pack(&judged.choice.settings)? as f64 / pixels as f64;
        progress.advance(1);
        if bpp <= bits_per_pixel {
            progress.end();
            return Ok((at, bpp));
        }
    }
    progress.end();
    Err(Error::invalid(format!(
        "no compression fits in {bits_per_pixel} bits/pixel (on the whole image, every \
         candidate within it on the sample is larger)"
    )))
}

/// [`choose`], judging the candidates side by side or one at a time.
#[cfg(test)]
pub(crate) fn choose_judging(
    image: &RelightableImage,
    capture: &Capture,
    bits_per_pixel: f64,
    progress: &dyn Progress,
    side_by_side: bool,
) -> Result<Choice> {
    let ranked = judge_grid(
        image,
        &Judges::of(capture)?,
        bits_per_pixel,
        1.0,
        progress,
        side_by_side,
    )?;
    Ok(best_of(ranked))
}

/// The first of candidates `ranked` best first, counting them.
fn best_of(mut ranked: Vec<Judged>) -> Choice {
    let within = ranked.len();
    let mut best = ranked.swap_remove(0).choice;
    best.within = within;
    best
}

/// Every candidate of [`grid`] for `image` judged: those within the budget (times
/// `allowance`), the best first (the higher score, the earlier in the grid on a tie); at
/// least one.
fn judge_grid(
    image: &RelightableImage,
    judges: &Judges,
    bits_per_pixel: f64,
    allowance: f64,
    progress: &dyn Progress,
    side_by_side: bool,
) -> Result<Vec<Judged>> {
    let capture = judges.capture;
    if !(bits_per_pixel.is_finite() && bits_per_pixel > 0.0) {
        return Err(Error::invalid(
            "the budget must be a positive number of bits per pixel",
        ));
    }
    let pixels = (image.width() * image.height()) as f64;
    let candidates = grid(image.maps.k);
    let directions = capture.directions();
    let gain = super::gain::perceptual(
        &image.maps,
        image.meta.basis.build()?.as_ref(),
        Some(&directions),
    );
    progress.begin("choosing compression", candidates.len() as u64);
    // Each candidate packed, measured and scored on its own, the best kept: candidates
    // side by side on small images (a small image's pack keeps few threads busy), one
    // at a time on large ones (each holds its decoded maps and frames).
    let judge = |(index, candidate): (usize, Settings)| -> Result<Option<Judged>> {
        let settings = Settings {
            directions: Some(directions.clone()),
            ..candidate
        };
        let packed = pack_with_gain(image, &settings, Some(&gain))?;
        let bytes = super::container::to_bytes(&packed)?.len();
        let bpp = 8.0 * bytes as f64 / pixels;
        progress.advance(1);
        if bpp > bits_per_pixel * allowance {
            return Ok(None);
        }
        let score = judges.score(&unpack(&packed)?)?;
        Ok(Some(Judged {
            index,
            choice: Choice {
                settings,
                packed,
                bits_per_pixel: bpp,
                score,
                within: 1,
                judged_pixels: pixels as usize,
            },
        }))
    };
    let judged: Vec<Option<Judged>> = if side_by_side {
        candidates
            .into_par_iter()
            .enumerate()
            .map(judge)
            .collect::<Result<_>>()?
    } else {
        candidates
            .into_iter()
            .enumerate()
            .map(judge)
            .collect::<Result<_>>()?
    };
    progress.end();
    let mut ranked: Vec<Judged> = judged.into_iter().flatten().collect();
    if ranked.is_empty() {
        return Err(Error::invalid(format!(
            "no compression fits in {bits_per_pixel} bits/pixel (the smallest candidate is larger)"
        )));
    }
    // A score that is not a number ranks last.
    let key = |j: &Judged| match j.choice.score {
        s if s.is_nan() => f64::NEG_INFINITY,
        s => s,
    };
    ranked.sort_by(|a, b| key(b).total_cmp(&key(a)).then(a.index.cmp(&b.index)));
    Ok(ranked)
}

/// How far over the budget a candidate may be on a sample and still be packed whole (in
/// the order of its score) to see whether its file fits: a sample's bits per pixel
/// are its windows', not the image's (item1 grown to 2048×512, ycc K′ 9 with blocks and
/// JPEG q90: 7.9 bits per pixel for the image, more than 8 on its sample).
const SAMPLE_ALLOWANCE: f64 = 1.25;

/// Images of more pixels than this are judged on a sample of [`SAMPLE_WINDOWS`] windows.
pub const SAMPLE_ABOVE_PIXELS: usize = 1 << 19;

/// Windows of a sample, and their side: whole blocks of principal components of
/// either side of [`PCA_BLOCKS`], lying on the image's blocks; together 262,144 pixels,
/// about as many as the captures of the shared RTI set (item1: 213,793), whose grids
/// take about a minute a basis.
pub const SAMPLE_WINDOWS: usize = 4;
const WINDOW: usize = 256;

/// Windows spread over a large image, judged as one image of them side by side.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Each window's top-left pixel, in the sample's order (row by row of windows).
    pub windows: Vec<(usize, usize)>,
    /// The windows' size and how many lie across the sample.
    pub side: (usize, usize),
    pub across: usize,
}

impl Sample {
    /// The sample of an image of `width × height` pixels, where it has more than
    /// [`SAMPLE_ABOVE_PIXELS`]: windows on a lattice of about the image's proportions,
    /// each at the centre of its cell, moved onto the lattice of [`WINDOW`] (so that
    /// its blocks of principal components are the whole image's).
    pub fn of(width: usize, height: usize) -> Option<Sample> {
        if width * height <= SAMPLE_ABOVE_PIXELS {
            return None;
        }
        let side = (WINDOW.min(width), WINDOW.min(height));
        let aspect = width as f64 / height as f64;
        // Whole rows of windows, as many as the image's proportions ask for.
        let across =
            ((SAMPLE_WINDOWS as f64 * aspect).sqrt().round() as usize).clamp(1, SAMPLE_WINDOWS);
        let down = (SAMPLE_WINDOWS / across).clamp(1, height / side.1);
        let across = SAMPLE_WINDOWS.div_ceil(down).min(width / side.0);
        let place = |cell: usize, cells: usize, extent: usize, side: usize| {
            let centre = (2 * cell + 1) * extent / (2 * cells);
            let snapped = centre.saturating_sub(side / 2) / WINDOW * WINDOW;
            snapped.min(extent - side)
        };
        let windows = (0..down)
            .flat_map(|j| (0..across).map(move |i| (i, j)))
            .map(|(i, j)| {
                (
                    place(i, across, width, side.0),
                    place(j, down, height, side.1),
                )
            })
            .collect();
        Some(Sample {
            windows,
            side,
            across,
        })
    }

    /// The sample's size.
    pub fn size(&self) -> (usize, usize) {
        let down = self.windows.len().div_ceil(self.across);
        (self.across * self.side.0, down * self.side.1)
    }

    /// Where pixel `(x, y)` of the sample comes from: a window and a pixel of it.
    fn window_pixel(&self, x: usize, y: usize) -> (usize, (usize, usize)) {
        let (w, h) = self.side;
        let window = ((y / h) * self.across + x / w).min(self.windows.len() - 1);
        (window, (x % w, y % h))
    }

    /// Where pixel `(x, y)` of the sample comes from in the image.
    fn source(&self, x: usize, y: usize) -> (usize, usize) {
        let (window, (lx, ly)) = self.window_pixel(x, y);
        let (x0, y0) = self.windows[window];
        (x0 + lx, y0 + ly)
    }

    /// The sample of `image`'s maps (no camera or depth: directional lights judge it).
    pub fn image(&self, image: &RelightableImage) -> RelightableImage {
        let width = image.width();
        let n = image.maps.pixels();
        self.assemble(image, |plane, (window, (lx, ly))| {
            let (x0, y0) = self.windows[window];
            image.maps.data[plane * n + (y0 + ly) * width + x0 + lx]
        })
    }

    /// The sample made of its windows' maps read on their own (`windows[i]`: window `i`,
    /// [`Sample::side`] in size, e.g. a region of a file): [`Sample::image`] of the
    /// image they were read from, without holding that image.
    pub fn image_of_windows(&self, windows: &[RelightableImage]) -> Result<RelightableImage> {
        let (w, h) = self.side;
        let first = windows
            .first()
            .ok_or_else(|| Error::invalid("a sample needs its windows"))?;
        if windows.len() != self.windows.len()
            || windows
                .iter()
                .any(|r| (r.width(), r.height(), r.maps.k) != (w, h, first.maps.k))
        {
            return Err(Error::invalid(format!(
                "a sample needs its {} windows of {w}×{h} pixels with one basis",
                self.windows.len()
            )));
        }
        Ok(self.assemble(first, |plane, (window, (lx, ly))| {
            windows[window].maps.data[plane * w * h + ly * w + lx]
        }))
    }

    /// Each pixel of the sample as its index in an image `width` pixels wide, in the
    /// sample's order (row by row).
    pub fn pixels_in(&self, width: usize) -> Vec<usize> {
        let (sw, sh) = self.size();
        (0..sw * sh)
            .map(|p| {
                let (x, y) = self.source(p % sw, p / sw);
                y * width + x
            })
            .collect()
    }

    /// The sample with `like`'s basis and metadata (no camera or depth), each value
    /// `value(plane, (window, pixel of the window))` of the pixel it comes from.
    fn assemble(
        &self,
        like: &RelightableImage,
        value: impl Fn(usize, (usize, (usize, usize))) -> f32,
    ) -> RelightableImage {
        let (sw, sh) = self.size();
        let mut maps = crate::maps::CoefficientMaps::zeros(sw, sh, like.maps.k);
        for (plane, out) in maps.data.chunks_exact_mut(sw * sh).enumerate() {
            for (p, o) in out.iter_mut().enumerate() {
                *o = value(plane, self.window_pixel(p % sw, p / sw));
            }
        }
        let mut meta = like.meta.clone();
        meta.camera = None;
        RelightableImage {
            meta,
            maps,
            depth: None,
        }
    }

    /// The sample of a photograph.
    fn photo(&self, photo: &crate::image::ImageRgb) -> crate::image::ImageRgb {
        let (sw, sh) = self.size();
        let mut out = crate::image::ImageRgb::new(sw, sh);
        for (p, o) in out.data.chunks_exact_mut(3).enumerate() {
            let (x, y) = self.source(p % sw, p / sw);
            let at = 3 * (y * photo.width + x);
            o.copy_from_slice(&photo.data[at..at + 3]);
        }
        out
    }
}

/// The captured lights candidates are scored at ([`SCORING_LIGHTS`] spread over the
/// capture's order) and their photographs.
struct Judges<'a> {
    capture: &'a Capture,
    lights: Vec<usize>,
    photos: Vec<crate::image::ImageRgb>,
}

impl<'a> Judges<'a> {
    /// The scoring lights of a capture of `n` lights.
    fn lights_of(n: usize) -> Vec<usize> {
        if n <= SCORING_LIGHTS {
            (0..n).collect()
        } else {
            (0..SCORING_LIGHTS)
                .map(|i| (i as f64 * (n - 1) as f64 / (SCORING_LIGHTS - 1) as f64).round() as usize)
                .collect()
        }
    }

    /// The scoring lights and their photographs' `sample`, each photograph read a few
    /// rows at a time ([`Capture::raw_pixels`]): what [`Judges::sampled`] gives,
    /// without holding a whole photograph.
    fn of_sample(capture: &'a Capture, sample: &Sample) -> Result<Judges<'a>> {
        let lights = Self::lights_of(capture.len());
        let (width, height) = sample.size();
        let pixels = sample.pixels_in(capture.width);
        let photos = lights
            .iter()
            .map(|&i| {
                Ok(crate::image::ImageRgb {
                    width,
                    height,
                    data: capture.raw_pixels(i, &pixels)?,
                })
            })
            .collect::<Result<_>>()?;
        Ok(Judges {
            capture,
            lights,
            photos,
        })
    }

    fn of(capture: &'a Capture) -> Result<Judges<'a>> {
        let lights = Self::lights_of(capture.len());
        let photos = lights
            .iter()
            .map(|&i| capture.load_raw(i))
            .collect::<Result<_>>()?;
        Ok(Judges {
            capture,
            lights,
            photos,
        })
    }

    /// The same lights, their photographs' sample.
    fn sampled(&self, sample: Sample) -> (Sample, Judges<'a>) {
        let photos = self.photos.iter().map(|p| sample.photo(p)).collect();
        let judges = Judges {
            capture: self.capture,
            lights: self.lights.clone(),
            photos,
        };
        (sample, judges)
    }

    /// The mean 8-bit sRGB PSNR of `image` relit at the lights against their photographs.
    fn score(&self, image: &RelightableImage) -> Result<f64> {
        let relighter = engine::Relighter::new(image)?;
        let mut score = 0.0;
        for (&i, photo) in self.lights.iter().zip(&self.photos) {
            let light = &self.capture.lights[i];
            let color = light.intensity.map(|v| v as f64);
            let rig = LightRig::new(vec![Light::directional(light.direction, color)]);
            let relit = relighter.relight(&rig, &RelightOptions::default())?;
            score += crate::metrics::psnr_srgb8(&relit.data, &photo.data);
        }
        Ok(score / self.lights.len() as f64)
    }
}

/// A fitted basis offered to [`choose_among`]: its maps, and its validation score (the
/// mean PSNR of the capture's own lights held out, the basis choice's figure).
pub struct Offer<'a> {
    pub image: &'a RelightableImage,
    pub validation: f64,
}

/// How [`choose_among`] judged one offer.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Estimate {
    pub basis: String,
    /// Its validation score, lossless.
    pub validation: f64,
    /// Its training lights' score, lossless and as its best file within the budget.
    pub lossless: f64,
    pub compressed: f64,
    /// The held-out score the file is expected to have: the validation's error plus
    /// the error its compression adds at the training lights, as mean squared errors
    /// (`None`: no file of it fits in the budget).
    pub estimate: Option<f64>,
}

/// The PSNR of a fit that scores `validation` on lights it has not seen, once stored in
/// a file that scores `compressed` at its training lights where its maps score
/// `lossless`: the compression's error adds to the fit's, as mean squared errors (peak 1)
/// — at its training lights a fit is far closer to the photographs than at others, so
/// the same added error costs it more decibels there.
fn expected_psnr(validation: f64, lossless: f64, compressed: f64) -> f64 {
    let mse = |psnr: f64| 10f64.powf(-psnr / 10.0);
    let added = (mse(compressed) - mse(lossless)).max(0.0);
    -10.0 * (mse(validation) + added).log10()
}

/// The best file within `bits_per_pixel` among several fits of the capture: each fit's
/// best candidate of [`grid`] ([`choose`]), and of those the one whose validation score,
/// with the error its compression adds at the training lights, is highest. The training
/// lights judge the compressions of one fit (its maps are the same whatever the file);
/// they cannot judge one basis against another, since a fit that follows its training
/// lights more closely need not predict other lights better: the validation does. Returns
/// the chosen offer's index, its file, and how every offer was judged.
pub fn choose_among(
    offers: &[Offer],
    capture: &Capture,
    bits_per_pixel: f64,
    progress: &dyn Progress,
) -> Result<(usize, Choice, Vec<Estimate>)> {
    let judges = Judges::of(capture)?;
    let mut tally = Tally::default();
    for (index, offer) in offers.iter().enumerate() {
        let image = offer.image;
        // The lossless maps scored on the pixels their files are.
        let sampled = Sample::of(image.width(), image.height()).map(|s| judges.sampled(s));
        let lossless = match &sampled {
            Some((sample, sample_judges)) => sample_judges.score(&sample.image(image))?,
            None => judges.score(image)?,
        };
        let basis = image.meta.basis.build()?.name();
        let chosen =
            choose_with(image, &judges, sampled.as_ref(), bits_per_pixel, progress).map(|choice| {
                let score = choice.score;
                (choice, score)
            });
        tally.record(index, basis, offer.validation, lossless, chosen);
    }
    tally.finish()
}

/// A fitted basis too large to hold, offered to [`choose_among_sampled`]: its maps'
/// sample ([`Sample::image_of_windows`]) and its validation score.
pub struct SampledOffer {
    pub sample: RelightableImage,
    pub validation: f64,
}

/// What a budget chose for a file it did not hold ([`choose_among_sampled`]): the
/// [`Choice`] but its packed file.
#[derive(Clone, Debug)]
pub struct Verdict {
    pub settings: Settings,
    pub bits_per_pixel: f64,
    pub score: f64,
    pub within: usize,
    pub judged_pixels: usize,
}

impl Choice {
    /// What was chosen, without the file.
    pub fn verdict(&self) -> Verdict {
        Verdict {
            settings: self.settings.clone(),
            bits_per_pixel: self.bits_per_pixel,
            score: self.score,
            within: self.within,
            judged_pixels: self.judged_pixels,
        }
    }
}

/// [`choose_among`] for fits too large to hold (of `capture`'s size, which has a
/// `sample`): each offer judged on its sample alone, then the whole file of its best
/// candidates made in turn by `pack_whole(offer, settings)`, which returns the file's
/// bytes (and keeps the file, so that the caller writes the one chosen), until one
/// fits. The same choice as [`choose_among`] of the fits held whole, where
/// `pack_whole` makes the bytes [`super::pack`] makes.
pub fn choose_among_sampled(
    offers: &[SampledOffer],
    capture: &Capture,
    sample: &Sample,
    bits_per_pixel: f64,
    pack_whole: &mut dyn FnMut(usize, &Settings) -> Result<u64>,
    progress: &dyn Progress,
) -> Result<(usize, Verdict, Vec<Estimate>)> {
    let judges = Judges::of_sample(capture, sample)?;
    let pixels = capture.width * capture.height;
    let mut tally = Tally::default();
    for (index, offer) in offers.iter().enumerate() {
        let lossless = judges.score(&offer.sample)?;
        let basis = offer.sample.meta.basis.build()?.name();
        let chosen = choose_on_sample(
            &offer.sample,
            &judges,
            pixels,
            bits_per_pixel,
            progress,
            |settings| pack_whole(index, settings),
        )
        .map(|verdict| {
            let score = verdict.score;
            (verdict, score)
        });
        tally.record(index, basis, offer.validation, lossless, chosen);
    }
    tally.finish()
}

/// The offers of [`choose_among`] as they are judged: each one's estimate, and the best.
struct Tally<T> {
    best: Option<(usize, T, f64)>,
    estimates: Vec<Estimate>,
    refusal: Option<Error>,
}

impl<T> Default for Tally<T> {
    fn default() -> Self {
        Tally {
            best: None,
            estimates: Vec::new(),
            refusal: None,
        }
    }
}

impl<T> Tally<T> {
    /// Offer `index` of `basis`, its validation and lossless scores, and its file and
    /// that file's score, or why none fits.
    fn record(
        &mut self,
        index: usize,
        basis: String,
        validation: f64,
        lossless: f64,
        chosen: Result<(T, f64)>,
    ) {
        match chosen {
            Ok((file, compressed)) => {
                let estimate = expected_psnr(validation, lossless, compressed);
                self.estimates.push(Estimate {
                    basis,
                    validation,
                    lossless,
                    compressed,
                    estimate: Some(estimate),
                });
                if self
                    .best
                    .as_ref()
                    .is_none_or(|(_, _, kept)| estimate > *kept)
                {
                    self.best = Some((index, file, estimate));
                }
            }
            Err(e) => {
                self.estimates.push(Estimate {
                    basis,
                    validation,
                    lossless,
                    compressed: f64::NAN,
                    estimate: None,
                });
                self.refusal = Some(e);
            }
        }
    }

    /// The best offer's index and file, and every estimate.
    fn finish(self) -> Result<(usize, T, Vec<Estimate>)> {
        match (self.best, self.refusal) {
            (Some((index, file, _)), _) => Ok((index, file, self.estimates)),
            (None, Some(e)) => Err(e),
            (None, None) => Err(Error::invalid("no fit was offered to the budget")),
        }
    }
}

/// Images of at most this many pixels have their candidates judged side by side.
const PARALLEL_PIXELS: f64 = (1 << 22) as f64;

/// A candidate within the budget and its place in the grid.
struct Judged {
    index: usize,
    choice: Choice,
}

#[cfg(test)]
mod tests {
    use super::expected_psnr;

    #[test]
    fn the_expected_score_adds_the_compressions_error_to_the_validations() {
        assert!((expected_psnr(30.0, 40.0, 40.0) - 30.0).abs() < 1e-12);
        // A file no worse than its maps adds nothing.
        assert!((expected_psnr(30.0, 40.0, 41.0) - 30.0).abs() < 1e-12);
        // Errors add as squares: 1e-3 + (1e-3.5 − 1e-4).
        let want = -10.0 * (1e-3 + 10f64.powf(-3.5) - 1e-4).log10();
        assert!((expected_psnr(30.0, 40.0, 35.0) - want).abs() < 1e-9);
        // The same loss at the training lights costs less where the fit is worse.
        let cost = |validation: f64| validation - expected_psnr(validation, 40.0, 35.0);
        assert!(cost(25.0) < cost(30.0) && cost(30.0) < 5.0);
    }
}
