//! Materials and textures: pbrt-v4's materials as the description's, colour parameters, textures.
use super::tokens::{Cursor, Param, Params, Values};
use super::{Colour, Parser};
use crate::error::Result;
use crate::scene::description::{
    FilterDescription, MaterialDescription, MaterialKind, TextureDescription, TextureKind, WrapDescription,
};
use crate::scene::import::{At, syntax};

impl Parser<'_> {
    /// Named and anonymous materials, and textures.
    pub(super) fn material_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        match d {
            "MakeNamedMaterial" => {
                let name = c.text(d)?;
                let params = c.params()?;
                let kind =
                    params.text("type", at)?.ok_or_else(|| syntax(at, "MakeNamedMaterial needs \"string type\""))?;
                let m = self.material(&kind, &params, at)?;
                let key = format!("named:{name}");
                self.out.materials.insert(key.clone(), m);
                self.out.origins.insert(format!("material {key}"), (at.file.to_path_buf(), at.line));
                self.named_materials.insert(name, key);
            }
            "NamedMaterial" => {
                let name = c.text(d)?;
                match self.named_materials.get(&name) {
                    Some(key) => self.state.material = key.clone(),
                    None => return Err(syntax(at, format!("NamedMaterial \"{name}\": no such material (before it)"))),
                }
            }
            "Material" => {
                let kind = c.text(d)?;
                let params = c.params()?;
                let m = self.material(&kind, &params, at)?;
                let key = self.fresh("material");
                self.out.materials.insert(key.clone(), m);
                self.out.origins.insert(format!("material {key}"), (at.file.to_path_buf(), at.line));
                self.state.material = key;
            }
            "Texture" => {
                let name = c.text(d)?;
                let class = c.text(d)?;
                let kind = c.text(d)?;
                let params = c.params()?;
                self.texture_directive(name, &class, &kind, &params, at)?;
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// A colour parameter: `rgb`, a single-valued or named `spectrum` (approximated), a
    /// `float`, or a `texture`.
    pub(super) fn colour(&mut self, params: &Params, name: &str, default: [f32; 3], at: &At) -> Result<Colour> {
        let Some(p) = params.get(name) else { return Ok(Colour::Constant(default)) };
        let (kind, values) = (p.kind.clone(), p.values.clone());
        match (kind.as_str(), values) {
            ("rgb", Values::Numbers(v)) if v.len() == 3 => {
                Ok(Colour::Constant([v[0] as f32, v[1] as f32, v[2] as f32]))
            }
            ("float", Values::Numbers(v)) if v.len() == 1 => Ok(Colour::Constant([v[0] as f32; 3])),
            ("spectrum", Values::Numbers(v)) if v.len() == 1 => Ok(Colour::Constant([v[0] as f32; 3])),
            ("spectrum", Values::Numbers(v)) if v.len() >= 4 && v.len() % 2 == 0 => {
                // λ/value pairs. A light's spectrum is normalised to luminance 1 (pbrt-v4
                // scales it by 1/∫Lȳ, then by "scale"); a reflectance is taken under D65.
                let points: Vec<(f64, f64)> = v.chunks(2).map(|p| (p[0], p[1])).collect();
                let emission = matches!(name, "L" | "I");
                let rgb = crate::color::spectrum_to_rgb(&points, emission)
                    .ok_or_else(|| syntax(at, format!("\"spectrum {name}\": wavelengths must increase")))?;
                if emission {
                    let y = f64::from(crate::geometry::luminance(glam::Vec3A::from_array(rgb)));
                    if y.is_nan() || y <= 0.0 {
                        return Err(syntax(at, format!("\"spectrum {name}\" has no luminance")));
                    }
                    Ok(Colour::Constant(rgb.map(|c| (f64::from(c) / y).max(0.0) as f32)))
                } else {
                    Ok(Colour::Constant(rgb.map(|c| c.clamp(0.0, 1.0))))
                }
            }
            ("blackbody", Values::Numbers(_)) => {
                self.unsupported(at, format!("\"blackbody {name}\" is not converted: white used"))?;
                Ok(Colour::Constant([1.0; 3]))
            }
            ("spectrum", Values::Texts(v)) => {
                self.unsupported(at, format!("named spectrum \"{}\" for {name}: grey 0.5 used", v[0]))?;
                Ok(Colour::Constant([0.5; 3]))
            }
            ("texture", Values::Texts(v)) if v.len() == 1 => match self.textures.get(&(false, v[0].clone())) {
                Some(t) => Ok(Colour::Texture(t.clone())),
                None => Err(syntax(at, format!("\"texture {name}\": no spectrum texture \"{}\" (before it)", v[0]))),
            },
            (k, _) => Err(syntax(at, format!("\"{k} {name}\": not a colour"))),
        }
    }

    /// GGX α from pbrt's roughness parameters (remapped by `sqrt` unless `remaproughness` is
    /// false, as pbrt-v4's `TrowbridgeReitzDistribution::RoughnessToAlpha`), or a float
    /// texture's name.
    pub(super) fn roughness(&mut self, params: &Params, at: &At) -> Result<(f32, Option<String>)> {
        let remap = params.boolean("remaproughness", true, at)?;
        let read = |this: &mut Self, name: &str| -> Result<Option<(f64, Option<String>)>> {
            match params.get(name).map(|p| (p.kind.clone(), p.values.clone())) {
                None => Ok(None),
                Some((k, Values::Numbers(v))) if k == "float" && v.len() == 1 => Ok(Some((v[0], None))),
                Some((k, Values::Texts(v))) if k == "texture" && v.len() == 1 => match this
                    .textures
                    .get(&(true, v[0].clone()))
                {
                    Some(t) => Ok(Some((0.0, Some(t.clone())))),
                    None => Err(syntax(at, format!("\"texture {name}\": no float texture \"{}\" (before it)", v[0]))),
                },
                Some((k, _)) => Err(syntax(at, format!("\"{k} {name}\" must be a float or a texture"))),
            }
        };
        let (r, texture) = match (read(self, "roughness")?, read(self, "uroughness")?, read(self, "vroughness")?) {
            (Some(r), _, _) => r,
            (None, Some(u), Some(v)) => {
                if u.0 != v.0 || u.1.is_some() || v.1.is_some() {
                    self.unsupported(at, "anisotropic roughness: the mean of uroughness and vroughness used".into())?;
                }
                ((u.0 + v.0) / 2.0, u.1.or(v.1))
            }
            (None, Some(r), None) | (None, None, Some(r)) => r,
            (None, None, None) => (0.0, None),
        };
        if texture.is_some() && remap {
            self.unsupported(at, "a roughness texture is read as α directly (no remapping)".into())?;
        }
        let alpha = if remap { r.max(0.0).sqrt() } else { r };
        Ok((alpha.min(1.0) as f32, texture))
    }

    pub(super) fn eta(&mut self, params: &Params, default: f32, at: &At) -> Result<f32> {
        match params.get("eta").map(|p| (p.kind.clone(), p.values.clone())) {
            None => Ok(default),
            Some((_, Values::Numbers(v))) if v.len() == 1 => Ok(v[0] as f32),
            Some((_, Values::Texts(v))) => match glass_ior(&v[0]) {
                Some(eta) => Ok(eta),
                None => {
                    self.unsupported(at, format!("eta \"{}\" is not a glass we know: {default} used", v[0]))?;
                    Ok(default)
                }
            },
            Some((k, _)) => Err(syntax(at, format!("\"{k} eta\" must be a number or a named spectrum"))),
        }
    }

    /// A hair material's colour: `color` if given, else the colour whose absorption is
    /// `sigma_a`, else that of the melanin concentrations (pbrt-v4's default: eumelanin 1.3),
    /// by Chiang et al.'s (2016) mapping between colour and absorption at the azimuthal
    /// roughness `beta_n`, as pbrt-v4's `HairBxDF` uses it.
    pub(super) fn hair_colour(&mut self, params: &Params, at: &At) -> Result<[f32; 3]> {
        let beta_n = params.float("beta_n", 0.3, at)?.clamp(0.0, 1.0);
        let constant = |this: &mut Self, name: &str| -> Result<Option<[f32; 3]>> {
            if params.get(name).is_none() {
                return Ok(None);
            }
            match this.colour(params, name, [0.0; 3], at)? {
                Colour::Constant(c) => Ok(Some(c)),
                Colour::Texture(_) => {
                    this.unsupported(at, format!("a hair's \"{name}\" as a texture: its default used"))?;
                    Ok(None)
                }
            }
        };
        if let Some(c) = constant(self, "color")? {
            for ignored in ["sigma_a", "eumelanin", "pheomelanin"] {
                params.get(ignored);
            }
            return Ok(c.map(|x| x.clamp(0.0, 1.0)));
        }
        let sigma_a = match constant(self, "sigma_a")? {
            Some(s) => s.map(f64::from),
            None => {
                let (e, p) =
                    (params.float("eumelanin", 1.3, at)?.max(0.0), params.float("pheomelanin", 0.0, at)?.max(0.0));
                let (eu, ph) = ([0.419, 0.697, 1.37], [0.187, 0.4, 1.05]);
                [0, 1, 2].map(|i| e * eu[i] + p * ph[i])
            }
        };
        let b = beta_n;
        let k = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3) + 5.574 * b.powi(4) + 0.245 * b.powi(5);
        Ok(sigma_a.map(|s| (-(s.max(0.0).sqrt()) * k).exp() as f32))
    }

    pub(super) fn material(&mut self, kind: &str, params: &Params, at: &At) -> Result<MaterialDescription> {
        let mut m = MaterialDescription::default();
        params.get("displacement").inspect(|_| ());
        match kind {
            "diffuse" => match self.colour(params, "reflectance", [0.5; 3], at)? {
                Colour::Constant(c) => m.diffuse = c,
                Colour::Texture(t) => m.diffuse_texture = Some(t),
            },
            "conductor" => {
                m.kind = MaterialKind::Conductor;
                let named = |p: Option<&Param>| match p.map(|p| &p.values) {
                    Some(Values::Texts(v)) => v.first().cloned(),
                    _ => None,
                };
                let (eta_p, k_p) = (params.get("eta").cloned(), params.get("k").cloned());
                match (named(eta_p.as_ref()), named(k_p.as_ref()), &eta_p, &k_p) {
                    (Some(e), Some(k), ..) => {
                        let metal = e.strip_prefix("metal-").and_then(|s| s.strip_suffix("-eta"));
                        let metal_k = k.strip_prefix("metal-").and_then(|s| s.strip_suffix("-k"));
                        match (metal, metal_k) {
                            (Some(a), Some(b)) if a == b && crate::material::metals::lookup(a).is_some() => {
                                m.metal = Some(a.to_string());
                            }
                            _ => {
                                self.unsupported(at, format!("conductor spectra \"{e}\"/\"{k}\": copper used"))?;
                                m.metal = Some("Cu".into());
                            }
                        }
                    }
                    (None, None, None, None) => {
                        if params.get("reflectance").is_some() {
                            self.unsupported(
                                at,
                                "conductor \"reflectance\" (artist mode) is not supported: copper used".into(),
                            )?;
                        }
                        m.metal = Some("Cu".into());
                    }
                    _ => {
                        let eta = match self.colour(params, "eta", [0.2; 3], at)? {
                            Colour::Constant(c) => c,
                            Colour::Texture(_) => return Err(syntax(at, "a conductor's eta cannot be a texture")),
                        };
                        let k = match self.colour(params, "k", [3.9; 3], at)? {
                            Colour::Constant(c) => c,
                            Colour::Texture(_) => return Err(syntax(at, "a conductor's k cannot be a texture")),
                        };
                        (m.eta, m.k) = (Some(eta), Some(k));
                    }
                }
                let (alpha, t) = self.roughness(params, at)?;
                (m.roughness, m.roughness_texture) = (Some(alpha), t);
            }
            "dielectric" | "thindielectric" => {
                m.kind = if kind == "dielectric" { MaterialKind::Dielectric } else { MaterialKind::ThinDielectric };
                m.ior = Some(self.eta(params, 1.5, at)?);
                if kind == "dielectric" {
                    let (alpha, t) = self.roughness(params, at)?;
                    (m.roughness, m.roughness_texture) = (Some(alpha), t);
                }
            }
            "coateddiffuse" => {
                self.unsupported(
                    at,
                    "coateddiffuse is approximated by Mitsuba's nonlinear plastic (one interface, no layer thickness or albedo)"
                        .into(),
                )?;
                m.kind = MaterialKind::Plastic;
                // Nonlinear: light reflected back down by the coat meets the base again, so the
                // base's colour compounds, ρ/(1 − ρ·F̄dr), as in pbrt-v4's random walk through
                // the layer (the linear form, ρ/(1 − F̄dr), made coffee's orange and grey floor
                // 1.5× too bright against Tungsten's render).
                m.nonlinear = Some(true);
                match self.colour(params, "reflectance", [0.5; 3], at)? {
                    Colour::Constant(c) => m.diffuse = c,
                    Colour::Texture(t) => m.diffuse_texture = Some(t),
                }
                m.ior = Some(self.eta(params, 1.5, at)?);
                let (alpha, t) = self.roughness(params, at)?;
                if t.is_some() {
                    self.unsupported(at, "a textured roughness of a coated diffuse: 0 used".into())?;
                }
                m.roughness = Some(if t.is_some() { 0.0 } else { alpha });
                for ignored in ["thickness", "albedo", "g", "maxdepth", "nsamples"] {
                    params.get(ignored);
                }
            }
            "mix" => {
                let names = match params.get("materials").map(|p| p.values.clone()) {
                    Some(Values::Texts(v)) if v.len() == 2 => v,
                    _ => return Err(syntax(at, "a mix material needs \"string materials\" with two names")),
                };
                let amount = match params.get("amount").map(|p| (p.kind.clone(), p.values.clone())) {
                    Some((k, Values::Numbers(v))) if k == "float" && v.len() == 1 => v[0],
                    _ => 0.5,
                };
                // pbrt-v4 picks the second material with probability `amount`.
                let pick = &names[usize::from(amount > 0.5)];
                self.unsupported(at, format!("a mix material (amount {amount}): \"{pick}\" stands for it"))?;
                let found = self.named_materials.get(pick).and_then(|key| self.out.materials.get(key)).cloned();
                m = found.ok_or_else(|| syntax(at, format!("mix: no named material \"{pick}\" (before it)")))?;
                params.get("amount");
            }
            "coatedconductor" => {
                self.unsupported(at, "coatedconductor is approximated by its conductor (no coating layer)".into())?;
                m.kind = MaterialKind::Conductor;
                let named = |name: &str| match params.get(name).map(|p| p.values.clone()) {
                    Some(Values::Texts(v)) => v.first().cloned(),
                    _ => None,
                };
                let metal = named("conductor.eta")
                    .and_then(|e| e.strip_prefix("metal-").and_then(|s| s.strip_suffix("-eta")).map(str::to_string))
                    .filter(|a| crate::material::metals::lookup(a).is_some());
                m.metal = Some(metal.unwrap_or_else(|| "Cu".into()));
                let r = params.float("conductor.roughness", 0.0, at)?;
                let remap = params.boolean("remaproughness", true, at)?;
                m.roughness = Some((if remap { r.max(0.0).sqrt() } else { r }).min(1.0) as f32);
                for p in &params.list {
                    p.used.set(true);
                }
            }
            "diffusetransmission" => {
                self.unsupported(at, "diffusetransmission is approximated by its diffuse reflection".into())?;
                match self.colour(params, "reflectance", [0.25; 3], at)? {
                    Colour::Constant(c) => m.diffuse = c,
                    Colour::Texture(t) => m.diffuse_texture = Some(t),
                }
                for ignored in ["transmittance", "scale"] {
                    params.get(ignored);
                }
            }
            "hair" => {
                self.unsupported(
                    at,
                    "hair is approximated by a diffuse surface of the colour its absorption gives".into(),
                )?;
                m.diffuse = self.hair_colour(params, at)?;
                for ignored in ["eta", "beta_m", "alpha"] {
                    params.get(ignored);
                }
            }
            "interface" => m.kind = MaterialKind::Interface,
            other => {
                self.unsupported(at, format!("Material \"{other}\" is not supported: grey diffuse (0.5) used"))?;
                for p in &params.list {
                    p.used.set(true);
                }
                m.diffuse = [0.5; 3];
            }
        }
        params.get("normalmap");
        self.check_unused(&format!("Material \"{kind}\""), params, at)?;
        Ok(m)
    }

    pub(super) fn texture_directive(
        &mut self,
        name: String,
        class: &str,
        kind: &str,
        params: &Params,
        at: &At,
    ) -> Result<()> {
        let float = match class {
            "float" => true,
            "spectrum" | "color" => false,
            other => {
                return Err(syntax(at, format!("Texture \"{name}\": class \"{other}\" is neither float nor spectrum")));
            }
        };
        let key = self.fresh("texture");
        let description = match kind {
            "imagemap" => {
                let file =
                    params.text("filename", at)?.ok_or_else(|| syntax(at, "an imagemap needs \"string filename\""))?;
                let wrap = match params.text("wrap", at)?.as_deref() {
                    None | Some("repeat") => WrapDescription::Repeat,
                    Some("clamp") => WrapDescription::Clamp,
                    Some(other) => {
                        self.unsupported(at, format!("wrap \"{other}\": repeat used"))?;
                        WrapDescription::Repeat
                    }
                };
                let filter = match params.text("filter", at)?.as_deref() {
                    Some("point") => FilterDescription::Nearest,
                    _ => FilterDescription::Bilinear,
                };
                let raw = match params.text("encoding", at)?.as_deref() {
                    None | Some("sRGB") => false,
                    Some("linear") => true,
                    Some(other) => {
                        self.unsupported(at, format!("encoding \"{other}\": sRGB used"))?;
                        false
                    }
                };
                let factor = params.float("scale", 1.0, at)? as f32;
                let invert = params.boolean("invert", false, at)?;
                let uv_transform = self.mapping(params, at)?;
                params.get("maxanisotropy");
                TextureDescription {
                    kind: TextureKind::Bitmap,
                    file: Some(self.resolve(&file).to_string_lossy().into_owned()),
                    wrap: Some(wrap),
                    filter: Some(filter),
                    raw: Some(raw),
                    color0: None,
                    color1: None,
                    scale: None,
                    v_from_top: None,
                    uv_transform,
                    factor: (factor != 1.0).then_some([factor; 3]),
                    invert: invert.then_some(true),
                }
            }
            "checkerboard" => {
                let value = |this: &mut Self, name: &str, default: f32| -> Result<[f32; 3]> {
                    match this.colour(params, name, [default; 3], at)? {
                        Colour::Constant(c) => Ok(c),
                        Colour::Texture(_) => {
                            this.unsupported(at, format!("a checkerboard's {name} as a texture: grey 0.5 used"))?;
                            Ok([0.5; 3])
                        }
                    }
                };
                let (c1, c2) = (value(self, "tex1", 1.0)?, value(self, "tex2", 0.0)?);
                let (us, vs) = (params.float("uscale", 1.0, at)?, params.float("vscale", 1.0, at)?);
                params.get("dimension");
                TextureDescription::checkerboard(c1, c2, [us.abs().max(1e-6) as f32, vs.abs().max(1e-6) as f32])
            }
            "constant" => match self.colour(params, "value", [1.0; 3], at)? {
                Colour::Constant(c) => TextureDescription::constant(c),
                Colour::Texture(t) => {
                    self.textures.insert((float, name), t);
                    self.check_unused(&format!("Texture \"{kind}\""), params, at)?;
                    return Ok(());
                }
            },
            "scale" => {
                // `tex` times `scale`: two constants fold into one colour; a texture times a
                // constant is that texture with a factor.
                let a = self.operand(params, "tex", float, at)?;
                let b = self.operand(params, "scale", float, at)?;
                match (a, b) {
                    (Colour::Constant(a), Colour::Constant(b)) => {
                        TextureDescription::constant([a[0] * b[0], a[1] * b[1], a[2] * b[2]])
                    }
                    (Colour::Texture(t), Colour::Constant(c)) | (Colour::Constant(c), Colour::Texture(t)) => {
                        let mut scaled = self
                            .out
                            .textures
                            .get(&t)
                            .cloned()
                            .unwrap_or_else(|| TextureDescription::constant([0.5; 3]));
                        let old = scaled.factor.unwrap_or([1.0; 3]);
                        scaled.factor = Some([old[0] * c[0], old[1] * c[1], old[2] * c[2]]);
                        if scaled.invert == Some(true) {
                            self.unsupported(
                                at,
                                format!(
                                    "Texture \"{name}\": an inverted imagemap scaled again: scaled before inverting"
                                ),
                            )?;
                        }
                        scaled
                    }
                    (Colour::Texture(t), Colour::Texture(_)) => {
                        self.unsupported(
                            at,
                            format!("Texture \"{name}\": the product of two textures is not supported: the first used"),
                        )?;
                        self.textures.insert((float, name), t);
                        self.check_unused(&format!("Texture \"{kind}\""), params, at)?;
                        return Ok(());
                    }
                }
            }
            other => {
                self.unsupported(at, format!("Texture \"{other}\" is not supported: grey 0.5 used"))?;
                for p in &params.list {
                    p.used.set(true);
                }
                TextureDescription::constant([0.5; 3])
            }
        };
        self.check_unused(&format!("Texture \"{kind}\""), params, at)?;
        self.out.origins.insert(format!("texture {key}"), (at.file.to_path_buf(), at.line));
        self.out.textures.insert(key.clone(), description);
        self.textures.insert((float, name), key);
        Ok(())
    }

    /// An operand of a texture of class `float` (or spectrum): a texture of the same class by
    /// name, or a value.
    pub(super) fn operand(&mut self, params: &Params, name: &str, float: bool, at: &At) -> Result<Colour> {
        match params.get(name).map(|p| (p.kind.clone(), p.values.clone())) {
            Some((k, Values::Texts(v))) if k == "texture" && v.len() == 1 => {
                match self.textures.get(&(float, v[0].clone())) {
                    Some(t) => Ok(Colour::Texture(t.clone())),
                    None => Err(syntax(at, format!("\"texture {name}\": no such texture \"{}\" (before it)", v[0]))),
                }
            }
            _ => self.colour(params, name, [1.0; 3], at),
        }
    }

    /// pbrt's `uv` mapping with its scale and shift (`s = su·u + du`, `t = sv·v + dv`), as a
    /// map of texture coordinates; other mappings are not supported.
    pub(super) fn mapping(&mut self, params: &Params, at: &At) -> Result<Option<[[f32; 3]; 2]>> {
        let mapping = params.text("mapping", at)?;
        let (us, vs) = (params.float("uscale", 1.0, at)?, params.float("vscale", 1.0, at)?);
        let (ud, vd) = (params.float("udelta", 0.0, at)?, params.float("vdelta", 0.0, at)?);
        if mapping.as_deref().is_some_and(|m| m != "uv") {
            self.unsupported(at, "a texture mapping other than uv (spherical, cylindrical, planar): uv used".into())?;
        }
        Ok(((us, vs, ud, vd) != (1.0, 1.0, 0.0, 0.0))
            .then_some([[us as f32, 0.0, ud as f32], [0.0, vs as f32, vd as f32]]))
    }
}

/// Named spectra of pbrt-v4's glasses, as indices of refraction (their value near 550 nm).
pub(super) fn glass_ior(name: &str) -> Option<f32> {
    Some(match name {
        "glass-BK7" => 1.5168,
        "glass-BAF10" => 1.6700,
        "glass-FK51A" => 1.4866,
        "glass-LASF9" => 1.8503,
        "glass-F5" | "glass-SF5" => 1.6034,
        "glass-F10" | "glass-SF10" => 1.7283,
        "glass-F11" | "glass-SF11" => 1.7847,
        "fused silica" | "glass-FusedSilica" => 1.4585,
        _ => return None,
    })
}
