//! The sRGB transfer curve, the one place where display encoding lives.
//!
//! relit works in linear radiance (see the [conventions](crate)); these functions are used
//! only when decoding 8/16-bit inputs, encoding 8-bit outputs, and weighting the
//! perceptual fit by the curve's slope.

use serde::{Deserialize, Serialize};
use std::sync::OnceLock;

/// How the samples of an image file relate to radiance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Encoding {
    /// Encoded with the sRGB transfer curve (8/16-bit photographs).
    #[default]
    Srgb,
    /// Proportional to radiance.
    Linear,
}

/// The linear value of an sRGB-encoded value in `[0, 1]`.
#[inline]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB encoding of a linear value, clamped to `[0, 1]`.
#[inline]
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The slope `d srgb / d linear` of the encoding at linear value `v` (clamped to `[0, 1]`).
///
/// The perceptual fit weights each squared residual by the square of this slope, so
/// that a linear-space error counts as much as the display-space error it causes.
#[inline]
pub fn srgb_slope(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92
    } else {
        1.055 / 2.4 * v.powf(1.0 / 2.4 - 1.0)
    }
}

/// The linear value where the sRGB curve's linear segment meets its power law.
pub const SRGB_KNEE: f64 = 0.003_130_8;

/// Intervals of the table behind [`linear_to_srgb_tabulated`], over `√v ∈ [0, 1]`.
const ENCODE_INTERVALS: usize = 4096;

/// The encoding at `√v = i / ENCODE_INTERVALS`, by the power law (continued below the
/// knee, where the table is not read).
fn encode_table() -> &'static [f32] {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=ENCODE_INTERVALS)
            .map(|i| {
                let u = i as f64 / ENCODE_INTERVALS as f64;
                (1.055 * (u * u).powf(1.0 / 2.4) - 0.055) as f32
            })
            .collect()
    })
}

/// [`linear_to_srgb`] by linear interpolation in a table over `√v`, where the curve is
/// gentle (`1.055·u^{5/6} − 0.055`): within 5e-8 of the exact encoding and several
/// times faster than `powf`. The fit's inner loops (perceptual weights, display
/// errors) call the curve for every sample and every candidate; 8-bit output keeps the
/// exact curve.
#[inline]
pub fn linear_to_srgb_tabulated(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v > 0.003_130_8 {
        let table = encode_table();
        let x = (v as f64).sqrt() * ENCODE_INTERVALS as f64;
        let i = (x as usize).min(ENCODE_INTERVALS - 1);
        let t = x - i as f64;
        let (a, b) = (table[i] as f64, table[i + 1] as f64);
        (a + t * (b - a)) as f32
    } else {
        v * 12.92 // the linear segment (and NaN, as the exact curve gives)
    }
}

/// [`srgb_slope`] from the tabulated encoding: above the knee the slope
/// `(1.055/2.4)·v^{−7/12}` equals `(srgb(v) + 0.055) / (2.4·v)`. Relative error
/// below 1e-6.
#[inline]
pub fn srgb_slope_tabulated(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    if v > SRGB_KNEE {
        (linear_to_srgb_tabulated(v as f32) as f64 + 0.055) / (2.4 * v)
    } else {
        12.92
    }
}

/// Linear values of the 256 8-bit sRGB codes.
pub fn srgb8_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// Linear values of the 65536 16-bit sRGB codes.
pub fn srgb16_table() -> &'static [f32] {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=65535u32)
            .map(|i| srgb_to_linear(i as f32 / 65535.0))
            .collect()
    })
}

/// Encode a linear value to an 8-bit sRGB code (rounded, clamped).
#[inline]
pub fn linear_to_srgb8(v: f32) -> u8 {
    // Non-finite values (a broken fit) show as black rather than panicking.
    let v = if v.is_finite() { v } else { 0.0 };
    (linear_to_srgb(v) * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_8bit_code_round_trips() {
        for (code, &lin) in srgb8_table().iter().enumerate() {
            assert_eq!(linear_to_srgb8(lin) as usize, code);
        }
    }

    #[test]
    fn tabulated_curve_and_slope_follow_the_exact_ones() {
        let (mut worst, mut worst_slope) = (0.0f64, 0.0f64);
        for i in 0..=200_000 {
            let v = (i as f64 / 200_000.0).powi(3); // dense near 0, where the curve bends
            let exact = 1.055 * v.powf(1.0 / 2.4) - 0.055;
            let exact = if v <= 0.003_130_8 { 12.92 * v } else { exact };
            worst = worst.max((linear_to_srgb_tabulated(v as f32) as f64 - exact).abs());
            let slope = srgb_slope(v);
            worst_slope = worst_slope.max((srgb_slope_tabulated(v) - slope).abs() / slope);
        }
        assert!(worst < 1e-7, "encoding off by {worst}");
        assert!(worst_slope < 1e-6, "slope off by {worst_slope} (relative)");
        assert_eq!(linear_to_srgb_tabulated(-1.0), 0.0);
        assert_eq!(linear_to_srgb_tabulated(2.0), 1.0);
        assert!(linear_to_srgb_tabulated(f32::NAN).is_nan());
        assert_eq!(srgb_slope_tabulated(0.0), 12.92);
    }

    #[test]
    fn curve_matches_the_standard() {
        // IEC 61966-2-1: 0.5 encoded is 0.21404 linear; 0.04045 is the knee.
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
        assert!((srgb_to_linear(0.04045) - 0.04045 / 12.92).abs() < 1e-7);
        assert!((linear_to_srgb(srgb_to_linear(0.73)) - 0.73).abs() < 1e-5);
        // The slope agrees with a finite difference.
        let (v, h) = (0.3f64, 1e-6);
        let fd = (linear_to_srgb((v + h) as f32) as f64 - linear_to_srgb((v - h) as f32) as f64)
            / (2.0 * h);
        assert!((srgb_slope(v) - fd).abs() / fd < 1e-2);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
    }
}
