//! HP's Polynomial Texture Map files, version 1.2 (`.ptm`), formats
//! `PTM_FORMAT_RGB` and `PTM_FORMAT_LRGB`.
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
//! Not read: the JPEG-compressed variants (`PTM_FORMAT_JPEG_*`), `PTM_FORMAT_LUM` and
//! the PTM 1.1 layout; they are refused with their name.

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

/// How the colour of a PTM is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PtmFormat {
    /// One polynomial per colour channel.
    Rgb,
    /// One luminance polynomial times a per-pixel RGB colour (what PTMfitter writes).
    Lrgb,
}

impl PtmFormat {
    /// Parse `rgb` or `lrgb`.
    pub fn parse(name: &str) -> Result<PtmFormat> {
        match name.to_ascii_lowercase().as_str() {
            "rgb" => Ok(PtmFormat::Rgb),
            "lrgb" => Ok(PtmFormat::Lrgb),
            other => Err(Error::invalid(format!(
                "unknown PTM format `{other}`: use rgb or lrgb"
            ))),
        }
    }

    fn header_name(self) -> &'static str {
        match self {
            PtmFormat::Rgb => "PTM_FORMAT_RGB",
            PtmFormat::Lrgb => "PTM_FORMAT_LRGB",
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
        Some(other) if other.starts_with("PTM_FORMAT_") => {
            return Err(Error::parse(format!(
                "{}: {other} is not supported (relit reads PTM_FORMAT_RGB and PTM_FORMAT_LRGB)",
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
    let bytes_per_pixel = match format {
        PtmFormat::Rgb => 3 * K,
        PtmFormat::Lrgb => K + 3,
    };
    check_payload(path, bytes.len(), offset, width, height, bytes_per_pixel)?;
    let data = &bytes[offset..];
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
            match format {
                PtmFormat::Rgb => {
                    for c in 0..3 {
                        let block = &data[c * n * K..(c + 1) * n * K];
                        for i in 0..K {
                            maps.data[(3 * i + c) * n + p] = decode(block, q, i) / 255.0;
                        }
                    }
                }
                PtmFormat::Lrgb => {
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
    }
    let meta = Metadata::new(ptm_basis()?.spec(), MapSpace::Srgb, Projection::default());
    Ok(RelightableImage {
        meta,
        maps,
        depth: None,
    })
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
    let (polynomials, colours): (Vec<[f32; K]>, Vec<[u8; 3]>) = match format {
        PtmFormat::Rgb => (
            (0..3)
                .flat_map(|c| (0..n).map(move |p| std::array::from_fn(|i| coefficient(p, c, i))))
                .collect(),
            Vec::new(),
        ),
        PtmFormat::Lrgb => lrgb_split(&maps, basis.as_ref()),
    };
    let mut scale = [0.0f32; K];
    let mut bias = [0i64; K];
    for i in 0..K {
        let range = Range::of(polynomials.iter().map(|a| a[i]));
        // The printed scale is what readers use: quantise with that same value.
        scale[i] = range.step().to_string().parse().unwrap_or(range.step());
        bias[i] = (-range.min / scale[i]).round() as i64;
    }
    let mut out = format!(
        "PTM_1.2\n{}\n{width}\n{height}\n{}\n{}\n",
        format.header_name(),
        scale.map(|s| s.to_string()).join(" "),
        bias.map(|b| b.to_string()).join(" ")
    )
    .into_bytes();
    let blocks = polynomials.len() / n;
    out.reserve(blocks * n * K + colours.len() * 3);
    for block in 0..blocks {
        for file_row in 0..height {
            let y = height - 1 - file_row;
            for x in 0..width {
                let a = &polynomials[block * n + y * width + x];
                for i in 0..K {
                    let code = (a[i] / scale[i] + bias[i] as f32).round();
                    out.push(code.clamp(0.0, 255.0) as u8);
                }
            }
        }
    }
    for file_row in 0..colours.len() / width.max(1) {
        let y = height - 1 - file_row;
        for x in 0..width {
            out.extend_from_slice(&colours[y * width + x]);
        }
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
