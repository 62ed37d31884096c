//! BSDFs: Mitsuba 3's BSDF plugins as the description's materials (wrappers unwrapped,
//! approximations warned), with named indices of refraction and microfacet parameters.
use super::*;

impl Translator<'_, '_> {
    /// An index of refraction: a number or one of Mitsuba's names.
    fn ior(&mut self, obj: &Obj, name: &str, default: f32) -> Result<f32> {
        match obj.param(name).cloned() {
            None => Ok(default),
            Some((_, Value::Float(v), _)) => Ok(v as f32),
            Some((_, Value::Text(s), at)) => {
                named_ior(&s.to_lowercase()).ok_or_else(|| syntax(&at, format!("`{name}`: unknown material \"{s}\"")))
            }
            Some((_, _, at)) => Err(syntax(&at, format!("`{name}` must be a number or a material name"))),
        }
    }

    /// The microfacets of a rough BSDF into `m`: its distribution (Mitsuba's default
    /// Beckmann), Mitsuba 3's separable masking, and `alpha` (default 0.1; anisotropic
    /// `alpha_u`/`alpha_v` by their mean) or a texture of it (`textured`: whether the BSDF
    /// can take one).
    fn microfacets(&mut self, b: &Obj, m: &mut MaterialDescription, textured: bool) -> Result<()> {
        let distribution = self.text(b, "distribution")?.unwrap_or_else(|| "beckmann".into());
        m.distribution = Some(match distribution.as_str() {
            "ggx" => DistributionDescription::Ggx,
            "beckmann" => DistributionDescription::Beckmann,
            other => {
                self.unsupported(
                    &b.at,
                    format!("<bsdf type=\"{}\">: unknown distribution \"{other}\": beckmann used", b.plugin),
                )?;
                DistributionDescription::Beckmann
            }
        });
        m.masking = Some(MaskingDescription::Separable);
        if b.param("alpha_u").is_some() || b.param("alpha_v").is_some() {
            let u = self.float(b, "alpha_u", 0.1)?;
            let v = self.float(b, "alpha_v", 0.1)?;
            self.unsupported(&b.at, "anisotropic roughness: the mean of alpha_u and alpha_v used".into())?;
            m.roughness = Some(((u + v) / 2.0) as f32);
            return Ok(());
        }
        let texture = match b.param("alpha").cloned() {
            Some((_, Value::Object(t), _)) if t.tag == "texture" => Some(self.texture(&t)?),
            Some((_, Value::Ref(id), at)) => {
                let t = self.resolve_ref(&id, &at)?.clone();
                Some(self.texture(&t)?)
            }
            _ => None,
        };
        let texture = texture.map(|name| self.scalar_texture(name));
        m.roughness = Some(if texture.is_some() { 0.1 } else { self.float(b, "alpha", 0.1)? as f32 });
        if texture.is_some() && !textured {
            self.unsupported(&b.at, "a textured roughness of a plastic is not supported: 0.1 used".into())?;
        } else {
            m.roughness_texture = texture;
        }
        Ok(())
    }

    /// A BSDF object (or a reference to one) as a material.
    pub(super) fn bsdf(&mut self, b: &Obj, depth: usize) -> Result<MitsubaBsdf> {
        let mut m = MaterialDescription { two_sided: Some(false), ..MaterialDescription::default() };
        let rough = b.plugin.starts_with("rough");
        match b.plugin.as_str() {
            "twosided" => {
                self.check_params(b, &[])?;
                let inner = b.children.first().cloned();
                if b.children.len() > 1 {
                    self.unsupported(&b.at, "a twosided BSDF with two BSDFs: the first one used on both sides".into())?;
                }
                let mut inner = match inner {
                    Some(c) if depth < 4 => self.child_bsdf(&c, depth + 1)?,
                    _ => return Err(syntax(&b.at, "a twosided BSDF needs one nested BSDF")),
                };
                if !matches!(inner.material.kind, MaterialKind::Dielectric | MaterialKind::ThinDielectric) {
                    inner.material.two_sided = Some(true);
                }
                return Ok(inner);
            }
            "bumpmap" | "normalmap" | "mask" => {
                let what = match b.plugin.as_str() {
                    "mask" => "its opacity is ignored (opaque)",
                    _ => "the nested BSDF used without the normal perturbation",
                };
                self.unsupported(&b.at, format!("<bsdf type=\"{}\">: {what}", b.plugin))?;
                let known: &[&str] = match b.plugin.as_str() {
                    "bumpmap" => &["arbitrary", "scale"],
                    "normalmap" => &["normalmap"],
                    _ => &["opacity"],
                };
                for (name, _, at) in &b.params {
                    if !known.contains(&name.as_str()) {
                        let message =
                            format!("<bsdf type=\"{}\">: parameter `{name}` is not supported: ignored", b.plugin);
                        self.reader.unsupported(at, message)?;
                    }
                }
                return match b.children.first() {
                    Some(c) if depth < 4 => self.child_bsdf(c, depth + 1),
                    _ => Err(syntax(&b.at, format!("a {} BSDF needs one nested BSDF", b.plugin))),
                };
            }
            "blendbsdf" => {
                self.check_params(b, &["weight"])?;
                // (1 − w)·first + w·second: the heavier one stands for the blend.
                let weight = match b.param("weight") {
                    Some((_, Value::Float(w), _)) => *w,
                    _ => 0.5,
                };
                self.unsupported(
                    &b.at,
                    format!(
                        "<bsdf type=\"blendbsdf\">: the {} BSDF (weight {weight}) stands for the blend",
                        if weight > 0.5 { "second" } else { "first" }
                    ),
                )?;
                let pick = usize::from(weight > 0.5);
                return match b.children.get(pick) {
                    Some(c) if depth < 4 && b.children.len() == 2 => self.child_bsdf(c, depth + 1),
                    _ => Err(syntax(&b.at, "a blendbsdf needs two nested BSDFs")),
                };
            }
            "principled" => {
                self.check_params(
                    b,
                    &[
                        "base_color",
                        "roughness",
                        "metallic",
                        "specular",
                        "spec_tint",
                        "anisotropic",
                        "sheen",
                        "sheen_tint",
                        "clearcoat",
                        "clearcoat_gloss",
                        "spec_trans",
                        "eta",
                        "sample_visible",
                    ],
                )?;
                let (c, t) = self.colour(b, "base_color", [0.5; 3])?;
                let number = |this: &mut Self, name: &str, default: f64| -> Result<f64> {
                    match b.param(name) {
                        Some((_, Value::Float(_), _)) | None => this.float(b, name, default),
                        Some(_) => Ok(default),
                    }
                };
                let roughness = number(self, "roughness", 0.5)?;
                let metallic = number(self, "metallic", 0.0)?;
                let transmission = number(self, "spec_trans", 0.0)?;
                let alpha = (roughness * roughness).clamp(0.0, 1.0) as f32;
                m.roughness = Some(alpha);
                m.distribution = Some(DistributionDescription::Ggx);
                m.masking = Some(MaskingDescription::Separable);
                let model = if transmission > 0.5 {
                    m.kind = MaterialKind::Dielectric;
                    m.two_sided = None;
                    m.ior = Some(number(self, "eta", 1.5)? as f32);
                    "a rough dielectric"
                } else if metallic > 0.5 {
                    m.kind = MaterialKind::Conductor;
                    m.metal = Some("none".into());
                    m.specular = c;
                    m.specular_texture = t;
                    "a rough mirror tinted by base_color"
                } else {
                    m.kind = MaterialKind::Plastic;
                    m.diffuse = c.unwrap_or([0.0; 3]);
                    m.diffuse_texture = t;
                    m.ior = Some(1.5);
                    "a rough plastic of base_color"
                };
                self.unsupported(
                    &b.at,
                    format!("<bsdf type=\"principled\"> is approximated by {model} (α = roughness²)"),
                )?;
            }
            // A medium's boundary, no surface.
            "null" => {
                self.check_params(b, &[])?;
                m.kind = MaterialKind::Interface;
                m.two_sided = None;
            }
            "diffuse" => {
                self.check_params(b, &["reflectance"])?;
                let (c, t) = self.colour(b, "reflectance", [0.5; 3])?;
                m.diffuse = c.unwrap_or([0.0; 3]);
                m.diffuse_texture = t;
            }
            "conductor" | "roughconductor" => {
                self.check_params(
                    b,
                    &[
                        "material",
                        "eta",
                        "k",
                        "specular_reflectance",
                        "alpha",
                        "alpha_u",
                        "alpha_v",
                        "distribution",
                        "sample_visible",
                    ],
                )?;
                m.kind = MaterialKind::Conductor;
                if b.param("eta").is_some() || b.param("k").is_some() {
                    m.eta = Some(self.constant_colour(b, "eta", [0.0; 3])?);
                    m.k = Some(self.constant_colour(b, "k", [1.0; 3])?);
                } else {
                    let name = self.text(b, "material")?.unwrap_or_else(|| "none".into());
                    if crate::material::metals::lookup(&name).is_none() {
                        self.unsupported(
                            &b.at,
                            format!(
                                "conductor material \"{name}\" is not in our table: a perfect mirror (\"none\") used"
                            ),
                        )?;
                        m.metal = Some("none".into());
                    } else {
                        m.metal = Some(name);
                    }
                }
                let (c, t) = self.colour(b, "specular_reflectance", [1.0; 3])?;
                m.specular = c;
                m.specular_texture = t;
                if rough {
                    self.microfacets(b, &mut m, true)?;
                }
            }
            "dielectric" | "roughdielectric" | "thindielectric" => {
                self.check_params(
                    b,
                    &[
                        "int_ior",
                        "ext_ior",
                        "alpha",
                        "alpha_u",
                        "alpha_v",
                        "distribution",
                        "sample_visible",
                        "specular_reflectance",
                        "specular_transmittance",
                    ],
                )?;
                for key in ["specular_reflectance", "specular_transmittance"] {
                    if b.param(key).is_some() {
                        self.unsupported(&b.at, format!("`{key}` of a dielectric is not supported: 1 used"))?;
                    }
                }
                m.kind =
                    if b.plugin == "thindielectric" { MaterialKind::ThinDielectric } else { MaterialKind::Dielectric };
                m.two_sided = None;
                m.ior = Some(self.ior(b, "int_ior", 1.5046)?);
                m.exterior_ior = Some(self.ior(b, "ext_ior", 1.000_277)?);
                if rough {
                    self.microfacets(b, &mut m, true)?;
                }
            }
            "plastic" | "roughplastic" => {
                self.check_params(
                    b,
                    &[
                        "diffuse_reflectance",
                        "int_ior",
                        "ext_ior",
                        "nonlinear",
                        "alpha",
                        "distribution",
                        "sample_visible",
                        "specular_reflectance",
                    ],
                )?;
                if b.param("specular_reflectance").is_some() {
                    self.unsupported(&b.at, "`specular_reflectance` of a plastic is not supported: 1 used".into())?;
                }
                m.kind = MaterialKind::Plastic;
                let (c, t) = self.colour(b, "diffuse_reflectance", [0.5; 3])?;
                m.diffuse = c.unwrap_or([0.0; 3]);
                m.diffuse_texture = t;
                m.ior = Some(self.ior(b, "int_ior", 1.49)?);
                m.exterior_ior = Some(self.ior(b, "ext_ior", 1.000_277)?);
                m.nonlinear = Some(self.boolean(b, "nonlinear", false)?);
                if rough {
                    self.microfacets(b, &mut m, false)?;
                }
            }
            other => {
                self.unsupported(&b.at, format!("<bsdf type=\"{other}\"> is not supported: grey diffuse (0.5) used"))?;
                m.diffuse = [0.5; 3];
            }
        }
        Ok(MitsubaBsdf { material: m })
    }

    fn child_bsdf(&mut self, c: &Child, depth: usize) -> Result<MitsubaBsdf> {
        match c {
            Child::Obj(o) if o.tag == "bsdf" => self.bsdf(o, depth),
            Child::Obj(o) => Err(syntax(&o.at, format!("<{}> where a BSDF was expected", o.tag))),
            Child::Ref(id, at) => {
                let o = self.resolve_ref(id, at)?.clone();
                if o.tag != "bsdf" {
                    return Err(syntax(at, format!("<ref id=\"{id}\"> names a <{}>, not a BSDF", o.tag)));
                }
                self.bsdf(&o, depth)
            }
        }
    }
}

/// Named indices of refraction, as Mitsuba 3 lists them.
fn named_ior(name: &str) -> Option<f32> {
    Some(match name {
        "vacuum" => 1.0,
        "helium" => 1.000_036,
        "hydrogen" => 1.000_132,
        "air" => 1.000_277,
        "carbon dioxide" => 1.000_449,
        "water" => 1.333,
        "acetone" => 1.36,
        "ethanol" => 1.361,
        "carbon tetrachloride" => 1.461,
        "glycerol" => 1.4729,
        "benzene" => 1.501,
        "silicone oil" => 1.520_45,
        "bromine" => 1.661,
        "water ice" => 1.31,
        "fused quartz" => 1.458,
        "pyrex" => 1.47,
        "acrylic glass" => 1.49,
        "polypropylene" => 1.49,
        "bk7" => 1.5046,
        "sodium chloride" => 1.544,
        "amber" => 1.55,
        "pet" => 1.575,
        "diamond" => 2.419,
        _ => return None,
    })
}
