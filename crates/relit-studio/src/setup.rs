//! Choosing a camera for a scene from short strings (`cylindrical`, `perspective:40`,
//! `640x480`), as the command line and callers that mimic it do.
//!
//! The camera keeps the scene's pose (where its designer put the eye); the
//! projection and size default to the scene's own, and a projection of another kind
//! brings its own usual size.

use crate::scene::Scene;
use crate::{parse_error, Result};
use relit::camera::{Camera, CameraSpec, Projection};

/// The pinhole field of view when `perspective` gives none.
pub const DEFAULT_FOV_Y_DEG: f64 = 50.0;

/// A projection asked for by name.
#[derive(Clone, Debug, PartialEq)]
pub struct ProjectionChoice {
    pub projection: Projection,
    /// Height of the image plane of an orthographic camera.
    pub orthographic_height: Option<f64>,
}

/// Parse `cylindrical[:FOV]`, `equirect`, `perspective[:FOV]` or `orthographic[:HEIGHT]`.
pub fn parse_projection(spec: &str) -> Result<ProjectionChoice> {
    let (kind, arg) = match spec.split_once(':') {
        Some((k, a)) => (k, Some(a)),
        None => (spec, None),
    };
    let number = |what: &str| -> Result<Option<f64>> {
        arg.map(|a| {
            a.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v > 0.0)
                .ok_or_else(|| {
                    parse_error(format!(
                        "bad camera `{spec}`: `{a}` is not a positive {what}"
                    ))
                })
        })
        .transpose()
    };
    let choice = |projection| ProjectionChoice {
        projection,
        orthographic_height: None,
    };
    match kind.trim().to_ascii_lowercase().as_str() {
        "cylindrical" | "cylinder" | "cyl" => Ok(choice(Projection::Cylindrical { fov_y_deg: number("field of view")? })),
        "equirect" | "equirectangular" | "latlong" if arg.is_none() => Ok(choice(Projection::Equirectangular)),
        "perspective" | "pinhole" => {
            Ok(choice(Projection::Planar { fov_y_deg: Some(number("field of view")?.unwrap_or(DEFAULT_FOV_Y_DEG)) }))
        }
        "orthographic" | "ortho" => Ok(ProjectionChoice { projection: Projection::Planar { fov_y_deg: None }, orthographic_height: number("height")? }),
        _ => Err(parse_error(format!(
            "bad camera `{spec}`: expected cylindrical[:FOV], equirect, perspective[:FOV] or orthographic[:HEIGHT]"
        ))),
    }
}

/// Parse `WIDTHxHEIGHT`.
pub fn parse_size(spec: &str) -> Result<(usize, usize)> {
    let bad = || {
        parse_error(format!(
            "bad size `{spec}`: expected WIDTHxHEIGHT, e.g. 1024x256"
        ))
    };
    let (w, h) = spec.split_once(['x', 'X', '×']).ok_or_else(bad)?;
    let (w, h): (usize, usize) = (
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    );
    if w == 0 || h == 0 {
        return Err(bad());
    }
    Ok((w, h))
}

/// The usual size of a projection's images.
fn usual_size(projection: &Projection) -> (usize, usize) {
    match projection {
        Projection::Cylindrical { .. } => (1024, 256),
        Projection::Equirectangular => (1024, 512),
        Projection::Planar { .. } => (640, 480),
    }
}

/// The camera for `scene`: its pose, with `projection` and `size` when given.
pub fn scene_camera(
    scene: &Scene,
    projection: Option<&ProjectionChoice>,
    size: Option<(usize, usize)>,
) -> Result<Camera> {
    let mut spec: CameraSpec = scene.camera.clone();
    if let Some(choice) = projection {
        if std::mem::discriminant(&choice.projection) != std::mem::discriminant(&spec.projection) {
            (spec.width, spec.height) = usual_size(&choice.projection);
        }
        spec.projection = choice.projection.clone();
        spec.orthographic_height = choice.orthographic_height;
    }
    if let Some((w, h)) = size {
        (spec.width, spec.height) = (w, h);
    }
    spec.build()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_strings() {
        assert_eq!(
            parse_projection("perspective").unwrap().projection,
            Projection::Planar {
                fov_y_deg: Some(DEFAULT_FOV_Y_DEG)
            }
        );
        assert_eq!(
            parse_projection("perspective:35").unwrap().projection,
            Projection::Planar {
                fov_y_deg: Some(35.0)
            }
        );
        assert_eq!(
            parse_projection("cylindrical").unwrap().projection,
            Projection::Cylindrical { fov_y_deg: None }
        );
        assert_eq!(
            parse_projection("equirect").unwrap().projection,
            Projection::Equirectangular
        );
        assert_eq!(
            parse_projection("ortho:3").unwrap().orthographic_height,
            Some(3.0)
        );
        for bad in ["fisheye", "perspective:abc", "perspective:-5", "equirect:3"] {
            assert!(parse_projection(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_size("1024x256").unwrap(), (1024, 256));
        for bad in ["1024", "0x5", "ax5", "-3x4"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}
