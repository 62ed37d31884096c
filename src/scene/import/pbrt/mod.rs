//! pbrt-v4 scenes, read into the same description a TOML scene file gives.
//!
//! A tokenizer of our own (the `pbrt4` crate panics on `Import` and does not load PLY), then
//! the directives in order with pbrt's graphics state: the current transform (with named
//! coordinate systems), `AttributeBegin`/`End`, `ReverseOrientation`, the current material
//! (named or not) and area light. Each shape gets the material it was declared with (made
//! emitting by the area light in force). Files named in the scene are relative to the main
//! scene file's folder, as in pbrt.
//!
//! Outside the subset: one warning naming the directive, its file and line, and the fallback
//! (`strict`: an error).
use super::super::description::{
    CameraDescription, EnvironmentDescription, FilterDescription, InlineMesh, LightDescription, MapLayout,
    MaterialDescription, MaterialKind, MeshDescription, PixelFilterDescription, PixelFilterKind, RenderDescription,
    SceneDescription, ShapeDescription, ShapeKind, TextureDescription, TextureKind, WrapDescription,
};
use super::{
    At, ImportOptions, Imported, MAX_INSTANCED_TRIANGLES, Mark, Prototype, empty_description, syntax, to_rows,
    unsupported,
};
use crate::error::Result;
use glam::{DMat4, DVec3, DVec4};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// Largest included file read (text), as for a scene file.
const MAX_FILE_BYTES: u64 = 16 << 20;
/// Deepest nesting of `Include`s (a cycle stops here), and most files read in all.
const MAX_INCLUDE_DEPTH: usize = 16;
const MAX_INCLUDES: usize = 1024;
/// Deepest `AttributeBegin` nesting.
const MAX_ATTRIBUTE_DEPTH: usize = 4096;
/// Most values in one parameter (a mesh's vertices, say), against hostile files: 2^28.
const MAX_VALUES: usize = 1 << 28;

#[derive(Clone, Debug, PartialEq)]
enum Token {
    /// A directive or a bare word (`true`, `false`).
    Word(String),
    Text(String),
    Number(f64),
    Open,
    Close,
}

/// The tokens of a file, each with its line.
fn tokenize(text: &str, file: &Rc<PathBuf>) -> Result<Vec<(Token, u32)>> {
    let bytes = text.as_bytes();
    let mut tokens = Vec::new();
    let (mut i, mut line) = (0usize, 1u32);
    while i < bytes.len() {
        let c = bytes[i];
        let at = || At { file: file.clone(), line };
        match c {
            b'\n' => {
                line += 1;
                i += 1;
            }
            _ if c.is_ascii_whitespace() => i += 1,
            b'#' => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'[' => {
                tokens.push((Token::Open, line));
                i += 1;
            }
            b']' => {
                tokens.push((Token::Close, line));
                i += 1;
            }
            b'"' => {
                let start_line = line;
                let mut s = String::new();
                i += 1;
                loop {
                    let Some(&b) = bytes.get(i) else {
                        return Err(syntax(&At { file: file.clone(), line: start_line }, "unterminated string"));
                    };
                    match b {
                        b'"' => break,
                        b'\n' => return Err(syntax(&at(), "a string runs past the end of its line")),
                        b'\\' => {
                            i += 1;
                            match bytes.get(i) {
                                Some(b'n') => s.push('\n'),
                                Some(b't') => s.push('\t'),
                                Some(&e) if e.is_ascii() => s.push(e as char),
                                _ => return Err(syntax(&at(), "a bad escape in a string")),
                            }
                            i += 1;
                        }
                        _ => {
                            // Whole UTF-8 characters (the text is valid UTF-8).
                            let len = text[i..].chars().next().map_or(1, char::len_utf8);
                            s.push_str(&text[i..i + len]);
                            i += len;
                        }
                    }
                }
                i += 1;
                tokens.push((Token::Text(s), start_line));
            }
            _ => {
                let start = i;
                while i < bytes.len() && !bytes[i].is_ascii_whitespace() && !b"[]\"#".contains(&bytes[i]) {
                    i += 1;
                }
                let word = &text[start..i];
                let first = word.as_bytes()[0];
                if first.is_ascii_digit() || b"+-.".contains(&first) {
                    let v: f64 = word.parse().map_err(|_| syntax(&at(), format!("\"{word}\" is not a number")))?;
                    if !v.is_finite() {
                        return Err(syntax(&at(), format!("{word} is not finite")));
                    }
                    tokens.push((Token::Number(v), line));
                } else {
                    tokens.push((Token::Word(word.to_string()), line));
                }
            }
        }
    }
    Ok(tokens)
}

/// A parameter's values.
#[derive(Clone, Debug)]
enum Values {
    Numbers(Vec<f64>),
    Texts(Vec<String>),
    Bools(Vec<bool>),
}

/// A parameter: `"type name" value(s)`.
#[derive(Clone, Debug)]
struct Param {
    kind: String,
    name: String,
    values: Values,
    used: std::cell::Cell<bool>,
}

/// A directive's parameter list.
#[derive(Clone, Debug, Default)]
struct Params {
    list: Vec<Param>,
}

impl Params {
    fn get(&self, name: &str) -> Option<&Param> {
        let p = self.list.iter().rev().find(|p| p.name == name)?;
        p.used.set(true);
        Some(p)
    }

    fn numbers(&self, name: &str, at: &At) -> Result<Option<&[f64]>> {
        match self.get(name) {
            None => Ok(None),
            Some(Param { values: Values::Numbers(v), .. }) => Ok(Some(v)),
            Some(p) => Err(syntax(at, format!("\"{} {}\" must hold numbers", p.kind, p.name))),
        }
    }

    fn float(&self, name: &str, default: f64, at: &At) -> Result<f64> {
        match self.numbers(name, at)? {
            None => Ok(default),
            Some([v]) => Ok(*v),
            Some(_) => Err(syntax(at, format!("\"{name}\" must be one number"))),
        }
    }

    fn integer(&self, name: &str, default: i64, at: &At) -> Result<i64> {
        let v = self.float(name, default as f64, at)?;
        if v.fract() != 0.0 || v.abs() > 1e15 {
            return Err(syntax(at, format!("\"{name}\" must be an integer, got {v}")));
        }
        Ok(v as i64)
    }

    fn text(&self, name: &str, at: &At) -> Result<Option<String>> {
        match self.get(name) {
            None => Ok(None),
            Some(Param { values: Values::Texts(v), .. }) if v.len() == 1 => Ok(Some(v[0].clone())),
            Some(p) => Err(syntax(at, format!("\"{} {}\" must be one string", p.kind, p.name))),
        }
    }

    fn boolean(&self, name: &str, default: bool, at: &At) -> Result<bool> {
        match self.get(name) {
            None => Ok(default),
            Some(Param { values: Values::Bools(v), .. }) if v.len() == 1 => Ok(v[0]),
            Some(p) => Err(syntax(at, format!("\"{} {}\" must be one bool", p.kind, p.name))),
        }
    }

    fn point(&self, name: &str, default: DVec3, at: &At) -> Result<DVec3> {
        match self.numbers(name, at)? {
            None => Ok(default),
            Some([x, y, z]) => Ok(DVec3::new(*x, *y, *z)),
            Some(_) => Err(syntax(at, format!("\"{name}\" must be 3 numbers"))),
        }
    }

    fn unused(&self) -> Vec<String> {
        self.list.iter().filter(|p| !p.used.get()).map(|p| format!("\"{} {}\"", p.kind, p.name)).collect()
    }
}

/// A colour-valued parameter: a constant, or a texture's name.
enum Colour {
    Constant([f32; 3]),
    Texture(String),
}

#[derive(Clone, Debug)]
struct AreaLight {
    radiance: [f32; 3],
    two_sided: bool,
}

/// pbrt's graphics state.
#[derive(Clone, Debug)]
struct State {
    ctm: DMat4,
    reverse: bool,
    /// The current material's name among the description's materials.
    material: String,
    area_light: Option<AreaLight>,
}

struct Parser<'o> {
    options: &'o ImportOptions,
    /// The main scene file's folder: every file is relative to it.
    folder: PathBuf,
    warnings: Vec<String>,
    files: Vec<PathBuf>,
    include_depth: usize,
    state: State,
    stack: Vec<State>,
    named_frames: HashMap<String, DMat4>,
    /// Named materials' names in the description (`MakeNamedMaterial` → `named:NAME`).
    named_materials: HashMap<String, String>,
    /// Textures by name: float and spectrum textures share pbrt's namespace per class.
    textures: HashMap<(bool, String), String>,
    out: SceneDescription,
    count: usize,
    /// (material, area light) → the emitting material made for them.
    emitting: HashMap<String, String>,
    camera_seen: bool,
    film: (i64, i64, Option<[f64; 4]>),
    camera: Option<(DMat4, f64, At)>,
    /// Objects (`ObjectBegin`) by name, and the one being defined with where it began.
    objects: HashMap<String, Prototype>,
    defining: Option<(String, Mark, At)>,
    /// `ObjectInstance`s: the object's name and the transform then.
    instances: Vec<(String, DMat4, At)>,
    /// The pixel filter (pbrt-v4's default: a Gaussian of σ 0.5, radius 1.5).
    filter: PixelFilterDescription,
    /// Curves tessellated so far, one mesh per material (a hair file holds thousands of
    /// one-curve directives), with where the first was written; and whether flat curves
    /// were warned about.
    curves: Vec<(String, crate::scene::mesh::curves::CurveMesh, String)>,
    warned_flat_curves: bool,
}

/// Reads the pbrt-v4 scene at `path` (text `text`).
pub(crate) fn import(path: &Path, text: &str, options: &ImportOptions) -> Result<Imported> {
    let folder = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let folder = std::path::absolute(&folder).unwrap_or(folder);
    let mut out = empty_description();
    // pbrt's default material: diffuse, reflectance 0.5.
    out.materials.insert("default".into(), MaterialDescription { diffuse: [0.5; 3], ..MaterialDescription::default() });
    let mut p = Parser {
        options,
        folder,
        warnings: Vec::new(),
        files: vec![path.to_path_buf()],
        include_depth: 0,
        state: State { ctm: DMat4::IDENTITY, reverse: false, material: "default".into(), area_light: None },
        stack: Vec::new(),
        named_frames: HashMap::new(),
        named_materials: HashMap::new(),
        textures: HashMap::new(),
        out,
        count: 0,
        emitting: HashMap::new(),
        camera_seen: false,
        film: (1280, 720, None),
        camera: None,
        objects: HashMap::new(),
        defining: None,
        instances: Vec::new(),
        filter: PixelFilterDescription { kind: PixelFilterKind::Gaussian, stddev: Some(0.5), radius: Some([1.5; 2]) },
        curves: Vec::new(),
        warned_flat_curves: false,
    };
    p.file(path, text)?;
    p.finish()?;
    Ok(Imported { description: p.out, warnings: p.warnings, sources: p.files })
}

/// Tessellated curves as an inline mesh of `material`.
fn curve_mesh(mesh: crate::scene::mesh::curves::CurveMesh, material: String, origin: String) -> InlineMesh {
    InlineMesh {
        origin,
        positions: mesh.positions,
        indices: mesh.indices,
        normals: Some(mesh.normals),
        uvs: None,
        material,
        reverse_winding: false,
    }
}

/// A cursor over one file's tokens.
struct Cursor<'t> {
    tokens: &'t [(Token, u32)],
    i: usize,
    file: Rc<PathBuf>,
}

impl Cursor<'_> {
    fn at(&self) -> At {
        let line = self.tokens.get(self.i.min(self.tokens.len().saturating_sub(1))).map_or(1, |t| t.1);
        At { file: self.file.clone(), line }
    }

    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.i).map(|t| &t.0)
    }

    fn next(&mut self) -> Option<Token> {
        let t = self.tokens.get(self.i).map(|t| t.0.clone());
        self.i += 1;
        t
    }

    fn number(&mut self, what: &str) -> Result<f64> {
        let at = self.at();
        match self.next() {
            Some(Token::Number(v)) => Ok(v),
            other => Err(syntax(&at, format!("{what}: expected a number, found {}", describe(other.as_ref())))),
        }
    }

    fn numbers(&mut self, n: usize, what: &str) -> Result<Vec<f64>> {
        (0..n).map(|_| self.number(what)).collect()
    }

    /// `n` numbers, bare or in brackets.
    fn bracketed_numbers(&mut self, n: usize, what: &str) -> Result<Vec<f64>> {
        if self.peek() == Some(&Token::Open) {
            self.next();
            let v = self.numbers(n, what)?;
            let at = self.at();
            return match self.next() {
                Some(Token::Close) => Ok(v),
                other => Err(syntax(&at, format!("{what}: expected ], found {}", describe(other.as_ref())))),
            };
        }
        self.numbers(n, what)
    }

    fn text(&mut self, what: &str) -> Result<String> {
        let at = self.at();
        match self.next() {
            Some(Token::Text(s)) => Ok(s),
            other => Err(syntax(&at, format!("{what}: expected a quoted string, found {}", describe(other.as_ref())))),
        }
    }

    /// A parameter list: `"type name" value` pairs up to the next directive.
    fn params(&mut self) -> Result<Params> {
        let mut list = Vec::new();
        while let Some(Token::Text(_)) = self.peek() {
            let at = self.at();
            let Some(Token::Text(decl)) = self.next() else { unreachable!() };
            let mut words = decl.split_whitespace();
            let (Some(kind), Some(name), None) = (words.next(), words.next(), words.next()) else {
                return Err(syntax(&at, format!("\"{decl}\" is not a parameter declaration (\"type name\")")));
            };
            let mut items = Vec::new();
            match self.next() {
                Some(Token::Open) => loop {
                    match self.next() {
                        Some(Token::Close) => break,
                        Some(t @ (Token::Number(_) | Token::Text(_) | Token::Word(_))) => {
                            if items.len() >= MAX_VALUES {
                                return Err(syntax(&at, format!("\"{name}\" holds more than {MAX_VALUES} values")));
                            }
                            items.push(t);
                        }
                        other => {
                            return Err(syntax(
                                &at,
                                format!("\"{name}\": expected a value or ], found {}", describe(other.as_ref())),
                            ));
                        }
                    }
                },
                Some(t @ (Token::Number(_) | Token::Text(_) | Token::Word(_))) => items.push(t),
                other => {
                    return Err(syntax(
                        &at,
                        format!("\"{name}\": expected a value, found {}", describe(other.as_ref())),
                    ));
                }
            }
            let values = match kind {
                "bool" => Values::Bools(
                    items
                        .iter()
                        .map(|t| match t {
                            Token::Word(w) | Token::Text(w) if w == "true" => Ok(true),
                            Token::Word(w) | Token::Text(w) if w == "false" => Ok(false),
                            _ => Err(syntax(&at, format!("\"{name}\": a bool is true or false"))),
                        })
                        .collect::<Result<_>>()?,
                ),
                "string" | "texture" => Values::Texts(
                    items
                        .iter()
                        .map(|t| match t {
                            Token::Text(s) => Ok(s.clone()),
                            _ => Err(syntax(&at, format!("\"{name}\": expected quoted strings"))),
                        })
                        .collect::<Result<_>>()?,
                ),
                "spectrum" if matches!(items.first(), Some(Token::Text(_))) => Values::Texts(
                    items
                        .iter()
                        .map(|t| match t {
                            Token::Text(s) => Ok(s.clone()),
                            _ => Err(syntax(&at, format!("\"{name}\": a named spectrum is one string"))),
                        })
                        .collect::<Result<_>>()?,
                ),
                "float" | "integer" | "point" | "point2" | "point3" | "vector" | "vector2" | "vector3" | "normal"
                | "normal3" | "rgb" | "spectrum" | "blackbody" => Values::Numbers(
                    items
                        .iter()
                        .map(|t| match t {
                            Token::Number(v) => Ok(*v),
                            _ => Err(syntax(&at, format!("\"{name}\": expected numbers"))),
                        })
                        .collect::<Result<_>>()?,
                ),
                other => return Err(syntax(&at, format!("\"{other} {name}\": unknown parameter type \"{other}\""))),
            };
            let kind = match kind {
                "point" => "point3",
                "vector" => "vector3",
                "normal" => "normal3",
                k => k,
            };
            list.push(Param { kind: kind.to_string(), name: name.to_string(), values, used: false.into() });
        }
        Ok(Params { list })
    }
}

fn describe(t: Option<&Token>) -> String {
    match t {
        None => "the end of the file".into(),
        Some(Token::Word(w)) => w.clone(),
        Some(Token::Text(s)) => format!("\"{s}\""),
        Some(Token::Number(v)) => v.to_string(),
        Some(Token::Open) => "[".into(),
        Some(Token::Close) => "]".into(),
    }
}

/// pbrt's `LookAt`: camera space's +z towards the target, +y up, +x to `up × dir` (pbrt's
/// image right).
fn look_at(eye: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - eye).try_normalize()?;
    let right = up.try_normalize()?.cross(dir).try_normalize()?;
    let new_up = dir.cross(right);
    // World from camera; the CTM is camera from world.
    Some(DMat4::from_cols(right.extend(0.0), new_up.extend(0.0), dir.extend(0.0), eye.extend(1.0)).inverse())
}

/// Named spectra of pbrt-v4's glasses, as indices of refraction (their value near 550 nm).
fn glass_ior(name: &str) -> Option<f32> {
    Some(match name {
        "glass-BK7" => 1.5168,
        "glass-BAF10" => 1.6700,
        "glass-FK51A" => 1.4866,
        "glass-LASF9" => 1.8503,
        "glass-F5" | "glass-SF5" => 1.6034,
        "glass-F10" | "glass-SF10" => 1.7283,
        "glass-F11" | "glass-SF11" => 1.7847,
        "fused silica" | "glass-FusedSilica" => 1.4585,
        _ => return None,
    })
}

impl Parser<'_> {
    fn unsupported(&mut self, at: &At, message: String) -> Result<()> {
        unsupported(self.options.strict, &mut self.warnings, at, message)
    }

    fn check_unused(&mut self, what: &str, params: &Params, at: &At) -> Result<()> {
        let unused = params.unused();
        if unused.is_empty() {
            return Ok(());
        }
        self.unsupported(at, format!("{what}: {} not supported: ignored", unused.join(", ")))
    }

    fn fresh(&mut self, prefix: &str) -> String {
        self.count += 1;
        format!("{prefix}{}", self.count)
    }

    fn resolve(&self, name: &str) -> PathBuf {
        self.folder.join(name)
    }

    fn file(&mut self, path: &Path, text: &str) -> Result<()> {
        let file = Rc::new(path.to_path_buf());
        let tokens = tokenize(text, &file)?;
        let mut c = Cursor { tokens: &tokens, i: 0, file };
        while let Some(t) = c.next() {
            let at = At { file: c.file.clone(), line: c.tokens[c.i - 1].1 };
            let Token::Word(directive) = t else {
                return Err(syntax(&at, format!("expected a directive, found {}", describe(Some(&t)))));
            };
            self.directive(&directive, &mut c, &at)?;
        }
        Ok(())
    }

    fn concat(&mut self, m: DMat4, at: &At) -> Result<()> {
        let ctm = self.state.ctm * m;
        if !ctm.is_finite() {
            return Err(syntax(at, "the transform is not finite"));
        }
        self.state.ctm = ctm;
        Ok(())
    }

    fn directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<()> {
        match d {
            "Identity" => self.state.ctm = DMat4::IDENTITY,
            "Translate" => {
                let v = c.numbers(3, d)?;
                self.concat(DMat4::from_translation(DVec3::new(v[0], v[1], v[2])), at)?;
            }
            "Scale" => {
                let v = c.numbers(3, d)?;
                self.concat(DMat4::from_scale(DVec3::new(v[0], v[1], v[2])), at)?;
            }
            "Rotate" => {
                let v = c.numbers(4, d)?;
                let axis = DVec3::new(v[1], v[2], v[3])
                    .try_normalize()
                    .ok_or_else(|| syntax(at, "Rotate needs a non-zero axis"))?;
                self.concat(DMat4::from_axis_angle(axis, v[0].to_radians()), at)?;
            }
            "LookAt" => {
                let v = c.numbers(9, d)?;
                let m =
                    look_at(DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]), DVec3::new(v[6], v[7], v[8]))
                        .ok_or_else(|| syntax(at, "LookAt: the eye is on the target, or up is parallel to the view"))?;
                self.concat(m, at)?;
            }
            "Transform" | "ConcatTransform" => {
                let v = c.bracketed_numbers(16, d)?;
                // pbrt's 16 numbers are the matrix's columns.
                let m = DMat4::from_cols_array(&v.try_into().expect("16 numbers"));
                if d == "Transform" {
                    self.state.ctm = DMat4::IDENTITY;
                }
                self.concat(m, at)?;
            }
            "CoordinateSystem" => {
                let name = c.text(d)?;
                self.named_frames.insert(name, self.state.ctm);
            }
            "CoordSysTransform" => {
                let name = c.text(d)?;
                match self.named_frames.get(&name) {
                    Some(m) => self.state.ctm = *m,
                    None => self
                        .unsupported(at, format!("CoordSysTransform \"{name}\": no such coordinate system: ignored"))?,
                }
            }
            "ReverseOrientation" => self.state.reverse = !self.state.reverse,
            "AttributeBegin" | "TransformBegin" => {
                if self.stack.len() >= MAX_ATTRIBUTE_DEPTH {
                    return Err(syntax(at, format!("{d} nests deeper than {MAX_ATTRIBUTE_DEPTH}")));
                }
                self.stack.push(self.state.clone());
            }
            "AttributeEnd" | "TransformEnd" => {
                let saved = self.stack.pop().ok_or_else(|| syntax(at, format!("{d} without a matching begin")))?;
                if d == "TransformEnd" {
                    self.state.ctm = saved.ctm;
                } else {
                    self.state = saved;
                }
            }
            "WorldBegin" => {
                self.named_frames.insert("camera".into(), self.state.ctm);
                self.state.ctm = DMat4::IDENTITY;
            }
            "WorldEnd" => {}
            "Include" | "Import" => {
                let name = c.text(d)?;
                let path = self.resolve(&name);
                if self.include_depth >= MAX_INCLUDE_DEPTH {
                    return Err(syntax(at, format!("includes nest deeper than {MAX_INCLUDE_DEPTH} (a cycle?)")));
                }
                if self.files.len() > MAX_INCLUDES {
                    return Err(syntax(at, format!("more than {MAX_INCLUDES} included files")));
                }
                let text = crate::io::read_text(&path, MAX_FILE_BYTES, "included file")?;
                self.files.push(path.clone());
                self.include_depth += 1;
                self.file(&path, &text)?;
                self.include_depth -= 1;
            }
            "Camera" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                self.camera_directive(&kind, &params, at)?;
            }
            "Film" => {
                let _kind = c.text(d)?;
                let params = c.params()?;
                let w = params.integer("xresolution", 1280, at)?;
                let h = params.integer("yresolution", 720, at)?;
                let crop = match params.numbers("cropwindow", at)? {
                    None => None,
                    Some([a, b, c2, d2]) => Some([*a, *b, *c2, *d2]),
                    Some(_) => return Err(syntax(at, "cropwindow needs 4 numbers")),
                };
                for ignored in [
                    "filename",
                    "sensor",
                    "iso",
                    "whitebalance",
                    "savefp16",
                    "exposuretime",
                    "diagonal",
                    "maxcomponentvalue",
                ] {
                    params.get(ignored);
                }
                self.film = (w, h, crop);
                self.check_unused("Film", &params, at)?;
            }
            "Sampler" => {
                let _kind = c.text(d)?;
                let params = c.params()?;
                let n = params.integer("pixelsamples", 16, at)?;
                if n < 1 {
                    return Err(syntax(at, format!("pixelsamples must be at least 1, got {n}")));
                }
                params.get("seed");
                params.get("randomization");
                self.out.render.get_or_insert_with(RenderDescription::default).spp =
                    Some(u32::try_from(n).unwrap_or(u32::MAX));
                self.check_unused("Sampler", &params, at)?;
            }
            "Integrator" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                // pbrt's maxdepth counts scattering events: one more path segment.
                let depth = params.integer("maxdepth", 5, at)?;
                params.get("regularize");
                params.get("lightsampler");
                if depth >= 0 {
                    self.out.render.get_or_insert_with(RenderDescription::default).max_depth =
                        Some(u32::try_from(depth + 1).unwrap_or(u32::MAX));
                }
                if !matches!(
                    kind.as_str(),
                    "path" | "volpath" | "bdpt" | "mlt" | "sppm" | "lightpath" | "simplepath" | "simplevolpath"
                ) {
                    self.unsupported(at, format!("Integrator \"{kind}\": its maxdepth alone is read"))?;
                }
            }
            "PixelFilter" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                let radius = |default: f64| -> Result<Option<[f32; 2]>> {
                    let (x, y) = (params.float("xradius", default, at)?, params.float("yradius", default, at)?);
                    Ok(Some([x as f32, y as f32]))
                };
                let (kind, stddev, radius) = match kind.as_str() {
                    "box" => (PixelFilterKind::Box, None, radius(0.5)?),
                    "gaussian" => {
                        let sigma = params.float("sigma", 0.5, at)? as f32;
                        (PixelFilterKind::Gaussian, Some(sigma), radius(1.5)?)
                    }
                    "triangle" => (PixelFilterKind::Tent, None, radius(2.0)?),
                    other => {
                        for p in &params.list {
                            p.used.set(true);
                        }
                        self.unsupported(at, format!("PixelFilter \"{other}\": pbrt's default gaussian used"))?;
                        (PixelFilterKind::Gaussian, Some(0.5), Some([1.5; 2]))
                    }
                };
                self.check_unused(&format!("PixelFilter \"{kind:?}\""), &params, at)?;
                self.filter = PixelFilterDescription { kind, stddev, radius };
            }
            "ColorSpace" | "Accelerator" | "Option" => {
                if d == "Option" {
                    let _ = c.params()?;
                } else {
                    let _ = c.text(d)?;
                    let _ = c.params()?;
                }
            }
            "MakeNamedMaterial" => {
                let name = c.text(d)?;
                let params = c.params()?;
                let kind =
                    params.text("type", at)?.ok_or_else(|| syntax(at, "MakeNamedMaterial needs \"string type\""))?;
                let m = self.material(&kind, &params, at)?;
                let key = format!("named:{name}");
                self.out.materials.insert(key.clone(), m);
                self.named_materials.insert(name, key);
            }
            "NamedMaterial" => {
                let name = c.text(d)?;
                match self.named_materials.get(&name) {
                    Some(key) => self.state.material = key.clone(),
                    None => return Err(syntax(at, format!("NamedMaterial \"{name}\": no such material (before it)"))),
                }
            }
            "Material" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                let m = self.material(&kind, &params, at)?;
                let key = self.fresh("material");
                self.out.materials.insert(key.clone(), m);
                self.state.material = key;
            }
            "Texture" => {
                let name = c.text(d)?;
                let class = c.text(d)?;
                let kind = c.text(d)?;
                let params = c.params()?;
                self.texture_directive(name, &class, &kind, &params, at)?;
            }
            "AreaLightSource" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                if kind != "diffuse" {
                    self.unsupported(at, format!("AreaLightSource \"{kind}\": read as diffuse"))?;
                }
                let radiance = match self.colour(&params, "L", [1.0; 3], at)? {
                    Colour::Constant(c) => c,
                    Colour::Texture(_) => unreachable!("L is never a texture"),
                };
                let scale = params.float("scale", 1.0, at)? as f32;
                let two_sided = params.boolean("twosided", false, at)?;
                self.check_unused("AreaLightSource", &params, at)?;
                self.state.area_light = Some(AreaLight { radiance: radiance.map(|v| v * scale), two_sided });
            }
            "LightSource" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                self.light(&kind, &params, at)?;
            }
            "Shape" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                self.shape(&kind, &params, at)?;
            }
            "MakeNamedMedium" => {
                let name = c.text(d)?;
                let _ = c.params()?;
                self.unsupported(at, format!("{d} \"{name}\" is not supported: ignored"))?;
            }
            "ObjectBegin" => {
                let name = c.text(d)?;
                if let Some((open, _, _)) = &self.defining {
                    return Err(syntax(at, format!("ObjectBegin \"{name}\" inside the definition of \"{open}\"")));
                }
                if self.stack.len() >= MAX_ATTRIBUTE_DEPTH {
                    return Err(syntax(at, format!("{d} nests deeper than {MAX_ATTRIBUTE_DEPTH}")));
                }
                // As pbrt-v4: an attribute block of its own, shapes without area lights.
                self.stack.push(self.state.clone());
                self.defining = Some((name, Prototype::mark(&self.out), at.clone()));
            }
            "ObjectEnd" => {
                let (name, mark, _) =
                    self.defining.take().ok_or_else(|| syntax(at, "ObjectEnd without an ObjectBegin"))?;
                self.state = self.stack.pop().ok_or_else(|| syntax(at, "ObjectEnd without a matching begin"))?;
                let prototype = Prototype::capture(&mut self.out, mark);
                if self.objects.insert(name.clone(), prototype).is_some() {
                    self.unsupported(at, format!("object \"{name}\" is defined again: the new definition used"))?;
                }
            }
            "ObjectInstance" => {
                let name = c.text(d)?;
                if self.defining.is_some() {
                    return Err(syntax(at, format!("ObjectInstance \"{name}\" inside an object's definition")));
                }
                // Resolved at the end: pbrt-v4 lets an instance come before its definition.
                self.instances.push((name, self.state.ctm, at.clone()));
            }
            "MediumInterface" => {
                let _ = c.text(d)?;
                if let Some(Token::Text(_)) = c.peek() {
                    let _ = c.text(d)?;
                }
                self.unsupported(at, "MediumInterface: media are not supported: ignored".into())?;
            }
            "Attribute" => {
                let _ = c.text(d)?;
                let _ = c.params()?;
                self.unsupported(at, "Attribute: default parameters are not supported: ignored".into())?;
            }
            "TransformTimes" => {
                let _ = c.numbers(2, d)?;
            }
            "ActiveTransform" => {
                let at2 = c.at();
                match c.next() {
                    Some(Token::Word(w)) if w == "All" => {}
                    Some(Token::Word(w)) if w == "StartTime" || w == "EndTime" => {
                        self.unsupported(
                            &at2,
                            "ActiveTransform: motion blur is not supported; every transform applies".into(),
                        )?;
                    }
                    other => {
                        return Err(syntax(
                            &at2,
                            format!(
                                "ActiveTransform: expected All, StartTime or EndTime, found {}",
                                describe(other.as_ref())
                            ),
                        ));
                    }
                }
            }
            other => return Err(syntax(at, format!("unknown directive {other}"))),
        }
        Ok(())
    }

    fn camera_directive(&mut self, kind: &str, params: &Params, at: &At) -> Result<()> {
        if self.camera_seen {
            return self.unsupported(at, "a second Camera: ignored".into());
        }
        self.camera_seen = true;
        if kind != "perspective" {
            return Err(syntax(at, format!("Camera \"{kind}\" is not supported (only perspective)")));
        }
        let fov = params.float("fov", 90.0, at)?;
        if params.float("lensradius", 0.0, at)? != 0.0 {
            self.unsupported(at, "Camera: lensradius (depth of field) is not supported: a pinhole".into())?;
        }
        for ignored in ["focaldistance", "shutteropen", "shutterclose"] {
            params.get(ignored);
        }
        self.check_unused("Camera", params, at)?;
        self.named_frames.insert("camera".into(), self.state.ctm);
        self.camera = Some((self.state.ctm, fov, at.clone()));
        Ok(())
    }

    /// The camera and film, once the whole file is read.
    fn finish(&mut self) -> Result<()> {
        if let Some((name, _, at)) = &self.defining {
            return Err(syntax(at, format!("ObjectBegin \"{name}\" without an ObjectEnd")));
        }
        for (material, mesh, origin) in std::mem::take(&mut self.curves) {
            self.out.inline_meshes.push(curve_mesh(mesh, material, origin));
        }
        let mut budget = MAX_INSTANCED_TRIANGLES;
        for (name, ctm, at) in std::mem::take(&mut self.instances) {
            match self.objects.get(&name) {
                Some(object) => object.instantiate(ctm, &mut self.out, &mut budget).map_err(|e| syntax(&at, e))?,
                None => self.unsupported(&at, format!("ObjectInstance \"{name}\": no such object: skipped"))?,
            }
        }
        let (w, h, crop) = self.film;
        let default_at = At { file: Rc::new(self.files[0].clone()), line: 1 };
        if w < 1 || h < 1 || w > i64::from(u32::MAX) || h > i64::from(u32::MAX) {
            return Err(syntax(&default_at, format!("the film must be at least 1×1, got {w}×{h}")));
        }
        let (camera_from_world, fov, at) = self.camera.clone().unwrap_or((DMat4::IDENTITY, 90.0, default_at));
        if !(fov > 0.0 && fov < 180.0) {
            return Err(syntax(&at, format!("fov must lie in (0, 180) degrees, got {fov}")));
        }
        let world_from_camera = camera_from_world.inverse();
        if !world_from_camera.is_finite() {
            return Err(syntax(&at, "the camera's transform cannot be inverted"));
        }
        let (wf, hf) = (w as f64, h as f64);
        // pbrt's fov spans the shorter side.
        let half = (fov.to_radians() / 2.0).tan();
        let tan_y = if w < h { half * hf / wf } else { half };
        let eye = world_from_camera.transform_point3(DVec3::ZERO);
        let forward = world_from_camera.transform_vector3(DVec3::Z).normalize_or_zero();
        let up = world_from_camera.transform_vector3(DVec3::Y).normalize_or_zero();
        let right = world_from_camera.transform_vector3(DVec3::X);
        // pbrt's image right is camera +x; ours is forward × up.
        let mirror = forward.cross(up).dot(right) < 0.0;
        self.out.camera = CameraDescription {
            eye: eye.as_vec3().to_array(),
            look_at: (eye + forward).as_vec3().to_array(),
            up: up.as_vec3().to_array(),
            fov_y: (2.0 * tan_y.atan()).to_degrees() as f32,
            width: w as u32,
            height: h as u32,
            crop: None,
            mirror,
            filter: Some(self.filter),
        };
        if let Some([x0, x1, y0, y1]) = crop {
            // pbrt: pixels ceil(res·min) up to ceil(res·max).
            let px = |f: f64, n: f64| (n * f.clamp(0.0, 1.0)).ceil() as u32;
            let (a, b, c, d) = (px(x0.min(x1), wf), px(x0.max(x1), wf), px(y0.min(y1), hf), px(y0.max(y1), hf));
            self.out.camera.crop = Some([a, c, b.saturating_sub(a), d.saturating_sub(c)]);
        }
        Ok(())
    }

    /// A colour parameter: `rgb`, a single-valued or named `spectrum` (approximated), a
    /// `float`, or a `texture`.
    fn colour(&mut self, params: &Params, name: &str, default: [f32; 3], at: &At) -> Result<Colour> {
        let Some(p) = params.get(name) else { return Ok(Colour::Constant(default)) };
        let (kind, values) = (p.kind.clone(), p.values.clone());
        match (kind.as_str(), values) {
            ("rgb", Values::Numbers(v)) if v.len() == 3 => {
                Ok(Colour::Constant([v[0] as f32, v[1] as f32, v[2] as f32]))
            }
            ("float", Values::Numbers(v)) if v.len() == 1 => Ok(Colour::Constant([v[0] as f32; 3])),
            ("spectrum", Values::Numbers(v)) if v.len() == 1 => Ok(Colour::Constant([v[0] as f32; 3])),
            ("spectrum", Values::Numbers(v)) if v.len() >= 4 && v.len() % 2 == 0 => {
                // λ/value pairs. A light's spectrum is normalised to luminance 1 (pbrt-v4
                // scales it by 1/∫Lȳ, then by "scale"); a reflectance is taken under D65.
                let points: Vec<(f64, f64)> = v.chunks(2).map(|p| (p[0], p[1])).collect();
                let emission = matches!(name, "L" | "I");
                let rgb = crate::material::cie::spectrum_to_rgb(&points, emission)
                    .ok_or_else(|| syntax(at, format!("\"spectrum {name}\": wavelengths must increase")))?;
                if emission {
                    let y = f64::from(crate::geometry::luminance(glam::Vec3A::from_array(rgb)));
                    if y.is_nan() || y <= 0.0 {
                        return Err(syntax(at, format!("\"spectrum {name}\" has no luminance")));
                    }
                    Ok(Colour::Constant(rgb.map(|c| (f64::from(c) / y).max(0.0) as f32)))
                } else {
                    Ok(Colour::Constant(rgb.map(|c| c.clamp(0.0, 1.0))))
                }
            }
            ("blackbody", Values::Numbers(_)) => {
                self.unsupported(at, format!("\"blackbody {name}\" is not converted: white used"))?;
                Ok(Colour::Constant([1.0; 3]))
            }
            ("spectrum", Values::Texts(v)) => {
                self.unsupported(at, format!("named spectrum \"{}\" for {name}: grey 0.5 used", v[0]))?;
                Ok(Colour::Constant([0.5; 3]))
            }
            ("texture", Values::Texts(v)) if v.len() == 1 => match self.textures.get(&(false, v[0].clone())) {
                Some(t) => Ok(Colour::Texture(t.clone())),
                None => Err(syntax(at, format!("\"texture {name}\": no spectrum texture \"{}\" (before it)", v[0]))),
            },
            (k, _) => Err(syntax(at, format!("\"{k} {name}\": not a colour"))),
        }
    }

    /// GGX α from pbrt's roughness parameters (remapped by `sqrt` unless `remaproughness` is
    /// false, as pbrt-v4's `TrowbridgeReitzDistribution::RoughnessToAlpha`), or a float
    /// texture's name.
    fn roughness(&mut self, params: &Params, at: &At) -> Result<(f32, Option<String>)> {
        let remap = params.boolean("remaproughness", true, at)?;
        let read = |this: &mut Self, name: &str| -> Result<Option<(f64, Option<String>)>> {
            match params.get(name).map(|p| (p.kind.clone(), p.values.clone())) {
                None => Ok(None),
                Some((k, Values::Numbers(v))) if k == "float" && v.len() == 1 => Ok(Some((v[0], None))),
                Some((k, Values::Texts(v))) if k == "texture" && v.len() == 1 => match this
                    .textures
                    .get(&(true, v[0].clone()))
                {
                    Some(t) => Ok(Some((0.0, Some(t.clone())))),
                    None => Err(syntax(at, format!("\"texture {name}\": no float texture \"{}\" (before it)", v[0]))),
                },
                Some((k, _)) => Err(syntax(at, format!("\"{k} {name}\" must be a float or a texture"))),
            }
        };
        let (r, texture) = match (read(self, "roughness")?, read(self, "uroughness")?, read(self, "vroughness")?) {
            (Some(r), _, _) => r,
            (None, Some(u), Some(v)) => {
                if u.0 != v.0 || u.1.is_some() || v.1.is_some() {
                    self.unsupported(at, "anisotropic roughness: the mean of uroughness and vroughness used".into())?;
                }
                ((u.0 + v.0) / 2.0, u.1.or(v.1))
            }
            (None, Some(r), None) | (None, None, Some(r)) => r,
            (None, None, None) => (0.0, None),
        };
        if texture.is_some() && remap {
            self.unsupported(at, "a roughness texture is read as α directly (no remapping)".into())?;
        }
        let alpha = if remap { r.max(0.0).sqrt() } else { r };
        Ok((alpha.min(1.0) as f32, texture))
    }

    fn eta(&mut self, params: &Params, default: f32, at: &At) -> Result<f32> {
        match params.get("eta").map(|p| (p.kind.clone(), p.values.clone())) {
            None => Ok(default),
            Some((_, Values::Numbers(v))) if v.len() == 1 => Ok(v[0] as f32),
            Some((_, Values::Texts(v))) => match glass_ior(&v[0]) {
                Some(eta) => Ok(eta),
                None => {
                    self.unsupported(at, format!("eta \"{}\" is not a glass we know: {default} used", v[0]))?;
                    Ok(default)
                }
            },
            Some((k, _)) => Err(syntax(at, format!("\"{k} eta\" must be a number or a named spectrum"))),
        }
    }

    /// A hair material's colour: `color` if given, else the colour whose absorption is
    /// `sigma_a`, else that of the melanin concentrations (pbrt-v4's default: eumelanin 1.3),
    /// by Chiang et al.'s (2016) mapping between colour and absorption at the azimuthal
    /// roughness `beta_n`, as pbrt-v4's `HairBxDF` uses it.
    fn hair_colour(&mut self, params: &Params, at: &At) -> Result<[f32; 3]> {
        let beta_n = params.float("beta_n", 0.3, at)?.clamp(0.0, 1.0);
        let constant = |this: &mut Self, name: &str| -> Result<Option<[f32; 3]>> {
            if params.get(name).is_none() {
                return Ok(None);
            }
            match this.colour(params, name, [0.0; 3], at)? {
                Colour::Constant(c) => Ok(Some(c)),
                Colour::Texture(_) => {
                    this.unsupported(at, format!("a hair's \"{name}\" as a texture: its default used"))?;
                    Ok(None)
                }
            }
        };
        if let Some(c) = constant(self, "color")? {
            for ignored in ["sigma_a", "eumelanin", "pheomelanin"] {
                params.get(ignored);
            }
            return Ok(c.map(|x| x.clamp(0.0, 1.0)));
        }
        let sigma_a = match constant(self, "sigma_a")? {
            Some(s) => s.map(f64::from),
            None => {
                let (e, p) =
                    (params.float("eumelanin", 1.3, at)?.max(0.0), params.float("pheomelanin", 0.0, at)?.max(0.0));
                let (eu, ph) = ([0.419, 0.697, 1.37], [0.187, 0.4, 1.05]);
                [0, 1, 2].map(|i| e * eu[i] + p * ph[i])
            }
        };
        let b = beta_n;
        let k = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3) + 5.574 * b.powi(4) + 0.245 * b.powi(5);
        Ok(sigma_a.map(|s| (-(s.max(0.0).sqrt()) * k).exp() as f32))
    }

    fn material(&mut self, kind: &str, params: &Params, at: &At) -> Result<MaterialDescription> {
        let mut m = MaterialDescription::default();
        params.get("displacement").inspect(|_| ());
        match kind {
            "diffuse" => match self.colour(params, "reflectance", [0.5; 3], at)? {
                Colour::Constant(c) => m.diffuse = c,
                Colour::Texture(t) => m.diffuse_texture = Some(t),
            },
            "conductor" => {
                m.kind = MaterialKind::Conductor;
                let named = |p: Option<&Param>| match p.map(|p| &p.values) {
                    Some(Values::Texts(v)) => v.first().cloned(),
                    _ => None,
                };
                let (eta_p, k_p) = (params.get("eta").cloned(), params.get("k").cloned());
                match (named(eta_p.as_ref()), named(k_p.as_ref()), &eta_p, &k_p) {
                    (Some(e), Some(k), ..) => {
                        let metal = e.strip_prefix("metal-").and_then(|s| s.strip_suffix("-eta"));
                        let metal_k = k.strip_prefix("metal-").and_then(|s| s.strip_suffix("-k"));
                        match (metal, metal_k) {
                            (Some(a), Some(b)) if a == b && crate::material::metals::lookup(a).is_some() => {
                                m.metal = Some(a.to_string());
                            }
                            _ => {
                                self.unsupported(at, format!("conductor spectra \"{e}\"/\"{k}\": copper used"))?;
                                m.metal = Some("Cu".into());
                            }
                        }
                    }
                    (None, None, None, None) => {
                        if params.get("reflectance").is_some() {
                            self.unsupported(
                                at,
                                "conductor \"reflectance\" (artist mode) is not supported: copper used".into(),
                            )?;
                        }
                        m.metal = Some("Cu".into());
                    }
                    _ => {
                        let eta = match self.colour(params, "eta", [0.2; 3], at)? {
                            Colour::Constant(c) => c,
                            Colour::Texture(_) => return Err(syntax(at, "a conductor's eta cannot be a texture")),
                        };
                        let k = match self.colour(params, "k", [3.9; 3], at)? {
                            Colour::Constant(c) => c,
                            Colour::Texture(_) => return Err(syntax(at, "a conductor's k cannot be a texture")),
                        };
                        (m.eta, m.k) = (Some(eta), Some(k));
                    }
                }
                let (alpha, t) = self.roughness(params, at)?;
                (m.roughness, m.roughness_texture) = (Some(alpha), t);
            }
            "dielectric" | "thindielectric" => {
                m.kind = if kind == "dielectric" { MaterialKind::Dielectric } else { MaterialKind::ThinDielectric };
                m.ior = Some(self.eta(params, 1.5, at)?);
                if kind == "dielectric" {
                    let (alpha, t) = self.roughness(params, at)?;
                    (m.roughness, m.roughness_texture) = (Some(alpha), t);
                }
            }
            "coateddiffuse" => {
                self.unsupported(
                    at,
                    "coateddiffuse is approximated by Mitsuba's nonlinear plastic (one interface, no layer thickness or albedo)"
                        .into(),
                )?;
                m.kind = MaterialKind::Plastic;
                // Nonlinear: light reflected back down by the coat meets the base again, so the
                // base's colour compounds, ρ/(1 − ρ·F̄dr), as in pbrt-v4's random walk through
                // the layer (the linear form, ρ/(1 − F̄dr), made coffee's orange and grey floor
                // 1.5× too bright against Tungsten's render).
                m.nonlinear = Some(true);
                match self.colour(params, "reflectance", [0.5; 3], at)? {
                    Colour::Constant(c) => m.diffuse = c,
                    Colour::Texture(t) => m.diffuse_texture = Some(t),
                }
                m.ior = Some(self.eta(params, 1.5, at)?);
                let (alpha, t) = self.roughness(params, at)?;
                if t.is_some() {
                    self.unsupported(at, "a textured roughness of a coated diffuse: 0 used".into())?;
                }
                m.roughness = Some(if t.is_some() { 0.0 } else { alpha });
                for ignored in ["thickness", "albedo", "g", "maxdepth", "nsamples"] {
                    params.get(ignored);
                }
            }
            "mix" => {
                let names = match params.get("materials").map(|p| p.values.clone()) {
                    Some(Values::Texts(v)) if v.len() == 2 => v,
                    _ => return Err(syntax(at, "a mix material needs \"string materials\" with two names")),
                };
                let amount = match params.get("amount").map(|p| (p.kind.clone(), p.values.clone())) {
                    Some((k, Values::Numbers(v))) if k == "float" && v.len() == 1 => v[0],
                    _ => 0.5,
                };
                // pbrt-v4 picks the second material with probability `amount`.
                let pick = &names[usize::from(amount > 0.5)];
                self.unsupported(at, format!("a mix material (amount {amount}): \"{pick}\" stands for it"))?;
                let found = self.named_materials.get(pick).and_then(|key| self.out.materials.get(key)).cloned();
                m = found.ok_or_else(|| syntax(at, format!("mix: no named material \"{pick}\" (before it)")))?;
                params.get("amount");
            }
            "coatedconductor" => {
                self.unsupported(at, "coatedconductor is approximated by its conductor (no coating layer)".into())?;
                m.kind = MaterialKind::Conductor;
                let named = |name: &str| match params.get(name).map(|p| p.values.clone()) {
                    Some(Values::Texts(v)) => v.first().cloned(),
                    _ => None,
                };
                let metal = named("conductor.eta")
                    .and_then(|e| e.strip_prefix("metal-").and_then(|s| s.strip_suffix("-eta")).map(str::to_string))
                    .filter(|a| crate::material::metals::lookup(a).is_some());
                m.metal = Some(metal.unwrap_or_else(|| "Cu".into()));
                let r = params.float("conductor.roughness", 0.0, at)?;
                let remap = params.boolean("remaproughness", true, at)?;
                m.roughness = Some((if remap { r.max(0.0).sqrt() } else { r }).min(1.0) as f32);
                for p in &params.list {
                    p.used.set(true);
                }
            }
            "diffusetransmission" => {
                self.unsupported(at, "diffusetransmission is approximated by its diffuse reflection".into())?;
                match self.colour(params, "reflectance", [0.25; 3], at)? {
                    Colour::Constant(c) => m.diffuse = c,
                    Colour::Texture(t) => m.diffuse_texture = Some(t),
                }
                for ignored in ["transmittance", "scale"] {
                    params.get(ignored);
                }
            }
            "hair" => {
                self.unsupported(
                    at,
                    "hair is approximated by a diffuse surface of the colour its absorption gives".into(),
                )?;
                m.diffuse = self.hair_colour(params, at)?;
                for ignored in ["eta", "beta_m", "alpha"] {
                    params.get(ignored);
                }
            }
            "interface" => {
                self.unsupported(at, "an interface material (media boundary): a glass of index 1.0001 used".into())?;
                m.kind = MaterialKind::ThinDielectric;
                m.ior = Some(1.0001);
            }
            other => {
                self.unsupported(at, format!("Material \"{other}\" is not supported: grey diffuse (0.5) used"))?;
                for p in &params.list {
                    p.used.set(true);
                }
                m.diffuse = [0.5; 3];
            }
        }
        params.get("normalmap");
        self.check_unused(&format!("Material \"{kind}\""), params, at)?;
        Ok(m)
    }

    fn texture_directive(&mut self, name: String, class: &str, kind: &str, params: &Params, at: &At) -> Result<()> {
        let float = match class {
            "float" => true,
            "spectrum" | "color" => false,
            other => {
                return Err(syntax(at, format!("Texture \"{name}\": class \"{other}\" is neither float nor spectrum")));
            }
        };
        let key = self.fresh("texture");
        let description = match kind {
            "imagemap" => {
                let file =
                    params.text("filename", at)?.ok_or_else(|| syntax(at, "an imagemap needs \"string filename\""))?;
                let wrap = match params.text("wrap", at)?.as_deref() {
                    None | Some("repeat") => WrapDescription::Repeat,
                    Some("clamp") => WrapDescription::Clamp,
                    Some(other) => {
                        self.unsupported(at, format!("wrap \"{other}\": repeat used"))?;
                        WrapDescription::Repeat
                    }
                };
                let filter = match params.text("filter", at)?.as_deref() {
                    Some("point") => FilterDescription::Nearest,
                    _ => FilterDescription::Bilinear,
                };
                let raw = match params.text("encoding", at)?.as_deref() {
                    None | Some("sRGB") => false,
                    Some("linear") => true,
                    Some(other) => {
                        self.unsupported(at, format!("encoding \"{other}\": sRGB used"))?;
                        false
                    }
                };
                let factor = params.float("scale", 1.0, at)? as f32;
                let invert = params.boolean("invert", false, at)?;
                let uv_transform = self.mapping(params, at)?;
                params.get("maxanisotropy");
                TextureDescription {
                    kind: TextureKind::Bitmap,
                    file: Some(self.resolve(&file).to_string_lossy().into_owned()),
                    wrap: Some(wrap),
                    filter: Some(filter),
                    raw: Some(raw),
                    color0: None,
                    color1: None,
                    scale: None,
                    v_from_top: None,
                    uv_transform,
                    factor: (factor != 1.0).then_some([factor; 3]),
                    invert: invert.then_some(true),
                }
            }
            "checkerboard" => {
                let value = |this: &mut Self, name: &str, default: f32| -> Result<[f32; 3]> {
                    match this.colour(params, name, [default; 3], at)? {
                        Colour::Constant(c) => Ok(c),
                        Colour::Texture(_) => {
                            this.unsupported(at, format!("a checkerboard's {name} as a texture: grey 0.5 used"))?;
                            Ok([0.5; 3])
                        }
                    }
                };
                let (c1, c2) = (value(self, "tex1", 1.0)?, value(self, "tex2", 0.0)?);
                let (us, vs) = (params.float("uscale", 1.0, at)?, params.float("vscale", 1.0, at)?);
                params.get("dimension");
                TextureDescription {
                    kind: TextureKind::Checkerboard,
                    file: None,
                    wrap: None,
                    filter: None,
                    raw: None,
                    color0: Some(c1),
                    color1: Some(c2),
                    scale: Some([us.abs().max(1e-6) as f32, vs.abs().max(1e-6) as f32]),
                    v_from_top: None,
                    uv_transform: None,
                    factor: None,
                    invert: None,
                }
            }
            "constant" => match self.colour(params, "value", [1.0; 3], at)? {
                Colour::Constant(c) => TextureDescription::constant(c),
                Colour::Texture(t) => {
                    self.textures.insert((float, name), t);
                    self.check_unused(&format!("Texture \"{kind}\""), params, at)?;
                    return Ok(());
                }
            },
            "scale" => {
                // `tex` times `scale`: two constants fold into one colour; a texture times a
                // constant is that texture with a factor.
                let a = self.operand(params, "tex", float, at)?;
                let b = self.operand(params, "scale", float, at)?;
                match (a, b) {
                    (Colour::Constant(a), Colour::Constant(b)) => {
                        TextureDescription::constant([a[0] * b[0], a[1] * b[1], a[2] * b[2]])
                    }
                    (Colour::Texture(t), Colour::Constant(c)) | (Colour::Constant(c), Colour::Texture(t)) => {
                        let mut scaled = self
                            .out
                            .textures
                            .get(&t)
                            .cloned()
                            .unwrap_or_else(|| TextureDescription::constant([0.5; 3]));
                        let old = scaled.factor.unwrap_or([1.0; 3]);
                        scaled.factor = Some([old[0] * c[0], old[1] * c[1], old[2] * c[2]]);
                        if scaled.invert == Some(true) {
                            self.unsupported(
                                at,
                                format!(
                                    "Texture \"{name}\": an inverted imagemap scaled again: scaled before inverting"
                                ),
                            )?;
                        }
                        scaled
                    }
                    (Colour::Texture(t), Colour::Texture(_)) => {
                        self.unsupported(
                            at,
                            format!("Texture \"{name}\": the product of two textures is not supported: the first used"),
                        )?;
                        self.textures.insert((float, name), t);
                        self.check_unused(&format!("Texture \"{kind}\""), params, at)?;
                        return Ok(());
                    }
                }
            }
            other => {
                self.unsupported(at, format!("Texture \"{other}\" is not supported: grey 0.5 used"))?;
                for p in &params.list {
                    p.used.set(true);
                }
                TextureDescription::constant([0.5; 3])
            }
        };
        self.check_unused(&format!("Texture \"{kind}\""), params, at)?;
        self.out.textures.insert(key.clone(), description);
        self.textures.insert((float, name), key);
        Ok(())
    }

    /// An operand of a texture of class `float` (or spectrum): a texture of the same class by
    /// name, or a value.
    fn operand(&mut self, params: &Params, name: &str, float: bool, at: &At) -> Result<Colour> {
        match params.get(name).map(|p| (p.kind.clone(), p.values.clone())) {
            Some((k, Values::Texts(v))) if k == "texture" && v.len() == 1 => {
                match self.textures.get(&(float, v[0].clone())) {
                    Some(t) => Ok(Colour::Texture(t.clone())),
                    None => Err(syntax(at, format!("\"texture {name}\": no such texture \"{}\" (before it)", v[0]))),
                }
            }
            _ => self.colour(params, name, [1.0; 3], at),
        }
    }

    /// pbrt's `uv` mapping with its scale and shift (`s = su·u + du`, `t = sv·v + dv`), as a
    /// map of texture coordinates; other mappings are not supported.
    fn mapping(&mut self, params: &Params, at: &At) -> Result<Option<[[f32; 3]; 2]>> {
        let mapping = params.text("mapping", at)?;
        let (us, vs) = (params.float("uscale", 1.0, at)?, params.float("vscale", 1.0, at)?);
        let (ud, vd) = (params.float("udelta", 0.0, at)?, params.float("vdelta", 0.0, at)?);
        if mapping.as_deref().is_some_and(|m| m != "uv") {
            self.unsupported(at, "a texture mapping other than uv (spherical, cylindrical, planar): uv used".into())?;
        }
        Ok(((us, vs, ud, vd) != (1.0, 1.0, 0.0, 0.0))
            .then_some([[us as f32, 0.0, ud as f32], [0.0, vs as f32, vd as f32]]))
    }

    /// The material a shape declared now gets: the current one, made emitting by the area
    /// light in force.
    fn shape_material(&mut self) -> Result<String> {
        let base = self.state.material.clone();
        let Some(light) = self.state.area_light.clone() else { return Ok(base) };
        if self.defining.is_some() {
            // pbrt-v4 does not instance area lights either (it warns, and the shape does
            // not emit).
            let at = self.defining.as_ref().map(|(_, _, at)| at.clone()).expect("defining");
            self.unsupported(&at, "an area light in an object (instances do not emit): not emitting".into())?;
            return Ok(base);
        }
        let key = format!("{base}|{:?}|{}", light.radiance, light.two_sided);
        if let Some(name) = self.emitting.get(&key) {
            return Ok(name.clone());
        }
        let mut m = self.out.materials.get(&base).cloned().unwrap_or_default();
        m.emission = light.radiance;
        m.two_sided_emission = light.two_sided;
        let name = self.fresh("emitter");
        self.out.materials.insert(name.clone(), m);
        self.emitting.insert(key, name.clone());
        Ok(name)
    }

    /// A `curve` (hair, fur): tessellated into triangles (see [`crate::scene::mesh::curves`]), in
    /// world space, its width scaled as the transform scales volumes.
    fn curve(&mut self, params: &Params, at: &At) -> Result<()> {
        use crate::scene::mesh::curves::{Basis, Curve, CurveMesh, Sweep};
        let p = params.numbers("P", at)?.ok_or_else(|| syntax(at, "a curve needs \"point3 P\""))?.to_vec();
        if p.len() % 3 != 0 {
            return Err(syntax(at, "\"P\" must hold whole points"));
        }
        let ctm = self.state.ctm;
        let points: Vec<DVec3> = p.chunks(3).map(|c| ctm.transform_point3(DVec3::new(c[0], c[1], c[2]))).collect();
        let basis = match params.text("basis", at)?.as_deref() {
            None | Some("bezier") => Basis::Bezier,
            Some("bspline") => Basis::Bspline,
            Some(other) => {
                return Err(syntax(at, format!("curve basis \"{other}\": pbrt-v4 knows bezier and bspline")));
            }
        };
        let degree = params.integer("degree", 3, at)?;
        let sweep = match params.text("type", at)?.as_deref() {
            None | Some("flat") => {
                if !self.warned_flat_curves {
                    self.warned_flat_curves = true;
                    self.unsupported(at, "flat curves (which face every ray) are tessellated as tubes".into())?;
                }
                Sweep::Tube
            }
            Some("cylinder") => Sweep::Tube,
            Some("ribbon") => Sweep::Ribbon,
            Some(other) => {
                return Err(syntax(at, format!("curve type \"{other}\": pbrt-v4 knows flat, cylinder and ribbon")));
            }
        };
        let width = params.float("width", 1.0, at)?;
        let scale = ctm.determinant().abs().cbrt();
        let width = [params.float("width0", width, at)? * scale, params.float("width1", width, at)? * scale];
        let normal_map = ctm.inverse().transpose();
        let normals: Option<Vec<DVec3>> = params.numbers("N", at)?.map(|n| {
            n.chunks(3)
                .filter(|c| c.len() == 3)
                .map(|c| normal_map.transform_vector3(DVec3::new(c[0], c[1], c[2])))
                .collect()
        });
        params.get("splitdepth");
        let degree = usize::try_from(degree).unwrap_or(0);
        let curve = Curve { points: &points, basis, degree, sweep, width, normals: normals.as_deref() };
        let material = self.shape_material()?;
        let max = crate::scene::limits::MAX_TRIANGLES;
        if self.defining.is_some() {
            // In an object: a mesh of its own, captured with the object's other shapes.
            let mut mesh = CurveMesh::default();
            mesh.add(&curve, max).map_err(|e| syntax(at, e))?;
            self.out.inline_meshes.push(curve_mesh(mesh, material, at.to_string()));
            return Ok(());
        }
        let k = match self.curves.iter().position(|(m, ..)| *m == material) {
            Some(k) => k,
            None => {
                self.curves.push((material, CurveMesh::default(), at.to_string()));
                self.curves.len() - 1
            }
        };
        let others: usize =
            self.curves.iter().enumerate().filter(|(i, _)| *i != k).map(|(_, (_, m, _))| m.indices.len() / 3).sum();
        let mesh = &mut self.curves[k].1;
        mesh.add(&curve, max.saturating_sub(others)).map_err(|e| syntax(at, e))
    }

    fn shape(&mut self, kind: &str, params: &Params, at: &At) -> Result<()> {
        for ignored in ["alpha", "emissionfilename"] {
            if params.get(ignored).is_some() {
                self.unsupported(at, format!("Shape \"{kind}\": \"{ignored}\" is not supported: ignored"))?;
            }
        }
        let ctm = self.state.ctm;
        let det = ctm.determinant();
        let world_reverse = self.state.reverse != (det < 0.0);
        match kind {
            "trianglemesh" | "bilinearmesh" => {
                let p = params
                    .numbers("P", at)?
                    .ok_or_else(|| syntax(at, format!("a {kind} needs \"point3 P\"")))?
                    .to_vec();
                if p.len() % 3 != 0 || p.is_empty() {
                    return Err(syntax(at, "\"P\" must hold whole points"));
                }
                let n = p.len() / 3;
                let indices: Vec<i64> = match params.numbers("indices", at)? {
                    Some(v) => v.iter().map(|&x| x as i64).collect(),
                    None if kind == "trianglemesh" && n == 3 => vec![0, 1, 2],
                    None if kind == "bilinearmesh" && n == 4 => vec![0, 1, 2, 3],
                    None => return Err(syntax(at, "\"indices\" is required")),
                };
                if let Some(&i) = indices.iter().find(|&&i| i < 0 || i as usize >= n) {
                    return Err(syntax(at, format!("vertex index {i} out of range ({n} vertices)")));
                }
                let normals = params.numbers("N", at)?.map(<[f64]>::to_vec);
                let uvs = params.numbers("uv", at)?.map(<[f64]>::to_vec);
                for ignored in ["S", "faceIndices", "tangent"] {
                    params.get(ignored);
                }
                let triangles: Vec<u32> = if kind == "trianglemesh" {
                    if !indices.len().is_multiple_of(3) {
                        return Err(syntax(at, "trianglemesh \"indices\" must come in threes"));
                    }
                    indices.iter().map(|&i| i as u32).collect()
                } else {
                    if !indices.len().is_multiple_of(4) {
                        return Err(syntax(at, "bilinearmesh \"indices\" must come in fours"));
                    }
                    // Patch corners p00, p10, p01, p11: two triangles (exact when planar).
                    indices.chunks(4).flat_map(|q| [q[0], q[1], q[3], q[0], q[3], q[2]]).map(|i| i as u32).collect()
                };
                let normal_map = ctm.inverse().transpose();
                let point = |k: usize| {
                    ctm.transform_point3(DVec3::new(p[3 * k], p[3 * k + 1], p[3 * k + 2])).as_vec3().to_array()
                };
                let positions: Vec<[f32; 3]> = (0..n).map(point).collect();
                let normals = match normals {
                    Some(v) if v.len() == p.len() => Some(
                        (0..n)
                            .map(|k| {
                                normal_map
                                    .transform_vector3(DVec3::new(v[3 * k], v[3 * k + 1], v[3 * k + 2]))
                                    .as_vec3()
                                    .to_array()
                            })
                            .collect(),
                    ),
                    Some(_) => return Err(syntax(at, "\"N\" must hold one normal per vertex")),
                    None => None,
                };
                let uvs = match uvs {
                    Some(v) if v.len() == 2 * n => {
                        Some((0..n).map(|k| [v[2 * k] as f32, v[2 * k + 1] as f32]).collect())
                    }
                    Some(_) => return Err(syntax(at, "\"uv\" must hold one point2 per vertex")),
                    None => None,
                };
                let has_normals = normals.is_some();
                let material = self.shape_material()?;
                self.out.inline_meshes.push(InlineMesh {
                    origin: at.to_string(),
                    positions,
                    indices: triangles,
                    normals,
                    uvs,
                    material,
                    // With normals, pbrt lets them decide the outside (so do we).
                    reverse_winding: world_reverse && !has_normals,
                });
            }
            "curve" => self.curve(params, at)?,
            "plymesh" => {
                let file =
                    params.text("filename", at)?.ok_or_else(|| syntax(at, "a plymesh needs \"string filename\""))?;
                for ignored in ["displacement", "edgelength"] {
                    if params.get(ignored).is_some() {
                        self.unsupported(
                            at,
                            format!("plymesh \"{ignored}\" (displacement) is not supported: ignored"),
                        )?;
                    }
                }
                let material = self.shape_material()?;
                self.out.meshes.push(MeshDescription {
                    obj: None,
                    ply: Some(self.resolve(&file).to_string_lossy().into_owned()),
                    material: Some(material),
                    reverse_winding: self.state.reverse,
                    matrix: (ctm != DMat4::IDENTITY).then(|| to_rows(ctm)),
                    smooth_normals: false,
                    face_normals: false,
                    flip_v: false,
                });
            }
            "sphere" | "disk" => {
                let radius = params.float("radius", 1.0, at)?;
                if !(radius.is_finite() && radius > 0.0) {
                    return Err(syntax(at, format!("a {kind} needs a positive radius, got {radius}")));
                }
                let partial = if kind == "sphere" {
                    params.float("zmin", -radius, at)? > -radius
                        || params.float("zmax", radius, at)? < radius
                        || params.float("phimax", 360.0, at)? < 360.0
                } else {
                    params.float("innerradius", 0.0, at)? > 0.0 || params.float("phimax", 360.0, at)? < 360.0
                };
                if partial {
                    self.unsupported(
                        at,
                        format!("a partial {kind} (zmin, zmax, phimax, innerradius): the whole {kind} used"),
                    )?;
                }
                let material = self.shape_material()?;
                let (shape, matrix, center, r) = if kind == "sphere" {
                    (ShapeKind::Sphere, ctm, Some([0.0; 3]), Some(radius as f32))
                } else {
                    let h = params.float("height", 0.0, at)?;
                    let m = ctm
                        * DMat4::from_translation(DVec3::new(0.0, 0.0, h))
                        * DMat4::from_scale(DVec3::splat(radius));
                    (ShapeKind::Disk, m, None, None)
                };
                self.out.shapes.push(ShapeDescription {
                    kind: shape,
                    material,
                    center,
                    radius: r,
                    segments: None,
                    subdivisions: None,
                    scale: None,
                    rotate: None,
                    translate: None,
                    matrix: Some(to_rows(matrix)),
                    reverse_winding: self.state.reverse,
                });
            }
            other => {
                for p in &params.list {
                    p.used.set(true);
                }
                return self.unsupported(at, format!("Shape \"{other}\" is not supported: skipped"));
            }
        }
        self.check_unused(&format!("Shape \"{kind}\""), params, at)
    }

    fn light(&mut self, kind: &str, params: &Params, at: &At) -> Result<()> {
        let ctm = self.state.ctm;
        let scale = params.float("scale", 1.0, at)? as f32;
        let constant = |this: &mut Self, name: &str, default: f32| -> Result<[f32; 3]> {
            match this.colour(params, name, [default; 3], at)? {
                Colour::Constant(c) => Ok(c.map(|v| v * scale)),
                Colour::Texture(_) => Err(syntax(at, format!("\"{name}\" of a light cannot be a texture"))),
            }
        };
        if params.get("power").is_some() {
            self.unsupported(at, format!("LightSource \"{kind}\": \"power\" is not supported: its I/L is used"))?;
        }
        match kind {
            "point" => {
                let intensity = constant(self, "I", 1.0)?;
                let from = ctm.transform_point3(params.point("from", DVec3::ZERO, at)?);
                self.out.lights.push(LightDescription::point(from.as_vec3().to_array(), intensity));
            }
            "spot" => {
                let intensity = constant(self, "I", 1.0)?;
                let from = params.point("from", DVec3::ZERO, at)?;
                let to = params.point("to", DVec3::Z, at)?;
                let cone = params.float("coneangle", 30.0, at)?;
                let delta = params.float("conedelta", 5.0, at)?;
                let (p, q) = (ctm.transform_point3(from), ctm.transform_point3(to));
                self.out.lights.push(LightDescription::spot(
                    p.as_vec3().to_array(),
                    intensity,
                    (q - p).as_vec3().to_array(),
                    cone as f32,
                    (cone - delta).max(0.0) as f32,
                ));
            }
            "distant" => {
                let irradiance = constant(self, "L", 1.0)?;
                let from = params.point("from", DVec3::ZERO, at)?;
                let to = params.point("to", DVec3::Z, at)?;
                let direction = ctm.transform_point3(to) - ctm.transform_point3(from);
                params.get("illuminance");
                self.out.lights.push(LightDescription::distant(direction.as_vec3().to_array(), irradiance));
            }
            "infinite" => {
                if self.out.environment.is_some() {
                    return self.unsupported(at, "a second infinite light: ignored".into());
                }
                if let Some(file) = params.text("filename", at)? {
                    // pbrt-v4's maps are equal-area octahedral squares in light space.
                    let rotation = DMat4::from_cols(ctm.x_axis, ctm.y_axis, ctm.z_axis, DVec4::W);
                    self.out.environment = Some(EnvironmentDescription {
                        radiance: None,
                        map: Some(self.resolve(&file).to_string_lossy().into_owned()),
                        scale: Some(scale),
                        layout: Some(MapLayout::EqualArea),
                        matrix: Some(to_rows(rotation)),
                        lookup: None,
                    });
                } else {
                    let radiance = constant(self, "L", 1.0)?;
                    let env = EnvironmentDescription {
                        radiance: Some(radiance),
                        map: None,
                        scale: None,
                        layout: None,
                        matrix: None,
                        lookup: None,
                    };
                    self.out.environment = Some(env);
                }
                params.get("illuminance");
            }
            other => {
                for p in &params.list {
                    p.used.set(true);
                }
                return self.unsupported(at, format!("LightSource \"{other}\" is not supported: ignored"));
            }
        }
        self.check_unused(&format!("LightSource \"{kind}\""), params, at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::description::LightKind;
    use glam::Vec3A;

    fn read(text: &str, strict: bool) -> Result<Imported> {
        import(Path::new("/nowhere/scene.pbrt"), text, &ImportOptions { defines: Vec::new(), strict })
    }

    fn ok(text: &str) -> SceneDescription {
        read(text, true).unwrap().description
    }

    fn message(r: Result<Imported>) -> String {
        match r {
            Err(e) => e.to_string(),
            Ok(_) => panic!("expected an error"),
        }
    }

    #[test]
    fn tokens_comments_and_strings() {
        let file = Rc::new(PathBuf::from("x.pbrt"));
        let t =
            tokenize("Shape \"sphere\" # a comment \"ignored\"\n \"float radius\" [ 2.5e0 ] true\n", &file).unwrap();
        let kinds: Vec<&Token> = t.iter().map(|(t, _)| t).collect();
        assert_eq!(
            kinds,
            [
                &Token::Word("Shape".into()),
                &Token::Text("sphere".into()),
                &Token::Text("float radius".into()),
                &Token::Open,
                &Token::Number(2.5),
                &Token::Close,
                &Token::Word("true".into())
            ]
        );
        assert_eq!(t[2].1, 2, "lines are counted");
        assert!(message_of(tokenize("\"open", &file)).contains("unterminated"));
        assert!(message_of(tokenize("1e999", &file)).contains("not finite"));
    }

    fn message_of<T>(r: Result<T>) -> String {
        match r {
            Err(e) => e.to_string(),
            Ok(_) => panic!("expected an error"),
        }
    }

    /// Transforms compose as pbrt's do (each new one applied first to points), and
    /// AttributeBegin/End restore them; named coordinate systems.
    /// Instances are their object's shapes placed by the instance's transform after the
    /// definition's: the same triangles (to f32 rounding) as the shapes written out in place,
    /// mirrored instances included; an instance may come before its definition.
    #[test]
    fn objects_and_instances() {
        let object = "Translate 0 0 1
                Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]
                Shape \"trianglemesh\" \"point3 P\" [0 0 0 0 1 0 1 0 0] \"normal N\" [0 0 1 0 0 1 0 0 1]
                Shape \"sphere\" \"float radius\" 0.25";
        let placements = ["Translate 5 0 0", "Rotate 30 0 1 0", "Scale -1 1 1"];
        let instanced = format!(
            "WorldBegin
            AttributeBegin {} ObjectInstance \"thing\" AttributeEnd
            ObjectBegin \"thing\" {object} ObjectEnd
            AttributeBegin {} ObjectInstance \"thing\" AttributeEnd
            AttributeBegin {} ObjectInstance \"thing\" AttributeEnd",
            placements[0], placements[1], placements[2]
        );
        let direct: String = std::iter::once("WorldBegin".to_string())
            .chain(placements.iter().map(|p| format!("AttributeBegin {p} {object} AttributeEnd")))
            .collect::<Vec<_>>()
            .join("\n");
        let triangles = |text: &str| {
            let scene =
                crate::scene::Scene::parse_pbrt(text, Path::new("/nowhere/s.pbrt"), &ImportOptions::default()).unwrap();
            let mut t: Vec<([f32; 9], [f32; 3])> = scene
                .triangles
                .iter()
                .enumerate()
                .map(|(i, t)| {
                    let n = scene.attributes.normals.get(i).map_or([0.0; 3], |c| c[0].to_array());
                    (t.map(|p| p.to_array()).concat().try_into().unwrap(), n)
                })
                .collect();
            t.sort_by(|a, b| {
                a.0.iter()
                    .zip(&b.0)
                    .map(|(x, y)| x.total_cmp(y))
                    .find(|o| o.is_ne())
                    .unwrap_or(std::cmp::Ordering::Equal)
            });
            t
        };
        let (a, b) = (triangles(&instanced), triangles(&direct));
        assert_eq!(a.len(), b.len());
        assert!(a.len() > 3 * 2 + 3 * 1000, "the spheres too: {}", a.len());
        for (x, y) in a.iter().zip(&b) {
            let far = x.0.iter().zip(&y.0).chain(x.1.iter().zip(&y.1)).any(|(p, q)| (p - q).abs() > 1e-5);
            assert!(!far, "{x:?} vs {y:?}");
        }
        // Without instances, an object's shapes are not in the scene.
        let d = ok("WorldBegin ObjectBegin \"a\" Shape \"sphere\" ObjectEnd Shape \"disk\"");
        assert_eq!(d.shapes.len(), 1);
        // Mistakes.
        for (text, want) in [
            ("WorldBegin ObjectBegin \"a\" ObjectBegin \"b\"", "inside the definition of \"a\""),
            ("WorldBegin ObjectEnd", "ObjectEnd without an ObjectBegin"),
            ("WorldBegin ObjectBegin \"a\" Shape \"sphere\"", "without an ObjectEnd"),
            ("WorldBegin ObjectBegin \"a\" ObjectInstance \"a\" ObjectEnd", "inside an object's definition"),
            ("WorldBegin Shape \"sphere\" ObjectInstance \"nope\"", "no such object"),
        ] {
            assert!(message(read(text, true)).contains(want), "{text}: {}", message(read(text, true)));
        }
        // Area lights in an object do not emit (as in pbrt-v4), with a warning.
        let r = read(
            "WorldBegin ObjectBegin \"lamp\" AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] Shape \"sphere\" ObjectEnd
             ObjectInstance \"lamp\"",
            false,
        )
        .unwrap();
        assert!(r.warnings.iter().any(|w| w.contains("instances do not emit")), "{:?}", r.warnings);
        assert!(r.description.materials.values().all(|m| m.emission == [0.0; 3]));
    }

    #[test]
    fn transforms_and_attributes() {
        let d = ok("WorldBegin
            AttributeBegin Translate 1 0 0 Scale 2 2 2 Shape \"sphere\" AttributeEnd
            Shape \"sphere\"
            Translate 0 5 0 CoordinateSystem \"up\" Identity CoordSysTransform \"up\" Shape \"sphere\"
            Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  7 8 9 1 ] Shape \"sphere\"");
        let m: Vec<[[f32; 4]; 4]> = d.shapes.iter().map(|s| s.matrix.unwrap()).collect();
        assert_eq!((m[0][0][0], m[0][0][3]), (2.0, 1.0), "x ↦ 2x + 1");
        assert_eq!(m[1][0], [1.0, 0.0, 0.0, 0.0], "restored");
        assert_eq!(m[2][1][3], 5.0);
        assert_eq!((m[3][0][3], m[3][1][3], m[3][2][3]), (7.0, 8.0, 9.0), "Transform's numbers are columns");
        assert!(message(read("AttributeEnd", false)).contains("without a matching begin"));
    }

    #[test]
    fn camera_film_sampler_integrator() {
        let d = ok("LookAt 0 0 5  0 0 0  0 1 0
            Camera \"perspective\" \"float fov\" 60
            Film \"rgb\" \"integer xresolution\" 200 \"integer yresolution\" 400 \"float cropwindow\" [ 0.25 0.75 0 0.5 ]
            Sampler \"halton\" \"integer pixelsamples\" 32
            Integrator \"volpath\" \"integer maxdepth\" 3
            WorldBegin");
        let c = &d.camera;
        assert_eq!((c.width, c.height, c.eye), (200, 400, [0.0, 0.0, 5.0]));
        // 60° across the shorter side (the width): tan(fov_y/2) = tan 30° · 400/200.
        let want = (2.0 * (30f64.to_radians().tan() * 2.0).atan()).to_degrees();
        assert!((f64::from(c.fov_y) - want).abs() < 1e-4, "{} vs {want}", c.fov_y);
        assert!(c.mirror, "pbrt's LookAt leaves a left-handed image");
        assert_eq!(c.crop, Some([50, 0, 100, 200]));
        let r = d.render.unwrap();
        assert_eq!((r.spp, r.max_depth), (Some(32), Some(4)));
        let d = ok("WorldBegin");
        assert_eq!((d.camera.width, d.camera.height, d.camera.fov_y), (1280, 720, 90.0), "pbrt's defaults");
    }

    /// Materials we approximate: mix by its likelier material, coatedconductor by its
    /// conductor, diffusetransmission by its reflection; each with a warning.
    #[test]
    fn approximated_materials() {
        let r = read(
            "WorldBegin
            MakeNamedMaterial \"a\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.1 0.2 0.3]
            MakeNamedMaterial \"b\" \"string type\" \"dielectric\"
            MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [\"a\" \"b\"] \"float amount\" 0.25
            NamedMaterial \"m\" Shape \"sphere\"
            Material \"coatedconductor\" \"spectrum conductor.eta\" \"metal-Au-eta\" \"spectrum conductor.k\" \"metal-Au-k\"
                \"float conductor.roughness\" 0.04 \"float interface.roughness\" 0
            Shape \"sphere\"
            Material \"diffusetransmission\" \"rgb reflectance\" [0.4 0.4 0.4] \"rgb transmittance\" [0.5 0.5 0.5]
            Shape \"sphere\"",
            false,
        )
        .unwrap();
        let d = &r.description;
        let m = |i: usize| &d.materials[&d.shapes[i].material];
        assert_eq!((m(0).kind, m(0).diffuse), (MaterialKind::Diffuse, [0.1, 0.2, 0.3]), "amount 0.25: the first");
        assert_eq!(
            (m(1).kind, m(1).metal.as_deref(), m(1).roughness),
            (MaterialKind::Conductor, Some("Au"), Some(0.2))
        );
        assert_eq!((m(2).kind, m(2).diffuse), (MaterialKind::Diffuse, [0.4; 3]));
        assert_eq!(r.warnings.len(), 3, "{:?}", r.warnings);
        let e = message(read("WorldBegin Material \"mix\" \"string materials\" [\"x\" \"y\"]", false));
        assert!(e.contains("no named material \"x\""), "{e}");
    }

    #[test]
    fn pixel_filters() {
        let filter = |f: &str| ok(&format!("{f} WorldBegin Shape \"sphere\"")).camera.filter.unwrap();
        let gaussian = |s: f32, r: f32| PixelFilterDescription {
            kind: PixelFilterKind::Gaussian,
            stddev: Some(s),
            radius: Some([r; 2]),
        };
        assert_eq!(filter(""), gaussian(0.5, 1.5), "pbrt-v4's default");
        assert_eq!(
            filter("PixelFilter \"gaussian\" \"float sigma\" 0.25 \"float xradius\" 1 \"float yradius\" 1"),
            gaussian(0.25, 1.0)
        );
        let f = filter("PixelFilter \"box\"");
        assert_eq!((f.kind, f.radius), (PixelFilterKind::Box, Some([0.5; 2])));
        let f = filter("PixelFilter \"triangle\" \"float yradius\" 1");
        assert_eq!((f.kind, f.radius), (PixelFilterKind::Tent, Some([2.0, 1.0])));
        let r = read("PixelFilter \"mitchell\" \"float B\" 0.3 WorldBegin Shape \"sphere\"", false).unwrap();
        assert_eq!(r.description.camera.filter, Some(gaussian(0.5, 1.5)));
        assert!(r.warnings[0].contains("mitchell"), "{:?}", r.warnings);
    }

    #[test]
    fn scaled_and_inverted_textures() {
        let d = ok("WorldBegin
            Texture \"img\" \"spectrum\" \"imagemap\" \"string filename\" \"a.png\" \"float scale\" 0.5 \"bool invert\" true
            Texture \"plain\" \"spectrum\" \"imagemap\" \"string filename\" \"b.png\"
            Texture \"dim\" \"spectrum\" \"scale\" \"texture tex\" \"plain\" \"rgb scale\" [0.25 0.5 1]
            Texture \"dimmer\" \"spectrum\" \"scale\" \"float tex\" 0.5 \"texture scale\" \"dim\"
            Texture \"grey\" \"spectrum\" \"scale\" \"rgb tex\" [0.2 0.4 0.6] \"float scale\" 0.5
            Texture \"r\" \"float\" \"imagemap\" \"string filename\" \"r.png\"
            Texture \"r2\" \"float\" \"scale\" \"texture tex\" \"r\" \"float scale\" 2");
        let t = |file: &str, factor: Option<[f32; 3]>| {
            d.textures.values().any(|t| t.file.as_deref().is_some_and(|f| f.ends_with(file)) && t.factor == factor)
        };
        assert!(d.textures.values().any(|t| t.factor == Some([0.5; 3]) && t.invert == Some(true)));
        assert!(t("b.png", None) && t("b.png", Some([0.25, 0.5, 1.0])) && t("b.png", Some([0.125, 0.25, 0.5])));
        assert!(t("r.png", Some([2.0; 3])), "a float texture scaled");
        assert!(d.textures.values().any(|t| t.color0 == Some([0.1, 0.2, 0.3])), "constants fold");
        let e = message(read("WorldBegin Texture \"s\" \"float\" \"scale\" \"texture tex\" \"nope\"", false));
        assert!(e.contains("no such texture \"nope\""), "{e}");
    }

    /// Curves become triangles (one mesh per material however many directives), placed by
    /// the transform with their width scaled; hair is a diffuse colour from its melanin.
    #[test]
    fn curves_and_hair() {
        let r = read(
            "WorldBegin
            MakeNamedMaterial \"h\" \"string type\" \"hair\" \"float eumelanin\" 0.2
            NamedMaterial \"h\"
            Translate 0 0 5
            Scale 2 2 2
            Shape \"curve\" \"string type\" \"cylinder\" \"string basis\" \"bspline\" \"point3 P\" [0 0 0 0 0 1 0 0 2 0 0 3 0 0 4] \"float width\" 0.1
            Shape \"curve\" \"point3 P\" [1 0 0 1 0 1 1 0 2 1 0 3] \"float width0\" 0.1 \"float width1\" 0
            Material \"diffuse\"
            Shape \"curve\" \"string type\" \"ribbon\" \"point3 P\" [2 0 0 2 0 1 2 0 2 2 0 3] \"normal N\" [1 0 0 1 0 0]",
            false,
        )
        .unwrap();
        let d = &r.description;
        assert_eq!(d.inline_meshes.len(), 2, "one mesh per material");
        let hair = &d.inline_meshes[0];
        assert!(!hair.indices.is_empty() && hair.indices.len().is_multiple_of(3));
        for p in &hair.positions {
            // Placed: z from 5 to 13, x near 0 (first curve) or 2 (second), radius ≤ 0.1.
            assert!(p[2] >= 4.9 && p[2] <= 13.1, "{p:?}");
            assert!(p[0].abs() <= 0.11 || (p[0] - 2.0).abs() <= 0.11, "{p:?}");
        }
        let colour = d.materials[&hair.material].diffuse;
        // Eumelanin 0.2: σa = 0.2 × (0.419, 0.697, 1.37); at βn 0.3, c = exp(−√σa · 5.888).
        for (c, eu) in colour.iter().zip([0.419f64, 0.697, 1.37]) {
            let want = (-(0.2 * eu).sqrt() * 5.888_29).exp() as f32;
            assert!((c - want).abs() < 1e-4, "{colour:?}");
        }
        assert!(r.warnings.iter().any(|w| w.contains("hair")) && r.warnings.iter().any(|w| w.contains("flat curves")));
        assert_eq!(r.warnings.iter().filter(|w| w.contains("flat curves")).count(), 1);
        for (body, want) in [
            ("Shape \"curve\" \"string basis\" \"catmull\" \"point3 P\" [0 0 0 0 0 1 0 0 2 0 0 3]", "basis"),
            ("Shape \"curve\" \"point3 P\" [0 0 0 0 0 1 0 0 2]", "control points"),
            ("Shape \"curve\" \"string type\" \"ribbon\" \"point3 P\" [0 0 0 0 0 1 0 0 2 0 0 3]", "normal"),
            ("Shape \"curve\" \"integer degree\" 5 \"point3 P\" [0 0 0 0 0 1 0 0 2 0 0 3]", "degree"),
        ] {
            let e = message(read(&format!("WorldBegin {body}"), false));
            assert!(e.contains(want), "{body}: {e}");
        }
    }

    #[test]
    fn materials_textures_and_area_lights() {
        let d = ok("WorldBegin
            Texture \"t\" \"float\" \"imagemap\" \"string filename\" \"r.png\"
            MakeNamedMaterial \"m\" \"string type\" \"conductor\" \"spectrum eta\" \"metal-Ag-eta\" \"spectrum k\" \"metal-Ag-k\"
                \"texture roughness\" \"t\" \"bool remaproughness\" false
            NamedMaterial \"m\"
            Shape \"sphere\"
            AttributeBegin
              AreaLightSource \"diffuse\" \"rgb L\" [ 1 2 3 ] \"float scale\" 2 \"bool twosided\" true
              Material \"dielectric\" \"spectrum eta\" \"glass-BK7\" \"float roughness\" 0.01
              Shape \"disk\"
            AttributeEnd
            Shape \"disk\"");
        let m = |i: usize| &d.materials[&d.shapes[i].material];
        assert_eq!((m(0).kind, m(0).metal.as_deref()), (MaterialKind::Conductor, Some("Ag")));
        assert!(m(0).roughness_texture.is_some());
        assert_eq!((m(1).kind, m(1).ior, m(1).roughness), (MaterialKind::Dielectric, Some(1.5168), Some(0.1)));
        assert_eq!((m(1).emission, m(1).two_sided_emission), ([2.0, 4.0, 6.0], true));
        assert_eq!(m(2).emission, [0.0; 3], "the area light ends with its attribute block");
        assert!(d.textures.values().next().unwrap().file.as_deref().unwrap().ends_with("r.png"));
    }

    #[test]
    fn lights() {
        let d = ok("WorldBegin
            Translate 0 1 0
            LightSource \"point\" \"rgb I\" [ 1 2 3 ] \"float scale\" 2
            LightSource \"spot\" \"point3 from\" [ 0 0 0 ] \"point3 to\" [ 0 -1 0 ] \"float coneangle\" 40 \"float conedelta\" 10
            LightSource \"distant\" \"point3 from\" [ 0 1 0 ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ 3 3 3 ]
            LightSource \"infinite\" \"spectrum L\" [ 400 1 700 1 ]");
        let l = &d.lights;
        assert_eq!(
            (l[0].kind, l[0].position, l[0].intensity),
            (LightKind::Point, Some([0.0, 1.0, 0.0]), Some([2.0, 4.0, 6.0]))
        );
        assert_eq!(
            (l[1].kind, l[1].direction, l[1].cutoff, l[1].beam),
            (LightKind::Spot, Some([0.0, -1.0, 0.0]), Some(40.0), Some(30.0))
        );
        assert_eq!(
            (l[2].kind, l[2].direction, l[2].irradiance),
            (LightKind::Distant, Some([0.0, -1.0, 0.0]), Some([3.0; 3]))
        );
        // A light's spectrum is normalised to luminance 1.
        let env = d.environment.unwrap().radiance.unwrap();
        let y = 0.2126 * env[0] + 0.7152 * env[1] + 0.0722 * env[2];
        assert!((y - 1.0).abs() < 1e-4, "{env:?}");
    }

    #[test]
    fn unsupported_warns_or_fails() {
        let text = "WorldBegin\nShape \"sphere\" \"float zmax\" 0.5\nLightSource \"goniometric\" \"rgb I\" [1 1 1]\nMaterial \"measured\"\nShape \"cylinder\"\n";
        let r = read(text, false).unwrap();
        assert_eq!(r.warnings.len(), 4, "{:?}", r.warnings);
        assert!(r.warnings[0].starts_with("/nowhere/scene.pbrt:2:") && r.warnings[0].contains("partial"));
        assert!(r.warnings[1].contains("goniometric") && r.warnings[2].contains("grey diffuse"));
        let e = message(read(text, true));
        assert!(e.contains("line 2") && e.contains("--strict"), "{e}");
        let r = read("WorldBegin Shape \"sphere\" \"float radius\" 2 \"float nonsense\" 3", false).unwrap();
        assert!(r.warnings[0].contains("nonsense"), "{:?}", r.warnings);
    }

    #[test]
    fn malformed_files_are_one_error() {
        for (text, want) in [
            ("Translate 1 2", "expected a number"),
            ("Bogus 1", "unknown directive"),
            ("WorldBegin Shape \"sphere\" \"float radius\" [ 1 ", "expected a value"),
            ("WorldBegin Shape \"sphere\" \"floaty radius\" 1", "unknown parameter type"),
            (
                "WorldBegin Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 5]",
                "out of range",
            ),
            ("WorldBegin NamedMaterial \"nope\"", "no such material"),
            ("Rotate 10 0 0 0", "axis"),
            ("Camera \"orthographic\"", "perspective"),
        ] {
            let e = message(read(text, false));
            assert!(e.contains(want), "{text}: {e}");
        }
    }

    /// pbrt-v4's equal-area map: the poles at the centre and the corners, the equator on the
    /// diamond, and every direction inside the square.
    #[test]
    fn equal_area_square() {
        use crate::geometry::warp::equal_area_sphere_to_square as f;
        assert!((f(Vec3A::Z) - glam::Vec2::splat(0.5)).length() < 1e-6);
        let south = f(-Vec3A::Z);
        assert!([south.x, south.y].iter().all(|c| *c == 0.0 || *c == 1.0), "the south pole at a corner: {south}");
        assert!((f(Vec3A::X) - glam::Vec2::new(1.0, 0.5)).length() < 1e-6);
        for k in 0..100 {
            let d = Vec3A::new((k as f32 * 0.7).sin(), (k as f32 * 1.3).cos(), (k as f32 * 0.37).sin()).normalize();
            let uv = f(d);
            assert!((0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y));
        }
    }
}
