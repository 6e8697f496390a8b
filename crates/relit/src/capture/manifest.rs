//! relit's JSON capture manifest, for captures richer than an `.lp` file can say.
//!
//! ```json
//! {
//!   "encoding": "srgb",
//!   "projection": { "type": "cylindrical" },
//!   "depth": "depth.exr",
//!   "mask": "mask.png",
//!   "images": [
//!     { "file": "light000.png", "direction": [0.1, 0.2, 0.97], "intensity": [1.0, 0.9, 0.8] },
//!     { "file": "light001.png", "direction": [0.5, 0.0, 0.87], "intensity": 2.0 }
//!   ]
//! }
//! ```
//!
//! * `images` (required): per image its `file` (relative to the manifest's folder), its
//!   light `direction` (toward the light, light frame of the [conventions](crate); it is
//!   normalised) and optional `intensity`, one number or RGB (default 1), divided out.
//! * `encoding` (optional): `srgb` or `linear`, how 8/16-bit samples relate to radiance
//!   (default `srgb`); float formats (EXR, HDR) are always linear.
//! * `projection` (optional): `{"type": "planar", "fov_y_deg": 50}` (no field of view:
//!   orthographic), `{"type": "cylindrical"}` or `{"type": "equirectangular"}`.
//! * `camera` (optional): the full camera, `{"projection": {...}, "width": W, "height": H,
//!   "pose": {"eye": [x,y,z], "right": [..], "up": [..], "back": [..]}}` (see
//!   [`crate::camera::CameraSpec`]); lights with a position relight from it and the depth.
//! * `depth`, `mask` (optional): single-channel images of the capture's size. Depth is
//!   the distance from the eye along each pixel's view ray; the mask is > 0.5 inside.

use super::{check_images, resolve_image_path, Capture, CapturedLight, ImageSource};
use crate::camera::{CameraSpec, Projection};
use crate::color::Encoding;
use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// The manifest as stored.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoding: Option<Encoding>,
    #[serde(default)]
    pub projection: Projection,
    /// The full camera (pose included); its projection wins over `projection`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<String>,
    pub images: Vec<ManifestImage>,
}

/// One image of a manifest.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ManifestImage {
    pub file: String,
    pub direction: Vec3,
    #[serde(default, skip_serializing_if = "Intensity::is_unit")]
    pub intensity: Intensity,
}

/// A light's intensity: one number for white light or an RGB triple.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Intensity {
    Gray(f32),
    Rgb([f32; 3]),
}

impl Default for Intensity {
    fn default() -> Self {
        Intensity::Gray(1.0)
    }
}

impl Intensity {
    pub fn rgb(self) -> [f32; 3] {
        match self {
            Intensity::Gray(v) => [v; 3],
            Intensity::Rgb(c) => c,
        }
    }
    fn is_unit(&self) -> bool {
        self.rgb() == [1.0; 3]
    }
}

/// Read a manifest and check its images, depth and mask.
pub fn read(path: &Path) -> Result<Capture> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "read", e))?;
    let manifest: Manifest = serde_json::from_str(&text)
        .map_err(|e| Error::parse(format!("{origin}: line {}: {e}", e.line())))?;
    let folder = path.parent().unwrap_or(Path::new("."));
    let mut lights = Vec::with_capacity(manifest.images.len());
    let mut seen = std::collections::HashMap::new();
    for (i, entry) in manifest.images.iter().enumerate() {
        let direction = entry.direction.normalized().ok_or_else(|| {
            Error::parse(format!(
                "{origin}: images[{i}] (`{}`): the direction has no length or is not finite",
                entry.file
            ))
        })?;
        let intensity = entry.intensity.rgb();
        if intensity.iter().any(|v| !v.is_finite() || *v <= 0.0) {
            return Err(Error::parse(format!(
                "{origin}: images[{i}] (`{}`): intensity must be positive",
                entry.file
            )));
        }
        if let Some(first) = seen.insert(entry.file.clone(), i) {
            return Err(Error::parse(format!(
                "{origin}: images[{i}]: `{}` is listed twice (first as images[{first}])",
                entry.file
            )));
        }
        lights.push(CapturedLight {
            image: ImageSource::File {
                path: resolve_image_path(folder, &entry.file),
                encoding: manifest.encoding,
            },
            direction,
            intensity,
        });
    }
    let (width, height) = check_images(&lights, &|i| format!("{origin}: images[{i}]"))?;
    let load_plane = |name: &Option<String>, what: &str| -> Result<Option<Arc<Vec<f32>>>> {
        let Some(name) = name else { return Ok(None) };
        let p = resolve_image_path(folder, name);
        let (w, h, values) = crate::image::load_scalar(&p)
            .map_err(|e| Error::parse(format!("{origin}: {what} `{name}`: {e}")))?;
        if (w, h) != (width, height) {
            return Err(Error::invalid(format!(
                "{origin}: {what} `{name}` is {w}×{h} but the images are {width}×{height}"
            )));
        }
        Ok(Some(Arc::new(values)))
    };
    let depth = load_plane(&manifest.depth, "depth")?;
    let mask = load_plane(&manifest.mask, "mask")?;
    if let Some(camera) = &manifest.camera {
        if (camera.width, camera.height) != (width, height) {
            return Err(Error::invalid(format!(
                "{origin}: the camera is {}×{} but the images are {width}×{height}",
                camera.width, camera.height
            )));
        }
        camera
            .build()
            .map_err(|e| Error::parse(format!("{origin}: camera: {e}")))?;
    }
    let projection = manifest
        .camera
        .as_ref()
        .map_or(manifest.projection, |c| c.projection.clone());
    Ok(Capture {
        lights,
        width,
        height,
        projection,
        camera: manifest.camera,
        depth,
        mask,
        origin,
        source_files: std::iter::once(path.to_path_buf())
            .chain(
                [&manifest.depth, &manifest.mask]
                    .into_iter()
                    .flatten()
                    .map(|name| resolve_image_path(folder, name)),
            )
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_parses_and_rejects_typos() {
        let m: Manifest = serde_json::from_str(
            r#"{"projection":{"type":"cylindrical"},"images":[{"file":"a.png","direction":[0,0,2],"intensity":[1,2,3]},{"file":"b.png","direction":[1,0,0]}]}"#,
        )
        .unwrap();
        assert_eq!(m.images[0].intensity.rgb(), [1.0, 2.0, 3.0]);
        assert_eq!(m.images[1].intensity.rgb(), [1.0; 3]);
        assert_eq!(m.projection, Projection::Cylindrical { fov_y_deg: None });
        assert!(serde_json::from_str::<Manifest>(r#"{"imgs":[]}"#).is_err());
        assert!(serde_json::from_str::<Manifest>(
            r#"{"images":[{"file":"a","direction":[0,0,1],"intensty":2}]}"#
        )
        .is_err());
    }

    #[test]
    fn intensity_is_divided_out() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = crate::image::ImageRgb::new(2, 2);
        img.data.iter_mut().for_each(|v| *v = 0.5);
        crate::image::save(&dir.path().join("a.exr"), &img, 0.0).unwrap();
        let path = dir.path().join("cap.json");
        std::fs::write(
            &path,
            r#"{"images":[{"file":"a.exr","direction":[0,0,1],"intensity":[0.5,1,2]}]}"#,
        )
        .unwrap();
        let cap = read(&path).unwrap();
        let px = cap.load(0).unwrap().get(1, 1);
        assert!(
            (px[0] - 1.0).abs() < 1e-3 && (px[1] - 0.5).abs() < 1e-3 && (px[2] - 0.25).abs() < 1e-3,
            "{px:?}"
        );
        std::fs::write(
            &path,
            r#"{"images":[{"file":"a.exr","direction":[0,0,0]}]}"#,
        )
        .unwrap();
        assert!(read(&path).unwrap_err().to_string().contains("images[0]"));
    }

    #[test]
    fn input_files_name_the_manifest_images_depth_and_mask() {
        let dir = tempfile::tempdir().unwrap();
        let img = crate::image::ImageRgb::new(2, 2);
        for name in ["a.exr", "b.exr", "depth.exr", "mask.png"] {
            crate::image::save(&dir.path().join(name), &img, 0.0).unwrap();
        }
        let path = dir.path().join("cap.json");
        std::fs::write(
            &path,
            r#"{"depth":"depth.exr","mask":"mask.png","images":[{"file":"a.exr","direction":[0,0,1]},{"file":"b.exr","direction":[0,1,1]}]}"#,
        )
        .unwrap();
        let files = read(&path).unwrap().input_files();
        let expected: Vec<_> = ["cap.json", "depth.exr", "mask.png", "a.exr", "b.exr"]
            .iter()
            .map(|n| dir.path().join(n))
            .collect();
        assert_eq!(files, expected);
    }
}
