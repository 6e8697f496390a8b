//! The orthographic camera of RTI on a flat object: parallel rays, no perspective.

use super::{check_size, CameraModel, ColumnRay, Projection, Ray, RayFactors, RowRay};
use crate::sphere::Vec3;
use crate::{Error, Result};

/// Parallel rays along −z starting on the plane z = 0, which the image covers with
/// square pixels `view_height` units high in total, centred on the origin.
#[derive(Clone, Debug, PartialEq)]
pub struct Orthographic {
    width: usize,
    height: usize,
    view_height: f64,
    half_width: f64,
    half_height: f64,
}

impl Orthographic {
    pub fn new(width: usize, height: usize, view_height: f64) -> Result<Orthographic> {
        check_size(width, height)?;
        if !(view_height.is_finite() && view_height > 0.0) {
            return Err(Error::invalid(format!(
                "an orthographic view height must be positive, not {view_height}"
            )));
        }
        let half_height = view_height / 2.0;
        let half_width = half_height * width as f64 / height as f64;
        Ok(Orthographic {
            width,
            height,
            view_height,
            half_width,
            half_height,
        })
    }

    /// The height of the image plane in scene units.
    pub fn view_height(&self) -> f64 {
        self.view_height
    }
}

impl CameraModel for Orthographic {
    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn ray(&self, x: f64, y: f64) -> Ray {
        let u = (2.0 * x / self.width as f64 - 1.0) * self.half_width;
        let v = (1.0 - 2.0 * y / self.height as f64) * self.half_height;
        Ray {
            origin: Vec3::new(u, v, 0.0),
            direction: Vec3::new(0.0, 0.0, -1.0),
        }
    }

    fn ray_factors(&self) -> RayFactors {
        // Parallel rays along −z from (u, v, 0): u per column, v per row.
        RayFactors {
            columns: (0..self.width)
                .map(|i| ColumnRay {
                    origin: Vec3::new(
                        (2.0 * (i as f64 + 0.5) / self.width as f64 - 1.0) * self.half_width,
                        0.0,
                        0.0,
                    ),
                    direction: Vec3::default(),
                })
                .collect(),
            rows: (0..self.height)
                .map(|j| RowRay {
                    origin: Vec3::new(
                        0.0,
                        (1.0 - 2.0 * (j as f64 + 0.5) / self.height as f64) * self.half_height,
                        0.0,
                    ),
                    scale: 0.0,
                    direction: Vec3::new(0.0, 0.0, -1.0),
                })
                .collect(),
            norm_per_row: true,
        }
    }

    fn pixel(&self, p: Vec3) -> Option<[f64; 2]> {
        if p.z >= 0.0 || !p.is_finite() {
            return None;
        }
        let x = (p.x / self.half_width + 1.0) * 0.5 * self.width as f64;
        let y = (1.0 - p.y / self.half_height) * 0.5 * self.height as f64;
        ((0.0..=self.width as f64).contains(&x) && (0.0..=self.height as f64).contains(&y))
            .then_some([x, y])
    }

    fn depth(&self, p: Vec3) -> f64 {
        -p.z
    }

    fn projection(&self) -> Projection {
        Projection::Planar { fov_y_deg: None }
    }
}
