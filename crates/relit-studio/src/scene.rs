//! Scenes: triangles with materials, their BVH, and a default camera.

use crate::bvh::{Aabb, Bvh, TraceRay};
use crate::material::{Material, Reflectance};
use crate::math::{Transform, V3};
use crate::shapes::{Mesh, Triangle};
use crate::{invalid, Result};
use relit::camera::{Camera, CameraSpec};
use std::collections::HashMap;
use std::path::PathBuf;

/// Index of a material in its scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MaterialId(pub u32);

/// Collects geometry and materials, then builds a [`Scene`].
#[derive(Debug, Default)]
pub struct SceneBuilder {
    triangles: Vec<Triangle>,
    material_of: Vec<u32>,
    materials: Vec<Material>,
    by_name: HashMap<String, MaterialId>,
    warnings: Vec<String>,
    files: Vec<PathBuf>,
}

impl SceneBuilder {
    /// Note a problem that does not stop the build (a missing texture…).
    pub fn warn(&mut self, message: String) {
        self.warnings.push(message);
    }

    /// Note a file the scene is read from (see [`Scene::files`]).
    pub fn read_file(&mut self, path: PathBuf) {
        if !self.files.contains(&path) {
            self.files.push(path);
        }
    }

    pub fn new() -> SceneBuilder {
        SceneBuilder::default()
    }

    /// Register a material; a second material of the same name replaces nothing and
    /// returns the first one's id.
    pub fn material(&mut self, material: Material) -> MaterialId {
        if let Some(&id) = self.by_name.get(&material.name) {
            return id;
        }
        let id = MaterialId(self.materials.len() as u32);
        self.by_name.insert(material.name.clone(), id);
        self.materials.push(material);
        id
    }

    /// The id of the material called `name`, if registered.
    pub fn material_named(&self, name: &str) -> Option<MaterialId> {
        self.by_name.get(name).copied()
    }

    /// Add `mesh` mapped by `transform` with material `material`.
    pub fn add(&mut self, mesh: &Mesh, transform: &Transform, material: MaterialId) {
        self.triangles.reserve(mesh.triangles.len());
        for t in &mesh.triangles {
            self.triangles.push(if *transform == Transform::IDENTITY {
                *t
            } else {
                t.transformed(transform)
            });
            self.material_of.push(material.0);
        }
    }

    /// The bounds of the vertices added so far, `None` before any.
    pub fn bounds(&self) -> Option<(V3, V3)> {
        let mut points = self.triangles.iter().flat_map(|t| t.p);
        let first = points.next()?;
        Some(points.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Triangles added so far.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Build the BVH and finish the scene. Fails on an empty scene, a material id
    /// that was never registered, or invalid material parameters.
    pub fn build(self, name: &str, camera: CameraSpec) -> Result<Scene> {
        if self.triangles.is_empty() {
            return Err(invalid(format!("scene `{name}` has no triangles")));
        }
        for m in &self.materials {
            m.validate()?;
        }
        if self
            .material_of
            .iter()
            .any(|&m| m as usize >= self.materials.len())
        {
            return Err(invalid(format!(
                "scene `{name}` uses a material it does not define"
            )));
        }
        camera.build()?;
        let positions: Vec<[V3; 3]> = self.triangles.iter().map(|t| t.p).collect();
        let bvh = Bvh::build(&positions);
        let bounds = bvh.bounds();
        if bounds.is_empty() {
            return Err(invalid(format!(
                "scene `{name}` has no triangle with an area"
            )));
        }
        // Shadow rays see only the surfaces that block light. When some do not (the
        // shell of an interior), they get a tree of their own: the shell's large
        // triangles would otherwise be tested, and skipped, by nearly every shadow ray.
        let casters: Vec<[V3; 3]> = self
            .triangles
            .iter()
            .zip(&self.material_of)
            .filter(|(_, &m)| self.materials[m as usize].casts_shadows)
            .map(|(t, _)| t.p)
            .collect();
        let shadow_bvh = (casters.len() < positions.len()).then(|| Bvh::build(&casters));
        Ok(Scene {
            name: name.into(),
            triangles: self.triangles,
            material_of: self.material_of,
            materials: self.materials,
            bvh,
            shadow_bvh,
            camera,
            warnings: self.warnings,
            files: self.files,
        })
    }
}

/// A traceable scene.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    triangles: Vec<Triangle>,
    material_of: Vec<u32>,
    materials: Vec<Material>,
    bvh: Bvh,
    /// The shadow-casting triangles, when not all of them cast shadows.
    shadow_bvh: Option<Bvh>,
    /// The camera the scene was designed for.
    pub camera: CameraSpec,
    /// Problems met while loading that did not stop it, for the caller to show.
    pub warnings: Vec<String>,
    /// The files the scene was read from: scene file, OBJ and MTL files, textures
    /// (empty for built-in scenes), so that commands can refuse to write over them.
    pub files: Vec<PathBuf>,
}

/// What a primary or bounce ray sees.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub t: f32,
    pub position: V3,
    /// Geometric normal, turned toward the incoming ray.
    pub geometric_normal: V3,
    /// Interpolated shading normal, on the same side as `geometric_normal`.
    pub shading_normal: V3,
    pub reflectance: Reflectance,
}

impl Scene {
    /// The number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The bounds of the geometry.
    pub fn bounds(&self) -> Aabb {
        self.bvh.bounds()
    }

    /// The materials.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// The default camera, built.
    pub fn default_camera(&self) -> Result<Camera> {
        self.camera.build()
    }

    /// The distance shadow rays start off a surface: small against the scene, large
    /// against f32 rounding at its farthest points.
    pub fn ray_epsilon(&self) -> f32 {
        let b = self.bounds();
        let reach = b
            .min
            .x
            .abs()
            .max(b.min.y.abs())
            .max(b.min.z.abs())
            .max(b.max.x.abs())
            .max(b.max.y.abs())
            .max(b.max.z.abs());
        (b.extent().length() * 1e-5).max(reach * 4e-6).max(1e-6)
    }

    /// The nearest surface along a ray (unit direction), within `t_max`.
    pub fn intersect(&self, origin: V3, direction: V3, t_max: f32) -> Option<SurfaceHit> {
        let ray = TraceRay::new(origin, direction);
        let hit = self.bvh.intersect(&ray, t_max)?;
        let tri = &self.triangles[hit.triangle as usize];
        let w = 1.0 - hit.u - hit.v;
        let face = (tri.p[1] - tri.p[0])
            .cross(tri.p[2] - tri.p[0])
            .normalized();
        let toward_ray = if face.dot(direction) > 0.0 { -1.0 } else { 1.0 };
        let geometric_normal = face * toward_ray;
        let mut shading_normal = (tri.n[0] * w + tri.n[1] * hit.u + tri.n[2] * hit.v).normalized();
        if shading_normal.dot(geometric_normal) <= 0.0 || !shading_normal.is_finite() {
            // Normals given for the other side (or none at all): the face decides.
            shading_normal = if (shading_normal * -1.0).dot(geometric_normal) > 0.0 {
                -shading_normal
            } else {
                geometric_normal
            };
        }
        let uv = [
            tri.uv[0][0] * w + tri.uv[1][0] * hit.u + tri.uv[2][0] * hit.v,
            tri.uv[0][1] * w + tri.uv[1][1] * hit.u + tri.uv[2][1] * hit.v,
        ];
        let m = &self.materials[self.material_of[hit.triangle as usize] as usize];
        let reflectance = Reflectance {
            albedo: m.albedo.sample(uv),
            specular: m.specular,
            shininess: m.shininess,
        };
        Some(SurfaceHit {
            t: hit.t,
            position: origin + direction * hit.t,
            geometric_normal,
            shading_normal,
            reflectance,
        })
    }

    /// Whether a shadow-casting surface lies on the ray before `t_max`.
    pub fn occluded(&self, origin: V3, direction: V3, t_max: f32) -> bool {
        let tree = self.shadow_bvh.as_ref().unwrap_or(&self.bvh);
        tree.occluded(&TraceRay::new(origin, direction), t_max)
    }
}
