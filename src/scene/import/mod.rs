//! Scenes in other renderers' formats, read into the description a TOML scene file gives
//! ([`super::description::SceneDescription`]): Mitsuba 3 XML and pbrt-v4.
pub(crate) mod mitsuba;
pub(crate) mod pbrt;

use super::description::{CameraDescription, SceneDescription};
use crate::error::{Error, Result};
use std::collections::BTreeMap;
use std::path::PathBuf;
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

/// What an importer produced: the description, its warnings and the files it read.
pub(crate) struct Imported {
    pub description: SceneDescription,
    pub warnings: Vec<String>,
    pub sources: Vec<PathBuf>,
}

/// An empty description to fill. Its camera is a placeholder: both importers always set the
/// camera (from the sensor, or the format's default) before building.
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
        },
        materials: BTreeMap::new(),
        textures: BTreeMap::new(),
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
    Toml,
    Mitsuba,
    Pbrt,
}

impl Format {
    #[must_use]
    pub fn of(path: &std::path::Path) -> Self {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("xml") => Format::Mitsuba,
            Some("pbrt") => Format::Pbrt,
            _ => Format::Toml,
        }
    }
}
