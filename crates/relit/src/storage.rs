//! How coefficient values are stored: the one description the relightable file (maps
//! in f32 or f16), the CPU engine (planes in any [`Precision`]), the GPU engine
//! (`relit-gpu`) and the browser viewer (`relit-viewer`, f16 or u8 layers) all share
//! ([conventions](crate#stored-numbers)).
//!
//! A stored plane holds one number `q` per value, in a [`Precision`], and one
//! [`PlaneCoding`] that gives it meaning: **`value = offset + scale · q`**.
//!
//! * **f32**: `q` is the value (the maps exactly); coding [`PlaneCoding::IDENTITY`].
//! * **f16**: `q` is the value rounded to the nearest IEEE half (relative error
//!   ≤ 2⁻¹¹ in the normal range, absolute ≤ 2⁻²⁵ below it; beyond ±65504 it becomes
//!   ±∞, NaN stays NaN); coding [`PlaneCoding::IDENTITY`].
//! * **u8**: `q` is an integer code 0–255. The coding spans the plane's finite values
//!   ([`FiniteRange`]): `offset` the least, `scale` one step of the range in 255 steps
//!   (`(max − min)/255`); a constant plane has `scale` 0 and its value as `offset`, a
//!   plane without finite values `(0, 0)`. A value's code is
//!   `round((v − offset)/scale)` clamped to 0–255 (0 when `scale` is 0, and for NaN),
//!   so a finite value comes back within half a step, `scale/2`.
//!
//! Every back end encodes with the functions here ([`Precision::encode`],
//! [`PlaneCoding::quantize`], [`to_f16_bits`]), so they read the same numbers.

use crate::maps::CoefficientMaps;
use crate::{Error, Result};
use half::slice::{HalfBitsSliceExt, HalfFloatSliceExt};
use rayon::prelude::*;

/// The number type of stored coefficient values.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// 32-bit IEEE floats: the values exactly.
    #[default]
    F32,
    /// 16-bit IEEE half floats.
    F16,
    /// 8-bit codes with a per-plane scale and offset.
    U8,
}

impl Precision {
    /// Every precision, widest first.
    pub const ALL: [Precision; 3] = [Precision::F32, Precision::F16, Precision::U8];

    /// The name commands and files use: `f32`, `f16`, `u8`.
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F16 => "f16",
            Precision::U8 => "u8",
        }
    }

    /// A precision by name, ignoring case and surrounding spaces. Besides the names,
    /// `float`/`32`, `half`/`16` and `8`/`png` are accepted (the names earlier commands
    /// used).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "f32" | "float" | "32" => Some(Precision::F32),
            "f16" | "half" | "16" => Some(Precision::F16),
            "u8" | "8" | "png" => Some(Precision::U8),
            _ => None,
        }
    }

    /// Bytes per stored value.
    pub fn bytes_per_value(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F16 => 2,
            Precision::U8 => 1,
        }
    }

    /// The coding of `plane` in this precision: the identity for floats, the plane's
    /// finite range in 255 steps for u8.
    pub fn coding(self, plane: &[f32]) -> PlaneCoding {
        match self {
            Precision::F32 | Precision::F16 => PlaneCoding::IDENTITY,
            Precision::U8 => PlaneCoding::u8(FiniteRange::of(plane.iter().copied())),
        }
    }

    /// The coding of every plane of `maps` (`3k` entries, plane `3i + c`).
    pub fn codings(self, maps: &CoefficientMaps) -> Vec<PlaneCoding> {
        let n = maps.pixels().max(1);
        match self {
            Precision::F32 | Precision::F16 => vec![PlaneCoding::IDENTITY; 3 * maps.k],
            Precision::U8 => maps.data.par_chunks(n).map(|p| self.coding(p)).collect(),
        }
    }

    /// Append `values` (a run of one plane, whose coding is `coding`) to `out` as
    /// stored numbers, little-endian.
    pub fn encode(self, values: &[f32], coding: PlaneCoding, out: &mut Vec<u8>) {
        match self {
            Precision::F32 if cfg!(target_endian = "little") => {
                out.extend_from_slice(bytemuck::cast_slice(values))
            }
            Precision::F32 => out.extend(values.iter().flat_map(|v| v.to_le_bytes())),
            Precision::F16 => {
                let mut bits = vec![0u16; values.len()];
                to_f16_bits(values, &mut bits);
                if cfg!(target_endian = "little") {
                    out.extend_from_slice(bytemuck::cast_slice(&bits));
                } else {
                    out.extend(bits.iter().flat_map(|b| b.to_le_bytes()));
                }
            }
            Precision::U8 => out.extend(values.iter().map(|&v| coding.quantize(v))),
        }
    }

    /// Append the values of little-endian stored numbers `bytes` (coding `coding`) to
    /// `out`: the inverse of [`Precision::encode`] up to its rounding.
    pub fn decode(self, bytes: &[u8], coding: PlaneCoding, out: &mut Vec<f32>) {
        match self {
            Precision::F32 => out.extend(
                bytes
                    .chunks_exact(4)
                    .map(|b| coding.decode(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))),
            ),
            Precision::F16 => out.extend(
                bytes
                    .chunks_exact(2)
                    .map(|b| coding.decode(f16_value(u16::from_le_bytes([b[0], b[1]])))),
            ),
            Precision::U8 => out.extend(bytes.iter().map(|&q| coding.decode(q as f32))),
        }
    }

    /// Replace every value of `plane` with what this precision keeps of it (encode, then
    /// decode) and return the coding used.
    pub fn round_trip(self, plane: &mut [f32]) -> PlaneCoding {
        let coding = self.coding(plane);
        match self {
            Precision::F32 => {}
            Precision::F16 => plane.iter_mut().for_each(|v| *v = f16_value(f16_bits(*v))),
            Precision::U8 => plane
                .iter_mut()
                .for_each(|v| *v = coding.decode(coding.quantize(*v) as f32)),
        }
        coding
    }

    /// An error unless this is one of `allowed`, naming `what` needs it.
    pub fn require(self, allowed: &[Precision], what: &str) -> Result<Self> {
        if allowed.contains(&self) {
            return Ok(self);
        }
        let names: Vec<_> = allowed.iter().map(|p| p.name()).collect();
        Err(Error::invalid(format!(
            "{what} stores {}, not {}",
            names.join(" or "),
            self.name()
        )))
    }
}

impl std::fmt::Display for Precision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Precision {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        Precision::parse(s).ok_or_else(|| format!("unknown precision `{s}` (f32, f16 or u8)"))
    }
}

/// What a plane's stored number `q` means: `value = offset + scale · q`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlaneCoding {
    pub scale: f32,
    pub offset: f32,
}

impl PlaneCoding {
    /// `q` is the value (f32 and f16).
    pub const IDENTITY: PlaneCoding = PlaneCoding {
        scale: 1.0,
        offset: 0.0,
    };

    /// The 8-bit coding of a plane whose finite values span `range`.
    pub fn u8(range: FiniteRange) -> Self {
        let FiniteRange { lo, hi } = range;
        if lo < hi {
            PlaneCoding {
                scale: (hi - lo) / 255.0,
                offset: lo,
            }
        } else if lo == hi {
            PlaneCoding {
                scale: 0.0,
                offset: lo,
            }
        } else {
            PlaneCoding {
                scale: 0.0,
                offset: 0.0,
            }
        }
    }

    /// The value of stored number `q`. Back ends may fuse the multiply and add (one
    /// rounding less, at most an f32 ulp apart).
    #[inline]
    pub fn decode(self, q: f32) -> f32 {
        self.offset + self.scale * q
    }

    /// The 8-bit code of `v`: `round((v − offset)/scale)` clamped to 0–255; 0 when
    /// `scale` is 0 and for NaN.
    #[inline]
    pub fn quantize(self, v: f32) -> u8 {
        let inv = if self.scale > 0.0 {
            1.0 / self.scale
        } else {
            0.0
        };
        // Float-to-int casts saturate, and give 0 for NaN.
        ((v - self.offset) * inv).round().clamp(0.0, 255.0) as u8
    }
}

/// The least and greatest finite value seen; `lo > hi` while none has been.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FiniteRange {
    pub lo: f32,
    pub hi: f32,
}

impl FiniteRange {
    /// The range of no values.
    pub const EMPTY: FiniteRange = FiniteRange {
        lo: f32::INFINITY,
        hi: f32::NEG_INFINITY,
    };

    /// The range grown by `v` (unchanged when `v` is not finite).
    #[inline]
    pub fn with(self, v: f32) -> Self {
        if v.is_finite() {
            FiniteRange {
                lo: self.lo.min(v),
                hi: self.hi.max(v),
            }
        } else {
            self
        }
    }

    /// The range of `values`.
    pub fn of(values: impl IntoIterator<Item = f32>) -> Self {
        values.into_iter().fold(Self::EMPTY, Self::with)
    }
}

/// The half-float bits of `v`, rounded to nearest even.
#[inline]
pub fn f16_bits(v: f32) -> u16 {
    half::f16::from_f32(v).to_bits()
}

/// The value of half-float bits.
#[inline]
pub fn f16_value(bits: u16) -> f32 {
    half::f16::from_bits(bits).to_f32()
}

/// [`f16_bits`] of every value (vector instructions where the CPU has them).
pub fn to_f16_bits(values: &[f32], out: &mut [u16]) {
    assert_eq!(values.len(), out.len(), "one half per value");
    out.reinterpret_cast_mut::<half::f16>()
        .convert_from_f32_slice(values);
}

/// [`f16_value`] of every half.
pub fn from_f16_bits(bits: &[u16], out: &mut [f32]) {
    assert_eq!(bits.len(), out.len(), "one value per half");
    bits.reinterpret_cast::<half::f16>()
        .convert_to_f32_slice(out);
}

/// Planes (plane `j` at `j · n`, `n` values each) in their precision, as the CPU
/// engine reads them every frame: the f32 maps borrowed, or a compact copy.
pub(crate) enum Planes<'a> {
    F32(&'a [f32]),
    /// Half-float bits.
    F16(Vec<u16>),
    U8 {
        data: Vec<u8>,
        coding: Vec<PlaneCoding>,
    },
}

/// Values per parallel conversion task.
const CONVERT_CHUNK: usize = 1 << 16;

impl<'a> Planes<'a> {
    pub(crate) fn new(maps: &'a CoefficientMaps, precision: Precision) -> Self {
        match precision {
            Precision::F32 => Planes::F32(&maps.data),
            Precision::F16 => {
                let mut bits = vec![0u16; maps.data.len()];
                bits.par_chunks_mut(CONVERT_CHUNK)
                    .zip(maps.data.par_chunks(CONVERT_CHUNK))
                    .for_each(|(h, f)| to_f16_bits(f, h));
                Planes::F16(bits)
            }
            Precision::U8 => quantize(&maps.data, maps.pixels(), |&v| v),
        }
    }

    pub(crate) fn precision(&self) -> Precision {
        match self {
            Planes::F32(_) => Precision::F32,
            Planes::F16(_) => Precision::F16,
            Planes::U8 { .. } => Precision::U8,
        }
    }

    /// The coding of plane `j`.
    #[inline]
    pub(crate) fn coding(&self, j: usize) -> PlaneCoding {
        match self {
            Planes::U8 { coding, .. } => coding[j],
            _ => PlaneCoding::IDENTITY,
        }
    }

    /// The value of plane `j` at pixel `p` (`n` pixels per plane), decoded.
    pub(crate) fn value(&self, j: usize, p: usize, n: usize) -> f32 {
        let i = j * n + p;
        match self {
            Planes::F32(d) => d[i],
            Planes::F16(d) => f16_value(d[i]),
            Planes::U8 { data, coding } => coding[j].decode(data[i] as f32),
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

/// 8-bit planes of `values` (planes of `n` values each, decoded by `decode`).
fn quantize<T: Sync>(values: &[T], n: usize, decode: impl Fn(&T) -> f32 + Sync) -> Planes<'static> {
    let n = n.max(1);
    let coding: Vec<PlaneCoding> = values
        .par_chunks(n)
        .map(|plane| PlaneCoding::u8(FiniteRange::of(plane.iter().map(&decode))))
        .collect();
    let mut data = vec![0u8; values.len()];
    data.par_chunks_mut(n)
        .zip(values.par_chunks(n))
        .enumerate()
        .for_each(|(j, (q, v))| {
            for (q, v) in q.iter_mut().zip(v) {
                *q = coding[j].quantize(decode(v));
            }
        });
    Planes::U8 { data, coding }
}

/// Planes in f16 or u8 that own their values, made without keeping f32 maps: what the
/// EXR reader's `read_compact` decodes a file into, so that a relighter with compact
/// planes never holds the f32 maps at all.
pub struct CompactPlanes {
    pub(crate) planes: Planes<'static>,
    /// Values per plane.
    pub(crate) pixels: usize,
    /// Planes (3 × coefficients).
    pub(crate) count: usize,
}

impl CompactPlanes {
    /// The planes of `maps` in `precision` (f16 or u8): the copy a relighter of that
    /// precision reads.
    pub fn from_maps(maps: &CoefficientMaps, precision: Precision) -> Result<Self> {
        let precision = precision.require(&[Precision::F16, Precision::U8], "compact planes")?;
        let planes = match Planes::new(maps, precision) {
            Planes::F16(bits) => Planes::F16(bits),
            Planes::U8 { data, coding } => Planes::U8 { data, coding },
            Planes::F32(_) => unreachable!("f32 was refused"),
        };
        Ok(CompactPlanes {
            planes,
            pixels: maps.pixels(),
            count: 3 * maps.k,
        })
    }

    /// Half-float planes from their bits, `count` planes of `pixels` values.
    pub fn from_f16_bits(bits: Vec<u16>, pixels: usize, count: usize) -> Option<Self> {
        (pixels.checked_mul(count) == Some(bits.len())).then_some(CompactPlanes {
            planes: Planes::F16(bits),
            pixels,
            count,
        })
    }

    /// 8-bit planes with the coding of each plane.
    pub fn from_u8(
        data: Vec<u8>,
        coding: Vec<PlaneCoding>,
        pixels: usize,
        count: usize,
    ) -> Option<Self> {
        (pixels.checked_mul(count) == Some(data.len()) && coding.len() == count).then_some(
            CompactPlanes {
                planes: Planes::U8 { data, coding },
                pixels,
                count,
            },
        )
    }

    /// The same planes in `precision` (F16 or U8; F32 is refused: compact planes do
    /// not widen). U8 quantises exactly as [`CompactPlanes::from_maps`] does from f32
    /// maps holding the same values.
    pub fn into_precision(self, precision: Precision) -> Option<Self> {
        let planes = match (precision, self.planes) {
            (Precision::F16, p @ Planes::F16(_)) => p,
            (Precision::U8, Planes::F16(bits)) => quantize(&bits, self.pixels, |&b| f16_value(b)),
            (Precision::U8, p @ Planes::U8 { .. }) => p,
            _ => return None,
        };
        Some(CompactPlanes { planes, ..self })
    }

    pub fn precision(&self) -> Precision {
        self.planes.precision()
    }

    /// The coding of plane `j`.
    pub fn coding(&self, j: usize) -> PlaneCoding {
        self.planes.coding(j)
    }

    /// The decoded value of plane `j` at pixel `p`.
    pub fn value(&self, j: usize, p: usize) -> f32 {
        self.planes.value(j, p, self.pixels)
    }

    /// Bytes of the stored values.
    pub fn bytes(&self) -> usize {
        self.planes.bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values over several magnitudes, both signs, subnormal halves and a constant
    /// plane's worth of repeats.
    fn awkward() -> Vec<f32> {
        (0..600)
            .map(|i| {
                let t = (i * 37 % 101) as f32 / 101.0 - 0.3;
                match i % 4 {
                    0 => t * 2.0,
                    1 => t * 1e-6,
                    2 => t * 3000.0,
                    _ => t,
                }
            })
            .collect()
    }

    #[test]
    fn names_round_trip() {
        for p in Precision::ALL {
            assert_eq!(Precision::parse(p.name()), Some(p));
            assert_eq!(p.to_string().parse::<Precision>(), Ok(p));
            assert_eq!(
                serde_json::to_string(&p).unwrap(),
                format!("\"{}\"", p.name())
            );
        }
        assert_eq!(Precision::parse(" Half "), Some(Precision::F16));
        assert_eq!(Precision::parse("float"), Some(Precision::F32));
        assert_eq!(Precision::parse("png"), Some(Precision::U8));
        assert_eq!(Precision::parse("f64"), None);
        assert!(Precision::U8
            .require(&[Precision::F32, Precision::F16], "a file")
            .unwrap_err()
            .to_string()
            .contains("f32 or f16, not u8"));
    }

    /// Encode then decode keeps every value within the precision's bound: exact for
    /// f32, 2⁻¹¹ relative (2⁻²⁵ absolute below the normal range) for f16, half a step
    /// for u8; and `round_trip` is exactly that encode-then-decode.
    #[test]
    fn round_trip_error_is_within_each_precisions_bound() {
        let values = awkward();
        for p in Precision::ALL {
            let coding = p.coding(&values);
            let mut bytes = Vec::new();
            p.encode(&values, coding, &mut bytes);
            assert_eq!(bytes.len(), values.len() * p.bytes_per_value());
            let mut back = Vec::new();
            p.decode(&bytes, coding, &mut back);
            let mut in_place = values.clone();
            assert_eq!(p.round_trip(&mut in_place), coding);
            assert_eq!(in_place, back, "{p}");
            for (&a, &v) in back.iter().zip(&values) {
                let bound = match p {
                    Precision::F32 => 0.0,
                    Precision::F16 => (v.abs() * 2f32.powi(-11)).max(2f32.powi(-25)),
                    // Half a step, plus f32 rounding of offset + scale · q.
                    Precision::U8 => 0.5 * coding.scale + 4.0 * f32::EPSILON * 3000.0,
                };
                assert!((a - v).abs() <= bound, "{p}: {a} for {v}");
            }
        }
        let FiniteRange { lo, hi } = FiniteRange::of(values.iter().copied());
        let coding = Precision::U8.coding(&values);
        assert_eq!(
            (coding.offset, coding.scale),
            (lo, (hi - lo) / 255.0),
            "the conventions' u8 coding"
        );
        assert_eq!(coding.quantize(lo), 0);
        assert_eq!(coding.quantize(hi), 255);
    }

    #[test]
    fn degenerate_planes_and_non_finite_values() {
        // A constant plane decodes exactly; a plane without finite values to 0.
        let mut constant = vec![0.25f32; 7];
        assert_eq!(
            Precision::U8.round_trip(&mut constant),
            PlaneCoding {
                scale: 0.0,
                offset: 0.25
            }
        );
        assert_eq!(constant, vec![0.25; 7]);
        let coding = Precision::U8.coding(&[f32::NAN, f32::INFINITY]);
        assert_eq!(
            coding,
            PlaneCoding {
                scale: 0.0,
                offset: 0.0
            }
        );
        // NaN takes code 0; infinities saturate; the range ignores them.
        let coding = Precision::U8.coding(&[0.0, 1.0, f32::NAN, f32::NEG_INFINITY]);
        assert_eq!(coding.offset, 0.0);
        assert_eq!(coding.quantize(f32::NAN), 0);
        assert_eq!(coding.quantize(f32::INFINITY), 255);
        assert_eq!(coding.quantize(f32::NEG_INFINITY), 0);
        // f16 keeps NaN and overflows to infinity.
        assert!(f16_value(f16_bits(f32::NAN)).is_nan());
        assert_eq!(f16_value(f16_bits(1e6)), f32::INFINITY);
    }

    #[test]
    fn bulk_and_single_half_conversions_agree() {
        let values = awkward();
        let mut bits = vec![0u16; values.len()];
        to_f16_bits(&values, &mut bits);
        let one: Vec<u16> = values.iter().map(|&v| f16_bits(v)).collect();
        assert_eq!(bits, one);
        let mut back = vec![0f32; bits.len()];
        from_f16_bits(&bits, &mut back);
        assert_eq!(back, bits.iter().map(|&b| f16_value(b)).collect::<Vec<_>>());
    }

    #[test]
    fn cpu_planes_decode_as_the_shared_encoder() {
        let mut maps = CoefficientMaps::zeros(10, 20, 2);
        for (v, a) in maps.data.iter_mut().zip(awkward()) {
            *v = a;
        }
        let n = maps.pixels();
        for p in Precision::ALL {
            let planes = Planes::new(&maps, p);
            assert_eq!(planes.precision(), p);
            assert_eq!(planes.bytes(), maps.data.len() * p.bytes_per_value());
            let codings = p.codings(&maps);
            for (j, plane) in maps.data.chunks(n).enumerate() {
                assert_eq!(planes.coding(j), codings[j]);
                let mut bytes = Vec::new();
                p.encode(plane, codings[j], &mut bytes);
                let mut shared = Vec::new();
                p.decode(&bytes, codings[j], &mut shared);
                for (q, &v) in shared.iter().enumerate() {
                    assert_eq!(planes.value(j, q, n), v, "{p} plane {j} pixel {q}");
                }
            }
        }
    }

    #[test]
    fn compact_planes_from_halves_quantise_as_from_the_maps() {
        let mut maps = CoefficientMaps::zeros(10, 3, 2);
        for (i, v) in maps.data.iter_mut().enumerate() {
            // Half-representable values, so f32 maps and half bits hold the same numbers.
            *v = f16_value(f16_bits(((i * 37 % 101) as f32 / 101.0 - 0.3) * 2.0));
        }
        let n = maps.pixels();
        let bits = maps.data.iter().map(|&v| f16_bits(v)).collect();
        let compact = CompactPlanes::from_f16_bits(bits, n, 3 * maps.k).unwrap();
        assert_eq!(compact.precision(), Precision::F16);
        let u8s = compact.into_precision(Precision::U8).unwrap();
        let direct = CompactPlanes::from_maps(&maps, Precision::U8).unwrap();
        for j in 0..3 * maps.k {
            assert_eq!(u8s.coding(j), direct.coding(j));
            for p in 0..n {
                assert_eq!(u8s.value(j, p), direct.value(j, p));
            }
        }
        assert!(CompactPlanes::from_f16_bits(vec![0; 5], n, 3).is_none());
        assert!(CompactPlanes::from_maps(&maps, Precision::F32).is_err());
    }
}
