//! Image metrics: the one definition of every fidelity figure relit reports.
//!
//! `relit eval`, `relit eval --scene`, `relit demo`, `relit bench`, the fit's own
//! residual and the studio's tests all score images through this module, so a figure
//! means the same thing wherever it is printed. Two PSNRs:
//!
//! * **linear**: `10·log10(peak² / MSE)` over the linear radiance samples, `peak` stated
//!   by the caller (1, the white of 8/16-bit inputs, everywhere relit reports one);
//! * **8-bit sRGB**: the same over the 8-bit sRGB codes the samples encode to
//!   ([`crate::color::linear_to_srgb8`]: clamped, rounded), peak 255 — what a person
//!   sees in a PNG, and the protocol of the RTI peer baseline.
//!
//! The MSE is the mean over every colour *sample* (pixels × 3) inside the region: a
//! mask (`> 0.5` inside, one value per pixel) or the whole frame. A perfect match, or a
//! region with no samples, scores [`PSNR_CAP_DB`]. A non-finite test value counts as
//! black, as it would display.

use serde::{Deserialize, Serialize};

/// The PSNR of a perfect match (and of an empty region), in dB.
pub const PSNR_CAP_DB: f64 = 100.0;

/// `10·log10(peak² / mse)`, capped at [`PSNR_CAP_DB`].
pub fn psnr(mse: f64, peak: f64) -> f64 {
    if mse <= 0.0 {
        PSNR_CAP_DB
    } else {
        (20.0 * peak.log10() - 10.0 * mse.log10()).min(PSNR_CAP_DB)
    }
}

/// The difference of two linear values once both are encoded as 8-bit sRGB codes.
#[inline]
pub fn srgb8_difference(test: f32, reference: f32) -> f64 {
    crate::color::linear_to_srgb8(test) as f64 - crate::color::linear_to_srgb8(reference) as f64
}

/// A test value as it enters the linear error: non-finite values show as black.
#[inline]
fn finite_or_black(v: f32) -> f32 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// Sums of squared errors over a region, from which both PSNRs follow.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SquaredErrors {
    /// Σ (test − reference)² of linear values.
    pub linear: f64,
    /// Σ (test − reference)² of 8-bit sRGB codes.
    pub srgb8: f64,
    /// Samples (pixels × 3) summed.
    pub samples: usize,
}

impl SquaredErrors {
    /// Squared errors of interleaved RGB `test` against `reference` over the pixels where
    /// `mask > 0.5` (every pixel when `mask` is `None`).
    ///
    /// # Panics
    /// If the buffers' lengths differ, or the mask's length is not theirs / 3: a caller
    /// comparing images of different sizes has a bug no figure should hide.
    pub fn of(test: &[f32], reference: &[f32], mask: Option<&[f32]>) -> SquaredErrors {
        assert_eq!(test.len(), reference.len(), "images of different sizes");
        if let Some(m) = mask {
            assert_eq!(m.len() * 3, test.len(), "a mask of another size");
        }
        let mut e = SquaredErrors::default();
        for (p, (t, r)) in test
            .chunks_exact(3)
            .zip(reference.chunks_exact(3))
            .enumerate()
        {
            if mask.is_some_and(|m| m[p] <= 0.5) {
                continue;
            }
            for c in 0..3 {
                let tv = finite_or_black(t[c]);
                e.linear += (tv as f64 - r[c] as f64).powi(2);
                let d8 = srgb8_difference(tv, r[c]);
                e.srgb8 += d8 * d8;
            }
            e.samples += 3;
        }
        e
    }

    /// Mean squared error of linear values (0 over an empty region).
    pub fn mse_linear(&self) -> f64 {
        self.linear / self.samples.max(1) as f64
    }

    /// Mean squared error of 8-bit codes (0 over an empty region).
    pub fn mse_srgb8(&self) -> f64 {
        self.srgb8 / self.samples.max(1) as f64
    }

    /// Both PSNRs, the linear one against `peak`.
    pub fn psnr(&self, peak: f64) -> Psnr {
        Psnr {
            psnr_linear: psnr(self.mse_linear(), peak),
            psnr_srgb8: psnr(self.mse_srgb8(), 255.0),
        }
    }
}

/// The two PSNRs of one comparison over one region.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Psnr {
    /// Linear radiance, peak 1.
    pub psnr_linear: f64,
    /// 8-bit sRGB codes, peak 255.
    pub psnr_srgb8: f64,
}

/// Both PSNRs (linear with peak 1) of interleaved RGB `test` against `reference` over
/// the pixels where `mask > 0.5`, or over the whole frame.
pub fn compare(test: &[f32], reference: &[f32], mask: Option<&[f32]>) -> Psnr {
    SquaredErrors::of(test, reference, mask).psnr(1.0)
}

/// 8-bit sRGB PSNR over the whole frame.
pub fn psnr_srgb8(test: &[f32], reference: &[f32]) -> f64 {
    compare(test, reference, None).psnr_srgb8
}

/// Linear PSNR (peak `peak`) over the pixels where `mask > 0.5`, or the whole frame.
pub fn psnr_linear(test: &[f32], reference: &[f32], mask: Option<&[f32]>, peak: f64) -> f64 {
    SquaredErrors::of(test, reference, mask)
        .psnr(peak)
        .psnr_linear
}

/// 8-bit sRGB PSNR of two images already encoded as 8-bit codes (a saved PNG pair),
/// over the pixels where `mask > 0.5` or the whole frame: the independent check of a
/// reported figure.
pub fn psnr_of_codes(test: &[u8], reference: &[u8], mask: Option<&[f32]>) -> f64 {
    assert_eq!(test.len(), reference.len(), "images of different sizes");
    let (mut sq, mut n) = (0.0f64, 0usize);
    for (p, (t, r)) in test
        .chunks_exact(3)
        .zip(reference.chunks_exact(3))
        .enumerate()
    {
        if mask.is_some_and(|m| m[p] <= 0.5) {
            continue;
        }
        for c in 0..3 {
            let d = t[c] as f64 - r[c] as f64;
            sq += d * d;
        }
        n += 3;
    }
    psnr(sq / n.max(1) as f64, 255.0)
}

/// The structural similarity (SSIM, Wang et al. 2004) of two `width × height`
/// interleaved RGB linear images, on the luma of their 8-bit sRGB codes (BT.601 weights,
/// `L = 255`, `K1 = 0.01`, `K2 = 0.03`) with an 11×11 Gaussian window of σ = 1.5
/// (edges clamped), averaged over the pixels where `mask > 0.5` or the whole frame; 1
/// for equal images and for an empty region.
pub fn ssim(
    test: &[f32],
    reference: &[f32],
    width: usize,
    height: usize,
    mask: Option<&[f32]>,
) -> f64 {
    assert_eq!(test.len(), reference.len(), "images of different sizes");
    assert_eq!(test.len(), 3 * width * height, "an image of another size");
    let luma = |rgb: &[f32]| -> Vec<f64> {
        rgb.chunks_exact(3)
            .map(|px| {
                let c = |v: f32| crate::color::linear_to_srgb8(finite_or_black(v)) as f64;
                0.299 * c(px[0]) + 0.587 * c(px[1]) + 0.114 * c(px[2])
            })
            .collect()
    };
    let (x, y) = (luma(test), luma(reference));
    let weights: Vec<f64> = {
        let w: Vec<f64> = (-5i32..=5)
            .map(|i| (-(i * i) as f64 / (2.0 * 1.5 * 1.5)).exp())
            .collect();
        let sum: f64 = w.iter().sum();
        w.into_iter().map(|v| v / sum).collect()
    };
    // Separable Gaussian blur, edges clamped: one pass along x (step 1 in rows of
    // `width`), one along y (step `width` in columns of `height`).
    let pass = |v: &[f64], along_x: bool| -> Vec<f64> {
        let (len, step) = if along_x { (width, 1) } else { (height, width) };
        (0..v.len())
            .map(|p| {
                let at = if along_x { p % width } else { p / width };
                let start = p - at * step;
                (0..11)
                    .map(|k| {
                        let i = (at as i64 + k as i64 - 5).clamp(0, len as i64 - 1) as usize;
                        weights[k] * v[start + i * step]
                    })
                    .sum()
            })
            .collect()
    };
    let blur = |v: &[f64]| pass(&pass(v, true), false);
    let product =
        |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(p, q)| p * q).collect() };
    let (mx, my) = (blur(&x), blur(&y));
    let (xx, yy, xy) = (
        blur(&product(&x, &x)),
        blur(&product(&y, &y)),
        blur(&product(&x, &y)),
    );
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    let (mut sum, mut n) = (0.0f64, 0usize);
    for p in 0..width * height {
        if mask.is_some_and(|m| m[p] <= 0.5) {
            continue;
        }
        let (vx, vy, cov) = (
            xx[p] - mx[p] * mx[p],
            yy[p] - my[p] * my[p],
            xy[p] - mx[p] * my[p],
        );
        sum += ((2.0 * mx[p] * my[p] + c1) * (2.0 * cov + c2))
            / ((mx[p] * mx[p] + my[p] * my[p] + c1) * (vx + vy + c2));
        n += 1;
    }
    if n == 0 {
        1.0
    } else {
        sum / n as f64
    }
}

/// Mean linear radiance (the mean of a pixel's three channels, averaged) over the pixels
/// where `mask > 0.5`, or the whole frame; 0 over an empty region. The ratio of a relit
/// image's mean to the truth's shows a fit that darkens or brightens.
pub fn mean_radiance(rgb: &[f32], mask: Option<&[f32]>) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (p, px) in rgb.chunks_exact(3).enumerate() {
        if mask.is_some_and(|m| m[p] <= 0.5) {
            continue;
        }
        sum += px.iter().map(|&v| v as f64).sum::<f64>() / 3.0;
        n += 1;
    }
    sum / n.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ssim_has_its_closed_form_on_flat_images_and_falls_with_noise() {
        let (w, h) = (23, 17);
        let grey = |code: u8| vec![crate::color::srgb8_table()[code as usize]; 3 * w * h];
        // Flat images: no variance, so SSIM = (2ab + C1) / (a² + b² + C1) exactly.
        let (a, b) = (grey(100), grey(140));
        let c1 = (0.01f64 * 255.0).powi(2);
        let want = (2.0 * 100.0 * 140.0 + c1) / (100.0f64.powi(2) + 140.0f64.powi(2) + c1);
        let got = ssim(&a, &b, w, h, None);
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        assert!((ssim(&a, &a, w, h, None) - 1.0).abs() < 1e-12);
        // Texture, then noise on it: below 1, lower with more noise.
        let texture: Vec<f32> = (0..3 * w * h)
            .map(|i| crate::color::srgb8_table()[((i / 3) * 37) % 200 + 20])
            .collect();
        let noisy = |amount: f32| -> Vec<f32> {
            texture
                .iter()
                .enumerate()
                .map(|(i, v)| v * (1.0 + amount * (((i * 7919) % 13) as f32 / 13.0 - 0.5)))
                .collect()
        };
        let (slight, strong) = (
            ssim(&noisy(0.05), &texture, w, h, None),
            ssim(&noisy(0.5), &texture, w, h, None),
        );
        assert!(1.0 > slight && slight > strong, "{slight} {strong}");
        // A mask scores only its pixels: the left half equal, the right half not.
        let mut half = texture.clone();
        for p in 0..w * h {
            if p % w >= w / 2 {
                half[3 * p..3 * p + 3].copy_from_slice(&[0.0; 3]);
            }
        }
        let left: Vec<f32> = (0..w * h)
            .map(|p| if p % w < w / 2 - 6 { 1.0 } else { 0.0 })
            .collect();
        assert!((ssim(&half, &texture, w, h, Some(&left)) - 1.0).abs() < 1e-9);
        assert!(ssim(&half, &texture, w, h, None) < 0.9);
    }

    #[test]
    fn a_constant_offset_gives_the_closed_form() {
        // δ everywhere: MSE δ², PSNR 20·log10(1/δ) exactly (powers of two, so that
        // f32 sums carry no rounding).
        for &delta in &[0.5f32, 0.125, 1.0 / 64.0, 1.0 / 1024.0] {
            let reference = vec![0.25f32; 3 * 40];
            let test: Vec<f32> = reference.iter().map(|v| v + delta).collect();
            let got = psnr_linear(&test, &reference, None, 1.0);
            let want = 20.0 * (1.0 / delta as f64).log10();
            assert!((got - want).abs() < 1e-9, "δ {delta}: {got} vs {want}");
            // The peak scales it: 20·log10(peak/δ).
            let got2 = psnr_linear(&test, &reference, None, 2.0);
            assert!((got2 - (want + 20.0 * 2f64.log10())).abs() < 1e-9);
        }
    }

    #[test]
    fn one_sample_off_in_an_n_pixel_image() {
        // One channel of one pixel off by d in an N-pixel image: MSE d²/(3N).
        let n = 1000;
        let reference = vec![0.0f32; 3 * n];
        let mut test = reference.clone();
        test[3 * 17 + 1] = 0.5;
        let want = 10.0 * ((3 * n) as f64 / 0.25).log10();
        assert!((psnr_linear(&test, &reference, None, 1.0) - want).abs() < 1e-9);
        // In 8-bit codes: 0.5 linear is code 188 (0.7354 encoded), 0 is code 0.
        let code = crate::color::linear_to_srgb8(0.5) as f64;
        assert_eq!(code, 188.0);
        let want8 = 10.0 * (255.0f64.powi(2) * (3 * n) as f64 / (code * code)).log10();
        assert!((psnr_srgb8(&test, &reference) - want8).abs() < 1e-9);
        // A whole pixel off in all three channels is three samples: 3× the MSE.
        let mut all = reference.clone();
        all[3 * 17..3 * 17 + 3].fill(0.5);
        let diff =
            psnr_linear(&test, &reference, None, 1.0) - psnr_linear(&all, &reference, None, 1.0);
        assert!((diff - 10.0 * 3f64.log10()).abs() < 1e-9);
    }

    #[test]
    fn a_mask_restricts_the_region() {
        let reference = vec![0.2f32; 3 * 10];
        let mut test = reference.clone();
        test[0] = 0.9; // pixel 0 only
        let mut mask = vec![1.0f32; 10];
        mask[0] = 0.0;
        let out = compare(&test, &reference, Some(&mask));
        assert_eq!(out.psnr_linear, PSNR_CAP_DB);
        assert_eq!(out.psnr_srgb8, PSNR_CAP_DB);
        // Inside the mask only: the same error over 3 of 30 samples or 3 of 3.
        let mut only = vec![0.0f32; 10];
        only[0] = 1.0;
        let inside = compare(&test, &reference, Some(&only)).psnr_linear;
        let whole = compare(&test, &reference, None).psnr_linear;
        assert!((inside - whole + 10.0).abs() < 1e-9, "{inside} {whole}");
        // An empty region is a perfect match, not a division by zero.
        assert_eq!(
            compare(&test, &reference, Some(&[0.0; 10])).psnr_linear,
            PSNR_CAP_DB
        );
    }

    #[test]
    fn mean_radiance_averages_the_region() {
        let rgb = [0.3f32, 0.3, 0.3, 0.0, 0.3, 0.6, 9.0, 9.0, 9.0];
        assert!((mean_radiance(&rgb, Some(&[1.0, 1.0, 0.0])) - 0.3).abs() < 1e-7);
        assert!((mean_radiance(&rgb, None) - 3.2).abs() < 1e-6);
        assert_eq!(mean_radiance(&rgb, Some(&[0.0; 3])), 0.0);
    }

    #[test]
    fn non_finite_values_count_as_black() {
        let reference = vec![0.0f32; 6];
        let test = vec![f32::NAN, f32::INFINITY, 0.0, 0.0, 0.0, 0.0];
        assert_eq!(compare(&test, &reference, None).psnr_linear, PSNR_CAP_DB);
    }

    #[test]
    fn codes_and_values_agree() {
        let t8 = crate::color::srgb8_table();
        let a: Vec<u8> = (0..300).map(|i| (i * 7 % 256) as u8).collect();
        let b: Vec<u8> = (0..300).map(|i| (i * 13 % 256) as u8).collect();
        let av: Vec<f32> = a.iter().map(|&c| t8[c as usize]).collect();
        let bv: Vec<f32> = b.iter().map(|&c| t8[c as usize]).collect();
        assert!((psnr_of_codes(&a, &b, None) - psnr_srgb8(&av, &bv)).abs() < 1e-12);
        // One 8-bit step in every sample: MSE 1 → 20·log10(255) = 48.13 dB.
        let c: Vec<u8> = a.iter().map(|&v| v.saturating_add(1).max(1)).collect();
        let d: Vec<u8> = c.iter().map(|&v| v - 1).collect();
        assert!((psnr_of_codes(&c, &d, None) - 20.0 * 255f64.log10()).abs() < 1e-9);
    }
}
