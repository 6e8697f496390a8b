//! In-memory linear RGB images and their file formats.
//!
//! Decoding: JPEG, PNG (8/16-bit), TIFF, OpenEXR and Radiance HDR. Integer samples are
//! sRGB-decoded to linear unless declared linear; float samples are linear already.
//! Encoding: 8-bit sRGB PNG/JPEG/TIFF, or linear OpenEXR (by the file extension).

use crate::color::{self, Encoding};
use crate::fsutil::write_atomically;
use crate::{Error, ErrorKind, Result};
use image::{DynamicImage, ImageReader};
use std::path::Path;

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
    limits.max_alloc = Some(4 << 30);
    reader.limits(limits);
    Ok(reader)
}

/// Decode an image file to linear RGB.
///
/// `encoding` overrides how integer samples are interpreted; by default 8/16-bit
/// samples are sRGB and float samples linear (see the [conventions](crate)).
pub fn load_linear(path: &Path, encoding: Option<Encoding>) -> Result<ImageRgb> {
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
/// image's size. Only those samples are converted to `f32`: the decoded image stays in
/// its own type (3 bytes a pixel for 8-bit files instead of 12), so a fit reading a band
/// of a big image holds the band, not the whole image, in floats.
pub fn load_linear_parts(
    path: &Path,
    encoding: Option<Encoding>,
    rows: std::ops::Range<usize>,
    pixels: &[usize],
) -> Result<(usize, usize, Vec<f32>, Vec<f32>)> {
    let decoded = decode(path)?;
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    if rows.end > height || pixels.iter().any(|&p| p >= width * height) {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            format!(
                "{}: {width}×{height} has no rows {rows:?} or pixels that far",
                path.display()
            ),
        ));
    }
    let band = linear_samples(
        &decoded,
        path,
        encoding,
        3 * width * rows.start..3 * width * rows.end,
    );
    let picked = linear_samples(
        &decoded,
        path,
        encoding,
        pixels.iter().flat_map(|&p| 3 * p..3 * p + 3),
    );
    Ok((width, height, band, picked))
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

    #[test]
    fn unknown_extension_and_garbage_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        assert!(save(&dir.path().join("x.what"), &ImageRgb::new(1, 1), 0.0).is_err());
        let bad = dir.path().join("bad.jpg");
        std::fs::write(&bad, b"not a jpeg at all").unwrap();
        assert!(load_linear(&bad, None).is_err());
    }
}
