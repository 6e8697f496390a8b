//! Cameras: how the image plane of a capture maps to rays in the scene.
//!
//! Relighting with directional lights needs none of this (every pixel shares one light
//! vector), but lights with a position need each pixel's surface point, which comes
//! from the depth map as `P = O + d·V` (seed 004 eq. 3): `O` the ray origin (the eye
//! for every camera but the orthographic one), `V` the unit view direction and `d` the
//! depth. The frame conventions are stated once in the [crate docs](crate), section
//! *Cameras*.
//!
//! [`Projection`] is the stored description (manifests, EXR metadata). A [`Camera`] is
//! the working object: a projection model at a size ([`Model`], one file per model)
//! placed by a [`Pose`]. Adding a model is one new file plus one [`Model`] variant.

mod cylindrical;
mod equirectangular;
mod orthographic;
mod perspective;

pub use cylindrical::Cylindrical;
pub use equirectangular::Equirectangular;
pub use orthographic::Orthographic;
pub use perspective::Perspective;

use crate::sphere::Vec3;
use crate::{Error, Result};
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

/// A ray: `origin + t·direction`, `direction` of unit length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub direction: Vec3,
}

impl Ray {
    /// The point at distance `t` along the ray.
    pub fn at(&self, t: f64) -> Vec3 {
        self.origin + self.direction * t
    }
}

/// The rays through a camera's pixel centres, factored into a part per column and a
/// part per row: the ray through pixel `(i, j)` starts at
/// `rows[j].origin + columns[i].origin` and points along
/// `rows[j].scale · columns[i].direction + rows[j].direction`, normalised.
///
/// Every model relit has factors this way (azimuth per column, height or latitude per
/// row; image-plane x per column, y per row), so the engine can rebuild the surface
/// points `P = O + d·V` from the depth map a block at a time from `width + height`
/// entries instead of holding three more values per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct RayFactors {
    pub columns: Vec<ColumnRay>,
    pub rows: Vec<RowRay>,
    /// The unnormalised direction's length is the same along each row (panoramas and
    /// orthographic views), so a row's normalisation serves all its pixels.
    pub norm_per_row: bool,
}

/// A column's part of [`RayFactors`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColumnRay {
    pub origin: Vec3,
    pub direction: Vec3,
}

/// A row's part of [`RayFactors`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowRay {
    pub origin: Vec3,
    pub scale: f64,
    pub direction: Vec3,
}

impl RayFactors {
    /// The ray through the centre of pixel `(i, j)`.
    pub fn ray(&self, i: usize, j: usize) -> Ray {
        let (c, r) = (self.columns[i], self.rows[j]);
        let d = c.direction * r.scale + r.direction;
        Ray {
            origin: r.origin + c.origin,
            direction: d * (1.0 / d.length()),
        }
    }
}

/// Where a camera stands and how it is turned, in the global light frame.
///
/// `right`, `up` and `back` are the camera's own x, y and z axes: the camera looks
/// along `-back`. They form a right-handed orthonormal basis; [`Pose::identity`]
/// (eye at the origin, axes equal to the light frame's) is the RTI convention.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    pub eye: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub back: Vec3,
}

impl Default for Pose {
    fn default() -> Self {
        Self::identity()
    }
}

impl Pose {
    /// Eye at the origin, looking along −z with y up.
    pub const fn identity() -> Pose {
        Pose {
            eye: Vec3::new(0.0, 0.0, 0.0),
            right: Vec3::new(1.0, 0.0, 0.0),
            up: Vec3::new(0.0, 1.0, 0.0),
            back: Vec3::new(0.0, 0.0, 1.0),
        }
    }

    /// The identity orientation with the eye at `eye`.
    pub fn at(eye: Vec3) -> Pose {
        Pose {
            eye,
            ..Pose::identity()
        }
    }

    /// A camera at `eye` looking at `target`, turned so that `up_hint` points up in the image.
    pub fn look_at(eye: Vec3, target: Vec3, up_hint: Vec3) -> Result<Pose> {
        let back = (eye - target)
            .normalized()
            .ok_or_else(|| Error::invalid("the camera's eye and target coincide"))?;
        let right = up_hint.cross(back).normalized().ok_or_else(|| {
            Error::invalid("the camera's up vector is parallel to its view direction (or zero)")
        })?;
        let up = back.cross(right);
        Ok(Pose {
            eye,
            right,
            up,
            back,
        })
    }

    /// Check that the axes are finite, orthonormal and right-handed.
    pub fn validate(&self) -> Result<()> {
        const TOLERANCE: f64 = 1e-6; // axes written as decimal text keep ~1e-9; this leaves room
        let axes = [self.right, self.up, self.back];
        if !self.eye.is_finite() || axes.iter().any(|a| !a.is_finite()) {
            return Err(Error::invalid("the camera pose has a non-finite component"));
        }
        let unit = axes.iter().all(|a| (a.length() - 1.0).abs() < TOLERANCE);
        let orthogonal = self.right.dot(self.up).abs() < TOLERANCE
            && self.up.dot(self.back).abs() < TOLERANCE
            && self.back.dot(self.right).abs() < TOLERANCE;
        let right_handed = self.right.cross(self.up).dot(self.back) > 0.0;
        if !(unit && orthogonal && right_handed) {
            return Err(Error::invalid(
                "the camera axes right, up, back must be orthonormal and right-handed",
            ));
        }
        Ok(())
    }

    /// A direction in the camera frame, expressed in the light frame.
    pub fn to_world_direction(&self, v: Vec3) -> Vec3 {
        self.right * v.x + self.up * v.y + self.back * v.z
    }

    /// A point in the camera frame, expressed in the light frame.
    pub fn to_world_point(&self, p: Vec3) -> Vec3 {
        self.eye + self.to_world_direction(p)
    }

    /// A point in the light frame, expressed in the camera frame.
    pub fn to_camera_point(&self, p: Vec3) -> Vec3 {
        let d = p - self.eye;
        Vec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.back))
    }
}

/// What every projection model does, in the camera frame (x right, y up, looking −z).
///
/// Pixel positions are continuous: pixel `(i, j)` covers `[i, i+1) × [j, j+1)` and its
/// centre is `(i + 0.5, j + 0.5)`, from the top-left corner (see the conventions).
pub trait CameraModel {
    /// The image size in pixels.
    fn size(&self) -> (usize, usize);
    /// The ray through image position `(x, y)`, unit direction.
    fn ray(&self, x: f64, y: f64) -> Ray;
    /// The image position of a point, or `None` when it is behind the camera, outside
    /// the image, or where the projection is undefined (on the panorama axis).
    fn pixel(&self, p: Vec3) -> Option<[f64; 2]>;
    /// The depth of a visible point: its distance from the ray origin along the ray.
    fn depth(&self, p: Vec3) -> f64;
    /// The pixel-centre rays of [`CameraModel::ray`], factored per column and per row.
    fn ray_factors(&self) -> RayFactors;
    /// The stored description of the projection.
    fn projection(&self) -> Projection;
}

/// Every projection model relit knows; each method forwards to the variant.
#[derive(Clone, Debug, PartialEq)]
pub enum Model {
    Perspective(Perspective),
    Orthographic(Orthographic),
    Cylindrical(Cylindrical),
    Equirectangular(Equirectangular),
}

impl Model {
    fn inner(&self) -> &dyn CameraModel {
        match self {
            Model::Perspective(m) => m,
            Model::Orthographic(m) => m,
            Model::Cylindrical(m) => m,
            Model::Equirectangular(m) => m,
        }
    }
}

/// The half height of the image plane of an orthographic camera made from a stored
/// [`Projection`], which has no field for it: the image spans y ∈ [−1, 1].
pub const DEFAULT_ORTHOGRAPHIC_HEIGHT: f64 = 2.0;

/// A projection model at a size, placed in the light frame by a pose.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    model: Model,
    pose: Pose,
}

impl Camera {
    /// A camera from a stored projection. A planar projection without a field of view
    /// is orthographic with an image plane [`DEFAULT_ORTHOGRAPHIC_HEIGHT`] high.
    pub fn new(projection: &Projection, width: usize, height: usize, pose: Pose) -> Result<Camera> {
        let model = match *projection {
            Projection::Planar {
                fov_y_deg: Some(fov),
            } => Model::Perspective(Perspective::new(width, height, fov)?),
            Projection::Planar { fov_y_deg: None } => Model::Orthographic(Orthographic::new(
                width,
                height,
                DEFAULT_ORTHOGRAPHIC_HEIGHT,
            )?),
            Projection::Cylindrical { fov_y_deg } => {
                Model::Cylindrical(Cylindrical::new(width, height, fov_y_deg)?)
            }
            Projection::Equirectangular => {
                Model::Equirectangular(Equirectangular::new(width, height)?)
            }
        };
        Camera::from_model(model, pose)
    }

    /// A camera from a model and a pose.
    pub fn from_model(model: Model, pose: Pose) -> Result<Camera> {
        pose.validate()?;
        Ok(Camera { model, pose })
    }

    pub fn model(&self) -> &Model {
        &self.model
    }

    pub fn pose(&self) -> &Pose {
        &self.pose
    }

    pub fn width(&self) -> usize {
        self.model.inner().size().0
    }

    pub fn height(&self) -> usize {
        self.model.inner().size().1
    }

    /// The stored description of the projection (the pose is not part of it).
    pub fn projection(&self) -> Projection {
        self.model.inner().projection()
    }

    /// The world ray through image position `(x, y)` (continuous pixel coordinates).
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let local = self.model.inner().ray(x, y);
        Ray {
            origin: self.pose.to_world_point(local.origin),
            direction: self.pose.to_world_direction(local.direction),
        }
    }

    /// The world ray through the centre of pixel `(i, j)`.
    pub fn pixel_ray(&self, i: usize, j: usize) -> Ray {
        self.ray(i as f64 + 0.5, j as f64 + 0.5)
    }

    /// The image position of a world point, or `None` when the camera cannot see it.
    pub fn pixel(&self, p: Vec3) -> Option<[f64; 2]> {
        self.model.inner().pixel(self.pose.to_camera_point(p))
    }

    /// The depth a world point would have in the depth map (distance along its ray).
    pub fn depth(&self, p: Vec3) -> f64 {
        self.model.inner().depth(self.pose.to_camera_point(p))
    }

    /// The world rays through the pixel centres, factored per column and per row.
    pub fn ray_factors(&self) -> RayFactors {
        let local = self.model.inner().ray_factors();
        let pose = &self.pose;
        RayFactors {
            columns: local
                .columns
                .iter()
                .map(|c| ColumnRay {
                    origin: pose.to_world_direction(c.origin),
                    direction: pose.to_world_direction(c.direction),
                })
                .collect(),
            rows: local
                .rows
                .iter()
                .map(|r| RowRay {
                    origin: pose.to_world_point(r.origin),
                    scale: r.scale,
                    direction: pose.to_world_direction(r.direction),
                })
                .collect(),
            norm_per_row: local.norm_per_row,
        }
    }

    /// The world point seen at the centre of pixel `(i, j)` at depth `d`: `P = O + d·V`.
    pub fn position(&self, i: usize, j: usize, depth: f64) -> Vec3 {
        self.pixel_ray(i, j).at(depth)
    }

    /// The world point of every pixel of a depth map (row-major, the camera's size);
    /// `None` where the depth is not a positive finite number (nothing was hit).
    pub fn positions_from_depth(&self, depth: &[f32]) -> Result<Vec<Option<Vec3>>> {
        let (w, h) = (self.width(), self.height());
        if depth.len() != w * h {
            return Err(Error::invalid(format!(
                "the depth map has {} values but the camera is {w}×{h} ({} pixels)",
                depth.len(),
                w * h
            )));
        }
        Ok(depth
            .iter()
            .enumerate()
            .map(|(k, &d)| {
                (d.is_finite() && d > 0.0).then(|| self.position(k % w, k / w, d as f64))
            })
            .collect())
    }
}

/// The stored form of a [`Camera`] (studio scene files and capture side files).
///
/// ```json
/// { "projection": { "type": "cylindrical" }, "width": 1024, "height": 256,
///   "pose": { "eye": [0, 1.6, 0], "right": [1, 0, 0], "up": [0, 1, 0], "back": [0, 0, 1] } }
/// ```
///
/// `orthographic_height` (optional) is the height of an orthographic image plane.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    pub projection: Projection,
    pub width: usize,
    pub height: usize,
    #[serde(default)]
    pub pose: Pose,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orthographic_height: Option<f64>,
}

impl CameraSpec {
    /// Build the camera, checking every parameter.
    pub fn build(&self) -> Result<Camera> {
        match (&self.projection, self.orthographic_height) {
            (Projection::Planar { fov_y_deg: None }, Some(h)) => Camera::from_model(
                Model::Orthographic(Orthographic::new(self.width, self.height, h)?),
                self.pose,
            ),
            _ => Camera::new(&self.projection, self.width, self.height, self.pose),
        }
    }
}

impl From<&Camera> for CameraSpec {
    fn from(camera: &Camera) -> CameraSpec {
        let orthographic_height = match &camera.model {
            Model::Orthographic(o) => Some(o.view_height()),
            _ => None,
        };
        CameraSpec {
            projection: camera.projection(),
            width: camera.width(),
            height: camera.height(),
            pose: camera.pose,
            orthographic_height,
        }
    }
}

/// Check an image size for a camera.
fn check_size(width: usize, height: usize) -> Result<()> {
    const MAX_SIDE: usize = 1 << 16; // far beyond any panorama; stops overflowing products
    if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
        return Err(Error::invalid(format!(
            "a camera image must be 1 to {MAX_SIDE} pixels a side, not {width}×{height}"
        )));
    }
    Ok(())
}

/// Check a field of view in degrees (strictly between 0 and 180).
fn check_fov(fov_y_deg: f64) -> Result<f64> {
    if !(fov_y_deg.is_finite() && fov_y_deg > 0.0 && fov_y_deg < 180.0) {
        return Err(Error::invalid(format!(
            "a vertical field of view must be between 0 and 180 degrees, not {fov_y_deg}"
        )));
    }
    Ok(fov_y_deg)
}

/// Azimuth of a camera-frame direction for the panoramas: 0 along −z, growing toward +x.
fn panorama_azimuth(p: Vec3) -> f64 {
    p.x.atan2(-p.z)
}

/// The image column of a panorama azimuth, wrapped into `[0, width)`.
fn panorama_column(azimuth: f64, width: usize) -> f64 {
    let x = (azimuth / std::f64::consts::TAU + 0.5) * width as f64;
    if x >= width as f64 {
        x - width as f64
    } else {
        x.max(0.0)
    }
}

/// The azimuth of a panorama column (inverse of [`panorama_column`]).
fn column_azimuth(x: f64, width: usize) -> f64 {
    (x / width as f64 - 0.5) * std::f64::consts::TAU
}

/// The column part of a panorama's [`RayFactors`]: the horizontal unit vector
/// `(sin φ, 0, −cos φ)` at each column centre's azimuth.
fn azimuth_columns(width: usize) -> Vec<ColumnRay> {
    (0..width)
        .map(|i| {
            let phi = column_azimuth(i as f64 + 0.5, width);
            ColumnRay {
                origin: Vec3::default(),
                direction: Vec3::new(phi.sin(), 0.0, -phi.cos()),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every camera model used by the tests, with a pose that is not the identity so
    /// that the world transform is exercised too.
    fn cameras() -> Vec<Camera> {
        let pose = Pose::look_at(
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(-2.0, 1.5, -1.0),
            Vec3::new(0.1, 1.0, 0.0),
        )
        .unwrap();
        vec![
            Camera::new(
                &Projection::Planar {
                    fov_y_deg: Some(50.0),
                },
                64,
                48,
                pose,
            )
            .unwrap(),
            Camera::new(&Projection::Planar { fov_y_deg: None }, 40, 30, pose).unwrap(),
            Camera::new(
                &Projection::Cylindrical { fov_y_deg: None },
                1024,
                256,
                pose,
            )
            .unwrap(),
            Camera::new(
                &Projection::Cylindrical {
                    fov_y_deg: Some(100.0),
                },
                96,
                40,
                Pose::identity(),
            )
            .unwrap(),
            Camera::new(&Projection::Equirectangular, 128, 64, pose).unwrap(),
        ]
    }

    #[test]
    fn pixel_ray_pixel_round_trips_for_every_camera() {
        // f64 round trips through trigonometry lose ~1e-13 of a pixel; 1e-7 is slack.
        const PIXEL_TOLERANCE: f64 = 1e-7;
        for camera in cameras() {
            let (w, h) = (camera.width(), camera.height());
            for j in (0..h).step_by(h.div_ceil(9)) {
                for i in (0..w).step_by(w.div_ceil(13)) {
                    // Off-centre positions too, so a half-pixel slip cannot hide.
                    for (dx, dy) in [(0.5, 0.5), (0.1, 0.9), (0.73, 0.02)] {
                        let (x, y) = (i as f64 + dx, j as f64 + dy);
                        let ray = camera.ray(x, y);
                        assert!((ray.direction.length() - 1.0).abs() < 1e-12);
                        let p = ray.at(3.7);
                        let back = camera
                            .pixel(p)
                            .unwrap_or_else(|| panic!("{:?} lost ({x}, {y})", camera.projection()));
                        assert!(
                            (back[0] - x).abs() < PIXEL_TOLERANCE
                                && (back[1] - y).abs() < PIXEL_TOLERANCE,
                            "{:?}: ({x}, {y}) came back as {back:?}",
                            camera.projection()
                        );
                        assert!((camera.depth(p) - 3.7).abs() < 1e-9);
                    }
                }
            }
        }
    }

    #[test]
    fn ray_factors_rebuild_every_pixel_ray() {
        for camera in cameras() {
            let factors = camera.ray_factors();
            assert_eq!(factors.columns.len(), camera.width());
            assert_eq!(factors.rows.len(), camera.height());
            for (j, r) in factors.rows.iter().enumerate() {
                let norm = |c: &ColumnRay| (c.direction * r.scale + r.direction).length();
                let first = norm(&factors.columns[0]);
                let same = factors
                    .columns
                    .iter()
                    .all(|c| (norm(c) - first).abs() < 1e-12);
                assert_eq!(
                    same,
                    factors.norm_per_row,
                    "{:?} row {j}",
                    camera.projection()
                );
            }
            for j in 0..camera.height() {
                for i in 0..camera.width() {
                    let (want, got) = (camera.pixel_ray(i, j), factors.ray(i, j));
                    assert!(
                        (want.origin - got.origin).length() < 1e-12
                            && (want.direction - got.direction).length() < 1e-12,
                        "{:?} pixel ({i}, {j}): {want:?} vs {got:?}",
                        camera.projection()
                    );
                }
            }
        }
    }

    #[test]
    fn identity_pose_follows_the_conventions() {
        // The image centre looks along −z; the right edge of a perspective image leans
        // toward +x; the top toward +y.
        let persp = Camera::new(
            &Projection::Planar {
                fov_y_deg: Some(90.0),
            },
            100,
            100,
            Pose::identity(),
        )
        .unwrap();
        let centre = persp.ray(50.0, 50.0).direction;
        assert!((centre - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        let corner = persp.ray(100.0, 0.0).direction;
        assert!(
            (corner - Vec3::new(1.0, 1.0, -1.0).normalized().unwrap()).length() < 1e-12,
            "{corner:?}"
        );
        // A cylindrical panorama pans right as x grows: a quarter turn right of the
        // centre column looks along +x, the first column looks along +z (behind).
        let cyl = Camera::new(
            &Projection::Cylindrical { fov_y_deg: None },
            1024,
            256,
            Pose::identity(),
        )
        .unwrap();
        assert!((cyl.ray(768.0, 128.0).direction - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-12);
        assert!((cyl.ray(0.0, 128.0).direction - Vec3::new(0.0, 0.0, 1.0)).length() < 1e-12);
        // Square pixels on the cylinder: 256 rows of 2π/1024 span ±π/4 of height.
        let top = cyl.ray(512.0, 0.0).direction;
        assert!((top.y / (-top.z) - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        let eq = Camera::new(&Projection::Equirectangular, 64, 32, Pose::identity()).unwrap();
        assert!((eq.ray(32.0, 0.0).direction - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-12);
        // Orthographic rays are parallel and start on the image plane.
        let ortho = Camera::new(
            &Projection::Planar { fov_y_deg: None },
            20,
            10,
            Pose::at(Vec3::new(0.0, 0.0, 5.0)),
        )
        .unwrap();
        let r = ortho.ray(20.0, 0.0);
        assert_eq!(r.direction, Vec3::new(0.0, 0.0, -1.0));
        assert!((r.origin - Vec3::new(2.0, 1.0, 5.0)).length() < 1e-12);
    }

    #[test]
    fn positions_from_depth_lie_on_the_rays() {
        let cam = Camera::new(
            &Projection::Planar {
                fov_y_deg: Some(60.0),
            },
            4,
            3,
            Pose::at(Vec3::new(0.0, 1.0, 2.0)),
        )
        .unwrap();
        // A plane z = −3 in front of the eye: depth = distance to it along each ray.
        let depth: Vec<f32> = (0..12)
            .map(|k| (5.0 / -cam.pixel_ray(k % 4, k / 4).direction.z) as f32)
            .collect();
        let mut with_hole = depth.clone();
        with_hole[5] = 0.0;
        let points = cam.positions_from_depth(&with_hole).unwrap();
        assert!(points[5].is_none());
        for (k, p) in points.iter().enumerate().filter(|(k, _)| *k != 5) {
            assert!((p.unwrap().z + 3.0).abs() < 1e-5, "pixel {k}: {p:?}");
        }
        assert!(cam.positions_from_depth(&depth[..11]).is_err());
    }

    #[test]
    fn bad_parameters_are_errors_not_panics() {
        assert!(Camera::new(
            &Projection::Planar {
                fov_y_deg: Some(180.0)
            },
            4,
            4,
            Pose::identity()
        )
        .is_err());
        assert!(Camera::new(
            &Projection::Planar {
                fov_y_deg: Some(f64::NAN)
            },
            4,
            4,
            Pose::identity()
        )
        .is_err());
        assert!(Camera::new(&Projection::Equirectangular, 0, 4, Pose::identity()).is_err());
        assert!(Camera::new(
            &Projection::Cylindrical {
                fov_y_deg: Some(-3.0)
            },
            4,
            4,
            Pose::identity()
        )
        .is_err());
        let skewed = Pose {
            right: Vec3::new(1.0, 0.1, 0.0),
            ..Pose::identity()
        };
        assert!(Camera::new(&Projection::Equirectangular, 8, 4, skewed).is_err());
        let left_handed = Pose {
            back: Vec3::new(0.0, 0.0, -1.0),
            ..Pose::identity()
        };
        assert!(left_handed.validate().is_err());
        assert!(Pose::look_at(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 5.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0)
        )
        .is_err());
        // Points the camera cannot see.
        let persp = Camera::new(
            &Projection::Planar {
                fov_y_deg: Some(40.0),
            },
            8,
            8,
            Pose::identity(),
        )
        .unwrap();
        assert!(
            persp.pixel(Vec3::new(0.0, 0.0, 1.0)).is_none(),
            "behind the eye"
        );
        assert!(
            persp.pixel(Vec3::new(10.0, 0.0, -1.0)).is_none(),
            "outside the image"
        );
        let cyl = Camera::new(
            &Projection::Cylindrical { fov_y_deg: None },
            64,
            16,
            Pose::identity(),
        )
        .unwrap();
        assert!(cyl.pixel(Vec3::new(0.0, 3.0, 0.0)).is_none(), "on the axis");
    }

    #[test]
    fn spec_json_round_trips_and_old_projections_still_parse() {
        for camera in cameras() {
            let spec = CameraSpec::from(&camera);
            let json = serde_json::to_string(&spec).unwrap();
            let back: CameraSpec = serde_json::from_str(&json).unwrap();
            let rebuilt = back.build().unwrap();
            assert_eq!(rebuilt.projection(), camera.projection());
            let (a, b) = (rebuilt.pixel_ray(3, 2), camera.pixel_ray(3, 2));
            assert!(
                (a.direction - b.direction).length() < 1e-12
                    && (a.origin - b.origin).length() < 1e-12
            );
        }
        let old: Projection = serde_json::from_str(r#"{"type":"planar","fov_y_deg":50}"#).unwrap();
        assert_eq!(
            old,
            Projection::Planar {
                fov_y_deg: Some(50.0)
            }
        );
        let spec: CameraSpec = serde_json::from_str(
            r#"{"projection":{"type":"equirectangular"},"width":8,"height":4}"#,
        )
        .unwrap();
        assert_eq!(spec.pose, Pose::identity());
    }
}
