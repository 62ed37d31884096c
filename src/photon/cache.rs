//! The guide cache (ALGORITHM.md §2, "Cost per vertex"): radiance estimates and floored guide
//! grids precomputed once, after the photon pass, at records placed on photon positions. A walk
//! vertex uses the nearest record whose normal points the same way, found with one
//! nearest-neighbour query and no allocation, instead of a k-nearest query plus a grid build.
//! Estimators stay unbiased: the weights use the pdf of the grid actually sampled and the `q`
//! actually used.
use super::guide::{GridShape, MAX_GUIDE_CELLS, weights_to_cdf};
use super::{FluxDensity, GuidePhotons, PhotonMap};
use crate::geometry::{Frame, Vec3A};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// Records are kept apart by the dominant axis and sign of their normal, so that a lookup
/// never returns a record from the other side of a wall or from a perpendicular wall at a
/// corner.
const BUCKETS: usize = 6;

#[inline]
fn bucket_of(n: Vec3A) -> usize {
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

pub struct GuideCache {
    shape: GridShape,
    trees: Vec<Option<ImmutableKdTree<f32, 3>>>,
    /// Record index of each tree item, per bucket.
    record_of: Vec<Vec<u32>>,
    density: Vec<FluxDensity>,
    cdf: Vec<f32>,
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
        let mut points: Vec<Vec<[f32; 3]>> = vec![Vec::new(); BUCKETS];
        let mut record_of: Vec<Vec<u32>> = vec![Vec::new(); BUCKETS];
        for (r, &i) in sites.iter().enumerate() {
            let b = bucket_of(map.normal[i]);
            points[b].push(map.position(i).to_array());
            record_of[b].push(r as u32);
        }
        let trees =
            points.iter().map(|p| if p.is_empty() { None } else { ImmutableKdTree::new_from_slice(p).ok() }).collect();
        let density = built.iter().map(|(d, _)| *d).collect();
        let cdf = built.into_iter().flat_map(|(_, w)| w).collect();
        debug_assert!(cells <= MAX_GUIDE_CELLS);
        Self { shape, trees, record_of, density, cdf }
    }

    #[must_use]
    pub fn shape(&self) -> GridShape {
        self.shape
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.density.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.density.is_empty()
    }

    /// The nearest record at `x` among those whose normal points like `n`.
    #[inline]
    #[must_use]
    pub fn lookup(&self, x: Vec3A, n: Vec3A) -> Option<GuideRecord<'_>> {
        let b = bucket_of(n);
        let tree = self.trees[b].as_ref()?;
        let near = tree.query(&x.to_array()).nearest_one::<SquaredEuclidean<f32>>().execute();
        let r = self.record_of[b][near.item as usize] as usize;
        let cells = self.shape.cells();
        Some(GuideRecord { density: self.density[r], cdf: &self.cdf[r * cells..(r + 1) * cells] })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_split_axes_and_sides() {
        assert_eq!(bucket_of(Vec3A::X), 0);
        assert_eq!(bucket_of(-Vec3A::X), 1);
        assert_eq!(bucket_of(Vec3A::Y), 2);
        assert_eq!(bucket_of(-Vec3A::Z), 5);
        assert_eq!(bucket_of(Vec3A::new(0.1, -0.9, 0.3).normalize()), 3);
    }
}
