//! Photon map build time and k-nearest radiance queries per second on `cornell-paper`
//! (`cargo bench --bench photon_map`), at the paper's size (6,891 photons) and at 100k.
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use zvidpt::accel::BvhAccel;
use zvidpt::geometry::Frame;
use zvidpt::photon::{GridShape, GuideCache, GuidePhotons, PhotonMap};
use zvidpt::scene::Scene;

fn photon_map(c: &mut Criterion) {
    let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
    let accel = BvhAccel::build(&scene.triangles);
    let shape = GridShape { rows: 4, cols: 16 };
    let mut group = c.benchmark_group("photon map cornell-paper");
    group.sample_size(10);
    for photons in [6891usize, 100_000] {
        group.throughput(Throughput::Elements(photons as u64));
        group.bench_function(BenchmarkId::new("build", photons), |b| {
            b.iter(|| PhotonMap::build(&scene, &accel, photons, 0).unwrap())
        });
        let map = PhotonMap::build(&scene, &accel, photons, 0).unwrap();
        // kNN queries (k = 50) with the guide grid, at photon positions (where walks go).
        let sites: Vec<usize> = (0..map.len()).step_by((map.len() / 4096).max(1)).collect();
        group.throughput(Throughput::Elements(sites.len() as u64));
        group.bench_function(BenchmarkId::new("knn50 + grid queries", photons), |b| {
            let mut cells = vec![0.0f32; shape.cells()];
            b.iter(|| {
                let mut sum = 0.0;
                for &i in &sites {
                    cells.fill(0.0);
                    let n = map.normal[i];
                    let d = map.gather(
                        map.position(i),
                        n,
                        50,
                        Some((&Frame::from_normal(n), shape, GuidePhotons::Indirect, &mut cells)),
                    );
                    sum += d.all.x;
                }
                sum
            })
        });
        group.throughput(Throughput::Elements(map.len().min(1 << 16) as u64));
        group.bench_function(BenchmarkId::new("guide cache", photons), |b| {
            b.iter(|| GuideCache::build(&map, shape, 50, GuidePhotons::Indirect, 0.1, 1 << 16))
        });
    }
    group.finish();
}

criterion_group!(benches, photon_map);
criterion_main!(benches);
