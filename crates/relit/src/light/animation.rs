//! Keyframed light rigs: lights that move, turn and change colour over time.
//!
//! ```json
//! { "keyframes": [
//!   { "time": 0, "lights": [ { "type": "point", "position": [-2, 1, -3], "intensity": 3 } ] },
//!   { "time": 1, "lights": [ { "type": "point", "position": [ 2, 1, -3], "intensity": 3 } ] }
//! ] }
//! ```
//!
//! Every keyframe lists the same lights in the same order and of the same types; between
//! keyframes positions, colours, intensities and angles interpolate linearly and
//! directions along the great circle (normalised linear interpolation). Properties that
//! do not interpolate (a projector's slide, a sample count) come from the earlier key.

use super::{AreaLight, AreaShape, Light, LightRig};
use crate::sphere::Vec3;
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The lights at one instant.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    pub time: f64,
    pub lights: Vec<Light>,
}

/// A keyframed rig.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Animation {
    pub keyframes: Vec<Keyframe>,
}

/// What a rig file holds: one rig, or an animation.
#[derive(Clone, Debug, PartialEq)]
pub enum RigFile {
    Rig(LightRig),
    Animation(Animation),
}

impl RigFile {
    /// Parse rig-file JSON; `origin` names the file in messages.
    pub fn parse(text: &str, origin: &str) -> Result<RigFile> {
        let value: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| Error::parse(format!("{origin}: line {}: {e}", e.line())))?;
        let file = if value.get("keyframes").is_some() {
            let anim: Animation = serde_json::from_value(value)
                .map_err(|e| Error::parse(format!("{origin}: {e}")))?;
            anim.validate()
                .map_err(|e| Error::parse(format!("{origin}: {e}")))?;
            RigFile::Animation(anim)
        } else {
            let rig: LightRig = serde_json::from_value(value)
                .map_err(|e| Error::parse(format!("{origin}: {e}")))?;
            rig.validate()
                .map_err(|e| Error::parse(format!("{origin}: {e}")))?;
            RigFile::Rig(rig)
        };
        Ok(file)
    }

    /// Read a rig file.
    pub fn load(path: &Path) -> Result<RigFile> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "read", e))?;
        Self::parse(&text, &path.display().to_string())
    }

    /// The files the rig's lights read (slides, environment maps) in every keyframe,
    /// resolved against `base`, the rig file's folder.
    pub fn referenced_files(&self, base: &Path) -> Vec<PathBuf> {
        let lights: Vec<&Light> = match self {
            RigFile::Rig(rig) => rig.lights.iter().collect(),
            RigFile::Animation(anim) => anim.keyframes.iter().flat_map(|k| &k.lights).collect(),
        };
        let mut files: Vec<PathBuf> = Vec::new();
        for file in lights.into_iter().filter_map(Light::file) {
            let path = base.join(file);
            if !files.contains(&path) {
                files.push(path);
            }
        }
        files
    }
}

impl Animation {
    /// Check the keyframes: at least one, times increasing, the same lights in each.
    pub fn validate(&self) -> Result<()> {
        let first = self
            .keyframes
            .first()
            .ok_or_else(|| Error::invalid("an animation needs at least one keyframe"))?;
        for (i, key) in self.keyframes.iter().enumerate() {
            if !key.time.is_finite() {
                return Err(Error::invalid(format!(
                    "keyframes[{i}]: time must be finite"
                )));
            }
            if i > 0 && key.time <= self.keyframes[i - 1].time {
                return Err(Error::invalid(format!(
                    "keyframes[{i}]: times must increase"
                )));
            }
            if key.lights.len() != first.lights.len()
                || key
                    .lights
                    .iter()
                    .zip(&first.lights)
                    .any(|(a, b)| a.kind() != b.kind())
            {
                return Err(Error::invalid(format!(
                    "keyframes[{i}]: every keyframe must list the same lights, in the same order, of the same types"
                )));
            }
            LightRig::new(key.lights.clone())
                .validate()
                .map_err(|e| Error::invalid(format!("keyframes[{i}]: {e}")))?;
        }
        Ok(())
    }

    pub fn start(&self) -> f64 {
        self.keyframes.first().map_or(0.0, |k| k.time)
    }

    pub fn end(&self) -> f64 {
        self.keyframes.last().map_or(0.0, |k| k.time)
    }

    /// The rig at time `t` (clamped to the keyframes' span).
    pub fn rig_at(&self, t: f64) -> Result<LightRig> {
        self.validate()?;
        let keys = &self.keyframes;
        let t = t.clamp(self.start(), self.end());
        let next = keys
            .iter()
            .position(|k| k.time >= t)
            .unwrap_or(keys.len() - 1);
        if next == 0 || keys[next].time == t {
            return Ok(LightRig::new(keys[next].lights.clone()));
        }
        let (a, b) = (&keys[next - 1], &keys[next]);
        let s = (t - a.time) / (b.time - a.time);
        Ok(LightRig::new(
            a.lights
                .iter()
                .zip(&b.lights)
                .map(|(x, y)| lerp_light(x, y, s))
                .collect(),
        ))
    }

    /// `frames` evenly spaced rigs from the first keyframe to the last, both included.
    pub fn frames(&self, frames: usize) -> Result<Vec<LightRig>> {
        let (t0, t1) = (self.start(), self.end());
        (0..frames)
            .map(|f| {
                let s = if frames <= 1 {
                    0.0
                } else {
                    f as f64 / (frames - 1) as f64
                };
                self.rig_at(t0 + (t1 - t0) * s)
            })
            .collect()
    }
}

fn lerp(a: f64, b: f64, s: f64) -> f64 {
    a + (b - a) * s
}
fn lerp3(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    std::array::from_fn(|i| lerp(a[i], b[i], s))
}
fn lerp_v(a: Vec3, b: Vec3, s: f64) -> Vec3 {
    a + (b - a) * s
}
/// Normalised linear interpolation of directions (kept at the earlier one if opposite).
fn nlerp(a: Vec3, b: Vec3, s: f64) -> Vec3 {
    let (ua, ub) = (a.normalized().unwrap_or(a), b.normalized().unwrap_or(b));
    lerp_v(ua, ub, s).normalized().unwrap_or(ua)
}

/// Interpolate two lights of the same type.
fn lerp_light(a: &Light, b: &Light, s: f64) -> Light {
    match (a, b) {
        (Light::Directional(x), Light::Directional(y)) => {
            let mut l = x.clone();
            l.direction = nlerp(x.direction, y.direction, s);
            l.color = lerp3(x.color, y.color, s);
            l.intensity = lerp(x.intensity, y.intensity, s);
            Light::Directional(l)
        }
        (Light::Point(x), Light::Point(y)) => {
            let mut l = x.clone();
            l.position = lerp_v(x.position, y.position, s);
            l.color = lerp3(x.color, y.color, s);
            l.intensity = lerp(x.intensity, y.intensity, s);
            Light::Point(l)
        }
        (Light::Spot(x), Light::Spot(y)) => {
            let mut l = x.clone();
            l.position = lerp_v(x.position, y.position, s);
            l.direction = nlerp(x.direction, y.direction, s);
            l.cone_deg = lerp(x.cone_deg, y.cone_deg, s);
            l.softness_deg = lerp(x.softness_deg, y.softness_deg, s);
            l.color = lerp3(x.color, y.color, s);
            l.intensity = lerp(x.intensity, y.intensity, s);
            Light::Spot(l)
        }
        (Light::Projector(x), Light::Projector(y)) => {
            let mut l = x.clone();
            l.position = lerp_v(x.position, y.position, s);
            l.direction = nlerp(x.direction, y.direction, s);
            l.up = nlerp(x.up, y.up, s);
            l.fov_deg = lerp(x.fov_deg, y.fov_deg, s);
            l.color = lerp3(x.color, y.color, s);
            l.intensity = lerp(x.intensity, y.intensity, s);
            Light::Projector(l)
        }
        (Light::Area(x), Light::Area(y)) => {
            let shape = match (&x.shape, &y.shape) {
                (
                    AreaShape::Rect {
                        center: c0,
                        u: u0,
                        v: v0,
                    },
                    AreaShape::Rect {
                        center: c1,
                        u: u1,
                        v: v1,
                    },
                ) => AreaShape::Rect {
                    center: lerp_v(*c0, *c1, s),
                    u: lerp_v(*u0, *u1, s),
                    v: lerp_v(*v0, *v1, s),
                },
                (
                    AreaShape::Disk {
                        center: c0,
                        normal: n0,
                        radius: r0,
                    },
                    AreaShape::Disk {
                        center: c1,
                        normal: n1,
                        radius: r1,
                    },
                ) => AreaShape::Disk {
                    center: lerp_v(*c0, *c1, s),
                    normal: nlerp(*n0, *n1, s),
                    radius: lerp(*r0, *r1, s),
                },
                _ => x.shape.clone(),
            };
            Light::Area(AreaLight {
                shape,
                color: lerp3(x.color, y.color, s),
                intensity: lerp(x.intensity, y.intensity, s),
                ..x.clone()
            })
        }
        (Light::Environment(x), Light::Environment(y)) => {
            let mut l = x.clone();
            l.yaw_deg = lerp(x.yaw_deg, y.yaw_deg, s);
            l.pitch_deg = lerp(x.pitch_deg, y.pitch_deg, s);
            l.roll_deg = lerp(x.roll_deg, y.roll_deg, s);
            l.color = lerp3(x.color, y.color, s);
            l.intensity = lerp(x.intensity, y.intensity, s);
            Light::Environment(l)
        }
        _ => a.clone(),
    }
}
