//! How the image plane of a capture maps to view directions.
//!
//! Relighting with directional lights needs none of this (every pixel shares one light
//! vector), but the file records it so that lights with a position can later derive a
//! per-pixel light vector from depth (seed 004 eq. 3).

use serde::{Deserialize, Serialize};

/// The projection of a capture's images.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Projection {
    /// An ordinary photograph: a pinhole with vertical field of view `fov_y_deg`, or an
    /// orthographic view (RTI of a flat object) when the field of view is absent.
    Planar {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        fov_y_deg: Option<f64>,
    },
    /// A cylindrical panorama covering 360° horizontally (seed 004's default); pixels are
    /// square on the cylinder unless `fov_y_deg` gives the vertical field of view.
    Cylindrical {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        fov_y_deg: Option<f64>,
    },
    /// A latitude–longitude panorama covering the whole sphere.
    Equirectangular,
}

impl Default for Projection {
    fn default() -> Self {
        Projection::Planar { fov_y_deg: None }
    }
}

impl Projection {
    /// The short name used in summaries.
    pub fn name(&self) -> &'static str {
        match self {
            Projection::Planar { .. } => "planar",
            Projection::Cylindrical { .. } => "cylindrical",
            Projection::Equirectangular => "equirectangular",
        }
    }
}
