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
            PlaneStorage::U8 => quantize(&maps.data, maps.pixels(), |&v| v),
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

    /// The value of plane `j` at pixel `p` (`n` pixels per plane), decoded (the tests'
    /// reference reads the planes this way).
    #[cfg(test)]
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

/// The 8-bit coding `(scale, bias)` of a plane whose finite values span `[lo, hi]`
/// (`lo > hi` when it has none): the range in 255 steps, `value = scale · q + bias`.
pub(crate) fn u8_coding(lo: f32, hi: f32) -> (f32, f32) {
    if lo < hi {
        ((hi - lo) / 255.0, lo)
    } else if lo == hi {
        (0.0, lo)
    } else {
        (0.0, 0.0)
    }
}

/// `v` in the coding `(scale, bias)`.
#[inline]
pub(crate) fn u8_quantize(v: f32, scale: f32, bias: f32) -> u8 {
    let inv = if scale > 0.0 { 1.0 / scale } else { 0.0 };
    // Saturating cast: NaN gives 0.
    ((v - bias) * inv).round().clamp(0.0, 255.0) as u8
}

/// The finite range `(lo, hi)` of `values` folded into `range`.
#[inline]
pub(crate) fn fold_range(range: (f32, f32), v: f32) -> (f32, f32) {
    if v.is_finite() {
        (range.0.min(v), range.1.max(v))
    } else {
        range
    }
}

/// The range of no values yet.
pub(crate) const EMPTY_RANGE: (f32, f32) = (f32::INFINITY, f32::NEG_INFINITY);

/// 8-bit planes of `values` (planes of `n` values each, decoded by `decode`).
fn quantize<T: Sync>(values: &[T], n: usize, decode: impl Fn(&T) -> f32 + Sync) -> Planes<'static> {
    let n = n.max(1);
    let (scale, bias): (Vec<f32>, Vec<f32>) = values
        .par_chunks(n)
        .map(|plane| {
            let (lo, hi) = plane.iter().map(&decode).fold(EMPTY_RANGE, fold_range);
            u8_coding(lo, hi)
        })
        .unzip();
    let mut data = vec![0u8; values.len()];
    data.par_chunks_mut(n)
        .zip(values.par_chunks(n))
        .enumerate()
        .for_each(|(j, (q, v))| {
            for (q, v) in q.iter_mut().zip(v) {
                *q = u8_quantize(decode(v), scale[j], bias[j]);
            }
        });
    Planes::U8 { data, scale, bias }
}

/// Planes in f16 or 8 bits that own their values, made without the f32 maps: what
/// [`crate::codec::exr::read_compact`] decodes a file into, so that a relighter with
/// compact storage never holds the f32 maps at all.
pub struct CompactPlanes {
    pub(crate) planes: Planes<'static>,
    /// Values per plane.
    pub(crate) pixels: usize,
    /// Planes (3 × coefficients).
    pub(crate) count: usize,
}

impl CompactPlanes {
    /// Half-float planes from their bits, `count` planes of `pixels` values.
    pub fn from_f16_bits(bits: Vec<u16>, pixels: usize, count: usize) -> Option<Self> {
        (pixels.checked_mul(count) == Some(bits.len())).then_some(CompactPlanes {
            planes: Planes::F16(bits),
            pixels,
            count,
        })
    }

    /// 8-bit planes in the coding `(scale[j], bias[j])` of each plane `j`.
    pub fn from_u8(
        data: Vec<u8>,
        scale: Vec<f32>,
        bias: Vec<f32>,
        pixels: usize,
        count: usize,
    ) -> Option<Self> {
        (pixels.checked_mul(count) == Some(data.len())
            && scale.len() == count
            && bias.len() == count)
            .then_some(CompactPlanes {
                planes: Planes::U8 { data, scale, bias },
                pixels,
                count,
            })
    }

    /// The same planes in `storage` (F16 or U8; F32 is refused: compact planes do not
    /// widen). U8 quantises exactly as [`Relighter::with_storage`](super::Relighter::with_storage)
    /// does from f32 maps holding the same values.
    pub fn into_storage(self, storage: PlaneStorage) -> Option<Self> {
        let planes = match (storage, self.planes) {
            (PlaneStorage::F16, p @ Planes::F16(_)) => p,
            (PlaneStorage::U8, Planes::F16(bits)) => {
                quantize(&bits, self.pixels, |&b| half::f16::from_bits(b).to_f32())
            }
            (PlaneStorage::U8, p @ Planes::U8 { .. }) => p,
            _ => return None,
        };
        Some(CompactPlanes { planes, ..self })
    }

    pub fn storage(&self) -> PlaneStorage {
        self.planes.storage()
    }

    /// Bytes of the stored values.
    pub fn bytes(&self) -> usize {
        self.planes.bytes()
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
        // Compact planes made from half-float bits quantise exactly as the maps do when
        // the maps hold the same (half-representable) values.
        let halves: Vec<f32> = maps
            .data
            .iter()
            .map(|&v| half::f16::from_f32(v).to_f32())
            .collect();
        let rounded = CoefficientMaps {
            data: halves.clone(),
            ..maps.clone()
        };
        let bits = halves
            .iter()
            .map(|&v| half::f16::from_f32(v).to_bits())
            .collect();
        let compact = CompactPlanes::from_f16_bits(bits, n, 3 * maps.k).unwrap();
        assert_eq!(compact.storage(), PlaneStorage::F16);
        let u8s = compact.into_storage(PlaneStorage::U8).unwrap();
        match (&u8s.planes, Planes::new(&rounded, PlaneStorage::U8)) {
            (
                Planes::U8 { data, scale, bias },
                Planes::U8 {
                    data: d2,
                    scale: s2,
                    bias: b2,
                },
            ) => {
                assert_eq!((data, scale, bias), (&d2, &s2, &b2));
            }
            _ => unreachable!(),
        }
        assert!(CompactPlanes::from_f16_bits(vec![0; 5], n, 3).is_none());
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
