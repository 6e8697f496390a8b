//! Colour layouts: how a pixel's three functions (one per colour channel) are stored.
//!
//! Relighting is linear in the coefficients and the same in every channel, so any
//! fixed linear change of colour commutes with it: a reader undoes the layout once,
//! on the planes, and relights as usual.
//!
//! * `rgb`: a function per channel.
//! * `ycc`: YCoCg (`Y = R/4 + G/2 + B/4`, `Co = (R − B)/2`, `Cg = −R/4 + G/2 − B/4`),
//!   exactly invertible. Colour varies less across lights than brightness, so the
//!   chroma functions get fewer components (relight's `mycc`).
//! * `lrgb`: one luminance function times a per-pixel RGB albedo (PTM's LRGB): `K′ + 3`
//!   planes instead of `3K′`; exact for a pixel whose channels are scaled copies of one
//!   function (no coloured highlights).

use crate::{Error, Result};

/// A colour layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    Rgb,
    Ycc,
    Lrgb,
}

impl Layout {
    pub const ALL: [Layout; 3] = [Layout::Rgb, Layout::Ycc, Layout::Lrgb];

    pub fn parse(s: &str) -> Result<Layout> {
        match s.trim().to_ascii_lowercase().as_str() {
            "rgb" => Ok(Layout::Rgb),
            "ycc" | "mycc" | "ycocg" => Ok(Layout::Ycc),
            "lrgb" => Ok(Layout::Lrgb),
            other => Err(Error::parse(format!(
                "unknown colour layout `{other}` (rgb, ycc or lrgb)"
            ))),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Layout::Rgb => "rgb",
            Layout::Ycc => "ycc",
            Layout::Lrgb => "lrgb",
        }
    }

    /// The names of the stored function channels, then of the per-pixel planes.
    pub fn channels(self) -> (&'static [&'static str], &'static [&'static str]) {
        match self {
            Layout::Rgb => (&["R", "G", "B"], &[]),
            Layout::Ycc => (&["Y", "Co", "Cg"], &[]),
            Layout::Lrgb => (&["L"], &["aR", "aG", "aB"]),
        }
    }
}

/// YCoCg of linear RGB.
#[inline]
pub fn ycc(rgb: [f32; 3]) -> [f32; 3] {
    let [r, g, b] = rgb;
    [
        0.25 * r + 0.5 * g + 0.25 * b,
        0.5 * (r - b),
        -0.25 * r + 0.5 * g - 0.25 * b,
    ]
}

/// Linear RGB of YCoCg.
#[inline]
pub fn rgb_of_ycc(ycc: [f32; 3]) -> [f32; 3] {
    let [y, co, cg] = ycc;
    [y + co - cg, y + cg, y - co - cg]
}

/// The luminance of the `lrgb` layout (the Y of [`ycc`]).
#[inline]
pub fn luma(rgb: [f32; 3]) -> f32 {
    ycc(rgb)[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ycc_inverts_exactly_on_dyadic_values() {
        for rgb in [[1.0, 0.0, 0.0], [0.25, 0.5, 0.75], [-1.0, 2.0, 0.125]] {
            assert_eq!(rgb_of_ycc(ycc(rgb)), rgb);
        }
        assert_eq!(ycc([1.0, 1.0, 1.0]), [1.0, 0.0, 0.0]);
    }

    #[test]
    fn names_round_trip() {
        for l in Layout::ALL {
            assert_eq!(Layout::parse(l.name()).unwrap(), l);
        }
        assert_eq!(Layout::parse("mycc").unwrap(), Layout::Ycc);
        assert!(Layout::parse("hsv").is_err());
    }
}
