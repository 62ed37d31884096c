//! Loading a scene: the TOML file, its OBJ/MTL meshes, and every check that turns bad input
//! into an error naming the file (and line, where the parser knows it).
use super::description::{MaterialDescription, SceneDescription};
use super::{Camera, Material, Scene};
use crate::geometry::Vec3A;
use crate::{Error, Result};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Largest accepted image side, in pixels.
pub const MAX_RESOLUTION: u32 = 16384;

pub(crate) fn check_resolution(width: u32, height: u32) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("resolution {width}x{height}: width and height must be at least 1"));
    }
    if width > MAX_RESOLUTION || height > MAX_RESOLUTION {
        return Err(format!("resolution {width}x{height} exceeds the maximum of {MAX_RESOLUTION} per side"));
    }
    Ok(())
}

/// A scene argument is a scene file or a folder holding `scene.toml`.
#[must_use]
pub fn resolve_scene_path(path: &Path) -> PathBuf {
    if path.is_dir() { path.join("scene.toml") } else { path.to_path_buf() }
}

impl Scene {
    /// Loads a scene file (or a folder holding `scene.toml`).
    pub fn load(path: impl AsRef<Path>) -> Result<Scene> {
        let path = resolve_scene_path(path.as_ref());
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let description: SceneDescription = toml::from_str(&text).map_err(|e| {
            let line = e.span().map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
            let message = e.message().trim().replace('\n', " ");
            Error::SceneSyntax {
                path: path.clone(),
                message: match line {
                    Some(l) => format!("line {l}: {message}"),
                    None => message,
                },
            }
        })?;
        build(&path, description)
    }
}

fn invalid(path: &Path, message: impl Into<String>) -> Error {
    Error::InvalidScene { path: path.to_path_buf(), message: message.into() }
}

fn vec3(a: [f32; 3]) -> Vec3A {
    Vec3A::from_array(a)
}

fn material_from(path: &Path, name: &str, d: &MaterialDescription) -> Result<Material> {
    let (diffuse, emission) = (vec3(d.diffuse), vec3(d.emission));
    if !diffuse.is_finite() || diffuse.min_element() < 0.0 || diffuse.max_element() > 1.0 {
        return Err(invalid(
            path,
            format!("material `{name}`: diffuse reflectance must lie in [0, 1], got {:?}", d.diffuse),
        ));
    }
    if !emission.is_finite() || emission.min_element() < 0.0 {
        return Err(invalid(
            path,
            format!("material `{name}`: emission must be finite and non-negative, got {:?}", d.emission),
        ));
    }
    Ok(Material { diffuse, emission })
}

fn build(path: &Path, d: SceneDescription) -> Result<Scene> {
    let c = &d.camera;
    check_resolution(c.width, c.height).map_err(|m| invalid(path, format!("camera: {m}")))?;
    if !(c.fov_y > 0.0 && c.fov_y < 180.0) {
        return Err(invalid(path, format!("camera: fov_y must lie in (0, 180) degrees, got {}", c.fov_y)));
    }
    if ![c.eye, c.look_at, c.up].iter().flatten().all(|x| x.is_finite()) {
        return Err(invalid(path, "camera: eye, look_at and up must be finite"));
    }
    let camera = Camera::new(vec3(c.eye), vec3(c.look_at), vec3(c.up), c.fov_y, c.width, c.height)
        .ok_or_else(|| invalid(path, "camera: eye equals look_at, or up is parallel to the view direction"))?;

    let mut materials = Vec::new();
    let mut by_name: HashMap<String, u32> = HashMap::new();
    for (name, m) in &d.materials {
        by_name.insert(name.clone(), materials.len() as u32);
        materials.push(material_from(path, name, m)?);
    }

    let folder = path.parent().unwrap_or(Path::new("."));
    let mut triangles = Vec::new();
    let mut triangle_material = Vec::new();
    let mut degenerate = 0usize;
    for mesh in &d.meshes {
        let obj_path = folder.join(&mesh.obj);
        let override_id = match &mesh.material {
            Some(name) => Some(
                *by_name
                    .get(name)
                    .ok_or_else(|| invalid(path, format!("mesh `{}`: unknown material `{name}`", mesh.obj)))?,
            ),
            None => None,
        };
        load_obj(
            &obj_path,
            override_id,
            mesh.reverse_winding,
            &mut materials,
            &mut by_name,
            &mut triangles,
            &mut triangle_material,
            &mut degenerate,
        )?;
    }
    if triangles.is_empty() {
        return Err(invalid(path, "the scene has no (non-degenerate) triangles"));
    }
    let mut warnings = Vec::new();
    if degenerate > 0 {
        warnings.push(format!("skipped {degenerate} degenerate (zero-area) triangle(s)"));
    }
    let name = path
        .parent()
        .and_then(|p| p.file_name())
        .map_or_else(|| "scene".to_string(), |n| n.to_string_lossy().into_owned());
    Ok(Scene::from_parts(name, path.to_path_buf(), camera, triangles, triangle_material, materials, warnings))
}

#[allow(clippy::too_many_arguments)]
fn load_obj(
    obj_path: &Path,
    override_id: Option<u32>,
    reverse: bool,
    materials: &mut Vec<Material>,
    by_name: &mut HashMap<String, u32>,
    triangles: &mut Vec<[Vec3A; 3]>,
    triangle_material: &mut Vec<u32>,
    degenerate: &mut usize,
) -> Result<()> {
    let mesh_err = |message: String| Error::Mesh { path: obj_path.to_path_buf(), message };
    if !obj_path.is_file() {
        // tobj reports only "open file failed"; the OS error says why.
        return Err(std::fs::File::open(obj_path)
            .err()
            .map_or_else(|| mesh_err("not a file".into()), |e| Error::io(obj_path, e)));
    }
    let options =
        tobj::LoadOptions { triangulate: true, ignore_points: true, ignore_lines: true, ..Default::default() };
    let (models, mtl) = tobj::load_obj(obj_path, &options).map_err(|e| mesh_err(e.to_string()))?;
    // MTL materials: a name the scene file defines wins; otherwise Kd/Ke from the MTL.
    let mut mtl_ids = Vec::new();
    match mtl {
        Ok(list) => {
            for m in list {
                let id = match by_name.get(&m.name) {
                    Some(&id) => id,
                    None => {
                        let d = MaterialDescription {
                            diffuse: m.diffuse.unwrap_or([0.0; 3]),
                            emission: m.emissive.unwrap_or([0.0; 3]),
                        };
                        let id = materials.len() as u32;
                        materials.push(material_from(obj_path, &m.name, &d)?);
                        by_name.insert(m.name.clone(), id);
                        id
                    }
                };
                mtl_ids.push(id);
            }
        }
        Err(e) if override_id.is_none() => {
            return Err(mesh_err(format!(
                "its material library could not be loaded ({e}); add one or give the mesh `material = \"...\"`"
            )));
        }
        Err(_) => {}
    }
    for model in &models {
        let m = &model.mesh;
        if let Some(i) = m.positions.iter().position(|x| !x.is_finite()) {
            return Err(mesh_err(format!("object `{}`: vertex {} has a non-finite coordinate", model.name, i / 3 + 1)));
        }
        let n_vertices = m.positions.len() / 3;
        if let Some(&i) = m.indices.iter().find(|&&i| i as usize >= n_vertices) {
            return Err(mesh_err(format!(
                "object `{}`: vertex index {} out of range ({n_vertices} vertices)",
                model.name,
                i + 1
            )));
        }
        let material = match (override_id, m.material_id) {
            (Some(id), _) => id,
            (None, Some(i)) if i < mtl_ids.len() => mtl_ids[i],
            _ => {
                return Err(mesh_err(format!(
                    "object `{}` has no material (use usemtl, or `material = \"...\"` in the scene)",
                    model.name
                )));
            }
        };
        let vertex = |i: u32| {
            let i = i as usize * 3;
            Vec3A::new(m.positions[i], m.positions[i + 1], m.positions[i + 2])
        };
        for f in m.indices.chunks_exact(3) {
            let mut t = [vertex(f[0]), vertex(f[1]), vertex(f[2])];
            if reverse {
                t.swap(1, 2);
            }
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            if n.length_squared() == 0.0 || !n.normalize().is_finite() {
                *degenerate += 1;
                continue;
            }
            triangles.push(t);
            triangle_material.push(material);
        }
    }
    Ok(())
}
