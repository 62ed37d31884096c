//! A material of the scene description turned into the scene's [`Material`]: its scattering
//! model (BSDF family and parameters, each family's allowed keys checked) and its texture
//! slots. Every front end (TOML, Mitsuba, pbrt, OBJ's MTL) reaches materials through here.
use super::description::{DistributionDescription, MaskingDescription, MaterialDescription};
use super::{Material, TextureSlots};
use crate::Result;
use crate::geometry::Vec3A;
use crate::material::microfacet::{Distribution, Masking, Microfacet};
use crate::material::{self, Bsdf, metals};
use std::collections::HashMap;
use std::path::Path;

use super::limits::*;
use super::mesh::*;

pub(super) fn material_from(
    path: &Path,
    name: &str,
    d: &MaterialDescription,
    texture_ids: &HashMap<String, u16>,
    mean_of: impl Fn(u16) -> Vec3A,
) -> Result<Material> {
    let err = |m: String| invalid(path, format!("material `{name}`: {m}"));
    let (diffuse, emission) = (vec3(d.diffuse), vec3(d.emission));
    if !diffuse.is_finite() || diffuse.min_element() < 0.0 || diffuse.max_element() > 1.0 {
        return Err(err(format!("diffuse reflectance must lie in [0, 1], got {:?}", d.diffuse)));
    }
    if !emission.is_finite() || emission.min_element() < 0.0 {
        return Err(err(format!("emission must be finite and non-negative, got {:?}", d.emission)));
    }
    // Samples are squared for the variance (kept in f32): beyond this a sample's square
    // overflows, and the image's error estimates become infinite.
    if emission.max_element() > MAX_EMISSION {
        return Err(err(format!("emission must be at most {MAX_EMISSION:e} per channel, got {:?}", d.emission)));
    }
    let bsdf = bsdf_from(d).map_err(err)?;
    if bsdf.transmits() && d.two_sided.is_some() {
        return Err(err("`two_sided` is for opaque materials (glass always has two sides)".into()));
    }
    if d.two_sided_emission && emission == Vec3A::ZERO {
        return Err(err("`two_sided_emission` needs an `emission`".into()));
    }
    let textures = texture_slots(d, &bsdf, texture_ids).map_err(err)?;
    // A textured plastic chooses its mirror by the texture's mean reflectance.
    let bsdf = match (bsdf, textures.reflectance) {
        (Bsdf::Plastic { eta, nonlinear, coat, .. }, Some(t)) => {
            Bsdf::plastic_with(mean_of(t), eta, coat.map_or(Microfacet::ggx(0.0), |c| c.mf), nonlinear)
        }
        (bsdf, _) => bsdf,
    };
    Ok(Material {
        bsdf,
        emission,
        two_sided: d.two_sided.unwrap_or(true),
        two_sided_emission: d.two_sided_emission,
        textures,
    })
}

/// The textures a material description names, checked against its type.
pub(super) fn texture_slots(
    d: &MaterialDescription,
    bsdf: &Bsdf,
    texture_ids: &HashMap<String, u16>,
) -> std::result::Result<TextureSlots, String> {
    let find = |key: &str, name: &Option<String>, applies: bool| -> std::result::Result<Option<u16>, String> {
        let Some(name) = name else { return Ok(None) };
        if !applies {
            return Err(format!("`{key}` does not apply to type \"{}\"", format!("{:?}", d.kind).to_lowercase()));
        }
        texture_ids.get(name).copied().map(Some).ok_or_else(|| format!("`{key}`: unknown texture `{name}`"))
    };
    let diffuse =
        find("diffuse_texture", &d.diffuse_texture, matches!(bsdf, Bsdf::Diffuse { .. } | Bsdf::Plastic { .. }))?;
    let specular = find("specular_texture", &d.specular_texture, matches!(bsdf, Bsdf::Conductor { .. }))?;
    let roughness = find(
        "roughness_texture",
        &d.roughness_texture,
        matches!(bsdf, Bsdf::Conductor { .. } | Bsdf::Dielectric { thin: false, .. }),
    )?;
    Ok(TextureSlots { reflectance: diffuse.or(specular), roughness })
}

/// The scattering model a material description asks for; keys that do not apply to its type
/// are errors.
pub(super) fn bsdf_from(d: &MaterialDescription) -> std::result::Result<Bsdf, String> {
    use crate::scene::description::MaterialKind as K;
    let kind = format!("{:?}", d.kind).to_lowercase();
    let allowed = match d.kind {
        K::Diffuse => material::diffuse::SCENE_KEYS,
        K::Conductor => material::conductor::SCENE_KEYS,
        K::Dielectric => material::dielectric::SCENE_KEYS,
        K::ThinDielectric => material::dielectric::THIN_SCENE_KEYS,
        K::Plastic => material::plastic::SCENE_KEYS,
        K::Interface => &[],
    };
    let given = [
        ("diffuse", d.diffuse != [0.0; 3] && d.kind != K::Diffuse),
        ("metal", d.metal.is_some()),
        ("eta", d.eta.is_some()),
        ("k", d.k.is_some()),
        ("specular", d.specular.is_some()),
        ("ior", d.ior.is_some()),
        ("exterior_ior", d.exterior_ior.is_some()),
        ("roughness", d.roughness.is_some()),
        ("distribution", d.distribution.is_some()),
        ("masking", d.masking.is_some()),
        ("nonlinear", d.nonlinear.is_some()),
    ];
    if let Some((key, _)) = given.iter().find(|(key, set)| *set && !allowed.contains(key)) {
        return Err(format!("`{key}` does not apply to type \"{kind}\""));
    }
    let alpha = d.roughness.unwrap_or(0.0);
    if !(alpha.is_finite() && (0.0..=1.0).contains(&alpha)) {
        return Err(format!("roughness must lie in [0, 1], got {alpha}"));
    }
    let distribution = match d.distribution {
        None | Some(DistributionDescription::Ggx) => Distribution::Ggx,
        Some(DistributionDescription::Beckmann) => Distribution::Beckmann,
    };
    let masking = match d.masking {
        None | Some(MaskingDescription::Correlated) => Masking::Correlated,
        Some(MaskingDescription::Separable) => Masking::Separable,
    };
    // A roughness texture sets α per hit: the material is rough whatever `roughness` says.
    let alpha = if d.roughness_texture.is_some() { alpha.max(Microfacet::MIN_ALPHA) } else { alpha };
    let rough = Microfacet::new(distribution, masking, alpha);
    // Defaults: glass 1.5; plastic 1.49 (Mitsuba's polypropylene); outside, vacuum. A
    // dielectric is an interface between two media, so its relative index may lie below 1
    // (ice seen from water, as pbrt-v4 and Mitsuba 3 allow); a plastic's coat is denser than
    // the air above it.
    let eta = |default: f32, interface: bool| -> std::result::Result<f32, String> {
        let (int, ext) = (d.ior.unwrap_or(default), d.exterior_ior.unwrap_or(1.0));
        let eta = int / ext;
        let finite = int.is_finite() && ext.is_finite() && eta.is_finite() && eta > 0.0;
        if interface {
            if !(finite && int > 0.0 && ext > 0.0 && (1e-2..=1e2).contains(&eta)) {
                return Err(format!(
                    "indices of refraction must be positive and finite, within a factor of 100 of each other, got {int} and {ext}"
                ));
            }
        } else if !(finite && int >= 1.0 && ext >= 1.0) {
            return Err(format!(
                "a plastic's indices of refraction must be finite and at least 1, got {int} and {ext}"
            ));
        }
        if (eta - 1.0).abs() < 1e-4 {
            return Err("interior and exterior index of refraction must differ".into());
        }
        Ok(eta)
    };
    let triple = |what: &str, v: [f32; 3], max: f32| {
        let ok = v.iter().all(|x| x.is_finite() && *x >= 0.0 && *x <= max);
        if ok { Ok(vec3(v)) } else { Err(format!("{what} must lie in [0, {max}] per channel, got {v:?}")) }
    };
    Ok(match d.kind {
        K::Diffuse => Bsdf::Diffuse { reflectance: vec3(d.diffuse) },
        K::Conductor => {
            let (eta, k) = match (&d.metal, d.eta, d.k) {
                (Some(m), None, None) => metals::lookup(m)
                    .ok_or_else(|| format!("unknown metal `{m}` (known: {})", metals::names().join(", ")))?,
                (None, Some(eta), Some(k)) => (triple("eta", eta, 1e3)?, triple("k", k, 1e3)?),
                (None, None, None) => metals::lookup("none").expect("the mirror is in the table"),
                _ => return Err("give either `metal` or both `eta` and `k`".into()),
            };
            let specular = triple("specular", d.specular.unwrap_or([1.0; 3]), 1.0)?;
            match Bsdf::conductor(eta, k, rough) {
                Bsdf::Conductor { eta, k, roughness, .. } => Bsdf::Conductor { eta, k, specular, roughness },
                other => other,
            }
        }
        K::Dielectric => Bsdf::dielectric(eta(1.5, true)?, rough),
        K::ThinDielectric => Bsdf::Dielectric { eta: eta(1.5, true)?, roughness: None, thin: true },
        K::Plastic => Bsdf::plastic_with(vec3(d.diffuse), eta(1.49, false)?, rough, d.nonlinear.unwrap_or(false)),
        K::Interface => Bsdf::interface(),
    })
}
