//! Scenes in other renderers' formats, read into the description a TOML scene file gives
//! ([`super::description::SceneDescription`]): Mitsuba 3 XML and pbrt-v4.
pub(crate) mod mitsuba;
pub(crate) mod pbrt;

use super::description::{CameraDescription, InlineMesh, MeshDescription, SceneDescription, ShapeDescription};
use super::limits::MAX_SCENE_BYTES;
use crate::error::{Error, Result};
use glam::{DMat4, DVec3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Where an element or directive stands: file and line.
#[derive(Clone, Debug)]
pub(crate) struct At {
    pub file: Rc<PathBuf>,
    pub line: u32,
}

impl std::fmt::Display for At {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}", self.file.display(), self.line)
    }
}

/// A malformed file: one error naming file and line.
pub(crate) fn syntax(at: &At, message: impl Into<String>) -> Error {
    Error::SceneSyntax { path: at.file.to_path_buf(), message: format!("line {}: {}", at.line, message.into()) }
}

/// Something outside the supported subset: a warning naming file and line (and the fallback
/// the message gives), or with `strict` the error it would be.
pub(crate) fn unsupported(strict: bool, warnings: &mut Vec<String>, at: &At, message: String) -> Result<()> {
    if strict {
        return Err(syntax(at, format!("{message} (--strict)")));
    }
    warnings.push(format!("{at}: {message}"));
    Ok(())
}

/// Deepest nesting of included files (a cycle stops here).
const MAX_INCLUDE_DEPTH: usize = 16;
/// Most files read in all (files that include each other many times over would otherwise
/// multiply).
const MAX_INCLUDES: usize = 1024;

/// The include guard both importers share: how deep includes nest now, and every file read
/// (the scene's sources, the main file first).
pub(crate) struct Includes {
    depth: usize,
    /// Every file read, the main scene file first.
    pub files: Vec<PathBuf>,
}

impl Includes {
    /// The guard of a scene read from `main`.
    pub(crate) fn new(main: &Path) -> Self {
        Self { depth: 0, files: vec![main.to_path_buf()] }
    }

    /// Reads the file `path` (written `name`) included at `at`, refused where includes nest
    /// deeper than [`MAX_INCLUDE_DEPTH`] or more than [`MAX_INCLUDES`] files were read; the
    /// caller reads its text, then calls [`Includes::leave`]. An empty name, or a file that
    /// cannot be read, is an error at `at` (the including file and line).
    pub(crate) fn enter(&mut self, name: &str, path: &Path, at: &At) -> Result<String> {
        if name.trim().is_empty() {
            return Err(syntax(at, "the include names no file (an empty path)"));
        }
        if self.depth >= MAX_INCLUDE_DEPTH {
            return Err(syntax(at, format!("includes nest deeper than {MAX_INCLUDE_DEPTH} (a cycle?)")));
        }
        if self.files.len() > MAX_INCLUDES {
            return Err(syntax(at, format!("more than {MAX_INCLUDES} included files")));
        }
        let text = crate::io::read_text(path, MAX_SCENE_BYTES, "included file").map_err(|e| match e {
            Error::Io { .. } => syntax(at, format!("cannot include {e}")),
            e => e,
        })?;
        self.files.push(path.to_path_buf());
        self.depth += 1;
        Ok(text)
    }

    /// The end of the file [`Includes::enter`] read.
    pub(crate) fn leave(&mut self) {
        self.depth -= 1;
    }
}

/// What an importer produced: the description, its warnings and the files it read.
pub(crate) struct Imported {
    pub description: SceneDescription,
    pub warnings: Vec<String>,
    pub sources: Vec<PathBuf>,
}

/// An empty description to fill, its camera one pixel at the origin looking along +z. Both
/// importers replace the camera with the scene's own (its sensor, or the format's default
/// view) when they finish reading.
pub(crate) fn empty_description() -> SceneDescription {
    SceneDescription {
        camera: CameraDescription {
            eye: [0.0; 3],
            look_at: [0.0, 0.0, 1.0],
            up: [0.0, 1.0, 0.0],
            fov_y: 45.0,
            width: 1,
            height: 1,
            crop: None,
            mirror: false,
            filter: None,
            medium: None,
        },
        origins: std::collections::HashMap::new(),
        materials: BTreeMap::new(),
        textures: BTreeMap::new(),
        media: BTreeMap::new(),
        meshes: Vec::new(),
        shapes: Vec::new(),
        lights: Vec::new(),
        environment: None,
        render: None,
        inline_meshes: Vec::new(),
    }
}

/// A 4×4 matrix as rows (the description's `matrix`).
pub(crate) fn to_rows(m: glam::DMat4) -> [[f32; 4]; 4] {
    let t = m.transpose();
    [t.x_axis, t.y_axis, t.z_axis, t.w_axis].map(|r| r.as_vec4().to_array())
}

/// How foreign scene files are read.
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// `-D name=value`: values for `$name` in a Mitsuba scene (over its `<default>`s).
    pub defines: Vec<(String, String)>,
    /// Anything outside the supported subset is an error, not a warning.
    pub strict: bool,
}

/// The formats a scene file can be in, by its extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// zvidpt's TOML (`.toml`).
    Toml,
    /// Mitsuba 3 XML (`.xml`).
    Mitsuba,
    /// pbrt-v4 (`.pbrt`).
    Pbrt,
}

impl Format {
    /// The format of `path` by its extension (TOML unless `.xml` or `.pbrt`).
    #[must_use]
    pub fn of(path: &std::path::Path) -> Self {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("xml") => Format::Mitsuba,
            Some("pbrt") => Format::Pbrt,
            _ => Format::Toml,
        }
    }
}

/// The shapes of an instancing prototype (pbrt's object, Mitsuba's shapegroup) as the
/// description holds them, each already placed by the transforms given at its definition.
/// Instancing copies them, placed further by the instance's transform: instances are
/// flattened into triangles (memory grows with the copies; the loader's triangle limit holds).
#[derive(Clone, Debug, Default)]
pub(crate) struct Prototype {
    meshes: Vec<MeshDescription>,
    shapes: Vec<ShapeDescription>,
    inline: Vec<InlineMesh>,
}

/// How much a description held when a prototype's definition began.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mark {
    meshes: usize,
    shapes: usize,
    inline: usize,
}

/// Most triangles written out inline that instancing may copy, in all (pbrt's instanced
/// `trianglemesh`es; meshes from files are counted by the loader).
pub(crate) const MAX_INSTANCED_TRIANGLES: usize = crate::scene::limits::MAX_TRIANGLES;

impl Prototype {
    pub(crate) fn mark(out: &SceneDescription) -> Mark {
        Mark { meshes: out.meshes.len(), shapes: out.shapes.len(), inline: out.inline_meshes.len() }
    }

    /// Takes what `out` gained since `mark` out of it, as a prototype.
    pub(crate) fn capture(out: &mut SceneDescription, mark: Mark) -> Self {
        Self {
            meshes: out.meshes.split_off(mark.meshes.min(out.meshes.len())),
            shapes: out.shapes.split_off(mark.shapes.min(out.shapes.len())),
            inline: out.inline_meshes.split_off(mark.inline.min(out.inline_meshes.len())),
        }
    }

    /// Adds a copy placed by `m` (after the prototype's own transforms) to `out`. `budget`:
    /// inline triangles still allowed; an error when the copy would exceed it.
    pub(crate) fn instantiate(
        &self,
        m: DMat4,
        out: &mut SceneDescription,
        budget: &mut usize,
    ) -> std::result::Result<(), String> {
        let det = m.determinant();
        if !(m.is_finite() && det.is_finite() && det != 0.0) {
            return Err("the instance's transform is not finite or flattens it".into());
        }
        let triangles: usize = self.inline.iter().map(|i| i.indices.len() / 3).sum();
        *budget = budget
            .checked_sub(triangles)
            .ok_or_else(|| format!("instancing copies more than {MAX_INSTANCED_TRIANGLES} triangles"))?;
        for mesh in &self.meshes {
            let own = mesh.matrix.as_ref().map_or(DMat4::IDENTITY, from_rows);
            out.meshes.push(MeshDescription { matrix: Some(to_rows(m * own)), ..mesh.clone() });
        }
        // (The importers place every shape by `matrix`.)
        for shape in &self.shapes {
            let own = shape.matrix.as_ref().map_or(DMat4::IDENTITY, from_rows);
            out.shapes.push(ShapeDescription { matrix: Some(to_rows(m * own)), ..shape.clone() });
        }
        let normal_map = m.inverse().transpose();
        for mesh in &self.inline {
            let has_normals = mesh.normals.is_some();
            out.inline_meshes.push(InlineMesh {
                positions: mesh
                    .positions
                    .iter()
                    .map(|p| m.transform_point3(DVec3::from_array(p.map(f64::from))).as_vec3().to_array())
                    .collect(),
                normals: mesh.normals.as_ref().map(|n| {
                    n.iter()
                        .map(|v| normal_map.transform_vector3(DVec3::from_array(v.map(f64::from))).as_vec3().to_array())
                        .collect()
                }),
                // Without normals, the winding says which side is out: a mirroring instance
                // turns it (with normals, they decide).
                reverse_winding: mesh.reverse_winding != (det < 0.0 && !has_normals),
                ..mesh.clone()
            });
        }
        Ok(())
    }
}

/// Rows (the description's `matrix`) as a matrix.
pub(crate) fn from_rows(r: &[[f32; 4]; 4]) -> DMat4 {
    DMat4::from_cols_array_2d(&r.map(|row| row.map(f64::from))).transpose()
}
