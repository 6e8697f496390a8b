//! Lights and light rigs: what the engine relights with.
//!
//! A rig is a list of lights, each with an RGB colour and an intensity; their effects
//! add up (superposition, seed 004 eq. 2). The JSON form is shared by the CLI, the
//! library and the viewer:
//!
//! ```json
//! { "lights": [
//!     { "type": "directional", "direction": [-1, 1, 1], "color": [1.0, 0.9, 0.8], "intensity": 1.5 }
//! ] }
//! ```
//!
//! `direction` points toward the light (light frame of the [conventions](crate)) and is
//! normalised; `color` defaults to white and `intensity` to 1. A light's radiance
//! scale is `color × intensity`: a directional light of intensity 1 reproduces the
//! captured images exactly.

use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

fn white() -> [f64; 3] {
    [1.0; 3]
}
fn one() -> f64 {
    1.0
}

/// A light at infinity: one light vector for every pixel.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectionalLight {
    /// Toward the light; normalised when used.
    pub direction: Vec3,
    #[serde(default = "white")]
    pub color: [f64; 3],
    #[serde(default = "one")]
    pub intensity: f64,
}

/// Any light the engine supports.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Light {
    Directional(DirectionalLight),
}

impl Light {
    /// A directional light toward `direction` with colour `color` and intensity 1.
    pub fn directional(direction: impl Into<Vec3>, color: [f64; 3]) -> Light {
        Light::Directional(DirectionalLight { direction: direction.into(), color, intensity: 1.0 })
    }

    /// The light's RGB radiance scale (colour × intensity).
    pub fn rgb(&self) -> [f64; 3] {
        match self {
            Light::Directional(l) => l.color.map(|c| c * l.intensity),
        }
    }

    /// Set the colour.
    pub fn set_color(&mut self, color: [f64; 3]) {
        match self {
            Light::Directional(l) => l.color = color,
        }
    }

    /// Check the light's parameters.
    pub fn validate(&self) -> Result<()> {
        let rgb = self.rgb();
        if rgb.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid("a light's colour and intensity must be finite"));
        }
        match self {
            Light::Directional(l) => {
                l.direction.normalized().ok_or_else(|| Error::invalid("a directional light needs a non-zero finite direction"))?;
            }
        }
        Ok(())
    }

    /// Parse the command-line form `dir:x,y,z`.
    pub fn parse_spec(spec: &str) -> Result<Light> {
        let (kind, args) = spec
            .split_once(':')
            .ok_or_else(|| Error::parse(format!("bad light `{spec}`: expected e.g. `dir:0.3,0.5,0.8`")))?;
        match kind.trim().to_ascii_lowercase().as_str() {
            "dir" | "directional" => {
                let v = parse_triple(args).map_err(|e| Error::parse(format!("bad light `{spec}`: {e}")))?;
                let light = Light::directional(v, white());
                light.validate().map_err(|e| Error::parse(format!("bad light `{spec}`: {e}")))?;
                Ok(light)
            }
            other => Err(Error::parse(format!("unknown light type `{other}` in `{spec}` (known: dir)"))),
        }
    }
}

/// Parse `a,b,c` into three finite numbers.
pub fn parse_triple(s: &str) -> std::result::Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected three comma-separated numbers, got `{s}`"));
    }
    let mut out = [0.0f64; 3];
    for (o, p) in out.iter_mut().zip(&parts) {
        *o = p.parse().map_err(|_| format!("`{p}` is not a number"))?;
        if !o.is_finite() {
            return Err(format!("`{p}` is not finite"));
        }
    }
    Ok(out)
}

/// A set of lights used together.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct LightRig {
    pub lights: Vec<Light>,
}

impl LightRig {
    pub fn new(lights: Vec<Light>) -> Self {
        Self { lights }
    }

    /// Read a rig from its JSON file.
    pub fn load(path: &Path) -> Result<LightRig> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "read", e))?;
        let rig: LightRig = serde_json::from_str(&text)
            .map_err(|e| Error::parse(format!("{}: line {}: {e}", path.display(), e.line())))?;
        for (i, l) in rig.lights.iter().enumerate() {
            l.validate().map_err(|e| Error::parse(format!("{}: lights[{i}]: {e}", path.display())))?;
        }
        Ok(rig)
    }

    /// The rig as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("rigs serialise")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rig_json_round_trips_with_defaults() {
        let rig: LightRig = serde_json::from_str(r#"{"lights":[{"type":"directional","direction":[0,0,1]}]}"#).unwrap();
        assert_eq!(rig.lights[0].rgb(), [1.0; 3]);
        let back: LightRig = serde_json::from_str(&rig.to_json()).unwrap();
        assert_eq!(back, rig);
        assert!(serde_json::from_str::<LightRig>(r#"{"lights":[{"type":"laser","direction":[0,0,1]}]}"#).is_err());
    }

    #[test]
    fn flag_specs() {
        assert_eq!(Light::parse_spec("dir:0,0,2").unwrap(), Light::directional([0.0, 0.0, 2.0], [1.0; 3]));
        assert!(Light::parse_spec("dir:0,0").is_err());
        assert!(Light::parse_spec("dir:0,0,0").is_err());
        assert!(Light::parse_spec("dir:0,nan,1").is_err());
        assert!(Light::parse_spec("sun:0,0,1").is_err());
        assert!(Light::parse_spec("0,0,1").is_err());
    }
}
