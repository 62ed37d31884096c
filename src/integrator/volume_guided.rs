//! `zvidpt` in scenes with participating media: volumetric path tracing (`path`'s, in `volume.rs`)
//! whose directions at medium points and on Lambertian surfaces come from a one-sample mixture
//! of the phase function (or cosine sampling) and a guide learned from the render's own paths
//! ([`VolumeGuide`]), trained over iterations of 1, 2, 4, … spp as the surface walk's guide is
//! (the same budget rules), the iterations' own samples kept in the image. Other surfaces
//! sample their BSDF as `path` does. (The surface walk's guide cannot serve here: it models
//! neither media nor the light that crosses them.)
//!
//! Unbiased: a direction's weight is the phase function (or `f·cos`) over the density of the
//! mixture that drew it, and NEE weighs its light against that same density. Each cell's
//! share of its tree is chosen after every iteration by the second moments its directions
//! would have had under each candidate share (0 where the phase function or cosine sampling
//! does best). At the end of training a probe measures variance × rays per sample of the
//! guided walk and of `path` from the same pixels; where the guided walk loses, `path`
//! renders the rest (the choice looks only at samples that are not the image's). Where a
//! light smaller than a pixel projects, the seen light is split over the pixel from the first
//! training pass on.
use super::path::PathTracer;
use super::seen::{
    SeenPlan, SeenStats, UNSPLIT, plan, plan_from_projection, probe_seen, projected_variance, split_seen,
};
use super::volume::{Guidance, trace_volume_path};
use super::zvidpt::{
    Allocation, Iteration, LearnedSettings, MIN_TRAINING_SPP, PROBE_SPP, PixelSums, Pooled, TrainingSums, add_sample,
    add_training_sample, gather_rows, iteration_fits, probe_lattice, render_rays, training_budget,
};
use super::{Integrator, RenderContext, Scratch};
use crate::Result;
use crate::accel::Accel;
use crate::film::PriorSamples;
use crate::geometry::{UVec2, Vec3A};
use crate::learned_guide::volume::{VolumeDeposits, VolumeGuide};
use crate::sampler::{Domain, SampleStream};
use rayon::prelude::*;
use std::time::Instant;

/// Each cell's first probability of sampling its learned tree (where it has one; then learned
/// per cell); the rest samples the phase function or the cosine (PPG's one-sample mixture
/// uses ½ throughout).
pub const VOLUME_GUIDE_MIX: f32 = 0.5;

/// The guided volumetric walk (see the module's text).
pub struct GuidedVolume {
    /// The learned integrator's settings (`mis`, `fallback`, `split_samples`, `train_spp`,
    /// `roulette` for the name).
    pub settings: LearnedSettings,
    /// The guide the training learned.
    pub guide: Option<VolumeGuide>,
    /// The training iterations, in order.
    pub iterations: Vec<Iteration>,
    prior: Option<PriorSamples>,
    /// The probe's figures (variance × rays per sample): guided walk, path.
    pub probe: Option<(f64, f64)>,
    /// Whether `path` renders the rest (the guided walk lost, or learned nothing).
    pub fell_back: bool,
    /// Where the seen light is split over the pixel, and how finely (after training).
    seen: Option<SeenPlan>,
    /// Each pixel's sample rate for the render (as the surface walk's: `allocation`).
    rates: Option<Vec<f32>>,
}

/// What one training iteration returns.
struct Pass {
    deposits: VolumeDeposits,
    sums: TrainingSums,
}

impl GuidedVolume {
    /// The walk with these settings, before training.
    #[must_use]
    pub fn new(settings: LearnedSettings) -> Self {
        Self {
            settings,
            guide: None,
            iterations: Vec::new(),
            prior: None,
            probe: None,
            fell_back: false,
            seen: None,
            rates: None,
        }
    }

    /// Training samples per pixel so far (iterations of 2^k spp).
    fn training_spp(&self) -> u32 {
        self.iterations.iter().map(|i| i.spp).sum()
    }

    /// One sample of the guided walk (the path tracer's where `guidance` has no guide).
    #[inline]
    fn walk<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
        guidance: Guidance,
    ) -> Vec3A {
        let path = PathTracer { mis: self.settings.mis, ..PathTracer::default() };
        trace_volume_path(ctx, pixel, rng, scratch, path.rr_depth, path.mis, guidance)
    }

    /// One training iteration over the whole image at `spp`: samples `spp .. 2·spp` of each
    /// pixel's sequence, what they deposited, each pixel's sums, and each pixel's sums of its
    /// seen light and the rest ([`SeenStats`]).
    fn train_pass<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        guide: &VolumeGuide,
        early: Option<&SeenPlan>,
        seed: u64,
        spp: u32,
    ) -> Pass {
        let (width, height) = (ctx.scene.camera.width, ctx.scene.camera.height);
        let (deposits, mut rows) = (0..height)
            .into_par_iter()
            .with_min_len(4)
            .fold(
                || (guide.deposits(), Vec::<(u32, Vec<PixelSums>, u64)>::new()),
                |(mut deposits, mut rows), y| {
                    let mut scratch = Scratch::default();
                    let row: Vec<PixelSums> = (0..width)
                        .map(|x| {
                            let mut sums = PixelSums::default();
                            let pixel = UVec2::new(x, y);
                            let strata = early.map_or(UNSPLIT, |p| p.strata(pixel));
                            let apart = strata > UNSPLIT;
                            for s in spp..2 * spp {
                                let mut rng = SampleStream::new(seed, y * width + x, s);
                                let rays_before = scratch.rays;
                                let guidance =
                                    Guidance { guide: Some(guide), deposits: Some(&mut deposits), seen_apart: apart };
                                let walk = self.walk(ctx, pixel, &mut rng, &mut scratch, guidance);
                                // The walk's own seen light (left out of `walk` where `apart`),
                                // for the plan's statistics.
                                let walk_seen = scratch.seen;
                                let v = if apart {
                                    walk + split_seen(ctx, pixel, strata, &mut rng, &mut scratch)
                                } else {
                                    walk
                                };
                                let (v, seen, walk) = if v.is_finite() && walk_seen.is_finite() {
                                    (v, f64::from(walk_seen.element_sum()), walk)
                                } else {
                                    (Vec3A::ZERO, 0.0, Vec3A::ZERO)
                                };
                                let rest = f64::from(walk.element_sum()) - if apart { 0.0 } else { seen };
                                let rays = scratch.rays - rays_before;
                                add_training_sample(&mut sums, v, seen, rest, (scratch.seen_rays, rays));
                            }
                            sums
                        })
                        .collect();
                    rows.push((y, row, scratch.rays));
                    (deposits, rows)
                },
            )
            .reduce(
                || (VolumeDeposits::default(), Vec::new()),
                |(a, mut rows), (b, more)| {
                    rows.extend(more);
                    (a.merge(b), rows)
                },
            );
        rows.sort_unstable_by_key(|r| r.0);
        Pass { deposits, sums: gather_rows(rows) }
    }

    /// Mean per-sample variance and rays per sample of a walk over the probe lattice
    /// ([`probe_lattice`]), [`PROBE_SPP`] samples per pixel from streams of their own (the same
    /// for both walks). The seen light is left out: both walks count it alike (split over the
    /// pixel where that pays), and where a light smaller than a pixel is seen, its hits and
    /// misses would decide the comparison.
    fn probe<A: Accel>(&self, ctx: &RenderContext<A>, guide: Option<&VolumeGuide>, seed: u64) -> (f64, f64) {
        let width = ctx.scene.camera.width;
        probe_lattice(ctx, |pixel, scratch| {
            let index = u64::from(pixel.y * width + pixel.x);
            let (mut sum, mut sum_sq) = ([0.0f64; 3], [0.0f64; 3]);
            for s in 0..PROBE_SPP {
                let mut rng = SampleStream::in_domain(Domain::Probe, seed, index, u64::from(s));
                let guidance = Guidance { guide, deposits: None, seen_apart: true };
                let v = self.walk(ctx, pixel, &mut rng, scratch, guidance);
                add_sample(&mut sum, &mut sum_sq, if v.is_finite() { v } else { Vec3A::ZERO });
            }
            (sum, sum_sq)
        })
    }
}

impl Integrator for GuidedVolume {
    /// The pixel's strata per axis for its seen light ([`super::seen`]).
    type PixelState = u8;

    fn name(&self) -> &'static str {
        match self.settings.roulette {
            super::Roulette::Albedo => "jensen-learned",
            _ => "zvidpt",
        }
    }

    fn prepare<A: Accel>(&mut self, ctx: &RenderContext<A>, seed: u64) -> Result<Option<String>> {
        let mut guide = VolumeGuide::new(ctx.scene.bounds, VOLUME_GUIDE_MIX, self.settings.split_samples);
        self.iterations.clear();
        self.probe = None;
        self.fell_back = false;
        let (planned, time_budget) = training_budget(ctx, self.settings.train_spp);
        let (width, height) = (ctx.scene.camera.width, ctx.scene.camera.height);
        let mut prior = PriorSamples::new(width, height);
        let mut rays = 0u64;
        let mut seen_stats = SeenStats::default();
        let mut pooled = Pooled::new(self.settings.allocation == Allocation::Error, (width * height) as usize);
        self.seen = None;
        // Pixels where a light smaller than the pixel projects are split from the first
        // training pass (a plan from the scene's geometry alone, so the training samples stay
        // unbiased): a training sample that meets such a light unsplit reads about its whole
        // radiance (2·10⁵ on volumetric-caustic), and a pass that holds one outweighs the
        // render's own.
        let projected = projected_variance(ctx);
        let early = (self.settings.seen_strata > UNSPLIT)
            .then(|| plan_from_projection(width, &projected, self.settings.seen_strata))
            .filter(|p| p.split_pixels().0 > 0);
        for k in 0..16u32 {
            if !iteration_fits(ctx, k, planned, time_budget, self.iterations.last()) {
                break;
            }
            let spp = 1u32 << k;
            let t = Instant::now();
            guide.begin_iteration();
            let pass = self.train_pass(ctx, &guide, early.as_ref(), seed, spp);
            guide.end_iteration(k, pass.deposits)?;
            prior.add_pass(spp, &pass.sums.sum, &pass.sums.sum_sq);
            rays += pass.sums.rays;
            seen_stats.add(spp, &pass.sums.seen, pass.sums.rays);
            pooled.add(spp, &pass.sums);
            self.iterations.push(Iteration { spp, seconds: t.elapsed().as_secs_f64() });
        }
        // The choice, with the guide the render would sample.
        if self.settings.fallback && self.training_spp() >= MIN_TRAINING_SPP {
            let (v_guided, r_guided) = self.probe(ctx, Some(&guide), seed);
            let (v_path, r_path) = self.probe(ctx, None, seed);
            let (g, p) = (v_guided * r_guided, v_path * r_path);
            self.probe = Some((g, p));
            self.fell_back = g > p;
        }
        // Where to split the seen light, as the surface walk decides it.
        let (mut seen_probe_rays, mut seen_probe_near, mut slivers) = (0u64, 0usize, 0usize);
        if self.settings.seen_strata > UNSPLIT && !seen_stats.sums.is_empty() {
            let samples = seen_stats.samples as f64 * seen_stats.sums.len() as f64;
            let cost = seen_stats.rays as f64 / samples.max(1.0);
            // The probe of pixels seen through delta scatters, as the surface walk's.
            let seconds: f64 = self.iterations.iter().map(|i| i.seconds).sum();
            let rays = if self.settings.seen_probe { render_rays(ctx, &seen_stats, seconds) } else { 0.0 };
            let probe = probe_seen(ctx, seed, width, &seen_stats, rays);
            prior.exclude(probe.sliver());
            self.seen = Some(plan(width, &seen_stats, &probe.planned(&projected), cost, self.settings.seen_strata));
            (seen_probe_rays, seen_probe_near, slivers) = (probe.rays, probe.refined, probe.slivers());
        }
        // (Its training splits the seen light where the projection asks from the start, so
        // the training's variances and rays are already those of the render there; where the
        // probe adds a split, the rates keep the unsplit measure: fewer samples there than
        // the split would ask, never a biased one.)
        self.rates = pooled.rates(width, height, |_, variance, cost| (variance, cost));
        drop(pooled);
        self.prior = (!prior.is_empty()).then_some(prior);
        let seen = match self.seen.as_ref().map(SeenPlan::split_pixels) {
            Some((n, m)) if n > 0 => {
                format!(
                    "; seen light split over the pixel in {n} pixels (up to {m}x{m} film points; delta prefixes probed with {:.2} M rays, {seen_probe_near} pixels twice near a light, {slivers} slivers of light without the training's samples)",
                    seen_probe_rays as f64 / 1e6
                )
            }
            _ => String::new(),
        };
        let training: Vec<String> = self.iterations.iter().map(|i| i.spp.to_string()).collect();
        let samples = f64::from(self.training_spp()) * f64::from(width) * f64::from(height);
        let probe = match self.probe {
            Some((g, p)) => format!(
                "; walk probe ({PROBE_SPP} spp, variance x rays per sample): guided {g:.3e}, path {p:.3e}: {}",
                if self.fell_back { "path renders the rest" } else { "guided walk kept" }
            ),
            None => String::new(),
        };
        let line = format!(
            "participating media: volumetric paths guided ({} cells, {:.1} MB, tree probabilities {:?} per cell of {:?}); training {} spp ({}) in {:.2} s, {:.2} rays per sample, {} of them in the image{probe}{seen}",
            guide.cells(),
            guide.bytes() as f64 / 1e6,
            guide.mix_histogram(),
            crate::learned_guide::volume::VOLUME_MIX_CANDIDATES,
            self.training_spp(),
            if training.is_empty() { "none".to_string() } else { training.join("+") },
            self.iterations.iter().map(|i| i.seconds).sum::<f64>(),
            rays as f64 / samples.max(1.0),
            self.prior.as_ref().map_or(0, |p| p.spp)
        );
        self.guide = Some(guide);
        Ok(Some(line))
    }

    fn prior_samples(&self) -> Option<&PriorSamples> {
        self.prior.as_ref()
    }

    fn pixel_rates(&self) -> Option<&[f32]> {
        self.rates.as_deref()
    }

    fn training_iterations(&self) -> Option<u32> {
        Some(self.iterations.len() as u32)
    }

    fn bytes_per_pixel(&self) -> u64 {
        272 + 52
    }

    fn first_sample_index(&self) -> u32 {
        if self.iterations.is_empty() { 0 } else { 1 << self.iterations.len() }
    }

    fn setup_pixel<A: Accel>(&self, _: &RenderContext<A>, pixel: UVec2, _: u64, _: &mut Scratch) -> u8 {
        self.seen.as_ref().map_or(UNSPLIT, |p| p.strata(pixel))
    }

    fn sample<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        strata: &u8,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
    ) -> Vec3A {
        let guide = if self.fell_back { None } else { self.guide.as_ref() };
        let split = *strata > UNSPLIT;
        let v = self.walk(ctx, pixel, rng, scratch, Guidance { guide, deposits: None, seen_apart: split });
        if split { v + split_seen(ctx, pixel, *strata, rng, scratch) } else { v }
    }
}
