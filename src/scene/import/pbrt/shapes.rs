//! Shapes (meshes, PLY files, spheres, disks, curves) with their materials and area lights, and objects and their instances.
use super::Parser;
use super::state::MAX_ATTRIBUTE_DEPTH;
use super::tokens::{Cursor, Params};
use crate::error::Result;
use crate::scene::description::{InlineMesh, MeshDescription, ShapeDescription, ShapeKind};
use crate::scene::import::{At, Prototype, syntax, to_rows};
use glam::{DMat4, DVec3};

impl Parser<'_> {
    /// `Shape`.
    pub(super) fn shape_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        match d {
            "Shape" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                self.shape(&kind, &params, at)?;
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// Objects and their instances.
    pub(super) fn object_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        match d {
            "ObjectBegin" => {
                let name = c.text(d)?;
                if let Some((open, _, _)) = &self.defining {
                    return Err(syntax(at, format!("ObjectBegin \"{name}\" inside the definition of \"{open}\"")));
                }
                if self.stack.len() >= MAX_ATTRIBUTE_DEPTH {
                    return Err(syntax(at, format!("{d} nests deeper than {MAX_ATTRIBUTE_DEPTH}")));
                }
                // As pbrt-v4: an attribute block of its own, shapes without area lights.
                self.stack.push((self.state.clone(), at.clone()));
                self.defining = Some((name, Prototype::mark(&self.out), at.clone()));
            }
            "ObjectEnd" => {
                let (name, mark, _) =
                    self.defining.take().ok_or_else(|| syntax(at, "ObjectEnd without an ObjectBegin"))?;
                self.state = self.stack.pop().ok_or_else(|| syntax(at, "ObjectEnd without a matching begin"))?.0;
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
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// The material a shape declared now gets: the current one, made emitting by the area
    /// light in force, bounding the media of the `MediumInterface` in force when they differ.
    pub(super) fn shape_material(&mut self) -> Result<String> {
        let material = self.emitting_material()?;
        let media = self.state.media.clone();
        if media[0] == media[1] {
            return Ok(material);
        }
        let key = (material, media);
        if let Some(name) = self.bounding.get(&key) {
            return Ok(name.clone());
        }
        let mut m = self.out.materials.get(&key.0).cloned().unwrap_or_default();
        [m.interior_medium, m.exterior_medium] = key.1.clone();
        let name = self.fresh("bounding");
        self.out.materials.insert(name.clone(), m);
        if let Some(o) = self.out.origins.get(&format!("material {}", key.0)).cloned() {
            self.out.origins.insert(format!("material {name}"), o);
        }
        self.bounding.insert(key, name.clone());
        Ok(name)
    }

    /// The current material, made emitting by the area light in force.
    fn emitting_material(&mut self) -> Result<String> {
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
        self.out.origins.insert(format!("material {name}"), light.origin.clone());
        self.emitting.insert(key, name.clone());
        Ok(name)
    }

    /// A `curve` (hair, fur): tessellated into triangles (see [`crate::scene::mesh::curves`]), in
    /// world space, its width scaled as the transform scales volumes.
    pub(super) fn curve(&mut self, params: &Params, at: &At) -> Result<()> {
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

    pub(super) fn shape(&mut self, kind: &str, params: &Params, at: &At) -> Result<()> {
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
                let ply = self.resolve(&file).to_string_lossy().into_owned();
                self.out.origins.entry(format!("mesh {ply}")).or_insert_with(|| (at.file.to_path_buf(), at.line));
                self.out.meshes.push(MeshDescription {
                    obj: None,
                    ply: Some(ply),
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
}

/// Tessellated curves as an inline mesh of `material`.
pub(super) fn curve_mesh(mesh: crate::scene::mesh::curves::CurveMesh, material: String, origin: String) -> InlineMesh {
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
