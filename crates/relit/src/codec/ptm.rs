//! HP's Polynomial Texture Map files, version 1.2 (`.ptm`), formats
//! `PTM_FORMAT_RGB` and `PTM_FORMAT_LRGB` and their JPEG variants
//! `PTM_FORMAT_JPEG_RGB` and `PTM_FORMAT_JPEG_LRGB`.
//!
//! # Layout (HP's "PTM File Format" 1.2)
//!
//! ```text
//! PTM_1.2
//! PTM_FORMAT_LRGB             (or PTM_FORMAT_RGB)
//! <width>                     (width and height may share a line)
//! <height>
//! <6 scales>                  floats
//! <6 biases>                  integers
//! <binary data>
//! ```
//!
//! Header fields are separated by any whitespace, and lines may carry trailing spaces.
//! The binary data stores **rows from the bottom of the image up**, pixels left to
//! right, one byte per coefficient:
//!
//! * `PTM_FORMAT_LRGB`: `width × height × 6` luminance coefficients (per pixel
//!   `a0..a5`), then `width × height × 3` bytes of RGB;
//! * `PTM_FORMAT_RGB`: three such coefficient blocks, red, green, blue.
//!
//! A byte `b` of coefficient `i` decodes to `a_i = (b − bias_i) · scale_i`, and the
//! pixel under a light whose unit vector has `(lu, lv)` as its x and y (the `.lp` frame:
//! x right, y up) is, in 8-bit display codes,
//!
//! ```text
//! L = a0·lu² + a1·lv² + a2·lu·lv + a3·lu + a4·lv + a5
//! RGB:  channel = L_channel                  LRGB: channel = rgb_channel · L / 255
//! ```
//!
//! which viewers clamp to `[0, 255]`. relit reads that as its `ptm:6` basis (same
//! order) in the display-referred colour space ([`MapSpace::Srgb`]), coefficients
//! divided by 255 (by 255² for LRGB's products), so a read file relights exactly as a
//! PTM viewer shows it except that the clamp applies to each light's result rather than
//! to `L` before the colour multiplies it.
//!
//! Writing re-expresses any relightable image in the biquadratic over the dome
//! ([`super::reexpress`]); a `ptm:6` display-space image is written as it is. Each
//! coefficient is quantised to 8 bits over its range in the whole image, as PTMfitter
//! does. LRGB stores, per pixel, the colour of its mean response (brightest channel at
//! 255) and the luminance polynomial that scales it.
//!
//! # The JPEG variants
//!
//! After the biases the header holds, for the `n` coefficient planes (18 for RGB: red's
//! `a0..a5`, then green's, blue's; 9 for LRGB: the luminance's `a0..a5`, then R, G, B):
//! the JPEG quality, then `n` integers each of `transforms`, motion vectors x and y,
//! decoding `order`, `reference planes` (−1 for none), compressed sizes and side
//! information sizes. The data is, for each plane in turn, its grayscale JPEG stream
//! (rows bottom-up, as the raw layout) and then its side information. Planes are
//! completed in `order`: a plane with a reference adds that (already completed) plane's
//! bytes minus 128, modulo 256 — inverted (`255 − byte`) where its transform's bit 0 is
//! set — and its side information is a list of 5-byte corrections (a big-endian 32-bit
//! pixel index, then the byte to put there). The bytes so completed are the raw layout's
//! codes. Motion-compensated prediction (transform bit 1) is refused by name: no writer
//! we know of uses it. Written JPEG files store every plane on its own, without
//! prediction or corrections, at the quality asked (default 90).
//!
//! Not read: `PTM_FORMAT_LUM`, the JPEG-LS variants and the PTM 1.1 layout; they are
//! refused with their name.

use super::legacy::{check_payload, field, text_header, Range};
use super::reexpress::reexpress;
use crate::basis::{Basis, BasisSpec};
use crate::camera::Projection;
use crate::fsutil::write_bytes_atomically;
use crate::maps::{CoefficientMaps, MapSpace, Metadata, RelightableImage};
use crate::{Error, Result};
use std::path::Path;

/// The first bytes of every PTM 1.2 file.
pub const MAGIC: &[u8] = b"PTM_1.2";

/// Coefficients of the biquadratic.
const K: usize = 6;

/// How the colour of a PTM is stored, and whether its planes are JPEG streams.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PtmFormat {
    /// One polynomial per colour channel.
    Rgb,
    /// One luminance polynomial times a per-pixel RGB colour (what PTMfitter writes).
    Lrgb,
    /// `Rgb` with each of its 18 planes a grayscale JPEG of this quality (1–100).
    JpegRgb(u8),
    /// `Lrgb` with each of its 9 planes a grayscale JPEG of this quality (1–100).
    JpegLrgb(u8),
}

/// The JPEG quality of written JPEG variants unless one is named.
pub const DEFAULT_JPEG_QUALITY: u8 = 90;

impl PtmFormat {
    /// Parse `rgb`, `lrgb`, `jpeg-rgb[:Q]` or `jpeg-lrgb[:Q]` (`Q` the JPEG quality,
    /// 1–100).
    pub fn parse(name: &str) -> Result<PtmFormat> {
        let lower = name.to_ascii_lowercase();
        let (kind, quality) = match lower.split_once(':') {
            Some((kind, q)) => match q.parse::<u8>() {
                Ok(q @ 1..=100) => (kind, Some(q)),
                _ => {
                    return Err(Error::invalid(format!(
                        "PTM JPEG quality `{q}`: use 1 to 100"
                    )))
                }
            },
            None => (lower.as_str(), None),
        };
        let q = quality.unwrap_or(DEFAULT_JPEG_QUALITY);
        match (kind, quality) {
            ("rgb", None) => Ok(PtmFormat::Rgb),
            ("lrgb", None) => Ok(PtmFormat::Lrgb),
            ("jpeg-rgb", _) => Ok(PtmFormat::JpegRgb(q)),
            ("jpeg-lrgb", _) => Ok(PtmFormat::JpegLrgb(q)),
            _ => Err(Error::invalid(format!(
                "unknown PTM format `{name}`: use rgb, lrgb, jpeg-rgb[:Q] or jpeg-lrgb[:Q]"
            ))),
        }
    }

    fn header_name(self) -> &'static str {
        match self {
            PtmFormat::Rgb => "PTM_FORMAT_RGB",
            PtmFormat::Lrgb => "PTM_FORMAT_LRGB",
            PtmFormat::JpegRgb(_) => "PTM_FORMAT_JPEG_RGB",
            PtmFormat::JpegLrgb(_) => "PTM_FORMAT_JPEG_LRGB",
        }
    }

    /// Whether the colour is one polynomial times a per-pixel colour.
    pub fn lrgb(self) -> bool {
        matches!(self, PtmFormat::Lrgb | PtmFormat::JpegLrgb(_))
    }

    /// The JPEG quality of a JPEG variant.
    pub fn jpeg_quality(self) -> Option<u8> {
        match self {
            PtmFormat::JpegRgb(q) | PtmFormat::JpegLrgb(q) => Some(q),
            _ => None,
        }
    }

    /// How `relit info` names it.
    pub fn describe(self) -> String {
        match self {
            PtmFormat::Rgb => "RGB".into(),
            PtmFormat::Lrgb => "LRGB".into(),
            PtmFormat::JpegRgb(q) => format!("JPEG RGB (quality {q})"),
            PtmFormat::JpegLrgb(q) => format!("JPEG LRGB (quality {q})"),
        }
    }

    /// Where plane `i` (a JPEG variant's stream order) lies in the raw layout of `n`
    /// pixels: its first byte, the bytes between a pixel's and the next's, and its slot.
    fn plane_place(self, i: usize, n: usize) -> (usize, usize, usize) {
        if i < K || !self.lrgb() {
            ((i / K) * n * K, K, i % K)
        } else {
            (n * K, 3, i - K)
        }
    }

    /// Bytes per pixel of the raw layout: all planes, one byte each.
    fn planes(self) -> usize {
        if self.lrgb() {
            K + 3
        } else {
            3 * K
        }
    }
}

/// Whether `prefix` (the first bytes of a file) starts a PTM 1.2 file.
pub fn is_ptm(prefix: &[u8]) -> bool {
    prefix.starts_with(MAGIC)
}

fn ptm_basis() -> Result<Box<dyn Basis>> {
    BasisSpec::new("ptm", serde_json::json!({})).build()
}

/// Read a `.ptm` file.
pub fn read(path: &Path) -> Result<RelightableImage> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "read", e))?;
    decode(path, &bytes)
}

/// One line about a `.ptm` file's own form, from its format line.
pub fn describe(path: &Path) -> Result<String> {
    use std::io::Read;
    let mut head = [0u8; 64];
    let read = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .map_err(|e| Error::io(path, "read", e))?;
    let text = String::from_utf8_lossy(&head[..read]);
    let format = text.split_ascii_whitespace().nth(1).unwrap_or("?");
    let planes = if format.contains("JPEG") {
        "8-bit codes, a JPEG per plane"
    } else {
        "8-bit codes"
    };
    Ok(format!("PTM 1.2, {format} ({planes})"))
}

/// Decode the bytes of a `.ptm` file (`path` names it in errors).
pub fn decode(path: &Path, bytes: &[u8]) -> Result<RelightableImage> {
    // The version and format first, so that an unsupported variant is named as such
    // whatever its header holds next.
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(64)]);
    let mut words = head.split_ascii_whitespace();
    if words.next() != Some("PTM_1.2") {
        return Err(Error::parse(format!(
            "{}: not a PTM 1.2 file (it must start with `PTM_1.2`)",
            path.display()
        )));
    }
    let format = match words.next() {
        Some("PTM_FORMAT_RGB") => PtmFormat::Rgb,
        Some("PTM_FORMAT_LRGB") => PtmFormat::Lrgb,
        // The quality is read with the rest of the header.
        Some("PTM_FORMAT_JPEG_RGB") => PtmFormat::JpegRgb(0),
        Some("PTM_FORMAT_JPEG_LRGB") => PtmFormat::JpegLrgb(0),
        Some(other) if other.starts_with("PTM_FORMAT_") => {
            return Err(Error::parse(format!(
                "{}: {other} is not supported (relit reads PTM_FORMAT_RGB, PTM_FORMAT_LRGB \
                 and their JPEG variants)",
                path.display()
            )))
        }
        _ => {
            return Err(Error::parse(format!(
                "{}: the header has no PTM_FORMAT_ line",
                path.display()
            )))
        }
    };
    let (fields, offset) = text_header(path, bytes, 2 + 2 + 2 * K, false)?;
    let width: usize = field(path, "width", &fields[2])?;
    let height: usize = field(path, "height", &fields[3])?;
    let mut scale = [0.0f32; K];
    let mut bias = [0.0f32; K];
    for i in 0..K {
        scale[i] = field(path, &format!("scale {i}"), &fields[4 + i])?;
        let b: f64 = field(path, &format!("bias {i}"), &fields[4 + K + i])?;
        if !scale[i].is_finite() || !b.is_finite() || b.fract() != 0.0 || b.abs() > 1e6 {
            return Err(Error::parse(format!(
                "{}: scale {i} `{}` and bias {i} `{}` must be a finite number and an integer",
                path.display(),
                fields[4 + i],
                fields[4 + K + i]
            )));
        }
        bias[i] = b as f32;
    }
    let raw;
    let data: &[u8] = if format.jpeg_quality().is_some() {
        raw = jpeg_planes(path, bytes, format, width, height)?;
        &raw
    } else {
        check_payload(path, bytes.len(), offset, width, height, format.planes())?;
        &bytes[offset..]
    };
    let n = width * height;
    let mut maps = CoefficientMaps::zeros(width, height, K);
    let decode = |block: &[u8], pixel_in_file: usize, i: usize| -> f32 {
        (block[pixel_in_file * K + i] as f32 - bias[i]) * scale[i]
    };
    for y in 0..height {
        // File row r holds image row height − 1 − r.
        let file_row = height - 1 - y;
        for x in 0..width {
            let (p, q) = (y * width + x, file_row * width + x);
            if !format.lrgb() {
                for c in 0..3 {
                    let block = &data[c * n * K..(c + 1) * n * K];
                    for i in 0..K {
                        maps.data[(3 * i + c) * n + p] = decode(block, q, i) / 255.0;
                    }
                }
            } else {
                let block = &data[..n * K];
                let rgb = &data[n * K + 3 * q..n * K + 3 * q + 3];
                for i in 0..K {
                    let l = decode(block, q, i);
                    for (c, &colour) in rgb.iter().enumerate() {
                        maps.data[(3 * i + c) * n + p] = l * colour as f32 / (255.0 * 255.0);
                    }
                }
            }
        }
    }
    let meta = Metadata::new(ptm_basis()?.spec(), MapSpace::Srgb, Projection::default());
    Ok(RelightableImage {
        meta,
        maps,
        depth: None,
    })
}

/// How many pixels a JPEG stream may claim per byte it holds: a baseline JPEG spends at
/// least a few bits on every 8×8 block (about 100 pixels a byte for a constant plane),
/// so a claim beyond this is a lie, refused before anything is allocated for it.
const JPEG_PIXELS_PER_BYTE: usize = 1024;

/// The raw layout's bytes (all planes, one byte each per pixel, rows as stored) of a
/// JPEG variant: its streams decoded, predictions added and corrections applied (see
/// the module docs).
fn jpeg_planes(
    path: &Path,
    bytes: &[u8],
    format: PtmFormat,
    width: usize,
    height: usize,
) -> Result<Vec<u8>> {
    let planes = format.planes();
    let first = 4 + 2 * K;
    let (fields, offset) = text_header(path, bytes, first + 1 + 7 * planes, false)?;
    let bad = |what: String| Error::parse(format!("{}: {what}", path.display()));
    // The JPEG quality the file was written at: checked to be a number, not needed to decode.
    field::<i64>(path, "compression parameter", &fields[first])?;
    let row = |name: &str, r: usize| -> Result<Vec<i64>> {
        (0..planes)
            .map(|i| {
                field(
                    path,
                    &format!("{name} {i}"),
                    &fields[first + 1 + r * planes + i],
                )
            })
            .collect()
    };
    let transforms = row("transform", 0)?;
    let order = row("order", 3)?;
    let references = row("reference plane", 4)?;
    let sizes = row("compressed size", 5)?;
    let side = row("side information size", 6)?;
    if width == 0 || height == 0 || width > 65535 || height > 65535 {
        return Err(bad(format!(
            "an image of {width}×{height} pixels (JPEG planes are 1 to 65535 a side)"
        )));
    }
    if let Some(i) = (0..planes).find(|&i| transforms[i] & !1 != 0) {
        return Err(bad(format!(
            "plane {i}'s transform {} asks for motion-compensated prediction, which relit \
             does not read",
            transforms[i]
        )));
    }
    let mut by_order = vec![usize::MAX; planes];
    for (i, &o) in order.iter().enumerate() {
        match usize::try_from(o) {
            Ok(o) if o < planes && by_order[o] == usize::MAX => by_order[o] = i,
            _ => {
                return Err(bad(format!(
                    "the decoding order {order:?} is not each of 0 to {} once",
                    planes - 1
                )))
            }
        }
    }
    for (i, &r) in references.iter().enumerate() {
        let usable = r == -1
            || usize::try_from(r).is_ok_and(|r| r < planes && r != i && order[r] < order[i]);
        if !usable {
            return Err(bad(format!(
                "plane {i}'s reference plane {r} is not a plane completed before it"
            )));
        }
    }
    // Every stream's claimed length within the file, before any is read.
    let mut spans = Vec::with_capacity(planes);
    let mut at = offset;
    let n = width * height;
    for i in 0..planes {
        let lengths = [sizes[i], side[i]].map(|v| usize::try_from(v).ok());
        let (Some(jpeg), Some(info)) = (lengths[0], lengths[1]) else {
            return Err(bad(format!(
                "plane {i}'s sizes {} and {} must not be negative",
                sizes[i], side[i]
            )));
        };
        let end = at
            .checked_add(jpeg)
            .and_then(|e| e.checked_add(info))
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| {
                bad(format!(
                    "truncated: plane {i}'s {jpeg}-byte JPEG and {info} bytes of side \
                     information run past the file's {} bytes",
                    bytes.len()
                ))
            })?;
        if n > jpeg.saturating_mul(JPEG_PIXELS_PER_BYTE) {
            return Err(bad(format!(
                "plane {i}'s {jpeg}-byte JPEG cannot hold {width}×{height} pixels"
            )));
        }
        if info % 5 != 0 {
            return Err(bad(format!(
                "plane {i}'s side information is {info} bytes, not 5-byte corrections"
            )));
        }
        spans.push((at, at + jpeg, end));
        at = end;
    }
    let mut decoded: Vec<Vec<u8>> = Vec::with_capacity(planes);
    for (i, &(start, mid, _)) in spans.iter().enumerate() {
        decoded.push(
            decode_gray_jpeg(&bytes[start..mid], width, height)
                .map_err(|why| bad(format!("plane {i}'s JPEG stream {why}")))?,
        );
    }
    for &i in &by_order {
        if let Ok(r) = usize::try_from(references[i]) {
            let invert = transforms[i] & 1 == 1;
            let (plane, reference) = if r < i {
                let (a, b) = decoded.split_at_mut(i);
                (&mut b[0], &a[r])
            } else {
                let (a, b) = decoded.split_at_mut(r);
                (&mut a[i], &b[0])
            };
            for (v, &p) in plane.iter_mut().zip(reference.iter()) {
                let p = if invert { 255 - p } else { p };
                *v = v.wrapping_add(p).wrapping_sub(128);
            }
        }
        let (_, mid, end) = spans[i];
        for fix in bytes[mid..end].chunks_exact(5) {
            let index = u32::from_be_bytes([fix[0], fix[1], fix[2], fix[3]]) as usize;
            if let Some(v) = decoded[i].get_mut(index) {
                *v = fix[4];
            }
        }
    }
    // The raw layout: coefficient blocks pixel by pixel (and LRGB's colours).
    let mut raw = vec![0u8; n * planes];
    for (i, plane) in decoded.iter().enumerate() {
        let (base, stride, slot) = format.plane_place(i, n);
        for (q, &v) in plane.iter().enumerate() {
            raw[base + q * stride + slot] = v;
        }
    }
    Ok(raw)
}

/// A grayscale JPEG's `width × height` bytes, its size checked before it is decoded.
fn decode_gray_jpeg(
    stream: &[u8],
    width: usize,
    height: usize,
) -> std::result::Result<Vec<u8>, String> {
    use image::ImageDecoder;
    let decoder = image::codecs::jpeg::JpegDecoder::new(std::io::Cursor::new(stream))
        .map_err(|e| format!("is not a JPEG: {e}"))?;
    let (w, h) = decoder.dimensions();
    if (w as usize, h as usize) != (width, height) {
        return Err(format!("is {w}×{h}, not the header's {width}×{height}"));
    }
    let img = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| format!("does not decode: {e}"))?
        .into_luma8();
    Ok(img.into_raw())
}

/// Write `image` as a `.ptm` file in `format`.
pub fn write(path: &Path, image: &RelightableImage, format: PtmFormat) -> Result<()> {
    write_bytes_atomically(path, &encode(image, format)?)
}

/// The bytes of `image` as a `.ptm` file in `format`.
pub fn encode(image: &RelightableImage, format: PtmFormat) -> Result<Vec<u8>> {
    let basis = ptm_basis()?;
    let maps = reexpress(image, basis.as_ref(), MapSpace::Srgb)?;
    let (width, height) = (maps.width, maps.height);
    let n = width * height;
    // Per pixel: the polynomials to store (one, or three) in PTM units (8-bit codes),
    // and for LRGB the colour.
    let coefficient = |p: usize, c: usize, i: usize| maps.data[(3 * i + c) * n + p] * 255.0;
    let (polynomials, colours): (Vec<[f32; K]>, Vec<[u8; 3]>) = if format.lrgb() {
        lrgb_split(&maps, basis.as_ref())
    } else {
        (
            (0..3)
                .flat_map(|c| (0..n).map(move |p| std::array::from_fn(|i| coefficient(p, c, i))))
                .collect(),
            Vec::new(),
        )
    };
    let mut scale = [0.0f32; K];
    let mut bias = [0i64; K];
    for i in 0..K {
        let range = Range::of(polynomials.iter().map(|a| a[i]));
        // The printed scale is what readers use: quantise with that same value.
        scale[i] = range.step().to_string().parse().unwrap_or(range.step());
        bias[i] = (-range.min / scale[i]).round() as i64;
    }
    let header = format!(
        "PTM_1.2\n{}\n{width}\n{height}\n{}\n{}\n",
        format.header_name(),
        scale.map(|s| s.to_string()).join(" "),
        bias.map(|b| b.to_string()).join(" ")
    );
    // The raw layout: every plane's code per pixel, rows from the bottom up.
    let blocks = polynomials.len() / n;
    let mut body = Vec::with_capacity(blocks * n * K + colours.len() * 3);
    for block in 0..blocks {
        for file_row in 0..height {
            let y = height - 1 - file_row;
            for x in 0..width {
                let a = &polynomials[block * n + y * width + x];
                for i in 0..K {
                    let code = (a[i] / scale[i] + bias[i] as f32).round();
                    body.push(code.clamp(0.0, 255.0) as u8);
                }
            }
        }
    }
    for file_row in 0..colours.len() / width.max(1) {
        let y = height - 1 - file_row;
        for x in 0..width {
            body.extend_from_slice(&colours[y * width + x]);
        }
    }
    let Some(quality) = format.jpeg_quality() else {
        let mut out = header.into_bytes();
        out.extend_from_slice(&body);
        return Ok(out);
    };
    if width > 65535 || height > 65535 {
        return Err(Error::invalid(format!(
            "a {width}×{height} image does not fit JPEG planes (at most 65535 a side)"
        )));
    }
    // Each plane its own grayscale JPEG: no prediction, no corrections.
    let planes = format.planes();
    let streams: Vec<Vec<u8>> = (0..planes)
        .map(|i| {
            let (base, stride, slot) = format.plane_place(i, n);
            let gray: Vec<u8> = (0..n).map(|q| body[base + q * stride + slot]).collect();
            let mut out = Vec::new();
            let mut encoder = jpeg_encoder::Encoder::new(&mut out, quality);
            encoder.set_optimized_huffman_tables(true);
            encoder
                .encode(
                    &gray,
                    width as u16,
                    height as u16,
                    jpeg_encoder::ColorType::Luma,
                )
                .map_err(|e| Error::new(crate::ErrorKind::Io, format!("JPEG: {e}")))?;
            Ok(out)
        })
        .collect::<Result<_>>()?;
    let line = |values: Vec<String>| values.join(" ") + "\n";
    let mut out = header;
    out += &format!("{quality}\n");
    out += &line(vec!["0".into(); planes]); // transforms
    out += &line(vec!["0".into(); planes]); // motion vectors, x
    out += &line(vec!["0".into(); planes]); // and y
    out += &line((0..planes).map(|i| i.to_string()).collect()); // order
    out += &line(vec!["-1".into(); planes]); // reference planes
    out += &line(streams.iter().map(|s| s.len().to_string()).collect());
    out += &line(vec!["0".into(); planes]); // side information sizes
    let mut out = out.into_bytes();
    for stream in &streams {
        out.extend_from_slice(stream);
    }
    Ok(out)
}

/// LRGB's luminance polynomial and colour per pixel: the colour is the pixel's mean
/// response over the dome per channel, scaled so that its brightest channel is 255,
/// and the polynomial the luma response times that scale (so that `rgb · L / 255`
/// gives each channel back wherever the pixel's chromaticity does not change with the
/// light).
fn lrgb_split(maps: &CoefficientMaps, basis: &dyn Basis) -> (Vec<[f32; K]>, Vec<[u8; 3]>) {
    const LUMA: [f32; 3] = [0.299, 0.587, 0.114];
    let n = maps.pixels();
    // The mean of each basis function over the dome, so that a pixel's mean response
    // is a dot product with its coefficients.
    let dome = super::reexpress::dome_directions();
    let mut mean = [0.0f32; K];
    let mut weights = [0.0f64; K];
    for &d in &dome {
        basis.eval(d, &mut weights);
        for i in 0..K {
            mean[i] += weights[i] as f32 / dome.len() as f32;
        }
    }
    let mut polynomials = Vec::with_capacity(n);
    let mut colours = Vec::with_capacity(n);
    for p in 0..n {
        let c = |ch: usize, i: usize| maps.data[(3 * i + ch) * n + p];
        let luma: [f32; K] = std::array::from_fn(|i| (0..3).map(|ch| LUMA[ch] * c(ch, i)).sum());
        let luma_mean: f32 = (0..K).map(|i| luma[i] * mean[i]).sum();
        let channel_mean: [f32; 3] =
            std::array::from_fn(|ch| (0..K).map(|i| c(ch, i) * mean[i]).sum());
        if luma_mean <= 1e-6 {
            polynomials.push([0.0; K]);
            colours.push([0; 3]);
            continue;
        }
        let chroma = channel_mean.map(|m| (m / luma_mean).max(0.0));
        let top = chroma.iter().cloned().fold(0.0f32, f32::max).max(1e-6);
        colours.push(chroma.map(|v| (255.0 * v / top).round().clamp(0.0, 255.0) as u8));
        polynomials.push(luma.map(|a| a * top * 255.0));
    }
    (polynomials, colours)
}
