//! Scattering models in the local shading frame (+z the shading normal, `wi` toward the
//! viewer, `wo` the scattered direction, both unit): the [`Bsdf`] enum with static dispatch to
//! one file per family — `diffuse.rs`, `conductor.rs` (named metals in `metals.rs`),
//! `dielectric.rs`, `plastic.rs` — each with `eval` (the BSDF value `f`, no cosine), `pdf`
//! (solid angle, of [`Bsdf::sample`]'s non-delta directions), `sample` (a direction and its
//! weight `f·|cos θo|/pdf`) and the scene-file keys it reads (`SCENE_KEYS`); a flag for delta
//! lobes (whose `eval` and `pdf` are 0: only `sample` reaches them). Shared pieces:
//! `fresnel.rs`, `microfacet.rs`.
//!
//! Surfaces are one-sided as in Mitsuba 3: `wi.z ≤ 0` scatters nothing; a two-sided surface
//! is handled by its caller flipping the frame to the viewer's side.
//!
//! A scene's [`crate::scene::Material`] holds one; the integrators build the local frame at
//! each hit ([`crate::scene::SurfaceInteraction::bsdf_frame`]). Adding a family: its file, a
//! variant of [`Bsdf`] with an arm in each method, and the importers' translation tables.
pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod fresnel;
pub mod metals;
pub mod microfacet;
pub mod plastic;

pub use plastic::{COAT_TABLE, RoughCoat, diffuse_fresnel};

use crate::geometry::{Vec2, Vec3A};
use microfacet::Microfacet;

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
// An explicit tag decodes in one load (the niche-packed one took a dozen instructions: 0.3%
// of `path` on cornell-paper). Each variant is then laid out as declared, tag first: the small
// fields come first, in the 15 bytes beside the tag, so the vectors stay at 16..64.
#[repr(u8)]
pub enum Bsdf {
    /// Lambertian reflection, `f = ρ/π`.
    Diffuse { reflectance: Vec3A },
    /// A metal: Fresnel reflectance of the complex index `eta + i·k`, times `specular`; a
    /// mirror without roughness, microfacets with it (GGX or Beckmann, visible-normal
    /// sampling, Smith masking height-correlated or separable).
    Conductor { roughness: Option<Microfacet>, eta: Vec3A, k: Vec3A, specular: Vec3A },
    /// Glass: reflection and refraction at an interface of relative index `eta` (inside over
    /// outside; +z is the outside), smooth or rough (Walter et al. 2007, sampled through
    /// visible normals, Fresnel choosing between the lobes). Radiance is scaled by `1/η²`
    /// crossing into a medium of relative index `η`, as Mitsuba 3 does in radiance mode.
    /// `thin`: a smooth thin sheet, both surfaces at once (inter-reflections summed; light
    /// passes straight through, unscaled).
    Dielectric { eta: f32, roughness: Option<Microfacet>, thin: bool },
    /// Smooth plastic (Mitsuba's `plastic`): a diffuse base of reflectance `diffuse` under a
    /// smooth dielectric coat of index `eta`. The coat reflects `F(θi)` as a mirror (a delta
    /// lobe); the rest enters, scatters diffusely with inter-reflections under the coat
    /// (internal diffuse Fresnel reflectance `fdr_int`: `ρ/(1 − fdr_int)`, or with
    /// `nonlinear` `ρ/(1 − ρ·fdr_int)`), and leaves through `1 − F(θo)`, scaled by `1/η²`.
    /// `specular_share` is the share of [`Bsdf::sample`]'s choices given to the mirror before
    /// Fresnel weighting.
    ///
    /// With a `coat`, rough plastic (Mitsuba's `roughplastic`): the coat reflects as a rough
    /// dielectric interface (microfacets), and the base's light enters and leaves through the coat's
    /// tabulated transmittance `T(θ) = 1 − R(θ)` instead of `1 − F(θ)`, `fdr_int` being the
    /// rough interface's internal reflectance of diffuse light.
    Plastic { eta: f32, fdr_int: f32, specular_share: f32, nonlinear: bool, coat: Option<RoughCoat>, diffuse: Vec3A },
}

/// Mirror `w` about `m`.
#[inline]
pub(super) fn reflect(w: Vec3A, m: Vec3A) -> Vec3A {
    2.0 * w.dot(m) * m - w
}

/// Roughness below which a glossy lobe is too narrow for a learned density to sample it: a
/// direction a guide picks almost never falls in a lobe of this width.
pub const GUIDE_MIN_ALPHA: f32 = 0.1;

impl Bsdf {
    /// Whether a guided integrator mixes its guide into this BSDF's sampling: not where every
    /// lobe is delta or near-specular (a glossy lobe narrower than [`GUIDE_MIN_ALPHA`]); a
    /// plastic's diffuse base is always worth guiding. The others are the specular vertices
    /// that caustic photons leave from.
    #[inline]
    #[must_use]
    pub fn is_guidable(&self) -> bool {
        let rough = |r: &Option<microfacet::Microfacet>| r.is_some_and(|m| m.alpha >= GUIDE_MIN_ALPHA);
        match self {
            Bsdf::Diffuse { .. } | Bsdf::Plastic { .. } => true,
            Bsdf::Conductor { roughness, .. } => rough(roughness),
            Bsdf::Dielectric { roughness, thin, .. } => !thin && rough(roughness),
        }
    }

    /// A conductor with microfacets `rough` (smooth below [`Microfacet::MIN_ALPHA`]).
    #[must_use]
    pub fn conductor(eta: Vec3A, k: Vec3A, rough: Microfacet) -> Self {
        let roughness = (rough.alpha >= Microfacet::MIN_ALPHA).then_some(rough);
        Bsdf::Conductor { eta, k, specular: Vec3A::ONE, roughness }
    }

    /// Glass of relative index `eta` with microfacets `rough` (smooth below
    /// [`Microfacet::MIN_ALPHA`]).
    #[must_use]
    pub fn dielectric(eta: f32, rough: Microfacet) -> Self {
        let roughness = (rough.alpha >= Microfacet::MIN_ALPHA).then_some(rough);
        Bsdf::Dielectric { eta, roughness, thin: false }
    }

    /// No surface: the boundary of a participating medium, which light crosses unchanged (a
    /// thin sheet of index 1, which reflects nothing).
    #[must_use]
    pub fn interface() -> Self {
        Bsdf::Dielectric { eta: 1.0, roughness: None, thin: true }
    }

    /// Whether this is [`Bsdf::interface`]: a path crossing it has not scattered.
    #[inline]
    #[must_use]
    pub fn is_interface(&self) -> bool {
        matches!(self, Bsdf::Dielectric { eta, thin: true, .. } if *eta == 1.0)
    }

    /// Smooth plastic: diffuse `reflectance` under a coat of index `eta` (Mitsuba's defaults:
    /// `eta` 1.49, linear).
    #[must_use]
    pub fn plastic(reflectance: Vec3A, eta: f32, nonlinear: bool) -> Self {
        Self::plastic_with(reflectance, eta, Microfacet::ggx(0.0), nonlinear)
    }

    /// Plastic with a coat of microfacets `rough`: smooth below [`Microfacet::MIN_ALPHA`],
    /// else Mitsuba's `roughplastic`.
    #[must_use]
    pub fn plastic_with(reflectance: Vec3A, eta: f32, rough: Microfacet, nonlinear: bool) -> Self {
        // Mitsuba's choice: the mirror's share by the mean of the specular reflectance (1)
        // against the diffuse one.
        let mean = (reflectance.x + reflectance.y + reflectance.z) / 3.0;
        let (coat, fdr_int) = if rough.alpha >= Microfacet::MIN_ALPHA {
            let (coat, fdr) = plastic::rough_coat(rough, eta);
            (Some(coat), fdr)
        } else {
            (None, diffuse_fresnel(1.0 / eta))
        };
        Bsdf::Plastic { diffuse: reflectance, eta, fdr_int, nonlinear, specular_share: 1.0 / (1.0 + mean), coat }
    }

    /// The BSDF at a hit where textures give the `reflectance` (a diffuse surface's, a
    /// plastic's base, a conductor's `specular` factor) and the microfacets' `alpha` (of a
    /// rough conductor or a rough dielectric that is not thin): the step from a material and
    /// its textures to the BSDF a hit scatters with (pbrt's `GetBxDF`).
    #[inline]
    pub fn set_textured(&mut self, reflectance: Option<Vec3A>, alpha: Option<f32>) {
        if let Some(r) = reflectance {
            match self {
                Bsdf::Diffuse { reflectance } => *reflectance = r,
                Bsdf::Plastic { diffuse, .. } => *diffuse = r,
                Bsdf::Conductor { specular, .. } => *specular = r,
                Bsdf::Dielectric { .. } => {}
            }
        }
        if let Some(alpha) = alpha {
            match self {
                // (The material's own microfacets, made rough by its loader, take the α.)
                Bsdf::Conductor { roughness: Some(r), .. }
                | Bsdf::Dielectric { roughness: Some(r), thin: false, .. } => {
                    r.alpha = alpha;
                }
                _ => {}
            }
        }
    }

    /// A stand-in for the share of light scattered, per channel, for decisions that only
    /// steer sampling (Russian roulette, the photon guide's radiance estimates): the
    /// reflectance of a diffuse surface or plastic base, a metal's reflectance at normal
    /// incidence, 1 for glass.
    #[must_use]
    #[inline]
    pub fn albedo(&self) -> Vec3A {
        // Matched by reference: a copy of the whole enum per vertex showed in profiles.
        match self {
            Bsdf::Diffuse { reflectance } => *reflectance,
            Bsdf::Conductor { eta, k, specular, .. } => fresnel::conductor(1.0, *eta, *k) * *specular,
            Bsdf::Dielectric { .. } => Vec3A::ONE,
            Bsdf::Plastic { diffuse, eta, .. } => {
                let f0 = fresnel::dielectric(1.0, *eta).0;
                (*diffuse * (1.0 - f0) + Vec3A::splat(f0)).min(Vec3A::ONE)
            }
        }
    }

    /// Whether every direction it scatters to is a delta lobe (no NEE, no guiding through it).
    #[inline]
    #[must_use]
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Bsdf::Conductor { roughness: None, .. }
                | Bsdf::Dielectric { roughness: None, .. }
                | Bsdf::Dielectric { thin: true, .. }
        )
    }

    /// Whether some direction it scatters to is a delta lobe (a mirror, smooth glass, a smooth
    /// plastic's coat).
    #[inline]
    #[must_use]
    pub fn has_delta_lobe(&self) -> bool {
        self.is_delta() || matches!(self, Bsdf::Plastic { coat: None, .. })
    }

    /// Whether light passes through (both sides are lit and seen).
    #[inline]
    #[must_use]
    pub fn transmits(&self) -> bool {
        matches!(self, Bsdf::Dielectric { .. })
    }

    /// `f(wi, wo)` (0 for delta lobes).
    #[must_use]
    pub fn eval(&self, wi: Vec3A, wo: Vec3A) -> Vec3A {
        if let Bsdf::Dielectric { eta, roughness, thin } = *self {
            return match roughness {
                Some(mf) if !thin => Vec3A::splat(dielectric::rough_dielectric(mf, eta, wi, wo).0),
                _ => Vec3A::ZERO,
            };
        }
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Vec3A::ZERO;
        }
        match *self {
            Bsdf::Dielectric { .. } => Vec3A::ZERO,
            Bsdf::Plastic { diffuse, eta, fdr_int, nonlinear, coat, .. } => {
                plastic::eval(diffuse, eta, fdr_int, nonlinear, coat.as_ref(), wi, wo)
            }
            Bsdf::Diffuse { reflectance } => diffuse::eval(reflectance),
            Bsdf::Conductor { roughness: None, .. } => Vec3A::ZERO,
            Bsdf::Conductor { eta, k, specular, roughness: Some(mf) } => conductor::eval(mf, eta, k, specular, wi, wo),
        }
    }

    /// Density of [`Bsdf::sample`] choosing `wo` (its non-delta part).
    #[must_use]
    pub fn pdf(&self, wi: Vec3A, wo: Vec3A) -> f32 {
        if let Bsdf::Dielectric { eta, roughness, thin } = *self {
            return match roughness {
                Some(mf) if !thin => dielectric::rough_dielectric(mf, eta, wi, wo).1,
                _ => 0.0,
            };
        }
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match *self {
            Bsdf::Dielectric { .. } => 0.0,
            Bsdf::Plastic { eta, specular_share, coat, .. } => plastic::pdf(eta, specular_share, coat.as_ref(), wi, wo),
            Bsdf::Diffuse { .. } => diffuse::pdf(wo),
            Bsdf::Conductor { roughness: None, .. } => 0.0,
            Bsdf::Conductor { roughness: Some(mf), .. } => conductor::pdf(mf, wi, wo),
        }
    }

    /// The probability that [`Bsdf::sample`] takes a plastic's diffuse base (a cosine
    /// direction) rather than its coat at `wi`: it does so exactly when `u_lobe` is at least
    /// `1 −` this. `None` for every other BSDF.
    #[inline]
    #[must_use]
    pub fn base_probability(&self, wi: Vec3A) -> Option<f32> {
        match *self {
            Bsdf::Plastic { eta, specular_share, coat, .. } if wi.z > 0.0 => {
                Some(1.0 - plastic::mirror_probability(eta, specular_share, coat.as_ref(), wi.z))
            }
            _ => None,
        }
    }

    /// A scattered direction for `wi`: `u_lobe` chooses a lobe (reflection or refraction),
    /// `u` in `[0,1)²` the direction; `None` when nothing scatters.
    #[must_use]
    pub fn sample(&self, wi: Vec3A, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if let Bsdf::Dielectric { eta, roughness, thin } = *self {
            return dielectric::sample_dielectric(eta, roughness, thin, wi, u_lobe, u);
        }
        if wi.z <= 0.0 {
            return None;
        }
        match *self {
            Bsdf::Dielectric { .. } => None,
            Bsdf::Plastic { .. } => plastic::sample(self, wi, u_lobe, u),
            Bsdf::Diffuse { reflectance } => diffuse::sample(reflectance, u),
            Bsdf::Conductor { eta, k, specular, roughness: None } => {
                Some(conductor::sample_mirror(eta, k, specular, wi))
            }
            Bsdf::Conductor { eta, k, specular, roughness: Some(mf) } => conductor::sample(mf, eta, k, specular, wi, u),
        }
    }
}

#[cfg(test)]
mod tests;
