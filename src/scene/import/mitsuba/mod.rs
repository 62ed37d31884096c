//! Mitsuba 3 XML scenes (RGB mode), read into the same description a TOML scene file gives.
//!
//! The file is first read into a tree of owned objects ([`Obj`]): `<default>` values and
//! `-D name=value` substituted for `$name`, `<include>`d files spliced in, every value parsed
//! where it stands (so that a malformed one is reported at its own file and line). The tree is
//! then translated: sensor, film and sampler to the camera and render defaults; shapes to
//! meshes and shapes with one material each (an area emitter makes the shape's material
//! emit); BSDFs and textures to materials and textures; other emitters to lights.
//!
//! What lies outside the subset gives one warning naming the element, its file and line, and
//! what is used instead (`strict`: an error).
use super::super::description::{
    CameraDescription, DistributionDescription, EnvLookupDescription, EnvironmentDescription, FilterDescription,
    LightDescription, MaskingDescription, MaterialDescription, MaterialKind, MeshDescription, PixelFilterDescription,
    PixelFilterKind, RenderDescription, RotateDescription, SceneDescription, ShapeDescription, ShapeKind,
    TextureDescription, TextureKind, WrapDescription,
};
use super::{
    At, ImportOptions, Imported, MAX_INSTANCED_TRIANGLES, Prototype, empty_description, syntax, to_rows, unsupported,
};
use crate::error::{Error, Result};
use glam::{DMat4, DVec3, DVec4};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Largest included file read (text), as for a scene file.
const MAX_FILE_BYTES: u64 = 16 << 20;
/// Deepest nesting of `<include>`s (a cycle stops here).
const MAX_INCLUDE_DEPTH: usize = 16;
/// Most `<include>`s read in all (files that include each other many times over would
/// otherwise multiply).
const MAX_INCLUDES: usize = 1024;
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
    include_depth: usize,
    /// Every file read (the scene's sources).
    files: Vec<PathBuf>,
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
        include_depth: 0,
        files: vec![path.to_path_buf()],
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
    };
    t.translate(&root)?;
    let description = t.out;
    Ok(Imported { description, warnings: reader.warnings, sources: reader.files })
}

impl Reader<'_> {
    /// A warning, or with `--strict` the error it would be.
    fn unsupported(&mut self, at: &At, message: String) -> Result<()> {
        unsupported(self.options.strict, &mut self.warnings, at, message)
    }

    /// Parses the document at `path` (text `text`) into its root `<scene>` object.
    fn read_document(&mut self, path: &Path, text: &str) -> Result<Obj> {
        let file = Rc::new(path.to_path_buf());
        let doc = roxmltree::Document::parse(text).map_err(|e| {
            let pos = e.pos();
            Error::SceneSyntax { path: path.to_path_buf(), message: format!("line {}: {e}", pos.row) }
        })?;
        let root = doc.root_element();
        self.newlines.push(text.bytes().enumerate().filter(|&(_, b)| b == b'\n').map(|(i, _)| i).collect());
        let read = self.read_root(&doc, root, &file);
        self.newlines.pop();
        read
    }

    fn read_root(&mut self, doc: &roxmltree::Document, root: roxmltree::Node, file: &Rc<PathBuf>) -> Result<Obj> {
        let at = self.at(doc, root, file);
        if root.tag_name().name() != "scene" {
            return Err(syntax(&at, format!("the root element is <{}>, not <scene>", root.tag_name().name())));
        }
        let mut scene =
            Obj { tag: "scene".into(), plugin: String::new(), id: None, at, params: Vec::new(), children: Vec::new() };
        self.read_children(doc, root, file, &mut scene, 0, false)?;
        Ok(scene)
    }

    /// Where `node` starts: its file and line (1 + the newlines before it).
    fn at(&self, doc: &roxmltree::Document, node: roxmltree::Node, file: &Rc<PathBuf>) -> At {
        let start = node.range().start;
        let line = match self.newlines.last() {
            Some(newlines) => 1 + newlines.partition_point(|&i| i < start),
            None => doc.text_pos_at(start).row as usize,
        };
        At { file: file.clone(), line: u32::try_from(line).unwrap_or(u32::MAX) }
    }

    /// Attribute `name` of `node` with `$name` references substituted.
    fn attr(&self, node: roxmltree::Node, name: &str, at: &At) -> Result<Option<String>> {
        node.attribute(name).map(|v| self.substitute(v, at)).transpose()
    }

    fn required(&self, node: roxmltree::Node, name: &str, at: &At) -> Result<String> {
        self.attr(node, name, at)?
            .ok_or_else(|| syntax(at, format!("<{}> needs the attribute `{name}`", node.tag_name().name())))
    }

    /// `$name` (or `${name}`) replaced by the `-D` value or `<default>`.
    fn substitute(&self, text: &str, at: &At) -> Result<String> {
        if !text.contains('$') {
            return Ok(text.to_string());
        }
        let mut out = String::with_capacity(text.len());
        let mut rest = text;
        while let Some(k) = rest.find('$') {
            out.push_str(&rest[..k]);
            rest = &rest[k + 1..];
            let (name, after) = if let Some(r) = rest.strip_prefix('{') {
                let end = r.find('}').ok_or_else(|| syntax(at, format!("unclosed `${{` in \"{text}\"")))?;
                (&r[..end], &r[end + 1..])
            } else {
                let end = rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(rest.len());
                (&rest[..end], &rest[end..])
            };
            if name.is_empty() {
                return Err(syntax(at, format!("a `$` without a name in \"{text}\"")));
            }
            let value = self
                .options
                .defines
                .iter()
                .rev()
                .find(|(n, _)| n == name)
                .map(|(_, v)| v.as_str())
                .or_else(|| self.defaults.get(name).map(String::as_str))
                .ok_or_else(|| syntax(at, format!("`${name}` has no value (give -D {name}=... or a <default>)")))?;
            out.push_str(value);
            rest = after;
        }
        out.push_str(rest);
        Ok(out)
    }

    /// Reads the element children of `node` into `obj`.
    fn read_children(
        &mut self,
        doc: &roxmltree::Document,
        node: roxmltree::Node,
        file: &Rc<PathBuf>,
        obj: &mut Obj,
        depth: usize,
        in_emitter: bool,
    ) -> Result<()> {
        for child in node.children().filter(roxmltree::Node::is_element) {
            let at = self.at(doc, child, file);
            if depth >= MAX_ELEMENT_DEPTH {
                return Err(syntax(&at, format!("elements nest deeper than {MAX_ELEMENT_DEPTH}")));
            }
            let tag = child.tag_name().name();
            match tag {
                "default" => {
                    let name = self.required(child, "name", &at)?;
                    let value = self.required(child, "value", &at)?;
                    self.defaults.entry(name).or_insert(value);
                }
                "include" => {
                    let name = self.required(child, "filename", &at)?;
                    let path = resolve(&self.files[0], file, &name);
                    if self.include_depth >= MAX_INCLUDE_DEPTH {
                        return Err(syntax(&at, format!("includes nest deeper than {MAX_INCLUDE_DEPTH} (a cycle?)")));
                    }
                    if self.files.len() > MAX_INCLUDES {
                        return Err(syntax(&at, format!("more than {MAX_INCLUDES} included files")));
                    }
                    let text = crate::io::read_text(&path, MAX_FILE_BYTES, "included file")?;
                    self.files.push(path.clone());
                    self.include_depth += 1;
                    let included = self.read_document(&path, &text)?;
                    self.include_depth -= 1;
                    obj.params.extend(included.params);
                    obj.children.extend(included.children);
                }
                "ref" => {
                    let id = self.required(child, "id", &at)?;
                    match self.attr(child, "name", &at)? {
                        Some(name) => obj.params.push((name, Value::Ref(id), at)),
                        None => obj.children.push(Child::Ref(id, at)),
                    }
                }
                "float" | "integer" | "boolean" | "string" | "rgb" | "spectrum" | "point" | "vector" => {
                    let name = self.required(child, "name", &at)?;
                    let value = self.value(child, tag, &at, in_emitter)?;
                    obj.params.push((name, value, at));
                }
                "transform" => {
                    let name = self.required(child, "name", &at)?;
                    let m = self.transform(doc, child, file)?;
                    obj.params.push((name, Value::Transform(m), at));
                }
                "bsdf" | "shape" | "emitter" | "texture" | "sensor" | "film" | "sampler" | "integrator" | "rfilter"
                | "medium" | "phase" | "volume" => {
                    let plugin = self.attr(child, "type", &at)?.unwrap_or_default();
                    let id = self.attr(child, "id", &at)?;
                    let mut nested = Obj {
                        tag: tag.to_string(),
                        plugin,
                        id,
                        at: at.clone(),
                        params: Vec::new(),
                        children: Vec::new(),
                    };
                    self.read_children(doc, child, file, &mut nested, depth + 1, in_emitter || tag == "emitter")?;
                    match self.attr(child, "name", &at)? {
                        Some(name) => obj.params.push((name, Value::Object(Box::new(nested)), at)),
                        None => obj.children.push(Child::Obj(nested)),
                    }
                }
                other => self.unsupported(&at, format!("<{other}> is not part of Mitsuba 3's format: ignored"))?,
            }
        }
        Ok(())
    }

    /// A `<float>`, `<rgb>`, … element's value. A sampled `<spectrum>` becomes linear sRGB as
    /// Mitsuba 3 computes it in RGB mode: as a radiance inside an emitter, else as a
    /// reflectance under D65 (clamped to [0, 1]).
    fn value(&mut self, node: roxmltree::Node, tag: &str, at: &At, in_emitter: bool) -> Result<Value> {
        let text = || self.required(node, "value", at);
        let number = |s: &str| -> Result<f64> {
            let v: f64 = s.trim().parse().map_err(|_| syntax(at, format!("<{tag}>: \"{s}\" is not a number")))?;
            if v.is_finite() { Ok(v) } else { Err(syntax(at, format!("<{tag}>: \"{s}\" is not finite"))) }
        };
        Ok(match tag {
            "float" => Value::Float(number(&text()?)?),
            "integer" => {
                let s = text()?;
                Value::Integer(
                    s.trim().parse().map_err(|_| syntax(at, format!("<integer>: \"{s}\" is not an integer")))?,
                )
            }
            "boolean" => Value::Boolean(match text()?.trim() {
                "true" => true,
                "false" => false,
                s => return Err(syntax(at, format!("<boolean>: \"{s}\" is neither true nor false"))),
            }),
            "string" => Value::Text(text()?),
            "rgb" => {
                let s = text()?;
                let v = numbers(&s).map_err(|m| syntax(at, format!("<rgb>: {m}")))?;
                match v[..] {
                    [g] => Value::Colour([g as f32; 3]),
                    [r, g, b] => Value::Colour([r as f32, g as f32, b as f32]),
                    _ => return Err(syntax(at, format!("<rgb> needs 1 or 3 numbers, got \"{s}\""))),
                }
            }
            "spectrum" => {
                if node.attribute("filename").is_some() {
                    self.unsupported(at, "<spectrum filename=...> is not read: grey 0.5 used".into())?;
                    return Ok(Value::Colour([0.5; 3]));
                }
                let s = text()?;
                if s.contains(':') {
                    let mut points = Vec::new();
                    for pair in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
                        let (l, v) = pair
                            .split_once(':')
                            .ok_or_else(|| syntax(at, format!("<spectrum>: \"{pair}\" is not λ:value")))?;
                        points.push((number(l)?, number(v)?));
                    }
                    let rgb = crate::material::cie::spectrum_to_rgb(&points, in_emitter).ok_or_else(|| {
                        syntax(at, "<spectrum> needs two or more λ:value pairs with increasing wavelengths")
                    })?;
                    Value::Colour(if in_emitter { rgb.map(|c| c.max(0.0)) } else { rgb.map(|c| c.clamp(0.0, 1.0)) })
                } else {
                    let v = numbers(&s).map_err(|m| syntax(at, format!("<spectrum>: {m}")))?;
                    match v[..] {
                        [g] => Value::Colour([g as f32; 3]),
                        _ => {
                            return Err(syntax(
                                at,
                                format!("<spectrum> needs one number or λ:value pairs, got \"{s}\""),
                            ));
                        }
                    }
                }
            }
            _ => Value::Vector(self.vector(node, at, 0.0)?),
        })
    }

    /// `x`/`y`/`z` attributes (each defaulting to `default`), or `value="x, y, z"` (one number:
    /// all three).
    fn vector(&self, node: roxmltree::Node, at: &At, default: f64) -> Result<DVec3> {
        if let Some(s) = self.attr(node, "value", at)? {
            let v = numbers(&s).map_err(|m| syntax(at, m))?;
            return match v[..] {
                [a] => Ok(DVec3::splat(a)),
                [x, y, z] => Ok(DVec3::new(x, y, z)),
                _ => Err(syntax(at, format!("\"{s}\" needs 1 or 3 numbers"))),
            };
        }
        let mut v = DVec3::splat(default);
        for (k, name) in ["x", "y", "z"].iter().enumerate() {
            if let Some(s) = self.attr(node, name, at)? {
                v[k] = one_number(&s).map_err(|m| syntax(at, m))?;
            }
        }
        Ok(v)
    }

    /// A `<transform>`'s operations, each applied after (to the left of) the ones before.
    fn transform(&mut self, doc: &roxmltree::Document, node: roxmltree::Node, file: &Rc<PathBuf>) -> Result<DMat4> {
        let mut m = DMat4::IDENTITY;
        for op in node.children().filter(roxmltree::Node::is_element) {
            let at = self.at(doc, op, file);
            let step = match op.tag_name().name() {
                "translate" => DMat4::from_translation(self.vector(op, &at, 0.0)?),
                "scale" => DMat4::from_scale(self.vector(op, &at, 1.0)?),
                "rotate" => {
                    let axis = self.vector(op, &at, 0.0)?;
                    let angle = one_number(&self.required(op, "angle", &at)?).map_err(|m| syntax(&at, m))?;
                    let axis = axis.try_normalize().ok_or_else(|| syntax(&at, "<rotate> needs a non-zero axis"))?;
                    DMat4::from_axis_angle(axis, angle.to_radians())
                }
                "matrix" => {
                    let s = self.required(op, "value", &at)?;
                    let v = numbers(&s).map_err(|m| syntax(&at, m))?;
                    match v.len() {
                        16 => DMat4::from_cols_array(&[
                            v[0], v[4], v[8], v[12], v[1], v[5], v[9], v[13], v[2], v[6], v[10], v[14], v[3], v[7],
                            v[11], v[15],
                        ]),
                        9 => DMat4::from_cols(
                            DVec4::new(v[0], v[3], v[6], 0.0),
                            DVec4::new(v[1], v[4], v[7], 0.0),
                            DVec4::new(v[2], v[5], v[8], 0.0),
                            DVec4::W,
                        ),
                        n => return Err(syntax(&at, format!("<matrix> needs 16 (or 9) numbers, got {n}"))),
                    }
                }
                "lookat" => {
                    let point = |name: &str| -> Result<DVec3> {
                        let s = self.required(op, name, &at)?;
                        match numbers(&s).map_err(|m| syntax(&at, m))?[..] {
                            [x, y, z] => Ok(DVec3::new(x, y, z)),
                            _ => Err(syntax(&at, format!("<lookat {name}> needs 3 numbers, got \"{s}\""))),
                        }
                    };
                    let (origin, target) = (point("origin")?, point("target")?);
                    let up = if op.attribute("up").is_some() { point("up")? } else { DVec3::Y };
                    lookat(origin, target, up).ok_or_else(|| {
                        syntax(&at, "<lookat>: origin equals target, or up is parallel to the view direction")
                    })?
                }
                other => {
                    self.unsupported(&at, format!("<{other}> in a <transform> is not supported: ignored"))?;
                    DMat4::IDENTITY
                }
            };
            m = step * m;
        }
        if !m.is_finite() {
            return Err(syntax(&self.at(doc, node, file), "the transform is not finite"));
        }
        Ok(m)
    }
}

/// Mitsuba's `lookat`: camera space's +z towards the target, +y up, +x to the left.
fn lookat(origin: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - origin).try_normalize()?;
    let left = up.cross(dir).try_normalize()?;
    let new_up = dir.cross(left);
    Some(DMat4::from_cols(left.extend(0.0), new_up.extend(0.0), dir.extend(0.0), origin.extend(1.0)))
}

/// Numbers separated by commas and/or white space.
fn numbers(s: &str) -> std::result::Result<Vec<f64>, String> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("\"{t}\" is not a finite number")),
        })
        .collect()
}

fn one_number(s: &str) -> std::result::Result<f64, String> {
    match numbers(s)?[..] {
        [v] => Ok(v),
        _ => Err(format!("\"{s}\" is not one number")),
    }
}

/// A file named in `from`: relative to `from`'s folder, made absolute (the description's
/// paths are otherwise read relative to the main scene file's folder).
/// A file a scene names, found as Mitsuba 3's file resolver finds it: in the main scene
/// file's folder first (for a name written in an included file too), then beside the file
/// that names it. A name found in neither is taken in the main folder (its error names that).
fn resolve(main: &Path, from: &Path, name: &str) -> PathBuf {
    let folder = |p: &Path| p.parent().unwrap_or(Path::new(".")).to_path_buf();
    let candidates = [folder(main).join(name), folder(from).join(name)];
    let path = candidates.iter().find(|p| p.exists()).unwrap_or(&candidates[0]).clone();
    std::path::absolute(&path).unwrap_or(path)
}

/// A `to_uv` transform (read as 3D, applied to `(u, v, 0)`) as the rows of its 2D affine map.
fn uv_rows(m: DMat4) -> [[f32; 3]; 2] {
    let r = |k: usize| [m.col(0)[k] as f32, m.col(1)[k] as f32, m.col(3)[k] as f32];
    [r(0), r(1)]
}

/// Named indices of refraction, as Mitsuba 3 lists them.
fn named_ior(name: &str) -> Option<f32> {
    Some(match name {
        "vacuum" => 1.0,
        "helium" => 1.000_036,
        "hydrogen" => 1.000_132,
        "air" => 1.000_277,
        "carbon dioxide" => 1.000_449,
        "water" => 1.333,
        "acetone" => 1.36,
        "ethanol" => 1.361,
        "carbon tetrachloride" => 1.461,
        "glycerol" => 1.4729,
        "benzene" => 1.501,
        "silicone oil" => 1.520_45,
        "bromine" => 1.661,
        "water ice" => 1.31,
        "fused quartz" => 1.458,
        "pyrex" => 1.47,
        "acrylic glass" => 1.49,
        "polypropylene" => 1.49,
        "bk7" => 1.5046,
        "sodium chloride" => 1.544,
        "amber" => 1.55,
        "pet" => 1.575,
        "diamond" => 2.419,
        _ => return None,
    })
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
}

/// A BSDF as a material, before a shape's emitter is added.
struct MitsubaBsdf {
    material: MaterialDescription,
}

impl Translator<'_, '_> {
    fn fresh(&mut self, prefix: &str) -> String {
        self.count += 1;
        format!("{prefix}{}", self.count)
    }

    fn unsupported(&mut self, at: &At, message: String) -> Result<()> {
        self.reader.unsupported(at, message)
    }

    /// Warns about every parameter of `obj` outside `known`.
    fn check_params(&mut self, obj: &Obj, known: &[&str]) -> Result<()> {
        for (name, _, at) in &obj.params {
            if !known.contains(&name.as_str()) {
                let message =
                    format!("<{} type=\"{}\">: parameter `{name}` is not supported: ignored", obj.tag, obj.plugin);
                self.reader.unsupported(at, message)?;
            }
        }
        Ok(())
    }

    fn resolve_ref<'a>(&'a self, id: &str, at: &At) -> Result<&'a Obj> {
        self.ids.get(id).ok_or_else(|| syntax(at, format!("<ref id=\"{id}\">: no object in the scene has that id")))
    }

    /// The resolution stage between reading and translating, as Mitsuba 3's parser has one:
    /// every object with an `id`, at any depth and in any included file, is known before the
    /// first is translated, so a `<ref>` may come before the object it names. An id given
    /// twice is an error (Mitsuba's too). Also notes which ids are referenced.
    fn register_ids(&mut self, obj: &Obj) -> Result<()> {
        let nested = obj.children.iter().filter_map(|c| match c {
            Child::Obj(o) => Some(o),
            Child::Ref(..) => None,
        });
        let named = obj.params.iter().filter_map(|(_, v, _)| match v {
            Value::Object(o) => Some(&**o),
            _ => None,
        });
        for o in nested.chain(named) {
            if let Some(id) = &o.id {
                if let Some(first) = self.ids.get(id) {
                    let (file, line) = (first.at.file.display(), first.at.line);
                    return Err(syntax(&o.at, format!("id \"{id}\" is given twice (first at {file}, line {line})")));
                }
                self.ids.insert(id.clone(), o.clone());
            }
            self.register_ids(o)?;
        }
        for c in &obj.children {
            if let Child::Ref(id, _) = c {
                self.referenced.insert(id.clone());
            }
        }
        for (_, v, _) in &obj.params {
            if let Value::Ref(id) = v {
                self.referenced.insert(id.clone());
            }
        }
        Ok(())
    }

    fn translate(&mut self, scene: &Obj) -> Result<()> {
        self.check_params(scene, &[])?;
        self.register_ids(scene)?;
        let mut sensor = None;
        for child in &scene.children {
            let obj = match child {
                Child::Obj(o) => o,
                Child::Ref(id, at) => {
                    self.unsupported(at, format!("a top-level <ref id=\"{id}\"> is not an object: ignored"))?;
                    continue;
                }
            };
            match obj.tag.as_str() {
                "shape" => self.shape(obj)?,
                "emitter" => self.emitter(obj)?,
                "sensor" => {
                    if sensor.is_some() {
                        self.unsupported(&obj.at, "a second <sensor>: ignored (the first one renders)".into())?;
                    } else {
                        sensor = Some(obj);
                    }
                }
                "integrator" => self.integrator(obj)?,
                // Defined for `<ref>`s.
                "bsdf" | "texture" => {}
                other => {
                    let message = format!("<{other} type=\"{}\"> is not supported: ignored", obj.plugin);
                    self.unsupported(&obj.at, message)?;
                }
            }
        }
        match sensor {
            Some(s) => self.sensor(s)?,
            None => {
                // Mitsuba's default sensor: at the origin looking along +z, 768×576, a 50 mm
                // lens on 36×24 mm film (its field of view across the diagonal).
                let fov = (36f64.hypot(24.0) / 100.0).atan().to_degrees() * 2.0;
                self.camera(DMat4::IDENTITY, fov, "diagonal", 768, 576, &scene.at)?;
                self.out.camera.filter = Some(MITSUBA_FILTER);
            }
        }
        Ok(())
    }

    fn float(&mut self, obj: &Obj, name: &str, default: f64) -> Result<f64> {
        match obj.param(name) {
            None => Ok(default),
            Some((_, Value::Float(v), _)) => Ok(*v),
            Some((_, Value::Integer(v), _)) => Ok(*v as f64),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be a number"))),
        }
    }

    fn integer(&mut self, obj: &Obj, name: &str, default: i64) -> Result<i64> {
        match obj.param(name) {
            None => Ok(default),
            Some((_, Value::Integer(v), _)) => Ok(*v),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be an <integer>"))),
        }
    }

    fn boolean(&mut self, obj: &Obj, name: &str, default: bool) -> Result<bool> {
        match obj.param(name) {
            None => Ok(default),
            Some((_, Value::Boolean(v), _)) => Ok(*v),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be a <boolean>"))),
        }
    }

    fn text(&mut self, obj: &Obj, name: &str) -> Result<Option<String>> {
        match obj.param(name) {
            None => Ok(None),
            Some((_, Value::Text(v), _)) => Ok(Some(v.clone())),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be a <string>"))),
        }
    }

    fn transform(&mut self, obj: &Obj, name: &str) -> Result<DMat4> {
        match obj.param(name) {
            None => Ok(DMat4::IDENTITY),
            Some((_, Value::Transform(m), _)) => Ok(*m),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be a <transform>"))),
        }
    }

    /// A colour parameter: a constant, or a texture (its name among the scene's textures).
    fn colour(&mut self, obj: &Obj, name: &str, default: [f32; 3]) -> Result<(Option<[f32; 3]>, Option<String>)> {
        let Some((_, value, at)) = obj.param(name).cloned() else {
            return Ok((Some(default), None));
        };
        match value {
            Value::Colour(c) => Ok((Some(c), None)),
            Value::Float(v) => Ok((Some([v as f32; 3]), None)),
            Value::Object(t) if t.tag == "texture" => Ok((None, Some(self.texture(&t)?))),
            Value::Ref(id) => {
                let t = self.resolve_ref(&id, &at)?.clone();
                if t.tag != "texture" {
                    return Err(syntax(&at, format!("`{name}` refers to a <{}>, not a texture", t.tag)));
                }
                Ok((None, Some(self.texture(&t)?)))
            }
            _ => Err(syntax(&at, format!("`{name}` must be a colour or a texture"))),
        }
    }

    /// A colour parameter that may not be a texture (falls back to the texture's mean with
    /// a warning... here to grey 0.5).
    fn constant_colour(&mut self, obj: &Obj, name: &str, default: [f32; 3]) -> Result<[f32; 3]> {
        let (c, t) = self.colour(obj, name, default)?;
        match (c, t) {
            (Some(c), _) => Ok(c),
            (None, _) => {
                let at = obj.param(name).map_or(obj.at.clone(), |p| p.2.clone());
                self.unsupported(
                    &at,
                    format!("`{name}` of <{} type=\"{}\"> cannot be a texture here: 0.5 used", obj.tag, obj.plugin),
                )?;
                Ok([0.5; 3])
            }
        }
    }

    /// A texture: its name in the description.
    fn texture(&mut self, t: &Obj) -> Result<String> {
        let name = self.fresh("texture");
        let description = match t.plugin.as_str() {
            "bitmap" => {
                self.check_params(t, &["filename", "filter_type", "wrap_mode", "raw", "to_uv"])?;
                let file = self.text(t, "filename")?.ok_or_else(|| syntax(&t.at, "a bitmap needs `filename`"))?;
                let path = resolve(&self.reader.files[0], &t.at.file, &file);
                let filter = match self.text(t, "filter_type")?.as_deref() {
                    None | Some("bilinear") => FilterDescription::Bilinear,
                    Some("nearest") => FilterDescription::Nearest,
                    Some(other) => return Err(syntax(&t.at, format!("unknown filter_type \"{other}\""))),
                };
                let wrap = match self.text(t, "wrap_mode")?.as_deref() {
                    None | Some("repeat") => WrapDescription::Repeat,
                    Some("mirror") => WrapDescription::Mirror,
                    Some("clamp") => WrapDescription::Clamp,
                    Some(other) => return Err(syntax(&t.at, format!("unknown wrap_mode \"{other}\""))),
                };
                let to_uv = self.transform(t, "to_uv")?;
                TextureDescription {
                    kind: TextureKind::Bitmap,
                    file: Some(path.to_string_lossy().into_owned()),
                    wrap: Some(wrap),
                    filter: Some(filter),
                    raw: Some(self.boolean(t, "raw", false)?),
                    color0: None,
                    color1: None,
                    scale: None,
                    v_from_top: Some(true),
                    uv_transform: (to_uv != DMat4::IDENTITY).then(|| uv_rows(to_uv)),
                    factor: None,
                    invert: None,
                }
            }
            "checkerboard" => {
                self.check_params(t, &["color0", "color1", "to_uv"])?;
                let c0 = self.constant_colour(t, "color0", [0.4; 3])?;
                let c1 = self.constant_colour(t, "color1", [0.2; 3])?;
                let m = self.transform(t, "to_uv")?;
                // One period of Mitsuba's checkerboard spans [0, 1]: two squares each way,
                // after `to_uv` (a positive scale is folded into the squares' count).
                let (sx, sy) = (m.x_axis.x, m.y_axis.y);
                let pure_scale = m.x_axis.y == 0.0 && m.y_axis.x == 0.0 && m.w_axis.x == 0.0 && m.w_axis.y == 0.0;
                let (scale, map) = if pure_scale && sx > 0.0 && sy > 0.0 {
                    ([(2.0 * sx) as f32, (2.0 * sy) as f32], None)
                } else {
                    ([2.0, 2.0], Some(uv_rows(m)))
                };
                TextureDescription {
                    kind: TextureKind::Checkerboard,
                    file: None,
                    wrap: None,
                    filter: None,
                    raw: None,
                    color0: Some(c0),
                    color1: Some(c1),
                    scale: Some(scale),
                    v_from_top: None,
                    uv_transform: map,
                    factor: None,
                    invert: None,
                }
            }
            other => {
                self.unsupported(&t.at, format!("<texture type=\"{other}\"> is not supported: grey 0.5 used"))?;
                TextureDescription::constant([0.5; 3])
            }
        };
        self.out.textures.insert(name.clone(), description);
        Ok(name)
    }

    /// The texture `name` as Mitsuba 3 reads it for a single value (`eval_1`): a bitmap by its
    /// luminance, as we read any scalar texture, but a checkerboard with its colours swapped
    /// (Mitsuba's `eval_1` puts `color1` where `eval` puts `color0`; checked with Mitsuba 3.9.1
    /// at the four quadrants).
    fn scalar_texture(&mut self, name: String) -> String {
        match self.out.textures.get(&name) {
            Some(t) if t.kind == TextureKind::Checkerboard => {
                let swapped = TextureDescription { color0: t.color1, color1: t.color0, ..t.clone() };
                let key = format!("{name}/scalar");
                self.out.textures.insert(key.clone(), swapped);
                key
            }
            _ => name,
        }
    }

    /// An index of refraction: a number or one of Mitsuba's names.
    fn ior(&mut self, obj: &Obj, name: &str, default: f32) -> Result<f32> {
        match obj.param(name).cloned() {
            None => Ok(default),
            Some((_, Value::Float(v), _)) => Ok(v as f32),
            Some((_, Value::Text(s), at)) => {
                named_ior(&s.to_lowercase()).ok_or_else(|| syntax(&at, format!("`{name}`: unknown material \"{s}\"")))
            }
            Some((_, _, at)) => Err(syntax(&at, format!("`{name}` must be a number or a material name"))),
        }
    }

    /// The microfacets of a rough BSDF into `m`: its distribution (Mitsuba's default
    /// Beckmann), Mitsuba 3's separable masking, and `alpha` (default 0.1; anisotropic
    /// `alpha_u`/`alpha_v` by their mean) or a texture of it (`textured`: whether the BSDF
    /// can take one).
    fn microfacets(&mut self, b: &Obj, m: &mut MaterialDescription, textured: bool) -> Result<()> {
        let distribution = self.text(b, "distribution")?.unwrap_or_else(|| "beckmann".into());
        m.distribution = Some(match distribution.as_str() {
            "ggx" => DistributionDescription::Ggx,
            "beckmann" => DistributionDescription::Beckmann,
            other => {
                self.unsupported(
                    &b.at,
                    format!("<bsdf type=\"{}\">: unknown distribution \"{other}\": beckmann used", b.plugin),
                )?;
                DistributionDescription::Beckmann
            }
        });
        m.masking = Some(MaskingDescription::Separable);
        if b.param("alpha_u").is_some() || b.param("alpha_v").is_some() {
            let u = self.float(b, "alpha_u", 0.1)?;
            let v = self.float(b, "alpha_v", 0.1)?;
            self.unsupported(&b.at, "anisotropic roughness: the mean of alpha_u and alpha_v used".into())?;
            m.roughness = Some(((u + v) / 2.0) as f32);
            return Ok(());
        }
        let texture = match b.param("alpha").cloned() {
            Some((_, Value::Object(t), _)) if t.tag == "texture" => Some(self.texture(&t)?),
            Some((_, Value::Ref(id), at)) => {
                let t = self.resolve_ref(&id, &at)?.clone();
                Some(self.texture(&t)?)
            }
            _ => None,
        };
        let texture = texture.map(|name| self.scalar_texture(name));
        m.roughness = Some(if texture.is_some() { 0.1 } else { self.float(b, "alpha", 0.1)? as f32 });
        if texture.is_some() && !textured {
            self.unsupported(&b.at, "a textured roughness of a plastic is not supported: 0.1 used".into())?;
        } else {
            m.roughness_texture = texture;
        }
        Ok(())
    }

    /// A BSDF object (or a reference to one) as a material.
    fn bsdf(&mut self, b: &Obj, depth: usize) -> Result<MitsubaBsdf> {
        let mut m = MaterialDescription { two_sided: Some(false), ..MaterialDescription::default() };
        let rough = b.plugin.starts_with("rough");
        match b.plugin.as_str() {
            "twosided" => {
                self.check_params(b, &[])?;
                let inner = b.children.first().cloned();
                if b.children.len() > 1 {
                    self.unsupported(&b.at, "a twosided BSDF with two BSDFs: the first one used on both sides".into())?;
                }
                let mut inner = match inner {
                    Some(c) if depth < 4 => self.child_bsdf(&c, depth + 1)?,
                    _ => return Err(syntax(&b.at, "a twosided BSDF needs one nested BSDF")),
                };
                if !matches!(inner.material.kind, MaterialKind::Dielectric | MaterialKind::ThinDielectric) {
                    inner.material.two_sided = Some(true);
                }
                return Ok(inner);
            }
            "bumpmap" | "normalmap" | "mask" => {
                let what = match b.plugin.as_str() {
                    "mask" => "its opacity is ignored (opaque)",
                    _ => "the nested BSDF used without the normal perturbation",
                };
                self.unsupported(&b.at, format!("<bsdf type=\"{}\">: {what}", b.plugin))?;
                let known: &[&str] = match b.plugin.as_str() {
                    "bumpmap" => &["arbitrary", "scale"],
                    "normalmap" => &["normalmap"],
                    _ => &["opacity"],
                };
                for (name, _, at) in &b.params {
                    if !known.contains(&name.as_str()) {
                        let message =
                            format!("<bsdf type=\"{}\">: parameter `{name}` is not supported: ignored", b.plugin);
                        self.reader.unsupported(at, message)?;
                    }
                }
                return match b.children.first() {
                    Some(c) if depth < 4 => self.child_bsdf(c, depth + 1),
                    _ => Err(syntax(&b.at, format!("a {} BSDF needs one nested BSDF", b.plugin))),
                };
            }
            "blendbsdf" => {
                self.check_params(b, &["weight"])?;
                // (1 − w)·first + w·second: the heavier one stands for the blend.
                let weight = match b.param("weight") {
                    Some((_, Value::Float(w), _)) => *w,
                    _ => 0.5,
                };
                self.unsupported(
                    &b.at,
                    format!(
                        "<bsdf type=\"blendbsdf\">: the {} BSDF (weight {weight}) stands for the blend",
                        if weight > 0.5 { "second" } else { "first" }
                    ),
                )?;
                let pick = usize::from(weight > 0.5);
                return match b.children.get(pick) {
                    Some(c) if depth < 4 && b.children.len() == 2 => self.child_bsdf(c, depth + 1),
                    _ => Err(syntax(&b.at, "a blendbsdf needs two nested BSDFs")),
                };
            }
            "principled" => {
                self.check_params(
                    b,
                    &[
                        "base_color",
                        "roughness",
                        "metallic",
                        "specular",
                        "spec_tint",
                        "anisotropic",
                        "sheen",
                        "sheen_tint",
                        "clearcoat",
                        "clearcoat_gloss",
                        "spec_trans",
                        "eta",
                        "sample_visible",
                    ],
                )?;
                let (c, t) = self.colour(b, "base_color", [0.5; 3])?;
                let number = |this: &mut Self, name: &str, default: f64| -> Result<f64> {
                    match b.param(name) {
                        Some((_, Value::Float(_), _)) | None => this.float(b, name, default),
                        Some(_) => Ok(default),
                    }
                };
                let roughness = number(self, "roughness", 0.5)?;
                let metallic = number(self, "metallic", 0.0)?;
                let transmission = number(self, "spec_trans", 0.0)?;
                let alpha = (roughness * roughness).clamp(0.0, 1.0) as f32;
                m.roughness = Some(alpha);
                m.distribution = Some(DistributionDescription::Ggx);
                m.masking = Some(MaskingDescription::Separable);
                let model = if transmission > 0.5 {
                    m.kind = MaterialKind::Dielectric;
                    m.two_sided = None;
                    m.ior = Some(number(self, "eta", 1.5)? as f32);
                    "a rough dielectric"
                } else if metallic > 0.5 {
                    m.kind = MaterialKind::Conductor;
                    m.metal = Some("none".into());
                    m.specular = c;
                    m.specular_texture = t;
                    "a rough mirror tinted by base_color"
                } else {
                    m.kind = MaterialKind::Plastic;
                    m.diffuse = c.unwrap_or([0.0; 3]);
                    m.diffuse_texture = t;
                    m.ior = Some(1.5);
                    "a rough plastic of base_color"
                };
                self.unsupported(
                    &b.at,
                    format!("<bsdf type=\"principled\"> is approximated by {model} (α = roughness²)"),
                )?;
            }
            "diffuse" => {
                self.check_params(b, &["reflectance"])?;
                let (c, t) = self.colour(b, "reflectance", [0.5; 3])?;
                m.diffuse = c.unwrap_or([0.0; 3]);
                m.diffuse_texture = t;
            }
            "conductor" | "roughconductor" => {
                self.check_params(
                    b,
                    &[
                        "material",
                        "eta",
                        "k",
                        "specular_reflectance",
                        "alpha",
                        "alpha_u",
                        "alpha_v",
                        "distribution",
                        "sample_visible",
                    ],
                )?;
                m.kind = MaterialKind::Conductor;
                if b.param("eta").is_some() || b.param("k").is_some() {
                    m.eta = Some(self.constant_colour(b, "eta", [0.0; 3])?);
                    m.k = Some(self.constant_colour(b, "k", [1.0; 3])?);
                } else {
                    let name = self.text(b, "material")?.unwrap_or_else(|| "none".into());
                    if crate::material::metals::lookup(&name).is_none() {
                        self.unsupported(
                            &b.at,
                            format!(
                                "conductor material \"{name}\" is not in our table: a perfect mirror (\"none\") used"
                            ),
                        )?;
                        m.metal = Some("none".into());
                    } else {
                        m.metal = Some(name);
                    }
                }
                let (c, t) = self.colour(b, "specular_reflectance", [1.0; 3])?;
                m.specular = c;
                m.specular_texture = t;
                if rough {
                    self.microfacets(b, &mut m, true)?;
                }
            }
            "dielectric" | "roughdielectric" | "thindielectric" => {
                self.check_params(
                    b,
                    &[
                        "int_ior",
                        "ext_ior",
                        "alpha",
                        "alpha_u",
                        "alpha_v",
                        "distribution",
                        "sample_visible",
                        "specular_reflectance",
                        "specular_transmittance",
                    ],
                )?;
                for key in ["specular_reflectance", "specular_transmittance"] {
                    if b.param(key).is_some() {
                        self.unsupported(&b.at, format!("`{key}` of a dielectric is not supported: 1 used"))?;
                    }
                }
                m.kind =
                    if b.plugin == "thindielectric" { MaterialKind::ThinDielectric } else { MaterialKind::Dielectric };
                m.two_sided = None;
                m.ior = Some(self.ior(b, "int_ior", 1.5046)?);
                m.exterior_ior = Some(self.ior(b, "ext_ior", 1.000_277)?);
                if rough {
                    self.microfacets(b, &mut m, true)?;
                }
            }
            "plastic" | "roughplastic" => {
                self.check_params(
                    b,
                    &[
                        "diffuse_reflectance",
                        "int_ior",
                        "ext_ior",
                        "nonlinear",
                        "alpha",
                        "distribution",
                        "sample_visible",
                        "specular_reflectance",
                    ],
                )?;
                if b.param("specular_reflectance").is_some() {
                    self.unsupported(&b.at, "`specular_reflectance` of a plastic is not supported: 1 used".into())?;
                }
                m.kind = MaterialKind::Plastic;
                let (c, t) = self.colour(b, "diffuse_reflectance", [0.5; 3])?;
                m.diffuse = c.unwrap_or([0.0; 3]);
                m.diffuse_texture = t;
                m.ior = Some(self.ior(b, "int_ior", 1.49)?);
                m.exterior_ior = Some(self.ior(b, "ext_ior", 1.000_277)?);
                m.nonlinear = Some(self.boolean(b, "nonlinear", false)?);
                if rough {
                    self.microfacets(b, &mut m, false)?;
                }
            }
            other => {
                self.unsupported(&b.at, format!("<bsdf type=\"{other}\"> is not supported: grey diffuse (0.5) used"))?;
                m.diffuse = [0.5; 3];
            }
        }
        Ok(MitsubaBsdf { material: m })
    }

    fn child_bsdf(&mut self, c: &Child, depth: usize) -> Result<MitsubaBsdf> {
        match c {
            Child::Obj(o) if o.tag == "bsdf" => self.bsdf(o, depth),
            Child::Obj(o) => Err(syntax(&o.at, format!("<{}> where a BSDF was expected", o.tag))),
            Child::Ref(id, at) => {
                let o = self.resolve_ref(id, at)?.clone();
                if o.tag != "bsdf" {
                    return Err(syntax(at, format!("<ref id=\"{id}\"> names a <{}>, not a BSDF", o.tag)));
                }
                self.bsdf(&o, depth)
            }
        }
    }

    /// A `shapegroup`: its shapes, kept for `instance`s and not rendered themselves.
    fn shapegroup(&mut self, g: &Obj) -> Result<Prototype> {
        self.check_params(g, &[])?;
        if self.in_group {
            return Err(syntax(&g.at, "a shapegroup inside a shapegroup (Mitsuba does not nest instancing)"));
        }
        let mark = Prototype::mark(&self.out);
        self.in_group = true;
        let read = g.children.iter().try_for_each(|child| {
            let o = match child {
                Child::Obj(o) => o.clone(),
                Child::Ref(id, at) => self.resolve_ref(id, at)?.clone(),
            };
            if o.tag == "shape" {
                self.shape(&o)
            } else {
                self.unsupported(&o.at, format!("a <{}> inside a shapegroup is not supported: ignored", o.tag))
            }
        });
        self.in_group = false;
        read?;
        Ok(Prototype::capture(&mut self.out, mark))
    }

    /// An `instance`: its shapegroup's shapes (a `<ref>` to it, or one inside) placed by
    /// `to_world` after their own transforms.
    fn instance(&mut self, s: &Obj) -> Result<()> {
        self.check_params(s, &["to_world"])?;
        if self.in_group {
            return Err(syntax(&s.at, "an instance inside a shapegroup (Mitsuba does not nest instancing)"));
        }
        let to_world = self.transform(s, "to_world")?;
        let group = match s.children.as_slice() {
            [Child::Ref(id, at)] => match self.groups.get(id) {
                Some(g) => g.clone(),
                None => {
                    let what = self.resolve_ref(id, at)?.clone();
                    if what.tag != "shape" || what.plugin != "shapegroup" {
                        return Err(syntax(
                            at,
                            format!("<ref id=\"{id}\"> in an instance names a <{}>, not a shapegroup", what.tag),
                        ));
                    }
                    // A shapegroup defined after its first instance: read it now, once.
                    let group = self.shapegroup(&what)?;
                    self.groups.insert(id.clone(), group.clone());
                    group
                }
            },
            [Child::Obj(g)] if g.tag == "shape" && g.plugin == "shapegroup" => self.shapegroup(g)?,
            _ => return Err(syntax(&s.at, "an instance holds one shapegroup (or a <ref> to one)")),
        };
        group.instantiate(to_world, &mut self.out, &mut self.budget).map_err(|e| syntax(&s.at, e))
    }

    /// A shape: its geometry as a mesh or canonical shape, its material with its emitter.
    fn shape(&mut self, s: &Obj) -> Result<()> {
        match s.plugin.as_str() {
            "shapegroup" => {
                if s.id.as_ref().is_some_and(|id| self.groups.contains_key(id)) {
                    return Ok(()); // read already, for an instance before it
                }
                let group = self.shapegroup(s)?;
                match &s.id {
                    Some(id) => {
                        self.groups.insert(id.clone(), group);
                    }
                    None => {
                        self.unsupported(&s.at, "a shapegroup without an id cannot be instanced: ignored".into())?
                    }
                }
                return Ok(());
            }
            "instance" => return self.instance(s),
            _ => {}
        }
        let mut bsdf = None;
        let mut emission = None;
        for child in &s.children {
            let o = match child {
                Child::Obj(o) => o.clone(),
                Child::Ref(id, at) => self.resolve_ref(id, at)?.clone(),
            };
            match o.tag.as_str() {
                "bsdf" => bsdf = Some(self.bsdf(&o, 0)?),
                "emitter" if o.plugin == "area" && self.in_group => self.unsupported(
                    &o.at,
                    "an area emitter in a shapegroup (Mitsuba 3 does not instance emitters): ignored".into(),
                )?,
                "emitter" if o.plugin == "area" => {
                    self.check_params(&o, &["radiance"])?;
                    emission = Some(self.constant_colour(&o, "radiance", [1.0; 3])?);
                }
                "emitter" => self.unsupported(
                    &o.at,
                    format!("a shape's <emitter type=\"{}\">: only area emitters attach to shapes; ignored", o.plugin),
                )?,
                other => self.unsupported(&o.at, format!("a <{other}> inside a shape is not supported: ignored"))?,
            }
        }
        let mut material = match bsdf {
            Some(b) => b.material,
            // Mitsuba's default BSDF: diffuse 0.5, one-sided; black on an emitter (Mitsuba 3
            // gives an emitting shape without a BSDF a reflectance of 0: measured, its images
            // do not change when the emitter is given a black BSDF).
            None => MaterialDescription {
                diffuse: if emission.is_some() { [0.0; 3] } else { [0.5; 3] },
                two_sided: Some(false),
                ..MaterialDescription::default()
            },
        };
        if let Some(e) = emission {
            material.emission = e;
        }
        let name = self.fresh("material");
        let to_world = self.transform(s, "to_world")?;
        let flip = self.boolean(s, "flip_normals", false)?;
        let matrix = to_rows(to_world);
        match s.plugin.as_str() {
            "obj" | "ply" => {
                self.check_params(s, &["filename", "to_world", "flip_normals", "face_normals", "flip_tex_coords"])?;
                let file = self.text(s, "filename")?.ok_or_else(|| syntax(&s.at, "a mesh shape needs `filename`"))?;
                // Mitsuba gives a mesh without normals smooth ones, unless `face_normals`
                // (which also drops the file's).
                let face_normals = self.boolean(s, "face_normals", false)?;
                // Mitsuba flips an OBJ's `v` by default (its bitmaps start at the top).
                let flip_v = s.plugin == "obj" && self.boolean(s, "flip_tex_coords", true)?;
                let path = resolve(&self.reader.files[0], &s.at.file, &file).to_string_lossy().into_owned();
                let (obj, ply) = if s.plugin == "obj" { (Some(path), None) } else { (None, Some(path)) };
                self.out.meshes.push(MeshDescription {
                    obj,
                    ply,
                    material: Some(name.clone()),
                    reverse_winding: flip,
                    matrix: (to_world != DMat4::IDENTITY).then_some(matrix),
                    smooth_normals: !face_normals,
                    face_normals,
                    flip_v,
                });
            }
            "rectangle" | "cube" | "sphere" | "disk" => {
                let kind = match s.plugin.as_str() {
                    "rectangle" => ShapeKind::Rectangle,
                    "cube" => ShapeKind::Cube,
                    "sphere" => ShapeKind::Sphere,
                    _ => ShapeKind::Disk,
                };
                let (mut center, mut radius) = (None, None);
                if kind == ShapeKind::Sphere {
                    self.check_params(s, &["to_world", "flip_normals", "center", "radius"])?;
                    if let Some((_, v, at)) = s.param("center") {
                        let Value::Vector(c) = v else { return Err(syntax(at, "`center` must be a <point>")) };
                        center = Some(c.as_vec3().to_array());
                    }
                    radius = Some(self.float(s, "radius", 1.0)? as f32);
                } else {
                    self.check_params(s, &["to_world", "flip_normals"])?;
                }
                self.out.shapes.push(ShapeDescription {
                    kind,
                    material: name.clone(),
                    center,
                    radius,
                    segments: None,
                    subdivisions: None,
                    scale: None,
                    rotate: None::<RotateDescription>,
                    translate: None,
                    matrix: Some(matrix),
                    reverse_winding: flip,
                });
            }
            other => {
                self.unsupported(&s.at, format!("<shape type=\"{other}\"> is not supported: skipped"))?;
                return Ok(());
            }
        }
        self.out.materials.insert(name, material);
        Ok(())
    }

    /// An emitter outside a shape: a light or the environment.
    fn emitter(&mut self, e: &Obj) -> Result<()> {
        let to_world = self.transform(e, "to_world")?;
        match e.plugin.as_str() {
            "point" => {
                self.check_params(e, &["intensity", "position", "to_world"])?;
                let intensity = self.constant_colour(e, "intensity", [1.0; 3])?;
                let position = match e.param("position") {
                    Some((_, Value::Vector(p), _)) => *p,
                    Some((_, _, at)) => return Err(syntax(at, "`position` must be a <point>")),
                    None => to_world.transform_point3(DVec3::ZERO),
                };
                self.out.lights.push(LightDescription::point(position.as_vec3().to_array(), intensity));
            }
            "spot" => {
                self.check_params(e, &["intensity", "cutoff_angle", "beam_width", "to_world"])?;
                let intensity = self.constant_colour(e, "intensity", [1.0; 3])?;
                let cutoff = self.float(e, "cutoff_angle", 20.0)? as f32;
                let beam = self.float(e, "beam_width", f64::from(cutoff) * 0.75)? as f32;
                let position = to_world.transform_point3(DVec3::ZERO);
                let direction = to_world.transform_vector3(DVec3::Z);
                self.out.lights.push(LightDescription::spot(
                    position.as_vec3().to_array(),
                    intensity,
                    direction.as_vec3().to_array(),
                    cutoff,
                    beam,
                ));
            }
            "constant" => {
                self.check_params(e, &["radiance"])?;
                let radiance = self.constant_colour(e, "radiance", [1.0; 3])?;
                let env = EnvironmentDescription {
                    radiance: Some(radiance),
                    map: None,
                    scale: None,
                    layout: None,
                    matrix: None,
                    lookup: None,
                };
                self.environment(e, env)?;
            }
            "envmap" => {
                self.check_params(e, &["filename", "scale", "to_world"])?;
                let file = self.text(e, "filename")?.ok_or_else(|| syntax(&e.at, "an envmap needs `filename`"))?;
                let scale = self.float(e, "scale", 1.0)? as f32;
                // Mitsuba's map space is ours (+y up, u = atan2(x, −z)/2π): its rotation
                // carries over.
                let rotation = DMat4::from_cols(to_world.x_axis, to_world.y_axis, to_world.z_axis, DVec4::W);
                let map = resolve(&self.reader.files[0], &e.at.file, &file).to_string_lossy().into_owned();
                let env = EnvironmentDescription {
                    radiance: None,
                    map: Some(map),
                    scale: Some(scale),
                    layout: None,
                    matrix: (rotation != DMat4::IDENTITY).then(|| to_rows(rotation)),
                    // Bilinear, rows from pole to pole, as Mitsuba reads it.
                    lookup: Some(EnvLookupDescription::Mitsuba),
                };
                self.environment(e, env)?;
            }
            "directional" => {
                self.check_params(e, &["irradiance", "direction", "to_world"])?;
                let irradiance = self.constant_colour(e, "irradiance", [1.0; 3])?;
                let direction = match e.param("direction") {
                    Some((_, Value::Vector(d), _)) => *d,
                    Some((_, _, at)) => return Err(syntax(at, "`direction` must be a <vector>")),
                    None => to_world.transform_vector3(DVec3::Z),
                };
                self.out.lights.push(LightDescription::distant(direction.as_vec3().to_array(), irradiance));
            }
            // Defined for the shapes that `<ref>` it.
            "area" if e.id.as_ref().is_some_and(|id| self.referenced.contains(id)) => {}
            "area" => self.unsupported(&e.at, "an area emitter outside a shape lights nothing: ignored".into())?,
            other => self.unsupported(&e.at, format!("<emitter type=\"{other}\"> is not supported: ignored"))?,
        }
        Ok(())
    }

    fn environment(&mut self, e: &Obj, env: EnvironmentDescription) -> Result<()> {
        if self.out.environment.is_some() {
            return self.unsupported(&e.at, "a second environment emitter: ignored (the first one lights)".into());
        }
        self.out.environment = Some(env);
        Ok(())
    }

    fn integrator(&mut self, i: &Obj) -> Result<()> {
        if !matches!(i.plugin.as_str(), "path" | "volpath" | "volpathmis" | "direct" | "prb" | "ptracer") {
            self.unsupported(
                &i.at,
                format!(
                    "<integrator type=\"{}\">: its max_depth alone is read; the integrator is --integrator's",
                    i.plugin
                ),
            )?;
        }
        let depth = match i.plugin.as_str() {
            "direct" => 2,
            _ => self.integer(i, "max_depth", -1)?,
        };
        if depth >= 0 {
            let render = self.out.render.get_or_insert_with(RenderDescription::default);
            render.max_depth = Some(u32::try_from(depth).unwrap_or(u32::MAX));
        }
        Ok(())
    }

    fn sensor(&mut self, s: &Obj) -> Result<()> {
        if !matches!(s.plugin.as_str(), "perspective" | "thinlens") {
            return Err(syntax(&s.at, format!("<sensor type=\"{}\"> is not supported (only perspective)", s.plugin)));
        }
        if s.plugin == "thinlens" {
            self.unsupported(&s.at, "a thinlens sensor renders as a pinhole (no depth of field)".into())?;
        }
        self.check_params(
            s,
            &[
                "fov",
                "fov_axis",
                "to_world",
                "near_clip",
                "far_clip",
                "focal_length",
                "aperture_radius",
                "focus_distance",
            ],
        )?;
        let to_world = self.transform(s, "to_world")?;
        let (mut width, mut height, mut crop) = (768i64, 576i64, None);
        let mut filter = MITSUBA_FILTER;
        for child in &s.children {
            let Child::Obj(o) = child else { continue };
            match o.tag.as_str() {
                "film" => {
                    if o.plugin != "hdrfilm" {
                        self.unsupported(&o.at, format!("<film type=\"{}\">: read as hdrfilm", o.plugin))?;
                    }
                    self.check_params(
                        o,
                        &[
                            "width",
                            "height",
                            "crop_offset_x",
                            "crop_offset_y",
                            "crop_width",
                            "crop_height",
                            "pixel_format",
                            "component_format",
                            "file_format",
                            "rfilter",
                            "banner",
                        ],
                    )?;
                    width = self.integer(o, "width", 768)?;
                    height = self.integer(o, "height", 576)?;
                    if ["crop_offset_x", "crop_offset_y", "crop_width", "crop_height"]
                        .iter()
                        .any(|k| o.param(k).is_some())
                    {
                        let x = self.integer(o, "crop_offset_x", 0)?;
                        let y = self.integer(o, "crop_offset_y", 0)?;
                        let w = self.integer(o, "crop_width", width - x)?;
                        let h = self.integer(o, "crop_height", height - y)?;
                        let window: Vec<u32> =
                            [x, y, w, h].iter().map(|&v| u32::try_from(v).unwrap_or(u32::MAX)).collect();
                        crop = Some([window[0], window[1], window[2], window[3]]);
                    }
                    for c in &o.children {
                        if let Child::Obj(f) = c
                            && f.tag == "rfilter"
                        {
                            filter = self.rfilter(f)?;
                        }
                    }
                }
                "sampler" => {
                    self.check_params(o, &["sample_count", "seed", "jitter"])?;
                    let n = self.integer(o, "sample_count", 4)?;
                    if n < 1 {
                        return Err(syntax(&o.at, format!("sample_count must be at least 1, got {n}")));
                    }
                    let render = self.out.render.get_or_insert_with(RenderDescription::default);
                    render.spp = Some(u32::try_from(n).unwrap_or(u32::MAX));
                }
                other => self.unsupported(&o.at, format!("a <{other}> inside the sensor is not supported: ignored"))?,
            }
        }
        let (fov, axis) = match (s.param("fov"), s.param("focal_length")) {
            (Some(_), Some((_, _, at))) => return Err(syntax(at, "give `fov` or `focal_length`, not both")),
            (Some(_), None) => (self.float(s, "fov", 45.0)?, self.text(s, "fov_axis")?.unwrap_or_else(|| "x".into())),
            (None, focal) => {
                let text = match focal {
                    Some((_, Value::Text(t), _)) => t.clone(),
                    Some((_, _, at)) => return Err(syntax(at, "`focal_length` must be a <string> such as \"50mm\"")),
                    None => "50mm".into(),
                };
                let mm: f64 = text
                    .trim()
                    .trim_end_matches("mm")
                    .parse()
                    .ok()
                    .filter(|f: &f64| f.is_finite() && *f > 0.0)
                    .ok_or_else(|| syntax(&s.at, format!("focal_length \"{text}\" is not a length in mm")))?;
                // A 36×24 mm film: the diagonal's field of view.
                ((36f64.hypot(24.0) / (2.0 * mm)).atan().to_degrees() * 2.0, "diagonal".into())
            }
        };
        if width < 1 || height < 1 || width > i64::from(u32::MAX) || height > i64::from(u32::MAX) {
            return Err(syntax(&s.at, format!("the film must be at least 1×1, got {width}×{height}")));
        }
        self.camera(to_world, fov, &axis, width as u32, height as u32, &s.at)?;
        self.out.camera.crop = crop;
        self.out.camera.filter = Some(filter);
        Ok(())
    }

    /// A film's reconstruction filter: `box`, `gaussian` (`stddev`), `tent` (`radius`);
    /// others fall back to Mitsuba's default Gaussian.
    fn rfilter(&mut self, f: &Obj) -> Result<PixelFilterDescription> {
        Ok(match f.plugin.as_str() {
            "box" => {
                self.check_params(f, &[])?;
                PixelFilterDescription { kind: PixelFilterKind::Box, stddev: None, radius: None }
            }
            "gaussian" => {
                self.check_params(f, &["stddev"])?;
                let stddev = self.float(f, "stddev", 0.5)? as f32;
                PixelFilterDescription { kind: PixelFilterKind::Gaussian, stddev: Some(stddev), radius: None }
            }
            "tent" => {
                self.check_params(f, &["radius"])?;
                let r = self.float(f, "radius", 1.0)? as f32;
                PixelFilterDescription { kind: PixelFilterKind::Tent, stddev: None, radius: Some([r; 2]) }
            }
            other => {
                self.unsupported(&f.at, format!("<rfilter type=\"{other}\">: the default gaussian used"))?;
                MITSUBA_FILTER
            }
        })
    }

    /// The camera of a Mitsuba sensor: its `to_world` (+z forward, +y up, +x to the image's
    /// left) and field of view `fov` degrees along `axis`.
    fn camera(&mut self, to_world: DMat4, fov: f64, axis: &str, width: u32, height: u32, at: &At) -> Result<()> {
        let (w, h) = (f64::from(width), f64::from(height));
        let half = (fov.to_radians() / 2.0).tan();
        let tan_y = match axis {
            "x" => half * h / w,
            "y" => half,
            "diagonal" => half * h / w.hypot(h),
            "smaller" => {
                if w < h {
                    half * h / w
                } else {
                    half
                }
            }
            "larger" => {
                if w > h {
                    half * h / w
                } else {
                    half
                }
            }
            other => return Err(syntax(at, format!("unknown fov_axis \"{other}\""))),
        };
        let fov_y = (2.0 * tan_y.atan()).to_degrees();
        let eye = to_world.transform_point3(DVec3::ZERO);
        let forward = to_world.transform_vector3(DVec3::Z).normalize_or_zero();
        let up = to_world.transform_vector3(DVec3::Y).normalize_or_zero();
        let left = to_world.transform_vector3(DVec3::X);
        // Our camera's right is forward × up; Mitsuba's image right is −x. They disagree
        // when `to_world` mirrors.
        let mirror = forward.cross(up).dot(left) > 0.0;
        self.out.camera = CameraDescription {
            eye: eye.as_vec3().to_array(),
            look_at: (eye + forward).as_vec3().to_array(),
            up: up.as_vec3().to_array(),
            fov_y: fov_y as f32,
            width,
            height,
            crop: None,
            mirror,
            filter: None,
        };
        Ok(())
    }
}

/// Mitsuba 3's default reconstruction filter: a Gaussian of σ 0.5, cut at 2.
const MITSUBA_FILTER: PixelFilterDescription =
    PixelFilterDescription { kind: PixelFilterKind::Gaussian, stddev: Some(0.5), radius: None };

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::description::LightKind;

    fn read(body: &str, defines: &[(&str, &str)], strict: bool) -> Result<Imported> {
        let text = format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n");
        let options = ImportOptions {
            defines: defines.iter().map(|(a, b)| ((*a).to_string(), (*b).to_string())).collect(),
            strict,
        };
        import(Path::new("/nowhere/scene.xml"), &text, &options)
    }

    fn ok(body: &str) -> SceneDescription {
        read(body, &[], true).unwrap().description
    }

    fn message(r: Result<Imported>) -> String {
        match r {
            Err(e) => e.to_string(),
            Ok(_) => panic!("expected an error"),
        }
    }

    const SHAPE: &str = "<shape type=\"rectangle\"/>";

    #[test]
    fn defaults_and_defines_substitute() {
        let body = "<default name=\"r\" value=\"0.25\"/>
            <shape type=\"sphere\"><float name=\"radius\" value=\"$r\"/></shape>
            <shape type=\"sphere\"><float name=\"radius\" value=\"${r}5\"/></shape>";
        let d = ok(body);
        assert_eq!(d.shapes[0].radius, Some(0.25));
        assert_eq!(d.shapes[1].radius, Some(0.255));
        let d = read(body, &[("r", "2")], true).unwrap().description;
        assert_eq!(d.shapes[0].radius, Some(2.0), "-D wins over <default>");
        let e =
            message(read("<shape type=\"sphere\">\n<float name=\"radius\" value=\"$missing\"/></shape>", &[], false));
        assert!(e.contains("line 3") && e.contains("$missing"), "{e}");
    }

    #[test]
    fn transforms_compose_in_order() {
        let d = ok("<shape type=\"rectangle\"><transform name=\"to_world\">
                <scale value=\"2\"/><translate x=\"1\"/><rotate z=\"1\" angle=\"90\"/>
            </transform></shape>");
        // x ↦ 2x, then +1 along x, then a quarter turn about z: (1, 0, 0) ↦ (3, 0, 0) ↦ (0, 3, 0).
        let m = d.shapes[0].matrix.unwrap();
        let p = [1.0f32, 0.0, 0.0, 1.0];
        let q: Vec<f32> = (0..3).map(|r| (0..4).map(|c| m[r][c] * p[c]).sum()).collect();
        assert!((q[0] - 0.0).abs() < 1e-6 && (q[1] - 3.0).abs() < 1e-6 && q[2].abs() < 1e-6, "{q:?}");
        let d = ok("<shape type=\"rectangle\"><transform name=\"to_world\">
                <matrix value=\"1 0 0 5  0 1 0 6  0 0 1 7  0 0 0 1\"/></transform></shape>");
        assert_eq!(d.shapes[0].matrix.unwrap()[1], [0.0, 1.0, 0.0, 6.0]);
    }

    /// Mitsuba's `fov` is across `fov_axis` (x by default); ours is vertical.
    #[test]
    fn field_of_view_axes() {
        let fov_y = |axis: &str, w: u32, h: u32| {
            let d = ok(&format!(
                "{SHAPE}<sensor type=\"perspective\"><float name=\"fov\" value=\"60\"/>
                 <string name=\"fov_axis\" value=\"{axis}\"/>
                 <film type=\"hdrfilm\"><integer name=\"width\" value=\"{w}\"/><integer name=\"height\" value=\"{h}\"/></film>
                 </sensor>"
            ));
            f64::from(d.camera.fov_y)
        };
        let t = 30f64.to_radians().tan();
        let deg = |x: f64| (2.0 * x.atan()).to_degrees();
        assert!((fov_y("x", 400, 200) - deg(t / 2.0)).abs() < 1e-4);
        assert!((fov_y("y", 400, 200) - 60.0).abs() < 1e-4);
        assert!((fov_y("diagonal", 400, 300) - deg(t * 300.0 / 500.0)).abs() < 1e-4);
        assert!((fov_y("smaller", 400, 200) - 60.0).abs() < 1e-4);
        assert!((fov_y("smaller", 200, 400) - deg(t * 2.0)).abs() < 1e-4);
        assert!((fov_y("larger", 400, 200) - deg(t / 2.0)).abs() < 1e-4);
        let d = ok(SHAPE);
        assert_eq!((d.camera.width, d.camera.height), (768, 576), "Mitsuba's default film");
        // The default 50 mm lens: 46.8° across the 43.3 mm diagonal.
        let diagonal = (36f64.hypot(24.0) / 100.0).atan();
        let want = (2.0 * (diagonal.tan() * 576.0 / 768f64.hypot(576.0)).atan()).to_degrees();
        assert!((f64::from(d.camera.fov_y) - want).abs() < 1e-4, "{} vs {want}", d.camera.fov_y);
    }

    /// `lookat` gives our camera as it is; a mirroring `to_world` sets `mirror`; a crop window.
    #[test]
    fn camera_frame_mirror_and_crop() {
        let sensor = |extra: &str| {
            ok(&format!(
                "{SHAPE}<sensor type=\"perspective\"><transform name=\"to_world\">{extra}
                 <lookat origin=\"1, 2, 3\" target=\"1, 2, 0\" up=\"0, 1, 0\"/></transform>
                 <film type=\"hdrfilm\"><integer name=\"crop_offset_x\" value=\"10\"/>
                 <integer name=\"crop_width\" value=\"20\"/></film></sensor>"
            ))
            .camera
        };
        let c = sensor("");
        assert_eq!(c.eye, [1.0, 2.0, 3.0]);
        assert!((c.look_at[2] - 2.0).abs() < 1e-6 && c.up == [0.0, 1.0, 0.0] && !c.mirror);
        assert_eq!(c.crop, Some([10, 0, 20, 576]));
        assert!(sensor("<scale x=\"-1\"/>").mirror);
    }

    /// `to_uv` of a bitmap, and of a checkerboard beyond a scale, becomes `uv_transform`.
    #[test]
    fn texture_coordinate_maps() {
        let d = ok("<shape type=\"rectangle\"><bsdf type=\"diffuse\"><texture type=\"bitmap\" name=\"reflectance\">
                <string name=\"filename\" value=\"t.png\"/>
                <transform name=\"to_uv\"><scale x=\"2\" y=\"3\"/><translate x=\"0.5\"/></transform></texture></bsdf></shape>
            <shape type=\"rectangle\"><bsdf type=\"diffuse\"><texture type=\"checkerboard\" name=\"reflectance\">
                <transform name=\"to_uv\"><rotate z=\"1\" angle=\"90\"/></transform></texture></bsdf></shape>");
        let t: Vec<&TextureDescription> = d.textures.values().collect();
        assert_eq!(t[0].uv_transform, Some([[2.0, 0.0, 0.5], [0.0, 3.0, 0.0]]));
        let r = t[1].uv_transform.unwrap();
        assert!((r[0][1] + 1.0).abs() < 1e-6 && (r[1][0] - 1.0).abs() < 1e-6, "{r:?}");
        assert_eq!(t[1].scale, Some([2.0, 2.0]));
    }

    /// An instance is its shapegroup's shapes placed by its `to_world` after their own: the
    /// same triangles (to f32 rounding) as the shapes written out in place, mirrored
    /// instances included; the group alone renders nothing.
    #[test]
    fn shapegroups_and_instances() {
        let shapes = "<shape type=\"rectangle\"><transform name=\"to_world\"><translate z=\"1\"/></transform></shape>
            <shape type=\"sphere\"><float name=\"radius\" value=\"0.25\"/><bsdf type=\"conductor\"/></shape>";
        let placements = ["<translate x=\"5\"/>", "<rotate y=\"1\" angle=\"30\"/>", "<scale x=\"-1\"/>"];
        let instanced: String = std::iter::once(format!("<shape type=\"shapegroup\" id=\"g\">{shapes}</shape>"))
            .chain(placements.iter().map(|p| {
                format!("<shape type=\"instance\"><ref id=\"g\"/><transform name=\"to_world\">{p}</transform></shape>")
            }))
            .collect();
        let placed = |p: &str| {
            // The same shapes with the placement after their own transform.
            shapes
                .replace("<translate z=\"1\"/></transform>", &format!("<translate z=\"1\"/>{p}</transform>"))
                .replace("<bsdf", &format!("<transform name=\"to_world\">{p}</transform><bsdf"))
        };
        let direct: String = placements.iter().map(|p| placed(p)).collect();
        let triangles = |body: &str| {
            let text = format!("<scene version=\"3.0.0\">{body}</scene>");
            let scene =
                crate::scene::Scene::parse_mitsuba(&text, Path::new("/nowhere/s.xml"), &ImportOptions::default())
                    .unwrap();
            let mut t: Vec<[f32; 9]> =
                scene.triangles.iter().map(|t| t.map(|p| p.to_array()).concat().try_into().unwrap()).collect();
            t.sort_by(|a, b| {
                a.iter().zip(b).map(|(x, y)| x.total_cmp(y)).find(|o| o.is_ne()).unwrap_or(std::cmp::Ordering::Equal)
            });
            (t, scene.materials.len())
        };
        let ((a, _), (b, _)) = (triangles(&instanced), triangles(&direct));
        assert_eq!(a.len(), b.len());
        assert!(a.len() > 3 * (2 + 1000), "{}", a.len());
        for (x, y) in a.iter().zip(&b) {
            assert!(x.iter().zip(y).all(|(p, q)| (p - q).abs() <= 1e-5), "{x:?} vs {y:?}");
        }
        let d = ok(&format!("<shape type=\"shapegroup\" id=\"g\">{shapes}</shape><shape type=\"cube\"/>"));
        assert_eq!(d.shapes.len(), 1, "a group is not rendered by itself");
        for (body, want) in [
            ("<shape type=\"instance\"><ref id=\"nope\"/></shape>", "no object in the scene has that id"),
            ("<bsdf type=\"diffuse\" id=\"b\"/><shape type=\"instance\"><ref id=\"b\"/></shape>", "not a shapegroup"),
            ("<shape type=\"instance\"/>", "holds one shapegroup"),
            ("<shape type=\"shapegroup\" id=\"g\"><shape type=\"shapegroup\"/></shape>", "inside a shapegroup"),
        ] {
            let e = message(read(body, &[], false));
            assert!(e.contains(want), "{body}: {e}");
        }
        let r = read(
            "<shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\"><emitter type=\"area\"/></shape></shape>
             <shape type=\"instance\"><ref id=\"g\"/></shape>",
            &[],
            false,
        )
        .unwrap();
        assert!(r.warnings.iter().any(|w| w.contains("does not instance emitters")), "{:?}", r.warnings);
        assert!(r.description.materials.values().all(|m| m.emission == [0.0; 3]));
    }

    /// BSDFs we approximate: normal maps, bump maps and masks by their nested BSDF, a blend
    /// by its heavier BSDF, principled by a rough plastic, conductor or dielectric; each with
    /// a warning.
    #[test]
    fn wrapped_and_approximated_bsdfs() {
        let material = |bsdf: &str| {
            let r = read(&format!("<shape type=\"cube\">{bsdf}</shape>"), &[], false).unwrap();
            (r.description.materials.values().next().unwrap().clone(), r.warnings)
        };
        let (m, w) = material(
            "<bsdf type=\"normalmap\"><texture name=\"normalmap\" type=\"bitmap\"><string name=\"filename\" value=\"n.png\"/></texture>
             <bsdf type=\"roughplastic\"><rgb name=\"diffuse_reflectance\" value=\"0.1, 0.2, 0.3\"/></bsdf></bsdf>",
        );
        assert_eq!((m.kind, m.diffuse), (MaterialKind::Plastic, [0.1, 0.2, 0.3]));
        assert!(w.len() == 1 && w[0].contains("normal perturbation"), "{w:?}");
        let (m, w) =
            material("<bsdf type=\"mask\"><float name=\"opacity\" value=\"0.5\"/><bsdf type=\"conductor\"/></bsdf>");
        assert!(m.kind == MaterialKind::Conductor && w[0].contains("opacity"), "{w:?}");
        let (m, _) = material(
            "<bsdf type=\"blendbsdf\"><float name=\"weight\" value=\"0.8\"/><bsdf type=\"diffuse\"/><bsdf type=\"dielectric\"/></bsdf>",
        );
        assert_eq!(m.kind, MaterialKind::Dielectric, "the heavier one");
        let (m, w) = material(
            "<bsdf type=\"principled\"><rgb name=\"base_color\" value=\"0.8, 0.1, 0.1\"/><float name=\"roughness\" value=\"0.4\"/></bsdf>",
        );
        assert_eq!(
            (m.kind, m.diffuse, m.roughness.map(|a| (a * 100.0).round())),
            (MaterialKind::Plastic, [0.8, 0.1, 0.1], Some(16.0))
        );
        assert!(w[0].contains("principled"), "{w:?}");
        let (m, _) = material("<bsdf type=\"principled\"><float name=\"metallic\" value=\"1\"/></bsdf>");
        assert_eq!((m.kind, m.metal.as_deref(), m.specular), (MaterialKind::Conductor, Some("none"), Some([0.5; 3])));
        let e = message(read("<shape type=\"cube\"><bsdf type=\"bumpmap\"/></shape>", &[], false));
        assert!(e.contains("needs one nested BSDF"), "{e}");
    }

    /// The film's `rfilter`, Mitsuba's default Gaussian without one.
    #[test]
    fn reconstruction_filters() {
        let filter = |film: &str| {
            let r = read(
                &format!(
                    "<sensor type=\"perspective\"><film type=\"hdrfilm\">{film}</film></sensor><shape type=\"cube\"/>"
                ),
                &[],
                false,
            )
            .unwrap();
            (r.description.camera.filter.unwrap(), r.warnings)
        };
        let gaussian = PixelFilterDescription { kind: PixelFilterKind::Gaussian, stddev: Some(0.5), radius: None };
        assert_eq!(filter("").0, gaussian);
        assert_eq!(ok("<shape type=\"cube\"/>").camera.filter, Some(gaussian), "the default sensor's film");
        assert_eq!(filter("<rfilter type=\"box\"/>").0.kind, PixelFilterKind::Box);
        let (f, _) = filter("<rfilter type=\"gaussian\"><float name=\"stddev\" value=\"0.25\"/></rfilter>");
        assert_eq!(f.stddev, Some(0.25));
        let (f, _) = filter("<rfilter type=\"tent\"><float name=\"radius\" value=\"2\"/></rfilter>");
        assert_eq!((f.kind, f.radius), (PixelFilterKind::Tent, Some([2.0; 2])));
        let (f, warnings) = filter("<rfilter type=\"mitchell\"/>");
        assert!(f == gaussian && warnings[0].contains("mitchell"), "{warnings:?}");
    }

    #[test]
    fn materials_and_their_defaults() {
        let d = ok("<bsdf type=\"roughconductor\" id=\"m\"><string name=\"material\" value=\"Cu\"/>
                <string name=\"distribution\" value=\"ggx\"/></bsdf>
            <shape type=\"cube\"><ref id=\"m\"/></shape>
            <shape type=\"cube\"><bsdf type=\"dielectric\"><string name=\"int_ior\" value=\"water\"/></bsdf></shape>
            <shape type=\"cube\"><bsdf type=\"twosided\"><bsdf type=\"plastic\"/></bsdf></shape>
            <shape type=\"cube\"/>");
        let m: Vec<&MaterialDescription> = d.shapes.iter().map(|s| &d.materials[&s.material]).collect();
        assert_eq!(
            (m[0].kind, m[0].metal.as_deref(), m[0].roughness),
            (MaterialKind::Conductor, Some("Cu"), Some(0.1))
        );
        assert_eq!(
            (m[0].distribution, m[0].masking),
            (Some(DistributionDescription::Ggx), Some(MaskingDescription::Separable))
        );
        let d2 = ok(
            "<shape type=\"cube\"><bsdf type=\"roughdielectric\"><float name=\"alpha\" value=\"0.3\"/></bsdf></shape>",
        );
        let rough = d2.materials.values().next().unwrap();
        assert_eq!(
            (rough.roughness, rough.distribution),
            (Some(0.3), Some(DistributionDescription::Beckmann)),
            "Mitsuba's default"
        );
        assert_eq!(m[0].two_sided, Some(false), "Mitsuba's surfaces are one-sided");
        assert_eq!((m[1].kind, m[1].ior, m[1].exterior_ior), (MaterialKind::Dielectric, Some(1.333), Some(1.000_277)));
        assert_eq!((m[2].kind, m[2].ior, m[2].two_sided), (MaterialKind::Plastic, Some(1.49), Some(true)));
        assert_eq!((m[2].diffuse, m[3].diffuse), ([0.5; 3], [0.5; 3]));
        // A checkerboard read as one value swaps its colours, as Mitsuba's `eval_1` does.
        let d3 = ok("<shape type=\"cube\"><bsdf type=\"roughconductor\"><texture type=\"checkerboard\" name=\"alpha\">
                <rgb name=\"color0\" value=\"0.05\"/><rgb name=\"color1\" value=\"0.5\"/></texture></bsdf></shape>");
        let m = d3.materials.values().next().unwrap();
        let t = &d3.textures[m.roughness_texture.as_ref().unwrap()];
        assert_eq!((t.color0, t.color1), (Some([0.5; 3]), Some([0.05; 3])));
        // An emitter without a BSDF reflects nothing, as in Mitsuba 3.
        let lamp = ok("<shape type=\"rectangle\"><emitter type=\"area\"/></shape>");
        let m = lamp.materials.values().next().unwrap();
        assert_eq!((m.diffuse, m.emission), ([0.0; 3], [1.0; 3]));
        let e = message(read("<shape type=\"cube\"><ref id=\"nope\"/></shape>", &[], false));
        assert!(e.contains("nope") && e.contains("line 2"), "{e}");
    }

    /// Outside the subset: one warning naming element, file and line, and the fallback; an
    /// error with `strict`.
    #[test]
    fn unsupported_warns_or_fails() {
        let body = "<shape type=\"cube\">\n<bsdf type=\"hair\"/></shape>";
        let r = read(body, &[], false).unwrap();
        assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
        assert!(r.warnings[0].starts_with("/nowhere/scene.xml:3:") && r.warnings[0].contains("grey diffuse"));
        let r = read("<shape type=\"cube\"><bsdf type=\"roughplastic\"><string name=\"distribution\" value=\"phong\"/></bsdf></shape>", &[], false).unwrap();
        assert!(r.warnings[0].contains("phong") && r.warnings[0].contains("beckmann used"), "{:?}", r.warnings);
        let e = message(read(body, &[], true));
        assert!(e.contains("line 3") && e.contains("hair") && e.contains("--strict"), "{e}");
        let r = read("<shape type=\"serialized\"/><emitter type=\"projector\"/>", &[], false).unwrap();
        assert_eq!(r.warnings.len(), 2);
    }

    #[test]
    fn malformed_files_are_one_error() {
        for (body, want) in [
            ("<shape type=\"cube\">", "line"),
            ("<float name=\"x\" value=\"1e999\"/>", "not finite"),
            ("<rgb name=\"x\" value=\"1, 2\"/>", "1 or 3 numbers"),
            ("<shape type=\"cube\"><transform name=\"to_world\"><rotate angle=\"3\"/></transform></shape>", "axis"),
            ("<shape type=\"cube\"><transform name=\"to_world\"><matrix value=\"1 2 3\"/></transform></shape>", "16"),
            ("<boolean name=\"b\" value=\"yes\"/>", "true nor false"),
            ("<sensor type=\"orthographic\"/>", "perspective"),
        ] {
            let e = message(read(body, &[], false));
            assert!(e.contains(want), "{body}: {e}");
        }
        let deep = "<bsdf type=\"diffuse\">".repeat(100) + &"</bsdf>".repeat(100);
        assert!(message(read(&deep, &[], false)).contains("nest"));
    }

    #[test]
    fn references_resolve_after_the_whole_scene_is_read() {
        // Mitsuba's own cbox-rgb.xml: shapes in one include name BSDFs of another and an area
        // emitter defined after both.
        let dir = std::env::temp_dir().join(format!("zvidpt-mitsuba-forward-{}", std::process::id()));
        // Files named in an included file are found from the main file's folder, as
        // Mitsuba's file resolver finds them (cbox's fragments/shapes.xml names meshes/…).
        std::fs::create_dir_all(dir.join("fragments")).unwrap();
        std::fs::create_dir_all(dir.join("meshes")).unwrap();
        std::fs::write(dir.join("meshes/tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let scene = |body: &str| format!("<scene version=\"3.0.0\">{body}</scene>");
        let mesh = "<string name=\"filename\" value=\"meshes/tri.obj\"/>";
        let shapes = format!("<shape type=\"obj\">{mesh}<ref id=\"white\"/><ref id=\"area-emitter\"/></shape>");
        std::fs::write(dir.join("fragments/shapes.xml"), scene(&shapes)).unwrap();
        let white = "<bsdf type=\"diffuse\" id=\"white\"><rgb name=\"reflectance\" value=\"0.2, 0.4, 0.6\"/></bsdf>";
        std::fs::write(dir.join("fragments/bsdfs.xml"), scene(white)).unwrap();
        let main = scene(
            "<include filename=\"fragments/shapes.xml\"/><include filename=\"fragments/bsdfs.xml\"/>\
             <emitter type=\"area\" id=\"area-emitter\"><rgb name=\"radiance\" value=\"3, 2, 1\"/></emitter>",
        );
        let r = import(&dir.join("main.xml"), &main, &ImportOptions { defines: Vec::new(), strict: true }).unwrap();
        let d = r.description;
        assert_eq!(d.meshes.len(), 1);
        assert_eq!(d.meshes[0].obj.as_deref().map(Path::new), Some(dir.join("meshes/tri.obj").as_path()));
        let m = &d.materials[d.meshes[0].material.as_ref().unwrap()];
        assert_eq!(m.diffuse, [0.2, 0.4, 0.6]);
        assert_eq!(m.emission, [3.0, 2.0, 1.0]);
        // An instance before its shapegroup; a nested object's id; an id given twice.
        let d = ok("<shape type=\"instance\"><ref id=\"g\"/></shape>\
             <shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\"><bsdf type=\"conductor\" id=\"metal\"/></shape></shape>\
             <shape type=\"cube\"><ref id=\"metal\"/></shape>");
        assert_eq!(d.shapes.len(), 2, "the instance's sphere and the cube; the group itself is not rendered");
        let e = message(read("<bsdf type=\"diffuse\" id=\"a\"/><bsdf type=\"conductor\" id=\"a\"/>", &[], false));
        assert!(e.contains("given twice") && e.contains("line"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn includes_and_their_cycles() {
        let dir = std::env::temp_dir().join(format!("zvidpt-mitsuba-include-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(dir.join("sub/part.xml"), "<scene version=\"3.0.0\"><shape type=\"sphere\"/></scene>").unwrap();
        std::fs::write(dir.join("loop.xml"), "<scene version=\"3.0.0\"><include filename=\"loop.xml\"/></scene>")
            .unwrap();
        let main = dir.join("main.xml");
        let text = "<scene version=\"3.0.0\"><include filename=\"sub/part.xml\"/></scene>";
        let r = import(&main, text, &ImportOptions::default()).unwrap();
        assert_eq!(r.description.shapes.len(), 1);
        assert!(r.sources.contains(&dir.join("sub/part.xml")));
        let text = "<scene version=\"3.0.0\"><include filename=\"loop.xml\"/></scene>";
        let e = message(import(&main, text, &ImportOptions::default()));
        assert!(e.contains("deeper"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn emitters_and_render_settings() {
        let d = ok("<shape type=\"rectangle\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"3\"/></emitter></shape>
            <emitter type=\"point\"><point name=\"position\" value=\"1, 2, 3\"/><rgb name=\"intensity\" value=\"5\"/></emitter>
            <emitter type=\"spot\"><transform name=\"to_world\"><lookat origin=\"0, 4, 0\" target=\"0, 0, 0\" up=\"0, 0, 1\"/></transform>
                <float name=\"cutoff_angle\" value=\"30\"/></emitter>
            <emitter type=\"constant\"><spectrum name=\"radiance\" value=\"0.5\"/></emitter>
            <emitter type=\"directional\"><vector name=\"direction\" value=\"0, -2, 0\"/><rgb name=\"irradiance\" value=\"2\"/></emitter>
            <integrator type=\"path\"><integer name=\"max_depth\" value=\"4\"/></integrator>
            <sensor type=\"perspective\"><sampler type=\"independent\"><integer name=\"sample_count\" value=\"9\"/></sampler></sensor>");
        assert_eq!(d.materials[&d.shapes[0].material].emission, [3.0; 3]);
        assert_eq!((d.lights[0].position, d.lights[0].intensity), (Some([1.0, 2.0, 3.0]), Some([5.0; 3])));
        let spot = &d.lights[1];
        assert_eq!(
            (spot.kind, spot.position, spot.cutoff, spot.beam),
            (LightKind::Spot, Some([0.0, 4.0, 0.0]), Some(30.0), Some(22.5))
        );
        assert!((spot.direction.unwrap()[1] + 1.0).abs() < 1e-6);
        assert_eq!(d.environment.as_ref().unwrap().radiance, Some([0.5; 3]));
        let sun = &d.lights[2];
        assert_eq!(
            (sun.kind, sun.direction, sun.irradiance),
            (LightKind::Distant, Some([0.0, -2.0, 0.0]), Some([2.0; 3]))
        );
        let r = d.render.unwrap();
        assert_eq!((r.spp, r.max_depth), (Some(9), Some(4)));
    }
}
