//! Adaptive quadtrees over the unit square (the D-tree of Müller et al. 2017, *Practical Path
//! Guiding*): each tree splits the square into quadrants where the learned energy is, so the
//! directions a surface point receives its light from are resolved finely (a bright patch
//! across the room) and the rest coarsely. The guide maps directions to the square by the
//! cosine warp of the shading frame ([`crate::geometry::warp::cosine_hemisphere`]), so a
//! uniform tree is exactly cosine sampling and a learned one samples `f·cos·L` (the cosine is
//! in the map); PPG's world-space sphere map instead wastes samples below a curved surface's
//! horizon and cannot follow the cosine of each point of a cell.
//!
//! All trees of a guide live in one flat node array (`Forest`). A tree being *filled* has
//! a fixed-point accumulator per leaf quadrant (kept apart by each worker and summed after
//! the pass, so the sums are the same bits in any order: integer addition is associative);
//! a *frozen* tree holds each quadrant's energy as `f32` for sampling and its pdf.
use crate::geometry::Vec2;

/// Deepest level a quadrant may reach (a leaf of depth 12 spans 1/4096 of the square's side,
/// about 0.05° of azimuth: finer than any light here needs, and within `f32`'s precision
/// when one uniform number is rescaled level by level).
pub const MAX_DEPTH: u32 = 12;

/// Fixed-point scale of the accumulators: deposits are rounded to multiples of 2⁻²⁰.
const FIXED_SCALE: f64 = (1u64 << 20) as f64;
/// Largest single deposit (a cap on *learning* data only: it shapes the guide, never the
/// weights an estimator uses, so it cannot bias an image). Keeps any sum of up to 2³² deposits
/// below `u64::MAX`.
pub const MAX_DEPOSIT: f64 = 4.0e6;

/// Rounds a non-negative value to fixed point (non-finite or negative values count as 0).
#[inline]
#[must_use]
pub fn to_fixed(v: f64) -> u64 {
    if v > 0.0 { (v.min(MAX_DEPOSIT) * FIXED_SCALE + 0.5) as u64 } else { 0 }
}

#[inline]
#[must_use]
pub fn from_fixed(v: u64) -> f64 {
    v as f64 / FIXED_SCALE
}

/// Quadrant of `p` in a node: bit 0 is `u ≥ ½`, bit 1 is `v ≥ ½`; `p` rescaled into it.
#[inline]
fn descend(p: Vec2) -> (usize, Vec2) {
    let (hx, hy) = (p.x >= 0.5, p.y >= 0.5);
    let q = hx as usize | (hy as usize) << 1;
    let r = Vec2::new(if hx { p.x * 2.0 - 1.0 } else { p.x * 2.0 }, if hy { p.y * 2.0 - 1.0 } else { p.y * 2.0 });
    (q, r.clamp(Vec2::ZERO, Vec2::splat(1.0 - f32::EPSILON)))
}

/// One node: four quadrants, each a child node or (index 0) a leaf.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Node {
    pub child: [u32; 4],
    /// Energy of each quadrant (frozen trees; zero in trees being filled).
    pub energy: [f32; 4],
    /// Deposits that fell in each quadrant (frozen trees): a quadrant is refined only where
    /// enough samples say its energy is really there.
    pub samples: [u32; 4],
}

impl Node {
    #[inline]
    fn total(&self) -> f32 {
        self.energy.iter().sum()
    }
}

/// Many trees in one node array; tree `t` starts at node `roots[t]`. Node 0 is always some
/// tree's root, so a child index of 0 can mean "leaf".
#[derive(Clone, Debug, Default)]
pub struct Forest {
    pub nodes: Vec<Node>,
    pub roots: Vec<u32>,
}

impl Forest {
    /// `trees` single-node trees (every quadrant a leaf).
    #[must_use]
    pub fn flat(trees: usize) -> Self {
        Self { nodes: vec![Node::default(); trees], roots: (0..trees as u32).collect() }
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.roots.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.roots.is_empty()
    }

    /// Bytes held (reported as the guide's memory).
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>() + self.roots.len() * 4
    }

    /// Node and quadrant of the leaf that holds point `p` of the square in tree `t`.
    #[inline]
    #[must_use]
    pub fn leaf_of(&self, t: usize, mut p: Vec2) -> (usize, usize) {
        let mut node = self.roots[t] as usize;
        for _ in 0..=MAX_DEPTH {
            let (q, r) = descend(p);
            let c = self.nodes[node].child[q];
            if c == 0 {
                return (node, q);
            }
            node = c as usize;
            p = r;
        }
        unreachable!("trees are at most MAX_DEPTH deep")
    }

    /// Total energy of tree `t` (frozen trees).
    #[inline]
    #[must_use]
    pub fn total(&self, t: usize) -> f32 {
        self.nodes[self.roots[t] as usize].total()
    }

    /// Density (over the unit square) of tree `t`'s distribution at `p`; 0 for a tree
    /// without energy.
    #[inline]
    #[must_use]
    pub fn pdf(&self, t: usize, mut p: Vec2) -> f32 {
        let mut node = &self.nodes[self.roots[t] as usize];
        let mut density = 1.0;
        for _ in 0..=MAX_DEPTH {
            let total = node.total();
            if total <= 0.0 {
                return 0.0;
            }
            let (q, r) = descend(p);
            density *= 4.0 * node.energy[q] / total;
            let c = node.child[q];
            if c == 0 || density == 0.0 {
                return density;
            }
            node = &self.nodes[c as usize];
            p = r;
        }
        density
    }

    /// Samples tree `t` (which must have energy): a point of the square and its density.
    /// A quadrant is picked by `u.x` between the halves `v < ½` and `v ≥ ½`, then by `u.y`
    /// between `u < ½` and `u ≥ ½` within the half, each number rescaled and reused below.
    #[inline]
    #[must_use]
    pub fn sample(&self, t: usize, mut u: Vec2) -> (Vec2, f32) {
        let mut node = &self.nodes[self.roots[t] as usize];
        let (mut origin, mut size) = (Vec2::ZERO, 1.0f32);
        let mut density = 1.0;
        let one = 1.0 - f32::EPSILON;
        for _ in 0..=MAX_DEPTH {
            let e = node.energy;
            let total = e[0] + e[1] + e[2] + e[3];
            let low_v = e[0] + e[1];
            // Halves in v (bit 1), then in u (bit 0).
            let hy = if u.x * total < low_v {
                u.x = (u.x * total / low_v).min(one);
                0
            } else {
                u.x = ((u.x * total - low_v) / (total - low_v)).clamp(0.0, one);
                1
            };
            let (a, b) = (e[hy << 1], e[(hy << 1) | 1]);
            let hx = if u.y * (a + b) < a {
                u.y = (u.y * (a + b) / a).min(one);
                0
            } else {
                u.y = ((u.y * (a + b) - a) / b).clamp(0.0, one);
                1
            };
            let q = hx | hy << 1;
            density *= 4.0 * e[q] / total;
            size *= 0.5;
            origin += Vec2::new(hx as f32, hy as f32) * size;
            let c = node.child[q];
            if c == 0 {
                break;
            }
            node = &self.nodes[c as usize];
        }
        // `u` is now uniform in the leaf quadrant. (Rounding may put a point on the leaf's far
        // edge, i.e. in its neighbour, about once in 10⁴ samples at depth 12: callers that need
        // the density of a point evaluate [`Self::pdf`].)
        ((origin + u * size).min(Vec2::splat(1.0 - f32::EPSILON)), density)
    }

    /// Fills `energy` and `samples` of every node of tree `t` from the leaf accumulators:
    /// energy at `acc[8·node + 2q]`, deposit count at `acc[8·node + 2q + 1]`.
    pub fn freeze_tree(&mut self, t: usize, acc: &[u64]) {
        self.freeze_tree_blended(t, acc, 0.0);
    }

    /// As [`Self::freeze_tree`], blending in the prior that [`Self::refine_into`] left in the
    /// tree's quadrants (the previous tree's energy over each quadrant's region). Both are
    /// normalised per deposit, then averaged with weights `deposits` and `carry · prior
    /// deposits`: with `carry` = 1 the tree is learned from every iteration's deposits alike,
    /// in whatever units the prior was (photon flux for the seed).
    pub fn freeze_tree_blended(&mut self, t: usize, acc: &[u64], carry: f32) {
        fn fill(nodes: &mut [Node], acc: &[u64], n: usize, blend: Option<(f32, f32)>) -> (f32, u32) {
            let (mut total, mut count) = (0.0, 0u32);
            for q in 0..4 {
                let c = nodes[n].child[q] as usize;
                let (e, k) = if c == 0 {
                    let k = acc[8 * n + 2 * q + 1].min(u32::MAX as u64) as u32;
                    let e = from_fixed(acc[8 * n + 2 * q]) as f32;
                    match blend {
                        // (energy scale, deposit weight) of the prior.
                        Some((scale, weight)) => {
                            let (pe, pk) = (nodes[n].energy[q], nodes[n].samples[q]);
                            (e + scale * pe, k.saturating_add((weight * pk as f32) as u32))
                        }
                        None => (e, k),
                    }
                } else {
                    fill(nodes, acc, c, blend)
                };
                nodes[n].energy[q] = e;
                nodes[n].samples[q] = k;
                total += e;
                count = count.saturating_add(k);
            }
            (total, count)
        }
        let root = self.roots[t] as usize;
        let prior = (self.nodes[root].total(), self.nodes[root].samples.iter().map(|&k| k as u64).sum::<u64>());
        let blend = if carry > 0.0 && prior.0 > 0.0 && prior.1 > 0 {
            // This iteration's own totals (a dry pass over the accumulators).
            let (mut energy, mut count) = (0.0f64, 0u64);
            let mut stack = vec![root];
            while let Some(n) = stack.pop() {
                for q in 0..4 {
                    match self.nodes[n].child[q] {
                        0 => {
                            energy += from_fixed(acc[8 * n + 2 * q]);
                            count += acc[8 * n + 2 * q + 1];
                        }
                        c => stack.push(c as usize),
                    }
                }
            }
            (energy > 0.0 && count > 0).then(|| {
                // Prior energy per prior deposit → this iteration's energy per deposit.
                let scale = carry as f64 * (energy / count as f64) / (prior.0 as f64 / prior.1 as f64);
                (scale as f32, carry)
            })
        } else {
            None
        };
        fill(&mut self.nodes, acc, root, blend);
    }

    /// Appends to `out` a refined copy of frozen tree `t` of `self`: a quadrant holding more
    /// than `threshold` of the tree's energy and at least `min_samples` deposits is split (a
    /// leaf's energy and deposits are assumed spread evenly over its four children), one
    /// holding less is merged back into a leaf. Each quadrant of the copy keeps the old tree's
    /// energy and deposits over its region (the prior [`Self::freeze_tree_blended`] may blend
    /// in). Returns the new root index.
    pub fn refine_into(&self, t: usize, threshold: f32, min_samples: u32, out: &mut Forest) -> u32 {
        let total = self.total(t);
        let root = out.nodes.len() as u32;
        out.nodes.push(Node::default());
        if total > 0.0 {
            let limit = threshold * total;
            let old_root = &self.nodes[self.roots[t] as usize];
            // (new node, old node if any, its quadrants' energy and deposits, depth)
            type Pending = (u32, Option<usize>, [f32; 4], [u32; 4], u32);
            let mut stack: Vec<Pending> =
                vec![(root, Some(self.roots[t] as usize), old_root.energy, old_root.samples, 1)];
            while let Some((new, old, energy, samples, depth)) = stack.pop() {
                out.nodes[new as usize].energy = energy;
                out.nodes[new as usize].samples = samples;
                for q in 0..4 {
                    if energy[q] <= limit || samples[q] < min_samples || depth >= MAX_DEPTH {
                        continue;
                    }
                    let old_child = old.map(|o| self.nodes[o].child[q]).filter(|&c| c != 0).map(|c| c as usize);
                    let (child_energy, child_samples) = match old_child {
                        Some(c) => (self.nodes[c].energy, self.nodes[c].samples),
                        None => ([energy[q] * 0.25; 4], [samples[q] / 4; 4]),
                    };
                    let c = out.nodes.len() as u32;
                    out.nodes.push(Node::default());
                    out.nodes[new as usize].child[q] = c;
                    stack.push((c, old_child, child_energy, child_samples, depth + 1));
                }
            }
        }
        out.roots.push(root);
        root
    }

    /// A refined copy of every tree, in order ([`Self::refine_into`]).
    #[must_use]
    pub fn refined(&self, threshold: f32, min_samples: u32) -> Forest {
        let mut forest = Forest::default();
        for t in 0..self.len() {
            self.refine_into(t, threshold, min_samples, &mut forest);
        }
        forest
    }

    /// Appends a copy of tree `t` of `self` (topology and energies) to `out`.
    pub fn copy_into(&self, t: usize, out: &mut Forest) -> u32 {
        let base = out.nodes.len() as u32;
        let mut order = vec![self.roots[t] as usize];
        let mut i = 0;
        // Breadth-first numbering, children renumbered relative to `base`.
        while i < order.len() {
            let n = order[i];
            for q in 0..4 {
                let c = self.nodes[n].child[q];
                if c != 0 {
                    order.push(c as usize);
                }
            }
            i += 1;
        }
        let mut next = 1u32;
        for &n in &order {
            let mut node = self.nodes[n];
            for q in 0..4 {
                if node.child[q] != 0 {
                    node.child[q] = base + next;
                    next += 1;
                }
            }
            out.nodes.push(node);
        }
        out.roots.push(base);
        base
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{Domain, SampleStream};

    /// Learns a tree from deposits ∝ a known density over three rounds of refinement; the
    /// frozen tree's samples follow its own pdf (chi-square over 64 bins), the pdf integrates
    /// to 1 and concentrates where the target does.
    #[test]
    fn sampled_points_follow_the_pdf() {
        let mut forest = Forest::flat(1);
        let mut rng = SampleStream::in_domain(Domain::Photon, 7, 0, 0);
        let target = |p: Vec2| 0.05 + (-((p - Vec2::new(0.3, 0.7)).length_squared()) * 400.0).exp() * 50.0;
        for round in 0..4 {
            let mut acc = vec![0u64; 8 * forest.nodes.len()];
            for _ in 0..20000 {
                let p = rng.next_2d();
                let (n, q) = forest.leaf_of(0, p);
                acc[8 * n + 2 * q] += to_fixed(target(p) as f64);
                acc[8 * n + 2 * q + 1] += 1;
            }
            forest.freeze_tree(0, &acc);
            if round < 3 {
                let mut next = Forest::default();
                forest.refine_into(0, 0.01, 8, &mut next);
                forest = next;
            }
        }
        assert!(forest.nodes.len() > 20, "tree refined: {} nodes", forest.nodes.len());
        let n = 1024;
        let mut integral = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                integral += forest.pdf(0, Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32)) as f64;
            }
        }
        integral /= (n * n) as f64;
        assert!((integral - 1.0).abs() < 1e-3, "integral {integral}");
        let bins = 8;
        let samples = 200_000;
        let mut observed = vec![0f64; bins * bins];
        let mut mismatched = 0;
        for _ in 0..samples {
            let (p, pdf) = forest.sample(0, rng.next_2d());
            if (pdf - forest.pdf(0, p)).abs() > 1e-4 * pdf {
                mismatched += 1;
            }
            observed[(p.x * bins as f32) as usize * bins + (p.y * bins as f32) as usize] += 1.0;
        }
        assert!(mismatched < samples / 1000, "{mismatched} samples' density differs from pdf()");
        let m = 128;
        let mut expected = vec![0f64; bins * bins];
        for i in 0..bins * m {
            for j in 0..bins * m {
                let p = Vec2::new((i as f32 + 0.5) / (bins * m) as f32, (j as f32 + 0.5) / (bins * m) as f32);
                expected[(i / m) * bins + j / m] +=
                    forest.pdf(0, p) as f64 / ((bins * m) * (bins * m)) as f64 * samples as f64;
            }
        }
        let chi2: f64 =
            observed.iter().zip(&expected).filter(|(_, e)| **e > 5.0).map(|(o, e)| (o - e) * (o - e) / e).sum();
        // At most 63 degrees of freedom: the 1e-4 quantile is about 112.
        assert!(chi2 < 112.0, "chi2 {chi2}");
        assert!(forest.pdf(0, Vec2::new(0.3, 0.7)) > 20.0 * forest.pdf(0, Vec2::new(0.8, 0.2)));
    }

    #[test]
    fn copy_keeps_topology_and_energy() {
        let mut forest = Forest::flat(2);
        let mut acc = vec![0u64; 16];
        acc[8] += to_fixed(3.0);
        acc[9] += 1000;
        acc[14] += to_fixed(1.0);
        acc[15] += 1000;
        forest.freeze_tree(1, &acc);
        let mut refined = Forest::default();
        forest.refine_into(1, 0.01, 8, &mut refined);
        // Quadrants 0 and 3 hold energy: both split (down to the depth limit for quadrant 0).
        assert!(refined.nodes.len() > 2);
        let mut out = Forest::flat(1);
        let r = forest.copy_into(1, &mut out);
        assert_eq!(out.total(1), forest.total(1));
        assert_eq!(out.nodes[r as usize].energy, forest.nodes[1].energy);
        assert_eq!(out.pdf(1, Vec2::new(0.1, 0.1)), 3.0);
    }

    /// Blending: a refined tree keeps the old energy over each quadrant as its prior; freezing
    /// with `carry` averages the old and new shapes by deposits × carry (units cancel).
    #[test]
    fn carry_blends_shapes_by_deposits() {
        let mut old = Forest::flat(1);
        let mut acc = vec![0u64; 8];
        // Old: all energy in quadrant 0 (100 units over 100 deposits).
        acc[0] += to_fixed(100.0);
        acc[1] += 100;
        old.freeze_tree(0, &acc);
        // A threshold above 1 keeps one node; quadrant 0's prior is the old energy.
        let mut new = Forest::default();
        old.refine_into(0, 2.0, 1, &mut new);
        assert_eq!(new.nodes[0].energy, [100.0, 0.0, 0.0, 0.0]);
        // New: all energy in quadrant 3, 1 unit per deposit over 300 deposits.
        let mut acc = vec![0u64; 8];
        acc[6] += to_fixed(300.0);
        acc[7] += 300;
        let mut blended = new.clone();
        blended.freeze_tree_blended(0, &acc, 0.5);
        // Shapes weighted 300 : 0.5·100 → quadrant 0 holds 50/350 of the density.
        let p0 = blended.pdf(0, Vec2::new(0.25, 0.25));
        assert!((p0 - 4.0 * 50.0 / 350.0).abs() < 1e-4, "{p0}");
        assert_eq!(blended.nodes[0].samples, [50, 0, 0, 300]);
        // Without carry the prior is dropped.
        new.freeze_tree(0, &acc);
        assert_eq!(new.pdf(0, Vec2::new(0.25, 0.25)), 0.0);
    }
}
