//! Quantised planes, tile by tile: integer codes with a [`PlaneCoding`] (`value =
//! offset + scale · q`, the one meaning every back end gives stored numbers), and the
//! entropy codes a tile of codes is stored in.
//!
//! * `zstd`: each code predicted from its left, upper and upper-left neighbours (the
//!   median edge detector of LOCO-I), the residual wrapped to the code width and
//!   zig-zagged so that small residuals are small bytes, then zstd. Lossless for the
//!   codes.
//! * `jpeg`: 8-bit codes as a greyscale baseline JPEG of the given quality. Lossy; any
//!   JPEG decoder (a browser's) reads it.
//! * `webp`: 8-bit codes as a lossy WebP of the given quality (grey as equal R, G, B,
//!   which WebP stores as luma alone). Lossy; every current browser reads it. On item1's
//!   27 principal-component planes it needs about a third fewer bytes than JPEG with
//!   fitted Huffman tables at equal error (40–45 dB of the planes' range); it cannot
//!   return codes exactly (limited-range luma), which tops it out near 50 dB.

use crate::storage::PlaneCoding;
use crate::{Error, Result};
use std::io::Read;

/// How a tile of codes is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "name", rename_all = "lowercase")]
pub enum TileCodec {
    /// Prediction residuals, zstd at `level` (1–22).
    Zstd { level: i32 },
    /// Baseline greyscale JPEG at `quality` (1–100); 8-bit codes only.
    Jpeg { quality: u8 },
    /// Lossy WebP at `quality` (1–100); 8-bit codes only.
    Webp { quality: u8 },
}

impl TileCodec {
    /// `zstd`, `zstd:19`, `jpeg`, `jpeg:85`.
    pub fn parse(s: &str) -> Result<TileCodec> {
        let s = s.trim().to_ascii_lowercase();
        let (name, arg) = match s.split_once(':') {
            Some((n, a)) => (n, Some(a)),
            None => (s.as_str(), None),
        };
        let number = |default: i64, lo: i64, hi: i64| -> Result<i64> {
            match arg {
                None => Ok(default),
                Some(a) => a
                    .parse::<i64>()
                    .ok()
                    .filter(|v| (lo..=hi).contains(v))
                    .ok_or_else(|| {
                        Error::parse(format!("bad codec setting `{s}`: {name} takes {lo}–{hi}"))
                    }),
            }
        };
        match name {
            "zstd" => Ok(TileCodec::Zstd {
                level: number(12, 1, 22)? as i32,
            }),
            "jpeg" | "jpg" => Ok(TileCodec::Jpeg {
                quality: number(90, 1, 100)? as u8,
            }),
            "webp" => Ok(TileCodec::Webp {
                quality: number(90, 1, 100)? as u8,
            }),
            _ => Err(Error::parse(format!(
                "unknown plane codec `{s}` (zstd[:level], jpeg[:quality] or webp[:quality])"
            ))),
        }
    }

    /// The name `parse` reads back.
    pub fn name(self) -> String {
        match self {
            TileCodec::Zstd { level } => format!("zstd:{level}"),
            TileCodec::Jpeg { quality } => format!("jpeg:{quality}"),
            TileCodec::Webp { quality } => format!("webp:{quality}"),
        }
    }

    /// Whether the codes come back exactly.
    pub fn lossless(self) -> bool {
        matches!(self, TileCodec::Zstd { .. })
    }

    /// The most distinct codes a plane may use.
    pub fn max_levels(self) -> u32 {
        match self {
            TileCodec::Zstd { .. } => 1 << 16,
            TileCodec::Jpeg { .. } | TileCodec::Webp { .. } => 256,
        }
    }

    /// Whether tiles are lossy 8-bit images (JPEG, WebP), whose decoders may return any
    /// of the 256 codes.
    pub fn is_image(self) -> bool {
        !self.lossless()
    }
}

/// A plane's coding and how many codes it uses (`0..levels`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Quantizer {
    #[serde(flatten)]
    pub coding: PlaneCoding,
    pub levels: u32,
}

impl Quantizer {
    /// Codes of step `step` from `lo` to at least `hi`, or the fewest steps of at most
    /// `max_levels` codes that span them (the step grows).
    pub fn spanning(lo: f32, hi: f32, step: f32, max_levels: u32) -> Quantizer {
        if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
            let offset = if lo.is_finite() { lo } else { 0.0 };
            return Quantizer {
                coding: PlaneCoding { scale: 0.0, offset },
                levels: 1,
            };
        }
        let mut scale = step.max(f32::MIN_POSITIVE);
        let mut levels = ((hi - lo) / scale).ceil() as f64 + 1.0;
        if levels > max_levels as f64 {
            scale = (hi - lo) / (max_levels - 1) as f32;
            levels = max_levels as f64;
        }
        Quantizer {
            coding: PlaneCoding { scale, offset: lo },
            levels: levels as u32,
        }
    }

    /// The code of `v` (clamped to the codes; NaN gives 0).
    #[inline]
    pub fn code(&self, v: f32) -> u16 {
        if self.coding.scale <= 0.0 {
            return 0;
        }
        let q = ((v - self.coding.offset) / self.coding.scale).round();
        q.clamp(0.0, (self.levels - 1) as f32) as u16
    }

    /// Bytes per code in a tile: 1 up to 256 levels, else 2.
    pub fn width(&self) -> usize {
        if self.levels <= 256 {
            1
        } else {
            2
        }
    }
}

/// The median edge detector's prediction from left `a`, upper `b`, upper-left `c`.
#[inline]
fn med(a: i32, b: i32, c: i32) -> i32 {
    if c >= a.max(b) {
        a.min(b)
    } else if c <= a.min(b) {
        a.max(b)
    } else {
        a + b - c
    }
}

/// Walk a `w × h` tile of codes in raster order with each code's prediction.
fn predictions(codes: &[u16], w: usize, i: usize) -> i32 {
    let (x, y) = (i % w, i / w);
    let at = |j: usize| codes[j] as i32;
    match (x, y) {
        (0, 0) => 0,
        (_, 0) => at(i - 1),
        (0, _) => at(i - w),
        _ => med(at(i - 1), at(i - w), at(i - w - 1)),
    }
}

/// Encode a `w × h` tile of codes (`width` bytes each) with `codec`.
pub fn encode_tile(
    codes: &[u16],
    w: usize,
    h: usize,
    width: usize,
    codec: TileCodec,
) -> Result<Vec<u8>> {
    debug_assert_eq!(codes.len(), w * h);
    match codec {
        TileCodec::Zstd { level } => {
            let mut bytes = Vec::with_capacity(codes.len() * width);
            for i in 0..codes.len() {
                let r = codes[i] as i32 - predictions(codes, w, i);
                if width == 1 {
                    let r = r as u8 as i8;
                    bytes.push(((r << 1) ^ (r >> 7)) as u8);
                } else {
                    let r = r as u16 as i16;
                    bytes.extend_from_slice(&(((r << 1) ^ (r >> 15)) as u16).to_le_bytes());
                }
            }
            zstd::bulk::compress(&bytes, level)
                .map_err(|e| Error::new(crate::ErrorKind::Io, format!("zstd: {e}")))
        }
        TileCodec::Jpeg { quality } => {
            if width != 1 {
                return Err(Error::invalid("JPEG planes hold 8-bit codes"));
            }
            let gray: Vec<u8> = codes.iter().map(|&q| q as u8).collect();
            // JPEG planes stay with a baseline encoder (standard tables, Huffman tables
            // fitted to each tile). MozJPEG (its tables, trellis quantisation, progressive
            // scans), which the web export uses, was tried here on 2026-12-05: 0.3–0.7 dB
            // more held-out PSNR at equal bits from quality 60 to 90 (3–10 bits/px; items
            // 1, 2 and 6, ycc K′ = 12 or 16), but trellis quantisation gives up PSNR near
            // lossless (item1 at quality 95: 35.15 dB at 10.6 bits/px against the
            // baseline's 35.44 at 17.9; MozJPEG needs quality 98 and 22.0 bits/px for
            // 35.40), and `--budget 24`, whose files sit there, gained nothing with it
            // (same decoder: item1 35.33 dB with MozJPEG everywhere, 35.25 below quality 95
            // only, 35.29 baseline; item2 36.49, 36.49, 36.56). Worth keeping for budgets
            // under about 12 bits/px, once measured on every item.
            let mut out = Vec::new();
            // Huffman tables fitted to the tile: a plane of small residual components
            // is mostly zeros, which the standard tables code poorly (item1's 27 planes
            // at equal quality: 1.7 bits/px less).
            let mut encoder = jpeg_encoder::Encoder::new(&mut out, quality);
            encoder.set_optimized_huffman_tables(true);
            encoder
                .encode(&gray, w as u16, h as u16, jpeg_encoder::ColorType::Luma)
                .map_err(|e| Error::new(crate::ErrorKind::Io, format!("JPEG: {e}")))?;
            Ok(out)
        }
        TileCodec::Webp { quality } => {
            if width != 1 {
                return Err(Error::invalid("WebP planes hold 8-bit codes"));
            }
            let rgb: Vec<u8> = codes.iter().flat_map(|&q| [q as u8; 3]).collect();
            let encoded = webp::Encoder::from_rgb(&rgb, w as u32, h as u32)
                .encode_simple(false, quality as f32)
                .map_err(|e| Error::new(crate::ErrorKind::Io, format!("WebP: {e:?}")))?;
            Ok(encoded.to_vec())
        }
    }
}

/// Decode a tile written by [`encode_tile`] into `out` (`w × h` codes), refusing
/// anything that does not decode to exactly that many codes below `levels`.
pub fn decode_tile(
    bytes: &[u8],
    w: usize,
    h: usize,
    width: usize,
    levels: u32,
    codec: TileCodec,
    out: &mut [u16],
) -> Result<()> {
    let n = w * h;
    debug_assert_eq!(out.len(), n);
    let bad = |why: String| Error::parse(format!("a plane tile {why}"));
    match codec {
        TileCodec::Zstd { .. } => {
            let want = n * width;
            let mut raw = Vec::new();
            let decoder = zstd::stream::read::Decoder::new(bytes)
                .map_err(|e| bad(format!("is not zstd: {e}")))?;
            // Never more than one byte past what the tile can hold.
            decoder
                .take(want as u64 + 1)
                .read_to_end(&mut raw)
                .map_err(|e| bad(format!("does not decompress: {e}")))?;
            if raw.len() != want {
                return Err(bad(format!("holds {} bytes, not {want}", raw.len())));
            }
            for i in 0..n {
                let z = if width == 1 {
                    raw[i] as u32
                } else {
                    u16::from_le_bytes([raw[2 * i], raw[2 * i + 1]]) as u32
                };
                let r = ((z >> 1) as i32) ^ -((z & 1) as i32);
                let pred = predictions(out, w, i);
                let q = if width == 1 {
                    (pred + r) as u8 as u16
                } else {
                    (pred + r) as u16
                };
                out[i] = q;
            }
        }
        TileCodec::Jpeg { .. } | TileCodec::Webp { .. } => {
            let (format, what) = match codec {
                TileCodec::Webp { .. } => (image::ImageFormat::WebP, "a WebP"),
                _ => (image::ImageFormat::Jpeg, "a JPEG"),
            };
            // Grey WebP decodes as equal R, G, B: its luma is the code.
            let img = image::load_from_memory_with_format(bytes, format)
                .map_err(|e| bad(format!("is not {what}: {e}")))?
                .into_luma8();
            if (img.width() as usize, img.height() as usize) != (w, h) {
                return Err(bad(format!(
                    "is {}×{}, not {w}×{h}",
                    img.width(),
                    img.height()
                )));
            }
            out.iter_mut()
                .zip(img.as_raw())
                .for_each(|(o, &q)| *o = q as u16);
        }
    }
    if let Some(q) = out.iter().find(|&&q| q as u32 >= levels) {
        return Err(bad(format!("has code {q}, beyond its {levels} levels")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize, levels: u32) -> Vec<u16> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                (((x * 7 + y * 3) as f64).sin().abs() * (levels - 1) as f64) as u16
            })
            .collect()
    }

    #[test]
    fn zstd_tiles_come_back_exactly_at_both_widths() {
        for levels in [2u32, 256, 1000, 65536] {
            let q = Quantizer {
                coding: PlaneCoding::IDENTITY,
                levels,
            };
            let codes = ramp(37, 19, levels);
            let bytes =
                encode_tile(&codes, 37, 19, q.width(), TileCodec::Zstd { level: 3 }).unwrap();
            let mut back = vec![0u16; codes.len()];
            decode_tile(
                &bytes,
                37,
                19,
                q.width(),
                levels,
                TileCodec::Zstd { level: 3 },
                &mut back,
            )
            .unwrap();
            assert_eq!(back, codes, "{levels} levels");
            // The wrong size or too few levels are refused.
            let mut small = vec![0u16; 36 * 19];
            assert!(decode_tile(
                &bytes,
                36,
                19,
                q.width(),
                levels,
                TileCodec::Zstd { level: 3 },
                &mut small
            )
            .is_err());
        }
    }

    #[test]
    fn image_tiles_come_back_close() {
        let codes = ramp(64, 40, 256);
        for codec in [
            TileCodec::Jpeg { quality: 95 },
            TileCodec::Webp { quality: 95 },
        ] {
            let bytes = encode_tile(&codes, 64, 40, 1, codec).unwrap();
            let mut back = vec![0u16; codes.len()];
            decode_tile(&bytes, 64, 40, 1, 256, codec, &mut back).unwrap();
            let rms = (codes
                .iter()
                .zip(&back)
                .map(|(&a, &b)| (a as f64 - b as f64).powi(2))
                .sum::<f64>()
                / codes.len() as f64)
                .sqrt();
            assert!(rms < 6.0, "{codec:?}: rms {rms}");
            assert!(encode_tile(&codes, 64, 40, 2, codec).is_err());
            // A tile of the other image codec, or of the wrong size, is refused.
            assert!(decode_tile(&bytes, 64, 41, 1, 256, codec, &mut vec![0; 64 * 41]).is_err());
        }
    }

    #[test]
    fn quantizers_span_their_range_in_steps() {
        let q = Quantizer::spanning(-1.0, 1.0, 0.01, 1 << 16);
        assert_eq!(q.levels, 201);
        assert_eq!(q.code(-1.0), 0);
        assert_eq!(q.code(1.0), 200);
        assert_eq!(q.code(f32::NAN), 0);
        assert!((q.coding.decode(q.code(0.333) as f32) - 0.333).abs() <= 0.005 + 1e-6);
        // Too many steps: the step grows to fit the codes.
        let q = Quantizer::spanning(0.0, 1.0, 1e-9, 256);
        assert_eq!(q.levels, 256);
        assert_eq!(q.code(1.0), 255);
        let constant = Quantizer::spanning(3.0, 3.0, 0.1, 256);
        assert_eq!((constant.levels, constant.coding.decode(0.0)), (1, 3.0));
    }

    #[test]
    fn codec_names_parse() {
        assert_eq!(
            TileCodec::parse("zstd").unwrap(),
            TileCodec::Zstd { level: 12 }
        );
        assert_eq!(
            TileCodec::parse("jpeg:80").unwrap(),
            TileCodec::Jpeg { quality: 80 }
        );
        assert!(TileCodec::parse("jpeg:0").is_err());
        assert!(TileCodec::parse("png").is_err());
        for c in [
            TileCodec::Zstd { level: 5 },
            TileCodec::Jpeg { quality: 70 },
        ] {
            assert_eq!(TileCodec::parse(&c.name()).unwrap(), c);
        }
    }
}
