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
const SRGB_KNEE: f64 = 0.003_130_8;

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

/// `dst[i] = linear_to_srgb_tabulated(src[i] as f32) as f64`, bit for bit, four
/// values at a time where the CPU has AVX2 (square roots and table reads side by side:
/// the per-pixel fit encodes every observation and every prediction, and one at a time
/// that was a fifth of its time).
pub fn linear_to_srgb_tabulated_batch(src: &[f64], dst: &mut [f64]) {
    tabulated_batch(Curve::Encode, src, dst);
}

/// The two tabulated curves, for the batch code they share.
#[derive(Clone, Copy)]
enum Curve {
    Encode,
    Decode,
}

impl Curve {
    fn scalar(self, v: f32) -> f32 {
        match self {
            Curve::Encode => linear_to_srgb_tabulated(v),
            Curve::Decode => srgb_to_linear_tabulated(v),
        }
    }
}

/// `dst[i] = curve(src[i] as f32) as f64`: whole quads by the curve's AVX2 kernel where
/// the CPU has AVX2, the rest (or all) one at a time.
fn tabulated_batch(curve: Curve, src: &[f64], dst: &mut [f64]) {
    assert_eq!(src.len(), dst.len());
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx2") {
        done = src.len() / 4 * 4;
        let (src, dst) = (&src[..done], &mut dst[..done]);
        // SAFETY: AVX2 is present (checked above); the quads lie inside both slices.
        unsafe {
            match curve {
                Curve::Encode => encode_quads_avx2(encode_table(), src, dst),
                Curve::Decode => decode_quads_avx2(decode_table(), src, dst),
            }
        }
    }
    for (d, &v) in dst[done..].iter_mut().zip(&src[done..]) {
        *d = curve.scalar(v as f32) as f64;
    }
}

/// The table's curve at four points: entry `i` plus `t` of the way to entry `i + 1`
/// (`i` within the table's intervals), interpolated in f64 and rounded to f32 as the
/// scalar curves do.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn interpolated_quad(
    table: &[f32],
    i: std::arch::x86_64::__m128i,
    t: std::arch::x86_64::__m256d,
) -> std::arch::x86_64::__m128 {
    use std::arch::x86_64::*;
    // Each interval's two ends in one 8-byte load, four loads regrouped into the lower
    // and upper ends (two gathers of four measured slower: 9 % of a perceptual fit's
    // time on an AMD EPYC, where a gather is microcoded).
    let mut at = [0i32; 4];
    // SAFETY: the caller keeps every index below the table's last entry.
    unsafe { _mm_storeu_si128(at.as_mut_ptr().cast(), i) };
    let ends = |l: usize| unsafe {
        _mm_castsi128_ps(_mm_loadl_epi64(table.as_ptr().add(at[l] as usize).cast()))
    };
    let (low, high) = (
        _mm_unpacklo_ps(ends(0), ends(1)),
        _mm_unpacklo_ps(ends(2), ends(3)),
    );
    let (a, b) = (_mm_movelh_ps(low, high), _mm_movehl_ps(high, low));
    let (a, b) = (_mm256_cvtps_pd(a), _mm256_cvtps_pd(b));
    _mm256_cvtpd_ps(_mm256_add_pd(a, _mm256_mul_pd(t, _mm256_sub_pd(b, a))))
}

/// [`linear_to_srgb_tabulated_batch`] of whole quads, the same operations in the same
/// order as the scalar curve (no fused multiply-adds).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn encode_quads_avx2(table: &[f32], src: &[f64], dst: &mut [f64]) {
    use std::arch::x86_64::*;
    debug_assert!(table.len() == ENCODE_INTERVALS + 1 && src.len().is_multiple_of(4));
    let zero = _mm_setzero_ps();
    let one = _mm_set1_ps(1.0);
    let knee = _mm_set1_ps(0.003_130_8);
    let slope = _mm_set1_ps(12.92);
    let scale = _mm256_set1_pd(ENCODE_INTERVALS as f64);
    let last = _mm_set1_epi32(ENCODE_INTERVALS as i32 - 1);
    let izero = _mm_setzero_si128();
    for (s, d) in src.chunks_exact(4).zip(dst.chunks_exact_mut(4)) {
        // SAFETY: four f64 are read from `s` and written to `d`; the indices are
        // clamped to the table's intervals, whose upper ends (i + 1) are in the table.
        let v = _mm256_cvtpd_ps(unsafe { _mm256_loadu_pd(s.as_ptr()) });
        // f32::clamp keeps NaN: max and min return their second operand on NaN.
        let v = _mm_min_ps(one, _mm_max_ps(zero, v));
        let above = _mm_cmpgt_ps(v, knee);
        let x = _mm256_mul_pd(_mm256_sqrt_pd(_mm256_cvtps_pd(v)), scale);
        // Lanes on the linear segment (or NaN) read entry 0 and are not kept.
        let i = _mm_min_epi32(_mm_max_epi32(_mm256_cvttpd_epi32(x), izero), last);
        let t = _mm256_sub_pd(x, _mm256_cvtepi32_pd(i));
        let curve = unsafe { interpolated_quad(table, i, t) };
        let encoded = _mm_blendv_ps(_mm_mul_ps(v, slope), curve, above);
        unsafe { _mm256_storeu_pd(d.as_mut_ptr(), _mm256_cvtps_pd(encoded)) };
    }
}

/// The sRGB value where the decoding's linear segment meets its power law.
const SRGB_DECODE_KNEE: f32 = 0.04045;

/// Intervals of the table behind [`srgb_to_linear_tabulated`], over `[0, 1]`.
const DECODE_INTERVALS: usize = 4096;

/// The decoding at `i / DECODE_INTERVALS`, by the power law (continued below the knee,
/// where the table is not read).
fn decode_table() -> &'static [f32] {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=DECODE_INTERVALS)
            .map(|i| {
                let s = i as f64 / DECODE_INTERVALS as f64;
                ((s + 0.055) / 1.055).powf(2.4) as f32
            })
            .collect()
    })
}

/// [`srgb_to_linear`] by linear interpolation in a table over `[0, 1]`: within 8e-8
/// of the exact decoding (relative: 3e-6 just above the knee, 5e-7 from 0.2 up) and
/// several times faster than `powf`. For the basis choice, which decodes every
/// prediction of display-referred maps to judge their brightness; values above 1 take
/// the exact curve.
#[inline]
pub fn srgb_to_linear_tabulated(v: f32) -> f32 {
    if v > SRGB_DECODE_KNEE && v <= 1.0 {
        let table = decode_table();
        let x = v as f64 * DECODE_INTERVALS as f64;
        let i = (x as usize).min(DECODE_INTERVALS - 1);
        let t = x - i as f64;
        let (a, b) = (table[i] as f64, table[i + 1] as f64);
        (a + t * (b - a)) as f32
    } else if v > 1.0 {
        srgb_to_linear(v)
    } else {
        v / 12.92 // the linear segment (and NaN, as the exact curve gives)
    }
}

/// `dst[i] = srgb_to_linear_tabulated(src[i] as f32) as f64`, bit for bit, four values
/// at a time where the CPU has AVX2.
pub fn srgb_to_linear_tabulated_batch(src: &[f64], dst: &mut [f64]) {
    tabulated_batch(Curve::Decode, src, dst);
}

/// [`srgb_to_linear_tabulated_batch`] of whole quads, the same operations in the same
/// order as the scalar curve (no fused multiply-adds); lanes above 1 take the exact
/// curve afterwards.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn decode_quads_avx2(table: &[f32], src: &[f64], dst: &mut [f64]) {
    use std::arch::x86_64::*;
    debug_assert!(table.len() == DECODE_INTERVALS + 1 && src.len().is_multiple_of(4));
    let one = _mm_set1_ps(1.0);
    let knee = _mm_set1_ps(SRGB_DECODE_KNEE);
    let slope = _mm_set1_ps(12.92);
    let scale = _mm256_set1_pd(DECODE_INTERVALS as f64);
    let last = _mm_set1_epi32(DECODE_INTERVALS as i32 - 1);
    let izero = _mm_setzero_si128();
    for (s, d) in src.chunks_exact(4).zip(dst.chunks_exact_mut(4)) {
        // SAFETY: four f64 are read from `s` and written to `d`; the indices are
        // clamped to the table's intervals, whose upper ends (i + 1) are in the table.
        let v = _mm256_cvtpd_ps(unsafe { _mm256_loadu_pd(s.as_ptr()) });
        // Lanes on the linear segment, above 1 or NaN read an entry that is not kept.
        let x = _mm256_mul_pd(_mm256_cvtps_pd(_mm_min_ps(v, one)), scale);
        let i = _mm_min_epi32(_mm_max_epi32(_mm256_cvttpd_epi32(x), izero), last);
        let t = _mm256_sub_pd(x, _mm256_cvtepi32_pd(i));
        let curve = unsafe { interpolated_quad(table, i, t) };
        let decoded = _mm_blendv_ps(_mm_div_ps(v, slope), curve, _mm_cmpgt_ps(v, knee));
        unsafe { _mm256_storeu_pd(d.as_mut_ptr(), _mm256_cvtps_pd(decoded)) };
        if _mm_movemask_ps(_mm_cmpgt_ps(v, one)) != 0 {
            for (d, &s) in d.iter_mut().zip(s) {
                if s as f32 > 1.0 {
                    *d = srgb_to_linear(s as f32) as f64;
                }
            }
        }
    }
}

/// [`srgb_slope`] from the tabulated encoding: above the knee the slope
/// `(1.055/2.4)·v^{−7/12}` equals `(srgb(v) + 0.055) / (2.4·v)`. Relative error
/// below 1e-6.
#[inline]
pub fn srgb_slope_tabulated(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    srgb_slope_of_encoded(v, linear_to_srgb_tabulated(v as f32) as f64)
}

/// `values[i] = srgb_slope_tabulated(values[i])`, bit for bit, the encodings a batch at
/// a time ([`linear_to_srgb_tabulated_batch`]); `scratch` holds them (any length, resized).
pub fn srgb_slope_tabulated_batch(values: &mut [f64], scratch: &mut Vec<f64>) {
    values.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
    scratch.resize(values.len(), 0.0);
    linear_to_srgb_tabulated_batch(values, scratch);
    for (v, &encoded) in values.iter_mut().zip(scratch.iter()) {
        *v = srgb_slope_of_encoded(*v, encoded);
    }
}

/// [`srgb_slope_tabulated`] of `v` in `[0, 1]` (or NaN) given its tabulated encoding
/// `encoded`, for callers that have encoded `v` already (the fit encodes its samples a
/// batch at a time).
#[inline]
pub fn srgb_slope_of_encoded(v: f64, encoded: f64) -> f64 {
    if v > SRGB_KNEE {
        (encoded + 0.055) / (2.4 * v)
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

    /// Both tabulated curves' batches against their scalar curves, over a dense sweep
    /// (`spread` maps [0, 1] onto the values tried) and the edges: both knees, zeros,
    /// values outside [0, 1], NaN and infinities.
    #[test]
    fn the_batch_curves_are_the_scalar_ones_bit_for_bit() {
        type Batch = fn(&[f64], &mut [f64]);
        type Scalar = fn(f32) -> f32;
        type Spread = fn(f64) -> f64;
        let curves: [(Batch, Scalar, Spread); 2] = [
            (
                linear_to_srgb_tabulated_batch,
                linear_to_srgb_tabulated,
                |x| x.powi(3),
            ),
            (
                srgb_to_linear_tabulated_batch,
                srgb_to_linear_tabulated,
                |x| x,
            ),
        ];
        for (batch, scalar, spread) in curves {
            let mut values: Vec<f64> = (0..=40_000)
                .map(|i| spread(i as f64 / 40_000.0) * 1.2 - 0.01)
                .collect();
            values.extend([
                0.0,
                -0.0,
                1.0,
                0.003_130_8,
                0.003_130_9,
                0.04045,
                0.040_450_1,
                1e-30,
                -5.0,
                7.0,
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                0.999_999_9,
                1.000_000_1,
            ]);
            let mut got = vec![0.0; values.len()];
            batch(&values, &mut got);
            for (&v, &b) in values.iter().zip(&got) {
                let want = scalar(v as f32) as f64;
                assert!(
                    want.to_bits() == b.to_bits() || (want.is_nan() && b.is_nan()),
                    "{v}: batch {b}, scalar {want}"
                );
            }
        }
    }

    #[test]
    fn the_batch_slope_is_the_scalar_one_bit_for_bit() {
        let mut values: Vec<f64> = (0..=20_000)
            .map(|i| (i as f64 / 20_000.0).powi(3) * 1.2 - 0.01)
            .chain([
                0.0,
                -0.0,
                1.0,
                0.003_130_8,
                0.003_130_9,
                -5.0,
                7.0,
                f64::NAN,
            ])
            .collect();
        let want: Vec<f64> = values.iter().map(|&v| srgb_slope_tabulated(v)).collect();
        srgb_slope_tabulated_batch(&mut values, &mut Vec::new());
        for (&w, &b) in want.iter().zip(&values) {
            assert!(
                w.to_bits() == b.to_bits() || (w.is_nan() && b.is_nan()),
                "batch {b}, scalar {w}"
            );
        }
    }

    #[test]
    fn the_tabulated_decoding_follows_the_exact_one() {
        let exact = |s: f64| {
            if s <= 0.04045 {
                s / 12.92
            } else {
                ((s + 0.055) / 1.055).powf(2.4)
            }
        };
        let (mut worst, mut worst_relative, mut worst_above) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..=400_000 {
            let s = i as f64 / 400_000.0;
            let want = exact(s as f32 as f64);
            let got = srgb_to_linear_tabulated(s as f32) as f64;
            let relative = (got - want).abs() / want.max(1e-30);
            worst = worst.max((got - want).abs());
            worst_relative = worst_relative.max(relative);
            if s >= 0.2 {
                worst_above = worst_above.max(relative);
            }
        }
        assert!(worst < 1e-7, "decoding off by {worst}");
        assert!(worst_relative < 3e-6, "off by {worst_relative} (relative)");
        assert!(
            worst_above < 5e-7,
            "off by {worst_above} (relative) from 0.2 up"
        );
        // The linear segment exactly, and what lies outside the table by the exact curve.
        for s in [0.0f32, 0.01, 0.04045, 1.5, 7.0, -0.5] {
            assert_eq!(srgb_to_linear_tabulated(s), srgb_to_linear(s), "{s}");
        }
        assert_eq!(srgb_to_linear_tabulated(1.0), 1.0);
        assert!(srgb_to_linear_tabulated(f32::NAN).is_nan());
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
