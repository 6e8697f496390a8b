//! The planes on the GPU: stored in a [`Precision`] and read back with each plane's
//! [`PlaneCoding`] (`value = offset + scale · q`), both from `relit::storage`, the one
//! description the CPU engine, the file and the browser viewer share. The upload encodes
//! with [`Precision::encode`], so both engines read the same stored numbers.
//!
//! Planes are padded to a stride of [`STRIDE_ALIGN`] pixels so that packed words (two
//! f16 or four u8 values per 32-bit word) never straddle two planes.

use relit::maps::CoefficientMaps;
use relit::storage::{PlaneCoding, Precision};

/// Plane strides are multiples of this many pixels (4 would do for `u8`; 64 keeps
/// every plane aligned to 256 bytes in `f32`).
pub const STRIDE_ALIGN: usize = 64;

/// The WGSL that declares the planes binding and `fetch` for `precision`.
pub(crate) fn shader_fetch(precision: Precision) -> &'static str {
    match precision {
        Precision::F32 => include_str!("../shaders/fetch_f32.wgsl"),
        Precision::F16 => include_str!("../shaders/fetch_f16.wgsl"),
        Precision::U8 => include_str!("../shaders/fetch_unorm8.wgsl"),
    }
}

/// Append a run of plane values to the bytes uploaded for it.
pub(crate) fn encode(precision: Precision, values: &[f32], coding: PlaneCoding, out: &mut Vec<u8>) {
    precision.encode(values, coding, out);
}

/// The maps as the GPU holds them in `precision`: every plane encoded as the upload
/// encodes it, then decoded (what the GPU computes with).
pub fn stored_maps(maps: &CoefficientMaps, precision: Precision) -> CoefficientMaps {
    let codings = precision.codings(maps);
    let mut out = maps.clone();
    let n = maps.pixels().max(1);
    let mut bytes = Vec::new();
    for (plane, &coding) in out.data.chunks_mut(n).zip(&codings) {
        bytes.clear();
        encode(precision, plane, coding, &mut bytes);
        let mut values = Vec::with_capacity(plane.len());
        precision.decode(&bytes, coding, &mut values);
        plane.copy_from_slice(&values);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stored_maps_are_the_shared_round_trip() {
        let mut maps = CoefficientMaps::zeros(10, 3, 2);
        for (i, v) in maps.data.iter_mut().enumerate() {
            *v = ((i * 37 % 101) as f32 / 101.0 - 0.3) * 2.0;
        }
        for p in Precision::ALL {
            let mut expected = maps.clone();
            for plane in expected.data.chunks_mut(maps.pixels()) {
                p.round_trip(plane);
            }
            assert_eq!(stored_maps(&maps, p), expected, "{p}");
        }
        assert_eq!(stored_maps(&maps, Precision::F32), maps);
    }
}
