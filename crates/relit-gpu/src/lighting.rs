//! What lights one frame, in the form the shader reads (`Frame` in relight.wgsl).
//!
//! Uniform lights (directional, environment) become *passes*: one weight per plane.
//! On linear maps every such light folds into a single pass before any pixel is
//! touched, exactly as the CPU engine folds them; on display-referred maps each light
//! keeps its own pass so that it can be decoded from sRGB before lights are added.
//! Positional lights (point, spot) are sent as they are and evaluated per pixel;
//! projectors carry their frustum and the place of their slide in the frame's slide
//! buffer, area lights their emitter and strata (`relit::light::{projector, area}`).

use crate::error::{invalid, GpuError, Result};
use bytemuck::{Pod, Zeroable};
use relit::image::ImageRgb;
use relit::light::{AreaLight, AreaShape, Attenuation, PreparedLight, ProjectorLight};
use relit::sphere::Vec3;
use relit::storage::PlaneCoding;
use std::sync::Arc;

/// The most coefficients per colour channel (the shader's arrays hold 64).
pub const MAX_K: usize = 64;
/// The most uniform passes per frame (only display-referred maps need more than one):
/// an environment's lights on such maps and 32 more.
pub const MAX_PASSES: usize = relit::engine::DISPLAY_ENVIRONMENT_LIGHTS + 32;
/// The most positional lights per frame.
pub const MAX_POSITIONAL: usize = 32;
/// The most projectors per frame.
pub const MAX_PROJECTORS: usize = 8;
/// The most area lights per frame.
pub const MAX_AREAS: usize = 8;
/// The most samples of one area light (`AreaLight::validate` allows as many).
const MAX_AREA_SAMPLES: usize = 4096;

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

/// `Projector` in relight.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ProjectorGpu {
    position: [f32; 4],
    forward: [f32; 4],
    right: [f32; 4],
    up: [f32; 4],
    rgb: [f32; 4],
    slide: [u32; 4],
}

/// `Area` in relight.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct AreaGpu {
    center: [f32; 4],
    u: [f32; 4],
    v: [f32; 4],
    normal: [f32; 4],
    rgb: [f32; 4],
    strata: [u32; 4],
}

/// `Frame` in relight.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct FrameGpu {
    counts: [u32; 4],
    passes: [PassGpu; MAX_PASSES],
    lights: [PosLightGpu; MAX_POSITIONAL],
    projectors: [ProjectorGpu; MAX_PROJECTORS],
    areas: [AreaGpu; MAX_AREAS],
}

/// A projector: its frustum (as `ProjectorLight::with_slide` computes it), RGB and slide.
#[derive(Clone, Debug)]
struct Projector {
    position: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_half_x: f64,
    tan_half_y: f64,
    attenuation: Attenuation,
    rgb: [f64; 3],
    slide: Arc<ImageRgb>,
}

/// An area light and its RGB (colour × intensity × exposure).
#[derive(Clone, Debug)]
struct Area {
    light: AreaLight,
    rgb: [f64; 3],
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
    projectors: Vec<Projector>,
    areas: Vec<Area>,
}

impl Lighting {
    pub(crate) fn new(k: usize, display: bool) -> Self {
        Self {
            k,
            display,
            folded: None,
            passes: Vec::new(),
            positional: Vec::new(),
            projectors: Vec::new(),
            areas: Vec::new(),
        }
    }

    /// Whether the frame has projector or area lights (the full pipeline's code).
    pub(crate) fn has_projectors_or_areas(&self) -> bool {
        !(self.projectors.is_empty() && self.areas.is_empty())
    }

    /// Whether any light needs the per-pixel surface points.
    pub fn has_positional(&self) -> bool {
        !(self.positional.is_empty() && self.projectors.is_empty() && self.areas.is_empty())
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
    /// `BasisEnvironment::weights`), scaled by `rgb` (colour × intensity ×
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

    /// Add a prepared point, spot or area light, its RGB scaled by `scale` (2^exposure).
    /// Add a light prepared by the CPU engine for maps of `basis` (the GPU engine's):
    /// directional lights and environment weights as uniform passes, the rest as
    /// positional lights; its colour times `scale`.
    pub fn add_prepared(
        &mut self,
        basis: &dyn relit::basis::Basis,
        light: &PreparedLight,
        scale: f64,
    ) -> Result<()> {
        match light {
            PreparedLight::Directional { direction, rgb } => {
                let y = basis.values(*direction);
                self.add_uniform([y.clone(), y.clone(), y], rgb.map(|v| v * scale))
            }
            PreparedLight::Weights(w) => self.add_uniform(w.clone(), [scale; 3]),
            positional => self.add_positional(positional, scale),
        }
    }

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
            PreparedLight::Area(l, rgb) => {
                l.validate().map_err(|e| invalid(e.to_string()))?;
                if l.samples > MAX_AREA_SAMPLES {
                    return Err(invalid("an area light has at most 4096 samples"));
                }
                self.areas.push(Area {
                    light: l.clone(),
                    rgb: rgb.map(|v| v * scale),
                });
                return Ok(());
            }
            _ => {
                return Err(invalid(
                    "only point, spot and area lights are positional here",
                ))
            }
        };
        self.positional.push(entry);
        Ok(())
    }

    /// Add a projector with its slide (linear RGB, as `ProjectorLight::prepare` loads
    /// it; `light.slide` is not read) and `rgb` (colour × intensity × 2^exposure).
    /// Frames upload a slide again only when the frame's slides change.
    pub fn add_projector(
        &mut self,
        light: &ProjectorLight,
        slide: Arc<ImageRgb>,
        rgb: [f64; 3],
    ) -> Result<()> {
        light.validate().map_err(|e| invalid(e.to_string()))?;
        if rgb.iter().any(|v| !v.is_finite()) {
            return Err(invalid("light colours must be finite"));
        }
        if slide.data.len() != 3 * slide.width * slide.height {
            return Err(invalid("the slide's pixels do not match its size"));
        }
        // The frame of `ProjectorLight::with_slide`, computed the same way.
        let forward = light.direction.normalized().expect("validated");
        let right = forward.cross(light.up).normalized().expect("validated");
        let up = right.cross(forward);
        let tan_half_y = (0.5 * light.fov_deg.to_radians()).tan();
        let aspect = slide.width as f64 / slide.height.max(1) as f64;
        self.projectors.push(Projector {
            position: light.position,
            forward,
            right,
            up,
            tan_half_x: tan_half_y * aspect,
            tan_half_y,
            attenuation: light.attenuation,
            rgb,
            slide,
        });
        Ok(())
    }

    /// The distinct slides of the projectors, in the order the frame's offsets count
    /// them (each `3 · width · height` floats after the previous).
    pub(crate) fn slides(&self) -> Vec<Arc<ImageRgb>> {
        let mut out: Vec<Arc<ImageRgb>> = Vec::new();
        for p in &self.projectors {
            if !out.iter().any(|s| Arc::ptr_eq(s, &p.slide)) {
                out.push(p.slide.clone());
            }
        }
        out
    }

    /// The shader's `Frame`, with the storage's per-plane coding folded into the passes:
    /// `Σ_i w_i (offset_i + scale_i q_i) = Σ_i (w_i scale_i) q_i + Σ_i w_i offset_i`.
    pub(crate) fn to_gpu(&self, coding: &[PlaneCoding]) -> Result<Box<FrameGpu>> {
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
        if self.projectors.len() > MAX_PROJECTORS {
            return Err(GpuError::Unsupported(format!(
                "{} projectors (at most {MAX_PROJECTORS} per frame)",
                self.projectors.len()
            )));
        }
        if self.areas.len() > MAX_AREAS {
            return Err(GpuError::Unsupported(format!(
                "{} area lights (at most {MAX_AREAS} per frame)",
                self.areas.len()
            )));
        }
        let mut frame: Box<FrameGpu> = bytemuck::zeroed_box();
        frame.counts = [
            uniform.len() as u32,
            self.positional.len() as u32,
            self.projectors.len() as u32,
            self.areas.len() as u32,
        ];
        for (dst, (weights, tint)) in frame.passes.iter_mut().zip(&uniform) {
            let mut offset = [0f64; 3];
            for c in 0..3 {
                for i in 0..self.k {
                    let j = 3 * i + c;
                    dst.w[i][c] = (weights[c][i] * coding[j].scale as f64) as f32;
                    offset[c] += weights[c][i] * coding[j].offset as f64;
                }
                dst.offset[c] = offset[c] as f32;
                dst.tint[c] = tint[c] as f32;
            }
        }
        for (dst, l) in frame.lights.iter_mut().zip(&self.positional) {
            let (kind, c0) = attenuation_code(l.attenuation);
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
        let slides = self.slides();
        let mut offsets = Vec::with_capacity(slides.len());
        let mut at = 0usize;
        for s in &slides {
            offsets.push(at);
            at += s.data.len();
        }
        if at > u32::MAX as usize {
            return Err(GpuError::TooLarge(format!(
                "projector slides of {at} values (at most {} per frame)",
                u32::MAX
            )));
        }
        let f4 = |v: Vec3, w: f64| [v.x as f32, v.y as f32, v.z as f32, w as f32];
        for (dst, p) in frame.projectors.iter_mut().zip(&self.projectors) {
            let (kind, c0) = attenuation_code(p.attenuation);
            let i = slides
                .iter()
                .position(|s| Arc::ptr_eq(s, &p.slide))
                .expect("listed");
            let empty = p.slide.data.is_empty() || p.slide.width == 0 || p.slide.height == 0;
            dst.position = f4(p.position, kind as f64);
            dst.forward = f4(p.forward, c0);
            dst.right = f4(p.right, p.tan_half_x);
            dst.up = f4(p.up, p.tan_half_y);
            dst.rgb = [p.rgb[0] as f32, p.rgb[1] as f32, p.rgb[2] as f32, 0.0];
            dst.slide = [
                offsets[i] as u32,
                p.slide.width as u32,
                p.slide.height as u32,
                (!empty) as u32,
            ];
        }
        for (dst, a) in frame.areas.iter_mut().zip(&self.areas) {
            let l = &a.light;
            let (columns, rows) = l.strata();
            let weight = (l.area() / l.samples as f64) as f32;
            match &l.shape {
                AreaShape::Rect { center, u, v } => {
                    let n = u.cross(*v).normalized().expect("validated");
                    dst.center = f4(*center, 0.0);
                    dst.u = f4(*u, 0.0);
                    dst.v = f4(*v, 0.0);
                    dst.normal = f4(n, l.two_sided as u8 as f64);
                }
                AreaShape::Disk { center, radius, .. } => {
                    let (n, da, db) = l.disk_frame().expect("a disk has a frame");
                    dst.center = f4(*center, 1.0);
                    dst.u = f4(da, *radius);
                    dst.v = f4(db, 0.0);
                    dst.normal = f4(n, l.two_sided as u8 as f64);
                }
            }
            dst.rgb = [a.rgb[0] as f32, a.rgb[1] as f32, a.rgb[2] as f32, weight];
            dst.strata = [l.samples as u32, columns as u32, rows as u32, 0];
        }
        Ok(frame)
    }
}

/// The shader's code of a falloff (0 inverse square, 1 `c0 / d`, 2 none) and its `c0`.
fn attenuation_code(a: Attenuation) -> (f32, f64) {
    match a {
        Attenuation::InverseSquare => (0.0, 0.0),
        Attenuation::InverseDistance(c0) => (1.0, c0),
        Attenuation::None => (2.0, 0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shader's `Frame` declares the arrays `FrameGpu` holds, size for size.
    #[test]
    fn the_shaders_frame_holds_what_the_engine_sends() {
        let wgsl = include_str!("../shaders/relight.wgsl");
        for decl in [
            format!("passes: array<Pass, {MAX_PASSES}>"),
            format!("lights: array<PosLight, {MAX_POSITIONAL}>"),
            format!("projectors: array<Projector, {MAX_PROJECTORS}>"),
            format!("areas: array<Area, {MAX_AREAS}>"),
            format!("w: array<vec4<f32>, {MAX_K}>"),
        ] {
            assert!(wgsl.contains(&decl), "relight.wgsl lacks `{decl}`");
        }
    }

    #[test]
    fn linear_maps_fold_uniform_lights_into_one_pass() {
        let coding = [PlaneCoding {
            scale: 2.0,
            offset: 0.5,
        }; 3];
        let mut l = Lighting::new(1, false);
        l.add_uniform([vec![1.0], vec![2.0], vec![3.0]], [1.0, 1.0, 0.5])
            .unwrap();
        l.add_uniform([vec![1.0], vec![1.0], vec![1.0]], [1.0, 0.0, 1.0])
            .unwrap();
        let f = l.to_gpu(&coding).unwrap();
        assert_eq!(f.counts[0], 1);
        // weights (2, 2, 2.5), times scale 2; offsets weights × offset.
        assert_eq!(&f.passes[0].w[0][..3], &[4.0, 4.0, 5.0]);
        assert_eq!(&f.passes[0].offset[..3], &[1.0, 1.0, 1.25]);
        assert!(l
            .add_uniform([vec![1.0, 2.0], vec![1.0], vec![1.0]], [1.0; 3])
            .is_err());
    }

    #[test]
    fn display_maps_keep_one_pass_per_light_up_to_the_limit() {
        let coding = [PlaneCoding::IDENTITY; 3];
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
