//! Ray-tracing backends behind one trait. The backend is picked once, at the top
//! ([`with_backend`]); everything below is generic over [`Accel`] and monomorphised.
#[forbid(unsafe_code)]
mod brute;
#[forbid(unsafe_code)]
mod bvh;
// One of the two places the `embree` feature appears (the other is `with_backend`).
#[cfg(feature = "embree")]
pub mod embree;

pub use brute::BruteForce;
pub use bvh::BvhAccel;

use crate::Result;
use crate::geometry::{Hit, Ray};
use glam::Vec3A;

/// A ray-tracing backend over a scene's triangles (in the scene's order).
pub trait Accel: Sync {
    /// Short name, written into image metadata.
    fn name(&self) -> &'static str;

    /// The closest hit along `ray` with `t ∈ (0, ∞)`. Invalid rays (NaN/inf) hit nothing.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// Whether anything lies along `ray` with `t ∈ (0, t_max)`. Invalid rays are unoccluded.
    fn occluded(&self, ray: &Ray, t_max: f32) -> bool;

    /// Closest hits for a batch of rays (the packet hook: backends with packet traversal
    /// override it).
    fn intersect_batch(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (r, h) in rays.iter().zip(hits.iter_mut()) {
            *h = self.intersect(r);
        }
    }

    /// Occlusion for a batch of rays with their own `t_max`.
    fn occluded_batch(&self, rays: &[Ray], t_max: &[f32], out: &mut [bool]) {
        for ((r, &t), o) in rays.iter().zip(t_max).zip(out.iter_mut()) {
            *o = self.occluded(r, t);
        }
    }
}

/// The user's backend choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendKind {
    /// Pure-Rust compressed wide BVH (obvhs).
    Bvh,
    /// Intel Embree (build with `--features embree`).
    Embree,
    /// Embree when compiled in, otherwise bvh.
    Auto,
}

/// Whether this build has the Embree backend.
pub const EMBREE_AVAILABLE: bool = cfg!(feature = "embree");

impl BackendKind {
    /// The backend this choice builds in this build (`auto` resolved).
    #[must_use]
    pub fn resolved_name(self) -> &'static str {
        match self {
            BackendKind::Bvh => "bvh",
            BackendKind::Embree => "embree",
            BackendKind::Auto if EMBREE_AVAILABLE => "embree",
            BackendKind::Auto => "bvh",
        }
    }

    /// Fails with a clear message when the backend is not compiled into this build.
    pub fn check_available(self) -> Result<()> {
        if self == BackendKind::Embree && !EMBREE_AVAILABLE {
            return Err(crate::Error::Backend(
                "the embree backend is not compiled in: rebuild with `cargo build --release --features embree`".into(),
            ));
        }
        Ok(())
    }
}

/// Code that runs once a backend is built: the generic entry point below the dispatch.
pub trait WithAccel {
    type Output;
    fn run<A: Accel>(self, accel: &A) -> Self::Output;
}

/// Builds the chosen backend over a scene's triangles (`Scene::triangles`) and runs `job`
/// with it: the one place where the backend is chosen at run time.
pub fn with_backend<J: WithAccel>(kind: BackendKind, triangles: &[[Vec3A; 3]], job: J) -> Result<J::Output> {
    with_backend_timed(kind, triangles, job).map(|(out, _)| out)
}

/// [`with_backend`], also returning the seconds the acceleration structure took to build.
pub fn with_backend_timed<J: WithAccel>(
    kind: BackendKind,
    triangles: &[[Vec3A; 3]],
    job: J,
) -> Result<(J::Output, f64)> {
    kind.check_available()?;
    let start = std::time::Instant::now();
    #[cfg(feature = "embree")]
    if matches!(kind, BackendKind::Embree | BackendKind::Auto) {
        let accel = embree::EmbreeAccel::build(triangles)?;
        let built = start.elapsed().as_secs_f64();
        return Ok((job.run(&accel), built));
    }
    let accel = BvhAccel::build(triangles);
    let built = start.elapsed().as_secs_f64();
    Ok((job.run(&accel), built))
}
