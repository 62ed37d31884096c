//! The guide cache (ALGORITHM.md §2, "Cost per vertex"): radiance estimates and floored guide
//! grids precomputed once, after the photon pass, at records placed on photon positions. A walk
//! vertex uses a nearby record whose normal points the same way, found by one read of a dense
//! voxel table (per normal orientation) that maps every voxel to the record nearest to it,
//! instead of a k-nearest query plus a grid build. Estimators stay unbiased: the weights use the
//! pdf of the grid actually sampled and the `q` actually used.
//!
//! The table first held kd-tree (kiddo) `nearest_one` lookups: they took 56% of a
//! zvidpt-terminal render's time on `cornell-paper`; the voxel read is a few nanoseconds.
use super::grid::{GridShape, MAX_GUIDE_CELLS, weights_to_cdf};
use super::{FluxDensity, GuidePhotons, PhotonMap};
use crate::geometry::{Frame, Vec3A};
use rayon::prelude::*;
use std::collections::VecDeque;

/// Records are kept apart by the dominant axis and sign of their normal, so that a lookup
/// never returns a record from the other side of a wall or from a perpendicular wall at a
/// corner.
pub(crate) const BUCKETS: usize = 6;

#[inline]
pub(crate) fn bucket_of(n: Vec3A) -> usize {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    axis * 2 + (n[axis] < 0.0) as usize
}

/// What a walk vertex reads from the cache.
#[derive(Clone, Copy, Debug)]
pub struct GuideRecord<'a> {
    pub density: FluxDensity,
    /// CDF over the guide grid's cells (floored; uniform where no photon guided).
    pub cdf: &'a [f32],
}

/// Voxels along the longest side of the bounds of the records.
const VOXELS_LONGEST_SIDE: f32 = 64.0;
const NO_RECORD: u32 = u32::MAX;

pub struct GuideCache {
    shape: GridShape,
    /// Voxel table: `min`, voxel size, dimensions; one record index per voxel and bucket.
    min: Vec3A,
    inv_voxel: f32,
    dims: [u32; 3],
    voxels: Vec<u32>,
    density: Vec<FluxDensity>,
    cdf: Vec<f32>,
    /// Seconds spent on the records' k-nearest queries and grids, and on the voxel table.
    pub seconds: (f64, f64),
}

impl GuideCache {
    /// Builds records at up to `max_records` photons (every photon when the map is smaller,
    /// evenly strided otherwise), each from one k-nearest query.
    #[must_use]
    pub fn build(
        map: &PhotonMap,
        shape: GridShape,
        k: usize,
        which: GuidePhotons,
        floor: f32,
        max_records: usize,
    ) -> Self {
        let start = std::time::Instant::now();
        let stride = map.len().div_ceil(max_records.max(1)).max(1);
        let sites: Vec<usize> = (0..map.len()).step_by(stride).collect();
        let cells = shape.cells();
        let built: Vec<(FluxDensity, Vec<f32>)> = sites
            .par_iter()
            .map(|&i| {
                let (p, n) = (map.position(i), map.normal[i]);
                let mut w = vec![0.0f32; cells];
                let d = map.gather(p, n, k, Some((&Frame::from_normal(n), shape, which, &mut w)));
                weights_to_cdf(&mut w, floor);
                (d, w)
            })
            .collect();
        let knn_seconds = start.elapsed().as_secs_f64();
        let start = std::time::Instant::now();
        // Voxel table over the records' bounds (a small margin so every vertex near a record
        // maps inside), each voxel holding the record nearest to it in voxel steps: records
        // are splatted into their voxels, then a breadth-first flood fills the rest.
        let (mut lo, mut hi) = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
        for &i in &sites {
            lo = lo.min(map.position(i));
            hi = hi.max(map.position(i));
        }
        let extent = (hi - lo).max_element().max(1e-3);
        let voxel = extent / VOXELS_LONGEST_SIDE;
        let min = lo - Vec3A::splat(voxel);
        let dims = ((hi - min) / voxel).to_array().map(|d| (d.ceil() as u32 + 2).max(1));
        let per_bucket = dims.iter().map(|&d| d as usize).product::<usize>();
        let mut voxels = if sites.is_empty() { Vec::new() } else { vec![NO_RECORD; per_bucket * BUCKETS] };
        let mut cache = Self {
            shape,
            min,
            inv_voxel: 1.0 / voxel,
            dims,
            voxels: Vec::new(),
            density: Vec::new(),
            cdf: Vec::new(),
            seconds: (knn_seconds, 0.0),
        };
        if !sites.is_empty() {
            for b in 0..BUCKETS {
                let table = &mut voxels[b * per_bucket..(b + 1) * per_bucket];
                let mut best = vec![f32::INFINITY; per_bucket];
                let mut queue = VecDeque::new();
                for (r, &i) in sites.iter().enumerate() {
                    if bucket_of(map.normal[i]) != b {
                        continue;
                    }
                    let p = map.position(i);
                    let v = cache.voxel_of(p);
                    let centre = min + (Vec3A::from(cache.voxel_coords(p).map(|c| c as f32)) + 0.5) * voxel;
                    let d = p.distance_squared(centre);
                    if d < best[v] {
                        if table[v] == NO_RECORD {
                            queue.push_back(v);
                        }
                        best[v] = d;
                        table[v] = r as u32;
                    }
                }
                flood_fill(table, dims, &mut queue);
            }
        }
        cache.voxels = voxels;
        cache.seconds.1 = start.elapsed().as_secs_f64();
        cache.density = built.iter().map(|(d, _)| *d).collect();
        cache.cdf = built.into_iter().flat_map(|(_, w)| w).collect();
        debug_assert!(cells <= MAX_GUIDE_CELLS);
        cache
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.density.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.density.is_empty()
    }

    #[inline]
    fn voxel_coords(&self, x: Vec3A) -> [u32; 3] {
        let c = ((x - self.min) * self.inv_voxel).to_array();
        [0, 1, 2].map(|k| (c[k].max(0.0) as u32).min(self.dims[k] - 1))
    }

    #[inline]
    fn voxel_of(&self, x: Vec3A) -> usize {
        let [i, j, k] = self.voxel_coords(x);
        ((k * self.dims[1] + j) * self.dims[0] + i) as usize
    }

    /// A record near `x` among those whose normal points like `n` (the one nearest to `x`'s
    /// voxel), or `None` when no record has that orientation.
    #[inline]
    #[must_use]
    pub fn lookup(&self, x: Vec3A, n: Vec3A) -> Option<GuideRecord<'_>> {
        if self.voxels.is_empty() {
            return None;
        }
        let per_bucket = self.voxels.len() / BUCKETS;
        let r = self.voxels[bucket_of(n) * per_bucket + self.voxel_of(x)];
        if r == NO_RECORD {
            return None;
        }
        let (r, cells) = (r as usize, self.shape.cells());
        Some(GuideRecord { density: self.density[r], cdf: &self.cdf[r * cells..(r + 1) * cells] })
    }
}

/// Breadth-first flood from the voxels in `queue`: each empty voxel takes the record of the
/// voxel it was first reached from (6-neighbourhood), so it holds a record a few voxels away
/// at most, the nearest in steps. Deterministic: the queue starts in record order.
fn flood_fill(table: &mut [u32], dims: [u32; 3], queue: &mut VecDeque<usize>) {
    let (nx, ny, nz) = (dims[0] as usize, dims[1] as usize, dims[2] as usize);
    while let Some(v) = queue.pop_front() {
        let (i, j, k) = (v % nx, (v / nx) % ny, v / (nx * ny));
        let r = table[v];
        let mut visit = |w: usize| {
            if table[w] == NO_RECORD {
                table[w] = r;
                queue.push_back(w);
            }
        };
        if i > 0 {
            visit(v - 1);
        }
        if i + 1 < nx {
            visit(v + 1);
        }
        if j > 0 {
            visit(v - nx);
        }
        if j + 1 < ny {
            visit(v + nx);
        }
        if k > 0 {
            visit(v - nx * ny);
        }
        if k + 1 < nz {
            visit(v + nx * ny);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::BvhAccel;
    use crate::scene::Scene;

    /// A lookup at a record's own site returns a record of the same orientation whose
    /// estimate is that site's, or a neighbour's within the kNN noise; never a miss.
    #[test]
    fn lookups_find_nearby_records() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
        let accel = BvhAccel::build(&scene.triangles);
        let map = PhotonMap::build(&scene, &accel, 4000, 2).unwrap();
        let shape = GridShape { rows: 4, cols: 16 };
        let cache = GuideCache::build(&map, shape, 50, GuidePhotons::Indirect, 0.1, 1 << 16);
        assert_eq!(cache.len(), map.len());
        let (mut exact, mut total) = (0, 0);
        for i in (0..map.len()).step_by(7) {
            let (p, n) = (map.position(i), map.normal[i]);
            let r = cache.lookup(p, n).expect("a record of this orientation exists");
            let own = map.gather(p, n, 50, None);
            exact += (r.density == own) as usize;
            total += 1;
            assert_eq!(r.cdf.len(), shape.cells());
            assert!((r.cdf[shape.cells() - 1] - 1.0).abs() < 1e-6);
        }
        // Several records can share a voxel (photons crowd the ceiling above the light); the
        // one nearest the voxel's centre is kept: 24% of sites read their own record here.
        assert!(exact * 6 >= total, "only {exact} of {total} lookups returned the site's own record");
        // An orientation with no records (the open front: normal +z inside the box has
        // records on the back wall; -z has none) misses.
        assert!(cache.lookup(Vec3A::new(0.0, 0.0, 0.5), -Vec3A::Z).is_none());
    }

    #[test]
    fn buckets_split_axes_and_sides() {
        assert_eq!(bucket_of(Vec3A::X), 0);
        assert_eq!(bucket_of(-Vec3A::X), 1);
        assert_eq!(bucket_of(Vec3A::Y), 2);
        assert_eq!(bucket_of(-Vec3A::Z), 5);
        assert_eq!(bucket_of(Vec3A::new(0.1, -0.9, 0.3).normalize()), 3);
    }
}
