//! Rays per second for each backend (`cargo bench --bench rays`; the Embree cases are added by
//! `--features embree`): coherent
//! primary rays (camera rays in tile order), incoherent diffuse-bounce rays (cosine directions
//! from the primary hits) and shadow rays (from the hits to points on a light), on
//! `cornell-paper` and on a procedural 1.28M-triangle terrain; single-ray queries against
//! 8-wide packets (the batched trait methods); 1 and 2 threads.
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rayon::prelude::*;
use std::time::Duration;
#[cfg(feature = "embree")]
use zvidpt::accel::embree::EmbreeAccel;
use zvidpt::accel::{Accel, BvhAccel};
use zvidpt::geometry::{Frame, Ray, Vec2, Vec3A, warp};
use zvidpt::sampler::{Domain, SampleStream};
use zvidpt::scene::{Camera, Material, Scene};

const RAYS: usize = 1 << 18;
const PACKET: usize = 8;

/// A 800×800-cell heightfield of two triangles a cell (1.28M triangles), hills and ridges.
fn terrain() -> Scene {
    let n = 800usize;
    let h = |i: usize, j: usize| {
        let (x, z) = (i as f32 / n as f32 * 8.0 - 4.0, j as f32 / n as f32 * 8.0 - 4.0);
        0.4 * (1.7 * x).sin() * (1.3 * z).cos()
            + 0.15 * (5.1 * x + 2.3 * z).sin()
            + 0.05 * (17.0 * x).sin() * (13.0 * z).cos()
    };
    let p = |i: usize, j: usize| Vec3A::new(i as f32 / n as f32 * 8.0 - 4.0, h(i, j), j as f32 / n as f32 * 8.0 - 4.0);
    let mut tris = Vec::with_capacity(2 * n * n);
    for i in 0..n {
        for j in 0..n {
            tris.push([p(i, j), p(i, j + 1), p(i + 1, j + 1)]);
            tris.push([p(i, j), p(i + 1, j + 1), p(i + 1, j)]);
        }
    }
    let camera = Camera::new(Vec3A::new(0.0, 3.0, 6.0), Vec3A::ZERO, Vec3A::Y, 50.0, 512, 512).unwrap();
    Scene::from_triangles("terrain", camera, tris, Material::diffuse(Vec3A::splat(0.5), Vec3A::ZERO))
}

/// Camera rays in 8×8 tiles, the order the renderer traces them.
fn primary_rays(scene: &Scene) -> Vec<Ray> {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut rays = Vec::with_capacity(RAYS);
    'tiles: for ty in (0..h).step_by(8) {
        for tx in (0..w).step_by(8) {
            for y in ty..(ty + 8).min(h) {
                for x in tx..(tx + 8).min(w) {
                    rays.push(scene.camera.ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)));
                    if rays.len() == RAYS {
                        break 'tiles;
                    }
                }
            }
        }
    }
    rays
}

/// Bounce and shadow rays from the primary hits (shadow rays towards random points of a
/// light: the scene's emitters, or a 1×1 square above the terrain).
fn secondary_rays(scene: &Scene, accel: &BvhAccel, primary: &[Ray]) -> (Vec<Ray>, Vec<Ray>, Vec<f32>) {
    let (mut bounce, mut shadow, mut t_max) = (Vec::new(), Vec::new(), Vec::new());
    let mut rng = SampleStream::in_domain(Domain::Camera, 99, 0, 0);
    let mut i = 0;
    while bounce.len() < RAYS {
        let ray = primary[i % primary.len()];
        i += 1;
        let Some(hit) = accel.intersect(&ray) else { continue };
        let si = scene.interaction(&ray, &hit);
        bounce.push(si.spawn_ray(Frame::from_normal(si.n).to_world(warp::cosine_hemisphere(rng.next_2d()))));
        let target = match scene.lights.emit_photon(rng.next_f32(), rng.next_2d(), rng.next_2d()) {
            Some((r, _)) => r.origin,
            None => Vec3A::new(rng.next_f32() - 0.5, 3.0, rng.next_f32() - 0.5),
        };
        let d = target - si.p;
        let s = si.spawn_ray(d.normalize());
        t_max.push((target - s.origin).length() * 0.999);
        shadow.push(s);
    }
    (bounce, shadow, t_max)
}

fn run_single<A: Accel>(accel: &A, rays: &[Ray], t_max: Option<&[f32]>) -> usize {
    rays.par_chunks(4096)
        .enumerate()
        .map(|(c, chunk)| match t_max {
            None => chunk.iter().filter(|r| accel.intersect(r).is_some()).count(),
            Some(t) => chunk.iter().zip(&t[c * 4096..]).filter(|(r, t)| accel.occluded(r, **t)).count(),
        })
        .sum()
}

fn run_packets<A: Accel>(accel: &A, rays: &[Ray], t_max: Option<&[f32]>) -> usize {
    rays.par_chunks(4096)
        .enumerate()
        .map(|(c, chunk)| {
            let mut hits = [None; PACKET];
            let mut occ = [false; PACKET];
            let mut n = 0;
            for (k, p) in chunk.chunks(PACKET).enumerate() {
                match t_max {
                    None => {
                        accel.intersect_batch(p, &mut hits[..p.len()]);
                        n += hits[..p.len()].iter().filter(|h| h.is_some()).count();
                    }
                    Some(t) => {
                        let start = c * 4096 + k * PACKET;
                        accel.occluded_batch(p, &t[start..start + p.len()], &mut occ[..p.len()]);
                        n += occ[..p.len()].iter().filter(|o| **o).count();
                    }
                }
            }
            n
        })
        .sum()
}

fn bench_scene(c: &mut Criterion, scene: &Scene) {
    let bvh = BvhAccel::build(&scene.triangles);
    #[cfg(feature = "embree")]
    let embree = EmbreeAccel::build(&scene.triangles).expect("Embree builds the scene");
    let primary = primary_rays(scene);
    let (bounce, shadow, t_max) = secondary_rays(scene, &bvh, &primary);
    let mut group = c.benchmark_group(format!("rays {}", scene.name));
    group.sample_size(10).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        for (kind, rays, t) in
            [("primary", &primary, None), ("bounce", &bounce, None), ("shadow", &shadow, Some(&t_max[..]))]
        {
            let id = |b: &str| BenchmarkId::new(format!("{kind}/{b}"), format!("{threads}t"));
            group.throughput(Throughput::Elements(rays.len() as u64));
            group.bench_function(id("bvh single"), |b| b.iter(|| pool.install(|| run_single(&bvh, rays, t))));
            // The trait's default batched methods (a loop): the batching overhead, for reference.
            group.bench_function(id("bvh batch8"), |b| b.iter(|| pool.install(|| run_packets(&bvh, rays, t))));
            #[cfg(feature = "embree")]
            {
                group.bench_function(id("embree single"), |b| b.iter(|| pool.install(|| run_single(&embree, rays, t))));
                group.bench_function(id("embree packet8"), |b| {
                    b.iter(|| pool.install(|| run_packets(&embree, rays, t)))
                });
            }
        }
    }
    group.finish();
}

fn rays(c: &mut Criterion) {
    let cornell = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
    bench_scene(c, &cornell);
    bench_scene(c, &terrain());
}

criterion_group!(benches, rays);
criterion_main!(benches);
