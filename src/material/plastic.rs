//! Plastic: a diffuse base under a dielectric coat, smooth (Mitsuba's `plastic`) or rough
//! (`roughplastic`, the coat's transmittance tabulated): the coat's reflection, the base's
//! light through the coat, and how sampling shares its choices between them; `eval`, `pdf` and
//! `sample` compose them.
use super::dielectric::refract;
use super::fresnel;
use super::microfacet::Microfacet;
use super::{Bsdf, BsdfSample, reflect};
use crate::geometry::{Vec2, Vec3A, warp};
use std::f32::consts::FRAC_1_PI;

/// The keys of a scene file's material that a plastic reads.
pub const SCENE_KEYS: &[&str] =
    &["diffuse", "ior", "exterior_ior", "nonlinear", "roughness", "distribution", "masking"];

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
    mf.for_visible_grid(wi, N, |m| {
        let v = w(m);
        if v.is_finite() {
            sum += f64::from(v);
        }
    });
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
pub(super) fn rough_coat(mf: Microfacet, eta: f32) -> (RoughCoat, f32) {
    use super::microfacet::Distribution;
    use rayon::prelude::*;
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    type Tables = HashMap<(Distribution, u32, u32), (&'static [f32; COAT_TABLE], f32)>;
    static TABLES: OnceLock<Mutex<Tables>> = OnceLock::new();
    let tables = || TABLES.get_or_init(Mutex::default).lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    // The table depends on the distribution, not on how masking and shadowing combine.
    let key = (mf.distribution, mf.alpha.to_bits(), eta.to_bits());
    if let Some(&(table, fdr)) = tables().get(&key) {
        return (RoughCoat { mf, transmittance: table }, fdr);
    }
    // Computed without holding the lock, the entries in parallel and the internal reflectance
    // summed in order: the same bits on any thread count.
    let entries: Vec<(f32, f64)> = (0..COAT_TABLE)
        .into_par_iter()
        .map(|i| {
            let mu = (i as f32 / (COAT_TABLE - 1) as f32).max(1e-6);
            let wi = Vec3A::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
            (rough_transmittance(mf, eta, wi) as f32, rough_reflectance(mf, 1.0 / eta, wi) * f64::from(mu))
        })
        .collect();
    let mut table = [0.0f32; COAT_TABLE];
    let mut inside = 0.0f64;
    for (t, (transmittance, reflected)) in table.iter_mut().zip(entries) {
        *t = transmittance;
        inside += reflected;
    }
    let fdr = (2.0 * inside / COAT_TABLE as f64) as f32;
    let (table, fdr) = *tables().entry(key).or_insert_with(|| (&*Box::leak(Box::new(table)), fdr));
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

/// The share of light a plastic's coat lets in at incidence `cos`: `1 − F`, or the rough
/// coat's tabulated transmittance.
#[inline]
pub(super) fn coat_transmittance(eta: f32, coat: Option<&RoughCoat>, cos: f32) -> f32 {
    match coat {
        Some(c) => c.transmittance(cos),
        None => 1.0 - fresnel::dielectric(cos, eta).0,
    }
}

/// Probability that [`Bsdf::sample`] takes a plastic's coat (mirror or rough reflection)
/// at incidence `cos_i`.
pub(super) fn mirror_probability(eta: f32, specular_share: f32, coat: Option<&RoughCoat>, cos_i: f32) -> f32 {
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
pub(super) fn base(
    diffuse: Vec3A,
    eta: f32,
    fdr_int: f32,
    nonlinear: bool,
    coat: Option<&RoughCoat>,
    wi: Vec3A,
    wo: Vec3A,
) -> Vec3A {
    let (ti, to) = (coat_transmittance(eta, coat, wi.z), coat_transmittance(eta, coat, wo.z));
    let base = if nonlinear { diffuse / (Vec3A::ONE - diffuse * fdr_int) } else { diffuse / (1.0 - fdr_int) };
    base * (ti * to * FRAC_1_PI / (eta * eta))
}

/// A rough coat's reflection `f` (no cosine) and its density under visible-normal
/// sampling (before the lobe's probability).
pub(super) fn coat_reflection(coat: &RoughCoat, eta: f32, wi: Vec3A, wo: Vec3A) -> (f32, f32) {
    let h = (wi + wo).normalize_or_zero();
    let cos = wo.dot(h);
    if h == Vec3A::ZERO || cos <= 0.0 {
        return (0.0, 0.0);
    }
    let mf = coat.mf;
    let f = fresnel::dielectric(wi.dot(h), eta).0 * mf.d(h) * mf.g(wi, wo, h) / (4.0 * wi.z * wo.z);
    (f, mf.visible_pdf(wi, h) / (4.0 * cos))
}

/// `f(wi, wo)` of a plastic (both directions above the surface): the base's light through the
/// coat, plus a rough coat's own reflection (a smooth coat's mirror is a delta lobe).
#[inline]
pub(super) fn eval(
    diffuse: Vec3A,
    eta: f32,
    fdr_int: f32,
    nonlinear: bool,
    coat: Option<&RoughCoat>,
    wi: Vec3A,
    wo: Vec3A,
) -> Vec3A {
    let base = base(diffuse, eta, fdr_int, nonlinear, coat, wi, wo);
    match coat {
        Some(c) => base + Vec3A::splat(coat_reflection(c, eta, wi, wo).0),
        None => base,
    }
}

/// The density of [`sample`]'s non-delta directions (both above the surface): the rough
/// coat's visible normals with the coat's probability, cosine sampling with the rest.
#[inline]
pub(super) fn pdf(eta: f32, specular_share: f32, coat: Option<&RoughCoat>, wi: Vec3A, wo: Vec3A) -> f32 {
    let p = mirror_probability(eta, specular_share, coat, wi.z);
    let coat_pdf = coat.map_or(0.0, |c| p * coat_reflection(c, eta, wi, wo).1);
    coat_pdf + (1.0 - p) * wo.z * FRAC_1_PI
}

/// A direction scattered by plastic `bsdf` for `wi` (above the surface): the coat (its mirror,
/// or a visible normal of the rough coat) with [`mirror_probability`], else a cosine direction
/// into the base. A rough coat's lobes both reach any direction: the weight is the whole
/// mixture's.
pub(super) fn sample(bsdf: &Bsdf, wi: Vec3A, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
    let Bsdf::Plastic { diffuse, eta, fdr_int, nonlinear, specular_share, coat } = *bsdf else {
        return None;
    };
    match coat {
        Some(c) => {
            let p = mirror_probability(eta, specular_share, Some(&c), wi.z);
            let wo = if u_lobe < p { reflect(wi, c.mf.sample_visible(wi, u)) } else { warp::cosine_hemisphere(u) };
            if wo.z <= 0.0 {
                return None;
            }
            let pdf = bsdf.pdf(wi, wo);
            let weight = bsdf.eval(wi, wo) * (wo.z / pdf);
            (pdf > 0.0 && weight.is_finite()).then_some(BsdfSample { wo, weight, pdf, delta: false })
        }
        None => {
            let p = mirror_probability(eta, specular_share, None, wi.z);
            if u_lobe < p {
                let f = fresnel::dielectric(wi.z, eta).0;
                let wo = Vec3A::new(-wi.x, -wi.y, wi.z);
                return Some(BsdfSample { wo, weight: Vec3A::splat(f / p), pdf: 1.0, delta: true });
            }
            let wo = warp::cosine_hemisphere(u);
            let pdf = (1.0 - p) * wo.z * FRAC_1_PI;
            if pdf <= 0.0 {
                return None;
            }
            let f = base(diffuse, eta, fdr_int, nonlinear, None, wi, wo);
            Some(BsdfSample { wo, weight: f * wo.z / pdf, pdf, delta: false })
        }
    }
}
