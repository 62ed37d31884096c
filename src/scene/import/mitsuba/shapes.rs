//! Shapes: meshes (`obj`, `ply`) and canonical shapes with one material each, `shapegroup`s
//! and their `instance`s.
use super::*;

impl Translator<'_, '_> {
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
    pub(super) fn shape(&mut self, s: &Obj) -> Result<()> {
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
        material.interior_medium = self.medium_param(s, "interior")?;
        material.exterior_medium = self.medium_param(s, "exterior")?;
        let name = self.fresh("material");
        let to_world = self.transform(s, "to_world")?;
        let flip = self.boolean(s, "flip_normals", false)?;
        let matrix = to_rows(to_world);
        match s.plugin.as_str() {
            "obj" | "ply" => {
                self.check_params(
                    s,
                    &[
                        "filename",
                        "to_world",
                        "flip_normals",
                        "face_normals",
                        "flip_tex_coords",
                        "interior",
                        "exterior",
                    ],
                )?;
                let file = self.text(s, "filename")?.ok_or_else(|| syntax(&s.at, "a mesh shape needs `filename`"))?;
                // Mitsuba gives a mesh without normals smooth ones, unless `face_normals`
                // (which also drops the file's).
                let face_normals = self.boolean(s, "face_normals", false)?;
                // Mitsuba flips an OBJ's `v` by default (its bitmaps start at the top).
                let flip_v = s.plugin == "obj" && self.boolean(s, "flip_tex_coords", true)?;
                let path = resolve(&self.reader.includes.files[0], &s.at.file, &file).to_string_lossy().into_owned();
                self.out.origins.entry(format!("mesh {path}")).or_insert_with(|| (s.at.file.to_path_buf(), s.at.line));
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
                    self.check_params(s, &["to_world", "flip_normals", "center", "radius", "interior", "exterior"])?;
                    if let Some((_, v, at)) = s.param("center") {
                        let Value::Vector(c) = v else { return Err(syntax(at, "`center` must be a <point>")) };
                        center = Some(c.as_vec3().to_array());
                    }
                    radius = Some(self.float(s, "radius", 1.0)? as f32);
                } else {
                    self.check_params(s, &["to_world", "flip_normals", "interior", "exterior"])?;
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
        self.out.origins.insert(format!("material {name}"), (s.at.file.to_path_buf(), s.at.line));
        self.out.materials.insert(name, material);
        Ok(())
    }
}
