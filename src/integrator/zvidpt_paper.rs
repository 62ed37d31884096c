//! Zero Variance Importance Sampling Driven Potential Tracing (paper §4, ALGORITHM.md §2–§3).
//!
//! A camera random walk solves `Lr = L1 + ∫ f cos Lr(y) dω`: pixels are importance-sampled on
//! a subpixel grid `Gp` (§4.1), directions on the photon `GL` grid (§4.2, Eq. 7), and the walk
//! terminates with `q = L̃1/L̃r` (§4.3). Two unbiased estimators:
//! - terminal: on termination at `xL`, `W0·Le(x0) + WL·L̂1(xL)/qL`; zero variance when the
//!   photon estimates are exact;
//! - collision: `Wk·L̂1(xk)` at every state, continuing with probability `1 − qk`.
//!
//! The weights are `W0 = 1/(n·m·Pj)` and `W(k+1) = Wk · f·cosθ / (pdf(ωi)·(1 − qk))`.
use super::photon_guided::{GuideSettings, PhotonGuide, radiance_estimate, termination_probability};
use super::{Integrator, MisAt, RenderContext, Scratch, direct_light};
use crate::Result;
use crate::accel::Accel;
use crate::geometry::{UVec2, Vec2, Vec3A, luminance};
use crate::photon::GridShape;
use crate::photon::grid::pick_cell;
use crate::sampler::survival_probability;
use crate::sampler::{Domain, SampleStream};
use crate::scene::SurfaceInteraction;

/// Most subpixels a pixel grid may have (the per-pixel state is a fixed array).
pub const MAX_SUBPIXELS: usize = 32;

/// Which of the paper's estimators a walk scores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Estimator {
    /// The terminal estimator: a walk scores the emission where it ends.
    Terminal,
    /// The collision estimator: a walk scores at every vertex.
    Collision,
}

/// The paper's ZVIDPT, as ALGORITHM.md states it: pixels, directions and termination drawn
/// in proportion to the photon map's estimates of the radiance they lead to.
pub struct Zvidpt {
    /// Terminal or collision.
    pub estimator: Estimator,
    /// The photon guide's settings.
    pub settings: GuideSettings,
    /// The pixel grid `Gp` (paper: 2×4).
    pub pixel_grid: GridShape,
    /// `ε_p`: subpixel values are floored at this fraction of their mean.
    pub pixel_floor: f32,
    /// Smallest termination probability `q`.
    pub q_min: f32,
    /// Largest termination probability `q`.
    pub q_max: f32,
    /// `κ` of [`termination_probability`] (1: ALGORITHM.md's `q = L̃1/L̃r`).
    pub q_kappa: f32,
    /// The guide the pre-pass built.
    pub guide: Option<PhotonGuide>,
}

impl Zvidpt {
    /// The paper's configuration for `estimator` with a guide of `settings`.
    #[must_use]
    pub fn new(estimator: Estimator, settings: GuideSettings) -> Self {
        Self {
            estimator,
            settings,
            pixel_grid: GridShape { rows: 2, cols: 4 },
            pixel_floor: 0.1,
            q_min: 0.05,
            q_max: 0.95,
            q_kappa: 1.0,
            guide: None,
        }
    }
}

/// A pixel's subpixel CDF (`Gp`), built once before its first sample.
#[derive(Clone, Copy, Debug)]
pub struct SubpixelGrid {
    cdf: [f32; MAX_SUBPIXELS],
}

impl Integrator for Zvidpt {
    type PixelState = SubpixelGrid;

    fn name(&self) -> &'static str {
        match self.estimator {
            Estimator::Terminal => "zvidpt-terminal",
            Estimator::Collision => "zvidpt-collision",
        }
    }

    fn prepare<A: Accel>(&mut self, ctx: &RenderContext<A>, seed: u64) -> Result<Option<String>> {
        let guide = PhotonGuide::build(ctx.scene, ctx.accel, &self.settings, seed)?;
        let report = guide.report.to_string();
        self.guide = Some(guide);
        Ok(Some(report))
    }

    /// Paper §4.1: one camera ray through a jittered point of each subpixel, `vj = lum(Le +
    /// L̃r)` at its first hit, floored by `ε_p · mean(v)`; uniform if all are zero.
    fn setup_pixel<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        seed: u64,
        scratch: &mut Scratch,
    ) -> SubpixelGrid {
        let guide = self.guide.as_ref().expect("prepare() builds the photon map");
        let shape = self.pixel_grid;
        let n = shape.cells();
        let index = pixel.y as u64 * ctx.scene.camera.width as u64 + pixel.x as u64;
        let mut rng = SampleStream::in_domain(Domain::PixelSetup, seed, index, 0);
        let mut cdf = [0.0f32; MAX_SUBPIXELS];
        for (j, v) in cdf.iter_mut().enumerate().take(n) {
            let film = ctx.scene.camera.film_point(pixel, subpixel_point(shape, j, rng.next_2d()));
            let ray = ctx.scene.camera.ray(film);
            scratch.rays += 1;
            *v = match ctx.accel.intersect(&ray) {
                Some(hit) => {
                    let si = ctx.scene.interaction(&ray, &hit);
                    let lr = radiance_estimate(si.material.albedo(), guide.density_at(&si).all);
                    luminance(si.emitted() + lr)
                }
                None => luminance(ctx.scene.lights.environment(ray.dir)),
            };
        }
        crate::photon::grid::weights_to_cdf(&mut cdf[..n], self.pixel_floor);
        SubpixelGrid { cdf }
    }

    fn sample<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        pixel: UVec2,
        grid: &SubpixelGrid,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
    ) -> Vec3A {
        let guide = self.guide.as_ref().expect("prepare() builds the photon map");
        let shape = self.pixel_grid;
        let n = shape.cells();
        let cdf = &grid.cdf[..n];
        // The sample's stratified pixel point picks the subpixel by inverting Gp's CDF along x
        // and, rescaled, places the point inside it: the film point's density is `n·Pj`, and
        // the pixel's stratification carries over to its subpixels.
        let u = rng.pixel_2d();
        let (j, pj, ux) = pick_cell(cdf, u.x);
        let film = ctx.scene.camera.film_point(pixel, subpixel_point(shape, j, Vec2::new(ux, u.y)));
        let ray = ctx.scene.camera.ray(film);
        scratch.rays += 1;
        let weight = Vec3A::splat(1.0 / (n as f32 * pj));
        let Some(hit) = ctx.accel.intersect(&ray) else {
            return weight * ctx.scene.lights.environment(ray.dir);
        };
        let si = ctx.scene.interaction(&ray, &hit);
        self.walk(ctx, guide, si, weight, rng, scratch)
    }
}

impl Zvidpt {
    /// The walk from the camera vertex `si` with weight `W0` (paper §4.2–§4.3); the photon
    /// guide's grids are built in `scratch`'s grid.
    #[inline]
    fn walk<A: Accel>(
        &self,
        ctx: &RenderContext<A>,
        guide: &PhotonGuide,
        mut si: SurfaceInteraction,
        mut weight: Vec3A,
        rng: &mut SampleStream,
        scratch: &mut Scratch,
    ) -> Vec3A {
        let mut grid = std::mem::take(&mut scratch.grid);
        let mut result = weight * si.emitted();
        let value = loop {
            let albedo = si.material.albedo();
            // A surface that reflects nothing ends the walk: both branches below add zero.
            if albedo == Vec3A::ZERO {
                break result;
            }
            let frame = si.bsdf_frame();
            let grid_frame = si.gather_frame(&frame);
            let g = guide.at(&si, &grid_frame, &mut grid);
            let wi = frame.to_local(si.wo);
            // A pure delta surface has no `L̂1` (NEE cannot reach through it; the emission its
            // lobe finds is counted at the next vertex): the walk continues by albedo.
            let delta = si.material.bsdf.is_delta();
            let q = if delta {
                1.0 - survival_probability(albedo)
            } else {
                termination_probability(albedo, &g.density, self.q_min, self.q_max, self.q_kappa)
            };
            let direct = |rng: &mut SampleStream, scratch: &mut Scratch| {
                if delta { Vec3A::ZERO } else { direct_light(ctx, &si, &frame, wi, MisAt::NONE, rng, scratch) }
            };
            match self.estimator {
                Estimator::Terminal => {
                    if rng.next_f32() < q {
                        break result + weight * direct(rng, scratch) / q;
                    }
                }
                Estimator::Collision => {
                    result += weight * direct(rng, scratch);
                    if rng.next_f32() < q {
                        break result;
                    }
                }
            }
            let Some(s) = guide.scatter(&g, &si, &grid_frame, &frame, wi, rng) else {
                break result;
            };
            weight *= s.weight / (1.0 - q);
            let ray = si.spawn_ray(s.dir);
            scratch.rays += 1;
            let Some(hit) = ctx.accel.intersect(&ray) else {
                // The environment behind a delta lobe (NEE counts it elsewhere).
                break if s.delta { result + weight * ctx.scene.lights.environment(s.dir) } else { result };
            };
            si = ctx.scene.interaction(&ray, &hit);
            if s.delta {
                result += weight * si.emitted();
            }
        };
        scratch.grid = grid;
        value
    }
}

/// A uniform point (`u ∈ [0,1)²`) inside subpixel `j` of a pixel, in pixel units.
#[inline]
fn subpixel_point(shape: GridShape, j: usize, u: Vec2) -> Vec2 {
    let (row, col) = (j as u32 / shape.cols, j as u32 % shape.cols);
    Vec2::new((col as f32 + u.x) / shape.cols as f32, (row as f32 + u.y) / shape.rows as f32)
}
