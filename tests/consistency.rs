//! The path tracer's `cornell-paper` image agrees with an independent, 8× longer render of
//! itself at another seed, block by block (16×16 pixels of a 64×48 image, each channel), by a
//! two-sample z-test at the reference's per-sample variance, and image-wide per channel. Each
//! bound is Šidák-corrected for its number of tests at a family-wise false-alarm rate of 1e-3
//! (seeds are fixed).
//!
//! The short render also runs with the other light-sampling strategy (area, ALGORITHM.md §3's):
//! both strategies must estimate the same image.
//!
//! Why so many samples per block (262k): with area light sampling this scene's estimator is
//! heavy-tailed (NEE at ceiling points just above the light, 0.03 away, gives rare samples ~10⁴
//! times the mean), and a block that happens to miss them underestimates its own variance (at
//! 16k samples per block a correct renderer gave |z| = 11). With solid-angle light sampling
//! (the default) the tails are light and the test sees a 5% bias (checked below with a
//! deliberately scaled estimator: block |z| 5.7, image 9.2); smaller biases are the furnace
//! test's job.
//!
//! These tests build the obvhs backend (`BvhAccel`) themselves: a build with `--features embree`
//! would run the same code again, so they are compiled only without it (CI runs both builds).
#![cfg(not(feature = "embree"))]
mod common;
use common::*;
use zvidpt::accel::BvhAccel;
use zvidpt::integrator::PathTracer;
use zvidpt::light::LightSampling;
use zvidpt::render::{RenderSettings, render};
use zvidpt::stats::family_z_bound;

#[test]
fn cornell_paper_consistent_with_longer_render() {
    let scene = scene_at("cornell-paper", 64, 48);
    let reference = render_bvh(&scene, &mut PathTracer::default(), 8192, 2);
    let short = render_bvh(&scene, &mut PathTracer::default(), 1024, 1);
    let (z, n) = max_block_z(&short, &reference, 16);
    let bound = family_z_bound(n, 1e-3);
    let global_bound = family_z_bound(3, 1e-3);
    let zg = max_image_z(&short, &reference);
    eprintln!(
        "cornell-paper path 1024 vs 8192 spp: blocks max |z| {z:.2} over {n} tests (bound {bound:.2}); image {zg:.2} (bound {global_bound:.2})"
    );
    assert!(z < bound, "max |z| {z} >= {bound}");
    assert!(zg < global_bound, "image-wide |z| {zg} >= {global_bound}");

    // Area sampling's tails are heavy here, so this check false-alarms more often than its
    // nominal 1e-3: over seeds 3–7 a correct renderer gave max block |z| 4.21, 2.68, 2.04,
    // 1.87, 2.44 (bound 4.19). A real disagreement shows at every seed.
    let area_settings = RenderSettings { light_sampling: LightSampling::Area, ..settings(4096, 4) };
    let area =
        render(&scene, &BvhAccel::build(&scene.triangles), &mut PathTracer::default(), &area_settings).unwrap().0;
    // Different estimators, so each image's mean at its own variance.
    let (za, _) = max_block_z_both(&area, &reference, 16);
    let zag = max_image_z_both(&area, &reference);
    eprintln!("area light sampling 4096 spp vs solid angle 8192 spp: blocks max |z| {za:.2}, image {zag:.2}");
    assert!(za < bound && zag < global_bound, "area and solid-angle light sampling disagree: |z| {za}, {zag}");

    // The same test sees a 5% bias (a deliberately broken estimator).
    let biased = render_bvh(&scene, &mut Scaled(PathTracer::default(), 0.95), 1024, 1);
    let (zb, _) = max_block_z(&biased, &reference, 16);
    let zbg = max_image_z(&biased, &reference);
    eprintln!("with a 5% bias: blocks max |z| {zb:.2}, image {zbg:.2}");
    assert!(zb >= bound || zbg >= global_bound, "a 5% bias went unnoticed: |z| {zb}, {zbg}");

    // SCENES.md's independent image mean, as a sanity check on the scene (5 s.e. + 0.5%).
    let m = reference.mean();
    let v = reference.variance.as_ref().unwrap();
    for (c, expected) in [0.581, 0.382, 0.116].into_iter().enumerate() {
        let n = v.len() as f64;
        let se = (v.iter().map(|p| p[c] as f64).sum::<f64>() / reference.spp as f64).sqrt() / n;
        eprintln!("channel {c}: mean {:.4} ± {se:.4} vs SCENES.md {expected}", m[c]);
        assert!((m[c] - expected).abs() < 5.0 * se + 0.005 * expected, "channel {c}: mean {} vs {expected}", m[c]);
    }
}
