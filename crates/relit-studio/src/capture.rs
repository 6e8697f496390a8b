//! Captures: a scene rendered under every light of a plan, in memory or into a folder.
//!
//! The viewpoint is fixed, so the G-buffer is traced once ([`Renderer::new`]) and each
//! light costs only its shadow rays. A folder capture holds:
//!
//! | file            | content                                                          |
//! |-----------------|------------------------------------------------------------------|
//! | `light_NNNN.exr`| the image under light NNNN (half-float linear EXR), or `.png`     |
//! |                 | (16-bit, linear, values clipped to [0, 1]) with `--format png16`  |
//! | `capture.json`  | the relit manifest (light directions, projection, depth, mask)    |
//! | `capture.lp`    | the same directions as an RTI `.lp` file                          |
//! | `depth.exr`     | depth along each view ray, 32-bit float channel `Z`; 0 = no hit   |
//! | `mask.png`      | 8-bit grey: 255 (1.0) where geometry was hit, 0 elsewhere         |
//! | `camera.json`   | the full camera, pose included ([`relit::camera::CameraSpec`])    |
//!
//! The files appear only when the capture is complete ([`relit::fsutil::StagedFolder`]):
//! a new folder in one rename, an existing one file by file with the manifest last, so
//! a folder with a manifest holds a whole capture and a failed capture adds nothing.

use crate::render::{RenderOptions, Renderer};
use crate::scene::Scene;
use crate::{invalid, Result};
use relit::camera::{Camera, CameraSpec};
use relit::capture::manifest::{Intensity, Manifest, ManifestImage};
use relit::capture::Capture;
use relit::color::Encoding;
use relit::fsutil::{
    check_outputs, write_atomically, write_bytes_atomically, Output, StagedFolder,
};
use relit::image::ImageRgb;
use relit::progress::Progress;
use relit::sphere::Vec3;
use relit::{Error, ErrorKind};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// The file format of the reference images of a folder capture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImageFormat {
    /// Half-float linear OpenEXR (keeps highlights above 1).
    #[default]
    Exr,
    /// 16-bit PNG holding linear values (clipped to [0, 1]); the manifest says `linear`.
    Png16,
}

impl ImageFormat {
    fn extension(self) -> &'static str {
        match self {
            ImageFormat::Exr => "exr",
            ImageFormat::Png16 => "png",
        }
    }
}

/// What a capture cost.
#[derive(Clone, Debug, Serialize)]
pub struct CaptureStats {
    pub scene: String,
    pub triangles: usize,
    pub lights: usize,
    pub width: usize,
    pub height: usize,
    /// Primary (and bounce) rays of the G-buffer.
    pub primary_rays: u64,
    /// Shadow rays of all lights.
    pub shadow_rays: u64,
    pub gbuffer_seconds: f64,
    /// Seconds spent lighting (shadow rays and shading), writing excluded.
    pub lighting_seconds: f64,
    pub total_seconds: f64,
    /// All rays over the time spent tracing them (G-buffer plus lighting).
    pub rays_per_second: f64,
}

/// A capture held in memory, ready for [`relit::fit::fit`].
#[derive(Clone, Debug)]
pub struct InMemoryCapture {
    /// Images, directions, projection, depth and mask.
    pub capture: Capture,
    /// The camera, pose included (depth → positions for non-directional lights).
    pub camera: Camera,
    pub stats: CaptureStats,
}

/// A capture written to a folder.
#[derive(Clone, Debug)]
pub struct FolderCapture {
    /// The manifest, to open with [`relit::capture::Capture::open`].
    pub manifest: PathBuf,
    pub stats: CaptureStats,
}

/// Render `scene` from `camera` under a unit white directional light toward each of
/// `directions`, keeping the images in memory.
pub fn capture_in_memory(
    scene: &Scene,
    camera: &Camera,
    directions: &[Vec3],
    options: &RenderOptions,
    progress: &dyn Progress,
) -> Result<InMemoryCapture> {
    let mut images = Vec::with_capacity(directions.len());
    let (renderer, stats) = run(
        scene,
        camera,
        directions,
        options,
        progress,
        &mut |_, image| {
            images.push(image);
            Ok(())
        },
    )?;
    let mut capture = Capture::from_memory(images, directions, camera.projection())?;
    capture.depth = Some(Arc::new(renderer.depth().to_vec()));
    capture.mask = Some(Arc::new(renderer.mask().to_vec()));
    capture.origin = format!("studio scene `{}`", scene.name);
    Ok(InMemoryCapture {
        capture,
        camera: camera.clone(),
        stats,
    })
}

/// Render as [`capture_in_memory`] but write each image for `folder` as it is done
/// (see the module docs for the files). The folder is created if needed; its files
/// appear when the capture is complete, and not at all when it fails. A folder that
/// holds one of the scene's files is refused.
pub fn capture_to_folder(
    scene: &Scene,
    camera: &Camera,
    directions: &[Vec3],
    options: &RenderOptions,
    folder: &Path,
    format: ImageFormat,
    progress: &dyn Progress,
) -> Result<FolderCapture> {
    if directions.is_empty() {
        return Err(invalid("a capture needs at least one light"));
    }
    check_outputs(&scene.files, &[Output::folder(folder)])?;
    let staged = StagedFolder::new(folder)?;
    let digits = directions.len().saturating_sub(1).to_string().len().max(4);
    let name = |i: usize| format!("light_{i:0digits$}.{}", format.extension());
    let write_image = |i: usize, image: &ImageRgb| -> Result<()> {
        let path = staged.file(name(i))?;
        match format {
            ImageFormat::Exr => relit::image::save(&path, image, 0.0),
            ImageFormat::Png16 => relit::image::save_png16_linear(&path, image),
        }
    };
    // A writer thread encodes each image while the next one renders; the bounded queue
    // keeps at most two finished images waiting when encoding is the slower side.
    let (renderer, stats) = std::thread::scope(|scope| -> Result<_> {
        let (sender, receiver) = std::sync::mpsc::sync_channel::<(usize, ImageRgb)>(2);
        let writer = scope.spawn(move || -> Result<()> {
            for (i, image) in receiver {
                write_image(i, &image)?;
            }
            Ok(())
        });
        let rendered = run(
            scene,
            camera,
            directions,
            options,
            progress,
            &mut |i, image| {
                // A closed queue means the writer stopped on an error, reported below.
                sender
                    .send((i, image))
                    .map_err(|_| invalid("the image writer stopped"))
            },
        );
        drop(sender);
        let written = writer
            .join()
            .map_err(|_| invalid("the image writer panicked"))?;
        written?;
        rendered
    })?;
    let (w, h) = (camera.width(), camera.height());
    write_depth_exr(&staged.file("depth.exr")?, w, h, renderer.depth())?;
    let mask: Vec<u8> = renderer
        .mask()
        .iter()
        .map(|&m| if m > 0.5 { 255 } else { 0 })
        .collect();
    write_gray8_png(&staged.file("mask.png")?, w, h, mask)?;
    let spec = CameraSpec::from(camera);
    write_json(&staged.file("camera.json")?, &spec)?;
    let names: Vec<String> = (0..directions.len()).map(name).collect();
    write_bytes_atomically(
        &staged.file("capture.lp")?,
        relit::capture::lp::format(&names, directions).as_bytes(),
    )?;
    let manifest = Manifest {
        encoding: (format == ImageFormat::Png16).then_some(Encoding::Linear),
        projection: camera.projection(),
        camera: Some(spec.clone()),
        depth: Some("depth.exr".into()),
        mask: Some("mask.png".into()),
        images: names
            .iter()
            .zip(directions)
            .map(|(file, &direction)| ManifestImage {
                file: file.clone(),
                direction,
                intensity: Intensity::Gray(1.0),
            })
            .collect(),
    };
    write_json(&staged.file("capture.json")?, &manifest)?;
    staged.commit()?;
    Ok(FolderCapture {
        manifest: folder.join("capture.json"),
        stats,
    })
}

/// The shared loop: G-buffer, then one image per light handed to `sink` in order.
fn run<'s>(
    scene: &'s Scene,
    camera: &Camera,
    directions: &[Vec3],
    options: &RenderOptions,
    progress: &dyn Progress,
    sink: &mut dyn FnMut(usize, ImageRgb) -> Result<()>,
) -> Result<(Renderer<'s>, CaptureStats)> {
    if directions.is_empty() {
        return Err(invalid("a capture needs at least one light"));
    }
    let start = Instant::now();
    let renderer = Renderer::new(scene, camera, options, progress)?;
    let mut shadow_rays = 0u64;
    let mut lighting_seconds = 0.0;
    progress.begin("lights", directions.len() as u64);
    for (i, &direction) in directions.iter().enumerate() {
        let lit = Instant::now();
        let rendered = renderer
            .render_directional(direction)
            .map_err(|e| Error::new(ErrorKind::InvalidInput, format!("light {i}: {e}")))?;
        lighting_seconds += lit.elapsed().as_secs_f64();
        shadow_rays += rendered.rays;
        sink(i, rendered.image)?;
        progress.advance(1);
    }
    progress.end();
    let tracing = renderer.gbuffer_seconds() + lighting_seconds;
    let total_rays = renderer.primary_rays() + shadow_rays;
    let stats = CaptureStats {
        scene: scene.name.clone(),
        triangles: scene.triangle_count(),
        lights: directions.len(),
        width: camera.width(),
        height: camera.height(),
        primary_rays: renderer.primary_rays(),
        shadow_rays,
        gbuffer_seconds: renderer.gbuffer_seconds(),
        lighting_seconds,
        total_seconds: start.elapsed().as_secs_f64(),
        rays_per_second: total_rays as f64 / tracing.max(1e-9),
    };
    Ok((renderer, stats))
}

/// Write a depth map as a single 32-bit float channel `Z`.
pub fn write_depth_exr(path: &Path, width: usize, height: usize, depth: &[f32]) -> Result<()> {
    use exr::prelude::*;
    if depth.len() != width * height {
        return Err(invalid("the depth map does not match its size"));
    }
    let channel = AnyChannel::new("Z", FlatSamples::F32(depth.to_vec()));
    let encoding = Encoding {
        compression: Compression::ZIP16,
        ..Encoding::default()
    };
    let layer = Layer::new(
        (width, height),
        LayerAttributes::default(),
        encoding,
        AnyChannels::sort(vec![channel].into()),
    );
    let image = Image::from_layer(layer);
    write_atomically(path, |out| {
        image.write().to_buffered(out).map_err(|e| {
            relit::Error::new(
                ErrorKind::Io,
                format!("cannot write {}: {e}", path.display()),
            )
        })
    })
}

/// Write 8-bit grey bytes as PNG.
fn write_gray8_png(path: &Path, width: usize, height: usize, bytes: Vec<u8>) -> Result<()> {
    let buffer = image::GrayImage::from_raw(width as u32, height as u32, bytes)
        .ok_or_else(|| invalid("the mask does not match its size"))?;
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

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value).map_err(|e| {
        Error::new(
            ErrorKind::InvalidInput,
            format!("cannot serialise {}: {e}", path.display()),
        )
    })?;
    write_bytes_atomically(path, text.as_bytes())
}
