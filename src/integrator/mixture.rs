//! Sampling a vertex that is not Lambertian as a one-sample mixture of the BSDF's own
//! sampling and a guide's density (the photon grid of `jensen`, the learned density of
//! `zvidpt`), and where a guide is worth mixing in at all.
use super::{Scatter, sample_bsdf};
use crate::geometry::{Frame, Vec3A};
use crate::sampler::SampleStream;
use crate::scene::SurfaceInteraction;

/// Share of directions a guided integrator takes from the BSDF's own sampling on a surface
/// that is not Lambertian (the photon grid and the learned density stand for incident light
/// times a Lambertian lobe; the BSDF's sampling follows a glossy lobe).
pub const BSDF_SHARE: f32 = 0.5;

/// Roughness below which a glossy lobe is too narrow for a learned density to sample it: a
/// direction the guide picks almost never falls in a lobe of this width.
pub const GUIDE_MIN_ALPHA: f32 = 0.1;

/// Whether the learned integrator mixes its guide into the sampling of `bsdf`: not where
/// every lobe is delta or near-specular (a glossy lobe narrower than [`GUIDE_MIN_ALPHA`]);
/// a plastic's diffuse base is always worth guiding.
#[inline]
#[must_use]
pub fn guides_at(bsdf: &crate::material::Bsdf) -> bool {
    use crate::material::Bsdf;
    let rough = |r: &Option<crate::material::microfacet::Microfacet>| r.is_some_and(|m| m.alpha >= GUIDE_MIN_ALPHA);
    match bsdf {
        Bsdf::Diffuse { .. } | Bsdf::Plastic { .. } => true,
        Bsdf::Conductor { roughness, .. } => rough(roughness),
        Bsdf::Dielectric { roughness, thin, .. } => !thin && rough(roughness),
    }
}

/// A direction at a vertex that is not Lambertian: the BSDF's own sampling on a pure delta
/// surface; elsewhere a one-sample mixture, the BSDF's sampling with probability
/// [`BSDF_SHARE`] and `guide` (a sampler and its density, both in local directions of
/// `guide_frame`) otherwise, weighted by the mixture's density. A delta lobe the BSDF picks
/// keeps its own weight over its share.
#[inline]
pub fn sample_mixture(
    si: &SurfaceInteraction,
    frame: &Frame,
    wi: Vec3A,
    guide_frame: &Frame,
    rng: &mut SampleStream,
    mut guide_sample: impl FnMut(&mut SampleStream) -> Vec3A,
    guide_pdf: impl Fn(Vec3A) -> f32,
) -> Option<Scatter> {
    let bsdf = &si.material.bsdf;
    if bsdf.is_delta() {
        return sample_bsdf(si, frame, wi, rng);
    }
    let u = rng.next_f32();
    let (dir, local, pdf_bsdf) = if u < BSDF_SHARE {
        let s = bsdf.sample(wi, u / BSDF_SHARE, rng.next_2d())?;
        if s.delta {
            let dir = frame.to_world(s.wo);
            return si.consistent(dir, s.wo.z).then_some(Scatter {
                dir,
                weight: s.weight / BSDF_SHARE,
                pdf: 1.0,
                delta: true,
            });
        }
        (frame.to_world(s.wo), s.wo, s.pdf)
    } else {
        let dir = guide_frame.to_world(guide_sample(rng));
        let local = frame.to_local(dir);
        (dir, local, bsdf.pdf(wi, local))
    };
    if !si.consistent(dir, local.z) {
        return None;
    }
    let pdf = BSDF_SHARE * pdf_bsdf + (1.0 - BSDF_SHARE) * guide_pdf(guide_frame.to_local(dir));
    let weight = bsdf.eval(wi, local) * (local.z.abs() / pdf);
    (pdf > 0.0 && weight.is_finite()).then_some(Scatter { dir, weight, pdf, delta: false })
}
