//! The learned directional density of the `zvidpt` integrator in scenes with participating
//! media: a spatial binary tree over the scene's bounds per kind of point (in a medium; on a
//! surface, per bucket of its normal, so the sides of a wall never share a cell), a leaf being
//! a *cell*, split in halves of its longest side where walks scattered often (as Müller et
//! al. 2017 split their SD-tree). Each cell holds a quadtree over the whole sphere of
//! directions (the cylindrical equal-area map, [`warp::uniform_sphere`]: a uniform tree is
//! uniform sampling) of the in-scattered light times the phase function, `Li·p`, or on a
//! Lambertian surface `Li·cos`, and its probability of being sampled.
//!
//! A medium point has no normal, so the surface guide's cells and cosine-warped hemispheres
//! do not apply there. Where light reaches a medium only through specular surfaces (a
//! volumetric caustic under a glass sphere), neither the phase function nor NEE finds it;
//! the learned tree does, after a few iterations, and the walk's one-sample mixture with the
//! phase function keeps every direction's density positive. Deposits are fixed-point
//! integers summed per worker and then over workers, as the surface guide's: what is learned
//! is bit-identical whatever the thread count.
use super::quadtree::{Forest, to_fixed};
use super::{MIN_LEAF_SAMPLES, MIN_TREE_SAMPLES, SPLIT_THRESHOLD};
use crate::geometry::{Vec2, Vec3A, warp};
use crate::photon::cache::{BUCKETS, bucket_of};
use std::f32::consts::PI;

/// The tree-sampling probabilities a cell chooses from by the second moments its directions
/// would have had under each (as the surface guide's cells do): 0 where the phase function or
/// the BSDF alone samples best (a cell lit directly, which NEE already covers).
pub const VOLUME_MIX_CANDIDATES: [f32; 4] = [0.0, 0.25, 0.5, 0.75];
const CANDIDATES: usize = VOLUME_MIX_CANDIDATES.len();
/// Directions a cell needs in an iteration before it changes its probability.
const MIN_MIX_SAMPLES: u64 = 64;
/// Roots of the spatial tree: medium points, then surface points by normal bucket.
const ROOTS: usize = 1 + BUCKETS;
/// Most cells a volume guide may have.
pub const MAX_VOLUME_CELLS: usize = 1 << 16;
/// Deepest spatial split (halvings of the scene's bounding cube along one axis).
const MAX_VOLUME_DEPTH: u32 = 48;

/// A node of the spatial tree: a leaf holds its cell; an inner node's children are at
/// `child` (below the middle of `axis`) and `child + 1`.
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3A,
    hi: Vec3A,
    child: u32,
    axis: u8,
    depth: u8,
    cell: u32,
}

/// The learned directions at medium points (see the module's text).
#[derive(Clone, Debug)]
pub struct VolumeGuide {
    nodes: Vec<Node>,
    /// The trees walks sample (frozen), one per cell.
    trees: Forest,
    /// The trees being filled during an iteration: the frozen ones, refined.
    filling: Option<Forest>,
    /// Probability of sampling a cell's tree where it has one (the rest: the phase function
    /// or the BSDF): each cell's, learned from its second moments ([`VOLUME_MIX_CANDIDATES`]).
    mix: Vec<f32>,
    /// Samples a cell must receive in the first iteration to be split (× √2 per iteration).
    pub split_samples: u64,
}

/// One worker's deposits during an iteration: per leaf quadrant of the filling trees its
/// energy and count (as [`super::Deposits`]), and per cell its scattering points.
#[derive(Clone, Debug, Default)]
pub struct VolumeDeposits {
    acc: Vec<u64>,
    counts: Vec<u64>,
    /// Per cell, per candidate of [`VOLUME_MIX_CANDIDATES`]: the estimated second moment of a
    /// direction's weight had the cell sampled its tree with that probability (fixed point).
    moments: Vec<[u64; CANDIDATES]>,
}

impl VolumeDeposits {
    /// The sum of two workers' deposits (integer sums: the same in any order).
    #[must_use]
    pub fn merge(mut self, other: Self) -> Self {
        if self.acc.is_empty() && self.counts.is_empty() {
            return other;
        }
        for (x, y) in self.acc.iter_mut().zip(&other.acc) {
            *x = x.wrapping_add(*y);
        }
        for (x, y) in self.counts.iter_mut().zip(&other.counts) {
            *x = x.wrapping_add(*y);
        }
        // Saturating sums (a candidate that cannot draw some direction reads u64::MAX): still
        // the same in any order.
        for (a, b) in self.moments.iter_mut().zip(&other.moments) {
            for (x, y) in a.iter_mut().zip(b) {
                *x = x.saturating_add(*y);
            }
        }
        self
    }
}

impl VolumeGuide {
    /// One cell over the cube around the scene's bounding sphere `(centre, radius)`, with a
    /// tree that learned nothing (walks sample the phase function until it has).
    #[must_use]
    pub fn new(bounds: (Vec3A, f32), mix: f32, split_samples: u64) -> Self {
        let (centre, radius) = bounds;
        let r = Vec3A::splat(radius.max(1e-6) * 1.001);
        // One root per kind of point: in a medium, then on a surface per normal bucket.
        let nodes = (0..ROOTS)
            .map(|k| Node { lo: centre - r, hi: centre + r, child: 0, axis: 0, depth: 0, cell: k as u32 })
            .collect();
        Self {
            nodes,
            trees: Forest::flat(ROOTS),
            filling: None,
            mix: vec![mix; ROOTS],
            split_samples: split_samples.max(1),
        }
    }

    /// Cells (leaves of the spatial tree).
    #[must_use]
    pub fn cells(&self) -> usize {
        self.trees.len()
    }

    /// How many cells sample their tree with each probability of [`VOLUME_MIX_CANDIDATES`]
    /// (cells that learned no tree left out).
    #[must_use]
    pub fn mix_histogram(&self) -> [usize; CANDIDATES] {
        let mut h = [0; CANDIDATES];
        for (c, &a) in self.mix.iter().enumerate() {
            if self.trees.total(c) > 0.0
                && let Some(k) = VOLUME_MIX_CANDIDATES.iter().position(|&x| x == a)
            {
                h[k] += 1;
            }
        }
        h
    }

    /// Bytes held by the trees and the spatial tree.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.trees.bytes() + self.nodes.len() * std::mem::size_of::<Node>()
    }

    /// The cell holding medium point `x` (points outside the bounds go to the nearest cell).
    #[inline]
    #[must_use]
    pub fn cell(&self, x: Vec3A) -> usize {
        self.cell_under(0, x)
    }

    /// The cell holding surface point `x` with shading normal `n` (surfaces facing apart never
    /// share a cell, nor do surfaces and media).
    #[inline]
    #[must_use]
    pub fn surface_cell(&self, x: Vec3A, n: Vec3A) -> usize {
        self.cell_under(1 + bucket_of(n), x)
    }

    #[inline]
    fn cell_under(&self, root: usize, x: Vec3A) -> usize {
        let mut node = &self.nodes[root];
        while node.child != 0 {
            let a = usize::from(node.axis);
            let mid = 0.5 * (node.lo[a] + node.hi[a]);
            node = &self.nodes[(node.child + u32::from(x[a] >= mid)) as usize];
        }
        node.cell as usize
    }

    /// The probability of sampling `cell`'s tree: 0 where it learned nothing.
    #[inline]
    #[must_use]
    pub fn mix_at(&self, cell: usize) -> f32 {
        if self.trees.total(cell) > 0.0 { self.mix[cell] } else { 0.0 }
    }

    /// The learned density of unit direction `w` at `cell`, per steradian.
    #[inline]
    #[must_use]
    pub fn pdf(&self, cell: usize, w: Vec3A) -> f32 {
        self.trees.pdf(cell, warp::uniform_sphere_inverse(w)) * (0.25 / PI)
    }

    /// A unit direction from `cell`'s learned density (which must have energy, [`Self::mix_at`]
    /// above 0).
    #[inline]
    #[must_use]
    pub fn sample(&self, cell: usize, u: Vec2) -> Vec3A {
        warp::uniform_sphere(self.trees.sample(cell, u).0)
    }

    /// The density of `dir` under `cell`'s one-sample mixture: its tree with probability
    /// `alpha`, the rest a base strategy of density `base` there.
    #[inline]
    #[must_use]
    pub fn mixture_pdf(&self, cell: usize, alpha: f32, dir: Vec3A, base: f32) -> f32 {
        if alpha > 0.0 { alpha * self.pdf(cell, dir) + (1.0 - alpha) * base } else { base }
    }

    /// Starts a training iteration: deposits go to a copy of the frozen trees, refined where
    /// they hold energy.
    pub fn begin_iteration(&mut self) {
        self.filling = Some(self.trees.refined(SPLIT_THRESHOLD, MIN_LEAF_SAMPLES));
    }

    /// Empty accumulators for one worker (none outside an iteration).
    #[must_use]
    pub fn deposits(&self) -> VolumeDeposits {
        match &self.filling {
            Some(f) => VolumeDeposits {
                acc: vec![0; 8 * f.nodes.len()],
                counts: vec![0; self.cells()],
                moments: vec![[0; CANDIDATES]; self.cells()],
            },
            None => VolumeDeposits::default(),
        }
    }

    /// Records `value` (an estimate of `Li·p / pdf` along unit direction `w`, summed over
    /// channels) at `cell`: over each leaf of the square this sums to `∫Li·p`, so the tree's
    /// density becomes `Li·p`.
    #[inline]
    pub fn deposit(&self, d: &mut VolumeDeposits, cell: usize, w: Vec3A, value: f32) {
        if let Some(f) = &self.filling {
            let (node, q) = f.leaf_of(cell, warp::uniform_sphere_inverse(w));
            let i = 8 * node + 2 * q;
            if i + 1 < d.acc.len() && cell < d.counts.len() {
                d.acc[i] = d.acc[i].wrapping_add(to_fixed(f64::from(value)));
                d.acc[i + 1] += 1;
                d.counts[cell] += 1;
            }
        }
    }

    /// Records, for the choice of `cell`'s mixture probability, one direction whose integrand
    /// is `g` (`Li·p` or `Li·f·cos`, channels summed), drawn with density `drawn`, where the
    /// tree's density is `tree` and the phase function's or the BSDF's `base`: under
    /// probability `a` its second moment is estimated by `g² / (p_a · drawn)`.
    #[inline]
    pub fn deposit_moments(&self, d: &mut VolumeDeposits, cell: usize, g: f32, drawn: f32, tree: f32, base: f32) {
        if self.filling.is_none() || !(g > 0.0 && drawn > 0.0) || cell >= d.moments.len() {
            return;
        }
        let m = &mut d.moments[cell];
        for (k, a) in VOLUME_MIX_CANDIDATES.into_iter().enumerate() {
            let p = f64::from(a * tree + (1.0 - a) * base);
            if p > 0.0 {
                m[k] = m[k].saturating_add(to_fixed(f64::from(g) * f64::from(g) / (p * f64::from(drawn))));
            } else {
                m[k] = u64::MAX;
            }
        }
    }

    /// Ends iteration `k` (0 first): cells that received enough directions sample what they
    /// learned (the others keep their tree), and cells that received more than
    /// `split_samples·√(2^k)` scattering points are halved (each half starting from the
    /// tree of the whole), as often as that count allows, halving it each time.
    pub fn end_iteration(&mut self, k: u32, deposits: VolumeDeposits) -> crate::Result<()> {
        let Some(mut filling) = self.filling.take() else {
            return Ok(());
        };
        let cells = self.cells();
        let VolumeDeposits { acc, counts, moments } = deposits;
        if acc.len() != 8 * filling.nodes.len() || counts.len() != cells {
            return Err(crate::Error::InvalidOption("volume deposits of another training iteration".into()));
        }
        let mut learned = Forest::default();
        for (t, &n) in counts.iter().enumerate() {
            filling.freeze_tree(t, &acc);
            if n >= MIN_TREE_SAMPLES && filling.total(t) > 0.0 {
                filling.copy_into(t, &mut learned);
            } else {
                self.trees.copy_into(t, &mut learned);
            }
        }
        // Each cell's probability: the candidate of least estimated second moment, from enough
        // directions (a candidate that would miss a direction some sample took is out).
        for (cell, (m, &n)) in moments.iter().zip(&counts).enumerate() {
            if n >= MIN_MIX_SAMPLES
                && m.iter().any(|&x| x > 0)
                && let Some(best) = (0..CANDIDATES).min_by_key(|&k| m[k])
            {
                self.mix[cell] = VOLUME_MIX_CANDIDATES[best];
            }
        }
        // Spatial splits; `source[c]`: the learned tree cell `c` starts from.
        let limit = (self.split_samples as f64 * 2f64.powf(f64::from(k) * 0.5)) as u64;
        let mut source: Vec<usize> = (0..cells).collect();
        let mut stack: Vec<(usize, u64)> = (0..self.nodes.len())
            .filter(|&i| self.nodes[i].child == 0)
            .map(|i| (i, counts[self.nodes[i].cell as usize]))
            .collect();
        while let Some((i, n)) = stack.pop() {
            let node = self.nodes[i];
            if n <= limit || u32::from(node.depth) >= MAX_VOLUME_DEPTH || source.len() >= MAX_VOLUME_CELLS {
                continue;
            }
            let axis = (node.hi - node.lo)
                .to_array()
                .iter()
                .enumerate()
                .fold(0, |best, (a, &e)| if e > (node.hi - node.lo)[best] { a } else { best });
            let mid = 0.5 * (node.lo[axis] + node.hi[axis]);
            let (mut below_hi, mut above_lo) = (node.hi, node.lo);
            below_hi[axis] = mid;
            above_lo[axis] = mid;
            let child = self.nodes.len() as u32;
            let new_cell = source.len() as u32;
            source.push(source[node.cell as usize]);
            self.mix.push(self.mix[node.cell as usize]);
            let depth = node.depth + 1;
            self.nodes.push(Node { lo: node.lo, hi: below_hi, child: 0, axis: 0, depth, cell: node.cell });
            self.nodes.push(Node { lo: above_lo, hi: node.hi, child: 0, axis: 0, depth, cell: new_cell });
            self.nodes[i] = Node { child, axis: axis as u8, ..node };
            stack.push((child as usize, n / 2));
            stack.push((child as usize + 1, n / 2));
        }
        let mut trees = Forest::default();
        for &s in &source {
            learned.copy_into(s, &mut trees);
        }
        self.trees = trees;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;

    /// A cell's probability follows its second moments: where the integrand is the base
    /// density itself (base sampling is exact) the cell chooses 0, where it is the tree's
    /// (a light the phase function rarely finds) the highest candidate.
    #[test]
    fn cells_choose_the_mixture_of_least_second_moment() {
        for (integrand_is_tree, expected) in [(false, 0.0), (true, 0.75)] {
            let mut guide = VolumeGuide::new((Vec3A::ZERO, 1.0), 0.5, 1 << 40);
            guide.begin_iteration();
            let mut d = guide.deposits();
            // Directions drawn from the 0.5 mixture of a tree (density 8 on an eighth of the
            // sphere's square, 0 elsewhere) and a uniform base (density 1).
            let mut rng = SampleStream::new(9, 0, 0);
            for _ in 0..1000 {
                let in_tree = rng.next_f32() < 0.5 || rng.next_f32() < 0.125;
                let (tree, base) = (if in_tree { 8.0 } else { 0.0 }, 1.0);
                let drawn = 0.5 * tree + 0.5 * base;
                let g = if integrand_is_tree { tree } else { base };
                let w = warp::uniform_sphere(rng.next_2d());
                guide.deposit(&mut d, 0, w, g / drawn);
                guide.deposit_moments(&mut d, 0, g, drawn, tree, base);
            }
            guide.end_iteration(0, d).unwrap();
            assert_eq!(guide.mix[0], expected, "integrand is the tree's: {integrand_is_tree}");
        }
    }

    /// A guide trained on directions inside a cone learns to sample them: its density
    /// integrates to 1 over the sphere (midpoint rule), its samples fall in the cone far more
    /// often than uniform ones, and a busy cell is split in space.
    #[test]
    fn learns_a_cone_of_directions_and_splits_busy_cells() {
        let mut guide = VolumeGuide::new((Vec3A::ZERO, 1.0), 0.5, 1000);
        let axis = Vec3A::new(0.0, 0.6, 0.8);
        let mut rng = SampleStream::new(5, 0, 0);
        for k in 0..3 {
            guide.begin_iteration();
            let mut d = guide.deposits();
            for _ in 0..20_000 {
                let x = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let w = warp::uniform_sphere(rng.next_2d());
                let value = if w.dot(axis) > 0.95 { 1.0 } else { 0.0 };
                guide.deposit(&mut d, guide.cell(x), w, value * 4.0 * PI);
            }
            guide.end_iteration(k, d).unwrap();
        }
        assert!(guide.cells() > 1, "cells {}", guide.cells());
        let cell = guide.cell(Vec3A::splat(0.3));
        assert!(guide.mix_at(cell) > 0.0);
        let (n_mu, n_phi) = (400, 400);
        let mut integral = 0.0f64;
        for i in 0..n_mu {
            for j in 0..n_phi {
                let u = Vec2::new((i as f32 + 0.5) / n_mu as f32, (j as f32 + 0.5) / n_phi as f32);
                integral +=
                    f64::from(guide.pdf(cell, warp::uniform_sphere(u))) * 4.0 * f64::from(PI) / f64::from(n_mu * n_phi);
            }
        }
        assert!((integral - 1.0).abs() < 0.01, "integral {integral}");
        let inside = (0..10_000).filter(|_| guide.sample(cell, rng.next_2d()).dot(axis) > 0.95).count();
        // The cone is 2.5% of the sphere: at least ten times that share (43% here; a tree that
        // learned nothing puts 2.5% there).
        assert!(inside > 2_500, "{inside} of 10,000 samples in the cone");
    }
}
