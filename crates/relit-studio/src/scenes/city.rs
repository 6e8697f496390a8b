//! A city street (seed 004's "city"): a road with sidewalks between two rows of
//! buildings in brick, plaster, concrete and glass, with windows, ledges and cornices,
//! trees, lamp posts and parked cars, closed at both ends by cross buildings. Seen from
//! a cylindrical panorama at eye height in the street. Every surface casts shadows.
//!
//! Building sizes and styles come from a hash of their index, so the street is the
//! same on every build.

use crate::material::Material;
use crate::math::{v3, Transform, V3};
use crate::scene::{MaterialId, Scene, SceneBuilder};
use crate::shapes;
use crate::texture::{hash2, rgb8, Bricks, Checker, Plaster, Texture};
use crate::Result;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::sphere::Vec3;

const STREET_END: f32 = 80.0;
const ROAD_HALF_WIDTH: f32 = 5.0;
const SIDEWALK: f32 = 4.0;

pub fn build() -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let m = Materials::new(&mut b);
    let id = Transform::IDENTITY;

    // Ground, road, markings, sidewalks with curbs.
    b.add(
        &shapes::quad(
            v3(-200.0, -0.01, 200.0),
            v3(400.0, 0.0, 0.0),
            v3(0.0, 0.0, -400.0),
        ),
        &id,
        m.ground,
    );
    b.add(
        &shapes::quad(
            v3(-STREET_END, 0.0, ROAD_HALF_WIDTH),
            v3(2.0 * STREET_END, 0.0, 0.0),
            v3(0.0, 0.0, -2.0 * ROAD_HALF_WIDTH),
        ),
        &id,
        m.asphalt,
    );
    let mut x = -STREET_END;
    while x < STREET_END {
        b.add(
            &shapes::quad(v3(x, 0.003, 0.08), v3(3.0, 0.0, 0.0), v3(0.0, 0.0, -0.16)),
            &id,
            m.paint,
        );
        x += 6.0;
    }
    for side in [-1.0f32, 1.0] {
        let (z0, z1) = (side * ROAD_HALF_WIDTH, side * (ROAD_HALF_WIDTH + SIDEWALK));
        b.add(
            &shapes::cuboid(
                v3(-STREET_END, 0.0, z0.min(z1)),
                v3(STREET_END, 0.15, z0.max(z1)),
            ),
            &id,
            m.sidewalk,
        );
    }

    // Two rows of buildings and the cross buildings that close the street.
    let mut index = 0;
    for side in [-1.0f32, 1.0] {
        let mut x = -STREET_END + 2.0;
        while x < STREET_END - 6.0 {
            let width = (8.0 + 8.0 * hash2(index, 1)).min(STREET_END - 2.0 - x);
            building(&mut b, &m, index, side, x, width);
            x += width + 0.6 + 1.6 * hash2(index, 2);
            index += 1;
        }
    }
    for end in [-1.0f32, 1.0] {
        let x0 = end * (STREET_END + 4.0);
        let slab = shapes::cuboid(
            v3(x0.min(x0 + end * 14.0), 0.0, -40.0),
            v3(x0.max(x0 + end * 14.0), 28.0, 40.0),
        );
        b.add(&slab, &id, m.bricks[1]);
    }

    // Street furniture: trees and lamps along both sidewalks, parked cars.
    for k in 0..11 {
        let x = -70.0 + 14.0 * k as f32;
        tree(&mut b, &m, v3(x, 0.15, 7.6), k);
        tree(&mut b, &m, v3(x + 7.0, 0.15, -7.6), k + 100);
        lamp(&mut b, &m, v3(x + 7.0, 0.15, 5.6), -1.0);
        lamp(&mut b, &m, v3(x, 0.15, -5.6), 1.0);
    }
    for (k, (x, z)) in [
        (9.0, 3.6),
        (-13.0, -3.6),
        (21.0, -3.6),
        (-27.0, 3.6),
        (35.0, 3.6),
        (-44.0, -3.6),
    ]
    .into_iter()
    .enumerate()
    {
        car(
            &mut b,
            m.car_paint[k % m.car_paint.len()],
            &m,
            v3(x, 0.0, z),
            if z > 0.0 { 0.0 } else { 180.0 },
        );
    }

    let pose = Pose::at(Vec3::new(0.0, 1.7, -1.0));
    let camera = CameraSpec {
        projection: Projection::Cylindrical { fov_y_deg: None },
        width: 1024,
        height: 256,
        pose,
        orthographic_height: None,
    };
    b.build("city", camera)
}

struct Materials {
    ground: MaterialId,
    asphalt: MaterialId,
    paint: MaterialId,
    sidewalk: MaterialId,
    bricks: [MaterialId; 2],
    plaster: [MaterialId; 3],
    concrete: MaterialId,
    curtain_glass: MaterialId,
    window_glass: MaterialId,
    stone_trim: MaterialId,
    metal: MaterialId,
    bark: MaterialId,
    leaves: MaterialId,
    tyre: MaterialId,
    car_paint: [MaterialId; 4],
}

impl Materials {
    fn new(b: &mut SceneBuilder) -> Materials {
        let plaster = |c| {
            Texture::Plaster(Plaster {
                color: c,
                variation: 0.1,
                scale: 1.5,
            })
        };
        let bricks = |c| {
            Texture::Bricks(Bricks {
                brick: c,
                mortar_color: rgb8(185, 180, 170),
                size: [0.24, 0.075],
                mortar: 0.012,
            })
        };
        Materials {
            ground: b.material(Material::matte(
                "ground",
                Texture::Plaster(Plaster {
                    color: rgb8(110, 108, 100),
                    variation: 0.2,
                    scale: 3.0,
                }),
            )),
            asphalt: b.material(Material::glossy(
                "asphalt",
                Texture::Plaster(Plaster {
                    color: rgb8(75, 75, 78),
                    variation: 0.25,
                    scale: 0.3,
                }),
                0.04,
                15.0,
            )),
            paint: b.material(Material::matte(
                "road paint",
                Texture::Constant(rgb8(235, 235, 225)),
            )),
            sidewalk: b.material(Material::matte(
                "sidewalk",
                Texture::Checker(Checker {
                    a: rgb8(190, 186, 178),
                    b: rgb8(165, 162, 155),
                    size: 0.6,
                }),
            )),
            bricks: [
                b.material(Material::matte("red brick", bricks(rgb8(165, 70, 50)))),
                b.material(Material::matte("yellow brick", bricks(rgb8(205, 175, 115)))),
            ],
            plaster: [
                b.material(Material::matte(
                    "beige plaster",
                    plaster(rgb8(225, 205, 170)),
                )),
                b.material(Material::matte(
                    "pastel blue plaster",
                    plaster(rgb8(160, 190, 210)),
                )),
                b.material(Material::matte(
                    "terracotta plaster",
                    plaster(rgb8(205, 120, 85)),
                )),
            ],
            concrete: b.material(Material::glossy(
                "concrete",
                Texture::Plaster(Plaster {
                    color: rgb8(170, 170, 165),
                    variation: 0.15,
                    scale: 0.8,
                }),
                0.03,
                10.0,
            )),
            curtain_glass: b.material(Material::glossy(
                "curtain wall",
                Texture::Constant(rgb8(45, 70, 90)),
                0.7,
                500.0,
            )),
            window_glass: b.material(Material::glossy(
                "window glass",
                Texture::Constant(rgb8(30, 38, 48)),
                0.6,
                400.0,
            )),
            stone_trim: b.material(Material::matte(
                "stone trim",
                Texture::Plaster(Plaster {
                    color: rgb8(215, 210, 198),
                    variation: 0.08,
                    scale: 0.4,
                }),
            )),
            metal: b.material(Material::glossy(
                "dark metal",
                Texture::Constant(rgb8(45, 50, 50)),
                0.35,
                120.0,
            )),
            bark: b.material(Material::matte(
                "bark",
                Texture::Plaster(Plaster {
                    color: rgb8(90, 70, 55),
                    variation: 0.3,
                    scale: 0.05,
                }),
            )),
            leaves: b.material(Material::matte(
                "leaves",
                Texture::Plaster(Plaster {
                    color: rgb8(70, 120, 50),
                    variation: 0.35,
                    scale: 0.25,
                }),
            )),
            tyre: b.material(Material::matte(
                "tyres",
                Texture::Constant(rgb8(25, 25, 25)),
            )),
            car_paint: [
                b.material(Material::glossy(
                    "red paint",
                    Texture::Constant(rgb8(170, 20, 25)),
                    0.5,
                    250.0,
                )),
                b.material(Material::glossy(
                    "white paint",
                    Texture::Constant(rgb8(225, 225, 222)),
                    0.5,
                    250.0,
                )),
                b.material(Material::glossy(
                    "blue paint",
                    Texture::Constant(rgb8(30, 60, 140)),
                    0.5,
                    250.0,
                )),
                b.material(Material::glossy(
                    "green paint",
                    Texture::Constant(rgb8(40, 95, 60)),
                    0.5,
                    250.0,
                )),
            ],
        }
    }
}

/// Building `index` on side `side` (±z) from `x` to `x + width`.
fn building(b: &mut SceneBuilder, m: &Materials, index: i32, side: f32, x: f32, width: f32) {
    let floors = 3 + (9.0 * hash2(index, 3) * hash2(index, 4)) as usize;
    let floor_height = 3.2;
    let height = floors as f32 * floor_height + 0.6;
    let front = ROAD_HALF_WIDTH + SIDEWALK + 0.2 + 1.5 * hash2(index, 5);
    let depth = 14.0;
    let style = (hash2(index, 6) * 7.0) as usize;
    let (wall, glass_tower) = match style {
        0 | 1 => (m.bricks[style], false),
        2..=4 => (m.plaster[style - 2], false),
        5 => (m.concrete, false),
        _ => (m.curtain_glass, true),
    };
    let (z_front, z_back) = (side * front, side * (front + depth));
    let id = Transform::IDENTITY;
    b.add(
        &shapes::cuboid(
            v3(x, 0.0, z_front.min(z_back)),
            v3(x + width, height, z_front.max(z_back)),
        ),
        &id,
        wall,
    );
    // Points on the facade: `u` along the street, `v` up, `out` metres toward the street.
    let at = |u: f32, v: f32, out: f32| v3(x + u, v, z_front - side * out);
    let facade_box = |lo: (f32, f32, f32), hi: (f32, f32, f32)| {
        let (a, c) = (at(lo.0, lo.1, lo.2), at(hi.0, hi.1, hi.2));
        shapes::cuboid(a.min(c), a.max(c))
    };
    if glass_tower {
        // Mullions and spandrels over the curtain wall.
        let mut u = 0.0;
        while u <= width {
            b.add(
                &facade_box((u - 0.06, 0.0, 0.0), (u + 0.06, height, 0.15)),
                &id,
                m.metal,
            );
            u += 1.5;
        }
        for f in 0..=floors {
            let v = f as f32 * floor_height;
            b.add(
                &facade_box((0.0, v, 0.0), (width, v + 0.25, 0.12)),
                &id,
                m.metal,
            );
        }
        return;
    }
    // Windows: a grid per floor, a shop window on the ground floor.
    let columns = ((width - 1.0) / 2.4).floor().max(1.0) as usize;
    let pitch = width / columns as f32;
    for f in 0..floors {
        let v0 = f as f32 * floor_height;
        for c in 0..columns {
            let centre = (c as f32 + 0.5) * pitch;
            let (half_w, bottom, top) = if f == 0 {
                (pitch * 0.4, 0.4, 2.7)
            } else {
                (0.65, v0 + 0.9, v0 + 2.6)
            };
            let (u0, u1) = (centre - half_w, centre + half_w);
            // A pane 2 cm proud of the wall reads as a window without cutting a hole;
            // which way it faces does not matter (shading faces the viewer).
            let pane = shapes::quad(
                at(u0, bottom, 0.02),
                at(u1, bottom, 0.02) - at(u0, bottom, 0.02),
                v3(0.0, top - bottom, 0.0),
            );
            b.add(&pane, &id, m.window_glass);
            if f > 0 {
                b.add(
                    &facade_box((u0 - 0.1, bottom - 0.12, 0.0), (u1 + 0.1, bottom, 0.12)),
                    &id,
                    m.stone_trim,
                );
                b.add(
                    &facade_box((u0 - 0.08, top, 0.0), (u1 + 0.08, top + 0.1, 0.06)),
                    &id,
                    m.stone_trim,
                );
            }
        }
        if f > 0 && hash2(index, 7) > 0.4 {
            b.add(
                &facade_box((0.0, v0 - 0.1, 0.0), (width, v0 + 0.05, 0.22)),
                &id,
                m.stone_trim,
            );
        }
    }
    // Cornice.
    b.add(
        &facade_box((-0.1, height - 0.45, 0.0), (width + 0.1, height, 0.4)),
        &id,
        m.stone_trim,
    );
}

fn tree(b: &mut SceneBuilder, m: &Materials, base: V3, seed: i32) {
    let height = 2.6 + 0.8 * hash2(seed, 11);
    b.add(
        &shapes::cylinder(0.14, height + 0.6, 12, false),
        &Transform::translate(base),
        m.bark,
    );
    let crown = base + v3(0.0, height + 1.2, 0.0);
    let r = 1.4 + 0.5 * hash2(seed, 12);
    b.add(
        &shapes::sphere(r, 32),
        &Transform::scale(v3(1.0, 1.15, 1.0)).then(Transform::translate(crown)),
        m.leaves,
    );
    let offset = v3(
        0.6 * (hash2(seed, 13) - 0.5),
        0.9,
        0.6 * (hash2(seed, 14) - 0.5),
    );
    b.add(
        &shapes::sphere(r * 0.7, 24),
        &Transform::translate(crown + offset),
        m.leaves,
    );
}

/// A lamp post whose arm reaches toward the road (`toward` = ±1 in z).
fn lamp(b: &mut SceneBuilder, m: &Materials, base: V3, toward: f32) {
    let top = base + v3(0.0, 5.5, 0.0);
    b.add(
        &shapes::cylinder(0.07, 5.5, 16, true),
        &Transform::translate(base),
        m.metal,
    );
    let end = top + v3(0.0, 0.2, toward * 1.2);
    b.add(
        &shapes::rod(top, end, 0.04, 10),
        &Transform::IDENTITY,
        m.metal,
    );
    b.add(
        &shapes::cuboid(end + v3(-0.2, -0.12, -0.3), end + v3(0.2, 0.05, 0.3)),
        &Transform::IDENTITY,
        m.metal,
    );
}

fn car(b: &mut SceneBuilder, paint: MaterialId, m: &Materials, position: V3, heading_deg: f32) {
    let place = Transform::rotate_y(heading_deg).then(Transform::translate(position));
    b.add(
        &shapes::cuboid(v3(-2.1, 0.3, -0.88), v3(2.1, 1.0, 0.88)),
        &place,
        paint,
    );
    b.add(
        &shapes::cuboid(v3(-1.1, 1.0, -0.8), v3(0.9, 1.55, 0.8)),
        &place,
        m.window_glass,
    );
    b.add(
        &shapes::cuboid(v3(-1.05, 1.55, -0.78), v3(0.85, 1.6, 0.78)),
        &place,
        paint,
    );
    // Wheels: cylinders turned onto the z axis, just proud of the body's sides.
    for (x, z) in [(-1.35, -0.92), (1.35, -0.92), (-1.35, 0.72), (1.35, 0.72)] {
        let wheel = Transform::rotate_x(90.0).then(Transform::translate(v3(x, 0.33, z)));
        b.add(
            &shapes::cylinder(0.33, 0.2, 20, true),
            &wheel.then(place),
            m.tyre,
        );
    }
}
