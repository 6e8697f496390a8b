//! Captures: the reference images of a scene, each lit by one directional light.
//!
//! A [`Capture`] lists, per image, where its samples come from, the light vector
//! (unit, toward the light, in the light frame of the [conventions](crate)) and the
//! light's RGB intensity, which is divided out when the image is loaded. Captures
//! come from RTI `.lp` files ([`lp`]), from relit's JSON manifest ([`manifest`]), or
//! from memory (the built-in renderers).

pub mod lp;
pub mod manifest;

use crate::camera::{CameraSpec, Projection};
use crate::color::Encoding;
use crate::image::{self, ImageRgb};
use crate::sphere::Vec3;
use crate::{Error, ErrorKind, Result};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where one reference image's samples come from.
#[derive(Clone, Debug)]
pub enum ImageSource {
    /// A file, decoded on demand; `encoding` overrides the format's default.
    File {
        path: PathBuf,
        encoding: Option<Encoding>,
    },
    /// A linear image already in memory.
    Memory(Arc<ImageRgb>),
    /// A linear image made on demand (a renderer), so that a capture of hundreds of
    /// images streams through the fit like files do instead of sitting in memory.
    Generated(Arc<dyn ImageGenerator>),
}

/// Something that produces one reference image on request (a renderer under one light).
pub trait ImageGenerator: Send + Sync + std::fmt::Debug {
    /// Produce the linear image.
    fn generate(&self) -> Result<ImageRgb>;
}

/// One reference image and the light it was taken under.
#[derive(Clone, Debug)]
pub struct CapturedLight {
    pub image: ImageSource,
    /// Unit light vector, toward the light.
    pub direction: Vec3,
    /// RGB intensity of the light (divided out on loading).
    pub intensity: [f32; 3],
}

/// A set of reference images from one fixed viewpoint.
#[derive(Clone, Debug)]
pub struct Capture {
    pub lights: Vec<CapturedLight>,
    pub width: usize,
    pub height: usize,
    pub projection: Projection,
    /// The full camera (pose included) when known; lights with a position need it.
    pub camera: Option<CameraSpec>,
    /// Depth per pixel (distance along the view ray), if known.
    pub depth: Option<Arc<Vec<f32>>>,
    /// Mask per pixel (> 0.5 inside), if known; evaluation restricts linear PSNR to it.
    pub mask: Option<Arc<Vec<f32>>>,
    /// Where the capture was read from, for messages.
    pub origin: String,
    /// The files it was read from besides its images: the `.lp` or manifest, and the
    /// depth and mask the manifest names (empty for captures made in memory).
    pub source_files: Vec<PathBuf>,
}

impl Capture {
    /// Whether every image holds linear radiance (floating-point files, files declared
    /// linear, images rendered or held in memory) rather than display-encoded values
    /// (8- and 16-bit photographs): what the basis choice judges its error in.
    pub fn radiance_images(&self) -> bool {
        self.lights.iter().all(|l| match &l.image {
            ImageSource::File { path, encoding } => {
                *encoding == Some(Encoding::Linear) || image::is_float_format(path)
            }
            ImageSource::Memory(_) | ImageSource::Generated(_) => true,
        })
    }

    /// Read a capture from an RTI `.lp` file or a relit JSON manifest (`.json`).
    ///
    /// Every image is checked to exist and to share one size before this returns, so a
    /// bad capture fails before any work is done.
    pub fn open(path: &Path) -> Result<Capture> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("json") => manifest::read(path),
            _ => lp::read(path),
        }
    }

    /// A capture from images in memory (linear, unit intensity).
    pub fn from_memory(
        images: Vec<ImageRgb>,
        directions: &[Vec3],
        projection: Projection,
    ) -> Result<Capture> {
        if images.is_empty() || images.len() != directions.len() {
            return Err(Error::invalid(
                "a capture needs one direction per image and at least one image",
            ));
        }
        let (width, height) = (images[0].width, images[0].height);
        let mut lights = Vec::with_capacity(images.len());
        for (i, (img, d)) in images.into_iter().zip(directions).enumerate() {
            if (img.width, img.height) != (width, height) {
                return Err(Error::invalid(format!(
                    "image {i} is {}×{} but image 0 is {width}×{height}",
                    img.width, img.height
                )));
            }
            let direction = d
                .normalized()
                .ok_or_else(|| Error::invalid(format!("light {i} has no direction")))?;
            lights.push(CapturedLight {
                image: ImageSource::Memory(Arc::new(img)),
                direction,
                intensity: [1.0; 3],
            });
        }
        Ok(Capture {
            lights,
            width,
            height,
            projection,
            camera: None,
            depth: None,
            mask: None,
            origin: "memory".into(),
            source_files: Vec::new(),
        })
    }

    /// A capture whose images are produced on demand by `generators` (linear, unit
    /// intensity), all of `width×height`.
    pub fn from_generators(
        generators: Vec<Arc<dyn ImageGenerator>>,
        directions: &[Vec3],
        width: usize,
        height: usize,
        projection: Projection,
    ) -> Result<Capture> {
        if generators.is_empty() || generators.len() != directions.len() {
            return Err(Error::invalid(
                "a capture needs one direction per image and at least one image",
            ));
        }
        let lights = generators
            .into_iter()
            .zip(directions)
            .enumerate()
            .map(|(i, (g, d))| {
                let direction = d
                    .normalized()
                    .ok_or_else(|| Error::invalid(format!("light {i} has no direction")))?;
                Ok(CapturedLight {
                    image: ImageSource::Generated(g),
                    direction,
                    intensity: [1.0; 3],
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Capture {
            lights,
            width,
            height,
            projection,
            camera: None,
            depth: None,
            mask: None,
            origin: "generated".into(),
            source_files: Vec::new(),
        })
    }

    /// The number of reference images.
    pub fn len(&self) -> usize {
        self.lights.len()
    }

    /// Whether the capture has no images.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Every file the capture reads: [`Capture::source_files`] and the image files.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let images = self.lights.iter().filter_map(|l| match &l.image {
            ImageSource::File { path, .. } => Some(path.clone()),
            ImageSource::Memory(_) | ImageSource::Generated(_) => None,
        });
        self.source_files.iter().cloned().chain(images).collect()
    }

    /// The light vectors in capture order.
    pub fn directions(&self) -> Vec<Vec3> {
        self.lights.iter().map(|l| l.direction).collect()
    }

    /// A short name for image `index` (its file name, or its number).
    pub fn image_name(&self, index: usize) -> String {
        match &self.lights[index].image {
            ImageSource::File { path, .. } => path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| path.display().to_string()),
            ImageSource::Memory(_) | ImageSource::Generated(_) => format!("#{index}"),
        }
    }

    /// Image `index` in linear RGB with its light intensity divided out.
    pub fn load(&self, index: usize) -> Result<ImageRgb> {
        let light = &self.lights[index];
        let mut img = self.load_raw(index)?;
        if light.intensity != [1.0; 3] {
            let inv = light.intensity.map(|v| 1.0 / v);
            for px in img.data.chunks_exact_mut(3) {
                px[0] *= inv[0];
                px[1] *= inv[1];
                px[2] *= inv[2];
            }
        }
        Ok(img)
    }

    /// Parts of image `index` as [`Capture::load`] gives them: rows `rows` and the
    /// pixels `pixels` (see [`image::load_linear_parts`]: a file's samples outside them
    /// are never converted to floats).
    pub fn load_parts(
        &self,
        index: usize,
        rows: std::ops::Range<usize>,
        pixels: &[usize],
        then: Option<fn(f32) -> f32>,
    ) -> Result<(Vec<f32>, Vec<f32>)> {
        let mut band = Vec::new();
        let picked = self.read_parts(index, rows.clone(), pixels, then, &mut |_, row| {
            if band.is_empty() {
                band.reserve_exact(row.len() * rows.len());
            }
            band.extend_from_slice(row);
            Ok(())
        })?;
        Ok((band, picked))
    }

    /// The error of image `index` being `size` (e.g. `640×480`), not the capture's size.
    fn wrong_size(&self, index: usize, size: String) -> Error {
        Error::new(
            ErrorKind::InvalidInput,
            format!(
                "{} is {size} but the capture is {}×{}",
                self.image_name(index),
                self.width,
                self.height
            ),
        )
    }

    /// Whether every image is a JPEG file, whose samples [`Capture::read_code_parts`]
    /// can hand over as 8-bit codes.
    pub fn eight_bit_codes(&self) -> bool {
        self.lights.iter().all(|l| match &l.image {
            ImageSource::File { path, .. } => image::is_jpeg_file(path),
            ImageSource::Memory(_) | ImageSource::Generated(_) => false,
        })
    }

    /// [`Capture::read_parts`] of a capture of [`Capture::eight_bit_codes`], without
    /// the conversion: rows and pixels as the file's 8-bit RGB codes. Image `index`'s
    /// code `c` of channel `ch` stands for `code_values(index, then)[256·ch + c]`, the
    /// value [`Capture::read_parts`] gives for it, bit for bit.
    pub fn read_code_parts(
        &self,
        index: usize,
        rows: std::ops::Range<usize>,
        pixels: &[usize],
        row: &mut dyn FnMut(usize, &[u8]) -> Result<()>,
    ) -> Result<Vec<u8>> {
        let ImageSource::File { path, .. } = &self.lights[index].image else {
            return Err(Error::invalid(format!(
                "{} is not a file, whose codes could be read",
                self.image_name(index)
            )));
        };
        let w = self.width;
        let wrong_size = |size: String| self.wrong_size(index, size);
        let (fw, fh, picked) = image::read_code_parts(path, rows, pixels, &mut |y, codes| {
            if codes.len() != 3 * w {
                return Err(wrong_size(format!("{} pixels wide", codes.len() / 3)));
            }
            row(y, codes)
        })?;
        if (fw, fh) != (self.width, self.height) {
            return Err(wrong_size(format!("{fw}×{fh}")));
        }
        Ok(picked)
    }

    /// What each 8-bit code of image `index` stands for, per channel (`256·channel +
    /// code`): the value [`Capture::read_parts`] gives for it with `then`, the light's
    /// intensity divided out, computed as it computes it.
    pub fn code_values(&self, index: usize, then: Option<fn(f32) -> f32>) -> Vec<f32> {
        let light = &self.lights[index];
        let encoding = match &light.image {
            ImageSource::File { encoding, .. } => *encoding,
            ImageSource::Memory(_) | ImageSource::Generated(_) => None,
        };
        let table = image::eight_bit_values(encoding);
        let inv = light.intensity.map(|v| 1.0 / v);
        let unit = light.intensity == [1.0; 3];
        (0..3)
            .flat_map(|c| {
                table.iter().map(move |&v| {
                    let v = if unit { v } else { v * inv[c] };
                    then.map_or(v, |f| f(v))
                })
            })
            .collect()
    }

    /// Parts of image `index` as [`Capture::load`] gives them, the rows handed over one
    /// at a time: `row(y, values)` gets each row of `rows` in order (`3·width` values,
    /// the caller may change them), and the pixels `pixels` are returned (3 values each,
    /// in the order asked). A JPEG photograph is decoded a few rows at a time, down to
    /// the last row wanted ([`image::read_linear_parts`]), so a caller that keeps no row
    /// holds a few rows of the image, whatever its size.
    ///
    /// `then`, where given, maps every value after the intensity is divided out (see
    /// [`image::read_linear_parts`]: free for 8-bit files of lights of unit intensity).
    pub fn read_parts(
        &self,
        index: usize,
        rows: std::ops::Range<usize>,
        pixels: &[usize],
        then: Option<fn(f32) -> f32>,
        row: &mut dyn FnMut(usize, &mut [f32]) -> Result<()>,
    ) -> Result<Vec<f32>> {
        let light = &self.lights[index];
        let inv = light.intensity.map(|v| 1.0 / v);
        let unit = light.intensity == [1.0; 3];
        // The intensity divided out, then `after` (where given) applied.
        let finish = |values: &mut [f32], after: Option<fn(f32) -> f32>| {
            if !unit {
                for px in values.chunks_exact_mut(3) {
                    px[0] *= inv[0];
                    px[1] *= inv[1];
                    px[2] *= inv[2];
                }
            }
            if let Some(f) = after {
                values.iter_mut().for_each(|v| *v = f(*v));
            }
        };
        let wrong_size = |size: String| self.wrong_size(index, size);
        let w = self.width;
        match &light.image {
            ImageSource::File { path, encoding } => {
                // The decoder applies `then` itself where nothing is divided out first.
                let (by_decoder, after) = if unit { (then, None) } else { (None, then) };
                let (fw, fh, mut picked) = image::read_linear_parts(
                    path,
                    *encoding,
                    by_decoder,
                    rows.clone(),
                    pixels,
                    &mut |y, values| {
                        // A file of another width shows at its first row; its height
                        // once it is read.
                        if values.len() != 3 * w {
                            return Err(wrong_size(format!("{} pixels wide", values.len() / 3)));
                        }
                        finish(values, after);
                        row(y, values)
                    },
                )?;
                if (fw, fh) != (self.width, self.height) {
                    return Err(wrong_size(format!("{fw}×{fh}")));
                }
                finish(&mut picked, after);
                Ok(picked)
            }
            ImageSource::Memory(_) | ImageSource::Generated(_) => {
                let img = self.load_raw(index)?;
                for y in rows {
                    let mut values = img.data[3 * w * y..3 * w * (y + 1)].to_vec();
                    finish(&mut values, then);
                    row(y, &mut values)?;
                }
                let mut picked: Vec<f32> = pixels
                    .iter()
                    .flat_map(|&p| img.data[3 * p..3 * p + 3].iter().copied())
                    .collect();
                finish(&mut picked, then);
                Ok(picked)
            }
        }
    }

    /// Image `index` in linear RGB as recorded (intensity not divided out).
    pub fn load_raw(&self, index: usize) -> Result<ImageRgb> {
        let img = match &self.lights[index].image {
            ImageSource::File { path, encoding } => image::load_linear(path, *encoding)?,
            ImageSource::Memory(img) => (**img).clone(),
            ImageSource::Generated(g) => g.generate()?,
        };
        if (img.width, img.height) != (self.width, self.height) {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!(
                    "{} is {}×{} but the capture is {}×{}",
                    self.image_name(index),
                    img.width,
                    img.height,
                    self.width,
                    self.height
                ),
            ));
        }
        Ok(img)
    }

    /// The pixels `pixels` of image `index` as [`Capture::load_raw`] gives them (3 values
    /// each, in the order asked), a JPEG photograph decoded a few rows at a time down to
    /// the last row wanted: a sample of a large image without holding the image.
    pub fn raw_pixels(&self, index: usize, pixels: &[usize]) -> Result<Vec<f32>> {
        let wrong_size = |size: String| self.wrong_size(index, size);
        match &self.lights[index].image {
            ImageSource::File { path, encoding } => {
                let (fw, fh, _, picked) = image::load_linear_parts(path, *encoding, 0..0, pixels)?;
                if (fw, fh) != (self.width, self.height) {
                    return Err(wrong_size(format!("{fw}×{fh}")));
                }
                Ok(picked)
            }
            ImageSource::Memory(_) | ImageSource::Generated(_) => {
                let img = self.load_raw(index)?;
                if let Some(&p) = pixels.iter().find(|&&p| p >= img.width * img.height) {
                    return Err(Error::invalid(format!(
                        "pixel {p} lies outside {}",
                        self.image_name(index)
                    )));
                }
                Ok(pixels
                    .iter()
                    .flat_map(|&p| img.data[3 * p..3 * p + 3].iter().copied())
                    .collect())
            }
        }
    }

    /// The capture restricted to the images at `keep` (in that order).
    pub fn subset(&self, keep: &[usize]) -> Capture {
        let mut sub = self.clone();
        sub.lights = keep.iter().map(|&i| self.lights[i].clone()).collect();
        sub
    }
}

/// Check that every file of `lights` exists and has the size of the first; returns it.
/// `line_of` names where each image was declared, for messages.
pub(crate) fn check_images(
    lights: &[CapturedLight],
    line_of: &dyn Fn(usize) -> String,
) -> Result<(usize, usize)> {
    let mut size = None;
    for (i, light) in lights.iter().enumerate() {
        let ImageSource::File { path, .. } = &light.image else {
            continue;
        };
        if !path.is_file() {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!("{}: image {} not found", line_of(i), path.display()),
            ));
        }
        let dims = image::dimensions(path).map_err(|e| {
            Error::new(
                ErrorKind::Image,
                format!("{}: cannot read the size of {}", line_of(i), path.display()),
            )
            .with_source(e)
        })?;
        match size {
            None => size = Some((dims, i)),
            Some(((w, h), first)) if (w, h) != dims => {
                return Err(Error::new(
                    ErrorKind::InvalidInput,
                    format!(
                        "{}: {} is {}×{} but {} ({}) is {w}×{h}; all images of a capture must share one size",
                        line_of(i),
                        path.display(),
                        dims.0,
                        dims.1,
                        match &lights[first].image {
                            ImageSource::File { path, .. } => path.display().to_string(),
                            _ => "the first image".into(),
                        },
                        line_of(first)
                    ),
                ))
            }
            Some(_) => {}
        }
    }
    size.map(|(d, _)| d)
        .ok_or_else(|| Error::invalid("the capture lists no images"))
}

/// Resolve an image name from a capture file relative to the file's folder. Names
/// written on another machine (absolute Windows paths, say) fall back to their last
/// component when the full path does not exist here.
pub(crate) fn resolve_image_path(folder: &Path, name: &str) -> PathBuf {
    let direct = folder.join(name);
    if direct.exists() {
        return direct;
    }
    let last = name.rsplit(['/', '\\']).next().unwrap_or(name);
    let fallback = folder.join(last);
    if fallback.exists() {
        fallback
    } else {
        direct
    }
}
