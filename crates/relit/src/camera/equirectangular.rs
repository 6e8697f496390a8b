//! The latitude–longitude panorama: the whole sphere of directions.

use super::{
    azimuth_columns, check_size, column_azimuth, panorama_azimuth, panorama_column, CameraModel,
    Projection, Ray, RayFactors, RowRay,
};
use crate::sphere::Vec3;
use crate::Result;
use std::f64::consts::PI;

/// Columns are azimuths as for [`super::Cylindrical`] (centre column along −z, +x to
/// the right); rows are evenly spaced in latitude from +90° (top, +y) to −90°.
#[derive(Clone, Debug, PartialEq)]
pub struct Equirectangular {
    width: usize,
    height: usize,
}

impl Equirectangular {
    pub fn new(width: usize, height: usize) -> Result<Equirectangular> {
        check_size(width, height)?;
        Ok(Equirectangular { width, height })
    }
}

impl CameraModel for Equirectangular {
    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn ray(&self, x: f64, y: f64) -> Ray {
        let phi = column_azimuth(x, self.width);
        let latitude = (0.5 - y / self.height as f64) * PI;
        let (s, c) = latitude.sin_cos();
        Ray {
            origin: Vec3::default(),
            direction: Vec3::new(c * phi.sin(), s, -c * phi.cos()),
        }
    }

    fn ray_factors(&self) -> RayFactors {
        // (cos θ·sin φ, sin θ, −cos θ·cos φ): the azimuth per column, the latitude per row.
        RayFactors {
            columns: azimuth_columns(self.width),
            rows: (0..self.height)
                .map(|j| {
                    let latitude = (0.5 - (j as f64 + 0.5) / self.height as f64) * PI;
                    let (s, c) = latitude.sin_cos();
                    RowRay {
                        origin: Vec3::default(),
                        scale: c,
                        direction: Vec3::new(0.0, s, 0.0),
                    }
                })
                .collect(),
            norm_per_row: true,
        }
    }

    fn pixel(&self, p: Vec3) -> Option<[f64; 2]> {
        let radius = p.x.hypot(p.z);
        if !p.is_finite() || p.length() == 0.0 {
            return None;
        }
        // At the poles every column is the same point; column 0's centre stands for them.
        let x = if radius > 0.0 {
            panorama_column(panorama_azimuth(p), self.width)
        } else {
            0.5
        };
        let y = (0.5 - p.y.atan2(radius) / PI) * self.height as f64;
        Some([x, y])
    }

    fn depth(&self, p: Vec3) -> f64 {
        p.length()
    }

    fn projection(&self) -> Projection {
        Projection::Equirectangular
    }
}
