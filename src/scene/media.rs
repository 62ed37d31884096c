//! The media of a scene description turned into the scene's [`Medium`]s, and the
//! [`MediumInterface`] of each material and the camera's medium, by name.
use super::description::{MaterialDescription, MediumDescription, SceneDescription};
use crate::Result;
use crate::medium::{Medium, MediumInterface};
use std::collections::HashMap;
use std::path::Path;

use super::mesh::{invalid, vec3};

/// Largest coefficient per unit length: beyond it a medium is opaque at any scale a scene
/// file describes, and products with distances stay far from overflow.
pub const MAX_COEFFICIENT: f32 = 1e8;

/// A scene's media, in the description's (sorted) order, and their indices by name.
pub(super) struct Media {
    pub media: Vec<Medium>,
    ids: HashMap<String, u16>,
}

impl Media {
    /// The media `d` describes, checked.
    pub fn from_description(path: &Path, d: &SceneDescription) -> Result<Self> {
        if d.media.len() > usize::from(u16::MAX) {
            return Err(invalid(path, format!("at most {} media, got {}", u16::MAX, d.media.len())));
        }
        let mut media = Vec::with_capacity(d.media.len());
        let mut ids = HashMap::new();
        for (name, m) in &d.media {
            let medium = medium_from(m).map_err(|e| invalid(path, format!("medium `{name}`: {e}")))?;
            ids.insert(name.clone(), media.len() as u16);
            media.push(medium);
        }
        Ok(Self { media, ids })
    }

    /// The medium named `name`, if any (`what` names the key for the error).
    pub fn id(&self, path: &Path, what: &str, name: Option<&String>) -> Result<Option<u16>> {
        name.map(|n| self.ids.get(n).copied().ok_or_else(|| invalid(path, format!("{what}: unknown medium `{n}`"))))
            .transpose()
    }

    /// The media on the two sides of material `name`'s surfaces.
    pub fn interface_of(&self, path: &Path, name: &str, m: &MaterialDescription) -> Result<MediumInterface> {
        let what = format!("material `{name}`");
        Ok(MediumInterface {
            inside: self.id(path, &what, m.interior_medium.as_ref())?,
            outside: self.id(path, &what, m.exterior_medium.as_ref())?,
        })
    }
}

fn medium_from(d: &MediumDescription) -> std::result::Result<Medium, String> {
    let scale = d.scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale >= 0.0) {
        return Err(format!("scale must be finite and non-negative, got {scale}"));
    }
    let g = d.g.unwrap_or(0.0);
    if !(g.is_finite() && g.abs() < 1.0) {
        return Err(format!("g must lie strictly between -1 and 1, got {g}"));
    }
    let coefficient = |what: &str, v: [f32; 3]| {
        let c = vec3(v) * scale;
        if c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= MAX_COEFFICIENT {
            Ok(c)
        } else {
            Err(format!("{what} (times scale) must lie in [0, {MAX_COEFFICIENT:e}] per channel, got {v:?} × {scale}"))
        }
    };
    Ok(Medium { sigma_a: coefficient("sigma_a", d.sigma_a)?, sigma_s: coefficient("sigma_s", d.sigma_s)?, g })
}
