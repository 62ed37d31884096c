//! Samples per second of each integrator on `cornell-paper` at 256×192, 8 spp per iteration,
//! pre-pass (photon map, guide cache) included, on the obvhs backend
//! (`cargo bench --bench render`). Throughput is reported per sample.
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use zvidpt::accel::BvhAccel;
use zvidpt::integrator::{Estimator, GuideSettings, Integrator, Jensen, PathTracer, Zvidpt};
use zvidpt::render::{RenderSettings, render};
use zvidpt::scene::Scene;

fn bench_integrator<I: Integrator>(
    c: &mut Criterion,
    name: &str,
    scene: &Scene,
    accel: &BvhAccel,
    mut make: impl FnMut() -> I,
) {
    let settings = RenderSettings { spp: Some(8), threads: Some(2), ..RenderSettings::default() };
    let samples = 8 * scene.camera.width as u64 * scene.camera.height as u64;
    let mut group = c.benchmark_group("render cornell-paper 256x192 8spp");
    group.throughput(Throughput::Elements(samples));
    group.sample_size(10);
    group.bench_function(name, |b| b.iter(|| render(scene, accel, &mut make(), &settings).unwrap()));
    group.finish();
}

fn integrators(c: &mut Criterion) {
    let mut scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
    scene.set_resolution(256, 192).unwrap();
    let accel = BvhAccel::build(&scene.triangles);
    bench_integrator(c, "path", &scene, &accel, PathTracer::default);
    bench_integrator(c, "jensen", &scene, &accel, || Jensen::new(GuideSettings::default()));
    bench_integrator(c, "zvidpt-terminal", &scene, &accel, || {
        Zvidpt::new(Estimator::Terminal, GuideSettings::default())
    });
    bench_integrator(c, "zvidpt-collision", &scene, &accel, || {
        Zvidpt::new(Estimator::Collision, GuideSettings::default())
    });
}

criterion_group!(benches, integrators);
criterion_main!(benches);
