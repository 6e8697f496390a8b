//! # relit-gpu — relighting on a GPU with wgpu compute shaders
//!
//! [`GpuRelighter`] uploads a [`relit::maps::RelightableImage`] of any basis once and
//! relights it with directional, point, spot, projector and area lights, or with any
//! folded weight vector (an environment light's, from
//! `relit::engine::Relighter::environment_weights`), over the whole image or a region
//! of interest. Directional and environment frames equal the CPU engine's
//! ([`relit::engine::relight`]) to f32 rounding; lights with a position read the
//! basis' `relit::basis::WeightTable` in half floats (as the CPU engine's table path
//! and the browser viewer do), and equal a per-pixel evaluation with that table to f32
//! rounding (and the basis itself within the table's measured error). The tests state
//! the bounds.
//!
//! ```no_run
//! # fn main() -> Result<(), relit_gpu::GpuError> {
//! use relit::light::{Light, LightRig};
//! # let image: relit::maps::RelightableImage = unimplemented!();
//! let gpu = relit_gpu::GpuRelighter::new(&image)?; // Err(NoAdapter) without a GPU
//! let rig = LightRig::new(vec![Light::directional([-1.0, 1.0, 1.0], [1.0; 3])]);
//! let frame = gpu.relight(&rig, 0.0)?;
//! # Ok(()) }
//! ```
//!
//! [`GpuLookup`] relights a codebook file (an index a pixel into `C` entries) without
//! expanding it: the entries through the same kernel, then one gather a pixel
//! (`shaders/lookup.wgsl`), under directional and environment lights.
//!
//! The kernel is `shaders/relight.wgsl`; one `shaders/fetch_*.wgsl` per
//! [`relit::storage::Precision`] supplies how a stored value is read. Frames of linear maps cost one pass over
//! the planes whatever the number of uniform lights (they fold into one weight per
//! plane, as on the CPU); positional lights take the basis' weights at each pixel's
//! light vector from its weight table (the bilinear lookup of
//! `relit::basis::WeightTable::sample`, in f32); projectors sample their slide as the
//! CPU engine does, area lights take the CPU engine's stratified samples with the same
//! per-pixel shift (its 64-bit hash, exactly).

mod engine;
mod error;
mod lighting;
mod roi;
mod storage;

pub use engine::{adapters, probe, AdapterSummary, GpuLookup, GpuOptions, GpuRelighter};
pub use error::{GpuError, Result};
pub use lighting::{Lighting, MAX_AREAS, MAX_PASSES, MAX_POSITIONAL, MAX_PROJECTORS};
pub use roi::Roi;
pub use storage::{stored_maps, STRIDE_ALIGN};
