//! Jensen 1995, importance-driven path tracing (ALGORITHM.md §5): the path tracer with
//! directions drawn from the photon `GL` grid (all photons), uniform pixel sampling, albedo
//! Russian roulette and next event estimation at every vertex (collision-type accumulation).
use super::guided::{Guide, GuideSettings};
use super::path::survival_probability;
use super::{Integrator, RenderContext, Scratch, direct_light};
use crate::Result;
use crate::accel::Accel;
use crate::geometry::{Frame, UVec2, Vec3A};
use crate::photon::GuidePhotons;
use crate::sampler::SampleStream;

pub struct Jensen {
    pub settings: GuideSettings,
    pub rr_depth: u32,
    pub guide: Option<Guide>,
}

impl Jensen {
    /// Jensen guides with all photons, whatever `settings.which` says.
    #[must_use]
    pub fn new(settings: GuideSettings) -> Self {
        Self { settings: GuideSettings { which: GuidePhotons::All, ..settings }, rr_depth: 3, guide: None }
    }
}

impl Integrator for Jensen {
    type PixelState = ();

    fn name(&self) -> &'static str {
        "jensen"
    }

    fn prepare<A: Accel>(&mut self, ctx: &RenderContext<A>, seed: u64) -> Result<Option<String>> {
        let guide = Guide::build(ctx.scene, ctx.accel, &self.settings, seed)?;
        let report = guide.report.to_string();
        self.guide = Some(guide);
        Ok(Some(report))
    }

    fn setup_pixel<A: Accel>(&self, _: &RenderContext<A>, _: UVec2, _: u64, _: &mut Scratch) {}

    fn sample<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        _: &(),
        rng: &mut SampleStream,
        scratch: &mut Scratch,
    ) -> Vec3A {
        let guide = self.guide.as_ref().expect("prepare() builds the photon map");
        let ray = ctx.scene.camera.ray(pixel.as_vec2() + rng.next_2d());
        scratch.rays += 1;
        let Some(hit) = ctx.accel.intersect(&ray) else {
            return Vec3A::ZERO;
        };
        let mut si = ctx.scene.interaction(&ray, &hit);
        let mut radiance = si.emitted();
        let mut grid = std::mem::take(&mut scratch.grid);
        let mut throughput = Vec3A::ONE;
        let mut bounce = 0;
        loop {
            let albedo = si.material.diffuse;
            if albedo == Vec3A::ZERO {
                break;
            }
            radiance += throughput * direct_light(ctx, &si, rng, scratch);
            if bounce >= self.rr_depth {
                let q = survival_probability(albedo);
                if rng.next_f32() >= q {
                    break;
                }
                throughput /= q;
            }
            let frame = Frame::from_normal(si.n);
            let g = guide.at(&si, &frame, &mut grid);
            let (wi, weight) = guide.sample_direction(&g, &frame, albedo, rng);
            throughput *= weight;
            let ray = si.spawn_ray(wi);
            scratch.rays += 1;
            let Some(hit) = ctx.accel.intersect(&ray) else {
                break;
            };
            si = ctx.scene.interaction(&ray, &hit);
            bounce += 1;
        }
        scratch.grid = grid;
        radiance
    }
}
