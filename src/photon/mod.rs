//! The first pass (ALGORITHM.md §4): photons traced from the emitters and stored at every
//! diffuse hit, in a kd-tree (kiddo) over positions with the payload kept apart
//! (structure of arrays), and the radiance estimates and guide grids built from them.
pub(crate) mod cache;
pub mod grid;

pub use cache::{GuideCache, GuideRecord};
pub use grid::{GridShape, MAX_GUIDE_CELLS};

use crate::accel::Accel;
use crate::geometry::{Frame, Vec3A, luminance, warp};
use crate::sampler::survival_probability;
use crate::sampler::{Domain, SampleStream};
use crate::scene::Scene;
use crate::{Error, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::f32::consts::PI;
use std::num::NonZeroUsize;

/// Most photons a map may hold (about 100 bytes each with the kd-tree and guide records: a
/// few GB at most).
pub const MAX_PHOTONS: usize = 1 << 25;

/// Photon paths traced per parallel batch; the map keeps whole paths, in path order.
const PATHS_PER_BATCH: u64 = 4096;

/// Photons whose stored normal disagrees with the query normal by more than this are skipped,
/// so light does not leak through thin walls (ALGORITHM.md §4).
const NORMAL_AGREEMENT: f32 = 0.5;

/// Which photons shape the guide grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GuidePhotons {
    /// Photons that bounced at least once: the walk's target `f·cos·Lr(y)` (ours).
    Indirect,
    /// All photons (the paper's and Jensen's choice).
    All,
}

/// Stored photons, structure of arrays: positions live in the kd-tree, the payload apart.
pub struct PhotonMap {
    tree: Option<ImmutableKdTree<f32, 3>>,
    positions: Vec<Vec3A>,
    /// RGB flux, already divided by the number of emitted paths.
    pub flux: Vec<Vec3A>,
    /// Unit direction the photon arrived from (pointing away from the surface).
    pub incoming: Vec<Vec3A>,
    /// Surface normal on the side the photon arrived at.
    pub normal: Vec<Vec3A>,
    /// Diffuse reflections before this hit (0: straight from an emitter).
    pub bounce: Vec<u8>,
    /// Reflectance of the surface the photon landed on.
    pub albedo: Vec<Vec3A>,
    /// Photon paths emitted.
    pub emitted: u64,
}

/// One radiance-estimate query's result: flux densities `ΣΦ/(πr²)` of all and of direct
/// (bounce-0) photons that agree with the normal. `L̃r = ρ/π · all`, `L̃1 = ρ/π · direct`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FluxDensity {
    pub all: Vec3A,
    pub direct: Vec3A,
}

/// Caustic photons: photons that landed on a Lambertian surface straight from a specular
/// vertex (a delta lobe, or one too narrow to guide: glass, a mirror), where the light came
/// from a point that next event estimation cannot see through.
#[derive(Debug, Default)]
pub struct Caustics {
    /// Where each landed.
    pub position: Vec<Vec3A>,
    /// The surface normal on the side it arrived at.
    pub normal: Vec<Vec3A>,
    /// RGB flux, divided by the number of emitted paths.
    pub flux: Vec<Vec3A>,
    /// The specular vertex it came from (the caustic's exit point).
    pub from: Vec<Vec3A>,
    /// Photon paths emitted.
    pub emitted: u64,
}

impl Caustics {
    /// Traces photon paths (as [`PhotonMap::build`], from their own random streams) until
    /// `target` caustic photons are kept or `max_paths` paths were emitted; none where no
    /// material of the scene is specular. Deterministic whatever the thread count.
    pub fn trace<A: Accel>(scene: &Scene, accel: &A, target: usize, max_paths: u64, seed: u64) -> Caustics {
        let mut c = Caustics::default();
        let specular = scene.materials.iter().any(|m| !m.bsdf.is_guidable());
        if !specular || target == 0 || !scene.lights.has_emitters() {
            return c;
        }
        // Streams apart from the photon map's (which index its paths from 0).
        const FIRST: u64 = 1 << 48;
        while c.emitted < max_paths && c.position.len() < target {
            let batch: Vec<Vec<Photon>> = (c.emitted..c.emitted + PATHS_PER_BATCH)
                .into_par_iter()
                .map(|i| trace_photon_path(scene, accel, seed, FIRST + i))
                .collect();
            for path in batch {
                c.emitted += 1;
                for p in path {
                    if let Some(y) = p.caustic_from {
                        c.position.push(p.p);
                        c.normal.push(p.normal);
                        c.flux.push(p.flux);
                        c.from.push(y);
                    }
                }
                if c.position.len() >= target || c.emitted >= max_paths {
                    break;
                }
            }
        }
        let scale = 1.0 / c.emitted.max(1) as f32;
        for f in &mut c.flux {
            *f *= scale;
        }
        c
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.position.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }
}

struct Photon {
    p: Vec3A,
    flux: Vec3A,
    incoming: Vec3A,
    normal: Vec3A,
    bounce: u8,
    albedo: Vec3A,
    /// On a Lambertian surface, the previous vertex where it was specular.
    caustic_from: Option<Vec3A>,
}

impl PhotonMap {
    /// Traces photon paths until at least `target` photons are stored (whole paths are kept,
    /// so a few more may be). Deterministic: path `i` draws from its own random stream, and
    /// paths are kept in index order whatever the thread count.
    pub fn build<A: Accel>(scene: &Scene, accel: &A, target: usize, seed: u64) -> Result<PhotonMap> {
        if target > MAX_PHOTONS {
            return Err(crate::Error::InvalidOption(format!("at most {MAX_PHOTONS} photons, asked for {target}")));
        }
        let mut photons: Vec<Photon> = Vec::with_capacity(target + 64);
        let mut emitted = 0u64;
        // A scene whose photons all escape would never fill the map: give up after many paths.
        let max_paths = 1000 * target as u64 + 1_000_000;
        if scene.lights.has_emitters() && target > 0 {
            'batches: while emitted < max_paths {
                let batch: Vec<Vec<Photon>> = (emitted..emitted + PATHS_PER_BATCH)
                    .into_par_iter()
                    .map(|i| trace_photon_path(scene, accel, seed, i))
                    .collect();
                for path in batch {
                    emitted += 1;
                    photons.extend(path);
                    if photons.len() >= target {
                        break 'batches;
                    }
                }
            }
        }
        let scale = if emitted > 0 { 1.0 / emitted as f32 } else { 0.0 };
        let positions: Vec<Vec3A> = photons.iter().map(|p| p.p).collect();
        let tree = if positions.is_empty() {
            None
        } else {
            let points: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
            Some(
                ImmutableKdTree::new_from_slice(&points)
                    .map_err(|e| Error::InvalidOption(format!("photon map: {e:?}")))?,
            )
        };
        Ok(PhotonMap {
            tree,
            positions,
            flux: photons.iter().map(|p| p.flux * scale).collect(),
            incoming: photons.iter().map(|p| p.incoming).collect(),
            normal: photons.iter().map(|p| p.normal).collect(),
            bounce: photons.iter().map(|p| p.bounce).collect(),
            albedo: photons.iter().map(|p| p.albedo).collect(),
            emitted,
        })
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    #[must_use]
    pub fn position(&self, i: usize) -> Vec3A {
        self.positions[i]
    }

    /// The `k` photons nearest to `x` (indices) and the squared distance to the farthest.
    /// Allocates: for pre-passes, never per walk vertex.
    #[must_use]
    pub fn nearest(&self, x: Vec3A, k: usize) -> (Vec<usize>, f32) {
        let (Some(tree), Some(k)) = (&self.tree, NonZeroUsize::new(k)) else {
            return (Vec::new(), 0.0);
        };
        let near = tree.query(&x.to_array()).nearest_n::<SquaredEuclidean<f32>>(k).execute();
        let r2 = near.last().map_or(0.0, |r| r.distance);
        (near.iter().map(|r| r.item as usize).collect(), r2)
    }

    /// One k-nearest query at `x` (shading normal `n`) gives the flux densities and, when
    /// `grid` is given, fills it with `lum(Φp)` per cell of each guiding photon's incoming
    /// direction in `frame` (the Lambertian `f` is constant and cancels on normalising).
    pub fn gather(
        &self,
        x: Vec3A,
        n: Vec3A,
        k: usize,
        grid: Option<(&Frame, GridShape, GuidePhotons, &mut [f32])>,
    ) -> FluxDensity {
        let (Some(tree), Some(k)) = (&self.tree, NonZeroUsize::new(k)) else {
            return FluxDensity::default();
        };
        let near = tree.query(&x.to_array()).nearest_n::<SquaredEuclidean<f32>>(k).execute();
        let Some(r2) = near.last().map(|r| r.distance) else {
            return FluxDensity::default();
        };
        let mut d = FluxDensity::default();
        let mut grid = grid;
        for r in &near {
            let i = r.item as usize;
            if self.normal[i].dot(n) < NORMAL_AGREEMENT {
                continue;
            }
            d.all += self.flux[i];
            if self.bounce[i] == 0 {
                d.direct += self.flux[i];
            }
            if let Some((frame, shape, which, cells)) = grid.as_mut() {
                let local = frame.to_local(self.incoming[i]);
                if local.z > 0.0 && (*which == GuidePhotons::All || self.bounce[i] > 0) {
                    cells[shape.cell_of(local)] += luminance(self.flux[i]);
                }
            }
        }
        if r2 > 0.0 {
            let inv_area = 1.0 / (PI * r2);
            d.all *= inv_area;
            d.direct *= inv_area;
        } else {
            // k photons on one point: no area to spread them over; treat as no information.
            d = FluxDensity::default();
        }
        d
    }
}

/// Traces photon path `index` from [`crate::light::LightSet::emit_photon`] (a light by power; on a surface a
/// uniform point and a cosine direction, flux `π·Le/pdf_area`; divided by the path count
/// later); stored at every
/// hit that is not pure delta; continued by Russian roulette on the albedo, in the BSDF's
/// sampled direction (cosine on a Lambertian surface).
fn trace_photon_path<A: Accel>(scene: &Scene, accel: &A, seed: u64, index: u64) -> Vec<Photon> {
    let mut rng = SampleStream::in_domain(Domain::Photon, seed, index, 0);
    let mut out = Vec::new();
    let (u_pick, u_point) = (rng.next_f32(), rng.next_2d());
    let Some((mut ray, mut flux)) = scene.lights.emit_photon(u_pick, u_point, rng.next_2d()) else {
        return out;
    };
    let mut bounce = 0u8;
    // The last vertex, where it was specular.
    let mut specular: Option<Vec3A> = None;
    while let Some(hit) = accel.intersect(&ray) {
        let si = scene.interaction(&ray, &hit);
        let albedo = si.material.albedo();
        if albedo == Vec3A::ZERO {
            break;
        }
        // No photon where a delta lobe is all there is: nothing could gather it.
        if !si.material.bsdf.is_delta() {
            let caustic_from = if si.material.lambertian().is_some() { specular } else { None };
            out.push(Photon { p: si.p, flux, incoming: si.wo, normal: si.n, bounce, albedo, caustic_from });
        }
        specular = (!si.material.bsdf.is_guidable()).then_some(si.p);
        let q = survival_probability(albedo);
        if rng.next_f32() >= q {
            break;
        }
        let wi = if let Some(rho) = si.material.lambertian() {
            flux *= rho / q;
            Frame::from_normal(si.n).to_world(warp::cosine_hemisphere(rng.next_2d()))
        } else {
            // The BSDF's sampling, from the side the photon arrived on (photons only shape the
            // guide, so the adjoint's 1/η² asymmetry at refraction is not tracked).
            let frame = si.bsdf_frame();
            let u_lobe = rng.next_f32();
            let Some(s) = si.material.bsdf.sample(frame.to_local(si.wo), u_lobe, rng.next_2d()) else {
                break;
            };
            flux *= s.weight / q;
            frame.to_world(s.wo)
        };
        ray = si.spawn_ray(wi);
        bounce = bounce.saturating_add(1);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::BvhAccel;

    fn cornell() -> Scene {
        Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap()
    }

    #[test]
    fn deterministic_whatever_the_thread_count() {
        let scene = cornell();
        let accel = BvhAccel::build(&scene.triangles);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let a = one.install(|| PhotonMap::build(&scene, &accel, 5000, 3).unwrap());
        let b = two.install(|| PhotonMap::build(&scene, &accel, 5000, 3).unwrap());
        assert!(a.len() >= 5000 && a.len() == b.len() && a.emitted == b.emitted);
        assert!(a.positions == b.positions && a.flux == b.flux && a.bounce == b.bounce);
    }

    /// Photons carry the scene's power: the flux arriving straight from the emitter (bounce
    /// 0) sums to the emitted power times the fraction of photons that hit something — all of
    /// them in the closed furnace, so the sum is π·A·Le there (z-bound 5 on the estimate).
    #[test]
    fn direct_photons_carry_the_emitted_power() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/furnace")).unwrap();
        let accel = BvhAccel::build(&scene.triangles);
        let map = PhotonMap::build(&scene, &accel, 20_000, 1).unwrap();
        let direct: Vec3A = (0..map.len()).filter(|&i| map.bounce[i] == 0).map(|i| map.flux[i]).sum();
        let power = scene.lights.emitted_power();
        // Every path stores exactly one bounce-0 photon here, each of equal flux: exact.
        assert!(((direct - power).length() / power.length()) < 1e-3, "{direct} vs {power}");
        // Irradiance estimate inside the furnace: E = π·L_incident = π·1 everywhere, so the
        // flux density of all photons is ≈ π (photon-map bias is small in the smooth furnace).
        let d = map.gather(Vec3A::new(0.0, 0.0, -0.99), Vec3A::Z, 200, None);
        assert!((d.all.x / PI - 1.0).abs() < 0.15, "flux density {}", d.all);
    }

    /// Caustic photons of `cornell-materials` come from its glass sphere (centre (0.1, −0.65,
    /// 0.4), radius 0.35), its only specular surface, and land on Lambertian surfaces; the
    /// same photons at any thread count; none in `cornell-paper`, which has no specular
    /// surface.
    #[test]
    fn caustic_photons_leave_the_glass_sphere() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-materials")).unwrap();
        let accel = BvhAccel::build(&scene.triangles);
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let a = one.install(|| Caustics::trace(&scene, &accel, 2000, 1_000_000, 5));
        let b = two.install(|| Caustics::trace(&scene, &accel, 2000, 1_000_000, 5));
        assert!(a.len() >= 2000 && a.len() == b.len() && a.emitted == b.emitted);
        assert!(a.position == b.position && a.flux == b.flux && a.from == b.from);
        let centre = Vec3A::new(0.1, -0.65, 0.4);
        for (i, y) in a.from.iter().enumerate() {
            // The sphere is tessellated: its facets lie within a percent of its radius.
            assert!(((*y - centre).length() - 0.35).abs() < 0.01, "photon {i} left from {y}");
            assert!(a.flux[i].min_element() >= 0.0 && a.flux[i].max_element() > 0.0);
        }
        // Most land on the floor (y = −1) below and around the sphere.
        let floor = a.position.iter().filter(|p| p.y < -0.99).count();
        assert!(floor * 2 > a.len(), "{floor} of {} on the floor", a.len());
        let paper = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
        let accel = BvhAccel::build(&paper.triangles);
        let none = Caustics::trace(&paper, &accel, 2000, 1_000_000, 5);
        assert!(none.is_empty() && none.emitted == 0);
    }
}
