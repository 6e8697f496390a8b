//! Lights and light rigs: what the engine relights with.
//!
//! A rig is a list of lights, each with an RGB colour and an intensity; their effects
//! add up (superposition, seed 004 eq. 2). One JSON form is shared by the CLI, the
//! library and the viewer:
//!
//! ```json
//! { "lights": [
//!   { "type": "directional", "direction": [-1, 1, 1], "color": [1, 0.9, 0.8], "intensity": 1.5 },
//!   { "type": "point", "position": [0, 1.5, -2], "intensity": 4, "attenuation": "inverse_square" },
//!   { "type": "spot", "position": [0, 2.5, -3], "direction": [0, -1, 0], "cone_deg": 25, "softness_deg": 5 },
//!   { "type": "projector", "position": [0, 1, 0], "direction": [0, 0, -1], "fov_deg": 40, "slide": "slide.png" },
//!   { "type": "area", "shape": { "rect": { "center": [0, 2.9, -3], "u": [0.5, 0, 0], "v": [0, 0, 0.5] } }, "samples": 16 },
//!   { "type": "environment", "map": "sky.hdr", "yaw_deg": 90, "window": { "type": "hann" } }
//! ] }
//! ```
//!
//! Every vector is in the light frame of the [conventions](crate). `direction` of a
//! directional light points toward the light; that of a spotlight or projector points
//! from the light into the scene. `color` defaults to white and `intensity` to 1.
//! Units: a directional light of intensity 1 reproduces the captured images; a point
//! light's intensity is the irradiance it gives at distance 1 relative to that (with
//! the default inverse-square falloff); an area light's is its emitted radiance.
//! Lights with a position need the file's depth map and camera (seed 004 eq. 3).
//! Slide and environment-map files are resolved relative to the rig file. Environment
//! lights need spherical-harmonic maps.

mod animation;
mod area;
mod directional;
mod environment;
mod point;
mod projector;
mod spot;

pub use animation::{Animation, Keyframe, RigFile};
pub use area::{AreaLight, AreaShape};
pub use directional::DirectionalLight;
pub use environment::EnvironmentMapLight;
pub use point::PointLight;
pub use projector::{PreparedProjector, ProjectorLight};
pub use spot::SpotLight;

use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

pub(crate) fn white() -> [f64; 3] {
    [1.0; 3]
}
pub(crate) fn one() -> f64 {
    1.0
}

/// Receives one incident contribution at a surface point: the unit light vector (toward
/// the light) and its RGB irradiance relative to a unit directional light.
pub type Emit<'a> = dyn FnMut(Vec3, [f64; 3]) + 'a;

/// How a positional light's irradiance falls off with distance `d`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Attenuation {
    /// `1 / d²`, physical (default).
    #[default]
    InverseSquare,
    /// `c0 / d`, the falloff of seed 000 ("C0/|L|").
    InverseDistance(f64),
    /// No falloff.
    None,
}

impl Attenuation {
    pub fn factor(self, d: f64) -> f64 {
        let d = d.max(1e-9);
        match self {
            Attenuation::InverseSquare => 1.0 / (d * d),
            Attenuation::InverseDistance(c0) => c0 / d,
            Attenuation::None => 1.0,
        }
    }
    fn validate(self) -> Result<()> {
        match self {
            Attenuation::InverseDistance(c0) if !c0.is_finite() => {
                Err(Error::invalid("attenuation constant must be finite"))
            }
            _ => Ok(()),
        }
    }
}

/// Any light the engine supports; each method forwards to the variant's own type.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Light {
    Directional(DirectionalLight),
    Point(PointLight),
    Spot(SpotLight),
    Projector(ProjectorLight),
    Area(AreaLight),
    Environment(EnvironmentMapLight),
}

impl Light {
    /// A directional light toward `direction` with colour `color` and intensity 1.
    pub fn directional(direction: impl Into<Vec3>, color: [f64; 3]) -> Light {
        Light::Directional(DirectionalLight {
            direction: direction.into(),
            color,
            intensity: 1.0,
        })
    }

    /// A point light at `position` with colour `color`, intensity 1 and inverse-square falloff.
    pub fn point(position: impl Into<Vec3>, color: [f64; 3]) -> Light {
        Light::Point(PointLight {
            position: position.into(),
            color,
            intensity: 1.0,
            attenuation: Attenuation::default(),
        })
    }

    /// The type name used in JSON.
    pub fn kind(&self) -> &'static str {
        match self {
            Light::Directional(_) => "directional",
            Light::Point(_) => "point",
            Light::Spot(_) => "spot",
            Light::Projector(_) => "projector",
            Light::Area(_) => "area",
            Light::Environment(_) => "environment",
        }
    }

    fn color_intensity(&self) -> ([f64; 3], f64) {
        match self {
            Light::Directional(l) => (l.color, l.intensity),
            Light::Point(l) => (l.color, l.intensity),
            Light::Spot(l) => (l.color, l.intensity),
            Light::Projector(l) => (l.color, l.intensity),
            Light::Area(l) => (l.color, l.intensity),
            Light::Environment(l) => (l.color, l.intensity),
        }
    }

    /// The light's RGB scale (colour × intensity).
    pub fn rgb(&self) -> [f64; 3] {
        let (color, intensity) = self.color_intensity();
        color.map(|c| c * intensity)
    }

    /// Set the colour.
    pub fn set_color(&mut self, color: [f64; 3]) {
        match self {
            Light::Directional(l) => l.color = color,
            Light::Point(l) => l.color = color,
            Light::Spot(l) => l.color = color,
            Light::Projector(l) => l.color = color,
            Light::Area(l) => l.color = color,
            Light::Environment(l) => l.color = color,
        }
    }

    /// Whether the light has one light vector for every pixel (needs no depth).
    pub fn is_uniform(&self) -> bool {
        matches!(self, Light::Directional(_) | Light::Environment(_))
    }

    /// Check the light's parameters.
    pub fn validate(&self) -> Result<()> {
        if self.rgb().iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid(
                "a light's colour and intensity must be finite",
            ));
        }
        match self {
            Light::Directional(l) => l.validate(),
            Light::Point(l) => l.validate(),
            Light::Spot(l) => l.validate(),
            Light::Projector(l) => l.validate(),
            Light::Area(l) => l.validate(),
            Light::Environment(l) => l.validate(),
        }
    }

    /// The file the light reads, relative to its rig file's folder: a projector's
    /// slide or an environment light's map.
    pub fn file(&self) -> Option<&str> {
        match self {
            Light::Projector(l) => Some(&l.slide),
            Light::Environment(l) => Some(&l.map),
            Light::Directional(_) | Light::Point(_) | Light::Spot(_) | Light::Area(_) => None,
        }
    }

    /// Load what the light refers to (a projector's slide, relative to `base`).
    /// Environment lights depend on the maps' basis, which a light does not know: the
    /// relighting engine prepares them.
    pub fn prepare(&self, base: &Path) -> Result<PreparedLight> {
        self.validate()?;
        let rgb = self.rgb();
        Ok(match self {
            Light::Directional(l) => PreparedLight::Directional {
                direction: l.unit(),
                rgb,
            },
            Light::Point(l) => PreparedLight::Point(l.clone(), rgb),
            Light::Spot(l) => PreparedLight::Spot(l.clone(), rgb),
            Light::Projector(l) => PreparedLight::Projector(Box::new(l.prepare(base)?), rgb),
            Light::Area(l) => PreparedLight::Area(l.clone(), rgb),
            Light::Environment(_) => {
                return Err(Error::invalid(
                    "environment lights are prepared by the engine, which knows the basis",
                ))
            }
        })
    }

    /// Parse the command-line forms `dir:x,y,z`, `point:x,y,z` and
    /// `spot:px,py,pz/dx,dy,dz/cone_deg`.
    pub fn parse_spec(spec: &str) -> Result<Light> {
        let bad = |e: String| Error::parse(format!("bad light `{spec}`: {e}"));
        let (kind, args) = spec.split_once(':').ok_or_else(|| {
            bad("expected e.g. `dir:0.3,0.5,0.8`, `point:0,1,-2` or `spot:0,2,-3/0,-1,0/30`".into())
        })?;
        let light = match kind.trim().to_ascii_lowercase().as_str() {
            "dir" | "directional" => Light::directional(parse_triple(args).map_err(bad)?, white()),
            "point" => Light::point(parse_triple(args).map_err(bad)?, white()),
            "spot" => {
                let parts: Vec<&str> = args.split('/').collect();
                if parts.len() != 3 {
                    return Err(bad("a spotlight is `spot:position/direction/cone_deg`".into()));
                }
                Light::Spot(SpotLight {
                    position: parse_triple(parts[0]).map_err(bad)?.into(),
                    direction: parse_triple(parts[1]).map_err(bad)?.into(),
                    cone_deg: parts[2].trim().parse().map_err(|_| bad(format!("`{}` is not an angle", parts[2])))?,
                    softness_deg: 5.0,
                    color: white(),
                    intensity: 1.0,
                    attenuation: Attenuation::default(),
                })
            }
            other => {
                return Err(Error::parse(format!(
                    "unknown light type `{other}` in `{spec}` (flags know dir, point, spot; rig files know every type)"
                )))
            }
        };
        light.validate().map_err(|e| bad(e.to_string()))?;
        Ok(light)
    }
}

/// A light ready to shine: files loaded, frames computed.
#[derive(Clone, Debug)]
pub enum PreparedLight {
    Directional {
        direction: Vec3,
        rgb: [f64; 3],
    },
    /// A light given directly as basis weights per colour channel (an environment).
    Weights([Vec<f64>; 3]),
    Point(PointLight, [f64; 3]),
    Spot(SpotLight, [f64; 3]),
    Projector(Box<PreparedProjector>, [f64; 3]),
    Area(AreaLight, [f64; 3]),
}

impl PreparedLight {
    /// The light reaching surface point `p` of pixel `pixel`: calls `emit` once per
    /// incident light vector (area lights: once per sample).
    pub fn illuminate(&self, p: Vec3, pixel: usize, emit: &mut Emit) {
        match self {
            PreparedLight::Directional { direction, rgb } => emit(*direction, *rgb),
            // Uniform by construction: the engine folds it into the plane weights.
            PreparedLight::Weights(_) => {}
            PreparedLight::Point(l, rgb) => l.illuminate(p, *rgb, emit),
            PreparedLight::Spot(l, rgb) => l.illuminate(p, *rgb, emit),
            PreparedLight::Projector(l, rgb) => l.illuminate(p, *rgb, emit),
            PreparedLight::Area(l, rgb) => l.illuminate(p, pixel, *rgb, emit),
        }
    }

    /// Whether every pixel shares one light vector.
    pub fn is_uniform(&self) -> bool {
        matches!(
            self,
            PreparedLight::Directional { .. } | PreparedLight::Weights(_)
        )
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

    /// Read a rig from its JSON file (an animation file gives its first keyframe).
    pub fn load(path: &Path) -> Result<LightRig> {
        match RigFile::load(path)? {
            RigFile::Rig(rig) => Ok(rig),
            RigFile::Animation(anim) => anim.rig_at(anim.start()),
        }
    }

    /// Check every light, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        for (i, l) in self.lights.iter().enumerate() {
            l.validate()
                .map_err(|e| Error::invalid(format!("lights[{i}] ({}): {e}", l.kind())))?;
        }
        Ok(())
    }

    /// The rig as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("rigs serialise")
    }
}

#[cfg(test)]
mod tests;
