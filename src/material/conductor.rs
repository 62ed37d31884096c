//! Metals: a mirror, or microfacets (GGX or Beckmann, visible-normal sampling), reflecting
//! the Fresnel reflectance of a complex index of refraction (named metals in `metals.rs`).
use super::microfacet::Microfacet;
use super::{BsdfSample, fresnel, reflect};
use crate::geometry::{Vec2, Vec3A};

/// The keys of a scene file's material that a conductor reads.
pub const SCENE_KEYS: &[&str] = &["metal", "eta", "k", "specular", "roughness", "distribution", "masking"];

/// `f(wi, wo)` of a rough conductor (both directions above the surface).
#[inline]
pub(super) fn eval(mf: Microfacet, eta: Vec3A, k: Vec3A, specular: Vec3A, wi: Vec3A, wo: Vec3A) -> Vec3A {
    let h = (wi + wo).normalize_or_zero();
    if h == Vec3A::ZERO {
        return Vec3A::ZERO;
    }
    let f = fresnel::conductor(wi.dot(h), eta, k) * specular;
    f * (mf.d(h) * mf.g(wi, wo, h) / (4.0 * wi.z * wo.z))
}

/// The density of [`sample`] choosing `wo` (both directions above the surface).
#[inline]
pub(super) fn pdf(mf: Microfacet, wi: Vec3A, wo: Vec3A) -> f32 {
    let h = (wi + wo).normalize_or_zero();
    let cos = wo.dot(h);
    if h == Vec3A::ZERO || cos <= 0.0 {
        return 0.0;
    }
    mf.visible_pdf(wi, h) / (4.0 * cos)
}

/// A smooth conductor's mirror direction and its weight (`wi` above the surface).
#[inline]
pub(super) fn sample_mirror(eta: Vec3A, k: Vec3A, specular: Vec3A, wi: Vec3A) -> BsdfSample {
    let wo = Vec3A::new(-wi.x, -wi.y, wi.z);
    BsdfSample { wo, weight: fresnel::conductor(wi.z, eta, k) * specular, pdf: 1.0, delta: true }
}

/// A rough conductor's direction through a visible normal (`wi` above the surface).
#[inline]
pub(super) fn sample(mf: Microfacet, eta: Vec3A, k: Vec3A, specular: Vec3A, wi: Vec3A, u: Vec2) -> Option<BsdfSample> {
    let m = mf.sample_visible(wi, u);
    let wo = reflect(wi, m);
    let cos = wo.dot(m);
    if wo.z <= 0.0 || cos <= 0.0 {
        return None;
    }
    let pdf = mf.visible_pdf(wi, m) / (4.0 * cos);
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    // f·cos/pdf = F·G(wi, wo)/G1(wi).
    let weight = fresnel::conductor(wi.dot(m), eta, k) * specular * (mf.g(wi, wo, m) / mf.g1(wi, m));
    Some(BsdfSample { wo, weight, pdf, delta: false })
}
