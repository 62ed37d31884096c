//! Scattering models beyond the Lambertian wall, in the local shading frame (+z
//! the shading normal, `wi` toward the viewer, `wo` the scattered direction, both unit): an
//! enum with static dispatch, each model with `eval` (the BSDF value `f`, no cosine), `pdf`
//! (solid angle, of [`Bsdf::sample`]'s non-delta directions) and `sample` (a direction and its
//! weight `f·|cos θo|/pdf`), and a flag for delta lobes (whose `eval` and `pdf` are 0: only
//! `sample` reaches them).
//!
//! Surfaces are one-sided as in Mitsuba 3: `wi.z ≤ 0` scatters nothing; a two-sided surface
//! is handled by its caller flipping the frame to the viewer's side.
//!
//! A scene's [`crate::scene::Material`] holds one; the integrators build the local frame at
//! each hit ([`crate::scene::SurfaceInteraction::bsdf_frame`]).
pub mod cie;
pub mod conductors;
pub mod fresnel;
pub mod microfacet;

use crate::geometry::{Vec2, Vec3A};
use microfacet::Microfacet;
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

/// Entries of a rough plastic's transmittance table, over `cos θ ∈ [0, 1]` (Mitsuba's 64).
pub const COAT_TABLE: usize = 64;

/// A rough plastic's coat: its microfacets and the share of light it lets through at each
/// incidence, `T(cos θ)` tabulated at `COAT_TABLE` equally spaced cosines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughCoat {
    pub mf: Microfacet,
    pub transmittance: &'static [f32; COAT_TABLE],
}

impl RoughCoat {
    /// `T(cos θ)`, interpolated linearly in the table.
    #[inline]
    #[must_use]
    pub fn transmittance(&self, cos: f32) -> f32 {
        let x = cos.clamp(0.0, 1.0) * (COAT_TABLE - 1) as f32;
        let i = (x as usize).min(COAT_TABLE - 2);
        let w = x - i as f32;
        self.transmittance[i] * (1.0 - w) + self.transmittance[i + 1] * w
    }
}

/// The mean of `w(m)` over the normals visible from `wi`, by a midpoint rule of 64 × 64 over
/// the visible-normal sampling's square (non-finite values count 0).
fn visible_mean(mf: Microfacet, wi: Vec3A, w: impl Fn(Vec3A) -> f32) -> f64 {
    const N: usize = 64;
    let mut sum = 0.0f64;
    for a in 0..N {
        for b in 0..N {
            let u = Vec2::new((a as f32 + 0.5) / N as f32, (b as f32 + 0.5) / N as f32);
            let v = w(mf.sample_visible(wi, u));
            if v.is_finite() {
                sum += f64::from(v);
            }
        }
    }
    sum / (N * N) as f64
}

/// The directional albedo of a rough dielectric interface's reflection for incidence `wi`, as
/// Mitsuba 3 tabulates it: over visible normals `m`, the mean of `F(wi·m)·G1(wo, m)` (its
/// uncorrelated masking).
fn rough_reflectance(mf: Microfacet, eta: f32, wi: Vec3A) -> f64 {
    visible_mean(mf, wi, |m| {
        let (wo, c) = (reflect(wi, m), wi.dot(m));
        if wo.z > 0.0 && c > 0.0 { fresnel::dielectric(c, eta).0 * mf.g1(wo, m) } else { 0.0 }
    })
}

/// The share of light from `wi` that a rough dielectric interface lets through, as Mitsuba 3
/// (since 3.0's `eval_transmittance`) tabulates a rough plastic's coat: over visible normals
/// `m`, the mean of `(1 − F(wi·m))·G1(wt, m)` with `wt` the refracted direction, so that
/// refracted light the microsurface masks does not reach the base. (`1 − R`, which ignores that
/// masking, is 13% higher at `cos θ = 0.1` for `α = 0.15`, `η = 1.5`: Mitsuba's images differed
/// by that much.)
fn rough_transmittance(mf: Microfacet, eta: f32, wi: Vec3A) -> f64 {
    visible_mean(mf, wi, |m| {
        let c = wi.dot(m);
        if c <= 0.0 {
            return 0.0;
        }
        let (f, cos_t, eta_it) = fresnel::dielectric(c, eta);
        let wt = refract(wi, m, eta_it, c, cos_t);
        if f < 1.0 && wt.z < 0.0 { (1.0 - f) * mf.g1(wt, m) } else { 0.0 }
    })
}

/// A rough coat's table and internal diffuse reflectance, as Mitsuba 3 computes them: `T` at
/// cosines `max(1e-6, i/63)`, and `2·mean(R_inside(μ)·μ)` over the same cosines with the
/// relative index inverted. Each (α, η) is computed once per process and kept (a table is
/// 256 bytes; a scene's materials hold references to it, so the BSDF stays `Copy`).
fn rough_coat(mf: Microfacet, eta: f32) -> (RoughCoat, f32) {
    use microfacet::Distribution;
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    type Tables = HashMap<(Distribution, u32, u32), (&'static [f32; COAT_TABLE], f32)>;
    static TABLES: OnceLock<Mutex<Tables>> = OnceLock::new();
    // The table depends on the distribution, not on how masking and shadowing combine.
    let key = (mf.distribution, mf.alpha.to_bits(), eta.to_bits());
    let mut tables = TABLES.get_or_init(Mutex::default).lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let (table, fdr) = *tables.entry(key).or_insert_with(|| {
        let mut table = [0.0f32; COAT_TABLE];
        let mut inside = 0.0f64;
        for (i, t) in table.iter_mut().enumerate() {
            let mu = (i as f32 / (COAT_TABLE - 1) as f32).max(1e-6);
            let wi = Vec3A::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
            *t = rough_transmittance(mf, eta, wi) as f32;
            inside += rough_reflectance(mf, 1.0 / eta, wi) * f64::from(mu);
        }
        (&*Box::leak(Box::new(table)), (2.0 * inside / COAT_TABLE as f64) as f32)
    });
    (RoughCoat { mf, transmittance: table }, fdr)
}

/// Diffuse Fresnel reflectance: `2 ∫₀¹ F(μ, eta) μ dμ`, the share of uniformly diffuse light
/// an interface of relative index `eta` reflects (midpoint rule, 2048 steps: error < 1e-6).
#[must_use]
pub fn diffuse_fresnel(eta: f32) -> f32 {
    let n = 2048;
    let mut sum = 0.0f64;
    for i in 0..n {
        let mu = (i as f32 + 0.5) / n as f32;
        sum += f64::from(fresnel::dielectric(mu, eta).0 * mu);
    }
    (2.0 * sum / f64::from(n)) as f32
}

/// Mirror `w` about `m`.
#[inline]
fn reflect(w: Vec3A, m: Vec3A) -> Vec3A {
    2.0 * w.dot(m) * m - w
}

impl Bsdf {
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
            let (coat, fdr) = rough_coat(rough, eta);
            (Some(coat), fdr)
        } else {
            (None, diffuse_fresnel(1.0 / eta))
        };
        Bsdf::Plastic { diffuse: reflectance, eta, fdr_int, nonlinear, specular_share: 1.0 / (1.0 + mean), coat }
    }

    /// The share of light a plastic's coat lets in at incidence `cos`: `1 − F`, or the rough
    /// coat's tabulated transmittance.
    #[inline]
    fn coat_transmittance(eta: f32, coat: Option<&RoughCoat>, cos: f32) -> f32 {
        match coat {
            Some(c) => c.transmittance(cos),
            None => 1.0 - fresnel::dielectric(cos, eta).0,
        }
    }

    /// Probability that [`Bsdf::sample`] takes a plastic's coat (mirror or rough reflection)
    /// at incidence `cos_i`.
    fn plastic_mirror_probability(eta: f32, specular_share: f32, coat: Option<&RoughCoat>, cos_i: f32) -> f32 {
        let (r, t) = match coat {
            Some(c) => {
                let t = c.transmittance(cos_i);
                (1.0 - t, t)
            }
            None => {
                let f = fresnel::dielectric(cos_i, eta).0;
                (f, 1.0 - f)
            }
        };
        let s = r * specular_share;
        s / (s + t * (1.0 - specular_share))
    }

    /// A plastic's diffuse value `f` (no cosine).
    fn plastic_diffuse(
        diffuse: Vec3A,
        eta: f32,
        fdr_int: f32,
        nonlinear: bool,
        coat: Option<&RoughCoat>,
        wi: Vec3A,
        wo: Vec3A,
    ) -> Vec3A {
        let (ti, to) = (Self::coat_transmittance(eta, coat, wi.z), Self::coat_transmittance(eta, coat, wo.z));
        let base = if nonlinear { diffuse / (Vec3A::ONE - diffuse * fdr_int) } else { diffuse / (1.0 - fdr_int) };
        base * (ti * to * FRAC_1_PI / (eta * eta))
    }

    /// A rough coat's reflection `f` (no cosine) and its density under visible-normal
    /// sampling (before the lobe's probability).
    fn coat_reflection(coat: &RoughCoat, eta: f32, wi: Vec3A, wo: Vec3A) -> (f32, f32) {
        let h = (wi + wo).normalize_or_zero();
        let cos = wo.dot(h);
        if h == Vec3A::ZERO || cos <= 0.0 {
            return (0.0, 0.0);
        }
        let mf = coat.mf;
        let f = fresnel::dielectric(wi.dot(h), eta).0 * mf.d(h) * mf.g(wi, wo, h) / (4.0 * wi.z * wo.z);
        (f, mf.visible_pdf(wi, h) / (4.0 * cos))
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
                Some(mf) if !thin => Vec3A::splat(rough_dielectric(mf, eta, wi, wo).0),
                _ => Vec3A::ZERO,
            };
        }
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Vec3A::ZERO;
        }
        match *self {
            Bsdf::Dielectric { .. } => Vec3A::ZERO,
            Bsdf::Plastic { diffuse, eta, fdr_int, nonlinear, coat, .. } => {
                let base = Self::plastic_diffuse(diffuse, eta, fdr_int, nonlinear, coat.as_ref(), wi, wo);
                match &coat {
                    Some(c) => base + Vec3A::splat(Self::coat_reflection(c, eta, wi, wo).0),
                    None => base,
                }
            }
            Bsdf::Diffuse { reflectance } => reflectance * FRAC_1_PI,
            Bsdf::Conductor { roughness: None, .. } => Vec3A::ZERO,
            Bsdf::Conductor { eta, k, specular, roughness: Some(mf) } => {
                let h = (wi + wo).normalize_or_zero();
                if h == Vec3A::ZERO {
                    return Vec3A::ZERO;
                }
                let f = fresnel::conductor(wi.dot(h), eta, k) * specular;
                f * (mf.d(h) * mf.g(wi, wo, h) / (4.0 * wi.z * wo.z))
            }
        }
    }

    /// Density of [`Bsdf::sample`] choosing `wo` (its non-delta part).
    #[must_use]
    pub fn pdf(&self, wi: Vec3A, wo: Vec3A) -> f32 {
        if let Bsdf::Dielectric { eta, roughness, thin } = *self {
            return match roughness {
                Some(mf) if !thin => rough_dielectric(mf, eta, wi, wo).1,
                _ => 0.0,
            };
        }
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match *self {
            Bsdf::Dielectric { .. } => 0.0,
            Bsdf::Plastic { eta, specular_share, coat, .. } => {
                let p = Self::plastic_mirror_probability(eta, specular_share, coat.as_ref(), wi.z);
                let coat_pdf = coat.map_or(0.0, |c| p * Self::coat_reflection(&c, eta, wi, wo).1);
                coat_pdf + (1.0 - p) * wo.z * FRAC_1_PI
            }
            Bsdf::Diffuse { .. } => wo.z * FRAC_1_PI,
            Bsdf::Conductor { roughness: None, .. } => 0.0,
            Bsdf::Conductor { roughness: Some(mf), .. } => {
                let h = (wi + wo).normalize_or_zero();
                let cos = wo.dot(h);
                if h == Vec3A::ZERO || cos <= 0.0 {
                    return 0.0;
                }
                mf.visible_pdf(wi, h) / (4.0 * cos)
            }
        }
    }

    /// A scattered direction for `wi`: `u_lobe` chooses a lobe (reflection or refraction),
    /// `u` in `[0,1)²` the direction; `None` when nothing scatters.
    #[must_use]
    pub fn sample(&self, wi: Vec3A, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if let Bsdf::Dielectric { eta, roughness, thin } = *self {
            return sample_dielectric(eta, roughness, thin, wi, u_lobe, u);
        }
        if wi.z <= 0.0 {
            return None;
        }
        match *self {
            Bsdf::Dielectric { .. } => None,
            Bsdf::Plastic { coat: Some(_), .. } => {
                let Bsdf::Plastic { eta, specular_share, coat: Some(c), .. } = *self else { return None };
                let p = Self::plastic_mirror_probability(eta, specular_share, Some(&c), wi.z);
                let wo = if u_lobe < p {
                    reflect(wi, c.mf.sample_visible(wi, u))
                } else {
                    crate::geometry::warp::cosine_hemisphere(u)
                };
                if wo.z <= 0.0 {
                    return None;
                }
                // Both lobes can reach any direction: the weight of the whole mixture.
                let pdf = self.pdf(wi, wo);
                let weight = self.eval(wi, wo) * (wo.z / pdf);
                (pdf > 0.0 && weight.is_finite()).then_some(BsdfSample { wo, weight, pdf, delta: false })
            }
            Bsdf::Plastic { diffuse, eta, fdr_int, nonlinear, specular_share, coat: None } => {
                let p = Self::plastic_mirror_probability(eta, specular_share, None, wi.z);
                if u_lobe < p {
                    let f = fresnel::dielectric(wi.z, eta).0;
                    let wo = Vec3A::new(-wi.x, -wi.y, wi.z);
                    return Some(BsdfSample { wo, weight: Vec3A::splat(f / p), pdf: 1.0, delta: true });
                }
                let wo = crate::geometry::warp::cosine_hemisphere(u);
                let pdf = (1.0 - p) * wo.z * FRAC_1_PI;
                if pdf <= 0.0 {
                    return None;
                }
                let f = Self::plastic_diffuse(diffuse, eta, fdr_int, nonlinear, None, wi, wo);
                Some(BsdfSample { wo, weight: f * wo.z / pdf, pdf, delta: false })
            }
            Bsdf::Diffuse { reflectance } => {
                let wo = crate::geometry::warp::cosine_hemisphere(u);
                (wo.z > 0.0).then_some(BsdfSample { wo, weight: reflectance, pdf: wo.z * FRAC_1_PI, delta: false })
            }
            Bsdf::Conductor { eta, k, specular, roughness: None } => {
                let wo = Vec3A::new(-wi.x, -wi.y, wi.z);
                Some(BsdfSample { wo, weight: fresnel::conductor(wi.z, eta, k) * specular, pdf: 1.0, delta: true })
            }
            Bsdf::Conductor { eta, k, specular, roughness: Some(mf) } => {
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
        }
    }
}

/// `wi` and `wo` mirrored so that `wi` is on the +z side, and the relative index seen from
/// there (`eta` from outside, `1/eta` from inside).
#[inline]
fn upper(eta: f32, wi: Vec3A, wo: Vec3A) -> (Vec3A, Vec3A, f32) {
    if wi.z >= 0.0 { (wi, wo, eta) } else { (-wi, -wo, 1.0 / eta) }
}

/// The refraction of `wi` (on `m`'s side, `cos_i = wi·m > 0`) through `m` into relative index
/// `eta`, given the transmitted cosine `cos_t` (negative).
#[inline]
fn refract(wi: Vec3A, m: Vec3A, eta: f32, cos_i: f32, cos_t: f32) -> Vec3A {
    -wi / eta + (cos_i / eta + cos_t) * m
}

/// `f` and `pdf` of the rough dielectric (Walter et al. 2007; radiance scaled by `1/η²`).
fn rough_dielectric(mf: Microfacet, eta: f32, wi: Vec3A, wo: Vec3A) -> (f32, f32) {
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
fn sample_dielectric(
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
        let r = fresnel::dielectric(wi_up.z, eta).0;
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

#[cfg(test)]
mod tests;
