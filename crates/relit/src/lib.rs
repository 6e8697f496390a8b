//! # relit — image-based relighting
//!
//! A scene captured from a fixed viewpoint under many directional lights gives every
//! pixel a spherical function of the light direction (its *apparent BRDF*, seed 004).
//! relit compresses those functions into a few coefficient maps and synthesises the
//! scene under new lighting, without geometry, by superposition.
//!
//! The data flows through one module per stage:
//!
//! * [`capture`] — images, light directions and intensities (`.lp` files, JSON manifests);
//! * [`basis`] — the spherical bases the functions are expressed in ([`basis::Basis`]);
//! * [`fit`] — streaming, regularised least squares from a capture to [`maps::RelightableImage`];
//! * [`storage`] — how coefficient values are stored (precision, per-plane coding), one
//!   description for files, engines and the viewer;
//! * [`codec`] — files: OpenEXR, the native format;
//! * [`light`] and [`engine`] — light rigs and the relighting of maps into images;
//! * [`eval`] — fidelity against held-out captures, scored by [`metrics`] (the one
//!   definition of PSNR).
//!
//! ```
//! use relit::{capture::Capture, engine, fit, light::{Light, LightRig}, sphere};
//!
//! // A tiny synthetic capture: 64 lights over the upper hemisphere.
//! let dirs = sphere::hemisphere_fibonacci(64);
//! let capture: Capture = relit::synth::bumpy_plane(32, 24, &dirs);
//!
//! // Fit 3-band spherical harmonics (9 coefficients) and relight from the upper left.
//! let options = fit::FitOptions { basis: fit::BasisRequest::parse("sh:9").unwrap(), ..Default::default() };
//! let fitted = fit::fit(&capture, &options, &relit::progress::Silent).unwrap();
//! let rig = LightRig::new(vec![Light::directional([-1.0, 1.0, 1.0], [1.0, 0.9, 0.8])]);
//! let frame = engine::relight(&fitted.image, &rig, &engine::RelightOptions::default()).unwrap();
//! assert_eq!((frame.width, frame.height), (32, 24));
//! ```
#![doc = include_str!("../../../docs/conventions.md")]
#![forbid(unsafe_op_in_unsafe_fn)]

pub mod basis;
pub mod budget_fit;
pub mod camera;
pub mod capture;
pub mod codec;
pub mod color;
pub mod compress;
pub mod engine;
pub mod envmap;
pub mod error;
pub mod eval;
pub mod fit;
pub mod fsutil;
pub mod image;
pub mod light;
mod linalg;
pub mod maps;
mod memo;
pub mod memory;
pub mod metrics;
pub mod normals;
pub mod progress;
#[doc(hidden)]
pub mod shard;
pub mod skip;
pub mod sphere;
pub mod storage;
pub mod synth;

pub use error::{Error, ErrorKind, Result};
