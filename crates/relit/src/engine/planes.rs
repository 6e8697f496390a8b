//! Coefficient planes as the CPU engine reads them every frame: the file's f32 maps as
//! they are, or a compact copy in f16 or 8 bits.
//!
//! The layout stays planar (plane `3i + c`, see the conventions), so a directional or
//! environment frame streams each plane once. f16 halves the bytes read per frame
//! (relative error ≤ 2⁻¹¹); 8-bit quarters them with a per-plane scale and bias
//! (`value = scale · q + bias`, the plane's range in 255 steps), the choice recorded
//! with the planes as the seed's [-1, 1] → [0, 1] mapping was.

use crate::maps::CoefficientMaps;
use rayon::prelude::*;

/// The value type of the planes the CPU engine reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum PlaneStorage {
    /// The maps' own f32 values, borrowed (no copy).
    #[default]
    F32,
    /// IEEE half floats.
    F16,
    /// 8-bit with a per-plane scale and bias.
    U8,
}

impl PlaneStorage {
    /// Every storage type, widest first.
    pub const ALL: [PlaneStorage; 3] = [PlaneStorage::F32, PlaneStorage::F16, PlaneStorage::U8];

    /// The short name (`f32`, `f16`, `u8`).
    pub fn name(self) -> &'static str {
        match self {
            PlaneStorage::F32 => "f32",
            PlaneStorage::F16 => "f16",
            PlaneStorage::U8 => "u8",
        }
    }

    /// Parse a short name.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|t| t.name().eq_ignore_ascii_case(s.trim()))
    }

    /// Bytes per stored value.
    pub fn bytes_per_value(self) -> usize {
        match self {
            PlaneStorage::F32 => 4,
            PlaneStorage::F16 => 2,
            PlaneStorage::U8 => 1,
        }
    }
}

/// The planes in their storage type.
pub(crate) enum Planes<'a> {
    F32(&'a [f32]),
    /// Half-float bits.
    F16(Vec<u16>),
    U8 {
        data: Vec<u8>,
        scale: Vec<f32>,
        bias: Vec<f32>,
    },
}

/// Values per parallel conversion task.
const CONVERT_CHUNK: usize = 1 << 16;

impl<'a> Planes<'a> {
    pub(crate) fn new(maps: &'a CoefficientMaps, storage: PlaneStorage) -> Self {
        match storage {
            PlaneStorage::F32 => Planes::F32(&maps.data),
            PlaneStorage::F16 => {
                use half::slice::HalfFloatSliceExt;
                let mut halves = vec![half::f16::ZERO; maps.data.len()];
                halves
                    .par_chunks_mut(CONVERT_CHUNK)
                    .zip(maps.data.par_chunks(CONVERT_CHUNK))
                    .for_each(|(h, f)| h.convert_from_f32_slice(f));
                Planes::F16(halves.into_iter().map(half::f16::to_bits).collect())
            }
            PlaneStorage::U8 => {
                let n = maps.pixels().max(1);
                let (scale, bias): (Vec<f32>, Vec<f32>) = maps
                    .data
                    .par_chunks(n)
                    .map(|plane| {
                        let (lo, hi) = plane
                            .iter()
                            .filter(|v| v.is_finite())
                            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                                (lo.min(v), hi.max(v))
                            });
                        if lo < hi {
                            ((hi - lo) / 255.0, lo)
                        } else if lo == hi {
                            (0.0, lo)
                        } else {
                            (0.0, 0.0)
                        }
                    })
                    .unzip();
                let mut data = vec![0u8; maps.data.len()];
                data.par_chunks_mut(n)
                    .zip(maps.data.par_chunks(n))
                    .enumerate()
                    .for_each(|(j, (q, v))| {
                        let inv = if scale[j] > 0.0 { 1.0 / scale[j] } else { 0.0 };
                        for (q, &v) in q.iter_mut().zip(v) {
                            // Saturating cast: NaN gives 0.
                            *q = ((v - bias[j]) * inv).round().clamp(0.0, 255.0) as u8;
                        }
                    });
                Planes::U8 { data, scale, bias }
            }
        }
    }

    pub(crate) fn storage(&self) -> PlaneStorage {
        match self {
            Planes::F32(_) => PlaneStorage::F32,
            Planes::F16(_) => PlaneStorage::F16,
            Planes::U8 { .. } => PlaneStorage::U8,
        }
    }

    /// `(scale, bias)` of plane `j`: `value = scale · stored + bias`.
    pub(crate) fn coding(&self, j: usize) -> (f32, f32) {
        match self {
            Planes::U8 { scale, bias, .. } => (scale[j], bias[j]),
            _ => (1.0, 0.0),
        }
    }

    /// The value of plane `j` at pixel `p` (`n` pixels per plane), decoded.
    pub(crate) fn value(&self, j: usize, p: usize, n: usize) -> f32 {
        let i = j * n + p;
        match self {
            Planes::F32(d) => d[i],
            Planes::F16(d) => half::f16::from_bits(d[i]).to_f32(),
            Planes::U8 { data, scale, bias } => data[i] as f32 * scale[j] + bias[j],
        }
    }

    /// Bytes of the stored planes.
    pub(crate) fn bytes(&self) -> usize {
        match self {
            Planes::F32(d) => d.len() * 4,
            Planes::F16(d) => d.len() * 2,
            Planes::U8 { data, .. } => data.len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compact_storage_reproduces_the_maps_within_its_step() {
        let mut maps = CoefficientMaps::zeros(10, 3, 2);
        for (i, v) in maps.data.iter_mut().enumerate() {
            *v = ((i * 37 % 101) as f32 / 101.0 - 0.3) * 2.0;
        }
        let n = maps.pixels();
        match Planes::new(&maps, PlaneStorage::U8) {
            Planes::U8 { data, scale, bias } => {
                for (i, (&q, &v)) in data.iter().zip(&maps.data).enumerate() {
                    let j = i / n;
                    let back = q as f32 * scale[j] + bias[j];
                    assert!((back - v).abs() <= 0.5 * scale[j] + 1e-6, "{back} vs {v}");
                }
            }
            _ => unreachable!(),
        }
        match Planes::new(&maps, PlaneStorage::F16) {
            Planes::F16(bits) => {
                for (&h, &v) in bits.iter().zip(&maps.data) {
                    let back = half::f16::from_bits(h).to_f32();
                    assert!((back - v).abs() <= v.abs() * 2f32.powi(-11) + 1e-7);
                }
            }
            _ => unreachable!(),
        }
        for s in PlaneStorage::ALL {
            assert_eq!(PlaneStorage::parse(s.name()), Some(s));
            assert_eq!(Planes::new(&maps, s).storage(), s);
            assert_eq!(
                Planes::new(&maps, s).bytes(),
                maps.data.len() * s.bytes_per_value()
            );
        }
    }
}
