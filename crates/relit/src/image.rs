//! In-memory linear RGB images and their file formats.
//!
//! Decoding: JPEG, PNG (8/16-bit), TIFF, OpenEXR and Radiance HDR. Integer samples are
//! sRGB-decoded to linear unless declared linear; float samples are linear already.
//! Encoding: 8-bit sRGB PNG/JPEG/TIFF, or linear OpenEXR (by the file extension).

use crate::color::{self, Encoding};
use crate::fsutil::write_atomically;
use crate::{Error, ErrorKind, Result};
use image::{DynamicImage, ImageReader};
use std::cell::Cell;
use std::path::Path;

pub(crate) mod jpeg;
pub use jpeg::{decoder_simd as jpeg_decoder_simd, DECODER_ADVICE as JPEG_DECODER_ADVICE};
#[cfg(test)]
pub(crate) mod test_maps;

/// The most bytes a decoded image may take in its own 8-bit or 16-bit samples: a header
/// that claims more is refused before anything is allocated.
const MAX_DECODED_BYTES: u64 = 4 << 30;

/// A linear RGB image, interleaved, row-major from the top-left corner.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageRgb {
    pub width: usize,
    pub height: usize,
    /// `3 * width * height` samples: pixel `(x, y)` channel `c` at `3 * (y * width + x) + c`.
    pub data: Vec<f32>,
}

impl ImageRgb {
    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0.0; 3 * width * height],
        }
    }

    /// The number of pixels.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// The RGB value of pixel `(x, y)`.
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        let i = 3 * (y * self.width + x);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Multiply every sample by `factor`.
    pub fn scale(&mut self, factor: f32) {
        self.data.iter_mut().for_each(|v| *v *= factor);
    }

    /// The 8-bit sRGB encoding of the image.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.data
            .iter()
            .map(|&v| color::linear_to_srgb8(v))
            .collect()
    }
}

/// Image file formats relit reads, by what their samples are.
/// Whether `path` names a floating-point image format (values proportional to radiance).
pub(crate) fn is_float_format(path: &Path) -> bool {
    matches!(extension(path).as_deref(), Some("exr" | "hdr" | "pic"))
}

fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
}

/// The width and height of an image file, reading only its header.
pub fn dimensions(path: &Path) -> Result<(usize, usize)> {
    let reader = open_reader(path)?;
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| Error::image(path, e))?;
    Ok((w as usize, h as usize))
}

fn open_reader(path: &Path) -> Result<ImageReader<std::io::BufReader<std::fs::File>>> {
    let mut reader = ImageReader::open(path)
        .map_err(|e| Error::io(path, "open image", e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, "read image", e))?;
    // The decoder refuses images whose header asks for more than this, so a corrupt
    // header cannot make relit allocate without bound.
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_DECODED_BYTES);
    reader.limits(limits);
    Ok(reader)
}

/// Decode an image file to linear RGB.
///
/// `encoding` overrides how integer samples are interpreted; by default 8/16-bit
/// samples are sRGB and float samples linear (see the [conventions](crate)).
pub fn load_linear(path: &Path, encoding: Option<Encoding>) -> Result<ImageRgb> {
    if jpeg::is_jpeg(path) {
        // Row by row, as a fit reads it, so that both see the same decoder's pixels.
        let (width, height) = dimensions(path)?;
        refuse_oversized(path, width, height)?;
        let (width, height, data, _) = load_linear_parts(path, encoding, 0..height, &[])?;
        return Ok(ImageRgb {
            width,
            height,
            data,
        });
    }
    let decoded = decode(path)?;
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    let data = linear_samples(&decoded, path, encoding, 0..3 * width * height);
    Ok(ImageRgb {
        width,
        height,
        data,
    })
}

/// Parts of an image in linear RGB, as [`load_linear`] would give them: the rows
/// `rows` (`3·width` values a row) and the pixels `pixels` (3 values each), and the
/// image's size. See [`read_linear_parts`], which hands the rows over one at a time.
pub fn load_linear_parts(
    path: &Path,
    encoding: Option<Encoding>,
    rows: std::ops::Range<usize>,
    pixels: &[usize],
) -> Result<(usize, usize, Vec<f32>, Vec<f32>)> {
    let mut band = Vec::new();
    let (width, height, picked) =
        read_linear_parts(path, encoding, None, rows.clone(), pixels, &mut |_, row| {
            if band.is_empty() {
                band.reserve_exact(row.len() * rows.len());
            }
            band.extend_from_slice(row);
            Ok(())
        })?;
    Ok((width, height, band, picked))
}

/// Parts of an image in linear RGB: each row of `rows`, in order, handed to
/// `row(y, values)` (`3·width` values, the caller may change them), and the pixels
/// `pixels` returned (3 values each, in the order asked), with the image's size. Only
/// those samples are converted to `f32`. A JPEG is decoded a few rows at a time and
/// only down to the last row wanted, so a reader that keeps nothing of a row holds a few
/// rows of the image, whatever its size; other formats are decoded whole, in their own
/// type (3 bytes a pixel for 8-bit files instead of 12).
///
/// `then`, where given, maps every linear value (rows and pixels) before they are
/// handed over: for an 8-bit file it is folded into the table of the 256 codes, so a
/// reader that wants another encoding of the values (the fit's display-referred maps)
/// pays nothing per sample for it.
pub fn read_linear_parts(
    path: &Path,
    encoding: Option<Encoding>,
    then: Option<fn(f32) -> f32>,
    rows: std::ops::Range<usize>,
    pixels: &[usize],
    row: &mut dyn FnMut(usize, &mut [f32]) -> Result<()>,
) -> Result<(usize, usize, Vec<f32>)> {
    if jpeg::is_jpeg(path) {
        if let Some(parts) = jpeg_parts(path, encoding, then, rows.clone(), pixels, row)? {
            return Ok(parts);
        }
    }
    let map = |values: &mut [f32]| {
        if let Some(f) = then {
            values.iter_mut().for_each(|v| *v = f(*v));
        }
    };
    let decoded = decode(path)?;
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    if rows.end > height || pixels.iter().any(|&p| p >= width * height) {
        return Err(missing_parts(path, width, height, &rows));
    }
    for y in rows {
        let mut values =
            linear_samples(&decoded, path, encoding, 3 * width * y..3 * width * (y + 1));
        map(&mut values);
        row(y, &mut values)?;
    }
    let mut picked = linear_samples(
        &decoded,
        path,
        encoding,
        pixels.iter().flat_map(|&p| 3 * p..3 * p + 3),
    );
    map(&mut picked);
    Ok((width, height, picked))
}

/// [`read_linear_parts`] for a JPEG, decoded row by row. `None` when libjpeg leaves the
/// file to the general decoder.
fn jpeg_parts(
    path: &Path,
    encoding: Option<Encoding>,
    then: Option<fn(f32) -> f32>,
    rows: std::ops::Range<usize>,
    pixels: &[usize],
    row: &mut dyn FnMut(usize, &mut [f32]) -> Result<()>,
) -> Result<Option<(usize, usize, Vec<f32>)>> {
    let mut table = eight_bit_table(encoding);
    if let Some(f) = then {
        table.iter_mut().for_each(|v| *v = f(*v));
    }
    let mut values = Vec::new();
    let parts = jpeg_code_parts(path, rows, pixels, &mut |y, codes| {
        values.clear();
        values.extend(codes.iter().map(|&b| table[b as usize]));
        row(y, &mut values)
    })?;
    Ok(parts.map(|(width, height, picked)| {
        let picked = picked.iter().map(|&b| table[b as usize]).collect();
        (width, height, picked)
    }))
}

/// [`read_code_parts`] for a JPEG libjpeg decodes to RGB, row by row; `None` when it
/// leaves the file to the general decoder.
fn jpeg_code_parts(
    path: &Path,
    rows: std::ops::Range<usize>,
    pixels: &[usize],
    row: &mut dyn FnMut(usize, &[u8]) -> Result<()>,
) -> Result<Option<(usize, usize, Vec<u8>)>> {
    // The picked pixels in file order, each with where its samples go.
    let mut order: Vec<(usize, usize)> = pixels.iter().copied().zip(0..).collect();
    order.sort_unstable();
    let mut next = 0;
    let mut picked = vec![0u8; 3 * pixels.len()];
    // The first error of the caller's, which stops the rows handed over.
    let mut failed = None;
    let width = Cell::new(0);
    let streamed = jpeg::stream_rows(
        path,
        |w, h| {
            let last = order.last().map_or(0, |&(p, _)| p + 1);
            if rows.end > h || last > w * h {
                return Err(missing_parts(path, w, h, &rows));
            }
            width.set(w);
            Ok(rows_wanted(&rows, &order, w))
        },
        |y, codes| {
            let w = width.get();
            while let Some(&(p, slot)) = order.get(next).filter(|&&(p, _)| p / w == y) {
                let x = p % w;
                picked[3 * slot..3 * slot + 3].copy_from_slice(&codes[3 * x..3 * x + 3]);
                next += 1;
            }
            if rows.contains(&y) && failed.is_none() {
                if let Err(e) = row(y, codes) {
                    failed = Some(e);
                }
            }
        },
    )?;
    if let Some(e) = failed {
        return Err(e);
    }
    Ok(match streamed {
        jpeg::Streamed::Done { width, height } => Some((width, height, picked)),
        jpeg::Streamed::Unsupported => None,
    })
}

/// The rows of an image `width` pixels wide that hold `rows` and the pixels `order`
/// (sorted, with their places): from the first of either to the last.
fn rows_wanted(
    rows: &std::ops::Range<usize>,
    order: &[(usize, usize)],
    width: usize,
) -> std::ops::Range<usize> {
    let w = width.max(1);
    let pixel_rows = match (order.first(), order.last()) {
        (Some(&(first, _)), Some(&(last, _))) => first / w..last / w + 1,
        _ => 0..0,
    };
    match (rows.is_empty(), pixel_rows.is_empty()) {
        (_, true) => rows.clone(),
        (true, false) => pixel_rows,
        (false, false) => rows.start.min(pixel_rows.start)..rows.end.max(pixel_rows.end),
    }
}

/// Whether `path` is a JPEG: its samples are 8-bit codes, which [`read_code_parts`]
/// hands over as they are.
pub fn is_jpeg_file(path: &Path) -> bool {
    jpeg::is_jpeg(path)
}

/// [`read_linear_parts`] of a JPEG without the conversion: each row of `rows` handed to
/// `row(y, codes)` as its 8-bit RGB codes (`3·width` bytes), and the codes of `pixels`
/// returned, with the image's size. `eight_bit_values(encoding)[code]` is the linear
/// value [`read_linear_parts`] gives for a code, so a reader that keeps the codes (the
/// fit's spill file, a quarter of the floats' bytes) can convert them later, in
/// whichever encoding it then needs, to the same values. JPEGs libjpeg does not convert
/// to RGB (CMYK) go through the general decoder, as there.
pub fn read_code_parts(
    path: &Path,
    rows: std::ops::Range<usize>,
    pixels: &[usize],
    row: &mut dyn FnMut(usize, &[u8]) -> Result<()>,
) -> Result<(usize, usize, Vec<u8>)> {
    if !jpeg::is_jpeg(path) {
        return Err(Error::new(
            ErrorKind::Image,
            format!("{}: not a JPEG, whose codes could be read", path.display()),
        ));
    }
    if let Some(parts) = jpeg_code_parts(path, rows.clone(), pixels, row)? {
        return Ok(parts);
    }
    let decoded = decode(path)?.to_rgb8();
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    if rows.end > height || pixels.iter().any(|&p| p >= width * height) {
        return Err(missing_parts(path, width, height, &rows));
    }
    let raw = decoded.as_raw();
    for y in rows {
        row(y, &raw[3 * width * y..3 * width * (y + 1)])?;
    }
    let picked = pixels
        .iter()
        .flat_map(|&p| raw[3 * p..3 * p + 3].iter().copied())
        .collect();
    Ok((width, height, picked))
}

/// The linear value of each of the 256 codes of an 8-bit file, as
/// [`read_linear_parts`] converts them.
pub fn eight_bit_values(encoding: Option<Encoding>) -> [f32; 256] {
    eight_bit_table(encoding)
}

/// Linear values of the 256 codes of an 8-bit file: sRGB-decoded unless `encoding`
/// says the codes are linear.
fn eight_bit_table(encoding: Option<Encoding>) -> [f32; 256] {
    if encoding.unwrap_or(Encoding::Srgb) == Encoding::Srgb {
        *color::srgb8_table()
    } else {
        std::array::from_fn(|i| i as f32 / 255.0)
    }
}

fn refuse_oversized(path: &Path, width: usize, height: usize) -> Result<()> {
    if 3 * width as u64 * height as u64 > MAX_DECODED_BYTES {
        return Err(Error::new(
            ErrorKind::Image,
            format!(
                "{}: a {width}×{height} image is larger than relit decodes ({} GiB)",
                path.display(),
                MAX_DECODED_BYTES >> 30
            ),
        ));
    }
    Ok(())
}

fn missing_parts(path: &Path, width: usize, height: usize, rows: &std::ops::Range<usize>) -> Error {
    Error::new(
        ErrorKind::InvalidInput,
        format!(
            "{}: {width}×{height} has no rows {rows:?} or pixels that far",
            path.display()
        ),
    )
}

fn decode(path: &Path) -> Result<DynamicImage> {
    open_reader(path)?
        .decode()
        .map_err(|e| Error::image(path, e))
}

/// The samples `indices` (`3·pixel + channel`) of a decoded image in linear RGB: 8- and
/// 16-bit files are sRGB-encoded unless `encoding` says linear; float files are linear
/// unless the caller insists they are sRGB.
fn linear_samples(
    decoded: &DynamicImage,
    path: &Path,
    encoding: Option<Encoding>,
    indices: impl Iterator<Item = usize>,
) -> Vec<f32> {
    let srgb = encoding.unwrap_or(Encoding::Srgb) == Encoding::Srgb;
    match decoded {
        DynamicImage::ImageLuma8(_)
        | DynamicImage::ImageLumaA8(_)
        | DynamicImage::ImageRgb8(_)
        | DynamicImage::ImageRgba8(_) => {
            let table = color::srgb8_table();
            let owned;
            let rgb = match decoded.as_rgb8() {
                Some(rgb) => rgb,
                None => {
                    owned = decoded.to_rgb8();
                    &owned
                }
            };
            let raw = rgb.as_raw();
            if srgb {
                indices.map(|i| table[raw[i] as usize]).collect()
            } else {
                indices.map(|i| raw[i] as f32 / 255.0).collect()
            }
        }
        DynamicImage::ImageLuma16(_)
        | DynamicImage::ImageLumaA16(_)
        | DynamicImage::ImageRgb16(_)
        | DynamicImage::ImageRgba16(_) => {
            let owned;
            let rgb = match decoded.as_rgb16() {
                Some(rgb) => rgb,
                None => {
                    owned = decoded.to_rgb16();
                    &owned
                }
            };
            let raw = rgb.as_raw();
            if srgb {
                let table = color::srgb16_table();
                indices.map(|i| table[raw[i] as usize]).collect()
            } else {
                indices.map(|i| raw[i] as f32 / 65535.0).collect()
            }
        }
        _ => {
            // Float formats: linear unless the caller insists they are sRGB-encoded.
            let owned;
            let rgb = match decoded.as_rgb32f() {
                Some(rgb) => rgb,
                None => {
                    owned = decoded.to_rgb32f();
                    &owned
                }
            };
            let raw = rgb.as_raw();
            if encoding == Some(Encoding::Srgb) && !is_float_format(path) {
                indices.map(|i| color::srgb_to_linear(raw[i])).collect()
            } else {
                indices.map(|i| raw[i]).collect()
            }
        }
    }
}

/// Decode a single-channel image (depth, mask) as float values without any transfer
/// curve; integer formats are scaled to `[0, 1]`. EXR files may hold the value in a
/// channel named `Z`, `Y`, `R` or `A`.
pub fn load_scalar(path: &Path) -> Result<(usize, usize, Vec<f32>)> {
    if extension(path).as_deref() == Some("exr") {
        return openexr::read_scalar_channel(path);
    }
    let decoded = open_reader(path)?
        .decode()
        .map_err(|e| Error::image(path, e))?;
    let (w, h) = (decoded.width() as usize, decoded.height() as usize);
    Ok((w, h, decoded.to_luma32f().into_raw()))
}

/// Write a linear image: `.exr` stays linear (half floats), any other extension gets
/// 8-bit sRGB. `exposure` is in stops (each +1 doubles the radiance).
pub fn save(path: &Path, image: &ImageRgb, exposure: f64) -> Result<()> {
    let factor = 2f32.powf(exposure as f32);
    let ext = extension(path).unwrap_or_default();
    if ext == "exr" {
        // Scaled while encoding: no copy of a frame that may be gigabytes.
        return openexr::write_rgb_scaled(path, image, factor);
    }
    let format = match ext.as_str() {
        "png" => image::ImageFormat::Png,
        "jpg" | "jpeg" => image::ImageFormat::Jpeg,
        "tif" | "tiff" => image::ImageFormat::Tiff,
        "bmp" => image::ImageFormat::Bmp,
        _ => {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!(
                    "cannot tell the output format of {} (use .png, .jpg, .tif or .exr)",
                    path.display()
                ),
            ))
        }
    };
    let bytes: Vec<u8> = image
        .data
        .iter()
        .map(|&v| color::linear_to_srgb8(v * factor))
        .collect();
    let buffer = image::RgbImage::from_raw(image.width as u32, image.height as u32, bytes)
        .ok_or_else(|| Error::invalid("image buffer has the wrong size"))?;
    write_atomically(path, |w| {
        buffer.write_to(w, format).map_err(|e| {
            Error::new(
                ErrorKind::Image,
                format!("cannot encode {}", path.display()),
            )
            .with_source(e)
        })
    })
}

/// Write 8-bit RGB bytes as PNG (used for pictures such as contact sheets).
pub fn save_srgb8_png(path: &Path, width: usize, height: usize, bytes: Vec<u8>) -> Result<()> {
    let buffer = image::RgbImage::from_raw(width as u32, height as u32, bytes)
        .ok_or_else(|| Error::invalid("image buffer has the wrong size"))?;
    write_atomically(path, |w| {
        buffer.write_to(w, image::ImageFormat::Png).map_err(|e| {
            Error::new(
                ErrorKind::Image,
                format!("cannot encode {}", path.display()),
            )
            .with_source(e)
        })
    })
}

/// Write a 16-bit PNG of linear values (no transfer curve), e.g. for test captures.
pub fn save_png16_linear(path: &Path, image: &ImageRgb) -> Result<()> {
    let samples: Vec<u16> = image
        .data
        .iter()
        .map(|&v| (v.clamp(0.0, 1.0) * 65535.0 + 0.5) as u16)
        .collect();
    let buffer = image::ImageBuffer::<image::Rgb<u16>, Vec<u16>>::from_raw(
        image.width as u32,
        image.height as u32,
        samples,
    )
    .ok_or_else(|| Error::invalid("image buffer has the wrong size"))?;
    write_atomically(path, |w| {
        buffer.write_to(w, image::ImageFormat::Png).map_err(|e| {
            Error::new(
                ErrorKind::Image,
                format!("cannot encode {}", path.display()),
            )
            .with_source(e)
        })
    })
}

/// Tile `frames` (all of one size) into a grid `columns` wide, each shrunk by an integer
/// box filter so the sheet is at most `max_width` pixels wide, with a 2-pixel dark gutter.
pub fn contact_sheet(frames: &[ImageRgb], columns: usize, max_width: usize) -> ImageRgb {
    const GUTTER: usize = 2;
    if frames.is_empty() {
        return ImageRgb::new(0, 0);
    }
    let columns = columns.clamp(1, frames.len());
    let (fw, fh) = (frames[0].width, frames[0].height);
    let factor = ((fw * columns) as f64 / max_width.max(1) as f64)
        .ceil()
        .max(1.0) as usize;
    let (tw, th) = ((fw / factor).max(1), (fh / factor).max(1));
    let rows = frames.len().div_ceil(columns);
    let mut sheet = ImageRgb::new(
        columns * (tw + GUTTER) + GUTTER,
        rows * (th + GUTTER) + GUTTER,
    );
    sheet.data.iter_mut().for_each(|v| *v = 0.01);
    for (n, frame) in frames.iter().enumerate() {
        let (ox, oy) = (
            GUTTER + (n % columns) * (tw + GUTTER),
            GUTTER + (n / columns) * (th + GUTTER),
        );
        for y in 0..th {
            for x in 0..tw {
                let mut sum = [0f32; 3];
                for sy in 0..factor {
                    for sx in 0..factor {
                        let px =
                            frame.get((x * factor + sx).min(fw - 1), (y * factor + sy).min(fh - 1));
                        (0..3).for_each(|c| sum[c] += px[c]);
                    }
                }
                let o = 3 * ((oy + y) * sheet.width + ox + x);
                let norm = 1.0 / (factor * factor) as f32;
                (0..3).for_each(|c| sheet.data[o + c] = sum[c] * norm);
            }
        }
    }
    sheet
}

/// OpenEXR images: frames, depth and masks (relightable files are the codec's).
mod openexr {
    use super::ImageRgb;
    use crate::fsutil::write_atomically;
    use crate::{Error, ErrorKind, Result};
    use ::exr::prelude::*;
    use std::path::Path;

    fn exr_error(path: &Path, action: &str, e: ::exr::error::Error) -> Error {
        Error::new(
            ErrorKind::Io,
            format!("cannot {action} {}: {e}", path.display()),
        )
    }

    fn read_all_data(path: &Path) -> Result<Image<Layers<AnyChannels<FlatSamples>>>> {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_file(path)
            .map_err(|e| exr_error(path, "read", e))
    }

    /// Write a linear RGB image times `factor` as half-float EXR (relit frames), scaled
    /// while encoding.
    pub(super) fn write_rgb_scaled(path: &Path, image: &ImageRgb, factor: f32) -> Result<()> {
        let (w, h) = (image.width, image.height);
        let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
            let i = 3 * (pos.y() * w + pos.x());
            (
                f16::from_f32(image.data[i] * factor),
                f16::from_f32(image.data[i + 1] * factor),
                f16::from_f32(image.data[i + 2] * factor),
            )
        });
        let encoding = Encoding {
            compression: Compression::ZIP16,
            ..Encoding::default()
        };
        let layer = Layer::new((w, h), LayerAttributes::default(), encoding, channels);
        let img = Image::from_layer(layer);
        write_atomically(path, |out| {
            img.write()
                .to_buffered(out)
                .map_err(|e| exr_error(path, "write", e))
        })
    }

    /// Read a single-valued plane (depth or mask) from the first of the channels `Z`, `Y`,
    /// `R`, `A` that the file has.
    pub(super) fn read_scalar_channel(path: &Path) -> Result<(usize, usize, Vec<f32>)> {
        let image = read_all_data(path)?;
        let layer = image.layer_data.into_iter().next().ok_or_else(|| {
            Error::parse(format!("{}: the EXR file has no layer", path.display()))
        })?;
        let (w, h) = (layer.size.width(), layer.size.height());
        for wanted in ["Z", "Y", "R", "A"] {
            if let Some(ch) = layer
                .channel_data
                .list
                .iter()
                .find(|c| c.name.to_string() == wanted)
            {
                return Ok((w, h, ch.sample_data.values_as_f32().collect()));
            }
        }
        Err(Error::parse(format!(
            "{}: no Z, Y, R or A channel",
            path.display()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png8_round_trip_is_exact_in_srgb() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = ImageRgb::new(7, 5);
        for (i, v) in img.data.iter_mut().enumerate() {
            *v = color::srgb8_table()[(i * 37) % 256];
        }
        let path = dir.path().join("a.png");
        save(&path, &img, 0.0).unwrap();
        assert_eq!(dimensions(&path).unwrap(), (7, 5));
        let back = load_linear(&path, None).unwrap();
        assert_eq!(back, img);
    }

    #[test]
    fn png16_linear_and_exr_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = ImageRgb::new(4, 3);
        for (i, v) in img.data.iter_mut().enumerate() {
            *v = i as f32 / 40.0;
        }
        let p16 = dir.path().join("a.png");
        save_png16_linear(&p16, &img).unwrap();
        let back = load_linear(&p16, Some(Encoding::Linear)).unwrap();
        for (a, b) in back.data.iter().zip(&img.data) {
            assert!((a - b).abs() < 1e-4);
        }
        let pexr = dir.path().join("a.exr");
        save(&pexr, &img, 1.0).unwrap();
        let back = load_linear(&pexr, None).unwrap();
        for (a, b) in back.data.iter().zip(&img.data) {
            assert!((a - 2.0 * b).abs() < 2e-3 * b.max(1.0), "{a} vs {b}");
        }
    }

    /// A coloured test image with detail everywhere, so that every row of its JPEG
    /// takes bytes.
    fn textured(width: usize, height: usize) -> ImageRgb {
        let mut img = ImageRgb::new(width, height);
        for y in 0..height {
            for x in 0..width {
                let code = |k: usize| (x * 7 + y * 13 + k * 50 + (x * y) % 31) % 256;
                for c in 0..3 {
                    img.data[3 * (y * width + x) + c] = color::srgb8_table()[code(c)];
                }
            }
        }
        img
    }

    #[test]
    fn jpeg_rows_and_pixels_are_those_of_the_whole_image() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.jpg");
        let (w, h) = (37, 29);
        save(&path, &textured(w, h), 0.0).unwrap();
        for encoding in [None, Some(Encoding::Linear)] {
            let whole = load_linear(&path, encoding).unwrap();
            assert_eq!((whole.width, whole.height), (w, h));
            let pixels = [40, 0, w * h - 1, 5, 3 * w + 2];
            let (pw, ph, band, picked) =
                load_linear_parts(&path, encoding, 7..19, &pixels).unwrap();
            assert_eq!((pw, ph), (w, h));
            assert_eq!(band, whole.data[3 * w * 7..3 * w * 19]);
            for (i, &p) in pixels.iter().enumerate() {
                assert_eq!(picked[3 * i..3 * i + 3], whole.data[3 * p..3 * p + 3]);
            }
            assert!(load_linear_parts(&path, encoding, 0..h + 1, &[]).is_err());
            assert!(load_linear_parts(&path, encoding, 0..1, &[w * h]).is_err());
        }
        // Linear codes are code / 255.
        let linear = load_linear(&path, Some(Encoding::Linear)).unwrap();
        let srgb = load_linear(&path, None).unwrap();
        for (l, s) in linear.data.iter().zip(&srgb.data) {
            assert_eq!(color::srgb8_table()[(l * 255.0).round() as usize], *s);
        }
    }

    #[test]
    fn jpeg_rows_below_skipped_rows_are_those_of_the_whole_image() {
        // Rows above a band are skipped (entropy-decoded only): the band's rows are
        // still bit for bit those of the whole image, at any start — inside or at the
        // edge of a row of blocks, with chroma at half and at full resolution (libjpeg
        // upsamples half-resolution chroma from the rows around, which skipping must
        // keep).
        use jpeg_encoder::{ColorType, Encoder, SamplingFactor};
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (53, 70);
        let rgb: Vec<u8> = textured(w, h).to_srgb8();
        for sampling in [SamplingFactor::R_4_2_0, SamplingFactor::R_4_4_4] {
            let path = dir.path().join(format!("{sampling:?}.jpg"));
            let mut encoder = Encoder::new_file(&path, 90).unwrap();
            encoder.set_sampling_factor(sampling);
            encoder
                .encode(&rgb, w as u16, h as u16, ColorType::Rgb)
                .unwrap();
            let whole = load_linear(&path, None).unwrap();
            for start in [1, 7, 8, 9, 15, 16, 17, 31, 37, 69] {
                let (_, _, band, _) = load_linear_parts(&path, None, start..h, &[]).unwrap();
                let want = &whole.data[3 * w * start..];
                assert!(band == want, "{sampling:?} from row {start}");
                // A pixel below the band's first row does not move its start.
                let (_, _, band, picked) =
                    load_linear_parts(&path, None, start..h.min(start + 5), &[w * (h - 1)])
                        .unwrap();
                assert_eq!(band, whole.data[3 * w * start..3 * w * h.min(start + 5)]);
                assert_eq!(picked, whole.data[3 * w * (h - 1)..3 * w * (h - 1) + 3]);
            }
        }
        // A file cut short is an error from a skipped start too.
        let path = dir.path().join("cut.jpg");
        save(&path, &textured(64, 256), 0.0).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() * 3 / 5]).unwrap();
        let err = load_linear_parts(&path, None, 100..256, &[]).unwrap_err();
        assert_eq!(err.kind(), ErrorKind::Image, "{err}");
    }

    #[test]
    fn jpeg_decodes_like_the_general_decoder() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.jpg");
        save(&path, &textured(64, 48), 0.0).unwrap();
        let ours = load_linear(&path, None).unwrap().to_srgb8();
        let theirs = image::open(&path).unwrap().to_rgb8().into_raw();
        assert_eq!(ours.len(), theirs.len());
        let worst = ours
            .iter()
            .zip(&theirs)
            .map(|(&a, &b)| (a as i32 - b as i32).abs())
            .max()
            .unwrap();
        // Two IDCTs and two chroma upsamplers: a few codes apart, never more.
        assert!(worst <= 4, "differs by {worst} codes");
    }

    #[test]
    fn a_truncated_jpeg_is_an_error_but_the_rows_above_the_cut_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.jpg");
        save(&path, &textured(64, 256), 0.0).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() * 3 / 5]).unwrap();
        let err = load_linear(&path, None).unwrap_err();
        assert_eq!(err.kind(), ErrorKind::Image, "{err}");
        assert!(load_linear_parts(&path, None, 0..200, &[]).is_err());
        // The first rows are read without decoding the missing ones below them.
        let (_, _, band, _) = load_linear_parts(&path, None, 0..8, &[64 * 3 + 1]).unwrap();
        assert_eq!(band.len(), 3 * 64 * 8);
    }

    #[test]
    fn grey_and_cmyk_jpegs_read_as_rgb() {
        let dir = tempfile::tempdir().unwrap();
        let grey = dir.path().join("grey.jpg");
        image::GrayImage::from_fn(20, 10, |x, y| image::Luma([(x * 10 + y) as u8]))
            .save(&grey)
            .unwrap();
        let img = load_linear(&grey, None).unwrap();
        assert_eq!((img.width, img.height), (20, 10));
        assert!(img.data.chunks(3).all(|p| p[0] == p[1] && p[1] == p[2]));
        let (_, _, band, _) = load_linear_parts(&grey, None, 2..4, &[]).unwrap();
        assert_eq!(band, img.data[3 * 20 * 2..3 * 20 * 4]);
        // libjpeg does not convert CMYK: the general decoder does, through the same calls.
        let cmyk = dir.path().join("cmyk.jpg");
        let samples: Vec<u8> = (0..16 * 8 * 4).map(|i| (i * 3 % 256) as u8).collect();
        jpeg_encoder::Encoder::new_file(&cmyk, 90)
            .unwrap()
            .encode(&samples, 16, 8, jpeg_encoder::ColorType::Cmyk)
            .unwrap();
        let img = load_linear(&cmyk, None).unwrap();
        let (_, _, band, _) = load_linear_parts(&cmyk, None, 1..3, &[]).unwrap();
        assert_eq!(band, img.data[3 * 16..3 * 16 * 3]);
    }

    #[test]
    fn unknown_extension_and_garbage_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        assert!(save(&dir.path().join("x.what"), &ImageRgb::new(1, 1), 0.0).is_err());
        let bad = dir.path().join("bad.jpg");
        std::fs::write(&bad, b"not a jpeg at all").unwrap();
        assert!(load_linear(&bad, None).is_err());
    }
}
