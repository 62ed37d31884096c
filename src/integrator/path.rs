//! The paper's "ordinary stochastic ray tracing" (ALGORITHM.md §5): uniform pixel sampling,
//! cosine sampling, next event estimation, Russian roulette by albedo after a few bounces.
//! Emission seen directly by the camera is added once; afterwards light is collected only by
//! NEE, so nothing is counted twice.
use super::{Integrator, RenderContext, Scratch, direct_light};
use crate::accel::Accel;
use crate::geometry::{Frame, UVec2, Vec3A, warp};
use crate::sampler::SampleStream;
use crate::scene::SurfaceInteraction;

#[derive(Clone, Debug)]
pub struct PathTracer {
    /// Bounces before Russian roulette starts.
    pub rr_depth: u32,
}

impl Default for PathTracer {
    fn default() -> Self {
        Self { rr_depth: 3 }
    }
}

/// Survival probability for Russian roulette: the albedo's largest channel, capped so that a
/// white (ρ = 1) closed scene still terminates. Any cap keeps the estimator unbiased.
#[inline]
#[must_use]
pub fn survival_probability(albedo: Vec3A) -> f32 {
    albedo.max_element().min(0.95)
}

impl Integrator for PathTracer {
    type PixelState = ();

    fn name(&self) -> &'static str {
        "path"
    }

    fn setup_pixel<A: Accel>(&self, _: &RenderContext<A>, _: UVec2, _: u64, _: &mut Scratch) {}

    #[inline]
    fn sample<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        _: &(),
        rng: &mut SampleStream,
        scratch: &mut Scratch,
    ) -> Vec3A {
        // Cosine sampling of a Lambertian BRDF: f·cosθ/pdf = ρ.
        trace_path(ctx, pixel, rng, scratch, self.rr_depth, |si, rng| {
            (Frame::from_normal(si.n).to_world(warp::cosine_hemisphere(rng.next_2d())), si.material.diffuse)
        })
    }
}

/// The path tracer's loop, with the choice of direction left to `sample_direction`, which
/// returns a world direction and `f·cosθ/pdf` for it: cosine sampling for `path`, the photon
/// grid for `jensen` (ALGORITHM.md §5 defines Jensen's method as exactly this loop).
#[inline(always)]
pub(crate) fn trace_path<A: Accel>(
    ctx: &RenderContext<A>,
    pixel: UVec2,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
    rr_depth: u32,
    mut sample_direction: impl FnMut(&SurfaceInteraction, &mut SampleStream) -> (Vec3A, Vec3A),
) -> Vec3A {
    let film = pixel.as_vec2() + rng.pixel_2d();
    let ray = ctx.scene.camera.ray(film);
    scratch.rays += 1;
    let Some(hit) = ctx.accel.intersect(&ray) else {
        return Vec3A::ZERO;
    };
    let mut si = ctx.scene.interaction(&ray, &hit);
    let mut radiance = si.emitted();
    let mut throughput = Vec3A::ONE;
    let mut bounce = 0;
    loop {
        let albedo = si.material.diffuse;
        if albedo == Vec3A::ZERO {
            break;
        }
        radiance += throughput * direct_light(ctx, &si, rng, scratch);
        if bounce >= rr_depth {
            let q = survival_probability(albedo);
            if rng.next_f32() >= q {
                break;
            }
            throughput /= q;
        }
        let (wi, f_cos_over_pdf) = sample_direction(&si, rng);
        throughput *= f_cos_over_pdf;
        let ray = si.spawn_ray(wi);
        scratch.rays += 1;
        let Some(hit) = ctx.accel.intersect(&ray) else {
            break;
        };
        si = ctx.scene.interaction(&ray, &hit);
        bounce += 1;
    }
    radiance
}
