//! The paper's "ordinary stochastic ray tracing" (ALGORITHM.md §5) on any material: uniform
//! pixel sampling, BSDF sampling (cosine sampling on a Lambertian surface), next event
//! estimation, Russian roulette by albedo after a few bounces. Emission is counted where the
//! camera sees it, after a delta lobe (NEE cannot reach it), and, for `path`, where BSDF
//! sampling hits it, weighted against NEE by multiple importance sampling (power heuristic):
//! each light path is counted once in expectation.
use super::{
    Integrator, MisAt, RenderContext, Scatter, Scratch, direct_light, nee_strategy, power_heuristic, sample_bsdf,
    sample_cosine,
};
use crate::accel::Accel;
use crate::geometry::{Frame, UVec2, Vec3A};
use crate::light::Receiver;
use crate::sampler::{SampleStream, survival_probability};
use crate::scene::SurfaceInteraction;

/// A unidirectional path tracer with next event estimation, weighed against BSDF sampling by
/// multiple importance sampling as `mis` says.
#[derive(Clone, Debug)]
pub struct PathTracer {
    /// Bounces before Russian roulette starts.
    pub rr_depth: u32,
    /// Which lights NEE weighs against BSDF sampling.
    pub mis: Mis,
}

impl Default for PathTracer {
    fn default() -> Self {
        Self { rr_depth: 3, mis: Mis::default() }
    }
}

/// Where light that BSDF sampling finds is weighed against NEE (multiple importance
/// sampling, power heuristic); elsewhere NEE alone counts it (except behind delta lobes).
/// Either way each path counts once: the two weights at a vertex sum to one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Mis {
    /// At vertices that are not Lambertian, and for the environment everywhere. On a
    /// Lambertian surface our NEE of emitting surfaces (cosine-warped solid-angle sampling) is
    /// close to ideal and cosine sampling only adds the noise of its misses: cornell-paper at
    /// 64 spp, seeds 1–3, MSE 0.0795–0.0809 without MIS there against 0.0913–0.0931 with it.
    /// The environment's sampling ignores the cosine: under a constant sky a Lambertian
    /// plane's standard error is 5× lower with MIS (`tests/lights.rs`).
    #[default]
    Glossy,
    /// At every vertex.
    All,
    /// Nowhere: NEE alone (unbiased, noisy on glossy surfaces).
    Off,
}

impl Mis {
    /// Where MIS applies at a vertex of material `m`.
    #[inline]
    #[must_use]
    pub fn at(self, m: &crate::scene::Material) -> MisAt {
        match self {
            Mis::Glossy => MisAt { surfaces: m.lambertian().is_none(), environment: true },
            Mis::All => MisAt { surfaces: true, environment: true },
            Mis::Off => MisAt::NONE,
        }
    }
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
        // On Lambertian scenes without an environment (the paper's) and without MIS at
        // Lambertian vertices, NEE alone counts light past the first hit: the loop without
        // the checks for emission found by BSDF sampling (same estimator, same bits).
        // A bound on the path depth is a third variant. The general loops are called, not
        // inlined here: inlining all three into the tile loop cost the Lambertian one 0.4%.
        let (r, m) = (self.rr_depth, self.mis);
        if ctx.volumetric {
            return super::volume::trace_volume_path(ctx, pixel, rng, scratch, r, m, Default::default());
        }
        match (self.mis != Mis::All && ctx.lambertian_only, ctx.max_depth != u32::MAX) {
            (true, false) => trace_path::<A, true, false, true>(ctx, pixel, rng, scratch, r, m, sample_lambertian),
            (false, false) => general_path::<A, false, true>(ctx, pixel, rng, scratch, r, m),
            (_, true) => general_path::<A, true, true>(ctx, pixel, rng, scratch, r, m),
        }
    }
}

impl PathTracer {
    /// One sample of `pixel` whose seen light is split over `strata × strata` film points
    /// ([`super::seen`]): the path leaves it out and the strata estimate it. Plain
    /// [`Integrator::sample`] where `strata` is 1 or the scene has media.
    pub fn sample_seen_split<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        strata: u8,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
    ) -> Vec3A {
        if strata <= super::seen::UNSPLIT || ctx.volumetric {
            return self.sample(ctx, pixel, &(), rng, scratch);
        }
        let (r, m) = (self.rr_depth, self.mis);
        let rest = if ctx.max_depth == u32::MAX {
            general_path::<A, false, false>(ctx, pixel, rng, scratch, r, m)
        } else {
            general_path::<A, true, false>(ctx, pixel, rng, scratch, r, m)
        };
        rest + super::seen::split_seen(ctx, pixel, strata, rng, scratch)
    }
}

/// [`sample_bsdf`] where every surface is Lambertian (the `NEE_ONLY` loop): cosine sampling,
/// always inlined, without the branch to the general sampler.
#[inline(always)]
fn sample_lambertian(si: &SurfaceInteraction, frame: &Frame, _: Vec3A, rng: &mut SampleStream) -> Option<Scatter> {
    sample_cosine(si, frame, si.material.lambertian().unwrap_or(Vec3A::ZERO), rng)
}

/// [`trace_path`] with BSDF sampling, any material, bounded or not, counting the seen light
/// or not.
#[inline(never)]
fn general_path<A: Accel, const BOUNDED: bool, const SEEN: bool>(
    ctx: &RenderContext<A>,
    pixel: UVec2,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
    rr_depth: u32,
    mis: Mis,
) -> Vec3A {
    trace_path::<A, false, BOUNDED, SEEN>(ctx, pixel, rng, scratch, rr_depth, mis, sample_bsdf)
}

/// The path tracer's loop, with the choice of direction left to `sample_direction` (given the
/// vertex, the BSDF's frame and the local direction to the viewer): the BSDF's sampling for
/// `path`, the photon grid for `jensen` (ALGORITHM.md §5 defines Jensen's method as exactly
/// this loop). Where `mis` applies, emission found by `sample_direction` is counted with the
/// power heuristic against NEE, whose density there [`crate::light::LightSet::triangle_pdf`]
/// replays (`sample_direction` must then return its true density); elsewhere only NEE counts
/// light past the first hit, except behind delta lobes.
///
/// `NEE_ONLY` promises that no vertex weighs BSDF-found emission (`mis` off there) and that
/// nothing is delta or seen beyond the scene, so that only NEE counts light past the first hit;
/// the loop then skips those checks. `BOUNDED`: paths end at `ctx.max_depth` segments (without
/// it, `ctx.max_depth` must be unbounded). Without `SEEN` the path leaves out the pixel's seen
/// light (emission at the first hit and behind delta lobes from it, [`super::seen`]).
#[inline(always)]
pub(crate) fn trace_path<A: Accel, const NEE_ONLY: bool, const BOUNDED: bool, const SEEN: bool>(
    ctx: &RenderContext<A>,
    pixel: UVec2,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
    rr_depth: u32,
    mis: Mis,
    mut sample_direction: impl FnMut(&SurfaceInteraction, &Frame, Vec3A, &mut SampleStream) -> Option<Scatter>,
) -> Vec3A {
    let film = ctx.scene.camera.film_point(pixel, rng.pixel_2d());
    let ray = ctx.scene.camera.ray(film);
    scratch.rays += 1;
    // Paths of at most `max_depth` segments: the camera's is the first.
    if BOUNDED && ctx.max_depth == 0 {
        return Vec3A::ZERO;
    }
    let Some(hit) = ctx.accel.intersect(&ray) else {
        return ctx.scene.lights.environment(ray.dir);
    };
    let mut si = if NEE_ONLY { ctx.scene.interaction_inline(&ray, &hit) } else { ctx.scene.interaction(&ray, &hit) };
    let mut radiance = if SEEN { si.emitted() } else { Vec3A::ZERO };
    // Whether every scatter so far was a delta lobe (only tracked without `SEEN`).
    let mut prefix = !SEEN;
    let mut throughput = Vec3A::ONE;
    // Light reaching a vertex (by NEE or by the next direction) ends a path of `bounce + 2`
    // segments: the last vertex that scatters.
    let last_bounce = ctx.max_depth.saturating_sub(2);
    if BOUNDED && ctx.max_depth < 2 {
        return radiance;
    }
    let mut bounce = 0;
    loop {
        let albedo = si.material.albedo();
        if albedo == Vec3A::ZERO || (BOUNDED && bounce > last_bounce) {
            break;
        }
        let frame = si.bsdf_frame();
        // The direction to the viewer in the BSDF's frame: a Lambertian surface's sampling
        // and density need only that it lies above (the shading point is seen from there).
        let wi = if NEE_ONLY || si.material.lambertian().is_some() { Vec3A::Z } else { frame.to_local(si.wo) };
        let weigh = if NEE_ONLY { MisAt::NONE } else { mis.at(&si.material) };
        if NEE_ONLY || !si.material.bsdf.is_delta() {
            radiance += throughput * direct_light(ctx, &si, &frame, wi, weigh, rng, scratch);
        }
        if bounce >= rr_depth {
            let q = survival_probability(albedo);
            if rng.next_f32() >= q {
                break;
            }
            throughput /= q;
        }
        let Some(s) = sample_direction(&si, &frame, wi, rng) else {
            break;
        };
        throughput *= s.weight;
        if !SEEN {
            prefix &= s.delta;
        }
        let ray = si.spawn_ray(s.dir);
        scratch.rays += 1;
        let Some(hit) = ctx.accel.intersect(&ray) else {
            if NEE_ONLY {
                break;
            }
            // Escaped: the environment, counted as emission found by this direction is.
            let env = ctx.scene.lights.environment(s.dir);
            if s.delta {
                radiance += throughput * env;
            } else if weigh.environment && env != Vec3A::ZERO {
                radiance += throughput * env * power_heuristic(s.pdf, ctx.scene.lights.environment_pdf(s.dir));
            }
            break;
        };
        let next = if NEE_ONLY { ctx.scene.interaction_inline(&ray, &hit) } else { ctx.scene.interaction(&ray, &hit) };
        // (Tested under `!NEE_ONLY` itself: a SIMD compare with zero is not folded away.)
        let emitted = if NEE_ONLY { Vec3A::ZERO } else { next.emitted() };
        if !NEE_ONLY && emitted != Vec3A::ZERO {
            if s.delta {
                if SEEN || !prefix {
                    radiance += throughput * emitted;
                }
            } else if weigh.surfaces {
                let strategy = nee_strategy(ctx.light_sampling, &si);
                let p_light =
                    ctx.scene.lights.triangle_pdf(&Receiver { x: si.p, n: si.n, strategy }, next.prim, next.p);
                radiance += throughput * emitted * power_heuristic(s.pdf, p_light);
            }
        }
        si = next;
        bounce += 1;
    }
    radiance
}
