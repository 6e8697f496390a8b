//! Built-in procedural scenes, one file each, registered in [`BUILT_IN`].
//!
//! * `attic` — seed 004's attic: a gabled room with pillars, beams, rafters, gable
//!   and roof windows, a hanging chair, plank floor, plaster and brick walls; seen
//!   by a 1024×256 cylindrical panorama. The shell (floor, walls, roof) lets light
//!   through so that every direction of the sphere lights the room (as in the seed's
//!   renders); everything inside casts shadows.
//! * `city` — a street of buildings in brick, plaster, concrete and glass with
//!   windows, ledges, trees, lamp posts and parked cars; 1024×256 cylindrical.
//! * `box` — seed 004 figure 8: a box lying on a plane; 512×384 pinhole.
//!
//! Geometry is in metres, y up. Scenes are pure functions of nothing: the same name
//! always gives the same triangles.

mod attic;
mod box_on_plane;
mod city;

use crate::scene::Scene;
use crate::{invalid, Result};

/// A scene the studio can build by name.
pub struct BuiltInScene {
    pub name: &'static str,
    pub description: &'static str,
    build: fn() -> Result<Scene>,
}

/// Every built-in scene.
pub const BUILT_IN: [BuiltInScene; 3] = [
    BuiltInScene { name: "attic", description: "gabled attic with pillars, beams, windows and a hanging chair (cylindrical 1024×256)", build: attic::build },
    BuiltInScene { name: "city", description: "street of brick, plaster and glass buildings with trees and cars (cylindrical 1024×256)", build: city::build },
    BuiltInScene { name: "box", description: "a box lying on a plane, seed 004 figure 8 (pinhole 512×384)", build: box_on_plane::build },
];

/// Build the built-in scene called `name`.
pub fn build(name: &str) -> Result<Scene> {
    let wanted = name.trim().to_ascii_lowercase();
    match BUILT_IN.iter().find(|s| s.name == wanted) {
        Some(s) => (s.build)(),
        None => Err(invalid(format!(
            "unknown scene `{name}`: expected a built-in scene ({}), an .obj file or a .json scene file",
            names().join(", ")
        ))),
    }
}

/// The names of the built-in scenes.
pub fn names() -> Vec<&'static str> {
    BUILT_IN.iter().map(|s| s.name).collect()
}
