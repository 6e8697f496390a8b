//! What lights one frame, in the form the shader reads (`Frame` in relight.wgsl).
//!
//! Uniform lights (directional, environment) become *passes*: one weight per plane.
//! On linear maps every such light folds into a single pass before any pixel is
//! touched, exactly as the CPU engine folds them; on display-referred maps each light
//! keeps its own pass so that it can be decoded from sRGB before lights are added.
//! Positional lights (point, spot) are sent as they are and evaluated per pixel.

use crate::error::{invalid, GpuError, Result};
use crate::storage::PlaneCoding;
use bytemuck::{Pod, Zeroable};
use relit::light::{Attenuation, PreparedLight};
use relit::sphere::Vec3;

/// The most SH coefficients a pass holds (8 bands).
pub const MAX_K: usize = 64;
/// The most uniform passes per frame (only display-referred maps need more than one).
pub const MAX_PASSES: usize = 16;
/// The most positional lights per frame.
pub const MAX_POSITIONAL: usize = 32;

/// `Pass` in relight.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct PassGpu {
    tint: [f32; 4],
    offset: [f32; 4],
    w: [[f32; 4]; MAX_K],
}

/// `PosLight` in relight.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct PosLightGpu {
    position: [f32; 4],
    rgb: [f32; 4],
    axis: [f32; 4],
    cone: [f32; 4],
}

/// `Frame` in relight.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct FrameGpu {
    counts: [u32; 4],
    passes: [PassGpu; MAX_PASSES],
    lights: [PosLightGpu; MAX_POSITIONAL],
}

/// A positional light with its RGB (colour × intensity × exposure).
#[derive(Clone, Debug)]
struct Positional {
    position: Vec3,
    rgb: [f64; 3],
    attenuation: Attenuation,
    /// Unit axis and the cosines of the outer and inner cone, for a spotlight.
    spot: Option<(Vec3, f64, f64)>,
}

/// The lights of one frame for a [`crate::GpuRelighter`], built by its `lighting*` methods.
#[derive(Clone, Debug)]
pub struct Lighting {
    k: usize,
    display: bool,
    /// Linear maps: Σ over uniform lights of rgb × weights, per channel and coefficient.
    folded: Option<[Vec<f64>; 3]>,
    /// Display-referred maps: one (weights, rgb) pass per uniform light.
    passes: Vec<([Vec<f64>; 3], [f64; 3])>,
    positional: Vec<Positional>,
}

impl Lighting {
    pub(crate) fn new(k: usize, display: bool) -> Self {
        Self {
            k,
            display,
            folded: None,
            passes: Vec::new(),
            positional: Vec::new(),
        }
    }

    /// Whether any light needs the per-pixel surface points.
    pub fn has_positional(&self) -> bool {
        !self.positional.is_empty()
    }

    /// Coefficients per channel the lighting was built for.
    pub fn k(&self) -> usize {
        self.k
    }

    /// Whether it was built for display-referred maps.
    pub fn display(&self) -> bool {
        self.display
    }

    /// Add a uniform light: `weights[c][i]` per channel `c` and coefficient `i` (a
    /// directional light's basis values, or an environment's
    /// `EnvironmentLight::light_weights`), scaled by `rgb` (colour × intensity ×
    /// 2^exposure). On display-referred maps each call is one light, decoded from sRGB
    /// on its own.
    pub fn add_uniform(&mut self, weights: [Vec<f64>; 3], rgb: [f64; 3]) -> Result<()> {
        if weights.iter().any(|w| w.len() != self.k) {
            return Err(invalid(format!(
                "a uniform light needs {} weights per channel, got {}",
                self.k,
                weights[0].len()
            )));
        }
        if weights.iter().flatten().chain(&rgb).any(|v| !v.is_finite()) {
            return Err(invalid("light weights and colours must be finite"));
        }
        if self.display {
            self.passes.push((weights, rgb));
        } else {
            let k = self.k;
            let folded = self
                .folded
                .get_or_insert_with(|| std::array::from_fn(|_| vec![0.0; k]));
            for c in 0..3 {
                for i in 0..k {
                    folded[c][i] += rgb[c] * weights[c][i];
                }
            }
        }
        Ok(())
    }

    /// Add a prepared positional light with its RGB already scaled by the exposure.
    pub(crate) fn add_positional(&mut self, light: &PreparedLight, scale: f64) -> Result<()> {
        let entry = match light {
            PreparedLight::Point(l, rgb) => Positional {
                position: l.position,
                rgb: rgb.map(|v| v * scale),
                attenuation: l.attenuation,
                spot: None,
            },
            PreparedLight::Spot(l, rgb) => {
                let axis = l
                    .direction
                    .normalized()
                    .ok_or_else(|| invalid("a spotlight needs a non-zero direction"))?;
                let outer = l.cone_deg.to_radians().cos();
                let inner = (l.cone_deg - l.softness_deg).max(0.0).to_radians().cos();
                Positional {
                    position: l.position,
                    rgb: rgb.map(|v| v * scale),
                    attenuation: l.attenuation,
                    spot: Some((axis, outer, inner)),
                }
            }
            PreparedLight::Projector(..) => {
                return Err(GpuError::Unsupported(
                    "projector lights (use the CPU engine)".into(),
                ))
            }
            PreparedLight::Area(..) => {
                return Err(GpuError::Unsupported(
                    "area lights (use the CPU engine)".into(),
                ))
            }
            _ => return Err(invalid("only point and spot lights are positional")),
        };
        self.positional.push(entry);
        Ok(())
    }

    /// The shader's `Frame`, with the storage's per-plane coding folded into the passes.
    pub(crate) fn to_gpu(&self, coding: &PlaneCoding) -> Result<Box<FrameGpu>> {
        let uniform: Vec<(&[Vec<f64>; 3], [f64; 3])> = match &self.folded {
            Some(w) => vec![(w, [1.0; 3])],
            None => self.passes.iter().map(|(w, rgb)| (w, *rgb)).collect(),
        };
        if uniform.len() > MAX_PASSES {
            return Err(GpuError::Unsupported(format!(
                "{} directional or environment lights on display-referred maps (at most {MAX_PASSES} per frame)",
                uniform.len()
            )));
        }
        if self.positional.len() > MAX_POSITIONAL {
            return Err(GpuError::Unsupported(format!(
                "{} positional lights (at most {MAX_POSITIONAL} per frame)",
                self.positional.len()
            )));
        }
        let mut frame: Box<FrameGpu> = bytemuck::zeroed_box();
        frame.counts = [uniform.len() as u32, self.positional.len() as u32, 0, 0];
        for (dst, (weights, tint)) in frame.passes.iter_mut().zip(&uniform) {
            let mut offset = [0f64; 3];
            for c in 0..3 {
                for i in 0..self.k {
                    let j = 3 * i + c;
                    dst.w[i][c] = (weights[c][i] * coding.scale[j] as f64) as f32;
                    offset[c] += weights[c][i] * coding.bias[j] as f64;
                }
                dst.offset[c] = offset[c] as f32;
                dst.tint[c] = tint[c] as f32;
            }
        }
        for (dst, l) in frame.lights.iter_mut().zip(&self.positional) {
            let (kind, c0) = match l.attenuation {
                Attenuation::InverseSquare => (0.0, 0.0),
                Attenuation::InverseDistance(c0) => (1.0, c0),
                Attenuation::None => (2.0, 0.0),
            };
            dst.position = [
                l.position.x as f32,
                l.position.y as f32,
                l.position.z as f32,
                kind,
            ];
            dst.rgb = [l.rgb[0] as f32, l.rgb[1] as f32, l.rgb[2] as f32, c0 as f32];
            if let Some((axis, outer, inner)) = l.spot {
                dst.axis = [axis.x as f32, axis.y as f32, axis.z as f32, 1.0];
                dst.cone = [outer as f32, inner as f32, 0.0, 0.0];
            }
        }
        Ok(frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_maps_fold_uniform_lights_into_one_pass() {
        let coding = PlaneCoding {
            scale: vec![2.0; 3],
            bias: vec![0.5; 3],
        };
        let mut l = Lighting::new(1, false);
        l.add_uniform([vec![1.0], vec![2.0], vec![3.0]], [1.0, 1.0, 0.5])
            .unwrap();
        l.add_uniform([vec![1.0], vec![1.0], vec![1.0]], [1.0, 0.0, 1.0])
            .unwrap();
        let f = l.to_gpu(&coding).unwrap();
        assert_eq!(f.counts[0], 1);
        // weights (2, 2, 2.5), times scale 2; offsets weights × bias.
        assert_eq!(&f.passes[0].w[0][..3], &[4.0, 4.0, 5.0]);
        assert_eq!(&f.passes[0].offset[..3], &[1.0, 1.0, 1.25]);
        assert!(l
            .add_uniform([vec![1.0, 2.0], vec![1.0], vec![1.0]], [1.0; 3])
            .is_err());
    }

    #[test]
    fn display_maps_keep_one_pass_per_light_up_to_the_limit() {
        let coding = PlaneCoding {
            scale: vec![1.0; 3],
            bias: vec![0.0; 3],
        };
        let mut l = Lighting::new(1, true);
        for _ in 0..MAX_PASSES {
            l.add_uniform([vec![1.0], vec![1.0], vec![1.0]], [0.5; 3])
                .unwrap();
        }
        assert_eq!(l.to_gpu(&coding).unwrap().counts[0], MAX_PASSES as u32);
        l.add_uniform([vec![1.0], vec![1.0], vec![1.0]], [0.5; 3])
            .unwrap();
        assert!(matches!(l.to_gpu(&coding), Err(GpuError::Unsupported(_))));
    }
}
