//! Participating media: `<medium type="homogeneous">` (`albedo`, `sigma_t`, `scale`, an
//! `isotropic` or `hg` phase), referenced or nested as a shape's `interior` and `exterior` and
//! inside the sensor. Other kinds are warned about and leave vacuum.
use super::*;
use crate::scene::description::MediumDescription;

impl Translator<'_, '_> {
    /// The description's name of the medium a shape or sensor gives as parameter `name` (a
    /// `<ref name=…>` or a nested `<medium name=…>`), if any.
    pub(super) fn medium_param(&mut self, obj: &Obj, name: &str) -> Result<Option<String>> {
        let medium = match obj.param(name) {
            None => return Ok(None),
            Some((_, Value::Ref(id), at)) => self.resolve_ref(id, at)?.clone(),
            Some((_, Value::Object(o), _)) => (**o).clone(),
            Some((_, _, at)) => return Err(syntax(at, format!("`{name}` must be a <medium>"))),
        };
        self.medium(&medium)
    }

    /// The sensor's medium: a `<ref>` to a medium or a nested `<medium>` among its children.
    pub(super) fn child_medium(&mut self, child: &Child) -> Result<Option<Option<String>>> {
        let medium = match child {
            Child::Obj(o) if o.tag == "medium" => o.clone(),
            Child::Ref(id, at) => {
                let o = self.resolve_ref(id, at)?;
                if o.tag != "medium" {
                    return Ok(None);
                }
                o.clone()
            }
            _ => return Ok(None),
        };
        self.medium(&medium).map(Some)
    }

    /// Translates medium `m` once (media with an id are shared); `None` for vacuum.
    fn medium(&mut self, m: &Obj) -> Result<Option<String>> {
        if m.tag != "medium" {
            return Err(syntax(&m.at, format!("a <{}> where a <medium> belongs", m.tag)));
        }
        if let Some(key) = m.id.as_ref().and_then(|id| self.media.get(id)) {
            return Ok(key.clone());
        }
        let key = self.new_medium(m)?;
        if let Some(id) = &m.id {
            self.media.insert(id.clone(), key.clone());
        }
        Ok(key)
    }

    fn new_medium(&mut self, m: &Obj) -> Result<Option<String>> {
        if m.plugin != "homogeneous" {
            self.unsupported(&m.at, format!("<medium type=\"{}\"> is not supported: vacuum used", m.plugin))?;
            return Ok(None);
        }
        self.check_params(m, &["albedo", "sigma_t", "scale", "sample_emitted"])?;
        let albedo = self.constant_colour(m, "albedo", [0.75; 3])?;
        let sigma_t = self.constant_colour(m, "sigma_t", [1.0; 3])?;
        let scale = self.float(m, "scale", 1.0)? as f32;
        let mut g = 0.0;
        for child in &m.children {
            let phase = match child {
                Child::Obj(o) => o.clone(),
                Child::Ref(id, at) => self.resolve_ref(id, at)?.clone(),
            };
            match (phase.tag.as_str(), phase.plugin.as_str()) {
                ("phase", "isotropic") => self.check_params(&phase, &[])?,
                ("phase", "hg") => {
                    self.check_params(&phase, &["g"])?;
                    g = self.float(&phase, "g", 0.8)? as f32;
                }
                ("phase", other) => {
                    self.unsupported(&phase.at, format!("<phase type=\"{other}\"> is not supported: isotropic used"))?;
                }
                (other, _) => {
                    self.unsupported(&phase.at, format!("a <{other}> inside a medium is not supported: ignored"))?;
                }
            }
        }
        let sigma_s: [f32; 3] = std::array::from_fn(|c| albedo[c] * sigma_t[c]);
        let sigma_a: [f32; 3] = std::array::from_fn(|c| (1.0 - albedo[c]) * sigma_t[c]);
        let name = self.fresh("medium");
        self.out.media.insert(name.clone(), MediumDescription { sigma_a, sigma_s, scale: Some(scale), g: Some(g) });
        Ok(Some(name))
    }
}
