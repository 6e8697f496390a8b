//! Seed 004 figure 8: a box lying on a plane, the scene that shows how shadows move
//! between a point light and a directional one.

use crate::material::Material;
use crate::math::{v3, Transform};
use crate::scene::{Scene, SceneBuilder};
use crate::shapes;
use crate::texture::{rgb8, Checker, Plaster, Texture};
use crate::Result;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::sphere::Vec3;

pub fn build() -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let floor = b.material(Material::matte(
        "floor",
        Texture::Checker(Checker {
            a: rgb8(205, 200, 190),
            b: rgb8(150, 145, 140),
            size: 0.5,
        }),
    ));
    let painted = b.material(Material::glossy(
        "painted box",
        Texture::Plaster(Plaster {
            color: rgb8(200, 90, 50),
            variation: 0.12,
            scale: 0.3,
        }),
        0.12,
        60.0,
    ));
    // A 12 m square floor at y = 0 (facing +y).
    b.add(
        &shapes::quad(v3(-6.0, 0.0, 6.0), v3(12.0, 0.0, 0.0), v3(0.0, 0.0, -12.0)),
        &Transform::IDENTITY,
        floor,
    );
    // The box: 1.2 × 0.6 × 0.8 m, turned 25° about the vertical.
    let half = v3(0.6, 0.3, 0.4);
    let placement = Transform::rotate_y(25.0).then(Transform::translate(v3(0.0, 0.3, 0.0)));
    b.add(&shapes::cuboid(-half, half), &placement, painted);
    let pose = Pose::look_at(
        Vec3::new(0.0, 2.0, 3.6),
        Vec3::new(0.0, 0.25, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    )?;
    let camera = CameraSpec {
        projection: Projection::Planar {
            fov_y_deg: Some(50.0),
        },
        width: 512,
        height: 384,
        pose,
        orthographic_height: None,
    };
    b.build("box", camera)
}
