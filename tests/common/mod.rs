//! Helpers shared by the integration tests.
#![allow(dead_code)]
pub mod cli;
use zvidpt::accel::{Accel, BvhAccel};
use zvidpt::film::Image;
use zvidpt::geometry::{UVec2, Vec3A};
use zvidpt::integrator::{Integrator, RenderContext, Scratch};
use zvidpt::render::{RenderSettings, render};
use zvidpt::sampler::SampleStream;
use zvidpt::scene::Scene;

pub fn scene(name: &str) -> Scene {
    Scene::load(format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"))).expect("shipped scene loads")
}

pub fn scene_at(name: &str, width: u32, height: u32) -> Scene {
    let mut s = scene(name);
    s.set_resolution(width, height).unwrap();
    s
}

pub fn settings(spp: u32, seed: u64) -> RenderSettings {
    RenderSettings { spp: Some(spp), seed, threads: Some(2), ..RenderSettings::default() }
}

pub fn render_bvh<I: Integrator>(scene: &Scene, integrator: &mut I, spp: u32, seed: u64) -> Image {
    let accel = BvhAccel::build(&scene.triangles);
    render(scene, &accel, integrator, &settings(spp, seed)).unwrap().0
}

/// Per-block, per-channel two-sample z statistics between an image `a` and an independent
/// higher-spp `reference`: `z = (ā − b̄) / √(σ²/n_a + σ²/n_b)`, with the per-sample variance σ²
/// taken from the reference (the "z-test at the reference's variance": with heavy-tailed
/// estimators a short render's own variance misses the rare large samples and inflates z).
/// Returns the largest |z| and the number of tests (blocks × 3).
pub fn max_block_z(a: &Image, reference: &Image, block: u32) -> (f64, usize) {
    block_z(a, reference, block, false, 0.0)
}

/// As [`max_block_z`], but each image's mean uses its own variance (the classic two-sample
/// test), for comparing different estimators whose variances differ.
pub fn max_block_z_both(a: &Image, reference: &Image, block: u32) -> (f64, usize) {
    block_z(a, reference, block, true, 0.0)
}

/// [`max_block_z_both`] with a floor on each block's standard error of `floor` times the
/// reference block's mean: for images with noise-free regions (a sky seen directly), where two
/// renderers' rounding alone would be many "standard errors" apart.
pub fn max_block_z_both_floored(a: &Image, reference: &Image, block: u32, floor: f64) -> (f64, usize) {
    block_z(a, reference, block, true, floor)
}

fn block_z(a: &Image, reference: &Image, block: u32, own_variance: bool, floor: f64) -> (f64, usize) {
    let b = reference;
    assert_eq!((a.width, a.height), (b.width, b.height));
    let vb = b.variance.as_ref().unwrap();
    let va = if own_variance { a.variance.as_ref().unwrap() } else { vb };
    let mut worst = 0.0f64;
    let mut tests = 0;
    for by in (0..a.height).step_by(block as usize) {
        for bx in (0..a.width).step_by(block as usize) {
            for c in 0..3 {
                let (mut ma, mut mb, mut sa, mut sb, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0f64);
                for y in by..(by + block).min(a.height) {
                    for x in bx..(bx + block).min(a.width) {
                        let i = (y * a.width + x) as usize;
                        ma += a.pixels[i][c] as f64;
                        mb += b.pixels[i][c] as f64;
                        sa += va[i][c] as f64 / a.spp as f64;
                        sb += vb[i][c] as f64 / b.spp as f64;
                        n += 1.0;
                    }
                }
                let var = (sa + sb) / (n * n) + (floor * mb / n).powi(2);
                if var > 0.0 {
                    let z = ((ma - mb) / n).abs() / var.sqrt();
                    if z > worst && std::env::var_os("ZVIDPT_TEST_VERBOSE").is_some() {
                        eprintln!("block ({bx},{by}) ch {c}: {:.4} vs {:.4}, z {z:.2}", ma / n, mb / n);
                    }
                    worst = worst.max(z);
                } else {
                    assert!((ma - mb).abs() < 1e-9, "zero variance but different means");
                }
                tests += 1;
            }
        }
    }
    (worst, tests)
}

/// Mean over all pixels and channels, and its standard error from the per-pixel variances.
pub fn image_mean_and_se(img: &Image) -> (f64, f64) {
    let v = img.variance.as_ref().unwrap();
    let n = (img.pixels.len() * 3) as f64;
    let mean = img.pixels.iter().flatten().map(|&x| x as f64).sum::<f64>() / n;
    let var_of_mean = v.iter().flatten().map(|&x| x as f64 / img.spp as f64).sum::<f64>() / (n * n);
    (mean, var_of_mean.sqrt())
}

/// A deliberately broken estimator: the wrapped integrator's samples scaled by `factor`.
/// Tests run it to show that their tolerance detects a bias of that size.
pub struct Scaled<I>(pub I, pub f32);

impl<I: Integrator> Integrator for Scaled<I> {
    type PixelState = I::PixelState;
    fn name(&self) -> &'static str {
        "scaled"
    }
    fn prepare<A: Accel>(&mut self, ctx: &RenderContext<A>, seed: u64) -> zvidpt::Result<Option<String>> {
        self.0.prepare(ctx, seed)
    }
    fn setup_pixel<A: Accel>(&self, ctx: &RenderContext<A>, p: UVec2, seed: u64, c: &mut Scratch) -> I::PixelState {
        self.0.setup_pixel(ctx, p, seed, c)
    }
    fn sample<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        p: UVec2,
        s: &I::PixelState,
        rng: &mut SampleStream,
        c: &mut Scratch,
    ) -> Vec3A {
        self.0.sample(ctx, p, s, rng, c) * self.1
    }
}

/// Image-wide per-channel z statistics of `a` against `reference`, at the reference's
/// per-sample variance (see [`max_block_z`]). Returns the largest |z| over the channels.
pub fn max_image_z(a: &Image, reference: &Image) -> f64 {
    max_block_z(a, reference, a.width.max(a.height)).0
}

/// As [`max_image_z`], each image at its own variance (see [`max_block_z_both`]).
pub fn max_image_z_both(a: &Image, reference: &Image) -> f64 {
    max_block_z_both(a, reference, a.width.max(a.height)).0
}
