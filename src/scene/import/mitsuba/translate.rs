//! The second stage: ids registered before anything is translated (so a `<ref>` may precede
//! its object), the scene's objects dispatched to their plugins, and the typed readers of
//! parameters (numbers, colours, transforms) every plugin uses.
use super::*;

impl Translator<'_, '_> {
    pub(super) fn fresh(&mut self, prefix: &str) -> String {
        self.count += 1;
        format!("{prefix}{}", self.count)
    }

    pub(super) fn unsupported(&mut self, at: &At, message: String) -> Result<()> {
        self.reader.unsupported(at, message)
    }

    /// Warns about every parameter of `obj` outside `known`.
    pub(super) fn check_params(&mut self, obj: &Obj, known: &[&str]) -> Result<()> {
        for (name, _, at) in &obj.params {
            if !known.contains(&name.as_str()) {
                let message =
                    format!("<{} type=\"{}\">: parameter `{name}` is not supported: ignored", obj.tag, obj.plugin);
                self.reader.unsupported(at, message)?;
            }
        }
        Ok(())
    }

    pub(super) fn resolve_ref<'a>(&'a self, id: &str, at: &At) -> Result<&'a Obj> {
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

    pub(super) fn translate(&mut self, scene: &Obj) -> Result<()> {
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
                "bsdf" | "texture" | "medium" | "phase" => {}
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

    pub(super) fn float(&mut self, obj: &Obj, name: &str, default: f64) -> Result<f64> {
        match obj.param(name) {
            None => Ok(default),
            Some((_, Value::Float(v), _)) => Ok(*v),
            Some((_, Value::Integer(v), _)) => Ok(*v as f64),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be a number"))),
        }
    }

    pub(super) fn integer(&mut self, obj: &Obj, name: &str, default: i64) -> Result<i64> {
        match obj.param(name) {
            None => Ok(default),
            Some((_, Value::Integer(v), _)) => Ok(*v),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be an <integer>"))),
        }
    }

    pub(super) fn boolean(&mut self, obj: &Obj, name: &str, default: bool) -> Result<bool> {
        match obj.param(name) {
            None => Ok(default),
            Some((_, Value::Boolean(v), _)) => Ok(*v),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be a <boolean>"))),
        }
    }

    pub(super) fn text(&mut self, obj: &Obj, name: &str) -> Result<Option<String>> {
        match obj.param(name) {
            None => Ok(None),
            Some((_, Value::Text(v), _)) => Ok(Some(v.clone())),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be a <string>"))),
        }
    }

    pub(super) fn transform(&mut self, obj: &Obj, name: &str) -> Result<DMat4> {
        match obj.param(name) {
            None => Ok(DMat4::IDENTITY),
            Some((_, Value::Transform(m), _)) => Ok(*m),
            Some((_, _, at)) => Err(syntax(at, format!("`{name}` must be a <transform>"))),
        }
    }

    /// A colour parameter: a constant, or a texture (its name among the scene's textures).
    pub(super) fn colour(
        &mut self,
        obj: &Obj,
        name: &str,
        default: [f32; 3],
    ) -> Result<(Option<[f32; 3]>, Option<String>)> {
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
    pub(super) fn constant_colour(&mut self, obj: &Obj, name: &str, default: [f32; 3]) -> Result<[f32; 3]> {
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
}
