//! The furnace: inside a closed sphere of albedo ρ = 0.5 emitting Le = 0.5, L = Le/(1−ρ) = 1
//! in every pixel. The image mean must match 1 within a z-bound of 4 standard errors (the
//! standard error estimated from the render's own per-pixel variances; a correct estimator
//! fails this with probability ~6e-5, and the seed is fixed).
mod common;
use common::*;
use zvidpt::integrator::PathTracer;

const Z_BOUND: f64 = 4.0;

#[test]
fn path_tracer_matches_analytic_furnace() {
    let scene = scene_at("furnace", 32, 32);
    let img = render_bvh(&scene, &mut PathTracer::default(), 64, 1);
    let (mean, se) = image_mean_and_se(&img);
    let z = (mean - 1.0) / se;
    eprintln!("furnace path: mean {mean:.6}, s.e. {se:.2e}, z {z:.2}");
    assert!(z.abs() < Z_BOUND, "mean {mean} s.e. {se} z {z}");
    // Every pixel, not just the mean: each is within a Šidák-corrected bound of 1, at the
    // pooled per-sample variance (every pixel sees the same sphere, so all share one
    // distribution). A pixel's own 64-sample variance is not used: the per-sample
    // distribution is skewed (Russian roulette's geometric tail), so pixels whose samples
    // stopped early look both low and certain, and own-variance z reached −6.6 for a
    // correct renderer (pooled: |z| ≤ 4.1 over seeds 1–5).
    let v = img.variance.as_ref().unwrap();
    let bound = zvidpt::stats::family_z_bound(img.pixels.len() * 3, 1e-3);
    let pooled = v.iter().map(|p| p[0] as f64).sum::<f64>() / v.len() as f64;
    let se = (pooled / img.spp as f64).sqrt();
    for p in &img.pixels {
        for c in 0..3 {
            assert!(((p[c] as f64 - 1.0) / se).abs() < bound, "pixel {p:?}, pooled s.e. {se}");
        }
    }
}

/// The tolerance above has the power to see a 2% bias: the same render scaled by 0.98 fails.
#[test]
fn furnace_test_detects_a_two_percent_bias() {
    let scene = scene_at("furnace", 32, 32);
    let img = render_bvh(&scene, &mut Scaled(PathTracer::default(), 0.98), 64, 1);
    let (mean, se) = image_mean_and_se(&img);
    assert!(((mean - 1.0) / se).abs() >= Z_BOUND, "a 2% bias went unnoticed: mean {mean} s.e. {se}");
}
