//! Scattering models beyond the Lambertian wall (issue #11), in the local shading frame (+z
//! the shading normal, `wi` toward the viewer, `wo` the scattered direction, both unit): an
//! enum with static dispatch, each model with `eval` (the BSDF value `f`, no cosine), `pdf`
//! (solid angle, of [`Bsdf::sample`]'s non-delta directions) and `sample` (a direction and its
//! weight `f·|cos θo|/pdf`), and a flag for delta lobes (whose `eval` and `pdf` are 0: only
//! `sample` reaches them).
//!
//! Surfaces are one-sided as in Mitsuba 3: `wi.z ≤ 0` scatters nothing; a two-sided surface
//! is handled by its caller flipping the frame to the viewer's side.
//!
//! This module is not yet wired into the scene and the integrators (they still use the
//! Lambertian `scene::Material`); it holds the models and their tests (chi-square against
//! `pdf`, weights, reciprocity, energy).
pub mod fresnel;
pub mod microfacet;

use crate::geometry::{Vec2, Vec3A};
use microfacet::Ggx;
use std::f32::consts::FRAC_1_PI;

/// A sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub wo: Vec3A,
    /// `f·|cos θo| / pdf` (for a delta lobe, the lobe's weight).
    pub weight: Vec3A,
    /// Solid-angle density (1 for a delta lobe, by convention; never used as a density).
    pub pdf: f32,
    pub delta: bool,
}

/// A scattering model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// Lambertian reflection, `f = ρ/π`.
    Diffuse { reflectance: Vec3A },
    /// A metal: Fresnel reflectance of the complex index `eta + i·k`, times `specular`; a
    /// mirror without roughness, GGX microfacets with it (visible-normal sampling, Smith
    /// height-correlated masking).
    Conductor { eta: Vec3A, k: Vec3A, specular: Vec3A, roughness: Option<Ggx> },
}

/// Mirror `w` about `m`.
#[inline]
fn reflect(w: Vec3A, m: Vec3A) -> Vec3A {
    2.0 * w.dot(m) * m - w
}

impl Bsdf {
    /// A conductor of roughness `alpha` (smooth below [`Ggx::MIN_ALPHA`]).
    #[must_use]
    pub fn conductor(eta: Vec3A, k: Vec3A, alpha: f32) -> Self {
        let roughness = (alpha >= Ggx::MIN_ALPHA).then(|| Ggx::new(alpha));
        Bsdf::Conductor { eta, k, specular: Vec3A::ONE, roughness }
    }

    /// Whether every direction it scatters to is a delta lobe (no NEE, no guiding through it).
    #[must_use]
    pub fn is_delta(&self) -> bool {
        matches!(self, Bsdf::Conductor { roughness: None, .. })
    }

    /// `f(wi, wo)` (0 for delta lobes).
    #[must_use]
    pub fn eval(&self, wi: Vec3A, wo: Vec3A) -> Vec3A {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Vec3A::ZERO;
        }
        match *self {
            Bsdf::Diffuse { reflectance } => reflectance * FRAC_1_PI,
            Bsdf::Conductor { roughness: None, .. } => Vec3A::ZERO,
            Bsdf::Conductor { eta, k, specular, roughness: Some(ggx) } => {
                let h = (wi + wo).normalize_or_zero();
                if h == Vec3A::ZERO {
                    return Vec3A::ZERO;
                }
                let f = fresnel::conductor(wi.dot(h), eta, k) * specular;
                f * (ggx.d(h) * ggx.g(wi, wo, h) / (4.0 * wi.z * wo.z))
            }
        }
    }

    /// Density of [`Bsdf::sample`] choosing `wo` (its non-delta part).
    #[must_use]
    pub fn pdf(&self, wi: Vec3A, wo: Vec3A) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match *self {
            Bsdf::Diffuse { .. } => wo.z * FRAC_1_PI,
            Bsdf::Conductor { roughness: None, .. } => 0.0,
            Bsdf::Conductor { roughness: Some(ggx), .. } => {
                let h = (wi + wo).normalize_or_zero();
                let cos = wo.dot(h);
                if h == Vec3A::ZERO || cos <= 0.0 {
                    return 0.0;
                }
                ggx.visible_pdf(wi, h) / (4.0 * cos)
            }
        }
    }

    /// A scattered direction for `wi`, from `u` in `[0,1)²`; `None` when nothing scatters.
    #[must_use]
    pub fn sample(&self, wi: Vec3A, u: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        match *self {
            Bsdf::Diffuse { reflectance } => {
                let wo = crate::geometry::warp::cosine_hemisphere(u);
                (wo.z > 0.0).then_some(BsdfSample { wo, weight: reflectance, pdf: wo.z * FRAC_1_PI, delta: false })
            }
            Bsdf::Conductor { eta, k, specular, roughness: None } => {
                let wo = Vec3A::new(-wi.x, -wi.y, wi.z);
                Some(BsdfSample { wo, weight: fresnel::conductor(wi.z, eta, k) * specular, pdf: 1.0, delta: true })
            }
            Bsdf::Conductor { eta, k, specular, roughness: Some(ggx) } => {
                let m = ggx.sample_visible(wi, u);
                let wo = reflect(wi, m);
                let cos = wo.dot(m);
                if wo.z <= 0.0 || cos <= 0.0 {
                    return None;
                }
                let pdf = ggx.visible_pdf(wi, m) / (4.0 * cos);
                if !(pdf > 0.0 && pdf.is_finite()) {
                    return None;
                }
                // f·cos/pdf = F·G(wi, wo)/G1(wi).
                let weight = fresnel::conductor(wi.dot(m), eta, k) * specular * (ggx.g(wi, wo, m) / ggx.g1(wi, m));
                Some(BsdfSample { wo, weight, pdf, delta: false })
            }
        }
    }
}

#[cfg(test)]
mod tests;
