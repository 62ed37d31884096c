//! Glass: smooth and rough dielectric interfaces (Walter et al. 2007, visible-normal
//! sampling), and thin sheets.
use super::microfacet::Microfacet;
use super::reflect;
use super::{BsdfSample, fresnel};
use crate::geometry::{Vec2, Vec3A};

/// The keys of a scene file's material that a dielectric reads.
pub const SCENE_KEYS: &[&str] = &["ior", "exterior_ior", "roughness", "distribution", "masking"];
/// The keys of a scene file's material that a thin dielectric reads.
pub const THIN_SCENE_KEYS: &[&str] = &["ior", "exterior_ior"];

/// `wi` and `wo` mirrored so that `wi` is on the +z side, and the relative index seen from
/// there (`eta` from outside, `1/eta` from inside).
#[inline]
pub(super) fn upper(eta: f32, wi: Vec3A, wo: Vec3A) -> (Vec3A, Vec3A, f32) {
    if wi.z >= 0.0 { (wi, wo, eta) } else { (-wi, -wo, 1.0 / eta) }
}

/// The refraction of `wi` (on `m`'s side, `cos_i = wi·m > 0`) through `m` into relative index
/// `eta`, given the transmitted cosine `cos_t` (negative).
#[inline]
pub(super) fn refract(wi: Vec3A, m: Vec3A, eta: f32, cos_i: f32, cos_t: f32) -> Vec3A {
    -wi / eta + (cos_i / eta + cos_t) * m
}

/// `f` and `pdf` of the rough dielectric (Walter et al. 2007; radiance scaled by `1/η²`).
pub(super) fn rough_dielectric(mf: Microfacet, eta: f32, wi: Vec3A, wo: Vec3A) -> (f32, f32) {
    let (wi, wo, eta) = upper(eta, wi, wo);
    if wi.z == 0.0 || wo.z == 0.0 {
        return (0.0, 0.0);
    }
    if wo.z > 0.0 {
        let m = (wi + wo).normalize_or_zero();
        let c = wi.dot(m);
        if m == Vec3A::ZERO || c <= 0.0 {
            return (0.0, 0.0);
        }
        let f = fresnel::dielectric(c, eta).0;
        let value = f * mf.d(m) * mf.g(wi, wo, m) / (4.0 * wi.z * wo.z);
        let pdf = f * mf.visible_pdf(wi, m) / (4.0 * wo.dot(m));
        (value, pdf)
    } else {
        // The half vector of a refraction, facing +z.
        let mut m = (wi + eta * wo).normalize_or_zero();
        if m.z < 0.0 {
            m = -m;
        }
        let (ci, co) = (wi.dot(m), wo.dot(m));
        if m == Vec3A::ZERO || ci <= 0.0 || co >= 0.0 {
            return (0.0, 0.0);
        }
        // Fresnel from both cosines: Snell's cos θt = √(1 − sin²θt) cancels near the critical
        // angle (from the denser side), where f32 put f(wi, wo) 0.15% off f(wo, wi).
        let f = fresnel::dielectric_cosines(ci, -co, eta);
        let denom = ci + eta * co;
        let value = (1.0 - f) * mf.d(m) * mf.g(wi, wo, m) * ci * (-co) / (wi.z * -wo.z * denom * denom);
        let pdf = (1.0 - f) * mf.visible_pdf(wi, m) * eta * eta * (-co) / (denom * denom);
        (value, pdf)
    }
}

/// Samples glass: Fresnel picks reflection or refraction (so `F` cancels from the weight).
pub(super) fn sample_dielectric(
    eta: f32,
    roughness: Option<Microfacet>,
    thin: bool,
    wi: Vec3A,
    u_lobe: f32,
    u: Vec2,
) -> Option<BsdfSample> {
    if wi.z == 0.0 {
        return None;
    }
    let flip = if wi.z > 0.0 { 1.0 } else { -1.0 };
    let (wi_up, _, eta_up) = upper(eta, wi, wi);
    if thin {
        // A sheet: reflectance R + T²R/(1 − R²) of the two surfaces, the rest straight through.
        // (Index 1, a medium's boundary: exactly nothing is reflected.)
        let r = if eta == 1.0 { 0.0 } else { fresnel::dielectric(wi_up.z, eta).0 };
        let r = if r < 1.0 { r + (1.0 - r) * (1.0 - r) * r / (1.0 - r * r) } else { 1.0 };
        let wo = if u_lobe < r { Vec3A::new(-wi.x, -wi.y, wi.z) } else { -wi };
        return Some(BsdfSample { wo, weight: Vec3A::ONE, pdf: 1.0, delta: true });
    }
    let Some(mf) = roughness else {
        let (f, cos_t, eta_t) = fresnel::dielectric(wi_up.z, eta_up);
        let (wo, weight) = if u_lobe < f {
            (Vec3A::new(-wi_up.x, -wi_up.y, wi_up.z), 1.0)
        } else {
            (refract(wi_up, Vec3A::Z, eta_t, wi_up.z, cos_t), 1.0 / (eta_t * eta_t))
        };
        return Some(BsdfSample { wo: wo * flip, weight: Vec3A::splat(weight), pdf: 1.0, delta: true });
    };
    let m = mf.sample_visible(wi_up, u);
    let ci = wi_up.dot(m);
    if ci <= 0.0 {
        return None;
    }
    let (f, cos_t, eta_t) = fresnel::dielectric(ci, eta_up);
    let (wo, weight) = if u_lobe < f {
        let wo = reflect(wi_up, m);
        if wo.z <= 0.0 {
            return None;
        }
        (wo, 1.0)
    } else {
        let wo = refract(wi_up, m, eta_t, ci, cos_t);
        if wo.z >= 0.0 {
            return None;
        }
        (wo, 1.0 / (eta_t * eta_t))
    };
    let (_, pdf) = rough_dielectric(mf, eta_up, wi_up, wo);
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    let g = mf.g(wi_up, wo, m) / mf.g1(wi_up, m);
    Some(BsdfSample { wo: wo * flip, weight: Vec3A::splat(weight * g), pdf, delta: false })
}
