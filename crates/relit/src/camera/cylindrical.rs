//! The cylindrical panorama of seed 004: 360° around the vertical axis.

use super::{
    azimuth_columns, check_fov, check_size, column_azimuth, panorama_azimuth, panorama_column,
    CameraModel, Projection, Ray, RayFactors, RowRay,
};
use crate::sphere::Vec3;
use crate::Result;
use std::f64::consts::TAU;

/// A unit cylinder around the camera's y axis. Column `x` looks at azimuth
/// `(x / width − ½)·360°` from −z toward +x (the centre column looks along −z, the
/// image pans right as x grows); rows are evenly spaced in height on the cylinder,
/// which is `2π·height/width` high (square pixels) or `2·tan(fov/2)` for a field of view.
#[derive(Clone, Debug, PartialEq)]
pub struct Cylindrical {
    width: usize,
    height: usize,
    fov_y_deg: Option<f64>,
    /// Height of the image on the unit cylinder.
    span: f64,
}

impl Cylindrical {
    pub fn new(width: usize, height: usize, fov_y_deg: Option<f64>) -> Result<Cylindrical> {
        check_size(width, height)?;
        let span = match fov_y_deg {
            Some(fov) => 2.0 * (check_fov(fov)?.to_radians() / 2.0).tan(),
            None => TAU * height as f64 / width as f64,
        };
        Ok(Cylindrical {
            width,
            height,
            fov_y_deg,
            span,
        })
    }
}

impl CameraModel for Cylindrical {
    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn ray(&self, x: f64, y: f64) -> Ray {
        let phi = column_azimuth(x, self.width);
        let h = (0.5 - y / self.height as f64) * self.span;
        let direction = Vec3::new(phi.sin(), h, -phi.cos()) * (1.0 / (1.0 + h * h).sqrt());
        Ray {
            origin: Vec3::default(),
            direction,
        }
    }

    fn ray_factors(&self) -> RayFactors {
        // (sin φ, h, −cos φ) normalised: the azimuth per column, the height per row.
        RayFactors {
            columns: azimuth_columns(self.width),
            rows: (0..self.height)
                .map(|j| RowRay {
                    origin: Vec3::default(),
                    scale: 1.0,
                    direction: Vec3::new(
                        0.0,
                        (0.5 - (j as f64 + 0.5) / self.height as f64) * self.span,
                        0.0,
                    ),
                })
                .collect(),
            norm_per_row: true,
        }
    }

    fn pixel(&self, p: Vec3) -> Option<[f64; 2]> {
        let radius = p.x.hypot(p.z);
        if !p.is_finite() || radius <= 1e-300 {
            return None;
        }
        let x = panorama_column(panorama_azimuth(p), self.width);
        let y = (0.5 - p.y / radius / self.span) * self.height as f64;
        (0.0..=self.height as f64).contains(&y).then_some([x, y])
    }

    fn depth(&self, p: Vec3) -> f64 {
        p.length()
    }

    fn projection(&self) -> Projection {
        Projection::Cylindrical {
            fov_y_deg: self.fov_y_deg,
        }
    }
}
