//! The relit viewer: relightable panoramas in the browser.
//!
//! * [`bundle`] turns a relightable image into what the browser loads: an `info.json`
//!   and coefficient *layers* (four planes per RGBA texel, either 8-bit PNG quantised
//!   with a scale and offset per plane, or raw little-endian half floats), the basis'
//!   weight table (the viewer knows no basis), a float depth map and the camera, plus
//!   environment maps as radiance.
//! * [`assets`] holds the viewer itself (HTML, ES modules, GLSL), embedded in the binary.
//! * [`tiles`] sends a big file a tile at a time: an overview level (and its depth) held
//!   whole, finer levels (each tile with its depth) read by region from the EXR or
//!   `.rlz` file when the view asks for them.
//! * [`server`] serves the embedded assets and an in-memory bundle over HTTP
//!   ([`serve`]); [`export`] writes the same files as a static folder ([`export_web`]).
//!
//! URL layout (the same for the live server and an exported folder): `/` is
//! `index.html`, the viewer's modules sit beside it, and the data lives under `data/`:
//! `data/info.json`, `data/planes/L00.png` (or `.f16`), `data/weights.f32`,
//! `data/depth.f32`, `data/env/0.f32` and `data/env/0.png`.

pub mod assets;
pub mod bundle;
pub mod export;
pub mod server;
pub mod tiles;

pub use bundle::{BundleOptions, WebBundle, PRECISIONS};
pub use export::export_web;
pub use server::{serve, serve_with, RunningServer, ServerOptions};
pub use tiles::{TileSource, Tiling};

use relit::{Error, ErrorKind};
use std::path::Path;

pub(crate) use relit::Result;

/// An invalid-input error.
pub(crate) fn invalid(message: impl Into<String>) -> Error {
    Error::new(ErrorKind::InvalidInput, message)
}

/// An I/O error naming the file and what was being done.
pub(crate) fn io_error(path: &Path, action: &str, source: std::io::Error) -> Error {
    Error::new(ErrorKind::Io, format!("cannot {action} {}", path.display())).with_source(source)
}
