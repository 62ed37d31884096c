//! Integrators behind one trait, generic over the backend. An integrator picks its own film
//! point inside the pixel (ZVIDPT importance-samples subpixels) and may keep per-pixel state
//! built once before the pixel's first sample, and may run a pre-pass (the photon map).
// The library's entry points: every public item documented (`cargo doc`).
#![warn(missing_docs)]
mod choice;
mod jensen;
pub mod mixture;
pub mod path;
pub mod photon_guided;
pub mod seen;
mod volume;
pub mod volume_guided;
pub mod zvidpt;
mod zvidpt_paper;

pub use choice::{IntegratorKind, IntegratorSettings};
pub use jensen::Jensen;
pub use path::{Mis, PathTracer};
pub use photon_guided::GuideSettings;
pub use volume_guided::GuidedVolume;
pub use zvidpt::{Allocation, LearnedSettings, LearnedZvidpt, PixelSetup, Roulette};
pub use zvidpt_paper::{Estimator, MAX_SUBPIXELS, Zvidpt};

use crate::accel::Accel;
use crate::film::PriorSamples;
use crate::geometry::{Frame, Ray, UVec2, Vec3A, offset_ray_origin};
use crate::light::{LightSampling, Receiver};
use crate::sampler::SampleStream;
use crate::scene::{Scene, SurfaceInteraction};

/// What an integrator sees while rendering.
pub struct RenderContext<'a, A: Accel> {
    /// The scene rendered.
    pub scene: &'a Scene,
    /// Its ray-tracing backend.
    pub accel: &'a A,
    /// How next event estimation picks points on emitters.
    pub light_sampling: LightSampling,
    /// When the render started (before the pre-pass) and its time budget, if any: an
    /// integrator that trains in its pre-pass takes its share of the budget from these.
    pub start: std::time::Instant,
    /// The render's time budget in seconds, if it has one.
    pub time_limit: Option<f64>,
    /// The final sample count asked for, if any.
    pub spp: Option<u32>,
    /// Training iterations a learning integrator must run (resuming a checkpoint of a
    /// time-budgeted render, whose iteration count came from the clock): with the count fixed,
    /// the pre-pass is a function of scene, options and seed alone.
    pub training_iterations: Option<u32>,
    /// [`Scene::lambertian_only`], once per render.
    pub lambertian_only: bool,
    /// [`Scene::volumetric`], once per render: paths must track media.
    pub volumetric: bool,
    /// The longest path counted, in segments (`u32::MAX`: unbounded): the scene's
    /// `max_depth` (Mitsuba's), honoured by `path`, `jensen` and the learned integrator.
    pub max_depth: u32,
}

/// Per-tile tallies and scratch memory, owned by the tile being rendered: no shared counters
/// and no allocation in the sample loop (pbrt's per-thread scratch).
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    /// Rays traced.
    pub rays: u64,
    /// Samples that came out NaN or infinite (dropped; reported after the render).
    pub non_finite: u64,
    /// Room for one guide grid, for integrators that build grids per vertex.
    pub grid: Vec<f32>,
    /// The current camera sample's seen light so far (emission at its first hit and behind
    /// delta lobes from there, weighted as in the sample: [`seen`]), where a walk records it.
    pub seen: Vec3A,
    /// Rays the current camera sample's delta prefix has traced (the camera's and each behind
    /// a delta lobe while every scatter so far was delta): what one more film point of the
    /// seen light costs there.
    pub seen_rays: u32,
    /// The medium vertices of the current guided path (learning data), reused per sample.
    pub(crate) medium_vertices: Vec<volume::MediumVertex>,
}

/// A light-transport estimator: one unbiased sample of a pixel's radiance at a time, generic
/// over the backend (no dynamic dispatch per ray).
pub trait Integrator: Sync + Send {
    /// State kept per pixel across passes (`()` when there is none).
    type PixelState: Send + Sync;

    /// The name the command line gives it.
    fn name(&self) -> &'static str;

    /// The pre-pass (the photon map), run once before any pixel; returns a line describing
    /// what it built, if anything.
    fn prepare<A: Accel>(&mut self, _ctx: &RenderContext<A>, _seed: u64) -> crate::Result<Option<String>> {
        Ok(None)
    }

    /// Samples the pre-pass already took of every pixel (unbiased, each from a fixed
    /// distribution), to be averaged into the image with the render's own: per-sample weights
    /// all equal, never chosen from the samples' values. `None` for most integrators.
    fn prior_samples(&self) -> Option<&PriorSamples> {
        None
    }

    /// Each pixel's sample rate (row-major, mean 1; [`crate::film::rates`]) for the
    /// render's samples, as the pre-pass measured where the image's error lies; `None`: every
    /// pixel alike. A pixel's rate must not depend on its own pre-pass samples.
    fn pixel_rates(&self) -> Option<&[f32]> {
        None
    }

    /// Index of the render's first sample in each pixel's sample sequence: the pre-pass took
    /// the ones before it. Film points come from one (0,2)-sequence per pixel, so samples
    /// taken in aligned blocks of it stay stratified together (training and render alike).
    fn first_sample_index(&self) -> u32 {
        0
    }

    /// Bytes a render with it holds per pixel at its peak, about (the render refuses an image
    /// that would not fit in the memory left): per-pixel sums and squares, the image and its
    /// variance, the EXR encoder's copy — 114 for `path` (peak resident size between
    /// 1024×768 and 2048×1536).
    fn bytes_per_pixel(&self) -> u64 {
        128
    }

    /// Training iterations the pre-pass ran (learning integrators), for a checkpoint.
    fn training_iterations(&self) -> Option<u32> {
        None
    }

    /// Set-up for one pixel, once, before its first sample.
    fn setup_pixel<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        seed: u64,
        scratch: &mut Scratch,
    ) -> Self::PixelState;

    /// One sample of `pixel`: an unbiased estimate of the pixel's mean radiance.
    fn sample<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        state: &Self::PixelState,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
    ) -> Vec3A;
}

/// A direction chosen at a vertex: world direction, `f·|cosθ|/pdf`, the density (solid angle;
/// meaningless for a delta lobe, 0 where a sampler used without MIS does not report it) and
/// whether a delta lobe was taken (emission seen next is
/// then counted, as NEE cannot reach it).
#[derive(Clone, Copy, Debug)]
pub struct Scatter {
    /// The world direction.
    pub dir: Vec3A,
    /// `f·|cos θ|/pdf`.
    pub weight: Vec3A,
    /// The density, per solid angle.
    pub pdf: f32,
    /// Whether a delta lobe was taken.
    pub delta: bool,
}

/// Cosine sampling of a Lambertian surface of reflectance `rho` at `si` (local frame `frame`):
/// two numbers, weight `rho`.
#[inline(always)]
pub(crate) fn sample_cosine(
    si: &SurfaceInteraction,
    frame: &Frame,
    rho: Vec3A,
    rng: &mut SampleStream,
) -> Option<Scatter> {
    let wo = crate::geometry::warp::cosine_hemisphere(rng.next_2d());
    if wo.z <= 0.0 {
        return None;
    }
    let dir = frame.to_world(wo);
    si.consistent(dir, wo.z).then_some(Scatter {
        dir,
        weight: rho,
        pdf: wo.z * std::f32::consts::FRAC_1_PI,
        delta: false,
    })
}

/// The BSDF's own sampling at `si` (local frame `frame`, `wi` the local direction to the
/// viewer): two numbers for the direction, one for the lobe.
#[inline]
pub fn sample_bsdf(si: &SurfaceInteraction, frame: &Frame, wi: Vec3A, rng: &mut SampleStream) -> Option<Scatter> {
    // A Lambertian surface has one lobe (no number to choose it) and needs no call into the
    // BSDF's general sampler: cosine sampling, inline.
    if let Some(rho) = si.material.lambertian() {
        return sample_cosine(si, frame, rho, rng);
    }
    let s = si.material.bsdf.sample(wi, rng.next_f32(), rng.next_2d())?;
    let dir = frame.to_world(s.wo);
    si.consistent(dir, s.wo.z).then_some(Scatter { dir, weight: s.weight, pdf: s.pdf, delta: s.delta })
}

/// Which light NEE weighs against BSDF sampling at a vertex (see [`path::Mis`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MisAt {
    /// Emitting surfaces.
    pub surfaces: bool,
    /// The environment.
    pub environment: bool,
}

impl MisAt {
    /// NEE alone counts every light (the guided integrators, `--mis off`).
    pub const NONE: MisAt = MisAt { surfaces: false, environment: false };
}

/// Veach's power heuristic (β = 2) for the strategy of density `a` against one of density `b`.
#[inline]
#[must_use]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 { a2 / (a2 + b2) } else { 0.0 }
}

/// The light-sampling strategy NEE uses at `si`: the render's, except on surfaces that
/// transmit, where light from both sides counts and area sampling (which ignores the normal)
/// is used.
#[inline]
#[must_use]
pub fn nee_strategy(strategy: LightSampling, si: &SurfaceInteraction) -> LightSampling {
    if si.material.bsdf.transmits() { LightSampling::Area } else { strategy }
}

/// One next-event-estimation sample of direct light at `si` (ALGORITHM.md §3, `L̂1`): an
/// emitter triangle by power, a point on it by `ctx.light_sampling` (area is ALGORITHM.md's
/// choice; solid angle is the default, see [`LightSampling`]), one shadow ray, the BSDF
/// evaluated in `frame` with `wi` the local direction to the viewer. Where `mis` says so
/// (surfaces, the environment) the result is weighted by the power heuristic against the
/// BSDF's own sampling (which then counts the emission it finds with the complementary
/// weight). Always draws three dimensions so that the
/// stream stays aligned whatever happens. Callers skip it on pure delta surfaces.
#[inline]
pub fn direct_light<A: Accel>(
    ctx: &RenderContext<A>,
    si: &SurfaceInteraction,
    frame: &Frame,
    wi: Vec3A,
    mis: MisAt,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
) -> Vec3A {
    let bsdf = &si.material.bsdf;
    direct_light_against(ctx, si, frame, wi, mis, rng, scratch, |local, _| bsdf.pdf(wi, local))
}

/// [`direct_light`] weighed by MIS against a direction sampler other than the BSDF's own:
/// `dir_pdf(local, world)` is that sampler's solid-angle density of a direction (given in
/// `frame` and in world space), the density its own hits of emission are weighed with.
// Eight arguments, in registers: the vertex and the MIS choice gathered into a struct cost
// `path` 1.1% of its instructions on cornell-paper (callgrind, 128×96, 4 spp: 309.3 M against
// 305.9 M), passed through memory at every call.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn direct_light_against<A: Accel>(
    ctx: &RenderContext<A>,
    si: &SurfaceInteraction,
    frame: &Frame,
    wi: Vec3A,
    mis: MisAt,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
    dir_pdf: impl FnOnce(Vec3A, Vec3A) -> f32,
) -> Vec3A {
    let u_pick = rng.next_f32();
    let u_point = rng.next_2d();
    let bsdf = &si.material.bsdf;
    let strategy = nee_strategy(ctx.light_sampling, si);
    let Some(light) = ctx.scene.lights.sample(&Receiver { x: si.p, n: si.n, strategy }, u_pick, u_point) else {
        return Vec3A::ZERO;
    };
    let dir = if light.infinite { light.p } else { (light.p - si.p).normalize_or_zero() };
    // Opaque surfaces reflect only on the side they are seen from.
    if !bsdf.transmits() && si.n.dot(dir) <= 0.0 {
        return Vec3A::ZERO;
    }
    // Lambertian: `ρ/π` and the cosine at the (shading) normal, without the local frame.
    let (f, cos, local) = match si.material.lambertian() {
        Some(rho) => (rho * std::f32::consts::FRAC_1_PI, si.ns.dot(dir), Vec3A::ZERO),
        None => {
            let local = frame.to_local(dir);
            if !si.consistent(dir, local.z) {
                return Vec3A::ZERO;
            }
            (bsdf.eval(wi, local), local.z.abs(), local)
        }
    };
    if f == Vec3A::ZERO || cos <= 0.0 {
        return Vec3A::ZERO;
    }
    let origin = offset_ray_origin(si.p, si.p_err, si.ng, dir);
    scratch.rays += 1;
    let blocked = if light.infinite {
        // Nothing lies beyond the scene's bounding sphere.
        let (centre, radius) = ctx.scene.bounds;
        ctx.accel.occluded(&Ray::new(origin, dir), 2.0 * ((origin - centre).length() + radius))
    } else {
        let target = offset_ray_origin(light.p, light.p_err, light.ng, -dir);
        let span = target - origin;
        let len = span.length();
        ctx.accel.occluded(&Ray::new(origin, span / len), len * (1.0 - 1e-4))
    };
    if blocked {
        return Vec3A::ZERO;
    }
    let value = f * light.emission * (cos * light.inv_pdf);
    // Delta lights (point, spot, distant) cannot be found by BSDF sampling: never weighed.
    let weigh = !light.delta && if light.infinite { mis.environment } else { mis.surfaces };
    if !weigh {
        return value;
    }
    let local = if si.material.lambertian().is_some() { frame.to_local(dir) } else { local };
    value * power_heuristic(1.0 / light.inv_pdf, dir_pdf(local, dir))
}
