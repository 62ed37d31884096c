//! `path` through participating media (pbrt-v4's `volpath`, Mitsuba 3's `volpath`, for
//! homogeneous media): the ray's medium is tracked across the surfaces that bound media;
//! free flights are sampled per channel with one-sample MIS over the channels
//! ([`crate::medium::Medium::sample_flight`]); at a point in a medium the path scatters by the
//! phase function, with next event estimation there as on surfaces. Shadow rays cross medium
//! boundaries and carry the transmittance of every medium they pass through. A boundary
//! without a surface ([`crate::material::Bsdf::interface`]) is crossed without a bounce: it
//! neither counts against the path's depth nor changes its weight.
//!
//! Emission found by BSDF or phase sampling is weighed against NEE with the power heuristic
//! on the two directions' solid-angle densities, as in [`super::path`]: any pair of weights
//! that sums to one keeps each path counted once, and the transmittance both strategies
//! share needs no place in them.
use super::{MisAt, RenderContext, Scatter, Scratch, nee_strategy, path::Mis, power_heuristic, sample_bsdf};
use crate::accel::Accel;
use crate::geometry::{Frame, Ray, UVec2, Vec2, Vec3A, offset_ray_origin, warp};
use crate::learned_guide::volume::{VolumeDeposits, VolumeGuide};
use crate::light::{LightSampling, Receiver};
use crate::sampler::{SampleStream, survival_probability};
use crate::scene::{Scene, SurfaceInteraction};

/// Most medium boundaries one ray segment crosses without scattering (a guard against
/// surfaces stacked on each other; far above any scene's nesting).
const MAX_CROSSINGS: u32 = 256;

/// The vertex the current direction was sampled at, for weighing the emission it finds.
#[derive(Clone, Copy)]
struct Previous {
    /// The vertex, as NEE saw it there.
    at: Receiver,
    /// The direction's solid-angle density.
    pdf: f32,
    /// Which emission NEE there weighed against this direction.
    mis: MisAt,
}

/// What a volumetric path does beyond `path`'s (the default: nothing).
#[derive(Default)]
pub(crate) struct Guidance<'a> {
    /// The guide its directions at medium points are drawn from (with the phase function).
    pub guide: Option<&'a VolumeGuide>,
    /// Where it deposits what it learned (training).
    pub deposits: Option<&'a mut VolumeDeposits>,
    /// Whether it leaves out the pixel's seen light (strata count it, [`super::seen`]).
    pub seen_apart: bool,
}

/// One sample of `pixel` by volumetric path tracing (see the module's text).
#[inline(never)]
pub(crate) fn trace_volume_path<A: Accel>(
    ctx: &RenderContext<A>,
    pixel: UVec2,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
    rr_depth: u32,
    mis: Mis,
    guidance: Guidance,
) -> Vec3A {
    let Guidance { guide, deposits, seen_apart } = guidance;
    let scene = ctx.scene;
    scratch.medium_vertices.clear();
    scratch.seen = Vec3A::ZERO;
    scratch.seen_rays = 0;
    let film = scene.camera.film_point(pixel, rng.pixel_2d());
    let mut ray = scene.camera.ray(film);
    if ctx.max_depth == 0 {
        return Vec3A::ZERO;
    }
    // On the camera's delta prefix: no scatter yet but delta ones (light found here is the
    // pixel's seen light, [`super::seen`]; left out where `seen_apart`, the strata count it).
    let mut prefix = true;
    let mut medium = scene.camera_medium;
    let (mut radiance, mut throughput) = (Vec3A::ZERO, Vec3A::ONE);
    // `None`: the camera, or a delta lobe: emission found next is counted whole.
    let mut previous: Option<Previous> = None;
    // Vertices that scattered so far; light reaching vertex `bounce` ends a path of
    // `bounce + 2` segments.
    let mut bounce = 0u32;
    let last_bounce = ctx.max_depth.saturating_sub(2);
    let mut crossings = 0;
    loop {
        scratch.rays += 1;
        if prefix {
            scratch.seen_rays += 1;
        }
        let hit = ctx.accel.intersect(&ray);
        if let Some(m) = medium.map(|i| &scene.media[usize::from(i)]) {
            let flight = m.sample_flight(hit.map_or(f32::INFINITY, |h| h.t), rng.next_f32(), rng.next_f32());
            throughput *= flight.weight;
            if throughput == Vec3A::ZERO {
                break;
            }
            if flight.scattered {
                if ctx.max_depth < 2 || bounce > last_bounce {
                    break;
                }
                let x = ray.origin + ray.dir * flight.t;
                let wi = -ray.dir;
                let weigh = if mis == Mis::Off { MisAt::NONE } else { MisAt { surfaces: true, environment: true } };
                let at = Receiver { x, n: Vec3A::ZERO, strategy: LightSampling::Area };
                // The learned tree's share of the one-sample mixture with the phase function.
                let (cell, alpha) = guide.map_or((0, 0.0), |g| {
                    let c = g.cell(x);
                    (c, g.mix_at(c))
                });
                let mixture = |dir: Vec3A, phase: f32| guide.map_or(phase, |g| g.mixture_pdf(cell, alpha, dir, phase));
                radiance += throughput
                    * next_event(ctx, &at, x, medium, weigh, rng, scratch, |dir| {
                        let p = m.phase(wi, dir);
                        (Vec3A::splat(p), mixture(dir, p))
                    });
                let albedo = m.sigma_s / m.sigma_t().max(Vec3A::splat(f32::MIN_POSITIVE));
                if bounce >= rr_depth && !survives(albedo, &mut throughput, rng) {
                    break;
                }
                let (dir, pdf) = match guide {
                    None => m.sample_phase(wi, rng.next_2d()),
                    Some(g) => {
                        // The weight `p/pdf` (1 without a tree).
                        let recording = deposits.is_some() && scratch.medium_vertices.len() < MAX_RECORDED;
                        let d = draw_mixture(
                            g,
                            cell,
                            alpha,
                            recording,
                            rng,
                            |u| m.sample_phase(wi, u).0,
                            |dir| m.phase(wi, dir),
                        );
                        if d.pdf.is_nan() || d.pdf <= 0.0 {
                            break;
                        }
                        throughput *= d.base / d.pdf;
                        if recording {
                            scratch.medium_vertices.push(d.vertex(cell, radiance, throughput));
                        }
                        (d.dir, d.pdf)
                    }
                };
                previous = Some(Previous { at, pdf, mis: weigh });
                prefix = false;
                ray = Ray::new(x, dir);
                bounce += 1;
                crossings = 0;
                continue;
            }
        }
        let Some(hit) = hit else {
            let env = scene.lights.environment(ray.dir);
            match previous {
                None if prefix => {
                    scratch.seen += throughput * env;
                    if !seen_apart {
                        radiance += throughput * env;
                    }
                }
                None => radiance += throughput * env,
                Some(p) if p.mis.environment && env != Vec3A::ZERO => {
                    radiance += throughput * env * power_heuristic(p.pdf, scene.lights.environment_pdf(ray.dir));
                }
                Some(_) => {}
            }
            break;
        };
        let si = scene.interaction(&ray, &hit);
        if si.material.bsdf.is_interface() {
            crossings += 1;
            if crossings > MAX_CROSSINGS {
                break;
            }
            medium = scene.medium_interface(si.prim).after(si.ng, ray.dir, medium);
            ray = si.spawn_ray(ray.dir);
            continue;
        }
        crossings = 0;
        let emitted = si.emitted();
        if emitted != Vec3A::ZERO {
            match previous {
                None if prefix => {
                    scratch.seen += throughput * emitted;
                    if !seen_apart {
                        radiance += throughput * emitted;
                    }
                }
                None => radiance += throughput * emitted,
                Some(p) if p.mis.surfaces => {
                    let p_light = scene.lights.triangle_pdf(&p.at, si.prim, si.p);
                    radiance += throughput * emitted * power_heuristic(p.pdf, p_light);
                }
                Some(_) => {}
            }
        }
        let albedo = si.material.albedo();
        if albedo == Vec3A::ZERO || ctx.max_depth < 2 || bounce > last_bounce {
            break;
        }
        let frame = si.bsdf_frame();
        let wi = frame.to_local(si.wo);
        let weigh = mis.at(&si.material);
        let at = Receiver { x: si.p, n: si.n, strategy: nee_strategy(ctx.light_sampling, &si) };
        let interface = scene.medium_interface(si.prim);
        // A Lambertian surface with a guide: a one-sample mixture of the cell's tree and
        // cosine sampling, as at medium points.
        let guided = match (guide, si.material.lambertian()) {
            (Some(g), Some(rho)) => {
                let cell = g.surface_cell(si.p, si.n);
                Some((g, cell, g.mix_at(cell), rho))
            }
            _ => None,
        };
        let mixture = |dir: Vec3A, bsdf_pdf: f32| match guided {
            Some((g, cell, alpha, _)) => g.mixture_pdf(cell, alpha, dir, bsdf_pdf),
            None => bsdf_pdf,
        };
        if !si.material.bsdf.is_delta() {
            radiance +=
                throughput * surface_light(ctx, &si, &frame, wi, &at, weigh, medium, interface, rng, scratch, mixture);
        }
        if bounce >= rr_depth && !survives(albedo, &mut throughput, rng) {
            break;
        }
        let s = match guided {
            None => sample_bsdf(&si, &frame, wi, rng),
            Some((g, cell, alpha, rho)) => {
                let recording = deposits.is_some() && scratch.medium_vertices.len() < MAX_RECORDED;
                let mut local = Vec3A::ZERO;
                let d = draw_mixture(
                    g,
                    cell,
                    alpha,
                    recording,
                    rng,
                    |u| frame.to_world(warp::cosine_hemisphere(u)),
                    |dir| {
                        local = frame.to_local(dir);
                        warp::cosine_hemisphere_pdf(local.z)
                    },
                );
                if local.z <= 0.0 || !si.consistent(d.dir, local.z) || d.pdf.is_nan() || d.pdf <= 0.0 {
                    break;
                }
                // f·cos/pdf with f = ρ/π: ρ·(cos/π)/pdf.
                let weight = rho * (d.base / d.pdf);
                if recording {
                    scratch.medium_vertices.push(d.vertex(cell, radiance, throughput * weight));
                }
                Some(Scatter { dir: d.dir, weight, pdf: d.pdf, delta: false })
            }
        };
        let Some(s) = s else {
            break;
        };
        throughput *= s.weight;
        previous = (!s.delta).then_some(Previous { at, pdf: s.pdf, mis: weigh });
        prefix &= s.delta;
        medium = interface.after(si.ng, s.dir, medium);
        ray = si.spawn_ray(s.dir);
        bounce += 1;
    }
    if let (Some(g), Some(d)) = (guide, deposits) {
        deposit(g, d, &scratch.medium_vertices, radiance);
    }
    radiance
}

/// A direction drawn from a cell's one-sample mixture ([`draw_mixture`]).
struct Drawn {
    dir: Vec3A,
    /// The base strategy's density of `dir` (the phase function's value, or `cos/π`).
    base: f32,
    /// The tree's density of `dir` (0 where neither the mixture nor the recording needs it).
    tree: f32,
    /// The mixture's density of `dir`: what the direction was drawn with.
    pdf: f32,
}

impl Drawn {
    /// The vertex to learn from, the path's throughput `throughput` with this direction's
    /// weight and `radiance` gathered before it.
    fn vertex(&self, cell: usize, radiance: Vec3A, throughput: Vec3A) -> MediumVertex {
        MediumVertex {
            cell: cell as u32,
            dir: self.dir,
            base: self.base,
            tree: self.tree,
            pdf: self.pdf,
            radiance,
            throughput,
        }
    }
}

/// Which strategy of `cell`'s one-sample mixture, then the direction: the tree with
/// probability `alpha`, else `base_sample`, whose density is `base_pdf`. The density is the
/// mixture's whichever drew it; the tree's is looked up where the mixture or, when
/// `recording`, the learning needs it.
#[inline]
fn draw_mixture(
    g: &VolumeGuide,
    cell: usize,
    alpha: f32,
    recording: bool,
    rng: &mut SampleStream,
    base_sample: impl FnOnce(Vec2) -> Vec3A,
    base_pdf: impl FnOnce(Vec3A) -> f32,
) -> Drawn {
    let pick = rng.next_f32();
    let dir = if pick < alpha { g.sample(cell, rng.next_2d()) } else { base_sample(rng.next_2d()) };
    let base = base_pdf(dir);
    let tree = if alpha > 0.0 || recording { g.pdf(cell, dir) } else { 0.0 };
    Drawn { dir, base, tree, pdf: alpha * tree + (1.0 - alpha) * base }
}

/// Most medium vertices of one path whose directions are learned from (the rest are still
/// sampled from the guide, but teach it nothing: learning data only).
const MAX_RECORDED: usize = 64;

/// A medium vertex whose direction a guided walk sampled, for learning once the path is
/// complete.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MediumVertex {
    cell: u32,
    dir: Vec3A,
    /// The phase function's value, or a Lambertian surface's `cos/π` (its `f·cos` over `ρ`,
    /// the same for every direction of a cell), along `dir`.
    base: f32,
    /// The cell's tree's density of `dir`.
    tree: f32,
    /// The density it was drawn with (the mixture's).
    pdf: f32,
    /// The radiance the path had gathered before this direction contributed.
    radiance: Vec3A,
    /// The path's throughput with this direction's weight.
    throughput: Vec3A,
}

/// Deposits at each recorded vertex the light that arrived along its direction (what the
/// path gathered after it, over the throughput that direction carried), times `base/pdf`:
/// an estimate of `Li·p/pdf` (`Li·f·cos/pdf` up to the cell's `ρ`), and its second moments
/// under each candidate mixture.
fn deposit(guide: &VolumeGuide, d: &mut VolumeDeposits, vertices: &[MediumVertex], radiance: Vec3A) {
    if !radiance.is_finite() {
        return;
    }
    for v in vertices {
        let gathered = radiance - v.radiance;
        let mut li = 0.0;
        for c in 0..3 {
            if v.throughput[c] > 0.0 && gathered[c] > 0.0 {
                li += gathered[c] / v.throughput[c];
            }
        }
        let g = li * v.base;
        let value = g / v.pdf;
        if value.is_finite() && value > 0.0 {
            guide.deposit(d, v.cell as usize, v.dir, value);
            guide.deposit_moments(d, v.cell as usize, g, v.pdf, v.tree, v.base);
        }
    }
}

/// The emission along the camera's delta prefix through film point `film` in a scene with
/// media (the counterpart of [`super::seen::seen_emission`] and its prefix's end): each stretch weighed by the
/// transmittance of the medium it crosses (exact for homogeneous media) instead of by sampled
/// free flights, the delta scatters' throughput as there; and where the prefix ended when it
/// scattered at least once and met a surface without a delta lobe.
#[inline]
pub(crate) fn trace_seen_volume<A: Accel>(
    ctx: &RenderContext<A>,
    film: crate::geometry::Vec2,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
) -> (Vec3A, Option<super::seen::PrefixEnd>) {
    let scene = ctx.scene;
    let mut ray = scene.camera.ray(film);
    let mut medium = scene.camera_medium;
    let (mut weight, mut seen) = (Vec3A::ONE, Vec3A::ZERO);
    let along = |m: Option<u16>, d: f32| m.map_or(Vec3A::ONE, |i| scene.media[usize::from(i)].transmittance(d));
    let (mut segments, mut crossings) = (1u32, 0u32);
    loop {
        scratch.rays += 1;
        if segments > ctx.max_depth {
            return (seen, None);
        }
        let Some(hit) = ctx.accel.intersect(&ray) else {
            return (seen + weight * along(medium, f32::INFINITY) * scene.lights.environment(ray.dir), None);
        };
        weight *= along(medium, hit.t);
        if weight == Vec3A::ZERO {
            return (seen, None);
        }
        let si = scene.interaction(&ray, &hit);
        if si.material.bsdf.is_interface() {
            crossings += 1;
            if crossings > MAX_CROSSINGS {
                return (seen, None);
            }
            medium = scene.medium_interface(si.prim).after(si.ng, ray.dir, medium);
            ray = si.spawn_ray(ray.dir);
            continue;
        }
        crossings = 0;
        seen += weight * si.emitted();
        let Some(s) = super::seen::delta_scatter(&si, segments, rng) else {
            return (seen, (segments > 1).then_some(super::seen::PrefixEnd { ray, t: hit.t }));
        };
        weight *= s.weight;
        medium = scene.medium_interface(si.prim).after(si.ng, s.dir, medium);
        ray = si.spawn_ray(s.dir);
        segments += 1;
    }
}

/// Russian roulette by `albedo`: whether the path goes on (its throughput then divided by
/// the survival probability).
#[inline]
fn survives(albedo: Vec3A, throughput: &mut Vec3A, rng: &mut SampleStream) -> bool {
    let q = survival_probability(albedo);
    if rng.next_f32() >= q {
        return false;
    }
    *throughput /= q;
    true
}

/// NEE at surface vertex `si` (BSDF in `frame`, `wi` the local direction to the viewer),
/// which the arriving ray reached in `medium`; `mixture(dir, bsdf_pdf)` is the density the
/// walk samples `dir` with (the BSDF's, or a guided mixture's).
#[allow(clippy::too_many_arguments)]
#[inline]
fn surface_light<A: Accel>(
    ctx: &RenderContext<A>,
    si: &SurfaceInteraction,
    frame: &Frame,
    wi: Vec3A,
    at: &Receiver,
    mis: MisAt,
    medium: Option<u16>,
    interface: crate::medium::MediumInterface,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
    mixture: impl FnOnce(Vec3A, f32) -> f32,
) -> Vec3A {
    let bsdf = &si.material.bsdf;
    let Some(light) = draw_light(ctx, at, rng) else { return Vec3A::ZERO };
    let dir = if light.infinite { light.p } else { (light.p - si.p).normalize_or_zero() };
    // Opaque surfaces reflect only on the side they are seen from.
    if !bsdf.transmits() && si.n.dot(dir) <= 0.0 {
        return Vec3A::ZERO;
    }
    let local = frame.to_local(dir);
    if !si.consistent(dir, local.z) {
        return Vec3A::ZERO;
    }
    let f = bsdf.eval(wi, local) * local.z.abs();
    if f == Vec3A::ZERO {
        return Vec3A::ZERO;
    }
    let start = interface.after(si.ng, dir, medium);
    let origin = offset_ray_origin(si.p, si.p_err, si.ng, dir);
    let tr = transmittance(ctx.scene, ctx.accel, origin, &light, start, scratch);
    finish(f, tr, &light, mis, || mixture(dir, bsdf.pdf(wi, local)))
}

/// A light sample for NEE at `at` (three dimensions of the stream, always).
#[inline]
fn draw_light<A: Accel>(
    ctx: &RenderContext<A>,
    at: &Receiver,
    rng: &mut SampleStream,
) -> Option<crate::light::LightSample> {
    let u_pick = rng.next_f32();
    let u_point = rng.next_2d();
    ctx.scene.lights.sample(at, u_pick, u_point)
}

/// NEE at point `x` inside a medium: `eval(dir)` gives the phase function's value (per
/// channel) and its sampling density for the direction to the light.
#[allow(clippy::too_many_arguments)]
#[inline]
fn next_event<A: Accel>(
    ctx: &RenderContext<A>,
    at: &Receiver,
    x: Vec3A,
    medium: Option<u16>,
    mis: MisAt,
    rng: &mut SampleStream,
    scratch: &mut Scratch,
    eval: impl FnOnce(Vec3A) -> (Vec3A, f32),
) -> Vec3A {
    let Some(light) = draw_light(ctx, at, rng) else { return Vec3A::ZERO };
    let dir = if light.infinite { light.p } else { (light.p - x).normalize_or_zero() };
    if dir == Vec3A::ZERO {
        return Vec3A::ZERO;
    }
    let (f, pdf) = eval(dir);
    let tr = transmittance(ctx.scene, ctx.accel, x, &light, medium, scratch);
    finish(f, tr, &light, mis, || pdf)
}

/// `f · T · Le / p_light`, weighed against the direction sampler of density `dir_pdf` where
/// `mis` says so (never for delta lights).
#[inline]
fn finish(f: Vec3A, tr: Vec3A, light: &crate::light::LightSample, mis: MisAt, dir_pdf: impl FnOnce() -> f32) -> Vec3A {
    if tr == Vec3A::ZERO {
        return Vec3A::ZERO;
    }
    let value = f * tr * light.emission * light.inv_pdf;
    let weigh = !light.delta && if light.infinite { mis.environment } else { mis.surfaces };
    if weigh { value * power_heuristic(1.0 / light.inv_pdf, dir_pdf()) } else { value }
}

/// The transmittance from `origin` (in `medium`) to the light sample: zero if a surface is
/// in the way, else the product of every crossed medium's transmittance over its stretch.
fn transmittance<A: Accel>(
    scene: &Scene,
    accel: &A,
    mut origin: Vec3A,
    light: &crate::light::LightSample,
    mut medium: Option<u16>,
    scratch: &mut Scratch,
) -> Vec3A {
    let (dir, mut remaining) = if light.infinite {
        // Nothing lies beyond the scene's bounding sphere.
        let (centre, radius) = scene.bounds;
        (light.p, 2.0 * ((origin - centre).length() + radius))
    } else {
        let target = offset_ray_origin(light.p, light.p_err, light.ng, (origin - light.p).normalize_or_zero());
        let span = target - origin;
        let len = span.length();
        if len <= 0.0 {
            return Vec3A::ZERO;
        }
        (span / len, len * (1.0 - 1e-4))
    };
    let mut tr = Vec3A::ONE;
    let along = |m: Option<u16>, d: f32| m.map_or(Vec3A::ONE, |i| scene.media[usize::from(i)].transmittance(d));
    for _ in 0..MAX_CROSSINGS {
        scratch.rays += 1;
        let ray = Ray::new(origin, dir);
        let Some(hit) = accel.intersect(&ray).filter(|h| h.t < remaining) else {
            // Towards the environment, the medium reaches to infinity (where it is not
            // vacuum, nothing arrives).
            let d = if light.infinite { f32::INFINITY } else { remaining };
            return tr * along(medium, d);
        };
        let si = scene.interaction(&ray, &hit);
        if !si.material.bsdf.is_interface() {
            return Vec3A::ZERO;
        }
        tr *= along(medium, hit.t);
        if tr == Vec3A::ZERO {
            return tr;
        }
        medium = scene.medium_interface(si.prim).after(si.ng, dir, medium);
        origin = offset_ray_origin(si.p, si.p_err, si.ng, dir);
        remaining -= hit.t;
    }
    Vec3A::ZERO
}
