//! Wavefront OBJ + MTL models (via `tobj`).
//!
//! Faces are triangulated; vertex normals, when the file has them, give smooth
//! shading. From each MTL material relit takes the diffuse colour `Kd` or texture
//! `map_Kd` (any image relit reads, relative to the MTL's folder), the specular colour
//! `Ks` (its mean becomes the glossy strength) and the exponent `Ns`. Emission (`Ke`)
//! is ignored: the studio's lights are its emitters. A missing or broken MTL file or
//! texture is not fatal: the model renders in a neutral grey and the loader reports
//! a warning.

use crate::material::Material;
use crate::math::{v3, Transform, V3};
use crate::scene::{MaterialId, Scene, SceneBuilder};
use crate::shapes::{Mesh, Triangle};
use crate::texture::{ImageTexture, Texture};
use crate::{invalid, parse_error, Result};
use relit::camera::{CameraSpec, Pose, Projection};
use relit::sphere::Vec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A loaded model: meshes with an index into `materials` each.
#[derive(Clone, Debug)]
pub struct ObjModel {
    pub parts: Vec<(Mesh, usize)>,
    pub materials: Vec<Material>,
    /// Problems that did not stop the load (missing MTL or texture…).
    pub warnings: Vec<String>,
    /// The files read: the OBJ, its MTL files and their textures.
    pub files: Vec<PathBuf>,
}

/// The albedo of surfaces whose material is unknown.
const NEUTRAL_GREY: f32 = 0.6;

/// The checks `tobj` makes without saying where, made first with the line: every
/// vertex position finite, every face's vertex index within the vertices defined so far
/// (1-based, or negative counting back), so that a broken model is refused naming its
/// line rather than loaded with a hole or a degenerate triangle.
fn check_lines(path: &Path, reader: &mut impl std::io::BufRead) -> Result<()> {
    let at =
        |line: usize, what: String| parse_error(format!("{}: line {line}: {what}", path.display()));
    let mut vertices = 0i64;
    let mut text = String::new();
    let mut line = 0;
    loop {
        text.clear();
        match reader.read_line(&mut text) {
            Ok(0) => return Ok(()),
            Ok(_) => line += 1,
            // Not text: tobj reports it.
            Err(_) => return Ok(()),
        }
        let mut words = text.split_whitespace();
        match words.next() {
            Some("v") => {
                let xyz: Vec<f64> = words.take(3).filter_map(|w| w.parse().ok()).collect();
                if xyz.len() < 3 || !xyz.iter().all(|c| c.is_finite()) {
                    return Err(at(
                        line,
                        format!("a vertex needs three finite numbers: `{}`", text.trim()),
                    ));
                }
                vertices += 1;
            }
            Some("f") => {
                for corner in words {
                    let index = corner.split('/').next().unwrap_or("");
                    let ok = match index.parse::<i64>() {
                        Ok(i) if i > 0 => i <= vertices,
                        Ok(i) if i < 0 => -i <= vertices,
                        _ => false,
                    };
                    if !ok {
                        return Err(at(
                            line,
                            format!("face vertex `{corner}` is not one of the {vertices} vertices defined so far"),
                        ));
                    }
                }
            }
            _ => {}
        }
    }
}

/// Load an OBJ file and its materials.
pub fn load(path: &Path) -> Result<ObjModel> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let cannot_load =
        |e: tobj::LoadError| parse_error(format!("cannot load OBJ {}: {e}", path.display()));
    let file =
        std::fs::File::open(path).map_err(|_| cannot_load(tobj::LoadError::OpenFileFailed))?;
    check_lines(path, &mut std::io::BufReader::new(&file))?;
    use std::io::Seek;
    let mut file = file;
    file.rewind()
        .map_err(|_| cannot_load(tobj::LoadError::ReadError))?;
    let folder = path.parent().unwrap_or(Path::new("."));
    // `tobj::load_obj`, with the MTL files it opens written down.
    let mtl_files = std::cell::RefCell::new(Vec::new());
    let (models, mtl) =
        tobj::load_obj_buf(&mut std::io::BufReader::new(file), &options, |mtl_path| {
            let mtl_path = folder.join(mtl_path);
            mtl_files.borrow_mut().push(mtl_path.clone());
            tobj::load_mtl(mtl_path)
        })
        .map_err(cannot_load)?;
    let mut files = vec![path.to_path_buf()];
    files.extend(mtl_files.into_inner());
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "obj".into());
    let mut warnings = Vec::new();
    let mtl = mtl.unwrap_or_else(|e| {
        warnings.push(format!(
            "{}: materials not loaded ({e}); using grey",
            path.display()
        ));
        Vec::new()
    });
    let mut materials: Vec<Material> = mtl
        .iter()
        .map(|m| convert_material(m, &stem, folder, &mut warnings, &mut files))
        .collect();
    let default_index = materials.len();
    materials.push(Material::matte(
        &format!("{stem}/default"),
        Texture::Constant(V3::splat(NEUTRAL_GREY)),
    ));
    let mut parts = Vec::with_capacity(models.len());
    for model in &models {
        let m = &model.mesh;
        let vertex = |i: u32| -> Option<V3> {
            let k = 3 * i as usize;
            m.positions.get(k..k + 3).map(|p| v3(p[0], p[1], p[2]))
        };
        let normal = |i: u32| -> Option<V3> {
            let k = 3 * i as usize;
            m.normals
                .get(k..k + 3)
                .map(|n| v3(n[0], n[1], n[2]).normalized())
        };
        let texcoord = |i: u32| -> [f32; 2] {
            let k = 2 * i as usize;
            m.texcoords
                .get(k..k + 2)
                .map_or([0.0, 0.0], |t| [t[0], t[1]])
        };
        let mut mesh = Mesh::default();
        for face in m.indices.chunks_exact(3) {
            let (Some(a), Some(b), Some(c)) = (vertex(face[0]), vertex(face[1]), vertex(face[2]))
            else {
                return Err(parse_error(format!(
                    "{}: object `{}` has a face index out of range",
                    path.display(),
                    model.name
                )));
            };
            let uv = [texcoord(face[0]), texcoord(face[1]), texcoord(face[2])];
            let mut tri = Triangle::flat([a, b, c], uv);
            if let (Some(na), Some(nb), Some(nc)) =
                (normal(face[0]), normal(face[1]), normal(face[2]))
            {
                if na.is_finite()
                    && nb.is_finite()
                    && nc.is_finite()
                    && na.length() > 0.5
                    && nb.length() > 0.5
                    && nc.length() > 0.5
                {
                    tri.n = [na, nb, nc];
                }
            }
            mesh.triangles.push(tri);
        }
        let material = m
            .material_id
            .filter(|&i| i < mtl.len())
            .unwrap_or(default_index);
        parts.push((mesh, material));
    }
    if parts.iter().all(|(mesh, _)| mesh.triangles.is_empty()) {
        return Err(invalid(format!(
            "{}: the OBJ file has no faces",
            path.display()
        )));
    }
    Ok(ObjModel {
        parts,
        materials,
        warnings,
        files,
    })
}

fn convert_material(
    m: &tobj::Material,
    stem: &str,
    folder: &Path,
    warnings: &mut Vec<String>,
    files: &mut Vec<PathBuf>,
) -> Material {
    let name = format!("{stem}/{}", m.name);
    let clamp01 = |c: [f32; 3]| {
        V3::from(c.map(|v| {
            if v.is_finite() {
                v.clamp(0.0, 1.0)
            } else {
                0.0
            }
        }))
    };
    let diffuse = m.diffuse.map(clamp01).unwrap_or(V3::splat(NEUTRAL_GREY));
    let mut albedo = Texture::Constant(diffuse);
    if let Some(file) = m
        .diffuse_texture
        .as_deref()
        .filter(|f| !f.trim().is_empty())
    {
        let texture_path = folder.join(file.trim());
        files.push(texture_path.clone());
        match relit::image::load_linear(&texture_path, None) {
            Ok(img) => {
                albedo = Texture::Image(ImageTexture {
                    image: Arc::new(img),
                })
            }
            Err(e) => warnings.push(format!(
                "material `{}`: texture {} not loaded ({e}); using Kd",
                m.name,
                texture_path.display()
            )),
        }
    }
    let specular = m
        .specular
        .map(clamp01)
        .map_or(0.0, |s| (s.x + s.y + s.z) / 3.0);
    let shininess = m
        .shininess
        .filter(|s| s.is_finite())
        .map_or(32.0, |s| s.clamp(1.0, 10_000.0));
    Material::glossy(&name, albedo, specular, shininess)
}

impl ObjModel {
    /// Add the model to `builder` mapped by `transform`; `material` replaces every
    /// material of the file when given.
    pub fn add_to(
        &self,
        builder: &mut SceneBuilder,
        transform: &Transform,
        material: Option<MaterialId>,
    ) {
        let ids: Vec<MaterialId> = self
            .materials
            .iter()
            .map(|m| material.unwrap_or_else(|| builder.material(m.clone())))
            .collect();
        for (mesh, index) in &self.parts {
            builder.add(mesh, transform, ids[*index]);
        }
    }

    /// The bounds of the model's vertices.
    pub fn bounds(&self) -> (V3, V3) {
        let mut lo = V3::splat(f32::INFINITY);
        let mut hi = V3::splat(f32::NEG_INFINITY);
        for p in self
            .parts
            .iter()
            .flat_map(|(m, _)| m.triangles.iter().flat_map(|t| t.p))
        {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (lo, hi)
    }
}

/// A scene of one OBJ file, seen from +z by a 40° pinhole that frames its bounds.
pub fn load_scene(path: &Path) -> Result<Scene> {
    let model = load(path)?;
    let mut builder = SceneBuilder::new();
    model.warnings.iter().for_each(|w| builder.warn(w.clone()));
    model
        .files
        .iter()
        .for_each(|f| builder.read_file(f.clone()));
    model.add_to(&mut builder, &Transform::IDENTITY, None);
    let (lo, hi) = model.bounds();
    let camera = framing_camera(lo, hi, 40.0, 640, 480)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "obj".into());
    builder.build(&name, camera)
}

/// A pinhole camera on the +z side of a bounding box, looking at its centre from
/// slightly above, far enough back that the box's bounding sphere fills the view.
pub fn framing_camera(
    lo: V3,
    hi: V3,
    fov_y_deg: f64,
    width: usize,
    height: usize,
) -> Result<CameraSpec> {
    let centre = Vec3::from((lo + hi) * 0.5);
    let radius = ((hi - lo).length() as f64 * 0.5).max(1e-6);
    let distance = radius / (fov_y_deg.to_radians() / 2.0).sin() * 1.05;
    let eye = centre
        + Vec3::new(0.0, 0.25, 1.0)
            .normalized()
            .unwrap_or(Vec3::new(0.0, 0.0, 1.0))
            * distance;
    let pose = Pose::look_at(eye, centre, Vec3::new(0.0, 1.0, 0.0))?;
    Ok(CameraSpec {
        projection: Projection::Planar {
            fov_y_deg: Some(fov_y_deg),
        },
        width,
        height,
        pose,
        orthographic_height: None,
    })
}
