//! The directives before `WorldBegin`: camera, film, sampler, integrator, pixel filter; and the camera made once the whole file is read.
use super::Parser;
use super::shapes::curve_mesh;
use super::tokens::{Cursor, Params};
use crate::error::Result;
use crate::scene::description::{CameraDescription, PixelFilterDescription, PixelFilterKind, RenderDescription};
use crate::scene::import::{At, MAX_INSTANCED_TRIANGLES, syntax};
use glam::{DMat4, DVec3};
use std::rc::Rc;

impl Parser<'_> {
    /// Camera, film, sampler, integrator and pixel filter.
    pub(super) fn option_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        // pbrt-v4 reads the rendering options before `WorldBegin` only (it refuses them after).
        if self.in_world && matches!(d, "Camera" | "Film" | "Sampler" | "Integrator" | "PixelFilter" | "Accelerator") {
            return Err(syntax(at, format!("{d} after WorldBegin: rendering options come before it")));
        }
        match d {
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
                let Some(n) = u32::try_from(n).ok().filter(|&n| n >= 1) else {
                    return Err(syntax(at, format!("pixelsamples must lie in 1..={}, got {n}", u32::MAX)));
                };
                params.get("seed");
                params.get("randomization");
                self.out.render.get_or_insert_with(RenderDescription::default).spp = Some(n);
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
            _ => return Ok(false),
        }
        Ok(true)
    }

    pub(super) fn camera_directive(&mut self, kind: &str, params: &Params, at: &At) -> Result<()> {
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
        self.camera_medium = self.state.media[1].clone();
        Ok(())
    }

    /// The camera and film, once the whole file is read.
    pub(super) fn finish(&mut self) -> Result<()> {
        if let Some((name, _, at)) = &self.defining {
            return Err(syntax(at, format!("ObjectBegin \"{name}\" without an ObjectEnd")));
        }
        // pbrt-v4 refuses a scene that ends inside a block.
        if let Some((_, at)) = self.stack.last() {
            return Err(syntax(
                at,
                "this block (AttributeBegin or TransformBegin) is not closed before the scene ends",
            ));
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
        let default_at = At { file: Rc::new(self.includes.files[0].clone()), line: 1 };
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
            medium: self.camera_medium.clone(),
        };
        if let Some([x0, x1, y0, y1]) = crop {
            // pbrt: pixels ceil(res·min) up to ceil(res·max).
            let px = |f: f64, n: f64| (n * f.clamp(0.0, 1.0)).ceil() as u32;
            let (a, b, c, d) = (px(x0.min(x1), wf), px(x0.max(x1), wf), px(y0.min(y1), hf), px(y0.max(y1), hf));
            self.out.camera.crop = Some([a, c, b.saturating_sub(a), d.saturating_sub(c)]);
        }
        Ok(())
    }
}
