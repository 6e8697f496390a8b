//! JSON scene files: objects, transforms, materials and a camera.
//!
//! ```json
//! {
//!   "camera": { "projection": { "type": "planar", "fov_y_deg": 45 }, "width": 640, "height": 480,
//!               "eye": [0, 1.5, 4], "look_at": [0, 0.5, 0] },
//!   "materials": {
//!     "floor": { "texture": { "type": "checker", "a": [0.8, 0.8, 0.8], "b": [0.2, 0.2, 0.2], "size": 0.5 } },
//!     "red":   { "albedo": [0.7, 0.1, 0.1], "specular": 0.1, "shininess": 60 },
//!     "wood":  { "texture": { "type": "image", "file": "wood.png" } }
//!   },
//!   "objects": [
//!     { "type": "quad", "size": [10, 10], "material": "floor", "transform": { "rotate_deg": [-90, 0, 0] } },
//!     { "type": "box", "size": [1, 1, 1], "material": "red",
//!       "transform": { "rotate_deg": [0, 30, 0], "translate": [0, 0.5, 0] } },
//!     { "type": "sphere", "radius": 0.5, "material": "red", "transform": { "translate": [1.5, 0.5, 0] } },
//!     { "type": "obj", "file": "bunny.obj", "transform": { "scale": 5 } }
//!   ]
//! }
//! ```
//!
//! **camera** (optional; default: a 40° pinhole on the +z side framing the scene):
//! `projection` as in relit manifests (`planar` with or without `fov_y_deg`,
//! `cylindrical`, `equirectangular`), `width`, `height`, `eye` (default the origin),
//! `look_at` (default: look along −z, the identity orientation of the conventions),
//! `up` (default +y), `orthographic_height` (planar without field of view).
//!
//! **materials**: a map from name to `albedo` (linear RGB, default 0.6 grey) or
//! `texture`, plus `specular` (glossy strength 0–1, default 0), `shininess`
//! (Blinn–Phong exponent, default 32) and `casts_shadows` (default true). Textures:
//! `{"type": "constant", "color": […]}`, `checker` (`a`, `b`, `size`), `planks`
//! (`light`, `dark`, `plank_width`, `plank_length`), `bricks` (`brick`, `mortar_color`,
//! `size: [w, h]`, `mortar`), `plaster` (`color`, `variation`, `scale`), `image`
//! (`file`). Texture coordinates of built-in shapes are metres along the surface.
//!
//! **objects**, each with a `material` (required except for `obj`, where it overrides
//! the file's materials) and an optional `transform`:
//! * `quad` — `size: [w, h]`, centred, in the x–y plane facing +z;
//! * `box` — `size: [x, y, z]`, centred on the origin;
//! * `sphere` — `radius`, `segments` (default 48);
//! * `cylinder` — `radius`, `height`, `segments` (default 32), `caps` (default true):
//!   around +y from y = 0 up;
//! * `obj` — `file`: an OBJ model (relative to the scene file).
//!
//! A `transform` is `scale` (a number or `[x, y, z]`), then `rotate_deg: [x, y, z]`
//! (about x, then y, then z, right-handed), then `translate`. Unknown fields are errors.

use crate::material::Material;
use crate::math::{v3, Transform, V3};
use crate::scene::{MaterialId, Scene, SceneBuilder};
use crate::texture::{Bricks, Checker, ImageTexture, Planks, Plaster, Texture};
use crate::{invalid, io_error, obj, parse_error, shapes, Result};
use relit::camera::{CameraSpec, Pose, Projection};
use relit::sphere::Vec3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// The file as stored.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    #[serde(default)]
    pub camera: Option<CameraEntry>,
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialEntry>,
    pub objects: Vec<ObjectEntry>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEntry {
    pub projection: Projection,
    pub width: usize,
    pub height: usize,
    #[serde(default)]
    pub eye: [f64; 3],
    #[serde(default)]
    pub look_at: Option<[f64; 3]>,
    #[serde(default = "y_up")]
    pub up: [f64; 3],
    #[serde(default)]
    pub orthographic_height: Option<f64>,
}

fn y_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialEntry {
    #[serde(default)]
    pub albedo: Option<[f32; 3]>,
    #[serde(default)]
    pub texture: Option<TextureEntry>,
    #[serde(default)]
    pub specular: f32,
    #[serde(default = "default_shininess")]
    pub shininess: f32,
    #[serde(default = "yes")]
    pub casts_shadows: bool,
}

fn default_shininess() -> f32 {
    32.0
}
fn yes() -> bool {
    true
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum TextureEntry {
    Constant {
        color: [f32; 3],
    },
    Checker {
        a: [f32; 3],
        b: [f32; 3],
        size: f32,
    },
    Planks {
        light: [f32; 3],
        dark: [f32; 3],
        plank_width: f32,
        plank_length: f32,
    },
    Bricks {
        brick: [f32; 3],
        mortar_color: [f32; 3],
        size: [f32; 2],
        mortar: f32,
    },
    Plaster {
        color: [f32; 3],
        variation: f32,
        scale: f32,
    },
    Image {
        file: String,
    },
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformEntry {
    #[serde(default)]
    pub scale: Option<ScaleEntry>,
    #[serde(default)]
    pub rotate_deg: Option<[f32; 3]>,
    #[serde(default)]
    pub translate: Option<[f32; 3]>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum ScaleEntry {
    Uniform(f32),
    Axes([f32; 3]),
}

#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum ObjectEntry {
    Quad {
        size: [f32; 2],
        material: String,
        #[serde(default)]
        transform: TransformEntry,
    },
    Box {
        size: [f32; 3],
        material: String,
        #[serde(default)]
        transform: TransformEntry,
    },
    Sphere {
        radius: f32,
        #[serde(default = "sphere_segments")]
        segments: usize,
        material: String,
        #[serde(default)]
        transform: TransformEntry,
    },
    Cylinder {
        radius: f32,
        height: f32,
        #[serde(default = "cylinder_segments")]
        segments: usize,
        #[serde(default = "yes")]
        caps: bool,
        material: String,
        #[serde(default)]
        transform: TransformEntry,
    },
    Obj {
        file: String,
        #[serde(default)]
        material: Option<String>,
        #[serde(default)]
        transform: TransformEntry,
    },
}

fn sphere_segments() -> usize {
    48
}
fn cylinder_segments() -> usize {
    32
}

/// Most segments a tessellated shape may have around (4 million triangles a sphere).
const MAX_SEGMENTS: usize = 4096;

/// Read and build a scene file.
pub fn load(path: &Path) -> Result<Scene> {
    let text = std::fs::read_to_string(path).map_err(|e| io_error(path, "read", e))?;
    let file: SceneFile = serde_json::from_str(&text)
        .map_err(|e| parse_error(format!("{}: line {}: {e}", path.display(), e.line())))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let mut scene = build(&file, path.parent().unwrap_or(Path::new(".")), &name)
        .map_err(|e| relit::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
    scene.files.insert(0, path.to_path_buf());
    Ok(scene)
}

/// Build a parsed scene file; relative paths resolve against `folder`.
pub fn build(file: &SceneFile, folder: &Path, name: &str) -> Result<Scene> {
    let mut builder = SceneBuilder::new();
    for (material_name, entry) in &file.materials {
        if let Some(TextureEntry::Image { file }) = &entry.texture {
            builder.read_file(folder.join(file));
        }
        let material = material(material_name, entry, folder)
            .map_err(|e| invalid(format!("material `{material_name}`: {e}")))?;
        builder.material(material);
    }
    let lookup = |builder: &SceneBuilder, i: usize, m: &str| -> Result<MaterialId> {
        builder
            .material_named(m)
            .ok_or_else(|| invalid(format!("objects[{i}]: unknown material `{m}`")))
    };
    for (i, object) in file.objects.iter().enumerate() {
        let context = |e: relit::Error| invalid(format!("objects[{i}]: {e}"));
        match object {
            ObjectEntry::Quad {
                size,
                material,
                transform,
            } => {
                check_positive(&[size[0], size[1]]).map_err(context)?;
                let mesh = shapes::quad(
                    v3(-size[0] / 2.0, -size[1] / 2.0, 0.0),
                    v3(size[0], 0.0, 0.0),
                    v3(0.0, size[1], 0.0),
                );
                let id = lookup(&builder, i, material)?;
                builder.add(&mesh, &to_transform(transform).map_err(context)?, id);
            }
            ObjectEntry::Box {
                size,
                material,
                transform,
            } => {
                check_positive(size).map_err(context)?;
                let half = V3::from(*size) * 0.5;
                let id = lookup(&builder, i, material)?;
                builder.add(
                    &shapes::cuboid(-half, half),
                    &to_transform(transform).map_err(context)?,
                    id,
                );
            }
            ObjectEntry::Sphere {
                radius,
                segments,
                material,
                transform,
            } => {
                check_positive(&[*radius]).map_err(context)?;
                check_segments(*segments).map_err(context)?;
                let id = lookup(&builder, i, material)?;
                builder.add(
                    &shapes::sphere(*radius, *segments),
                    &to_transform(transform).map_err(context)?,
                    id,
                );
            }
            ObjectEntry::Cylinder {
                radius,
                height,
                segments,
                caps,
                material,
                transform,
            } => {
                check_positive(&[*radius, *height]).map_err(context)?;
                check_segments(*segments).map_err(context)?;
                let id = lookup(&builder, i, material)?;
                builder.add(
                    &shapes::cylinder(*radius, *height, *segments, *caps),
                    &to_transform(transform).map_err(context)?,
                    id,
                );
            }
            ObjectEntry::Obj {
                file: obj_file,
                material,
                transform,
            } => {
                let model = obj::load(&folder.join(obj_file)).map_err(context)?;
                let id = material
                    .as_deref()
                    .map(|m| lookup(&builder, i, m))
                    .transpose()?;
                model.warnings.iter().for_each(|w| builder.warn(w.clone()));
                model
                    .files
                    .iter()
                    .for_each(|f| builder.read_file(f.clone()));
                model.add_to(&mut builder, &to_transform(transform).map_err(context)?, id);
            }
        }
    }
    let camera = match (&file.camera, builder.bounds()) {
        (Some(entry), _) => camera(entry)?,
        (None, Some((lo, hi))) => obj::framing_camera(lo, hi, 40.0, 640, 480)?,
        (None, None) => return Err(invalid("the scene has no objects")),
    };
    builder.build(name, camera)
}

fn check_positive(values: &[f32]) -> Result<()> {
    if values.iter().all(|v| v.is_finite() && *v > 0.0) {
        Ok(())
    } else {
        Err(invalid("sizes must be positive"))
    }
}

fn check_segments(segments: usize) -> Result<()> {
    if (3..=MAX_SEGMENTS).contains(&segments) {
        Ok(())
    } else {
        Err(invalid(format!("segments must be 3 to {MAX_SEGMENTS}")))
    }
}

fn to_transform(entry: &TransformEntry) -> Result<Transform> {
    let scale = match entry.scale {
        None => V3::splat(1.0),
        Some(ScaleEntry::Uniform(s)) => V3::splat(s),
        Some(ScaleEntry::Axes(a)) => V3::from(a),
    };
    if !(scale.is_finite() && scale.x != 0.0 && scale.y != 0.0 && scale.z != 0.0) {
        return Err(invalid("a scale must be finite and non-zero"));
    }
    let rotate = V3::from(entry.rotate_deg.unwrap_or([0.0; 3]));
    let translate = V3::from(entry.translate.unwrap_or([0.0; 3]));
    if !(rotate.is_finite() && translate.is_finite()) {
        return Err(invalid("a transform must be finite"));
    }
    Ok(Transform::scale(scale)
        .then(Transform::rotate_x(rotate.x))
        .then(Transform::rotate_y(rotate.y))
        .then(Transform::rotate_z(rotate.z))
        .then(Transform::translate(translate)))
}

fn material(name: &str, entry: &MaterialEntry, folder: &Path) -> Result<Material> {
    let rgb = |c: [f32; 3]| -> Result<V3> {
        if c.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)) {
            Ok(V3::from(c))
        } else {
            Err(invalid("colours must be in [0, 1]"))
        }
    };
    let albedo = match (&entry.albedo, &entry.texture) {
        (Some(_), Some(_)) => return Err(invalid("give `albedo` or `texture`, not both")),
        (Some(c), None) => Texture::Constant(rgb(*c)?),
        (None, None) => Texture::Constant(V3::splat(0.6)),
        (None, Some(t)) => match t {
            TextureEntry::Constant { color } => Texture::Constant(rgb(*color)?),
            TextureEntry::Checker { a, b, size } => {
                check_positive(&[*size])?;
                Texture::Checker(Checker {
                    a: rgb(*a)?,
                    b: rgb(*b)?,
                    size: *size,
                })
            }
            TextureEntry::Planks {
                light,
                dark,
                plank_width,
                plank_length,
            } => {
                check_positive(&[*plank_width, *plank_length])?;
                Texture::Planks(Planks {
                    light: rgb(*light)?,
                    dark: rgb(*dark)?,
                    plank_width: *plank_width,
                    plank_length: *plank_length,
                })
            }
            TextureEntry::Bricks {
                brick,
                mortar_color,
                size,
                mortar,
            } => {
                check_positive(&[size[0], size[1]])?;
                if !(mortar.is_finite() && *mortar >= 0.0) {
                    return Err(invalid("mortar must be a non-negative width"));
                }
                Texture::Bricks(Bricks {
                    brick: rgb(*brick)?,
                    mortar_color: rgb(*mortar_color)?,
                    size: *size,
                    mortar: *mortar,
                })
            }
            TextureEntry::Plaster {
                color,
                variation,
                scale,
            } => {
                check_positive(&[*scale])?;
                if !(variation.is_finite() && (0.0..=1.0).contains(variation)) {
                    return Err(invalid("variation must be in [0, 1]"));
                }
                Texture::Plaster(Plaster {
                    color: rgb(*color)?,
                    variation: *variation,
                    scale: *scale,
                })
            }
            TextureEntry::Image { file } => {
                let image = relit::image::load_linear(&folder.join(file), None)?;
                Texture::Image(ImageTexture {
                    image: Arc::new(image),
                })
            }
        },
    };
    let mut m = Material::glossy(name, albedo, entry.specular, entry.shininess);
    m.casts_shadows = entry.casts_shadows;
    m.validate()?;
    Ok(m)
}

fn camera(entry: &CameraEntry) -> Result<CameraSpec> {
    let eye = Vec3::from(entry.eye);
    let pose = match entry.look_at {
        Some(target) => Pose::look_at(eye, Vec3::from(target), Vec3::from(entry.up))?,
        None => Pose::at(eye),
    };
    let spec = CameraSpec {
        projection: entry.projection.clone(),
        width: entry.width,
        height: entry.height,
        pose,
        orthographic_height: entry.orthographic_height,
    };
    spec.build()?;
    Ok(spec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_documented_example_builds_except_its_files() {
        let text = r#"{
          "camera": { "projection": { "type": "planar", "fov_y_deg": 45 }, "width": 64, "height": 48,
                      "eye": [0, 1.5, 4], "look_at": [0, 0.5, 0] },
          "materials": {
            "floor": { "texture": { "type": "checker", "a": [0.8, 0.8, 0.8], "b": [0.2, 0.2, 0.2], "size": 0.5 } },
            "red":   { "albedo": [0.7, 0.1, 0.1], "specular": 0.1, "shininess": 60 }
          },
          "objects": [
            { "type": "quad", "size": [10, 10], "material": "floor", "transform": { "rotate_deg": [-90, 0, 0] } },
            { "type": "box", "size": [1, 1, 1], "material": "red", "transform": { "rotate_deg": [0, 30, 0], "translate": [0, 0.5, 0] } },
            { "type": "sphere", "radius": 0.5, "material": "red", "transform": { "translate": [1.5, 0.5, 0] } },
            { "type": "cylinder", "radius": 0.2, "height": 1, "material": "red" }
          ]
        }"#;
        let file: SceneFile = serde_json::from_str(text).unwrap();
        let scene = build(&file, Path::new("."), "example").unwrap();
        assert_eq!(scene.camera.width, 64);
        // The floor faces up after its −90° turn about x.
        let hit = scene
            .intersect(v3(3.0, 2.0, 3.0), v3(0.0, -1.0, 0.0), f32::INFINITY)
            .unwrap();
        assert!((hit.position.y).abs() < 1e-5 && hit.geometric_normal.y > 0.99);
    }

    #[test]
    fn mistakes_are_reported() {
        let cases = [
            (
                r#"{"objects":[{"type":"box","size":[1,1,1],"material":"nope"}]}"#,
                "unknown material",
            ),
            (
                r#"{"objects":[{"type":"box","size":[1,-1,1],"material":"m"}],"materials":{"m":{}}}"#,
                "positive",
            ),
            (r#"{"objects":[],"materials":{}}"#, "no objects"),
            (
                r#"{"objects":[{"type":"sphere","radius":1,"segments":100000,"material":"m"}],"materials":{"m":{}}}"#,
                "segments",
            ),
            (
                r#"{"objects":[{"type":"box","size":[1,1,1],"material":"m"}],"materials":{"m":{"albedo":[2,0,0]}}}"#,
                "[0, 1]",
            ),
        ];
        for (text, expected) in cases {
            let file: SceneFile = serde_json::from_str(text).unwrap();
            let err = build(&file, Path::new("."), "t").unwrap_err().to_string();
            assert!(err.contains(expected), "{text}: {err}");
        }
        assert!(serde_json::from_str::<SceneFile>(
            r#"{"objects":[{"type":"box","sise":[1,1,1],"material":"m"}]}"#
        )
        .is_err());
    }
}
