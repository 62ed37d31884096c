//! pbrt-v4's participating media: `MakeNamedMedium` (homogeneous media; the other kinds are
//! warned about and leave vacuum), `MediumInterface` (the media inside and outside the shapes
//! that follow; the outside one is the camera's when `Camera` is declared).
use super::Parser;
use super::tokens::{Cursor, Params, Token, Values};
use crate::error::Result;
use crate::scene::description::MediumDescription;
use crate::scene::import::{At, syntax};

/// pbrt-v4's homogeneous medium when neither coefficients nor a preset are given.
const DEFAULT_SIGMA_A: [f32; 3] = [0.0011, 0.0024, 0.014];
const DEFAULT_SIGMA_S: [f32; 3] = [2.55, 3.21, 3.77];

impl Parser<'_> {
    pub(super) fn medium_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        match d {
            "MakeNamedMedium" => {
                let name = c.text(d)?;
                let params = c.params()?;
                let described = self.medium(&name, &params, at)?;
                self.check_unused(&format!("MakeNamedMedium \"{name}\""), &params, at)?;
                let key = described.map(|m| {
                    let key = format!("medium:{name}");
                    self.out.media.insert(key.clone(), m);
                    key
                });
                self.media.insert(name, key);
            }
            "MediumInterface" => {
                let inside = c.text(d)?;
                // One name: the same medium on both sides.
                let outside = if let Some(Token::Text(_)) = c.peek() { c.text(d)? } else { inside.clone() };
                self.state.media = [self.medium_key(&inside, at)?, self.medium_key(&outside, at)?];
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// The description of medium `name`, or `None` (with a warning) for a kind we do not
    /// render: the space it fills is then vacuum.
    fn medium(&mut self, name: &str, params: &Params, at: &At) -> Result<Option<MediumDescription>> {
        let kind = params.text("type", at)?.ok_or_else(|| syntax(at, format!("medium \"{name}\" has no \"type\"")))?;
        if kind != "homogeneous" {
            for p in &params.list {
                p.used.set(true);
            }
            self.unsupported(at, format!("medium \"{name}\": type \"{kind}\" is not supported: vacuum used"))?;
            return Ok(None);
        }
        if let Some(preset) = params.text("preset", at)? {
            self.unsupported(
                at,
                format!("medium \"{name}\": measured preset \"{preset}\" is not tabulated: pbrt-v4's default coefficients used"),
            )?;
        }
        let (a, s) = (self.coefficient(params, "sigma_a", at)?, self.coefficient(params, "sigma_s", at)?);
        let (sigma_a, sigma_s) = match (a, s) {
            (None, None) => (DEFAULT_SIGMA_A, DEFAULT_SIGMA_S),
            (a, s) => (a.unwrap_or([1.0; 3]), s.unwrap_or([1.0; 3])),
        };
        let scale = params.float("scale", 1.0, at)? as f32;
        let g = params.float("g", 0.0, at)? as f32;
        let le = self.coefficient(params, "Le", at)?;
        let _ = params.float("Lescale", 1.0, at)?;
        if le.is_some_and(|l| l.iter().any(|&v| v != 0.0)) {
            self.unsupported(at, format!("medium \"{name}\": emission (\"Le\") is not supported: ignored"))?;
        }
        Ok(Some(MediumDescription { sigma_a, sigma_s, scale: Some(scale), g: Some(g) }))
    }

    /// A medium's coefficient: `rgb`, one number (`float` or `spectrum`), or a sampled
    /// `spectrum` converted to RGB without clamping (coefficients are not reflectances).
    fn coefficient(&mut self, params: &Params, name: &str, at: &At) -> Result<Option<[f32; 3]>> {
        let Some(p) = params.get(name) else { return Ok(None) };
        match (p.kind.as_str(), &p.values) {
            ("rgb", Values::Numbers(v)) if v.len() == 3 => Ok(Some([v[0] as f32, v[1] as f32, v[2] as f32])),
            ("float" | "spectrum", Values::Numbers(v)) if v.len() == 1 => Ok(Some([v[0] as f32; 3])),
            ("spectrum", Values::Numbers(v)) if v.len() >= 4 && v.len() % 2 == 0 => {
                let points: Vec<(f64, f64)> = v.chunks(2).map(|p| (p[0], p[1])).collect();
                crate::color::spectrum_to_rgb(&points, false)
                    .map(Some)
                    .ok_or_else(|| syntax(at, format!("\"spectrum {name}\": wavelengths must increase")))
            }
            (k, _) => {
                let k = k.to_string();
                self.unsupported(at, format!("\"{k} {name}\" of a medium is not converted: 1 used"))?;
                Ok(Some([1.0; 3]))
            }
        }
    }

    /// The description's name of pbrt medium `name` (`None`: vacuum, for `""` and for media
    /// not rendered); a name never defined is warned about once.
    fn medium_key(&mut self, name: &str, at: &At) -> Result<Option<String>> {
        if name.is_empty() {
            return Ok(None);
        }
        if let Some(key) = self.media.get(name) {
            return Ok(key.clone());
        }
        self.unsupported(at, format!("medium \"{name}\" is not defined (before it): vacuum used"))?;
        self.media.insert(name.to_string(), None);
        Ok(None)
    }
}
