//! Wall time for each integrator to reach a fixed MSE on `cornell-paper` at 64×48
//! (`cargo bench --bench time_to_mse`): one iteration is the whole search (renders at 1, 2, 4, …
//! spp until the MSE is at most the target). The target is the error of a 64-spp path image of
//! the same size against a 4096-spp reference, both computed once in the set-up.
use criterion::{Criterion, criterion_group, criterion_main};
use zvidpt::accel::BvhAccel;
use zvidpt::converge::time_to_mse;
use zvidpt::film::{Image, metrics};
use zvidpt::integrator::{Estimator, GuideSettings, Integrator, Jensen, PathTracer, Zvidpt};
use zvidpt::render::{RenderSettings, render};
use zvidpt::scene::Scene;

fn settings(spp: u32, seed: u64) -> RenderSettings {
    RenderSettings { spp: Some(spp), seed, threads: Some(2), ..RenderSettings::default() }
}

fn search<I: Integrator>(scene: &Scene, accel: &BvhAccel, reference: &Image, target: f64, make: &dyn Fn() -> I) -> f64 {
    let t = time_to_mse(
        |spp| {
            let (image, stats) = render(scene, accel, &mut make(), &settings(spp, 7))?;
            Ok((stats.seconds, metrics(&image, reference)?.mse))
        },
        target,
        4096,
    )
    .expect("renders succeed");
    t.seconds
}

fn bench<I: Integrator>(
    c: &mut Criterion,
    name: &str,
    scene: &Scene,
    accel: &BvhAccel,
    reference: &Image,
    target: f64,
    make: impl Fn() -> I,
) {
    eprintln!("{name}: {:.3} s to MSE {target:.3} (interpolated)", search(scene, accel, reference, target, &make));
    let mut group = c.benchmark_group("time to MSE cornell-paper 64x48");
    group.sample_size(10);
    group.bench_function(name, |b| b.iter(|| search(scene, accel, reference, target, &make)));
    group.finish();
}

fn time_to_target(c: &mut Criterion) {
    let mut scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
    scene.set_resolution(64, 48).unwrap();
    let accel = BvhAccel::build(&scene.triangles);
    let reference = render(&scene, &accel, &mut PathTracer::default(), &settings(4096, 999)).unwrap().0;
    let path64 = render(&scene, &accel, &mut PathTracer::default(), &settings(64, 1)).unwrap().0;
    let target = metrics(&path64, &reference).unwrap().mse;
    bench(c, "path", &scene, &accel, &reference, target, PathTracer::default);
    bench(c, "jensen", &scene, &accel, &reference, target, || Jensen::new(GuideSettings::default()));
    bench(c, "zvidpt-terminal", &scene, &accel, &reference, target, || {
        Zvidpt::new(Estimator::Terminal, GuideSettings::default())
    });
    bench(c, "zvidpt-collision", &scene, &accel, &reference, target, || {
        Zvidpt::new(Estimator::Collision, GuideSettings::default())
    });
}

criterion_group!(benches, time_to_target);
criterion_main!(benches);
