//! Seed 004's attic: a gabled room 12 m long (x) and 8 m wide (z) under a roof rising
//! from 1.2 m knee walls to a 4.2 m ridge, seen from a cylindrical panorama near its
//! centre.
//!
//! The shell (floor, knee walls, roof, gables) is drawn but lets light through, so a
//! directional light from anywhere on the sphere lights the room as in the seed's
//! renders; pillars, beams, rafters, window frames and furniture cast shadows.

use crate::material::Material;
use crate::math::{v3, Transform, V3};
use crate::scene::{MaterialId, Scene, SceneBuilder};
use crate::shapes::{self, Mesh};
use crate::texture::{rgb8, Bricks, Checker, Planks, Plaster, Texture};
use crate::Result;
use relit::camera::{CameraSpec, Pose, Projection};
use relit::sphere::Vec3;

const HALF_LENGTH: f32 = 6.0; // x
const HALF_WIDTH: f32 = 4.0; // z
const KNEE: f32 = 1.2;
const RIDGE: f32 = 4.2;

/// A wall or roof plane: origin, unit axes along and up the surface, and its normal
/// into the room (`along × up`).
#[derive(Clone, Copy)]
struct Plane {
    origin: V3,
    along: V3,
    up: V3,
}

impl Plane {
    fn inward(&self) -> V3 {
        self.along.cross(self.up)
    }
    /// Local (along, up, inward) coordinates to the room.
    fn frame(&self) -> Transform {
        Transform::from_columns(self.along, self.up, self.inward(), self.origin)
    }
    /// A box given in local coordinates.
    fn block(&self, min: V3, max: V3) -> (Mesh, Transform) {
        (shapes::cuboid(min, max), self.frame())
    }
}

pub fn build() -> Result<Scene> {
    let mut b = SceneBuilder::new();
    let m = Materials::new(&mut b);
    let slope_len = (HALF_WIDTH * HALF_WIDTH + (RIDGE - KNEE) * (RIDGE - KNEE)).sqrt();
    let (sy, sz) = ((RIDGE - KNEE) / slope_len, HALF_WIDTH / slope_len);

    // Shell.
    let floor = shapes::quad(
        v3(-HALF_LENGTH, 0.0, HALF_WIDTH),
        v3(2.0 * HALF_LENGTH, 0.0, 0.0),
        v3(0.0, 0.0, -2.0 * HALF_WIDTH),
    );
    b.add(&floor, &Transform::IDENTITY, m.floor);
    for z in [-HALF_WIDTH, HALF_WIDTH] {
        let knee = shapes::quad(
            v3(-HALF_LENGTH, 0.0, z),
            v3(2.0 * HALF_LENGTH, 0.0, 0.0),
            v3(0.0, KNEE, 0.0),
        );
        b.add(&knee, &Transform::IDENTITY, m.plaster);
        // A skirting board along the knee wall.
        let skirting = shapes::cuboid(
            v3(-HALF_LENGTH, 0.0, z - 0.03),
            v3(HALF_LENGTH, 0.12, z + 0.03),
        );
        b.add(&skirting, &Transform::IDENTITY, m.dark_wood);
    }
    let north = Plane {
        origin: v3(-HALF_LENGTH, KNEE, -HALF_WIDTH),
        along: v3(1.0, 0.0, 0.0),
        up: v3(0.0, sy, sz),
    };
    let south = Plane {
        origin: v3(HALF_LENGTH, KNEE, HALF_WIDTH),
        along: v3(-1.0, 0.0, 0.0),
        up: v3(0.0, sy, -sz),
    };
    let skylights = [[2.6, 1.6, 3.6, 2.8], [8.4, 1.6, 9.4, 2.8]];
    for roof in [north, south] {
        let boards = shapes::wall_with_holes(
            roof.origin,
            roof.along * (2.0 * HALF_LENGTH),
            roof.up * slope_len,
            &skylights,
        );
        b.add(&boards, &Transform::IDENTITY, m.roof_boards);
        for hole in skylights {
            window_frame(&mut b, &roof, hole, m.frame);
        }
        // Rafters every 1.5 m, clear of the skylights.
        for k in 0..8 {
            let x = 0.75 + 1.5 * k as f32;
            let (mesh, t) = roof.block(v3(x - 0.05, 0.0, 0.0), v3(x + 0.05, slope_len, 0.16));
            b.add(&mesh, &t, m.dark_wood);
        }
        // A purlin halfway up the slope.
        let (mesh, t) = roof.block(
            v3(0.0, slope_len * 0.5 - 0.1, 0.16),
            v3(2.0 * HALF_LENGTH, slope_len * 0.5 + 0.1, 0.34),
        );
        b.add(&mesh, &t, m.dark_wood);
    }
    let east = Plane {
        origin: v3(HALF_LENGTH, 0.0, -HALF_WIDTH),
        along: v3(0.0, 0.0, 1.0),
        up: v3(0.0, 1.0, 0.0),
    };
    let west = Plane {
        origin: v3(-HALF_LENGTH, 0.0, HALF_WIDTH),
        along: v3(0.0, 0.0, -1.0),
        up: v3(0.0, 1.0, 0.0),
    };
    for (gable, window) in [(east, [3.3, 1.7, 4.7, 3.1]), (west, [2.9, 1.6, 5.1, 2.9])] {
        // The rectangle above the roof line is hidden behind the roof from inside.
        let wall = shapes::wall_with_holes(
            gable.origin,
            gable.along * (2.0 * HALF_WIDTH),
            gable.up * RIDGE,
            &[window],
        );
        b.add(&wall, &Transform::IDENTITY, m.bricks);
        window_frame(&mut b, &gable, window, m.frame);
        let (sill, t) = gable.block(
            v3(window[0] - 0.15, window[1] - 0.12, 0.0),
            v3(window[2] + 0.15, window[1] - 0.06, 0.25),
        );
        b.add(&sill, &t, m.painted);
    }

    // Structure: ridge beam, collar ties, two pillars.
    b.add(
        &shapes::cuboid(v3(-HALF_LENGTH, 3.82, -0.13), v3(HALF_LENGTH, 4.1, 0.13)),
        &Transform::IDENTITY,
        m.dark_wood,
    );
    for x in [-4.5, -1.5, 1.5, 4.5] {
        let reach = (RIDGE - 2.55) / (RIDGE - KNEE) * HALF_WIDTH;
        b.add(
            &shapes::cuboid(v3(x - 0.09, 2.35, -reach), v3(x + 0.09, 2.55, reach)),
            &Transform::IDENTITY,
            m.dark_wood,
        );
    }
    for x in [-3.0, 3.0] {
        let at = Transform::translate(v3(x, 0.0, 0.0));
        b.add(&shapes::cylinder(0.16, 3.82, 48, false), &at, m.pillar);
        b.add(
            &shapes::cuboid(v3(-0.24, 0.0, -0.24), v3(0.24, 0.22, 0.24)),
            &at,
            m.stone,
        );
        b.add(
            &shapes::cuboid(v3(-0.22, 3.64, -0.22), v3(0.22, 3.82, 0.22)),
            &at,
            m.stone,
        );
        b.add(
            &shapes::torus(0.18, 0.035, 48, 12),
            &Transform::translate(v3(x, 0.26, 0.0)),
            m.stone,
        );
    }

    hanging_chair(&mut b, &m, v3(1.5, 0.0, -1.1));
    furniture(&mut b, &m);

    let pose = Pose::at(Vec3::new(0.0, 1.45, 0.4));
    let camera = CameraSpec {
        projection: Projection::Cylindrical { fov_y_deg: None },
        width: 1024,
        height: 256,
        pose,
        orthographic_height: None,
    };
    b.build("attic", camera)
}

struct Materials {
    floor: MaterialId,
    plaster: MaterialId,
    roof_boards: MaterialId,
    bricks: MaterialId,
    dark_wood: MaterialId,
    frame: MaterialId,
    painted: MaterialId,
    pillar: MaterialId,
    stone: MaterialId,
    wicker: MaterialId,
    cushion: MaterialId,
    rope: MaterialId,
    rug: MaterialId,
    brass: MaterialId,
    glaze: MaterialId,
    books: [MaterialId; 4],
}

impl Materials {
    fn new(b: &mut SceneBuilder) -> Materials {
        let shell = |m: Material| m.without_shadows();
        let planks = |light, dark, w, l| {
            Texture::Planks(Planks {
                light,
                dark,
                plank_width: w,
                plank_length: l,
            })
        };
        Materials {
            floor: b.material(shell(Material::glossy(
                "floor boards",
                planks(rgb8(190, 140, 95), rgb8(110, 70, 40), 0.18, 2.4),
                0.06,
                80.0,
            ))),
            plaster: b.material(shell(Material::matte(
                "plaster",
                Texture::Plaster(Plaster {
                    color: rgb8(225, 215, 195),
                    variation: 0.08,
                    scale: 0.6,
                }),
            ))),
            roof_boards: b.material(shell(Material::matte(
                "roof boards",
                planks(rgb8(200, 165, 120), rgb8(140, 100, 65), 0.14, 3.0),
            ))),
            bricks: b.material(shell(Material::matte(
                "gable bricks",
                Texture::Bricks(Bricks {
                    brick: rgb8(170, 85, 60),
                    mortar_color: rgb8(200, 195, 185),
                    size: [0.24, 0.075],
                    mortar: 0.012,
                }),
            ))),
            dark_wood: b.material(Material::glossy(
                "beams",
                planks(rgb8(120, 80, 50), rgb8(70, 45, 28), 0.25, 5.0),
                0.04,
                30.0,
            )),
            frame: b.material(Material::glossy(
                "window frames",
                Texture::Constant(rgb8(235, 235, 228)),
                0.15,
                60.0,
            )),
            painted: b.material(Material::glossy(
                "sills",
                Texture::Constant(rgb8(225, 225, 218)),
                0.1,
                40.0,
            )),
            pillar: b.material(Material::glossy(
                "pillars",
                Texture::Plaster(Plaster {
                    color: rgb8(230, 225, 210),
                    variation: 0.05,
                    scale: 0.3,
                }),
                0.12,
                50.0,
            )),
            stone: b.material(Material::matte(
                "stone",
                Texture::Plaster(Plaster {
                    color: rgb8(160, 155, 145),
                    variation: 0.25,
                    scale: 0.08,
                }),
            )),
            wicker: b.material(Material::glossy(
                "wicker",
                Texture::Bricks(Bricks {
                    brick: rgb8(200, 160, 100),
                    mortar_color: rgb8(90, 60, 30),
                    size: [0.05, 0.025],
                    mortar: 0.006,
                }),
                0.05,
                20.0,
            )),
            cushion: b.material(Material::matte(
                "cushion",
                Texture::Plaster(Plaster {
                    color: rgb8(170, 40, 45),
                    variation: 0.1,
                    scale: 0.05,
                }),
            )),
            rope: b.material(Material::matte(
                "rope",
                Texture::Constant(rgb8(190, 175, 140)),
            )),
            rug: b.material(Material::matte(
                "rug",
                Texture::Checker(Checker {
                    a: rgb8(150, 40, 40),
                    b: rgb8(200, 160, 90),
                    size: 0.25,
                }),
            )),
            brass: b.material(Material::glossy(
                "brass ball",
                Texture::Constant(rgb8(180, 140, 60)),
                0.6,
                300.0,
            )),
            glaze: b.material(Material::glossy(
                "glazed vase",
                Texture::Constant(rgb8(40, 90, 150)),
                0.35,
                150.0,
            )),
            books: [
                b.material(Material::glossy(
                    "book red",
                    Texture::Constant(rgb8(150, 30, 30)),
                    0.08,
                    40.0,
                )),
                b.material(Material::glossy(
                    "book green",
                    Texture::Constant(rgb8(40, 110, 60)),
                    0.08,
                    40.0,
                )),
                b.material(Material::glossy(
                    "book blue",
                    Texture::Constant(rgb8(40, 60, 140)),
                    0.08,
                    40.0,
                )),
                b.material(Material::glossy(
                    "book cream",
                    Texture::Constant(rgb8(220, 205, 170)),
                    0.08,
                    40.0,
                )),
            ],
        }
    }
}

/// A window frame with a cross of mullions around `hole` (`[u0, v0, u1, v1]` metres
/// along the plane), protruding into the room.
fn window_frame(b: &mut SceneBuilder, plane: &Plane, hole: [f32; 4], material: MaterialId) {
    let [u0, v0, u1, v1] = hole;
    let (t, depth) = (0.08, 0.14);
    let (um, vm) = (0.5 * (u0 + u1), 0.5 * (v0 + v1));
    let bars = [
        (v3(u0 - t, v0 - t, -0.02), v3(u0, v1 + t, depth)),
        (v3(u1, v0 - t, -0.02), v3(u1 + t, v1 + t, depth)),
        (v3(u0, v0 - t, -0.02), v3(u1, v0, depth)),
        (v3(u0, v1, -0.02), v3(u1, v1 + t, depth)),
        (v3(um - 0.03, v0, 0.0), v3(um + 0.03, v1, 0.06)),
        (v3(u0, vm - 0.03, 0.0), v3(u1, vm + 0.03, 0.06)),
    ];
    for (lo, hi) in bars {
        let (mesh, transform) = plane.block(lo, hi);
        b.add(&mesh, &transform, material);
    }
}

/// A wicker bowl chair hanging from the collar tie above `base` by four ropes and a chain.
fn hanging_chair(b: &mut SceneBuilder, m: &Materials, base: V3) {
    let centre = base + v3(0.0, 0.95, 0.0);
    // An open bowl: a sphere with its top cut off, squashed a little.
    let cut = 0.3;
    let mut bowl = shapes::sphere(0.5, 64);
    bowl.triangles
        .retain(|t| t.p.iter().all(|p| p.y <= cut + 1e-4));
    let squash = Transform::scale(v3(1.0, 0.85, 1.0)).then(Transform::translate(centre));
    b.add(&bowl, &squash, m.wicker);
    let rim_height = centre.y + cut * 0.85;
    let rim_radius = (0.5f32 * 0.5 - cut * cut).sqrt();
    b.add(
        &shapes::torus(rim_radius, 0.035, 64, 12),
        &Transform::translate(v3(centre.x, rim_height, centre.z)),
        m.wicker,
    );
    let cushion = Transform::scale(v3(1.0, 0.28, 1.0))
        .then(Transform::translate(centre + v3(0.0, -0.12, 0.0)));
    b.add(&shapes::sphere(0.36, 48), &cushion, m.cushion);
    let hook = v3(centre.x, 2.05, centre.z);
    for k in 0..4 {
        let a = std::f32::consts::FRAC_PI_2 * k as f32 + 0.4;
        let on_rim = v3(
            centre.x + rim_radius * a.sin(),
            rim_height,
            centre.z + rim_radius * a.cos(),
        );
        b.add(
            &shapes::rod(on_rim, hook, 0.012, 8),
            &Transform::IDENTITY,
            m.rope,
        );
    }
    b.add(
        &shapes::torus(0.06, 0.012, 24, 8),
        &Transform::rotate_x(90.0).then(Transform::translate(hook)),
        m.brass,
    );
    b.add(
        &shapes::rod(hook, v3(centre.x, 2.35, centre.z), 0.02, 10),
        &Transform::IDENTITY,
        m.rope,
    );
}

/// A chest, a side table with a ball and a vase, a stack of books and a rug.
fn furniture(b: &mut SceneBuilder, m: &Materials) {
    // Chest with a lid band.
    let chest = Transform::rotate_y(12.0).then(Transform::translate(v3(-4.2, 0.0, -2.9)));
    b.add(
        &shapes::cuboid(v3(-0.5, 0.0, -0.3), v3(0.5, 0.5, 0.3)),
        &chest,
        m.dark_wood,
    );
    b.add(
        &shapes::cuboid(v3(-0.52, 0.5, -0.32), v3(0.52, 0.6, 0.32)),
        &chest,
        m.dark_wood,
    );
    b.add(
        &shapes::cuboid(v3(-0.53, 0.44, -0.33), v3(0.53, 0.5, 0.33)),
        &chest,
        m.brass,
    );
    // Side table.
    let table = Transform::translate(v3(-1.9, 0.0, 2.3));
    b.add(
        &shapes::cuboid(v3(-0.45, 0.68, -0.45), v3(0.45, 0.72, 0.45)),
        &table,
        m.painted,
    );
    for (x, z) in [(-0.38, -0.38), (0.38, -0.38), (-0.38, 0.38), (0.38, 0.38)] {
        b.add(
            &shapes::cylinder(0.025, 0.68, 12, false),
            &Transform::translate(v3(x, 0.0, z)).then(table),
            m.dark_wood,
        );
    }
    b.add(
        &shapes::sphere(0.12, 48),
        &Transform::translate(v3(-0.15, 0.84, 0.1)).then(table),
        m.brass,
    );
    b.add(
        &shapes::cylinder(0.08, 0.3, 32, true),
        &Transform::translate(v3(0.2, 0.72, -0.1)).then(table),
        m.glaze,
    );
    // Books.
    let mut y = 0.0;
    for (k, book) in m.books.iter().enumerate() {
        let h = 0.05 + 0.01 * k as f32;
        let place =
            Transform::rotate_y(7.0 * k as f32 - 10.0).then(Transform::translate(v3(3.9, y, 2.9)));
        b.add(
            &shapes::cuboid(v3(-0.16, 0.0, -0.11), v3(0.16, h, 0.11)),
            &place,
            *book,
        );
        y += h;
    }
    // Rug under the chair, a hair above the floor.
    b.add(
        &shapes::quad(v3(0.2, 0.004, -1.2), v3(2.6, 0.0, 0.0), v3(0.0, 0.0, -1.8)),
        &Transform::IDENTITY,
        m.rug,
    );
}
