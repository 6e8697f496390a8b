//! The pinhole camera of an ordinary photograph.

use super::{check_fov, check_size, CameraModel, ColumnRay, Projection, Ray, RayFactors, RowRay};
use crate::sphere::Vec3;
use crate::Result;

/// A pinhole at the origin looking along −z, with square pixels and vertical field of
/// view `fov_y_deg`; the image plane sits at z = −1.
#[derive(Clone, Debug, PartialEq)]
pub struct Perspective {
    width: usize,
    height: usize,
    fov_y_deg: f64,
    /// Half extents of the image plane at z = −1.
    half_width: f64,
    half_height: f64,
}

impl Perspective {
    pub fn new(width: usize, height: usize, fov_y_deg: f64) -> Result<Perspective> {
        check_size(width, height)?;
        let fov_y_deg = check_fov(fov_y_deg)?;
        let half_height = (fov_y_deg.to_radians() / 2.0).tan();
        let half_width = half_height * width as f64 / height as f64;
        Ok(Perspective {
            width,
            height,
            fov_y_deg,
            half_width,
            half_height,
        })
    }

    pub fn fov_y_deg(&self) -> f64 {
        self.fov_y_deg
    }
}

impl CameraModel for Perspective {
    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn ray(&self, x: f64, y: f64) -> Ray {
        let u = (2.0 * x / self.width as f64 - 1.0) * self.half_width;
        let v = (1.0 - 2.0 * y / self.height as f64) * self.half_height;
        let direction = Vec3::new(u, v, -1.0) * (1.0 / (u * u + v * v + 1.0).sqrt());
        Ray {
            origin: Vec3::default(),
            direction,
        }
    }

    fn ray_factors(&self) -> RayFactors {
        // (u, v, −1) normalised: image-plane x per column, y per row.
        RayFactors {
            columns: (0..self.width)
                .map(|i| ColumnRay {
                    origin: Vec3::default(),
                    direction: Vec3::new(
                        (2.0 * (i as f64 + 0.5) / self.width as f64 - 1.0) * self.half_width,
                        0.0,
                        0.0,
                    ),
                })
                .collect(),
            rows: (0..self.height)
                .map(|j| RowRay {
                    origin: Vec3::default(),
                    scale: 1.0,
                    direction: Vec3::new(
                        0.0,
                        (1.0 - 2.0 * (j as f64 + 0.5) / self.height as f64) * self.half_height,
                        -1.0,
                    ),
                })
                .collect(),
            norm_per_row: false,
        }
    }

    fn pixel(&self, p: Vec3) -> Option<[f64; 2]> {
        if p.z >= 0.0 || !p.is_finite() {
            return None;
        }
        let (u, v) = (p.x / -p.z, p.y / -p.z);
        let x = (u / self.half_width + 1.0) * 0.5 * self.width as f64;
        let y = (1.0 - v / self.half_height) * 0.5 * self.height as f64;
        ((0.0..=self.width as f64).contains(&x) && (0.0..=self.height as f64).contains(&y))
            .then_some([x, y])
    }

    fn depth(&self, p: Vec3) -> f64 {
        p.length()
    }

    fn projection(&self) -> Projection {
        Projection::Planar {
            fov_y_deg: Some(self.fov_y_deg),
        }
    }
}
