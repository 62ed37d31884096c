//! Emitters other than area lights: point, spot, directional, constant and `envmap`.
use super::*;

impl Translator<'_, '_> {
    /// An emitter outside a shape: a light or the environment; the lights it adds are located
    /// at its element.
    pub(super) fn emitter(&mut self, e: &Obj) -> Result<()> {
        let before = self.out.lights.len();
        self.emitter_here(e)?;
        for k in before..self.out.lights.len() {
            self.out.origins.insert(format!("light {}", k + 1), (e.at.file.to_path_buf(), e.at.line));
        }
        Ok(())
    }

    fn emitter_here(&mut self, e: &Obj) -> Result<()> {
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
                let env = EnvironmentDescription::constant(radiance);
                self.environment(e, env)?;
            }
            "envmap" => {
                self.check_params(e, &["filename", "scale", "to_world"])?;
                let file = self.text(e, "filename")?.ok_or_else(|| syntax(&e.at, "an envmap needs `filename`"))?;
                let scale = self.float(e, "scale", 1.0)? as f32;
                // Mitsuba's map space is ours (+y up, u = atan2(x, −z)/2π): its rotation
                // carries over.
                let rotation = DMat4::from_cols(to_world.x_axis, to_world.y_axis, to_world.z_axis, DVec4::W);
                let map = resolve(&self.reader.includes.files[0], &e.at.file, &file).to_string_lossy().into_owned();
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
}
