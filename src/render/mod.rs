//! The tiled scheduler: rayon over image tiles, whole passes of samples, a sample or time
//! budget, and a progress bar. Each tile owns its accumulators and per-pixel state, so the
//! sample loop takes no lock and allocates nothing.
use crate::accel::Accel;
use crate::film::Image;
use crate::geometry::{UVec2, Vec3A};
use crate::integrator::passes::mean_and_variance;
use crate::integrator::{Integrator, RenderContext, Scratch};
use crate::sampler::SampleStream;
use crate::scene::{LightSampling, Scene};
use crate::{Error, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::io::IsTerminal;
use std::time::Instant;

/// How long and how to render.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Samples per pixel; with `time_limit` too, whichever is reached first stops the render.
    pub spp: Option<u32>,
    /// Seconds; the render stops after the first whole pass that ends past it.
    pub time_limit: Option<f64>,
    pub seed: u64,
    /// Worker threads (`None`: one per core).
    pub threads: Option<usize>,
    /// Tile side in pixels.
    pub tile_size: u32,
    /// Show a progress bar on stderr (only when it is a terminal).
    pub progress: bool,
    /// How next event estimation picks points on emitters (every integrator).
    pub light_sampling: LightSampling,
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
        }
    }
}

/// What a render measured.
#[derive(Clone, Debug)]
pub struct RenderStats {
    pub spp: u32,
    /// Wall-clock seconds of the whole render: pre-pass, pixel set-up and sampling.
    pub seconds: f64,
    /// Seconds of the pre-pass alone (the photon map), included in `seconds`.
    pub prepass_seconds: f64,
    pub samples: u64,
    pub rays: u64,
    pub threads: usize,
    /// What the pre-pass built, if the integrator has one.
    pub prepass: Option<String>,
    /// Samples dropped for being NaN or infinite (0 for a correct integrator).
    pub non_finite: u64,
    /// Samples per pixel the pre-pass took and the image includes (training samples of a
    /// learning integrator), beyond `spp`.
    pub prior_spp: u32,
}

impl RenderStats {
    #[must_use]
    /// Samples per second of sampling (pre-pass excluded).
    pub fn samples_per_second(&self) -> f64 {
        self.samples as f64 / (self.seconds - self.prepass_seconds).max(1e-9)
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
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    state: Vec<S>,
    scratch: Scratch,
}

impl<S: Send + Sync> Tile<S> {
    fn pixels(&self) -> impl Iterator<Item = (usize, UVec2)> + '_ {
        (0..self.size.y).flat_map(move |y| {
            (0..self.size.x).map(move |x| ((y * self.size.x + x) as usize, self.origin + UVec2::new(x, y)))
        })
    }

    fn run_pass<A: Accel, I: Integrator<PixelState = S>>(
        &mut self,
        ctx: &RenderContext<A>,
        integrator: &I,
        seed: u64,
        width: u32,
        first: u32,
        count: u32,
    ) {
        let mut scratch = std::mem::take(&mut self.scratch);
        for y in 0..self.size.y {
            for x in 0..self.size.x {
                let i = (y * self.size.x + x) as usize;
                let pixel = self.origin + UVec2::new(x, y);
                let index = pixel.y * width + pixel.x;
                let (mut sum, mut sum_sq) = (self.sum[i], self.sum_sq[i]);
                for s in first..first + count {
                    let mut rng = SampleStream::new(seed, index, s);
                    let v = integrator.sample(ctx, pixel, &self.state[i], &mut rng, &mut scratch);
                    // (A sample may be negative: `zvidpt`'s roulette around a control variate
                    // is unbiased with signed samples.)
                    debug_assert!(v.is_finite(), "sample {v} at {pixel}");
                    // Never silently: a non-finite sample is counted and reported.
                    let v = if v.is_finite() {
                        v
                    } else {
                        scratch.non_finite += 1;
                        Vec3A::ZERO
                    };
                    for c in 0..3 {
                        let x = v[c] as f64;
                        sum[c] += x;
                        sum_sq[c] += x * x;
                    }
                }
                self.sum[i] = sum;
                self.sum_sq[i] = sum_sq;
            }
        }
        self.scratch = scratch;
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
    if settings.spp.is_none() && settings.time_limit.is_none() {
        return Err(Error::InvalidOption("give a sample count (--spp) or a time budget (--time)".into()));
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
    let ctx = RenderContext {
        scene,
        accel,
        light_sampling: settings.light_sampling,
        start,
        time_limit: settings.time_limit,
        spp: settings.spp,
    };
    let prepass = integrator.prepare(&ctx, settings.seed)?;
    let prepass_seconds = start.elapsed().as_secs_f64();
    let integrator: &I = integrator;
    let ts = settings.tile_size;
    let mut tiles: Vec<Tile<I::PixelState>> = Vec::new();
    for ty in (0..height).step_by(ts as usize) {
        for tx in (0..width).step_by(ts as usize) {
            let size = UVec2::new(ts.min(width - tx), ts.min(height - ty));
            let n = (size.x * size.y) as usize;
            tiles.push(Tile {
                origin: UVec2::new(tx, ty),
                size,
                sum: vec![[0.0; 3]; n],
                sum_sq: vec![[0.0; 3]; n],
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
    let bar = progress_bar(settings);
    tiles.par_iter_mut().for_each(|tile| {
        let mut scratch = Scratch::default();
        tile.state = tile.pixels().map(|(_, p)| integrator.setup_pixel(&ctx, p, settings.seed, &mut scratch)).collect();
        tile.scratch = scratch;
    });
    // Whole passes. A pass is one sample per pixel under a time budget (so the budget is
    // overshot by at most one pass) and a few samples otherwise (fewer, larger tasks).
    let mut done = 0u32;
    loop {
        let elapsed = start.elapsed().as_secs_f64();
        if settings.spp.is_some_and(|n| done >= n) || (done > 0 && settings.time_limit.is_some_and(|t| elapsed >= t)) {
            break;
        }
        let remaining = settings.spp.map_or(u32::MAX, |n| n - done);
        let pass = if settings.time_limit.is_some() { 1 } else { remaining.min(4) };
        if done.checked_add(offset + pass).is_none() {
            break;
        }
        tiles
            .par_iter_mut()
            .for_each(|tile| tile.run_pass(&ctx, integrator, settings.seed, width, offset + done, pass));
        done += pass;
        match (settings.spp, settings.time_limit) {
            (Some(_), None) => bar.set_position(done as u64),
            (_, Some(t)) => bar.set_position(((start.elapsed().as_secs_f64() / t) * 1000.0).min(1000.0) as u64),
            _ => {}
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();

    let n = done as f64;
    let (mut rays, mut non_finite) = (0, 0);
    for tile in &tiles {
        rays += tile.scratch.rays;
        non_finite += tile.scratch.non_finite;
    }
    let (pixels, variance) = match prior {
        // Samples from before the passes (training) come in by inverse-variance weights, over
        // the whole image's sums.
        Some(prior) => {
            let mut sum = vec![[0.0f64; 3]; (width * height) as usize];
            let mut sum_sq = vec![[0.0f64; 3]; sum.len()];
            for tile in &tiles {
                for (i, p) in tile.pixels() {
                    let j = (p.y * width + p.x) as usize;
                    sum[j] = tile.sum[i];
                    sum_sq[j] = tile.sum_sq[i];
                }
            }
            drop(tiles);
            prior.combine(done, &sum, &sum_sq)
        }
        None => {
            let mut pixels = vec![[0.0f32; 3]; (width * height) as usize];
            let mut variance = vec![[0.0f32; 3]; pixels.len()];
            for tile in &tiles {
                for (i, p) in tile.pixels() {
                    let j = (p.y * width + p.x) as usize;
                    for c in 0..3 {
                        let (mean, var) = if n > 1.0 {
                            mean_and_variance(tile.sum[i][c], tile.sum_sq[i][c], n)
                        } else {
                            (tile.sum[i][c] / n, 0.0)
                        };
                        pixels[j][c] = mean as f32;
                        variance[j][c] = var as f32;
                    }
                }
            }
            (pixels, variance)
        }
    };
    let stats = RenderStats {
        spp: done,
        seconds,
        prepass_seconds,
        samples: done as u64 * (width * height) as u64,
        rays,
        threads,
        prepass,
        non_finite,
        prior_spp,
    };
    Ok((Image { width, height, pixels, variance: Some(variance), spp: done + prior_spp }, stats))
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
