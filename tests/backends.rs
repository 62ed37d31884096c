//! Backends agree with brute force: same primitive and `t` within a relative 1e-4 (two
//! different f32 intersection routines; differences are rounding, far below that), on random
//! rays through the shipped scenes and through a random triangle soup, plus occlusion queries.
//!
//! These tests build the obvhs backend (`BvhAccel`) themselves: a build with `--features embree`
//! would run the same code again, so they are compiled only without it (CI runs both builds).
#![cfg(not(feature = "embree"))]
mod common;
use common::*;
use zvidpt::accel::{Accel, BruteForce, BvhAccel};
use zvidpt::geometry::{Ray, Vec3A};
use zvidpt::sampler::{Domain, SampleStream};

fn random_dir(rng: &mut SampleStream) -> Vec3A {
    let z = 1.0 - 2.0 * rng.next_f32();
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * rng.next_f32();
    Vec3A::new(r * phi.cos(), r * phi.sin(), z)
}

fn random_point(rng: &mut SampleStream, lo: f32, hi: f32) -> Vec3A {
    Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * (hi - lo) + Vec3A::splat(lo)
}

/// Compares every query; a mismatch is allowed only where the two routines disagree about a
/// ray that grazes an edge (both hits within 1e-4 relative in t, on triangles sharing the
/// point), and such cases must be rare.
fn check_agreement<A: Accel>(accel: &A, tris: &[[Vec3A; 3]], rays: &[Ray]) {
    let brute = BruteForce { triangles: tris.to_vec() };
    let (mut same, mut grazing) = (0usize, 0usize);
    for r in rays {
        let (a, b) = (accel.intersect(r), brute.intersect(r));
        match (a, b) {
            (None, None) => same += 1,
            (Some(a), Some(b)) if a.prim == b.prim => {
                assert!((a.t - b.t).abs() <= 1e-4 * b.t.max(1.0), "t {} vs {} for {r:?}", a.t, b.t);
                assert!((a.u - b.u).abs() < 1e-3 && (a.v - b.v).abs() < 1e-3, "uv {a:?} vs {b:?}");
                same += 1;
            }
            (Some(a), Some(b)) if (a.t - b.t).abs() <= 1e-4 * b.t.max(1.0) => grazing += 1,
            _ => {
                // A miss on one side and a hit on the other: only on an edge (tiny u/v/1-u-v).
                let h = a.or(b).unwrap();
                let w = 1.0 - h.u - h.v;
                assert!(h.u.min(h.v).min(w) < 1e-4, "hit {a:?} vs {b:?} for {r:?}");
                grazing += 1;
            }
        }
        let t_max = b.map_or(10.0, |h| h.t * 0.5);
        assert_eq!(accel.occluded(r, t_max), brute.occluded(r, t_max), "occluded({t_max}) for {r:?}");
    }
    assert!(grazing * 1000 <= rays.len(), "{grazing} grazing disagreements in {} rays", rays.len());
    eprintln!("{}: {same} identical, {grazing} grazing-edge disagreements of {}", accel.name(), rays.len());
}

#[test]
fn bvh_agrees_with_brute_force_in_shipped_scenes() {
    for name in ["cornell-paper", "furnace"] {
        let scene = scene(name);
        let bvh = BvhAccel::build(&scene.triangles);
        let mut rng = SampleStream::in_domain(Domain::Camera, 5, 0, 0);
        let rays: Vec<Ray> =
            (0..20_000).map(|_| Ray::new(random_point(&mut rng, -0.99, 0.99), random_dir(&mut rng))).collect();
        check_agreement(&bvh, &scene.triangles, &rays);
    }
}

#[test]
fn bvh_agrees_with_brute_force_on_triangle_soup() {
    let mut rng = SampleStream::in_domain(Domain::Camera, 6, 0, 0);
    let tris: Vec<[Vec3A; 3]> = (0..3000)
        .map(|_| {
            let c = random_point(&mut rng, -4.0, 4.0);
            [
                c + random_point(&mut rng, -0.3, 0.3),
                c + random_point(&mut rng, -0.3, 0.3),
                c + random_point(&mut rng, -0.3, 0.3),
            ]
        })
        .collect();
    let bvh = BvhAccel::build(&tris);
    let rays: Vec<Ray> =
        (0..20_000).map(|_| Ray::new(random_point(&mut rng, -6.0, 6.0), random_dir(&mut rng))).collect();
    check_agreement(&bvh, &tris, &rays);
}

#[test]
fn invalid_rays_hit_nothing() {
    let scene = scene("cornell-paper");
    let bvh = BvhAccel::build(&scene.triangles);
    let brute = BruteForce { triangles: scene.triangles.clone() };
    let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
    for &x in &bad {
        for ray in [
            Ray::new(Vec3A::new(x, 0.0, 0.0), Vec3A::Z),
            Ray::new(Vec3A::ZERO, Vec3A::new(0.0, x, 1.0)),
            Ray::new(Vec3A::ZERO, Vec3A::ZERO),
        ] {
            assert!(bvh.intersect(&ray).is_none() && brute.intersect(&ray).is_none());
            assert!(!bvh.occluded(&ray, 1.0) && !brute.occluded(&ray, 1.0));
        }
    }
    assert!(!bvh.occluded(&Ray::new(Vec3A::ZERO, Vec3A::Y), f32::NAN));
}
