//! How coefficient values are stored on the GPU, and the per-plane affine coding that
//! turns a stored number `q` back into a coefficient: `value = offset + scale · q`, the
//! meaning the CPU engine's planes (`relit::engine::PlaneStorage`) and the browser
//! viewer's layers give it too.
//!
//! `f32` stores the maps exactly; `f16` halves the bytes streamed per frame (about
//! 3 significant digits, relative error ≤ 2⁻¹¹); in both `q` is the value itself (scale
//! 1, offset 0). `unorm8` quarters the bytes: `q` is an integer code 0–255, `offset` the
//! plane's least finite value and `scale` one step of its range in 255 steps, exactly
//! as the CPU engine quantises (so both engines relight the same 8-bit planes). Planes
//! are padded to a stride of [`STRIDE_ALIGN`] pixels so that packed words never
//! straddle two planes.

use half::slice::HalfFloatSliceExt;
use relit::maps::CoefficientMaps;

/// Plane strides are multiples of this many pixels (4 would do for `unorm8`; 64 keeps
/// every plane aligned to 256 bytes in `f32`).
pub const STRIDE_ALIGN: usize = 64;

/// The value type of the planes on the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Storage {
    /// 32-bit floats: the maps exactly.
    #[default]
    F32,
    /// IEEE half floats, two pixels per 32-bit word.
    F16,
    /// 8-bit integer codes with a per-plane scale and offset, four pixels per word.
    Unorm8,
}

impl Storage {
    /// Every storage type, widest first.
    pub const ALL: [Storage; 3] = [Storage::F32, Storage::F16, Storage::Unorm8];

    /// The short name (`f32`, `f16`, `u8`).
    pub fn name(self) -> &'static str {
        match self {
            Storage::F32 => "f32",
            Storage::F16 => "f16",
            Storage::Unorm8 => "u8",
        }
    }

    /// Parse a short name.
    pub fn parse(s: &str) -> Option<Storage> {
        Self::ALL
            .into_iter()
            .find(|t| t.name().eq_ignore_ascii_case(s.trim()))
    }

    /// Bytes per stored value.
    pub fn bytes_per_value(self) -> usize {
        match self {
            Storage::F32 => 4,
            Storage::F16 => 2,
            Storage::Unorm8 => 1,
        }
    }

    /// The WGSL that declares the planes binding and `fetch` for this type.
    pub(crate) fn shader_fetch(self) -> &'static str {
        match self {
            Storage::F32 => include_str!("../shaders/fetch_f32.wgsl"),
            Storage::F16 => include_str!("../shaders/fetch_f16.wgsl"),
            Storage::Unorm8 => include_str!("../shaders/fetch_unorm8.wgsl"),
        }
    }

    /// The per-plane coding of `maps` in this storage type.
    pub fn coding(self, maps: &CoefficientMaps) -> PlaneCoding {
        let planes = 3 * maps.k;
        match self {
            Storage::F32 | Storage::F16 => PlaneCoding {
                scale: vec![1.0; planes],
                offset: vec![0.0; planes],
            },
            Storage::Unorm8 => {
                let n = maps.pixels();
                let (scale, offset) = (0..planes)
                    .map(|j| {
                        let plane = &maps.data[j * n..(j + 1) * n];
                        let (lo, hi) = plane
                            .iter()
                            .filter(|v| v.is_finite())
                            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                                (lo.min(v), hi.max(v))
                            });
                        u8_coding(lo, hi)
                    })
                    .unzip();
                PlaneCoding { scale, offset }
            }
        }
    }

    /// Encode `values` (one plane's run of pixels) into little-endian stored bytes.
    pub(crate) fn encode(self, values: &[f32], scale: f32, offset: f32, out: &mut Vec<u8>) {
        out.clear();
        match self {
            Storage::F32 => out.extend_from_slice(bytemuck::cast_slice(values)),
            Storage::F16 => {
                let mut halves = vec![half::f16::ZERO; values.len()];
                halves.convert_from_f32_slice(values);
                out.extend(halves.iter().flat_map(|h| h.to_le_bytes()));
            }
            Storage::Unorm8 => {
                let inv = if scale > 0.0 { 1.0 / scale } else { 0.0 };
                // Float-to-int casts saturate (NaN gives 0).
                out.extend(
                    values
                        .iter()
                        .map(|&v| ((v - offset) * inv).round().clamp(0.0, 255.0) as u8),
                );
            }
        }
    }

    /// The maps as this storage type reproduces them (what the GPU computes with).
    pub fn round_trip(self, maps: &CoefficientMaps) -> CoefficientMaps {
        let coding = self.coding(maps);
        let n = maps.pixels();
        let mut out = maps.clone();
        let mut bytes = Vec::new();
        for (j, plane) in out.data.chunks_mut(n.max(1)).enumerate() {
            let (scale, offset) = (coding.scale[j], coding.offset[j]);
            self.encode(plane, scale, offset, &mut bytes);
            match self {
                Storage::F32 => {}
                Storage::F16 => {
                    for (v, b) in plane.iter_mut().zip(bytes.chunks_exact(2)) {
                        *v = half::f16::from_le_bytes([b[0], b[1]]).to_f32();
                    }
                }
                Storage::Unorm8 => {
                    for (v, &q) in plane.iter_mut().zip(&bytes) {
                        *v = (q as f32).mul_add(scale, offset);
                    }
                }
            }
        }
        out
    }
}

/// The 8-bit coding `(scale, offset)` of a plane whose finite values span `[lo, hi]`
/// (`lo > hi` when it has none): the range in 255 steps from its least value. The same
/// rule as the CPU engine's `u8_coding` (crates/relit/src/engine/planes.rs), which the
/// tests hold the GPU's 8-bit frames to.
fn u8_coding(lo: f32, hi: f32) -> (f32, f32) {
    if lo < hi {
        ((hi - lo) / 255.0, lo)
    } else if lo == hi {
        (0.0, lo)
    } else {
        (0.0, 0.0)
    }
}

/// Stored-to-coefficient coding of every plane (`3k` entries, plane `3i + c`):
/// `value = offset + scale · q` for the stored number `q`.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneCoding {
    pub scale: Vec<f32>,
    pub offset: Vec<f32>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> CoefficientMaps {
        let mut maps = CoefficientMaps::zeros(10, 3, 2);
        for (i, v) in maps.data.iter_mut().enumerate() {
            *v = ((i * 37 % 101) as f32 / 101.0 - 0.3) * 2.0;
        }
        maps
    }

    #[test]
    fn names_round_trip() {
        for s in Storage::ALL {
            assert_eq!(Storage::parse(s.name()), Some(s));
        }
        assert_eq!(Storage::parse("F16"), Some(Storage::F16));
        assert_eq!(Storage::parse("f64"), None);
    }

    /// Each type reproduces the maps within its quantisation step.
    #[test]
    fn round_trip_error_is_within_the_step() {
        let maps = ramp();
        assert_eq!(Storage::F32.round_trip(&maps), maps);
        let half = Storage::F16.round_trip(&maps);
        for (a, b) in half.data.iter().zip(&maps.data) {
            assert!(
                (a - b).abs() <= b.abs() * 2f32.powi(-11) + 1e-7,
                "{a} vs {b}"
            );
        }
        let coding = Storage::Unorm8.coding(&maps);
        let q = Storage::Unorm8.round_trip(&maps);
        let n = maps.pixels();
        for (i, (a, b)) in q.data.iter().zip(&maps.data).enumerate() {
            let step = coding.scale[i / n];
            assert!((a - b).abs() <= 0.5 * step + 1e-6, "{a} vs {b}");
        }
    }

    #[test]
    fn constant_planes_quantise_exactly() {
        let mut maps = CoefficientMaps::zeros(4, 1, 1);
        maps.data.iter_mut().for_each(|v| *v = 0.25);
        assert_eq!(Storage::Unorm8.round_trip(&maps), maps);
    }
}
