//! What the photon-guided integrators share: the photon map and guide cache built in the
//! pre-pass, the per-vertex query (`L̃r`, `L̃1` and the `GL` grid from one lookup), sampling a
//! direction from the grid, and ZVIDPT's termination probability.
use super::Scatter;
use super::mixture::sample_mixture;
use crate::Result;
use crate::accel::Accel;
use crate::geometry::{Frame, Vec3A, luminance};
use crate::photon::grid::{grid_pdf, sample_cdf, weights_to_cdf};
use crate::photon::{FluxDensity, GridShape, GuideCache, GuidePhotons, MAX_GUIDE_CELLS, PhotonMap};
use crate::sampler::SampleStream;
use crate::scene::{Scene, SurfaceInteraction};
use std::f32::consts::FRAC_1_PI;
use std::time::Instant;

/// Photon map and guide parameters (ALGORITHM.md §2, §4; paper values as defaults).
#[derive(Clone, Debug)]
pub struct GuideSettings {
    /// Photons to store (paper: 6,891).
    pub photons: usize,
    /// Photons per radiance estimate (paper: N = 50).
    pub knn: usize,
    /// The `GL` grid (paper: 4×16).
    pub grid: GridShape,
    /// Photons shaping the grid.
    pub which: GuidePhotons,
    /// Precompute records (true) or query the photon map at every vertex (false).
    pub cache: bool,
    /// `ε_L`: every grid cell is floored at this fraction of the mean cell. Flooring is a
    /// defensive mixture: the grid's pdf is `(g + ε·mean)/Σ(...)`, i.e. `1/(1+ε)` of the photon
    /// grid plus `ε/(1+ε)` of cosine sampling, so `f·cosθ/pdf ≤ (1 + 1/ε)·ρ`. ALGORITHM.md §2
    /// marks 0.1 as our choice; on cornell-paper (64 spp, 3 seeds, solid-angle NEE) ε = 0.1
    /// gave MSE 0.55–0.77 for zvidpt-terminal and 0.52–0.97 for jensen, ε = 1 gave 0.15–0.17 and
    /// 0.12, ε = 2 about the same, ε = 4 slightly worse: rare directions into cells the k
    /// nearest photons missed carried weights up to 11ρ at ε = 0.1. Default 1.
    pub floor: f32,
    /// Most records the cache holds.
    pub max_records: usize,
}

impl Default for GuideSettings {
    fn default() -> Self {
        Self {
            photons: 6891,
            knn: 50,
            grid: GridShape { rows: 4, cols: 16 },
            which: GuidePhotons::Indirect,
            cache: true,
            floor: 1.0,
            max_records: 1 << 16,
        }
    }
}

/// Pre-pass measurements, for the summary line and the closing figures.
#[derive(Clone, Copy, Debug, Default)]
pub struct PrepassReport {
    /// Photons stored.
    pub photons: usize,
    /// Photon paths emitted.
    pub emitted: u64,
    /// Seconds of photon tracing.
    pub photon_seconds: f64,
    /// Guide records built.
    pub records: usize,
    /// The records' k-nearest queries and grids.
    pub knn_seconds: f64,
    /// The voxel table that finds a record for any point.
    pub table_seconds: f64,
}

impl std::fmt::Display for PrepassReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} photons from {} paths in {:.3} s", self.photons, self.emitted, self.photon_seconds)?;
        if self.records > 0 {
            write!(
                f,
                ", {} guide records in {:.3} s ({:.0} k kNN queries/s) + voxel table {:.3} s",
                self.records,
                self.knn_seconds,
                self.records as f64 / self.knn_seconds.max(1e-9) / 1e3,
                self.table_seconds
            )?;
        }
        Ok(())
    }
}

/// The photon map and the guide records built from it: the approximate radiance field the
/// photon-guided integrators sample directions from.
pub struct PhotonGuide {
    /// What the guide was built with.
    pub settings: GuideSettings,
    /// The photons.
    pub map: PhotonMap,
    cache: Option<GuideCache>,
    /// The grid used where nothing is known: uniform, i.e. cosine sampling.
    uniform_cdf: Vec<f32>,
    /// What the pre-pass measured.
    pub report: PrepassReport,
}

/// `L̃r`-side estimates and the grid to sample at one vertex.
pub struct VertexGuide<'a> {
    /// The photons' flux density near the vertex, for the `L̃r` estimates.
    pub density: FluxDensity,
    /// The cumulative distribution of the grid to sample directions from.
    pub cdf: &'a [f32],
}

impl PhotonGuide {
    /// Traces the photons of `settings` (seeded by `seed`) and builds the guide records.
    pub fn build<A: Accel>(scene: &Scene, accel: &A, settings: &GuideSettings, seed: u64) -> Result<PhotonGuide> {
        let t = Instant::now();
        let map = PhotonMap::build(scene, accel, settings.photons, seed)?;
        let photon_seconds = t.elapsed().as_secs_f64();
        let cache = settings.cache.then(|| {
            GuideCache::build(&map, settings.grid, settings.knn, settings.which, settings.floor, settings.max_records)
        });
        let report = PrepassReport {
            photons: map.len(),
            emitted: map.emitted,
            photon_seconds,
            records: cache.as_ref().map_or(0, |c| c.len()),
            knn_seconds: cache.as_ref().map_or(0.0, |c| c.seconds.0),
            table_seconds: cache.as_ref().map_or(0.0, |c| c.seconds.1),
        };
        let mut uniform_cdf = vec![0.0; settings.grid.cells()];
        weights_to_cdf(&mut uniform_cdf, 0.0);
        debug_assert!(settings.grid.cells() <= MAX_GUIDE_CELLS);
        Ok(PhotonGuide { settings: settings.clone(), map, cache, uniform_cdf, report })
    }

    /// The estimates and grid at `si`: from a nearby cache record, or from a k-nearest query
    /// built into `grid` (per-tile scratch, sized once) when the cache is off. With no
    /// information the grid is uniform (cosine sampling) and the densities are zero.
    #[inline]
    pub fn at<'a>(&'a self, si: &SurfaceInteraction, frame: &Frame, grid: &'a mut Vec<f32>) -> VertexGuide<'a> {
        if let Some(cache) = &self.cache {
            return match cache.lookup(si.p, si.n) {
                Some(r) => VertexGuide { density: r.density, cdf: r.cdf },
                None => VertexGuide { density: FluxDensity::default(), cdf: &self.uniform_cdf },
            };
        }
        let w = grid;
        w.clear();
        w.resize(self.settings.grid.cells(), 0.0);
        let density = self.map.gather(
            si.p,
            si.n,
            self.settings.knn,
            Some((frame, self.settings.grid, self.settings.which, &mut *w)),
        );
        weights_to_cdf(w, self.settings.floor);
        VertexGuide { density, cdf: w }
    }

    /// Flux density only (for the pixel grid), same source as [`PhotonGuide::at`].
    #[inline]
    pub fn density_at(&self, si: &SurfaceInteraction) -> FluxDensity {
        match &self.cache {
            Some(cache) => cache.lookup(si.p, si.n).map_or_else(FluxDensity::default, |r| r.density),
            None => self.map.gather(si.p, si.n, self.settings.knn, None),
        }
    }

    /// Samples a world direction from the vertex's grid; returns it with `f·cosθ/pdf`, which
    /// for a Lambertian surface is `ρ / (Pc·|GL|)`.
    #[inline]
    pub fn sample_direction(
        &self,
        g: &VertexGuide,
        frame: &Frame,
        albedo: Vec3A,
        rng: &mut SampleStream,
    ) -> (Vec3A, Vec3A) {
        let u_cell = rng.next_f32();
        let (local, pc_cells) = sample_cdf(self.settings.grid, g.cdf, u_cell, rng.next_2d());
        (frame.to_world(local), albedo / pc_cells)
    }

    /// A direction at `si` for any material: the grid on a Lambertian surface (`grid_frame`
    /// around `si.n`), else [`sample_mixture`] of the BSDF (`frame`, `wi` local) and the grid.
    #[inline]
    pub fn scatter(
        &self,
        g: &VertexGuide,
        si: &SurfaceInteraction,
        grid_frame: &Frame,
        frame: &Frame,
        wi: Vec3A,
        rng: &mut SampleStream,
    ) -> Option<Scatter> {
        if let Some(albedo) = si.material.lambertian() {
            let (dir, weight) = self.sample_direction(g, grid_frame, albedo, rng);
            let weight = if si.shaded { weight * si.shading_ratio(dir, dir.dot(si.n)) } else { weight };
            return Some(Scatter { dir, weight, pdf: 0.0, delta: false });
        }
        let shape = self.settings.grid;
        sample_mixture(
            si,
            frame,
            wi,
            grid_frame,
            rng,
            |rng| {
                let u_cell = rng.next_f32();
                sample_cdf(shape, g.cdf, u_cell, rng.next_2d()).0
            },
            |w| grid_pdf(shape, g.cdf, w),
        )
    }
}

/// `L̃ = ρ/π ⊙ density` (Lambertian).
#[inline]
#[must_use]
pub fn radiance_estimate(albedo: Vec3A, density: Vec3A) -> Vec3A {
    albedo * density * FRAC_1_PI
}

/// ZVIDPT's termination probability `q = clamp(lum(L̃1)/lum(L̃r), q_min, q_max)`, 0.5 where
/// `L̃r = 0` (ALGORITHM.md §2). `q_max < 1` keeps the indirect term, so no bias.
///
/// `kappa` generalises it to `q = L̃1 / (L̃1 + κ·L̃ind)` (κ = 1: ALGORITHM.md's). Terminating
/// with probability q costs `L1²/q + E[S²]/(1−q)` in second moment, S being the rest of the
/// walk's estimate of `Lind`; that is smallest at `q = L1/(L1 + √E[S²])`, which is
/// ALGORITHM.md's q only when S is exact. κ > 1 stands for the rest of the walk's noise.
#[inline]
#[must_use]
pub fn termination_probability(albedo: Vec3A, d: &FluxDensity, q_min: f32, q_max: f32, kappa: f32) -> f32 {
    let lr = luminance(albedo * d.all);
    let l1 = luminance(albedo * d.direct);
    if lr > 0.0 { (l1 / (l1 + kappa * (lr - l1).max(0.0))).clamp(q_min, q_max) } else { 0.5 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn termination_probability_follows_its_definition() {
        let d = |direct: f32, all: f32| FluxDensity { all: Vec3A::splat(all), direct: Vec3A::splat(direct) };
        let white = Vec3A::ONE;
        // κ = 1: ALGORITHM.md's L̃1/L̃r, clamped to [q_min, q_max]; 0.5 without light.
        assert!((termination_probability(white, &d(3.0, 4.0), 0.05, 0.95, 1.0) - 0.75).abs() < 1e-6);
        assert_eq!(termination_probability(white, &d(4.0, 4.0), 0.05, 0.95, 1.0), 0.95);
        assert_eq!(termination_probability(white, &d(0.0, 4.0), 0.05, 0.95, 1.0), 0.05);
        assert_eq!(termination_probability(white, &d(0.0, 0.0), 0.05, 0.95, 1.0), 0.5);
        // κ = 3: L1/(L1 + 3·Lind) = 3/(3 + 3) = 0.5.
        assert!((termination_probability(white, &d(3.0, 4.0), 0.05, 0.95, 3.0) - 0.5).abs() < 1e-6);
    }
}
