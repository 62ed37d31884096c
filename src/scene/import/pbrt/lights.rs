//! Area lights and light sources.
use super::state::AreaLight;
use super::tokens::{Cursor, Params};
use super::{Colour, Parser};
use crate::error::Result;
use crate::scene::description::{EnvironmentDescription, LightDescription, MapLayout};
use crate::scene::import::{At, syntax, to_rows};
use glam::{DMat4, DVec3, DVec4};

impl Parser<'_> {
    /// `AreaLightSource` and `LightSource`; the lights it adds are located at `at`.
    pub(super) fn light_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        let before = self.out.lights.len();
        let known = self.light_directive_here(d, c, at)?;
        for k in before..self.out.lights.len() {
            self.out.origins.insert(format!("light {}", k + 1), (at.file.to_path_buf(), at.line));
        }
        Ok(known)
    }

    fn light_directive_here(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        match d {
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
                self.state.area_light = Some(AreaLight {
                    radiance: radiance.map(|v| v * scale),
                    two_sided,
                    origin: (at.file.to_path_buf(), at.line),
                });
            }
            "LightSource" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                self.light(&kind, &params, at)?;
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    pub(super) fn light(&mut self, kind: &str, params: &Params, at: &At) -> Result<()> {
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
                    let env = EnvironmentDescription::constant(radiance);
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
