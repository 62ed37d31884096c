//! Jensen 1995, importance-driven path tracing (ALGORITHM.md §5): the path tracer with
//! directions drawn from the photon `GL` grid (all photons), uniform pixel sampling, albedo
//! Russian roulette and next event estimation at every vertex (collision-type accumulation).
//! On a surface that is not Lambertian, directions come from a mixture of the BSDF's sampling
//! and the grid ([`super::mixture::sample_mixture`]).
use super::path::{Mis, trace_path};
use super::photon_guided::{GuideSettings, PhotonGuide};
use super::{Integrator, RenderContext, Scratch};
use crate::Result;
use crate::accel::Accel;
use crate::geometry::{UVec2, Vec3A};
use crate::photon::GuidePhotons;
use crate::sampler::SampleStream;

/// Jensen's photon-guided path tracer: directions at diffuse vertices drawn from the photon
/// grid of the nearest guide record, Russian roulette by albedo.
pub struct Jensen {
    /// The guide's settings (photons, grid, records).
    pub settings: GuideSettings,
    /// Bounces before Russian roulette starts.
    pub rr_depth: u32,
    /// The guide the pre-pass built.
    pub guide: Option<PhotonGuide>,
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
        let guide = PhotonGuide::build(ctx.scene, ctx.accel, &self.settings, seed)?;
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
        let mut grid = std::mem::take(&mut scratch.grid);
        // Without MIS (Jensen's method counts light by NEE only), so the grid's density on a
        // Lambertian surface is never needed.
        let radiance = trace_path::<A, false, true, true>(
            ctx,
            pixel,
            rng,
            scratch,
            self.rr_depth,
            Mis::Off,
            |si, frame, wi, rng| {
                let grid_frame = si.gather_frame(frame);
                let g = guide.at(si, &grid_frame, &mut grid);
                guide.scatter(&g, si, &grid_frame, frame, wi, rng)
            },
        );
        scratch.grid = grid;
        radiance
    }
}
