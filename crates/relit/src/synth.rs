//! A tiny analytic scene for tests and examples: a bumpy, striped, glossy plane seen
//! from above, shaded with Lambert plus Blinn–Phong under one directional light.
//!
//! It has no geometry to trace, so its images under any light are exact and cheap;
//! the capture studio (ray tracer) is the source of richer scenes.

use crate::camera::Projection;
use crate::capture::{Capture, ImageGenerator};
use crate::image::{self, ImageRgb};
use crate::sphere::Vec3;
use crate::Result;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The bumpy plane at `width×height` pixels.
#[derive(Clone, Copy, Debug)]
pub struct BumpyPlane {
    pub width: usize,
    pub height: usize,
}

impl BumpyPlane {
    fn height_at(u: f64, v: f64) -> f64 {
        use std::f64::consts::TAU;
        let dome = (-((u - 0.5).powi(2) + (v - 0.5).powi(2)) * 18.0).exp();
        0.05 * (TAU * 3.0 * u).sin() * (TAU * 2.0 * v).cos() + 0.25 * dome
    }

    /// Normal (light frame: x right, y up, z toward the camera) and albedo of pixel (x, y).
    fn surface(&self, x: usize, y: usize) -> (Vec3, [f64; 3]) {
        let (u, v) = (
            (x as f64 + 0.5) / self.width as f64,
            (y as f64 + 0.5) / self.height as f64,
        );
        let e = 1e-4;
        let dhdu = (Self::height_at(u + e, v) - Self::height_at(u - e, v)) / (2.0 * e);
        let dhdv = (Self::height_at(u, v + e) - Self::height_at(u, v - e)) / (2.0 * e);
        // Image v grows downward, the frame's y upward.
        let n = Vec3::new(-dhdu, dhdv, 1.0).normalized().expect("finite");
        let stripe = (u * 5.0).floor() as usize % 3;
        let albedo = match stripe {
            0 => [0.7, 0.35, 0.2],
            1 => [0.25, 0.55, 0.3],
            _ => [0.3, 0.35, 0.75],
        };
        (n, albedo.map(|a| a * (0.75 + 0.25 * v)))
    }

    /// The image under a unit directional light toward `light`.
    pub fn render(&self, light: Vec3) -> ImageRgb {
        let l = light.normalized().expect("a light direction");
        let view = Vec3::new(0.0, 0.0, 1.0);
        let half = (l + view).normalized().unwrap_or(view);
        let mut img = ImageRgb::new(self.width, self.height);
        for y in 0..self.height {
            for x in 0..self.width {
                let (n, albedo) = self.surface(x, y);
                let diffuse = n.dot(l).max(0.0);
                let spec = if diffuse > 0.0 {
                    0.15 * n.dot(half).max(0.0).powi(12)
                } else {
                    0.0
                };
                let o = 3 * (y * self.width + x);
                for (dst, a) in img.data[o..o + 3].iter_mut().zip(albedo) {
                    *dst = (0.8 * a * diffuse + spec) as f32;
                }
            }
        }
        img
    }

    /// A capture under `dirs` whose images are rendered when the fit asks for them.
    pub fn capture(&self, dirs: &[Vec3]) -> Capture {
        let generators: Vec<Arc<dyn ImageGenerator>> = dirs
            .iter()
            .map(|&light| {
                Arc::new(PlaneUnderLight {
                    plane: *self,
                    light,
                }) as Arc<dyn ImageGenerator>
            })
            .collect();
        Capture::from_generators(
            generators,
            dirs,
            self.width,
            self.height,
            Projection::Planar { fov_y_deg: None },
        )
        .expect("consistent synthetic capture")
    }

    /// Write the capture as 8-bit sRGB PNGs plus `dirs.lp` into `folder`; returns the `.lp` path.
    pub fn write_lp_capture(&self, folder: &Path, dirs: &[Vec3]) -> Result<PathBuf> {
        let mut names = Vec::with_capacity(dirs.len());
        for (j, &d) in dirs.iter().enumerate() {
            let name = format!("light {j:03}.png");
            image::save(&folder.join(&name), &self.render(d), 0.0)?;
            names.push(name);
        }
        let lp = folder.join("dirs.lp");
        crate::fsutil::write_bytes_atomically(
            &lp,
            crate::capture::lp::format(&names, dirs).as_bytes(),
        )?;
        Ok(lp)
    }
}

/// The plane under one light, rendered on demand.
#[derive(Debug)]
struct PlaneUnderLight {
    plane: BumpyPlane,
    light: Vec3,
}

impl ImageGenerator for PlaneUnderLight {
    fn generate(&self) -> Result<ImageRgb> {
        Ok(self.plane.render(self.light))
    }
}

/// Shorthand for `BumpyPlane { width, height }.capture(dirs)`.
pub fn bumpy_plane(width: usize, height: usize, dirs: &[Vec3]) -> Capture {
    BumpyPlane { width, height }.capture(dirs)
}
