//! Same scene, flags and seed ⇒ the same pixels, bit for bit, whatever the thread count and
//! the tile size (so whatever the tile order).
mod common;
use common::*;
use zvidpt::accel::BvhAccel;
use zvidpt::integrator::PathTracer;
use zvidpt::render::{RenderSettings, render};

#[test]
fn identical_across_threads_and_tiles() {
    let scene = scene_at("cornell-paper", 96, 72);
    let accel = BvhAccel::build(&scene.triangles);
    let run = |threads, tile_size| {
        let s =
            RenderSettings { spp: Some(6), seed: 42, threads: Some(threads), tile_size, ..RenderSettings::default() };
        render(&scene, &accel, &mut PathTracer::default(), &s).unwrap().0
    };
    let reference = run(1, 32);
    for (threads, tile) in [(2, 32), (2, 7), (3, 16), (1, 100)] {
        let img = run(threads, tile);
        let bits = |i: &zvidpt::film::Image| {
            i.pixels.iter().chain(i.variance.as_ref().unwrap()).flatten().map(|x| x.to_bits()).collect::<Vec<_>>()
        };
        assert!(bits(&img) == bits(&reference), "{threads} threads, tile {tile} differ");
    }
    let other_seed =
        render(&scene, &accel, &mut PathTracer::default(), &RenderSettings { seed: 43, ..settings(6, 0) }).unwrap().0;
    assert_ne!(other_seed.pixels, reference.pixels);
}
