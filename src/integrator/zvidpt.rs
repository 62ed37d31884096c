//! `zvidpt`: ZVIDPT with a learned importance function.
//!
//! The paper's walk solves `Lr = L1 + ∫ f cos Lr(y) dω` from the camera. Here
//! - `L̃` is learned from the render's own walks ([`crate::learned_guide::LearnedGuide`]), seeded by
//!   the photon map: training iterations of 1, 2, 4, … samples per pixel, each sampling from
//!   the guide frozen at the end of the previous one;
//! - directions come from a one-sample mixture of the learned `f·cos·L̃r` quadtree and cosine
//!   sampling, weighted by the mixture's own density (unbiased whatever was learned);
//! - direct light is collected by NEE at every vertex (collision style): on the ceiling beside
//!   the light, where `L1 ≫ Lind`, the terminal estimator's `q` sat at its 0.95 cap and a
//!   continuing walk carried 1/(1−q) = 20; here the direct part is never gambled;
//! - only the indirect part is rouletted or split, by a weight window in the sense of
//!   Vorba & Křivánek 2016 (ADRRS) on the walk's expected indirect contribution relative to
//!   the pixel's, summed over the three channels (so a red wall's growing red weight counts
//!   as red, not as luminance): a walk expected to contribute r times the pixel's indirect
//!   light is split into r (r above the window) or survives with probability r (below it).
//!   Under exact `L̃` and guiding this is ALGORITHM.md's zero-variance roulette applied to
//!   `Lind`: the survival after k vertices is the product of `Lind/Lr` along the walk.
//!
//! `--roulette q` uses the paper's `q = L̃1/L̃r` (learned) instead, and `--roulette albedo`
//! the path tracer's rule: with it, this is PPG-style guided path tracing
//! (`--integrator jensen --learned-guide on`).
use super::mixture::{Mixture, sample_mixture};
use super::path::{Mis, PathTracer};
use super::seen::{SeenPlan, SeenStats, UNSPLIT, after_split, plan, probe_seen, projected_variance, split_seen};
use super::{Integrator, RenderContext, Scratch, direct_light_against, nee_strategy, power_heuristic, sample_bsdf};
use crate::Result;
use crate::accel::Accel;
use crate::film::{PriorSamples, mean_variance};
use crate::geometry::{Frame, UVec2, Vec3A, luminance, warp};
use crate::learned_guide::{Deposits, DirectionDensities, LearnedGuide, mixture_pdf};
use crate::light::Receiver;
use crate::photon::{Caustics, PhotonMap};
use crate::sampler::{Domain, SampleStream, survival_probability};
use crate::scene::SurfaceInteraction;
use rayon::prelude::*;
use std::f32::consts::FRAC_1_PI;
use std::time::Instant;

/// How a walk decides whether (and how many times) to continue after a vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Roulette {
    /// Weight window on the expected indirect contribution, all channels (splits too).
    Window,
    /// The paper's zero-variance roulette: continue with probability `1 − q`, `q = L̃1/L̃r`.
    Q,
    /// The path tracer's: survival by albedo after 3 bounces (guided path tracing).
    Albedo,
}

/// Settings of the learned integrator.
#[derive(Clone, Debug)]
pub struct LearnedSettings {
    /// Photons seeding the guide (the paper's first pass) and photons per seed estimate.
    pub photons: usize,
    /// Photons in each seed estimate's k-nearest search.
    pub knn: usize,
    /// Samples a guide cell must receive in an iteration to be split (× √2 per iteration;
    /// PPG's c).
    pub split_samples: u64,
    /// Relative second moment of a cell's directions (`n·Σ(g/p)²/(Σ g/p)²` with its best
    /// mixture) above which it splits sooner: at `split_samples·split_moment/ρ`, down to a
    /// quarter ([`crate::learned_guide::LearnedGuide::split_moment`]); 0: off. 2 against off
    /// at equal time (one run; shipped scenes 256×192, 10 s, seeds 1–4; Bitterli's at an
    /// eighth of their size, 8 s, seeds 1–8): water-caustic MSE 26 against 101 (path 539),
    /// cornell-paper 0.0024 against 0.0028, cornell-classic and sky 5% and 12% lower,
    /// cornell-box, coffee and veach-mis 2–5% lower, hair-curl 11% higher, cornell-materials
    /// and veach-bidir within their spread.
    pub split_moment: f32,
    /// Probability of sampling the learned density (the rest: cosine sampling): fixed, or the
    /// start of each cell's learned probability. 0.75 against 0.5: cornell-paper 20–24% lower
    /// MSE at 32 spp for 11% more time; cornell-classic, cornell-blocks and partition 0–4%
    /// lower MSE at equal time (20 s).
    pub guide_mix: f32,
    /// Learn each cell's probability (see [`crate::learned_guide::MIX_CANDIDATES`]), starting from
    /// `guide_mix`. On by default since trees carry over between iterations: cornell-paper
    /// 32 spp MSE 0.0184 on vs 0.0194 off; in the furnace, where cosine sampling is exact,
    /// the variance falls 60× (cells learn 0). (Before the carry-over, on cost 15% there.)
    pub learn_mix: bool,
    /// Weight of earlier iterations' directional data per deposit when a tree is rebuilt
    /// (0: each iteration's tree from its own deposits only, as PPG; 1: from all alike).
    /// On cornell-paper (32 + 31 training spp, seeds 2 and 3) 0.25 and 0.5 lowered the MSE
    /// 15–17% against 0; 0.75 matched 0 and 1 was 25% worse (early iterations' outliers
    /// persist).
    pub guide_carry: f32,
    /// How the walk ends and splits (the weight window, or albedo roulette).
    pub roulette: Roulette,
    /// Weight-window width `s`: no action while the expected contribution ratio lies in
    /// `[2/(1+s), 2s/(1+s)]`.
    pub window: f32,
    /// Most branches one vertex splits into.
    pub max_split: u32,
    /// Roulette around the learned `L̃ind` (a stopped walk returns it) instead of around 0.
    pub control_variate: bool,
    /// Probability of aiming at a cell's learned source box (where it has one).
    pub box_mix: f32,
    /// Caustic photons traced before training, whose exit points from specular surfaces give
    /// source boxes for the cells they reached ([`LearnedGuide::add_caustic_sources`]; 0:
    /// none).
    pub caustic_photons: usize,
    /// Cells that caustic photons reached aim at the caustic lobes of each shading point
    /// rather than at the whole caustic box ([`LearnedGuide::use_caustic_lobes`]).
    pub caustic_lobes: bool,
    /// Training samples per pixel in all (iterations 1, 2, 4, … while they fit); `None`: half
    /// the final sample count, or by the time budget's rule under `--time`.
    pub train_spp: Option<u32>,
    /// Where light that the walk's own directions find is weighed against NEE (power
    /// heuristic, with the density of the mixture actually sampled): as `path`'s `--mis`.
    /// Glossy vertices without it (NEE alone) were the learned integrators' fireflies on
    /// near-specular coats (Bitterli's coffee and veach-mis).
    pub mis: Mis,
    /// Measure the path tracer during training and render with it instead where the learned
    /// walk is less efficient ([`Choice`]).
    pub fallback: bool,
    /// Lowest survival probability the weight window draws (a floor on `1/f`, the factor a
    /// surviving walk's weight grows by where the learned `L̃` is too low). 0.2 against 0.05
    /// at equal time (8 s, 4 seeds; Bitterli's scenes at an eighth of their size): veach-bidir
    /// MSE 0.037 against 0.057, cornell-box 7.0e-6 against 7.8e-6, volumetric-caustic 239
    /// against 1728 (single-pixel fireflies decide the last); shipped scenes at 10 s, 2 seeds:
    /// cornell-paper level (0.0041), cornell-classic and cornell-materials 6% lower, sky 17%
    /// higher (0.0218 against 0.0186; path 0.0229).
    pub min_survival: f32,
    /// Least share of cosine sampling at a Lambertian vertex, whatever the cell learned for
    /// its tree (`alpha`) and source box (`beta`): a defensive mixture, so a direction's
    /// weight is at most `1/defensive` times the path tracer's where a young or wrong guide
    /// misses light. Off (0) by default: 0.25 (with `min_survival` 0.2) lowered veach-bidir's
    /// MSE a further 40% and cornell-classic's 5%, but raised volumetric-caustic's 2.6×,
    /// cornell-paper's 12% and sky's.
    pub defensive: f32,
    /// Most strata per axis over which a pixel's seen light is split ([`super::seen`]; 1:
    /// never split): where a light smaller than the pixel is seen directly or through delta
    /// lobes, up to `seen_strata²` film points per camera sample trace the camera's delta
    /// prefix again, each pixel's count chosen from the training's measurements and the
    /// lights' projection.
    pub seen_strata: u8,
    /// Probe the pixels that see through delta scatters with many film points before the
    /// seen light's plan ([`super::seen::probe_seen`]), so a light's image too small for the
    /// training to meet is split too.
    pub seen_probe: bool,
    /// How the render's samples are shared among the pixels: each pixel's rate from the
    /// training's variance around it ([`crate::film::rates`]), or every pixel alike.
    pub allocation: Allocation,
}

/// How a learned render shares its samples among the pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Allocation {
    /// In proportion to the per-sample standard deviation the training measured around each
    /// pixel (its other-parity neighbours within 5 pixels): least MSE for the samples.
    #[default]
    Error,
    /// The same samples for every pixel.
    Uniform,
}

/// Training samples per pixel below which the training's variances are too few to share the
/// render's samples by.
const MIN_ALLOCATION_SPP: u32 = 7;

impl Default for LearnedSettings {
    fn default() -> Self {
        Self {
            photons: 6891,
            knn: 50,
            split_samples: 4000,
            split_moment: 2.0,
            guide_mix: 0.75,
            learn_mix: true,
            guide_carry: 0.25,
            roulette: Roulette::Window,
            window: 5.0,
            max_split: 8,
            control_variate: true,
            box_mix: 0.3,
            caustic_photons: 10_000,
            caustic_lobes: true,
            train_spp: None,
            mis: Mis::Glossy,
            fallback: true,
            min_survival: 0.2,
            defensive: 0.0,
            seen_strata: 8,
            seen_probe: true,
            allocation: Allocation::Error,
        }
    }
}

/// One training iteration, as reported.
#[derive(Clone, Copy, Debug)]
pub struct Iteration {
    /// Samples per pixel it took.
    pub spp: u32,
    /// Seconds it took.
    pub seconds: f64,
}

/// The learned zero-variance walk (`zvidpt`, and `jensen --learned-guide on`): a guide learned
/// over training iterations from the photon map onwards drives directions, roulette and
/// splitting; it renders with the path tracer instead where training measured that it loses.
pub struct LearnedZvidpt {
    /// How it learns and walks.
    pub settings: LearnedSettings,
    /// The guide the training learned.
    pub guide: Option<LearnedGuide>,
    /// The training iterations, in order.
    pub iterations: Vec<Iteration>,
    /// The training iterations' samples (those of at least 2 spp), which the image includes.
    prior: Option<PriorSamples>,
    /// What the training measured of the learned walk against the path tracer, if it did.
    pub choice: Option<Choice>,
    /// The path tracer that renders instead, when the learned walk lost ([`Choice`]).
    path: Option<PathTracer>,
    /// Whether walks split (up to `max_split` branches) or only roulette: split unless the
    /// probe found the walk more efficient without ([`Choice::split`]).
    split: bool,
    /// Where the seen light is split over the pixel, and how finely (after training).
    seen: Option<SeenPlan>,
    /// Each pixel's sample rate for the render ([`Allocation::Error`]).
    rates: Option<Vec<f32>>,
}

/// What the learned integrator keeps per pixel: the weight window's reference and the
/// strata of its seen light ([`super::seen`]).
#[derive(Clone, Copy, Debug)]
pub struct PixelSetup {
    /// The pixel's reference indirect radiance (channels summed).
    pub reference: f32,
    /// Strata per axis of its seen light (1: counted by the walk).
    pub strata: u8,
}

/// The learned walk against the path tracer, measured during and at the end of training: a
/// probe of each walk from the same first hits ([`PROBE_SPP`] samples through the centres of a
/// lattice of pixels, [`probe_stride`], not in the image; the learned walk with the guide the
/// final render samples) gives the mean per-sample variance times the cost per sample of each.
/// Cost is counted in rays, the learned walk's rays weighing [`LEARNED_RAY_COST`] each, so the
/// choice is a function of scene, options and seed alone (never of the clock). Where the
/// learned walk loses, the path tracer renders the rest; a first judgement as soon as the guide
/// has [`MIN_TRAINING_SPP`] stops the training where the walk loses by more than
/// [`EARLY_MARGIN`], and a walk ahead by [`CLEAR_WIN`] there is not probed again. The training
/// samples stay in the image (each pass unbiased, weighed by inverse variance). Either
/// estimator is unbiased, and the choice looks only at samples that are not the final
/// render's, so the image stays unbiased.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Choice {
    /// Variance × rays per sample: the path probe's, the learned walk's last measured (its
    /// rays weighed).
    pub path: f64,
    /// The same for the learned walk: the better of splitting and not.
    pub learned: f64,
    /// The learned walk's figure without splitting (the same as with it where it cannot
    /// split: `--max-split 1`).
    pub unsplit: f64,
    /// Whether the learned walk splits: its figure with splitting was no higher than
    /// without.
    pub split: bool,
    /// Training samples per pixel before the probe.
    pub after_spp: u32,
    /// Whether the path tracer renders the rest.
    pub fell_back: bool,
}

/// Samples per probed pixel, for each walk.
pub const PROBE_SPP: u32 = 8;
/// Most pixels a probe visits (a regular lattice of them, every second pixel of every second
/// row or sparser): the mean variance of 16,384 pixels × [`PROBE_SPP`] samples is measured well
/// enough to choose between walks, and at 512×384 the probes then cost a quarter of what a
/// quarter of the pixels did (they had taken 1 s of a 12-s `cornell-paper` render).
pub const PROBE_PIXELS: u32 = 16_384;
/// Where the first judgement finds the learned walk ahead by this factor, its further training
/// cannot plausibly turn that into a loss: the final judgement is skipped (its probe cost
/// about 0.4 s of a 12-s `cornell-paper` render, where the walk is 12× ahead).
pub const CLEAR_WIN: f64 = 4.0;

/// Whether a judgement `c` during training stops it: the walk loses by more than its margin
/// ([`Choice::fell_back`]), or it loses after an earlier judgement that measured it at
/// `last` and has gained less than [`MIN_GAIN`] since.
fn stops_training(c: &Choice, last: Option<f64>) -> bool {
    c.fell_back || last.is_some_and(|l| c.learned > c.path && c.learned > (1.0 - MIN_GAIN) * l)
}

/// The training budget of a learning integrator: iterations of 1, 2, 4, … spp. With a sample
/// count, their total stays within `train_spp` (half the final count by default). With a time
/// budget, iterations run while the next (about twice the last) would end within
/// [`TRAIN_FRACTION`] of the budget. Either way the rule never looks at the samples' values.
/// Returns the budget's planned iteration count (for a sample budget) and its time (for a time
/// budget).
pub(crate) fn training_budget<A: Accel>(ctx: &RenderContext<A>, train_spp: Option<u32>) -> (Option<u32>, Option<f64>) {
    let spp_budget = train_spp.or_else(|| ctx.spp.map(|n| (n / 2).max(1)));
    let time_budget = if spp_budget.is_none() { ctx.time_limit } else { None };
    // Iterations that fit the sample budget: 1 + 2 + … + 2^(k−1) = 2^k − 1 ≤ budget.
    let planned = spp_budget.map(|b| (u64::from(b) + 1).ilog2().min(16));
    (planned, time_budget)
}

/// The rays the render will trace, as the training's `stats` (samples and rays over
/// `seconds`) project them: its samples times the rays per sample, or its time budget times
/// the rays per second (a render to a noise target alone: a 64-spp render's).
pub(crate) fn render_rays<A: Accel>(ctx: &RenderContext<A>, stats: &SeenStats, seconds: f64) -> f64 {
    let pixels = stats.sums.len() as f64;
    let per_sample = stats.rays as f64 / (stats.samples as f64 * pixels).max(1.0);
    match (ctx.spp, ctx.time_limit) {
        (Some(spp), _) => f64::from(spp) * pixels * per_sample,
        (None, Some(t)) => t * stats.rays as f64 / seconds.max(1e-3),
        (None, None) => 64.0 * pixels * per_sample,
    }
}

/// Whether training iteration `k` (of `2^k` spp) runs, under [`training_budget`]'s plan, after
/// the iteration `last`.
pub(crate) fn iteration_fits<A: Accel>(
    ctx: &RenderContext<A>,
    k: u32,
    planned: Option<u32>,
    time_budget: Option<f64>,
    last: Option<&Iteration>,
) -> bool {
    match (ctx.training_iterations.or(planned), time_budget) {
        (Some(n), _) => k < n,
        (None, Some(t)) => {
            // An iteration takes about twice its predecessor (first: an estimate).
            let elapsed = ctx.start.elapsed().as_secs_f64();
            let next = last.map_or(0.0, |i| 2.0 * i.seconds);
            k == 0 || elapsed + next <= TRAIN_FRACTION * t
        }
        // Neither (a render to a noise target alone): a 64-spp render's training.
        (None, None) => k < UNBUDGETED_ITERATIONS,
    }
}

/// The probe lattice's spacing for a `width × height` image: the smallest, at least 2, with at
/// most [`PROBE_PIXELS`] pixels.
pub fn probe_stride(width: u32, height: u32) -> u32 {
    // Every lattice denser than sqrt(pixels / PROBE_PIXELS) holds more pixels: start there.
    let pixels = u64::from(width) * u64::from(height);
    let mut s = ((pixels / u64::from(PROBE_PIXELS)) as f64).sqrt() as u32;
    s = s.max(2);
    while u64::from(width.div_ceil(s)) * u64::from(height.div_ceil(s)) > u64::from(PROBE_PIXELS) {
        s += 1;
    }
    s
}
/// At the first judgement (after [`MIN_TRAINING_SPP`]) the learned walk must lose by this
/// factor to stop the training; at the end of training, by any.
pub const EARLY_MARGIN: f64 = 1.5;
/// A learned walk that loses at a judgement after the first must have lowered its figure by
/// this fraction since the last, or the training stops there: a guide that a doubling of its
/// samples leaves as it was will not turn a loss into a win (Bitterli's coffee: its guide,
/// learned on the few Lambertian surfaces, reads the same 1.2× path's figure after 7 and 63
/// spp; veach-mis 1.35× and 1.33×; water-caustic, which wins at the end, gained 6% a
/// doubling).
pub const MIN_GAIN: f64 = 0.03;
/// Training samples per pixel the guide needs before it is judged (1 + 2 + 4: the youngest
/// guides are no measure of the walk).
pub const MIN_TRAINING_SPP: u32 = 7;
/// Seconds per ray of the learned walk over the path tracer's (guide lookups, splitting):
/// measured 1.12 (Bitterli's coffee), 1.22 (veach-mis), ... at 2 threads.
pub const LEARNED_RAY_COST: f64 = 1.2;

/// Training iterations (1 + 2 + … + 16 = 31 spp, as a 64-spp render's) where the render has
/// neither a sample count nor a time budget (it stops at a noise target).
const UNBUDGETED_ITERATIONS: u32 = 5;

/// Under a time budget, training iterations run while the next would end within this
/// fraction of it.
pub const TRAIN_FRACTION: f64 = 0.35;

/// Most branches one camera sample may grow into (bounds the cost of a sample).
const MAX_BRANCHES: u32 = 64;
/// The tree's share `alpha` (of the directions not aimed at the source box) and the source
/// box's share `beta` as learned, lowered where needed so that cosine sampling keeps at least
/// `defensive` of all directions: `(1 − beta)(1 − alpha) ≥ defensive`. Unchanged when
/// `defensive` is 0.
fn defensive_shares(alpha: f32, beta: f32, defensive: f32) -> (f32, f32) {
    if defensive <= 0.0 {
        return (alpha, beta);
    }
    let alpha = alpha.min(1.0 - defensive);
    (alpha, beta.min(1.0 - defensive / (1.0 - alpha)).max(0.0))
}

/// Photon paths traced per caustic photon asked for, at most (a scene whose glass few
/// photons reach gives up early: caustics that rare are no source worth aiming at).
const CAUSTIC_PATHS_PER_PHOTON: u64 = 20;

/// Set-up rays per pixel for its reference indirect radiance.
const SETUP_RAYS: u32 = 4;

impl LearnedZvidpt {
    /// An integrator that has not trained yet (its pre-pass trains).
    #[must_use]
    pub fn new(settings: LearnedSettings) -> Self {
        Self {
            settings,
            guide: None,
            iterations: Vec::new(),
            prior: None,
            choice: None,
            path: None,
            split: true,
            seen: None,
            rates: None,
        }
    }

    /// Where the pixels' seen light is split, as the training decided ([`super::seen`]).
    #[must_use]
    pub fn seen_plan(&self) -> Option<&SeenPlan> {
        self.seen.as_ref()
    }

    /// Training samples actually spent.
    #[must_use]
    pub fn training_spp(&self) -> u32 {
        self.iterations.iter().map(|i| i.spp).sum()
    }

    /// The continuation factor at a vertex: the expected number of continuations (below 1: a
    /// survival probability). Any positive value keeps the estimator unbiased, since each
    /// continuation is weighted by its inverse.
    #[inline]
    fn continuation(&self, albedo: Vec3A, walk: WalkState, est: Option<crate::learned_guide::CellEstimate>) -> f32 {
        let WalkState { weight, reference, depth, .. } = walk;
        let f = match self.settings.roulette {
            Roulette::Albedo => {
                if depth >= 3 {
                    survival_probability(albedo)
                } else {
                    1.0
                }
            }
            Roulette::Q => match est {
                Some(e) => {
                    let (l1, lr) = (luminance(e.direct), luminance(e.direct + e.indirect));
                    1.0 - if lr > 0.0 { (l1 / lr).clamp(0.05, 0.95) } else { 0.5 }
                }
                None => 0.5,
            },
            Roulette::Window => match est {
                Some(e) => {
                    let r = (weight * e.indirect).element_sum() / reference;
                    let s = self.settings.window;
                    let lower = 2.0 / (1.0 + s);
                    if r.is_nan() {
                        1.0
                    } else if r < lower || r > s * lower {
                        let most = if self.split { self.settings.max_split } else { 1 };
                        r.clamp(self.settings.min_survival, most as f32)
                    } else {
                        1.0
                    }
                }
                None => survival_probability(albedo),
            },
        };
        // Long walks end: beyond 32 vertices at most 0.8 survive (unbiased, and the chance of
        // a walk deeper than 500 is below 1e-45), and deep vertices never split.
        if depth >= 32 { f.min(0.8) } else { f }
    }

    /// The pixel's reference indirect radiance (summed over channels) for the weight window:
    /// the mean learned `L̃ind` at the first hits of [`SETUP_RAYS`] set-up rays. Their rays
    /// are the caller's to count: a render traces them once per pixel, where the training
    /// passes and the probes, which trace them once per pass, leave them out of the walk's
    /// rays per sample (counted, they charged the probe's learned walk half a ray per
    /// sample: 12% of veach-mis's, 11% of coffee's).
    fn pixel_reference<A: Accel>(&self, ctx: &RenderContext<A>, guide: &LearnedGuide, pixel: UVec2, seed: u64) -> f32 {
        let index = pixel.y as u64 * ctx.scene.camera.width as u64 + pixel.x as u64;
        let mut rng = SampleStream::in_domain(Domain::PixelSetup, seed, index, 1);
        let mut sum = 0.0;
        for _ in 0..SETUP_RAYS {
            let ray = ctx.scene.camera.ray(ctx.scene.camera.film_point(pixel, rng.next_2d()));
            if let Some(hit) = ctx.accel.intersect(&ray) {
                let si = ctx.scene.interaction(&ray, &hit);
                if let Some(e) = guide.estimate(guide.cell(si.p, si.n)) {
                    sum += e.indirect.element_sum();
                }
            }
        }
        (sum / SETUP_RAYS as f32).max(1e-4)
    }

    /// One training iteration over the whole image at `spp`; returns what its walks
    /// deposited, each pixel's sums and sums of squares (row-major), and each pixel's sums of
    /// its seen light and the rest ([`SeenStats`]) with the rays traced.
    fn train_pass<A: Accel>(&self, ctx: &RenderContext<A>, guide: &LearnedGuide, seed: u64, spp: u32) -> TrainPass {
        let (width, height) = (ctx.scene.camera.width, ctx.scene.camera.height);
        let walker = Walker { zvidpt: self, ctx, guide };
        // Each worker deposits into its own accumulators, summed afterwards (integer sums:
        // the same bits however rayon split the rows).
        let (deposits, mut rows) = (0..height)
            .into_par_iter()
            .with_min_len(4)
            .fold(
                || (guide.deposits(), Vec::<(u32, Vec<PixelSums>, u64)>::new()),
                |(mut deposits, mut rows), y| {
                    let mut scratch = Scratch::default();
                    let mut row = Vec::new();
                    for x in 0..width {
                        let pixel = UVec2::new(x, y);
                        let reference = self.pixel_reference(ctx, guide, pixel, seed);
                        let mut sums = PixelSums::default();
                        // Iteration k takes samples 2^k .. 2^(k+1) of the pixel's sequence (an
                        // aligned block: stratified by itself, and with the others).
                        for s in spp..2 * spp {
                            let mut rng = SampleStream::new(seed, y * width + x, s);
                            scratch.seen = Vec3A::ZERO;
                            let rays_before = scratch.rays;
                            let v = walker.camera_sample(
                                pixel,
                                reference,
                                UNSPLIT,
                                &mut rng,
                                &mut scratch,
                                Some(&mut deposits),
                            );
                            let (v, seen) = if v.is_finite() && scratch.seen.is_finite() {
                                (v, f64::from(scratch.seen.element_sum()))
                            } else {
                                (Vec3A::ZERO, 0.0)
                            };
                            let rest = f64::from(v.element_sum()) - seen;
                            let rays = scratch.rays - rays_before;
                            add_training_sample(&mut sums, v, seen, rest, (scratch.seen_rays, rays));
                        }
                        row.push(sums);
                    }
                    rows.push((y, row, scratch.rays));
                    (deposits, rows)
                },
            )
            .reduce(
                || (Deposits::default(), Vec::new()),
                |(a, mut rows), (b, more)| {
                    rows.extend(more);
                    (a.merge(b), rows)
                },
            );
        rows.sort_unstable_by_key(|r| r.0);
        TrainPass { deposits, sums: gather_rows(rows) }
    }

    /// Probes both walks (the path tracer's once, kept in `path_probe`) and records the
    /// choice: the learned walk falls back when its figure exceeds `margin` times path's.
    fn judge<A: Accel>(
        &mut self,
        ctx: &RenderContext<A>,
        path: &PathTracer,
        guide: &LearnedGuide,
        seed: u64,
        path_probe: &mut Option<(f64, f64)>,
        margin: f64,
    ) -> Choice {
        let (v_path, rays_path) = *path_probe.get_or_insert_with(|| self.probe(ctx, path, None, seed));
        let figure = |(v, rays): (f64, f64)| v * rays * LEARNED_RAY_COST;
        self.split = true;
        let split = figure(self.probe(ctx, path, Some(guide), seed));
        let unsplit = if self.settings.max_split > 1 && self.settings.roulette == Roulette::Window {
            self.split = false;
            let u = figure(self.probe(ctx, path, Some(guide), seed));
            self.split = split <= u;
            u
        } else {
            split
        };
        let (p, l) = (v_path * rays_path, split.min(unsplit));
        let c = Choice {
            path: p,
            learned: l,
            unsplit,
            split: self.split,
            after_spp: self.training_spp(),
            fell_back: l > margin * p,
        };
        self.choice = Some(c);
        c
    }

    /// A probe of the walks: over a lattice of pixels ([`probe_stride`]: every second pixel of
    /// every second row, sparser in images of more than 4 × [`PROBE_PIXELS`]), [`PROBE_SPP`] samples through the pixel's centre, so that every sample starts
    /// from the same first hit and the spread is the walk's alone (the pixel footprint's
    /// variance, which both estimators share and the pixel's (0,2)-sequence removes from the
    /// image, would otherwise dominate: on `cornell-paper` at 256×192 the per-sample variance
    /// was 8.0 for path and 3.6 for the learned walk, whose MSE is a tenth of path's).
    /// Returns the mean per-sample variance and the rays per sample; the path tracer's walk
    /// when `guide` is `None`, else the learned walk from `guide`. Sample streams of their own.
    fn probe<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        path: &PathTracer,
        guide: Option<&LearnedGuide>,
        seed: u64,
    ) -> (f64, f64) {
        let width = ctx.scene.camera.width;
        let walker = guide.map(|guide| Walker { zvidpt: self, ctx, guide });
        probe_lattice(ctx, |pixel, scratch| {
            let index = u64::from(pixel.y * width + pixel.x);
            let reference = guide.map_or(0.0, |g| self.pixel_reference(ctx, g, pixel, seed));
            let (mut sum, mut sum_sq) = ([0.0f64; 3], [0.0f64; 3]);
            for s in 0..PROBE_SPP {
                // Keyed apart for the two walks; the film point is the centre.
                let key = 2 * u64::from(s) + u64::from(guide.is_some());
                let mut rng = SampleStream::in_domain(Domain::Probe, seed, index, key);
                let v = match &walker {
                    Some(w) => w.camera_sample(pixel, reference, UNSPLIT, &mut rng, scratch, None),
                    None => path.sample(ctx, pixel, &(), &mut rng, scratch),
                };
                add_sample(&mut sum, &mut sum_sq, if v.is_finite() { v } else { Vec3A::ZERO });
            }
            (sum, sum_sq)
        })
    }
}

/// One pixel's sums over a training pass: of its samples per channel, of their squares, the
/// parts of [`SeenStats`] (seen, seen², rest, rest², rays of the delta prefix, seen·rest), and the rays
/// its samples traced.
pub(crate) type PixelSums = ([f64; 3], [f64; 3], [f64; 6], f64);

/// Adds training sample `v`, of seen light `seen` and rest `rest` (channels summed) after
/// `seen_rays` rays of its delta prefix and `rays` in all, to its pixel's sums.
#[inline]
pub(crate) fn add_training_sample(p: &mut PixelSums, v: Vec3A, seen: f64, rest: f64, (seen_rays, rays): (u32, u64)) {
    add_sample(&mut p.0, &mut p.1, v);
    p.3 += rays as f64;
    let parts = &mut p.2;
    parts[0] += seen;
    parts[1] += seen * seen;
    parts[2] += rest;
    parts[3] += rest * rest;
    parts[4] += f64::from(seen_rays);
    parts[5] += seen * rest;
}

/// A training pass's rows (row index, its pixels' sums, its rays), sorted by row: every
/// pixel's sums, sums of squares, seen parts and rays in row-major order, and the rays in all.
pub(crate) fn gather_rows(rows: Vec<(u32, Vec<PixelSums>, u64)>) -> TrainingSums {
    let rays = rows.iter().map(|r| r.2).sum();
    let (mut sum, mut sum_sq, mut seen, mut cost) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (a, b, c, d) in rows.into_iter().flat_map(|r| r.1) {
        sum.push(a);
        sum_sq.push(b);
        seen.push(c);
        cost.push(d);
    }
    TrainingSums { sum, sum_sq, seen, cost, rays }
}

/// What [`gather_rows`] returns: per pixel (row-major) the sums of samples, of their squares,
/// the seen parts and the rays traced; and the rays in all.
pub(crate) struct TrainingSums {
    pub sum: Vec<[f64; 3]>,
    pub sum_sq: Vec<[f64; 3]>,
    pub seen: Vec<[f64; 6]>,
    pub cost: Vec<f64>,
    pub rays: u64,
}

/// Every training sample's sums per pixel (all passes together), for the sample rates that
/// share the render's samples ([`Allocation::Error`]).
pub(crate) struct Pooled {
    spp: u32,
    /// Per pixel: sums of samples and of their squares per channel, and rays traced.
    sums: Vec<([f64; 3], [f64; 3], f64)>,
}

impl Pooled {
    /// Pooled sums of `pixels` pixels, kept only `on`.
    pub(crate) fn new(on: bool, pixels: usize) -> Self {
        Self { spp: 0, sums: if on { vec![([0.0; 3], [0.0; 3], 0.0); pixels] } else { Vec::new() } }
    }

    /// Adds a training pass of `spp` samples per pixel.
    pub(crate) fn add(&mut self, spp: u32, pass: &TrainingSums) {
        if self.sums.len() != pass.sum.len() {
            return;
        }
        for (p, ((s, q), c)) in self.sums.iter_mut().zip(pass.sum.iter().zip(&pass.sum_sq).zip(&pass.cost)) {
            for k in 0..3 {
                p.0[k] += s[k];
                p.1[k] += q[k];
            }
            p.2 += c;
        }
        self.spp += spp;
    }

    /// Each pixel's sample rate ([`crate::film::rates`]) from its neighbours' per-sample
    /// variances (channels averaged) and rays per sample, as `render(pixel, variance, rays)`
    /// expects the render's samples to have them; `None` below [`MIN_ALLOCATION_SPP`]
    /// training samples per pixel or without sums.
    pub(crate) fn rates(
        &self,
        width: u32,
        height: u32,
        render: impl Fn(usize, f64, f64) -> (f64, f64),
    ) -> Option<Vec<f32>> {
        if self.sums.is_empty() || self.spp < MIN_ALLOCATION_SPP {
            return None;
        }
        let n = f64::from(self.spp);
        let (variance, cost): (Vec<f64>, Vec<f64>) = self
            .sums
            .iter()
            .enumerate()
            .map(|(i, (s, q, r))| {
                let v = (0..3).map(|c| ((q[c] - s[c] * s[c] / n) / (n - 1.0)).max(0.0)).sum::<f64>() / 3.0;
                // Rays per sample, at least the camera ray.
                render(i, v, (r / n).max(1.0))
            })
            .unzip();
        crate::film::rates::pixel_rates(width, height, &variance, Some(&cost))
    }
}

/// Adds sample `v` to a pixel's per-channel sums and sums of squares.
#[inline]
pub(crate) fn add_sample(sum: &mut [f64; 3], sum_sq: &mut [f64; 3], v: Vec3A) {
    for c in 0..3 {
        sum[c] += f64::from(v[c]);
        sum_sq[c] += f64::from(v[c]) * f64::from(v[c]);
    }
}

/// A probe over the lattice of pixels of [`probe_stride`]: `pixel_sums(pixel, scratch)` takes
/// the pixel's [`PROBE_SPP`] samples and returns their per-channel sums and sums of squares.
/// Returns the mean per-sample variance and the rays per sample (rows summed in order: the
/// same figures at any thread count).
pub(crate) fn probe_lattice<A: Accel>(
    ctx: &RenderContext<A>,
    pixel_sums: impl Fn(UVec2, &mut Scratch) -> ([f64; 3], [f64; 3]) + Sync,
) -> (f64, f64) {
    let (width, height) = (ctx.scene.camera.width, ctx.scene.camera.height);
    let stride = probe_stride(width, height);
    let (mut rows, rays) = (0..height.div_ceil(stride))
        .into_par_iter()
        .map(|i| stride * i)
        .with_min_len(2)
        .fold(
            || (Vec::new(), 0u64),
            |(mut rows, rays), y| {
                let mut scratch = Scratch::default();
                let row: Vec<([f64; 3], [f64; 3])> =
                    (0..width).step_by(stride as usize).map(|x| pixel_sums(UVec2::new(x, y), &mut scratch)).collect();
                rows.push((y, row));
                (rows, rays + scratch.rays)
            },
        )
        .reduce(
            || (Vec::new(), 0),
            |(mut rows, r), (more, s)| {
                rows.extend(more);
                (rows, r + s)
            },
        );
    rows.sort_unstable_by_key(|r: &(u32, Vec<_>)| r.0);
    let (sum, sum_sq): (Vec<_>, Vec<_>) = rows.into_iter().flat_map(|r| r.1).unzip();
    let samples = sum.len() as f64 * f64::from(PROBE_SPP);
    (mean_variance(PROBE_SPP, &sum, &sum_sq), rays as f64 / samples.max(1.0))
}

/// The environment seen along `dir`, sampled with density `pdf`, weighed against NEE's.
#[inline]
fn found_environment<A: Accel>(ctx: &RenderContext<A>, dir: Vec3A, pdf: f32) -> Vec3A {
    let env = ctx.scene.lights.environment(dir);
    if env == Vec3A::ZERO { env } else { env * power_heuristic(pdf, ctx.scene.lights.environment_pdf(dir)) }
}

/// What one training iteration returns ([`LearnedZvidpt::train_pass`]).
struct TrainPass {
    deposits: Deposits,
    /// Its samples' sums per pixel; the rays the walks traced, the pixels' set-up rays left
    /// out.
    sums: TrainingSums,
}

/// What a learned walk carries from vertex to vertex.
#[derive(Clone, Copy, Debug)]
struct WalkState {
    /// The path's weight so far (the product of the throughputs and continuation weights).
    weight: Vec3A,
    /// The pixel's reference indirect radiance, which the weight window compares against.
    reference: f32,
    /// Vertices before this one (0 at the camera's first hit).
    depth: u32,
    /// How many walks this one's splits have made of the camera sample so far.
    branches: u32,
    /// Whether every scatter from the camera to here was a delta lobe: emission found next
    /// behind a delta lobe is the pixel's seen light (recorded in `Scratch::seen`).
    prefix: bool,
    /// Whether the pixel's seen light is estimated apart ([`super::seen`]): the walk leaves
    /// it out.
    split_seen: bool,
}

/// What a learned walk reads at every vertex: the integrator's settings, the render and the
/// learned guide.
struct Walker<'a, A: Accel> {
    zvidpt: &'a LearnedZvidpt,
    ctx: &'a RenderContext<'a, A>,
    guide: &'a LearnedGuide,
}

impl<A: Accel> Walker<'_, A> {
    /// One camera sample: emission seen directly, plus the walk's estimate of `Lr`
    /// (depositing what it learns into `deposits` in a training iteration).
    fn camera_sample(
        &self,
        pixel: UVec2,
        reference: f32,
        strata: u8,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
        deposits: Option<&mut Deposits>,
    ) -> Vec3A {
        let ctx = self.ctx;
        let ray = ctx.scene.camera.ray(ctx.scene.camera.film_point(pixel, rng.pixel_2d()));
        scratch.rays += 1;
        scratch.seen_rays = 1;
        // Paths of at most `max_depth` segments: the camera's is the first.
        if ctx.max_depth == 0 {
            return Vec3A::ZERO;
        }
        let Some(hit) = ctx.accel.intersect(&ray) else {
            return ctx.scene.lights.environment(ray.dir);
        };
        let si = ctx.scene.interaction(&ray, &hit);
        let emitted = si.emitted();
        scratch.seen += emitted;
        let split = strata > UNSPLIT;
        let walk = WalkState { weight: Vec3A::ONE, reference, depth: 0, branches: 1, prefix: true, split_seen: split };
        let reflected = self.reflected(&si, walk, rng, scratch, deposits);
        if split { reflected + split_seen(ctx, pixel, strata, rng, scratch) } else { emitted + reflected }
    }

    /// An unbiased estimate of `Lr` leaving `si` towards `si.wo`, from a walk (tree, when
    /// split) in state `walk`; deposits what it learns when the guide learns.
    fn reflected(
        &self,
        si: &SurfaceInteraction,
        walk: WalkState,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
        mut deposits: Option<&mut Deposits>,
    ) -> Vec3A {
        let Some(albedo) = si.material.lambertian() else {
            return self.reflected_bsdf(si, walk, rng, scratch, deposits);
        };
        let (ctx, guide, settings) = (self.ctx, self.guide, &self.zvidpt.settings);
        let WalkState { weight, depth, branches, .. } = walk;
        // Light reaching this vertex ends a path of `depth + 2` segments.
        if albedo == Vec3A::ZERO || depth.saturating_add(2) > ctx.max_depth {
            return Vec3A::ZERO;
        }
        let frame = Frame::from_normal(si.n);
        let cell = guide.cell(si.p, si.n);
        let est = guide.estimate(cell);
        let learning = deposits.is_some();
        // What the cell aims at, looked up (caustic lobes: a voxel per vertex) only where it is
        // sampled or its share is being learned.
        let source = if learning || guide.box_share(cell) > 0.0 { guide.aim(cell, si.p, si.n) } else { None };
        let (alpha, beta) = defensive_shares(
            guide.mix(cell),
            if source.is_some() { guide.box_share(cell) } else { 0.0 },
            settings.defensive,
        );
        let tree = alpha > 0.0 || (learning && guide.has_tree(cell));
        // The source box, sampled first with probability `beta`; else the mixture of the
        // tree (`alpha`) and cosine sampling (at least `defensive` of all directions).
        let weigh = settings.mis.at(&si.material);
        // NEE weighed against the density of the directions sampled below.
        let density = |local: Vec3A, wi: Vec3A| {
            if local.z <= 0.0 {
                return 0.0;
            }
            let learned = if tree { guide.pdf(cell, local) } else { 0.0 };
            let box_pdf = match source {
                Some(b) if beta > 0.0 => b.pdf(si.p, wi),
                _ => 0.0,
            };
            beta * box_pdf + (1.0 - beta) * mixture_pdf(alpha, learned, local.z)
        };
        let direct = direct_light_against(ctx, si, &frame, frame.to_local(si.wo), weigh, rng, scratch, density);
        let mut f = self.zvidpt.continuation(albedo, walk, est);
        if f > 1.0 && (depth >= 16 || branches * (f.ceil() as u32) > MAX_BRANCHES) {
            f = 1.0;
        }
        // Stochastic rounding: n continuations with E[n] = f, each weighted 1/f.
        let u = rng.next_f32();
        let n = f.floor() as u32 + u32::from(u < f - f.floor());
        let mut indirect = Vec3A::ZERO;
        if n > 0 {
            for _ in 0..n {
                let u_pick = rng.next_f32();
                let u_dir = rng.next_2d();
                // Local directions (z = normal); the learned density from the leaf a guided
                // direction came from, or looked up otherwise.
                let (local, wi, learned) = match source {
                    Some(b) if u_pick < beta => {
                        let Some(wi) = b.sample(si.p, Vec3A::new(u_dir.x, u_dir.y, u_pick / beta)) else {
                            continue;
                        };
                        let local = frame.to_local(wi);
                        (local, wi, if tree && local.z > 0.0 { guide.pdf(cell, local) } else { 0.0 })
                    }
                    _ => {
                        let u_pick = (u_pick - beta) / (1.0 - beta);
                        let (local, learned) = if u_pick < alpha {
                            guide.sample(cell, u_dir)
                        } else {
                            let w = warp::cosine_hemisphere(u_dir);
                            (w, if tree { guide.pdf(cell, w) } else { 0.0 })
                        };
                        (local, frame.to_world(local), learned)
                    }
                };
                let cos = local.z;
                if cos <= 0.0 {
                    continue;
                }
                // Needed where the box is sampled, or for the moments that learn `beta`.
                let box_pdf = match source {
                    Some(b) if beta > 0.0 || learning => b.pdf(si.p, wi),
                    _ => 0.0,
                };
                let pdf = beta * box_pdf + (1.0 - beta) * mixture_pdf(alpha, learned, cos);
                // f·cosθ/pdf for a Lambertian surface (the cosine at its shading normal).
                let cos_s = cos * si.shading_ratio(wi, cos);
                if cos_s <= 0.0 {
                    continue;
                }
                let throughput = albedo * (cos_s * FRAC_1_PI / pdf);
                let ray = si.spawn_ray(wi);
                scratch.rays += 1;
                let mut source_point = None;
                let li = match ctx.accel.intersect(&ray) {
                    Some(hit) => {
                        let next = ctx.scene.interaction(&ray, &hit);
                        source_point = Some(next.p);
                        let seen = if weigh.surfaces { self.found_emission(si, &next, pdf) } else { Vec3A::ZERO };
                        let walk = WalkState {
                            weight: weight * throughput / f,
                            depth: depth + 1,
                            branches: branches * n,
                            prefix: false,
                            ..walk
                        };
                        seen + self.reflected(&next, walk, rng, scratch, deposits.as_deref_mut())
                    }
                    None if weigh.environment => found_environment(ctx, wi, pdf),
                    None => Vec3A::ZERO,
                };
                indirect += throughput * li;
                if let Some(d) = deposits.as_deref_mut() {
                    // The zero-variance target f·cos·Lr: Σ_channels (ρ/π·Lr)·cos / pdf.
                    let g = (albedo * li).element_sum() * cos_s * FRAC_1_PI;
                    guide.deposit_direction(d, cell, local, g / pdf);
                    let p = DirectionDensities {
                        drawn: pdf,
                        tree: learned,
                        cosine: cos * FRAC_1_PI,
                        source: source.map(|_| box_pdf),
                    };
                    guide.deposit_moments(d, cell, g, p);
                    if let Some(y) = source_point {
                        guide.deposit_source(d, cell, y, g / pdf);
                    }
                }
            }
        }
        // Roulette and splitting around the learned value (a control variate): a walk that
        // stops returns `L̃ind`, and the continuations correct it, `X = L̃ind + Σᵢ(Sᵢ − L̃ind)/f`.
        // E[X] = L̃ind + E[n]·(Lind − L̃ind)/f = Lind for any `L̃ind`, and a stopped walk costs
        // `(Lind − L̃ind)²` instead of `Lind²`: with an exact `L̃` the roulette adds no noise,
        // which is ALGORITHM.md's zero-variance termination in collision form. Only
        // walk-learned values serve: a photon density from a starved map can be orders of
        // magnitude off.
        let cv = match est {
            Some(e) if settings.control_variate && e.from_walks => e.indirect,
            _ => Vec3A::ZERO,
        };
        let indirect = cv + (indirect - cv * n as f32) / f;
        if let Some(d) = deposits {
            guide.deposit_estimates(d, cell, si.p, direct, indirect);
        }
        direct + indirect
    }

    /// [`Self::reflected`] at a surface that is not Lambertian: NEE unless the BSDF is pure
    /// delta, roulette by albedo after 3 vertices, directions from the BSDF's sampling mixed
    /// with the cell's learned density where it has one ([`sample_mixture`]), emission behind a
    /// delta lobe counted. The guide learns nothing here (its densities and estimates stand
    /// for Lambertian surfaces), and the walk's continuation carries no control variate.
    fn reflected_bsdf(
        &self,
        si: &SurfaceInteraction,
        walk: WalkState,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
        deposits: Option<&mut Deposits>,
    ) -> Vec3A {
        let (ctx, guide, settings) = (self.ctx, self.guide, &self.zvidpt.settings);
        let WalkState { weight, depth, .. } = walk;
        let albedo = si.material.albedo();
        if albedo == Vec3A::ZERO || depth.saturating_add(2) > ctx.max_depth {
            return Vec3A::ZERO;
        }
        let frame = si.bsdf_frame();
        let wi = frame.to_local(si.wo);
        let cell = guide.cell(si.p, si.n);
        let guide_frame = si.gather_frame(&frame);
        let bsdf = &si.material.bsdf;
        let guided = bsdf.is_guidable() && guide.has_tree(cell);
        let weigh = settings.mis.at(&si.material);
        let direct = if bsdf.is_delta() {
            Vec3A::ZERO
        } else {
            // NEE weighed against the density of the directions sampled below.
            let mixture = guided.then(|| Mixture::at(bsdf, wi));
            let density = |local: Vec3A, w: Vec3A| {
                let p = bsdf.pdf(wi, local);
                match mixture {
                    Some(m) => m.density(local, p, guide.pdf(cell, guide_frame.to_local(w))),
                    None => p,
                }
            };
            direct_light_against(ctx, si, &frame, wi, weigh, rng, scratch, density)
        };
        let q = if depth >= 3 { survival_probability(albedo) } else { 1.0 };
        let q = if depth >= 32 { q.min(0.8) } else { q };
        if rng.next_f32() >= q {
            return direct;
        }
        let scatter = if guided {
            sample_mixture(
                si,
                &frame,
                wi,
                &guide_frame,
                rng,
                |rng| guide.sample(cell, rng.next_2d()).0,
                |w| guide.pdf(cell, w),
            )
        } else {
            sample_bsdf(si, &frame, wi, rng)
        };
        let Some(s) = scatter else {
            return direct;
        };
        let throughput = s.weight / q;
        let ray = si.spawn_ray(s.dir);
        scratch.rays += 1;
        if walk.prefix && s.delta {
            scratch.seen_rays += 1;
        }
        let Some(hit) = ctx.accel.intersect(&ray) else {
            // The environment: all of it behind a delta lobe, else its share against NEE.
            let env = if s.delta {
                ctx.scene.lights.environment(s.dir)
            } else if weigh.environment {
                found_environment(ctx, s.dir, s.pdf)
            } else {
                Vec3A::ZERO
            };
            return direct + throughput * env;
        };
        let next = ctx.scene.interaction(&ray, &hit);
        let prefix = walk.prefix && s.delta;
        let seen = if s.delta {
            let e = next.emitted();
            if prefix {
                scratch.seen += weight * throughput * e;
            }
            if prefix && walk.split_seen { Vec3A::ZERO } else { e }
        } else if weigh.surfaces {
            self.found_emission(si, &next, s.pdf)
        } else {
            Vec3A::ZERO
        };
        let li = seen
            + self.reflected(
                &next,
                WalkState { weight: weight * throughput, depth: depth + 1, prefix, ..walk },
                rng,
                scratch,
                deposits,
            );
        direct + throughput * li
    }

    /// Emission at `next` found by a direction of density `pdf` sampled at `si`, weighed
    /// against NEE's density of the same point (power heuristic).
    #[inline]
    fn found_emission(&self, si: &SurfaceInteraction, next: &SurfaceInteraction, pdf: f32) -> Vec3A {
        let emitted = next.emitted();
        if emitted == Vec3A::ZERO {
            return emitted;
        }
        let (ctx, strategy) = (self.ctx, nee_strategy(self.ctx.light_sampling, si));
        emitted
            * power_heuristic(
                pdf,
                ctx.scene.lights.triangle_pdf(&Receiver { x: si.p, n: si.n, strategy }, next.prim, next.p),
            )
    }
}

impl Integrator for LearnedZvidpt {
    type PixelState = PixelSetup;

    fn name(&self) -> &'static str {
        match self.settings.roulette {
            Roulette::Albedo => "jensen-learned",
            _ => "zvidpt",
        }
    }

    fn prepare<A: Accel>(&mut self, ctx: &RenderContext<A>, seed: u64) -> Result<Option<String>> {
        let start = Instant::now();
        let map = PhotonMap::build(ctx.scene, ctx.accel, self.settings.photons, seed)?;
        let mut guide = LearnedGuide::seed(ctx.scene, &map, self.settings.knn)?;
        // Caustic boxes are source boxes: with `--box-mix 0` nothing aims at them.
        if self.settings.caustic_photons > 0 && self.settings.box_mix > 0.0 {
            let target = self.settings.caustic_photons;
            let caustics =
                Caustics::trace(ctx.scene, ctx.accel, target, CAUSTIC_PATHS_PER_PHOTON * target as u64, seed);
            guide.add_caustic_sources(&caustics);
        }
        guide.split_samples = self.settings.split_samples;
        guide.split_moment = self.settings.split_moment;
        guide.set_mix(self.settings.guide_mix);
        guide.learn_mix = self.settings.learn_mix;
        guide.carry = self.settings.guide_carry;
        guide.set_box_mix(self.settings.box_mix);
        guide.use_caustic_lobes(self.settings.caustic_lobes);
        let seeded = start.elapsed().as_secs_f64();
        drop(map);
        self.iterations.clear();
        // Training budget: iterations of 1, 2, 4, … spp ([`training_budget`]). Every
        // iteration of at least 2 spp goes into the image by inverse-variance weights that
        // are independent of each pixel's own values (`passes`): unbiased.
        let (planned, time_budget) = training_budget(ctx, self.settings.train_spp);
        let (width, height) = (ctx.scene.camera.width, ctx.scene.camera.height);
        let mut prior = PriorSamples::new(width, height);
        self.choice = None;
        self.path = None;
        self.split = true;
        let mut path_probe = None;
        let mut seen_stats = SeenStats::default();
        self.seen = None;
        self.rates = None;
        // Every training sample's sums per pixel, for the variances that share the render's
        // samples ([`Allocation::Error`]).
        let mut pooled = Pooled::new(self.settings.allocation == Allocation::Error, (width * height) as usize);
        let path = PathTracer { mis: self.settings.mis, ..PathTracer::default() };
        for k in 0..16u32 {
            let spp = 1u32 << k;
            if !iteration_fits(ctx, k, planned, time_budget, self.iterations.last()) {
                break;
            }
            let t = Instant::now();
            guide.begin_iteration();
            let pass = self.train_pass(ctx, &guide, seed, spp);
            guide.end_iteration(k, pass.deposits)?;
            prior.add_pass(spp, &pass.sums.sum, &pass.sums.sum_sq);
            pooled.add(spp, &pass.sums);
            seen_stats.add(spp, &pass.sums.seen, pass.sums.rays);
            self.iterations.push(Iteration { spp, seconds: t.elapsed().as_secs_f64() });
            // The first judgement, as soon as the guide has its minimum training: a walk that
            // loses clearly stops the training there. A walk that loses by less is judged
            // again after each iteration until it wins, and stops the training where it
            // gained less than MIN_GAIN on its last figure.
            if self.settings.fallback && self.training_spp() >= MIN_TRAINING_SPP {
                let last = match self.choice {
                    None => None,
                    Some(c) if c.learned > c.path => Some(c.learned),
                    Some(_) => continue,
                };
                let c = self.judge(ctx, &path, &guide, seed, &mut path_probe, EARLY_MARGIN);
                if stops_training(&c, last) {
                    self.choice = Some(Choice { fell_back: true, ..c });
                    self.path = Some(path.clone());
                    break;
                }
            }
        }
        // The choice, with the guide the final render would sample (the figures of the first
        // judgement if the guide has not changed since).
        if self.settings.fallback && self.path.is_none() {
            let c = match self.choice {
                Some(c) if c.after_spp == self.training_spp() => Some(Choice { fell_back: c.learned > c.path, ..c }),
                Some(c) if c.learned * CLEAR_WIN <= c.path => Some(c),
                _ if self.training_spp() >= MIN_TRAINING_SPP => {
                    Some(self.judge(ctx, &path, &guide, seed, &mut path_probe, 1.0))
                }
                _ => None,
            };
            self.choice = c;
            if c.is_some_and(|c| c.fell_back) {
                self.path = Some(path.clone());
            }
        }
        // Where to split the seen light: from the training's per-pixel variances of it and of
        // the rest, and the lights' projection; the walk's cost in rays per sample.
        let mut projected = Vec::new();
        let (mut seen_probe_rays, mut seen_probe_near, mut slivers) = (0u64, 0usize, 0usize);
        if self.settings.seen_strata > UNSPLIT && !seen_stats.sums.is_empty() {
            let samples = seen_stats.samples as f64 * seen_stats.sums.len() as f64;
            let cost = seen_stats.rays as f64 / samples.max(1.0);
            projected = projected_variance(ctx);
            let seconds: f64 = self.iterations.iter().map(|i| i.seconds).sum();
            let rays = if self.settings.seen_probe { render_rays(ctx, &seen_stats, seconds) } else { 0.0 };
            let probe = probe_seen(ctx, seed, width, &seen_stats, rays);
            prior.exclude(probe.sliver());
            probe.raise(&mut projected);
            (seen_probe_rays, seen_probe_near, slivers) = (probe.rays, probe.refined, probe.slivers());
            self.seen = Some(plan(width, &seen_stats, &projected, cost, self.settings.seen_strata));
        }
        // Each pixel's share of the render's samples, from the per-sample variances and rays
        // the training measured around it, as the render's samples will have them: where the
        // seen light is split (the training's samples were not), its variance falls and its
        // film points cost rays.
        self.rates = pooled.rates(width, height, |i, variance, cost| match &self.seen {
            Some(plan) => after_split(plan, &seen_stats, &projected, i, variance, cost),
            None => (variance, cost),
        });
        drop(pooled);
        // The last pass stays unweighed: the image weighs it against the final passes.
        self.prior = (!prior.is_empty()).then_some(prior);
        let stats = guide.stats();
        self.guide = Some(guide);
        let training: Vec<String> = self.iterations.iter().map(|i| format!("{}", i.spp)).collect();
        let choice = match self.choice {
            Some(c) => format!(
                "; walk probe ({PROBE_SPP} spp, variance x rays per sample) after {} training spp: learned {:.3e} (without splitting {:.3e}), path {:.3e}: {}",
                c.after_spp,
                c.learned,
                c.unsplit,
                c.path,
                if c.fell_back {
                    "path renders the rest"
                } else if c.split {
                    "learned walk kept"
                } else {
                    "learned walk kept, without splitting"
                }
            ),
            None => String::new(),
        };
        let seen = match self.seen.as_ref().map(SeenPlan::split_pixels) {
            Some((n, m)) if n > 0 => {
                format!(
                    "; seen light split over the pixel in {n} pixels (up to {m}x{m} film points; delta prefixes probed with {:.2} M rays, {seen_probe_near} pixels twice near a light, {slivers} slivers of light without the training's samples)",
                    seen_probe_rays as f64 / 1e6
                )
            }
            _ => String::new(),
        };
        Ok(Some(format!(
            "photon seed {:.3} s; guide {stats}; training {} spp ({}) in {:.2} s, {} of them in the image{choice}{seen}",
            seeded,
            self.training_spp(),
            if training.is_empty() { "none".to_string() } else { training.join("+") },
            self.iterations.iter().map(|i| i.seconds).sum::<f64>(),
            self.prior.as_ref().map_or(0, |p| p.spp)
        )))
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

    /// With the training passes' sums and their combination: 256 measured where `path`
    /// measured 114 ([`Integrator::bytes_per_pixel`]), counted with the same margin; and the
    /// training's pooled sums and the sample rates (52).
    fn bytes_per_pixel(&self) -> u64 {
        272 + 52
    }

    /// Training iteration k took samples 2^k .. 2^(k+1); the render continues the sequence.
    fn first_sample_index(&self) -> u32 {
        if self.iterations.is_empty() { 0 } else { 1 << self.iterations.len() }
    }

    fn setup_pixel<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        seed: u64,
        scratch: &mut Scratch,
    ) -> PixelSetup {
        let strata = self.seen.as_ref().map_or(UNSPLIT, |p| p.strata(pixel));
        if self.path.is_some() {
            return PixelSetup { reference: 0.0, strata };
        }
        let guide = self.guide.as_ref().expect("prepare() builds the guide");
        scratch.rays += u64::from(SETUP_RAYS);
        PixelSetup { reference: self.pixel_reference(ctx, guide, pixel, seed), strata }
    }

    fn sample<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        setup: &PixelSetup,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
    ) -> Vec3A {
        if let Some(path) = &self.path {
            return path.sample_seen_split(ctx, pixel, setup.strata, rng, scratch);
        }
        let guide = self.guide.as_ref().expect("prepare() builds the guide");
        Walker { zvidpt: self, ctx, guide }.camera_sample(pixel, setup.reference, setup.strata, rng, scratch, None)
    }
}

#[cfg(test)]
mod tests {
    use super::{Choice, MIN_GAIN, PROBE_PIXELS, defensive_shares, probe_stride, stops_training};

    #[test]
    fn training_stops_where_a_losing_walk_stalls() {
        let c = |learned: f64, fell_back: bool| Choice {
            path: 1.0,
            learned,
            unsplit: learned,
            split: false,
            after_spp: 15,
            fell_back,
        };
        // The first judgement stops only beyond its margin.
        assert!(!stops_training(&c(1.3, false), None));
        assert!(stops_training(&c(1.6, true), None));
        // Later, a losing walk must keep gaining.
        assert!(stops_training(&c(1.22, false), Some(1.226)));
        assert!(!stops_training(&c(1.2, false), Some(1.2 / (1.0 - 2.0 * MIN_GAIN))));
        // A walk that wins is never stopped for gaining little.
        assert!(!stops_training(&c(0.99, false), Some(1.0)));
    }

    /// The probe lattice: every second pixel of every second row up to 4 × PROBE_PIXELS
    /// pixels, then the densest lattice within PROBE_PIXELS.
    #[test]
    fn probe_stride_caps_the_probed_pixels() {
        assert_eq!(probe_stride(1, 1), 2);
        assert_eq!(probe_stride(160, 90), 2);
        assert_eq!(probe_stride(256, 256), 2);
        assert_eq!(probe_stride(512, 384), 4);
        assert_eq!(probe_stride(1920, 1080), 12);
        for (w, h) in [(512u32, 384u32), (1920, 1080), (4000, 7), (u32::MAX, 3)] {
            let s = probe_stride(w, h);
            let count = |s: u32| u64::from(w.div_ceil(s)) * u64::from(h.div_ceil(s));
            assert!(count(s) <= u64::from(PROBE_PIXELS) && (s == 2 || count(s - 1) > u64::from(PROBE_PIXELS)));
        }
    }

    /// Cosine sampling keeps at least `defensive` of the directions; shares only fall, and
    /// shares that already leave it that much are kept as learned.
    #[test]
    fn defensive_shares_keep_cosine_sampling() {
        let grid = [0.0f32, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99, 1.0];
        for &alpha in &grid {
            for &beta in &grid {
                assert_eq!(defensive_shares(alpha, beta, 0.0), (alpha, beta));
                for &d in &grid {
                    let (a, b) = defensive_shares(alpha, beta, d);
                    assert!((0.0..=alpha).contains(&a) && (0.0..=beta).contains(&b), "{alpha} {beta} {d}");
                    assert!((1.0 - a) * (1.0 - b) >= d - 1e-6, "{alpha} {beta} {d}: {a} {b}");
                    if (1.0 - alpha) * (1.0 - beta) >= d {
                        assert!((a - alpha).abs() < 1e-6 && (b - beta).abs() < 1e-6, "{alpha} {beta} {d}");
                    }
                }
            }
        }
    }
}
