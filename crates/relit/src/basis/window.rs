//! Band windows: truncating a band-limited expansion of a map with a bright sun rings
//! (negative lobes), so a window scales band `l` of the `bands` kept by `h_l`
//! ([`Window::factors`]):
//!
//! * `None`: `h_l = 1`;
//! * `Hann`: `h_l = ½ (1 + cos(π l / bands))`;
//! * `Lanczos`: `h_l = sinc(π l / bands) = sin(π l / bands) / (π l / bands)`;
//! * `Laplacian { lambda }`: `h_l = 1 / (1 + λ l² (l+1)²)`, the window that minimises
//!   the squared Laplacian of the windowed function plus `1/λ` times its squared
//!   distance from the original (seed 003 §4.1, Sloan's "Stupid SH tricks"). Without
//!   `lambda` the default strength is `λ = 1 / (L² (L+1)²)` with `L = bands − 1`, which
//!   halves the highest band (`h_L = ½`).
//!
//! All leave band 0 (the mean radiance) untouched and decrease with `l`. `l(l+1)` is the
//! eigenvalue of the spherical Laplacian on band `l`, which is why only bases whose
//! coefficients come in such bands take a window.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// How the coefficients of an environment are attenuated by band, on a basis with bands
/// ([`super::Basis::coefficient_bands`]; module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Window {
    /// `h_l = 1`.
    #[default]
    None,
    /// `h_l = ½ (1 + cos(π l / bands))`.
    Hann,
    /// `h_l = sinc(π l / bands)`.
    Lanczos,
    /// `h_l = 1 / (1 + λ l²(l+1)²)`; `lambda` defaults to `1 / (L²(L+1)²)`, `L = bands − 1`.
    Laplacian {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        lambda: Option<f64>,
    },
}

impl Window {
    /// The window's name as users type it (`none`, `hann`, `lanczos`, `laplacian`).
    pub fn name(&self) -> &'static str {
        match self {
            Window::None => "none",
            Window::Hann => "hann",
            Window::Lanczos => "lanczos",
            Window::Laplacian { .. } => "laplacian",
        }
    }

    /// Parse `none`, `hann`, `lanczos`, `laplacian` or `laplacian:λ`.
    pub fn parse(spec: &str) -> Result<Window> {
        let window = match spec.split_once(':') {
            None => match spec {
                "none" => Window::None,
                "hann" => Window::Hann,
                "lanczos" => Window::Lanczos,
                "laplacian" => Window::Laplacian { lambda: None },
                other => {
                    return Err(Error::invalid(format!(
                        "unknown window `{other}`: use none, hann, lanczos or laplacian[:λ]"
                    )))
                }
            },
            Some(("laplacian", lambda)) => Window::Laplacian {
                lambda: Some(
                    lambda
                        .parse()
                        .map_err(|_| Error::invalid(format!("`{lambda}` is not a number")))?,
                ),
            },
            Some(_) => {
                return Err(Error::invalid(format!(
                    "only the laplacian window takes a value, not `{spec}`"
                )))
            }
        };
        window.validate()?;
        Ok(window)
    }

    /// Check the window's parameter.
    pub fn validate(&self) -> Result<()> {
        if let Window::Laplacian {
            lambda: Some(lambda),
        } = *self
        {
            if !(lambda.is_finite() && lambda >= 0.0) {
                return Err(Error::invalid(format!(
                    "a Laplacian window needs a finite λ ≥ 0, not {lambda}"
                )));
            }
        }
        Ok(())
    }

    /// The factors `h_0..h_{bands-1}` (bands ≥ 1).
    pub fn factors(&self, bands: usize) -> Result<Vec<f64>> {
        if bands == 0 {
            return Err(Error::invalid("a band window needs at least one band"));
        }
        self.validate()?;
        let b = bands as f64;
        let h = |l: usize| -> f64 {
            let x = PI * l as f64 / b;
            match *self {
                Window::None => 1.0,
                Window::Hann => 0.5 * (1.0 + x.cos()),
                Window::Lanczos if l == 0 => 1.0,
                Window::Lanczos => x.sin() / x,
                Window::Laplacian { lambda } => {
                    let lambda = lambda.unwrap_or_else(|| default_laplacian_lambda(bands));
                    let ll = (l * (l + 1)) as f64;
                    1.0 / (1.0 + lambda * ll * ll)
                }
            }
        };
        Ok((0..bands).map(h).collect())
    }
}

/// The default strength of the Laplacian window: `h_{bands-1} = ½`.
fn default_laplacian_lambda(bands: usize) -> f64 {
    let top = (bands - 1) as f64;
    if bands > 1 {
        1.0 / (top * top * (top + 1.0) * (top + 1.0))
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_keep_band_zero_and_decrease() {
        let windows = [
            Window::Hann,
            Window::Lanczos,
            Window::Laplacian { lambda: None },
            Window::Laplacian { lambda: Some(1e-3) },
        ];
        for bands in 1..=8 {
            assert!(Window::None
                .factors(bands)
                .unwrap()
                .iter()
                .all(|&h| h == 1.0));
            for window in windows {
                let h = window.factors(bands).unwrap();
                assert_eq!(h.len(), bands);
                assert_eq!(h[0], 1.0, "{window:?}");
                for l in 1..bands {
                    assert!(
                        h[l] < h[l - 1] && h[l] > 0.0,
                        "{window:?} bands {bands}: {h:?}"
                    );
                }
            }
            if bands > 1 {
                let h = Window::Laplacian { lambda: None }.factors(bands).unwrap();
                assert!(
                    (h[bands - 1] - 0.5).abs() < 1e-15,
                    "the default strength halves the top band"
                );
            }
        }
        // The formulas at one point: bands 4, l 2.
        let at = |w: Window| w.factors(4).unwrap()[2];
        assert!((at(Window::Hann) - 0.5).abs() < 1e-15);
        assert!((at(Window::Lanczos) - 2.0 / PI).abs() < 1e-15);
        assert!((at(Window::Laplacian { lambda: Some(0.01) }) - 1.0 / 1.36).abs() < 1e-15);
        assert!(Window::Laplacian { lambda: Some(-1.0) }.validate().is_err());
        let json = serde_json::to_string(&Window::Laplacian { lambda: None }).unwrap();
        assert_eq!(json, r#"{"type":"laplacian"}"#);
        assert_eq!(
            serde_json::from_str::<Window>(r#"{"type":"hann"}"#).unwrap(),
            Window::Hann
        );
    }
}
