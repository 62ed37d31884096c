//! Mitsuba 3 XML scenes (RGB mode), read into the same description a TOML scene file gives,
//! in Mitsuba 3's three stages:
//!
//! 1. `reader.rs` reads the file into a tree of owned objects ([`Obj`]): `<default>` values and
//!    `-D name=value` substituted for `$name`, `<include>`d files spliced in, every value parsed
//!    where it stands (so that a malformed one is reported at its own file and line);
//! 2. `translate.rs` resolves references (every `id` known before the first object is
//!    translated) and dispatches the scene's objects, with the typed parameter readers;
//! 3. one file per kind of plugin translates it: `bsdfs.rs` (BSDFs to materials),
//!    `textures.rs`, `shapes.rs` (meshes and shapes with one material each, shapegroups and
//!    instances; an area emitter makes the shape's material emit), `emitters.rs` (other
//!    emitters to lights), `sensor.rs` (sensor, film, sampler and integrator to the camera and
//!    render defaults), `media.rs` (homogeneous media, a shape's `interior` and `exterior`).
//!
//! What lies outside the subset gives one warning naming the element, its file and line, and
//! what is used instead (`strict`: an error).
mod bsdfs;
mod emitters;
mod media;
mod reader;
mod sensor;
mod shapes;
mod textures;
mod translate;

use reader::resolve;
#[cfg(test)]
mod tests;

use super::super::description::{
    CameraDescription, DistributionDescription, EnvLookupDescription, EnvironmentDescription, FilterDescription,
    LightDescription, MaskingDescription, MaterialDescription, MaterialKind, MeshDescription, PixelFilterDescription,
    PixelFilterKind, RenderDescription, RotateDescription, SceneDescription, ShapeDescription, ShapeKind,
    TextureDescription, TextureKind, WrapDescription,
};
use super::{
    At, ImportOptions, Imported, Includes, MAX_INSTANCED_TRIANGLES, Prototype, empty_description, syntax, to_rows,
    unsupported,
};
use crate::error::{Error, Result};
use glam::{DMat4, DVec3, DVec4};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Deepest nesting of elements (roxmltree's own limit is far deeper; a recursive walk must
/// not overflow the stack on a hostile file).
const MAX_ELEMENT_DEPTH: usize = 64;

/// A parameter's value, parsed where it was written.
#[derive(Clone, Debug)]
enum Value {
    Float(f64),
    Integer(i64),
    Boolean(bool),
    Text(String),
    /// `rgb`, or a `spectrum` reduced to RGB.
    Colour([f32; 3]),
    /// `point` or `vector`.
    Vector(DVec3),
    Transform(DMat4),
    /// A nested object (texture, BSDF, …) given for a named parameter, or a `<ref>` to one.
    Object(Box<Obj>),
    Ref(String),
}

/// A Mitsuba object: `<bsdf type="diffuse" id="...">` with its parameters and nested objects.
#[derive(Clone, Debug)]
struct Obj {
    /// The element's tag: `bsdf`, `shape`, `emitter`, `texture`, `sensor`, …
    tag: String,
    /// Its `type` attribute (the plugin).
    plugin: String,
    id: Option<String>,
    at: At,
    /// Named parameters, in file order.
    params: Vec<(String, Value, At)>,
    /// Nested objects without a `name` (a shape's BSDF and emitter, a sensor's film, …),
    /// and `<ref>`s without one.
    children: Vec<Child>,
}

#[derive(Clone, Debug)]
enum Child {
    Obj(Obj),
    Ref(String, At),
}

impl Obj {
    fn param(&self, name: &str) -> Option<&(String, Value, At)> {
        self.params.iter().rev().find(|(n, ..)| n == name)
    }
}

/// The reader's state across the main file and its includes.
struct Reader<'o> {
    options: &'o ImportOptions,
    /// `<default>` values (the command line's `-D` take precedence).
    defaults: HashMap<String, String>,
    warnings: Vec<String>,
    /// The include guard, with every file read (the scene's sources).
    includes: Includes,
    /// The byte offsets of the newlines of each document being read, innermost include last:
    /// a node's line is a binary search, not a count from the start of its file.
    newlines: Vec<Vec<usize>>,
}

/// Reads the Mitsuba 3 scene at `path`.
pub(crate) fn import(path: &Path, text: &str, options: &ImportOptions) -> Result<Imported> {
    let mut reader = Reader {
        options,
        defaults: HashMap::new(),
        warnings: Vec::new(),
        includes: Includes::new(path),
        newlines: Vec::new(),
    };
    let root = reader.read_document(path, text)?;
    let mut t = Translator {
        reader: &mut reader,
        ids: HashMap::new(),
        referenced: std::collections::HashSet::new(),
        out: empty_description(),
        count: 0,
        groups: HashMap::new(),
        in_group: false,
        budget: MAX_INSTANCED_TRIANGLES,
        media: HashMap::new(),
    };
    t.translate(&root)?;
    let description = t.out;
    Ok(Imported { description, warnings: reader.warnings, sources: reader.includes.files })
}

/// Turns the object tree into a scene description.
struct Translator<'r, 'o> {
    reader: &'r mut Reader<'o>,
    /// Every object with an `id`, for `<ref>`s (registered before translation).
    ids: HashMap<String, Obj>,
    /// The ids some `<ref>` names.
    referenced: std::collections::HashSet<String>,
    out: SceneDescription,
    /// Names handed out for materials and textures.
    count: usize,
    /// `shapegroup`s by id; whether one is being read; inline triangles instancing may still
    /// copy.
    groups: HashMap<String, Prototype>,
    in_group: bool,
    budget: usize,
    /// Media translated so far, by id (`None`: vacuum stands in).
    media: HashMap<String, Option<String>>,
}

/// A BSDF as a material, before a shape's emitter is added.
struct MitsubaBsdf {
    material: MaterialDescription,
}

/// Mitsuba 3's default reconstruction filter: a Gaussian of σ 0.5, cut at 2.
const MITSUBA_FILTER: PixelFilterDescription =
    PixelFilterDescription { kind: PixelFilterKind::Gaussian, stddev: Some(0.5), radius: None };
