//! The first stage: the XML file and its includes read into a tree of objects, `<default>`s
//! and `-D` values substituted, every value and transform parsed where it stands.
use super::*;

/// Longest attribute value `$name` substitution may make (a scene file is at most 16 MiB).
const MAX_SUBSTITUTED_BYTES: usize = 1 << 24;

impl Reader<'_> {
    /// A warning, or with `--strict` the error it would be.
    pub(super) fn unsupported(&mut self, at: &At, message: String) -> Result<()> {
        unsupported(self.options.strict, &mut self.warnings, at, message)
    }

    /// Parses the document at `path` (text `text`) into its root `<scene>` object.
    pub(super) fn read_document(&mut self, path: &Path, text: &str) -> Result<Obj> {
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

    /// `$name` (or `${name}`) replaced by the `-D` value or `<default>`; at most
    /// [`MAX_SUBSTITUTED_BYTES`] in all.
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
            // Defaults may name defaults: doubling at each of 40 levels would reach terabytes.
            if out.len() + value.len() > MAX_SUBSTITUTED_BYTES {
                return Err(syntax(
                    at,
                    format!("substituting `${name}` makes a value longer than {MAX_SUBSTITUTED_BYTES} bytes"),
                ));
            }
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
                    let path = resolve(&self.includes.files[0], file, &name);
                    let text = self.includes.enter(&name, &path, &at)?;
                    let included = self.read_document(&path, &text)?;
                    self.includes.leave();
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
                    let rgb = crate::color::spectrum_to_rgb(&points, in_emitter).ok_or_else(|| {
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
    pub(super) fn transform(
        &mut self,
        doc: &roxmltree::Document,
        node: roxmltree::Node,
        file: &Rc<PathBuf>,
    ) -> Result<DMat4> {
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
pub(super) fn resolve(main: &Path, from: &Path, name: &str) -> PathBuf {
    let folder = |p: &Path| p.parent().unwrap_or(Path::new(".")).to_path_buf();
    let candidates = [folder(main).join(name), folder(from).join(name)];
    let path = candidates.iter().find(|p| p.exists()).unwrap_or(&candidates[0]).clone();
    std::path::absolute(&path).unwrap_or(path)
}
