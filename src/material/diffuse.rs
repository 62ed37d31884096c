//! Lambertian reflection, `f = ρ/π`, sampled by the cosine.
use super::BsdfSample;
use crate::geometry::{Vec2, Vec3A, warp};
use std::f32::consts::FRAC_1_PI;

/// The keys of a scene file's material that a diffuse one reads.
pub const SCENE_KEYS: &[&str] = &["diffuse"];

/// `f(wi, wo)` (both directions above the surface).
#[inline]
pub(super) fn eval(reflectance: Vec3A) -> Vec3A {
    reflectance * FRAC_1_PI
}

/// The density of [`sample`]'s `wo` (above the surface).
#[inline]
pub(super) fn pdf(wo: Vec3A) -> f32 {
    wo.z * FRAC_1_PI
}

/// A cosine-distributed direction, weighted by the reflectance.
#[inline]
pub(super) fn sample(reflectance: Vec3A, u: Vec2) -> Option<BsdfSample> {
    let wo = warp::cosine_hemisphere(u);
    (wo.z > 0.0).then_some(BsdfSample { wo, weight: reflectance, pdf: wo.z * FRAC_1_PI, delta: false })
}
