//! # relit-studio — the capture studio
//!
//! A small ray tracer that renders relightable captures of synthetic scenes: the
//! reference images under a plan of directional lights, the depth map and mask that
//! non-directional relighting needs, and ground truth under any light the studio can
//! emit. It is also the source of relit's test data.
//!
//! * Scenes: built-in procedural scenes ([`scenes`]: `attic`, `city`, `box`), OBJ + MTL
//!   files ([`obj`]) and JSON scene files ([`scene_file`], format documented there);
//!   [`open_scene`] takes any of the three by name or path.
//! * Tracing: triangles in a binned-SAH [`bvh`], Lambert + Blinn–Phong [`material`]s
//!   with procedural and image [`texture`]s, hard shadows, optional one-bounce
//!   diffuse indirect light, rayon over rows ([`render`]).
//! * Lights: [`plan`] parses light plans (`grid:70x140`, `fibonacci:3072`,
//!   `hemisphere:300`, `list:FILE`); [`emitter`] is what lights a shading point.
//! * Transfer: [`bake`] projects visibility, diffuse transfer or one-bounce colour
//!   bleeding onto SH per pixel (seed 003): relightable maps without a capture.
//! * Outputs: [`capture`] (in memory or a folder with manifest, `.lp`, depth and mask)
//!   and [`render_truth`] (one image under any emitters).
//!
//! Frames and units follow relit's conventions: light vectors point toward the light,
//! in the global light frame; a unit directional light makes a white Lambertian
//! surface facing it read 1 (linear radiance).
//!
//! ```
//! use relit_studio::{capture, plan::LightPlan, render::RenderOptions, scenes};
//! use relit::camera::{Camera, Projection};
//!
//! let scene = scenes::build("box").unwrap();
//! // The scene's own camera pose, at a small size for the example.
//! let camera = Camera::new(&Projection::Planar { fov_y_deg: Some(50.0) }, 32, 24, scene.camera.pose).unwrap();
//! let lights = LightPlan::parse("hemisphere:8").unwrap().directions();
//! let result = capture::capture_in_memory(&scene, &camera, &lights, &RenderOptions::default(), &relit::progress::Silent).unwrap();
//! assert_eq!(result.capture.len(), 8);
//! assert!(result.capture.depth.is_some());
//! ```

pub mod bake;
pub mod bvh;
pub mod capture;
pub mod emitter;
pub mod material;
pub mod math;
pub mod obj;
pub mod plan;
pub mod render;
pub mod scene;
pub mod scene_eval;
pub mod scene_file;
pub mod scenes;
pub mod setup;
pub mod shapes;
pub mod texture;

pub use relit::{Error, ErrorKind, Result};

use emitter::Emitter;
use relit::camera::Camera;
use relit::image::ImageRgb;
use relit::progress::Progress;
use render::{RenderOptions, Renderer};
use scene::Scene;
use std::path::Path;

/// The file a scene spec names (an `.obj` or `.json` path), `None` for a built-in
/// name. The files that one names in turn are in [`Scene::files`] once it is open.
pub fn scene_path(spec: &str) -> Option<&Path> {
    let path = Path::new(spec);
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    matches!(ext.as_str(), "obj" | "json").then_some(path)
}

/// Open a scene by built-in name (`attic`, `city`, `box`), `.obj` path or `.json`
/// scene-file path.
pub fn open_scene(spec: &str) -> Result<Scene> {
    let path = Path::new(spec);
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("obj") => obj::load_scene(path),
        Some("json") => scene_file::load(path),
        _ => scenes::build(spec).map_err(|e| {
            if path.exists() {
                invalid(format!("{spec}: scene files must end in .obj or .json"))
            } else {
                e
            }
        }),
    }
}

/// The image of `scene` seen by `camera` under `emitters` together: the ground truth
/// that relighting is compared with. It shades exactly as a capture does, so under a
/// unit white directional light it equals that light's capture image.
///
/// To render many images from one viewpoint, build a [`Renderer`] once instead.
pub fn render_truth(
    scene: &Scene,
    camera: &Camera,
    emitters: &[Emitter],
    options: &RenderOptions,
    progress: &dyn Progress,
) -> Result<ImageRgb> {
    let renderer = Renderer::new(scene, camera, options, progress)?;
    Ok(renderer.render(emitters).image)
}

pub(crate) fn invalid(message: impl Into<String>) -> Error {
    Error::new(ErrorKind::InvalidInput, message)
}

pub(crate) fn parse_error(message: impl Into<String>) -> Error {
    Error::new(ErrorKind::Parse, message)
}

pub(crate) fn io_error(path: &Path, action: &str, source: std::io::Error) -> Error {
    Error::new(ErrorKind::Io, format!("cannot {action} {}", path.display())).with_source(source)
}
