//! The tiled scheduler: rayon over image tiles, whole passes of samples, a sample or time
//! budget, and a progress bar. Each tile owns its accumulators and per-pixel state, so the
//! sample loop takes no lock and allocates nothing.
// The library's entry points: every public item documented (`cargo doc`).
#![warn(missing_docs)]
pub mod aov;
pub mod checkpoint;
pub mod interrupt;
mod scene;

use crate::accel::Accel;
use crate::film::{Image, Partial, PixelSums, add_fixed, finish_counted, finish_pixel, rates, to_fixed};
use crate::geometry::{UVec2, Vec3A};
use crate::integrator::{Integrator, RenderContext, Scratch};
use crate::light::LightSampling;
use crate::sampler::SampleStream;
use crate::scene::Scene;
use crate::{Error, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
pub use scene::{render_scene, render_scene_with_aovs};
use std::io::IsTerminal;
use std::time::Instant;

/// Samples per pixel of a render given neither a sample count nor a time budget.
pub const DEFAULT_SPP: u32 = 64;

/// How long and how to render.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Samples per pixel; with `time_limit` too, whichever is reached first stops the render.
    pub spp: Option<u32>,
    /// Seconds; the render stops after the first whole pass that ends past it.
    pub time_limit: Option<f64>,
    /// Seed of every sample stream (the same seed gives the same pixels).
    pub seed: u64,
    /// Worker threads (`None`: one per core).
    pub threads: Option<usize>,
    /// Tile side in pixels.
    pub tile_size: u32,
    /// Show a progress bar on stderr (only when it is a terminal).
    pub progress: bool,
    /// How next event estimation picks points on emitters (every integrator).
    pub light_sampling: LightSampling,
    /// Render only final samples `a..b` of an `spp`-sample render (a part for
    /// [`Partial::merge`]); needs `spp` and no time budget.
    pub samples: Option<(u32, u32)>,
    /// Progress as one JSON line per pass on stderr (for batches whose stderr is a file).
    pub progress_json: bool,
    /// Keep a checkpoint (and continue an earlier run's).
    pub checkpoint: Option<checkpoint::CheckpointSettings>,
    /// Stop once the image's estimated relative error is this low ([`NoiseTarget`]); with
    /// `spp` or `time_limit` too, whichever comes first stops the render.
    pub noise_target: Option<NoiseTarget>,
}

/// Rendering to a noise target: after every pass (once `min_spp` samples per pixel are in),
/// the render stops when [`relative_error`] of the image is at most `error`; or, `per_pixel`,
/// each pixel stops taking samples once the error its neighbourhood estimates for it is at
/// most `error` ([`local_errors`]), and the render when every pixel has stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseTarget {
    /// The relative error to reach (0.05: 5%).
    pub error: f64,
    /// Samples per pixel before the error is first judged.
    pub min_spp: u32,
    /// Converged pixels stop receiving samples (adaptive sampling).
    pub per_pixel: bool,
}

/// Fixed-point scale of each pixel's share of the image error (see [`relative_error`]).
const ERROR_SCALE: f64 = (1u64 << 40) as f64;

/// The image's estimated relative error after `spp` samples per pixel: the root of the mean
/// over pixels and channels of `σ²/(n·(μ² + 0.01))` (σ² the pixel's per-sample variance, μ its
/// mean, n its samples): the relMSE `zvidpt diff` measures against a reference, predicted
/// from the samples themselves. `sums` yields each pixel's exact sums and sample count.
/// Summed in fixed point, so the value is the same bits whatever order the pixels come in.
pub fn relative_error<'a>(sums: impl Iterator<Item = (&'a [i128; 3], &'a [i128; 3], u32)>) -> f64 {
    let (mut total, mut count) = (0u128, 0u64);
    for (s, q, spp) in sums {
        total = total.saturating_add(error_share(s, q, spp));
        count += 3;
    }
    ((total as f64 / ERROR_SCALE) / count.max(1) as f64).sqrt()
}

/// A pixel's share of the squared relative error, summed over its channels, in fixed point
/// ([`relative_error`]).
fn error_share(s: &[i128; 3], q: &[i128; 3], spp: u32) -> u128 {
    relative_in_fixed_point(s, q, spp, f64::from(spp.max(1)))
}

/// A pixel's relative per-sample variance, summed over its channels, in fixed point:
/// `Σ σ²/(μ² + 0.01)` (its [`error_share`] times its samples).
fn relative_variance(s: &[i128; 3], q: &[i128; 3], spp: u32) -> u128 {
    relative_in_fixed_point(s, q, spp, 1.0)
}

/// `Σ σ²/(per · (μ² + 0.01))` over the channels of a pixel of `spp` samples, in fixed point.
fn relative_in_fixed_point(s: &[i128; 3], q: &[i128; 3], spp: u32, per: f64) -> u128 {
    let (mean, var) = finish_pixel(s, q, spp);
    let mut total = 0u128;
    for c in 0..3 {
        let (m, v) = (f64::from(mean[c]), f64::from(var[c]));
        let share = v / (per * (m * m + 0.01));
        // Non-finite or absurd shares count as the largest representable.
        total = total.saturating_add(if share.is_finite() {
            (share.min(1e12) * ERROR_SCALE) as u128
        } else {
            u128::MAX >> 8
        });
    }
    total
}

/// Each pixel's estimated relative error for adaptive sampling: the relative per-sample
/// variance of its 3 × 3 neighbourhood *other than itself* (`relative`, row-major, from
/// `relative_variance`), averaged, over the pixel's own sample count (`counts`). A pixel's
/// own samples never decide when it stops, so stopping does not favour the pixels whose
/// samples happened to agree (a pixel that has not yet met a rare bright path would look
/// converged to itself): its stopping time is independent of its own samples given its
/// neighbours', which keeps its mean unbiased. (The bias left, through the neighbours'
/// counts, which their own neighbourhoods, this pixel included, decide, is measured in
/// `tests/adaptive.rs`.) Its own count is what makes the estimate fall as it takes samples,
/// so a pixel never waits on neighbours that have stopped.
#[must_use]
pub fn local_errors(relative: &[u128], counts: &[u32], width: u32, height: u32) -> Vec<f64> {
    let (w, h) = (width as i64, height as i64);
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (mut total, mut count) = (0u128, 0u64);
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let (nx, ny) = (x + dx, y + dy);
                    if (dx, dy) == (0, 0) || nx < 0 || ny < 0 || nx >= w || ny >= h {
                        continue;
                    }
                    total = total.saturating_add(relative[(ny * w + nx) as usize]);
                    count += 3;
                }
            }
            let n = f64::from(counts[(y * w + x) as usize].max(1));
            if count == 0 { f64::INFINITY } else { ((total as f64 / ERROR_SCALE) / (count as f64 * n)).sqrt() }
        })
        .collect()
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            spp: Some(16),
            time_limit: None,
            seed: 0,
            threads: None,
            tile_size: 32,
            progress: false,
            light_sampling: LightSampling::default(),
            samples: None,
            progress_json: false,
            checkpoint: None,
            noise_target: None,
        }
    }
}

/// What a render measured.
#[derive(Clone, Debug)]
pub struct RenderStats {
    /// Samples per pixel rendered (including any resumed).
    pub spp: u32,
    /// Wall-clock seconds of the whole render: pre-pass, pixel set-up and sampling.
    pub seconds: f64,
    /// Seconds of the pre-pass alone (the photon map), included in `seconds`.
    pub prepass_seconds: f64,
    /// Camera samples taken.
    pub samples: u64,
    /// Rays traced.
    pub rays: u64,
    /// Worker threads used.
    pub threads: usize,
    /// What the pre-pass built, if the integrator has one.
    pub prepass: Option<String>,
    /// Samples dropped for being NaN or infinite (0 for a correct integrator).
    pub non_finite: u64,
    /// Samples per pixel the pre-pass took and the image includes (training samples of a
    /// learning integrator), beyond `spp`.
    pub prior_spp: u32,
    /// A render of a sample range (`RenderSettings::samples`): its exact sums, to merge.
    pub partial: Option<std::sync::Arc<Partial>>,
    /// Samples per pixel taken from a checkpoint (included in `spp`, not in `samples`).
    pub resumed_spp: u32,
    /// Seconds the earlier runs of a resumed render took (not in `seconds`).
    pub resumed_seconds: f64,
    /// Checkpoints written during the render, and the seconds they took (in `seconds`).
    pub checkpoints: u32,
    /// Seconds the checkpoints took.
    pub checkpoint_seconds: f64,
    /// Seconds the ray-tracing backend took to build its acceleration structure (set by the
    /// caller that built it; not in `seconds`).
    pub build_seconds: f64,
    /// With a noise target: the image's estimated relative error when the render stopped
    /// ([`relative_error`], final samples only), and whether that met the target.
    pub noise: Option<(f64, bool)>,
    /// With adaptive sampling: the fewest, mean and most final samples a pixel took.
    pub pixel_spp: Option<(u32, f64, u32)>,
    /// With adaptive sampling: each pixel's final samples (row-major; `prior_spp` more are in
    /// the image).
    pub pixel_counts: Option<Vec<u32>>,
}

impl RenderStats {
    #[must_use]
    /// Samples per second of sampling (pre-pass excluded).
    pub fn samples_per_second(&self) -> f64 {
        self.samples as f64 / (self.seconds - self.prepass_seconds).max(1e-9)
    }

    /// Seconds over every run of a resumed render.
    #[must_use]
    pub fn total_seconds(&self) -> f64 {
        self.seconds + self.resumed_seconds
    }

    /// Rays per second of sampling (pre-pass excluded).
    #[must_use]
    pub fn rays_per_second(&self) -> f64 {
        self.rays as f64 / (self.seconds - self.prepass_seconds).max(1e-9)
    }
}

struct Tile<S> {
    origin: UVec2,
    size: UVec2,
    sum: Vec<[i128; 3]>,
    sum_sq: Vec<[i128; 3]>,
    /// Samples each pixel has taken (from the render's first sample).
    count: Vec<u32>,
    /// Whether each pixel takes samples in the next pass (adaptive sampling stops some).
    active: Vec<bool>,
    /// Each pixel's sample rate ([`rates`]; empty: one sample per pixel per sample of the
    /// render).
    rate: Vec<f32>,
    state: Vec<S>,
    scratch: Scratch,
}

impl<S: Send + Sync> Tile<S> {
    /// (index in the tile, pixel) of every pixel; borrows nothing, so the tile's sums can be
    /// written while iterating.
    fn pixels(&self) -> impl Iterator<Item = (usize, UVec2)> + use<S> {
        let (origin, size) = (self.origin, self.size);
        (0..size.y).flat_map(move |y| (0..size.x).map(move |x| ((y * size.x + x) as usize, origin + UVec2::new(x, y))))
    }

    fn run_pass<A: Accel, I: Integrator<PixelState = S>>(
        &mut self,
        ctx: &RenderContext<A>,
        integrator: &I,
        seed: u64,
        width: u32,
        // The pixels' next sample index without rates; the render's first sample index and
        // its samples per pixel done so far, for rates.
        (first, offset, done): (u32, u32, u32),
        count: u32,
    ) {
        let mut scratch = std::mem::take(&mut self.scratch);
        for y in 0..self.size.y {
            for x in 0..self.size.x {
                let i = (y * self.size.x + x) as usize;
                if !self.active[i] {
                    continue;
                }
                let pixel = self.origin + UVec2::new(x, y);
                let (start, count) = match self.rate.get(i) {
                    // With rates, the render's samples `done..done + count` are the pixel's
                    // `⌊done·r⌋..⌊(done + count)·r⌋` (the caller keeps them within u32).
                    Some(&r) => {
                        let (a, b) = (rates::taken(done, r), rates::taken(done + count, r));
                        (offset + a as u32, (b - a) as u32)
                    }
                    // Pixel samples are numbered on from the ones it took.
                    None => (first + self.count[i], count),
                };
                if count == 0 {
                    continue;
                }
                self.count[i] += count;
                let job =
                    PixelJob { ctx, integrator, pixel, state: &self.state[i], seed, index: pixel.y * width + pixel.x };
                let (sum, sum_sq) = if count >= 2 * SAMPLE_CHUNK {
                    // Many samples of one pixel (the last pixels of an adaptive render, or
                    // large passes): chunks of them are open to idle threads. The sums are
                    // fixed point, so their order leaves the bits as they are.
                    let chunks = count.div_ceil(SAMPLE_CHUNK);
                    let (sum, sum_sq, rays, non_finite) = (0..chunks)
                        .into_par_iter()
                        .map(|k| {
                            let mut own = Scratch::default();
                            let from = start + k * SAMPLE_CHUNK;
                            let (s, q) = job.samples(from..(from + SAMPLE_CHUNK).min(start + count), &mut own);
                            (s, q, own.rays, own.non_finite)
                        })
                        .reduce(
                            || ([0; 3], [0; 3], 0, 0),
                            |a, b| (add_fixed(a.0, b.0), add_fixed(a.1, b.1), a.2 + b.2, a.3 + b.3),
                        );
                    scratch.rays += rays;
                    scratch.non_finite += non_finite;
                    (sum, sum_sq)
                } else {
                    job.samples(start..start + count, &mut scratch)
                };
                self.sum[i] = add_fixed(self.sum[i], sum);
                self.sum_sq[i] = add_fixed(self.sum_sq[i], sum_sq);
            }
        }
        self.scratch = scratch;
    }
}

/// Samples of one pixel in a pass at most this many to a task: a pass larger than two of them
/// is split among the threads (about 0.1 ms of sampling each, well above rayon's cost of a task).
const SAMPLE_CHUNK: u32 = 64;

/// What one pixel's samples need: the integrator, its state for the pixel and the pixel's place
/// in the sample streams.
struct PixelJob<'a, A: Accel, I: Integrator> {
    ctx: &'a RenderContext<'a, A>,
    integrator: &'a I,
    pixel: UVec2,
    state: &'a I::PixelState,
    seed: u64,
    index: u32,
}

impl<A: Accel, I: Integrator> PixelJob<'_, A, I> {
    /// The fixed-point sums (and sums of squares) of the samples numbered `range`.
    #[inline]
    fn samples(&self, range: std::ops::Range<u32>, scratch: &mut Scratch) -> ([i128; 3], [i128; 3]) {
        let (mut sum, mut sum_sq) = ([0i128; 3], [0i128; 3]);
        for s in range {
            let mut rng = SampleStream::new(self.seed, self.index, s);
            let v = self.integrator.sample(self.ctx, self.pixel, self.state, &mut rng, scratch);
            // (A sample may be negative: `zvidpt`'s roulette around a control variate is
            // unbiased with signed samples.)
            debug_assert!(v.is_finite(), "sample {v} at {}", self.pixel);
            // Never silently: a non-finite sample is counted and reported.
            let v = if v.is_finite() {
                v
            } else {
                scratch.non_finite += 1;
                Vec3A::ZERO
            };
            for c in 0..3 {
                let x = f64::from(v[c]);
                sum[c] = sum[c].saturating_add(to_fixed(x));
                sum_sq[c] = sum_sq[c].saturating_add(to_fixed(x * x));
            }
        }
        (sum, sum_sq)
    }
}

/// Refuses a `width × height` render of `per_pixel` bytes a pixel that needs more memory than
/// `available`, with one line, before its buffers are allocated (an allocation that fails
/// aborts the process).
fn check_memory(width: u32, height: u32, per_pixel: u64, available: Option<u64>) -> Result<()> {
    let need = u64::from(width) * u64::from(height) * per_pixel;
    match available {
        Some(free) if need > free => Err(Error::InvalidOption(format!(
            "a {width}x{height} render needs about {} of memory and {} is available: render it smaller (--resolution)",
            crate::io::human_bytes(need),
            crate::io::human_bytes(free)
        ))),
        _ => Ok(()),
    }
}

/// Renders `scene` with `integrator` over `accel`: the integrator's pre-pass, then passes of
/// samples. A time budget counts the pre-pass, so equal-time comparisons are fair.
pub fn render<A: Accel, I: Integrator>(
    scene: &Scene,
    accel: &A,
    integrator: &mut I,
    settings: &RenderSettings,
) -> Result<(Image, RenderStats)> {
    if settings.spp == Some(0) {
        return Err(Error::InvalidOption("spp must be at least 1".into()));
    }
    check_memory(scene.camera.width, scene.camera.height, integrator.bytes_per_pixel(), crate::io::memory_available())?;
    if settings.spp.is_none() && settings.time_limit.is_none() && settings.noise_target.is_none() {
        return Err(Error::InvalidOption(
            "give a sample count (--spp), a time budget (--time) or a noise target (--noise-target)".into(),
        ));
    }
    if let Some(t) = settings.noise_target {
        if !(t.error.is_finite() && t.error > 0.0) {
            return Err(Error::InvalidOption(format!(
                "noise target must be a positive relative error, got {}",
                t.error
            )));
        }
        if settings.samples.is_some() {
            return Err(Error::InvalidOption(
                "a part (--samples) cannot stop at a noise target: the parts of a render would stop at different counts; render it whole".into(),
            ));
        }
    }
    if let Some(t) = settings.time_limit
        && !(t.is_finite() && t > 0.0)
    {
        return Err(Error::InvalidOption(format!("time budget must be a positive number of seconds, got {t}")));
    }
    if settings.tile_size == 0 {
        return Err(Error::InvalidOption("tile size must be at least 1".into()));
    }
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = settings.threads {
        if n == 0 {
            return Err(Error::InvalidOption("threads must be at least 1".into()));
        }
        // Thousands of threads on a few cores only slow the render down (each owns tiles and
        // a stack): at most 8 per core.
        let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
        if n > 8 * cores {
            return Err(Error::InvalidOption(format!(
                "{n} threads: at most {} on this machine (8 per core; more only slows the render)",
                8 * cores
            )));
        }
        builder = builder.num_threads(n);
    }
    let pool = builder.build().map_err(|e| Error::InvalidOption(format!("cannot start worker threads: {e}")))?;
    let threads = pool.current_num_threads();
    pool.install(|| render_in_pool(scene, accel, integrator, settings, threads))
}

fn render_in_pool<A: Accel, I: Integrator>(
    scene: &Scene,
    accel: &A,
    integrator: &mut I,
    settings: &RenderSettings,
    threads: usize,
) -> Result<(Image, RenderStats)> {
    let (width, height) = (scene.camera.width, scene.camera.height);
    let start = Instant::now();
    let resume = settings.checkpoint.as_ref().and_then(|c| c.resume.as_ref());
    let resumed_seconds = resume.map_or(0.0, |r| r.seconds);
    // A resumed time budget continues with what is left of it.
    let time_limit = settings.time_limit.map(|t| t - resumed_seconds);
    let ctx = RenderContext {
        scene,
        accel,
        light_sampling: settings.light_sampling,
        start,
        time_limit,
        spp: settings.spp,
        training_iterations: resume.and_then(|r| r.training_iterations),
        lambertian_only: scene.lambertian_only(),
        volumetric: scene.volumetric(),
        max_depth: scene.render.max_depth.unwrap_or(u32::MAX),
    };
    let marked = settings.checkpoint.as_ref().map(|_| interrupt::Prepass::new());
    if settings.progress_json {
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), "{}", serde_json::json!({ "event": "prepass" }));
    }
    let prepass = integrator.prepare(&ctx, settings.seed)?;
    drop(marked);
    let prepass_seconds = start.elapsed().as_secs_f64();
    let integrator: &I = integrator;
    let per_pixel = settings.noise_target.is_some_and(|t| t.per_pixel);
    // Sample rates per pixel, where the integrator measured them (adaptive sampling decides
    // its own counts instead).
    let rates = integrator.pixel_rates().filter(|_| !per_pixel);
    if rates.is_some_and(|r| {
        r.len() != (width * height) as usize || r.iter().any(|&x| !(x > 0.0 && x <= rates::MAX_PIXEL_RATE))
    }) {
        return Err(Error::InvalidOption("pre-pass sample rates do not match the image".into()));
    }
    let ts = settings.tile_size;
    let mut tiles: Vec<Tile<I::PixelState>> = Vec::new();
    for ty in (0..height).step_by(ts as usize) {
        for tx in (0..width).step_by(ts as usize) {
            let size = UVec2::new(ts.min(width - tx), ts.min(height - ty));
            let n = (size.x * size.y) as usize;
            let rate = rates.map_or_else(Vec::new, |r| {
                (0..size.y).flat_map(|y| (0..size.x).map(move |x| r[((ty + y) * width + tx + x) as usize])).collect()
            });
            tiles.push(Tile {
                origin: UVec2::new(tx, ty),
                size,
                sum: vec![[0; 3]; n],
                sum_sq: vec![[0; 3]; n],
                count: vec![0; n],
                active: vec![true; n],
                rate,
                state: Vec::new(),
                scratch: Scratch::default(),
            });
        }
    }
    let prior = integrator.prior_samples().filter(|p| !p.is_empty());
    if prior.is_some_and(|p| p.len() != (width * height) as usize) {
        return Err(Error::InvalidOption("pre-pass samples do not match the image size".into()));
    }
    let prior_spp = prior.map_or(0, |p| p.spp);
    let offset = integrator.first_sample_index();
    if settings.spp.is_some_and(|n| n.checked_add(offset).is_none()) {
        return Err(Error::InvalidOption(format!("spp must be at most {} here", u32::MAX - offset)));
    }
    let (first, last) = match settings.samples {
        None => (0, settings.spp),
        Some((a, b)) => {
            if settings.time_limit.is_some() || settings.spp.is_none_or(|n| !(a < b && b <= n)) {
                return Err(Error::InvalidOption(format!(
                    "samples {a}..{b}: a part of an spp-sample render needs 0 <= a < b <= spp and no time budget"
                )));
            }
            (a, Some(b))
        }
    };
    let total_spp = settings.spp.unwrap_or(u32::MAX);
    let mut done = first;
    if let (Some(r), Some(c)) = (resume, &settings.checkpoint) {
        checkpoint::check_fits(r, &c.path, (width, height), first, total_spp, prior)?;
        if last.is_some_and(|n| first + r.part.sums.spp > n) {
            return Err(Error::InvalidOption(format!("{}: the checkpoint holds more samples", c.path.display())));
        }
        let sums = &r.part.sums;
        if !sums.counts.is_empty() && !per_pixel && rates.is_none() {
            return Err(Error::InvalidOption(format!(
                "{}: the checkpoint has per-pixel sample counts (adaptive sampling); resume it with --adaptive",
                c.path.display()
            )));
        }
        tiles.par_iter_mut().for_each(|tile| {
            for (i, p) in tile.pixels() {
                let j = (p.y * width + p.x) as usize;
                (tile.sum[i], tile.sum_sq[i]) = (sums.sum[j], sums.sum_sq[j]);
                tile.count[i] = sums.count(j);
            }
        });
        done += sums.spp;
    }
    let resumed_spp = done - first;
    // Pixels keep their own counts: adaptive sampling's, or the rates'.
    let counted = per_pixel || rates.is_some();
    let taken = |tiles: &[Tile<I::PixelState>]| tiles.iter().flat_map(|t| &t.count).map(|&c| u64::from(c)).sum::<u64>();
    let resumed_samples = taken(&tiles);
    let bar = progress_bar(settings);
    bar.set_position(u64::from(resumed_spp));
    tiles.par_iter_mut().for_each(|tile| {
        let mut scratch = Scratch::default();
        tile.state = tile.pixels().map(|(_, p)| integrator.setup_pixel(&ctx, p, settings.seed, &mut scratch)).collect();
        tile.scratch = scratch;
    });
    // While sampling, a signal is answered by a checkpoint (see `interrupt`).
    let _watch = settings.checkpoint.as_ref().map(|_| interrupt::Watch::new());
    let mut last_checkpoint = Instant::now();
    // Checkpoints written on the way, and their seconds.
    let mut checkpoints = (0u32, 0.0f64);
    // Seconds of this run that count against a time budget: a resumed render's rebuilt
    // pre-pass was paid for in its first run.
    let budget_seconds = || start.elapsed().as_secs_f64() - if resume.is_some() { prepass_seconds } else { 0.0 };
    let save = |tiles: &[Tile<I::PixelState>], done: u32| -> Result<()> {
        let Some(c) = &settings.checkpoint else { return Ok(()) };
        let progress = checkpoint::Progress {
            first,
            done,
            total_spp,
            seconds: resumed_seconds + budget_seconds(),
            training_iterations: integrator.training_iterations(),
        };
        let counts = counted.then(|| row_major(tiles, width, height, |t, i| t.count[i]));
        checkpoint::write(
            c,
            (width, height),
            &progress,
            |j| row_major_at(tiles, width, ts, j, |t, i| (t.sum[i], t.sum_sq[i])),
            prior,
            counts.as_deref(),
        )
    };
    // Whole passes. A pass is one sample per pixel under a time budget (so the budget is
    // overshot by at most one pass) and a few samples otherwise (fewer, larger tasks).
    loop {
        if settings.checkpoint.is_some()
            && let Some(signal) = interrupt::requested()
        {
            bar.finish_and_clear();
            let kept = if done > first {
                save(&tiles, done)?;
                format!(
                    "interrupted: {} samples per pixel kept in {} (`--resume` continues)",
                    done - first,
                    settings.checkpoint.as_ref().map_or(String::new(), |c| c.path.display().to_string())
                )
            } else {
                "interrupted before the first pass: nothing to keep".to_string()
            };
            return Err(Error::Interrupted { signal, message: kept });
        }
        let elapsed = budget_seconds();
        if last.is_some_and(|n| done >= n) || (done > 0 && time_limit.is_some_and(|t| elapsed >= t)) {
            break;
        }
        if let Some(target) = settings.noise_target
            && done - first >= target.min_spp.max(2)
        {
            if target.per_pixel {
                // Each pixel from its neighbours' error; the render ends when none is left.
                let (relative, counts): (Vec<u128>, Vec<u32>) = row_major(&tiles, width, height, |t, i| {
                    (relative_variance(&t.sum[i], &t.sum_sq[i], t.count[i]), t.count[i])
                })
                .into_iter()
                .unzip();
                let errors = local_errors(&relative, &counts, width, height);
                let min_spp = target.min_spp.max(2);
                tiles.par_iter_mut().for_each(|tile| {
                    for (i, p) in tile.pixels() {
                        let e = errors[(p.y * width + p.x) as usize];
                        tile.active[i] = tile.count[i] < min_spp || e > target.error;
                    }
                });
                if !tiles.iter().any(|t| t.active.iter().any(|&a| a)) {
                    break;
                }
            } else if relative_error(
                tiles.iter().flat_map(|t| t.pixels().map(|(i, _)| (&t.sum[i], &t.sum_sq[i], t.count[i]))),
            ) <= target.error
            {
                break;
            }
        }
        let remaining = last.map_or(u32::MAX, |n| n - done);
        let mut pass = if settings.time_limit.is_some() { 1 } else { remaining.min(4) };
        if per_pixel {
            // With few pixels left, a pass of the usual size is mostly the judging around it
            // (and one thread): the pixels left take up to a full image's pass of samples at
            // once, never more than a sixteenth of the samples taken (so none overshoots its
            // stop by more than about 6%).
            let active = tiles.iter().map(|t| t.active.iter().filter(|&&a| a).count()).sum::<usize>().max(1);
            let share = (pass as usize * (width * height) as usize / active).min(u32::MAX as usize) as u32;
            pass = pass.max(share.min((done - first) / 16)).min(remaining);
        }
        // Sample indices stay within u32 (a pixel's rate at most MAX_PIXEL_RATE).
        let most = if rates.is_some() {
            (f64::from(done) + f64::from(pass)) * f64::from(rates::MAX_PIXEL_RATE) + f64::from(offset)
        } else {
            f64::from(done) + f64::from(pass) + f64::from(offset)
        };
        if most > f64::from(u32::MAX) {
            break;
        }
        tiles.par_iter_mut().for_each(|tile| {
            tile.run_pass(&ctx, integrator, settings.seed, width, (offset + first, offset, done), pass);
        });
        done += pass;
        match (settings.spp, settings.time_limit) {
            (Some(_), None) => bar.set_position(u64::from(done - first)),
            (_, Some(t)) => bar.set_position((((resumed_seconds + budget_seconds()) / t) * 1000.0).min(1000.0) as u64),
            _ => {}
        }
        if settings.progress_json {
            use std::io::Write as _;
            let line = serde_json::json!({
                "event": "pass",
                "samples_done": done - first,
                "samples": last.map(|n| n - first),
                "seconds": start.elapsed().as_secs_f64(),
            });
            let _ = writeln!(std::io::stderr().lock(), "{line}");
        }
        let finished = last.is_some_and(|n| done >= n);
        if let Some(c) = &settings.checkpoint
            && !finished
            && last_checkpoint.elapsed().as_secs_f64() >= c.interval
        {
            let t = Instant::now();
            save(&tiles, done)?;
            checkpoints.0 += 1;
            checkpoints.1 += t.elapsed().as_secs_f64();
            last_checkpoint = Instant::now();
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let noise = settings.noise_target.map(|target| {
        let e =
            relative_error(tiles.iter().flat_map(|t| t.pixels().map(|(i, _)| (&t.sum[i], &t.sum_sq[i], t.count[i]))));
        (e, e <= target.error)
    });
    let samples = taken(&tiles) - resumed_samples;
    let counts = counted.then(|| row_major(&tiles, width, height, |t, i| t.count[i]));

    let (mut rays, mut non_finite) = (0, 0);
    for tile in &tiles {
        rays += tile.scratch.rays;
        non_finite += tile.scratch.non_finite;
    }
    // With adaptive sampling, the most samples any pixel took (a pixel may stop, take up
    // again when its neighbours' variance grows, and end below the passes run).
    // With rates, the render's count (pixels took about rate × it).
    let spp = match &counts {
        Some(c) if per_pixel => c.iter().copied().max().unwrap_or(0),
        _ => done - first,
    };
    let (pixels, variance, partial) = if prior.is_some() || settings.samples.is_some() {
        // The whole image's exact sums, row-major: training passes are combined over the
        // whole image, and a part keeps its sums.
        let mut sums = PixelSums {
            width,
            height,
            spp,
            sum: vec![[0; 3]; (width * height) as usize],
            sum_sq: vec![[0; 3]; (width * height) as usize],
            counts: counts.clone().unwrap_or_default(),
        };
        for tile in tiles.drain(..) {
            for (i, p) in tile.pixels() {
                let j = (p.y * width + p.x) as usize;
                sums.sum[j] = tile.sum[i];
                sums.sum_sq[j] = tile.sum_sq[i];
            }
        }
        let (pixels, variance) = sums.finish(prior);
        let partial = settings.samples.map(|_| {
            std::sync::Arc::new(Partial { first, sums, prior: prior.cloned(), total_spp: settings.spp.unwrap_or(0) })
        });
        (pixels, variance, partial)
    } else {
        // Straight from the tiles (no second copy of the sums).
        let mut pixels = vec![[0.0f32; 3]; (width * height) as usize];
        let mut variance = vec![[0.0f32; 3]; pixels.len()];
        for tile in tiles.drain(..) {
            for (i, p) in tile.pixels() {
                let j = (p.y * width + p.x) as usize;
                (pixels[j], variance[j]) = finish_counted(&tile.sum[i], &tile.sum_sq[i], tile.count[i], spp);
            }
        }
        (pixels, variance, None)
    };
    let stats = RenderStats {
        spp,
        seconds,
        prepass_seconds,
        samples,
        resumed_spp,
        resumed_seconds,
        checkpoints: checkpoints.0,
        checkpoint_seconds: checkpoints.1,
        build_seconds: 0.0,
        rays,
        threads,
        prepass,
        non_finite,
        prior_spp,
        partial,
        noise,
        pixel_spp: counts.as_ref().map(|c| {
            let (lo, hi) = c.iter().fold((u32::MAX, 0), |(lo, hi), &n| (lo.min(n), hi.max(n)));
            (lo, c.iter().map(|&n| f64::from(n)).sum::<f64>() / c.len().max(1) as f64, hi)
        }),
        pixel_counts: counts,
    };
    Ok((Image { width, height, pixels, variance: Some(variance), spp: spp + prior_spp }, stats))
}

/// `value(tile, index in tile)` of every pixel, row-major (computed tile by tile in parallel).
fn row_major<S: Send + Sync, T: Default + Clone + Send>(
    tiles: &[Tile<S>],
    width: u32,
    height: u32,
    value: impl Fn(&Tile<S>, usize) -> T + Sync,
) -> Vec<T> {
    let per_tile: Vec<Vec<T>> = tiles.par_iter().map(|t| t.pixels().map(|(i, _)| value(t, i)).collect()).collect();
    let mut out = vec![T::default(); width as usize * height as usize];
    for (tile, values) in tiles.iter().zip(per_tile) {
        for ((_, p), v) in tile.pixels().zip(values) {
            out[(p.y * width + p.x) as usize] = v;
        }
    }
    out
}

/// `value(tile, index in tile)` of pixel `j` (row-major) of tiles `ts` pixels wide.
fn row_major_at<S, T>(tiles: &[Tile<S>], width: u32, ts: u32, j: usize, value: impl Fn(&Tile<S>, usize) -> T) -> T {
    let tiles_x = width.div_ceil(ts) as usize;
    let (x, y) = (j as u32 % width, j as u32 / width);
    let tile = &tiles[(y / ts) as usize * tiles_x + (x / ts) as usize];
    value(tile, ((y - tile.origin.y) * tile.size.x + (x - tile.origin.x)) as usize)
}

fn progress_bar(settings: &RenderSettings) -> ProgressBar {
    if !settings.progress || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let (len, template) = match (settings.spp, settings.time_limit) {
        (Some(n), None) => (n as u64, "{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} spp (eta {eta})"),
        _ => (1000, "{spinner} [{elapsed_precise}] {wide_bar} time budget {percent}%"),
    };
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style);
    }
    bar
}

#[cfg(test)]
mod tests {
    use super::check_memory;

    /// A render larger than the memory left is refused before its buffers exist; unknown
    /// memory refuses nothing.
    #[test]
    fn renders_that_cannot_fit_are_refused() {
        assert!(check_memory(8000, 8000, 128, Some(600 << 20)).unwrap_err().to_string().contains("8000x8000"));
        assert!(check_memory(512, 384, 272, Some(600 << 20)).is_ok());
        assert!(check_memory(8000, 8000, 128, None).is_ok());
    }
}
