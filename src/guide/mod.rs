//! The learned importance function of the `zvidpt` integrator: `L̃` learned from the render's
//! own walks, in the spirit of Müller et al. 2017 (*Practical Path Guiding*, an SD-tree) and
//! Open PGL.
//!
//! Space is a binary tree per orientation of the surface normal (six buckets, so the two
//! sides of a wall and the walls meeting at a corner never share a cell). A leaf is a *cell*;
//! a cell that received many samples in an iteration is split in two, along the axis its
//! samples spread most, at their mean — cells are small where walks go often and large where
//! they rarely go, so every cell learns from enough samples. Each cell holds
//! - a directional quadtree ([`quadtree::Forest`]) of `f·cos·Lr` arriving from every
//!   direction: the zero-variance target of the walk's transition (ALGORITHM.md §2, Eq. 7);
//! - per-channel estimates of the outgoing direct (`L̃1`) and indirect (`L̃ind`) radiance,
//!   which drive roulette and splitting.
//!
//! The photon map is the first estimate (the paper's first pass): the first tree is split by
//! photon positions, each cell's directions seeded from the indirect photons inside it and its
//! estimates from its nearest photons. Then each training iteration samples from the guide
//! frozen at the end of the previous one and deposits into a fresh copy whose quadtrees were
//! refined where the previous one found energy. Deposits are fixed-point integers, summed per
//! worker ([`Deposits`]) and then over workers: integer addition is associative, so what is
//! learned is bit-identical whatever the thread count and tile order.
pub mod quadtree;

use crate::geometry::{Frame, Vec2, Vec3A, warp};
use crate::photon::PhotonMap;
use crate::photon::cache::{BUCKETS, bucket_of};
use crate::scene::Scene;
use quadtree::{Forest, from_fixed, to_fixed};
use rayon::prelude::*;
use std::f32::consts::{FRAC_1_PI, PI};

/// A quadrant holding more than this fraction of its tree's energy is split (PPG's ρ is 0.01).
/// 0.02 on cornell-paper at 32 spp (seeds 1, 2): MSE×s 0.184 against 0.217 at 0.01 (0.005:
/// 0.249; 0.03: 0.184; 0.05: 0.191): finer trees fit the early iterations' noise. At equal
/// time (20 s, 256×192) cornell-blocks −19% MSE, cornell-classic −1%, partition +3%.
pub const SPLIT_THRESHOLD: f32 = 0.02;
/// The same for the photon seed's trees (measured with 0.01 there).
pub const SEED_SPLIT_THRESHOLD: f32 = 0.01;
/// Most cells a guide may have (memory bound: a cell with a full tree is a few kB).
pub const MAX_CELLS: usize = 1 << 18;
/// Deepest spatial split.
const MAX_SPATIAL_DEPTH: u32 = 40;
/// A cell replaces its tree only when it received at least this many directions in the
/// iteration (fewer give a spiky tree that is worse than the one it has).
const MIN_TREE_SAMPLES: u64 = 64;
/// A cell's learned estimates replace its photon seed once it has this many samples.
const MIN_SAMPLES: u64 = 16;
/// Photons per cell when the first tree is split by photon positions.
const PHOTONS_PER_CELL: u64 = 200;
/// Deposits a quadrant needs before it is refined (training; photon seed).
const MIN_LEAF_SAMPLES: u32 = 32;
const MIN_LEAF_PHOTONS: u32 = 8;

/// A cell's outgoing radiance estimates, per channel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CellEstimate {
    /// `L̃1`: reflected light that came straight from an emitter.
    pub direct: Vec3A,
    /// `L̃ind`: reflected light that bounced at least once.
    pub indirect: Vec3A,
    /// Averaged from walks' unbiased estimates (rather than a photon density estimate, which
    /// with few photons can be off by orders of magnitude).
    pub from_walks: bool,
}

/// What the guide holds, for reports.
#[derive(Clone, Copy, Debug, Default)]
pub struct GuideStats {
    pub cells: usize,
    pub nodes: usize,
    pub bytes: usize,
}

impl std::fmt::Display for GuideStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} cells, {} direction nodes, {:.1} MB", self.cells, self.nodes, self.bytes as f64 / 1e6)
    }
}

/// A node of a spatial tree: a leaf holds a cell, an inner node two children at `child`,
/// `child + 1` (below and above `split` along `axis`).
#[derive(Clone, Copy, Debug)]
struct SpatialNode {
    child: u32,
    axis: u8,
    split: f32,
    cell: u32,
    depth: u32,
}

/// Per cell and iteration: sample count, position sums and squares (fixed point, relative to
/// the scene's lower corner) — where the cell's samples are, to split it where they spread.
type Spread = [u64; 7];

/// What walks deposit during one training iteration, in fixed point: one worker's share, or
/// (after [`Deposits::merge`]) everyone's. Each worker fills its own, so deposits cost no
/// atomic operations (on `cornell-paper` atomics made a training sample about 20% dearer
/// than a final one), and the sums are the same bits however the work was split.
#[derive(Clone, Debug, Default)]
pub struct Deposits {
    /// Per quadrant of the trees being filled: energy at `8·node + 2q`, count at `+ 1`.
    acc: Vec<u64>,
    /// Per cell: direct RGB, indirect RGB, samples.
    sums: Vec<[u64; 7]>,
    spread: Vec<Spread>,
    /// Per cell: the second-moment estimates of [`MIX_CANDIDATES`].
    moments: Vec<[u64; MIX_CANDIDATES.len()]>,
}

impl Deposits {
    /// Adds `other` into `self` (wrapping, as fixed-point sums may).
    #[must_use]
    pub fn merge(mut self, other: Self) -> Self {
        fn add<const N: usize>(to: &mut [[u64; N]], from: &[[u64; N]]) {
            for (a, b) in to.iter_mut().zip(from) {
                for (x, y) in a.iter_mut().zip(b) {
                    *x = x.wrapping_add(*y);
                }
            }
        }
        if self.acc.is_empty() && self.sums.is_empty() {
            return other;
        }
        if other.acc.is_empty() && other.sums.is_empty() {
            return self;
        }
        for (x, y) in self.acc.iter_mut().zip(&other.acc) {
            *x = x.wrapping_add(*y);
        }
        add(&mut self.sums, &other.sums);
        add(&mut self.spread, &other.spread);
        add(&mut self.moments, &other.moments);
        self
    }
}

pub struct LearnedGuide {
    /// Scene bounds' lower corner (positions in the spread sums are relative to it).
    origin: Vec3A,
    nodes: Vec<SpatialNode>,
    roots: [u32; BUCKETS],
    /// The guide walks sample from (frozen), one tree per cell.
    trees: Forest,
    estimates: Vec<CellEstimate>,
    /// Whether a cell's estimates mean anything (photons or samples reached it).
    known: Vec<bool>,
    /// The trees being filled (during an iteration): the frozen ones, refined.
    filling: Option<Forest>,
    /// Per cell, summed over iterations: direct RGB, indirect RGB (fixed point), samples.
    sums: Vec<[u64; 7]>,
    /// Per cell: the probability of sampling its tree (the rest: cosine sampling), chosen by
    /// each iteration's estimates of the second moment of a direction's weight for each
    /// candidate in [`MIX_CANDIDATES`].
    mix: Vec<f32>,
    /// Whether the mixture probability is learned (or stays at its initial value).
    pub learn_mix: bool,
    /// Samples a cell must have received in an iteration to be split.
    pub split_samples: u64,
    /// Weight per deposit of the previous trees' data in each new tree (see
    /// [`Forest::freeze_tree_blended`]).
    pub carry: f32,
}

/// The tree-sampling probabilities a cell chooses from, by the second moment each would have
/// given this iteration's directions (one-sample MIS: a direction drawn with density `p` is
/// weighted `g/(α·p_tree + (1−α)·p_cos)`; its second moment under any `α` is estimated from
/// the same samples by `g²/(p_α·p)`). In the furnace, where cosine sampling is exact, cells
/// choose 0; where light comes from a small bright patch, 0.75 or 0.9. The last candidate is
/// open only to cells whose moments come from at least [`MIN_HIGH_MIX_SAMPLES`] directions:
/// with a guide learned from one training spp, cells that chose 0.9 left 10% to cosine
/// sampling and their samples were heavy-tailed, failing the path-reference z-test at 5.6 at
/// two seeds. Gated, it lowers cornell-paper's MSE at 32 spp by 5–10% (0.0173/0.0159 against
/// 0.0181/0.0177 at seeds 1/2).
pub const MIX_CANDIDATES: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 0.9];
/// Directions a cell needs in an iteration before it may choose the last (highest) candidate.
const MIN_HIGH_MIX_SAMPLES: u64 = 1024;
/// A cell changes its probability only when another candidate's estimated second moment is
/// below this fraction of its current one's, and from at least this many directions
/// (0.7 or 0.97 kept the furnace's cells at 0.5: their moments differ by a few percent, yet
/// cosine sampling's exactness there is worth 30× in variance).
const MIX_SWITCH_GAIN: f64 = 1.0;
const MIN_MIX_SAMPLES: u64 = 64;

impl LearnedGuide {
    /// The first guide, from the photon map: space split until a cell holds about
    /// [`PHOTONS_PER_CELL`] photons, directions from the indirect photons in each cell,
    /// estimates from the `knn` photons nearest each cell's photons' centre.
    pub fn seed(scene: &Scene, map: &PhotonMap, knn: usize) -> crate::Result<Self> {
        let (mut lo, mut hi) = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
        for t in &scene.triangles {
            for v in t {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
        if scene.triangles.is_empty() {
            (lo, hi) = (Vec3A::ZERO, Vec3A::ONE);
        }
        // Positions in the spread sums are taken relative to a corner just below the scene.
        let origin = lo - Vec3A::splat(1e-3 * (hi - lo).max_element().max(1e-3));
        let mut guide = Self {
            origin,
            nodes: Vec::new(),
            roots: [0; BUCKETS],
            trees: Forest::default(),
            estimates: Vec::new(),
            known: Vec::new(),
            filling: None,
            sums: Vec::new(),
            mix: Vec::new(),
            learn_mix: false,
            split_samples: 4000,
            carry: 0.25,
        };
        for b in 0..BUCKETS {
            guide.roots[b] = guide.nodes.len() as u32;
            guide.nodes.push(SpatialNode { child: 0, axis: 0, split: 0.0, cell: b as u32, depth: 0 });
        }
        // Split by photon positions until no cell holds more than PHOTONS_PER_CELL photons.
        let mut cells = BUCKETS;
        for _round in 0..MAX_SPATIAL_DEPTH {
            let mut spread = vec![[0u64; 7]; cells];
            for i in 0..map.len() {
                let c = guide.cell(map.position(i), map.normal[i]);
                add_spread(&mut spread[c], map.position(i) - guide.origin);
            }
            let before = cells;
            cells = guide.split_cells(&spread, PHOTONS_PER_CELL, cells)?;
            if cells == before {
                break;
            }
        }
        // Seed each cell.
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); cells];
        for i in 0..map.len() {
            members[guide.cell(map.position(i), map.normal[i])].push(i);
        }
        let seeded: Vec<(CellEstimate, bool, Forest)> = members
            .par_iter()
            .map(|photons| {
                let mut tree = Forest::flat(1);
                let mut est = CellEstimate::default();
                if photons.is_empty() {
                    return (est, false, tree);
                }
                let centre = photons.iter().map(|&i| map.position(i)).sum::<Vec3A>() / photons.len() as f32;
                let n = map.normal[photons[0]];
                let albedo = map.albedo[photons[0]];
                let (near, r2) = map.nearest(centre, knn);
                if r2 > 0.0 {
                    let scale = FRAC_1_PI / (PI * r2);
                    for i in near.into_iter().filter(|&i| map.normal[i].dot(n) >= 0.5) {
                        if map.bounce[i] == 0 {
                            est.direct += albedo * map.flux[i] * scale;
                        } else {
                            est.indirect += albedo * map.flux[i] * scale;
                        }
                    }
                }
                for round in 0..3 {
                    let mut acc = vec![0u64; 8 * tree.nodes.len()];
                    // A photon's flux is `L·cos·dω`; the cosine warp's `dω = π/cos·du·dv`, so
                    // flux summed per leaf is `π∫L du dv`, as the walks deposit.
                    for &i in photons.iter().filter(|&&i| map.bounce[i] > 0) {
                        let local = Frame::from_normal(map.normal[i]).to_local(map.incoming[i]);
                        if local.z <= 0.0 {
                            continue;
                        }
                        let (node, q) = tree.leaf_of(0, warp::cosine_hemisphere_inverse(local));
                        acc[8 * node + 2 * q] += to_fixed(map.flux[i].element_sum() as f64);
                        acc[8 * node + 2 * q + 1] += 1;
                    }
                    tree.freeze_tree(0, &acc);
                    if round < 2 {
                        let mut next = Forest::default();
                        tree.refine_into(0, SEED_SPLIT_THRESHOLD, MIN_LEAF_PHOTONS, &mut next);
                        tree = next;
                    }
                }
                (est, true, tree)
            })
            .collect();
        for (est, known, tree) in &seeded {
            guide.estimates.push(*est);
            guide.known.push(*known);
            tree.copy_into(0, &mut guide.trees);
        }
        guide.sums = vec![[0; 7]; cells];
        guide.mix = vec![0.5; cells];
        Ok(guide)
    }

    /// Splits every cell whose `spread` count exceeds `limit`: at the samples' mean along the
    /// axis they spread most, then — while the parts would still exceed it, assuming samples
    /// halve at each split — at the mean along the second axis, then at the quartiles of the
    /// first and of the second (a normal's ±0.674σ): at most 16 cells from one per call. The
    /// new cells copy their parent's tree and estimates. Returns the number of cells.
    fn split_cells(&mut self, spread: &[Spread], limit: u64, cells: usize) -> crate::Result<usize> {
        let mut parent_of: Vec<usize> = Vec::with_capacity(cells);
        let mut stack: Vec<(u32, Option<Plan>)> = Vec::new();
        for b in (0..BUCKETS).rev() {
            stack.push((self.roots[b], None));
        }
        // Depth first over every node, so the cells' numbering is deterministic.
        while let Some((n, plan)) = stack.pop() {
            let node = self.nodes[n as usize];
            if node.child != 0 {
                stack.push((node.child + 1, None));
                stack.push((node.child, None));
                continue;
            }
            let plan = plan.or_else(|| Plan::from_spread(&spread[node.cell as usize], self.origin));
            let split = plan.filter(|p| p.count > limit && p.level < 4 && node.depth < MAX_SPATIAL_DEPTH);
            let Some(plan) = split else {
                self.nodes[n as usize].cell = parent_of.len() as u32;
                parent_of.push(node.cell as usize);
                continue;
            };
            if parent_of.len() + stack.len() + 2 > MAX_CELLS {
                return Err(crate::Error::InvalidOption(format!(
                    "the learned guide would need more than {MAX_CELLS} cells; raise its split threshold"
                )));
            }
            let (axis, at) = plan.plane();
            let child = self.nodes.len() as u32;
            for _ in 0..2 {
                self.nodes.push(SpatialNode { child: 0, axis: 0, split: 0.0, cell: node.cell, depth: node.depth + 1 });
            }
            let parent = &mut self.nodes[n as usize];
            (parent.child, parent.axis, parent.split) = (child, axis as u8, at);
            stack.push((child + 1, Some(plan.child(1.0))));
            stack.push((child, Some(plan.child(-1.0))));
        }
        // Carry trees and estimates over to the new numbering.
        let unchanged = parent_of.len() == cells && parent_of.iter().enumerate().all(|(i, &p)| i == p);
        if !unchanged {
            if !self.trees.is_empty() {
                let mut trees = Forest::default();
                for &p in &parent_of {
                    self.trees.copy_into(p, &mut trees);
                }
                self.trees = trees;
            }
            if !self.estimates.is_empty() {
                self.estimates = parent_of.iter().map(|&p| self.estimates[p]).collect();
                self.known = parent_of.iter().map(|&p| self.known[p]).collect();
                self.mix = parent_of.iter().map(|&p| self.mix[p]).collect();
                let mut children = vec![0u32; cells];
                for &p in &parent_of {
                    children[p] += 1;
                }
                // An unsplit cell keeps its sums; parts start afresh (keeping the parent's
                // estimates until they have their own).
                self.sums = parent_of.iter().map(|&p| if children[p] == 1 { self.sums[p] } else { [0; 7] }).collect();
            }
        }
        Ok(parent_of.len())
    }

    /// The cell at surface point `x` with shading normal `n`.
    #[inline]
    #[must_use]
    pub fn cell(&self, x: Vec3A, n: Vec3A) -> usize {
        let mut node = &self.nodes[self.roots[bucket_of(n)] as usize];
        while node.child != 0 {
            node = &self.nodes[(node.child + u32::from(x[node.axis as usize] >= node.split)) as usize];
        }
        node.cell as usize
    }

    /// A cell's estimates, if anything reached it.
    #[inline]
    #[must_use]
    pub fn estimate(&self, cell: usize) -> Option<CellEstimate> {
        self.known[cell].then(|| self.estimates[cell])
    }

    /// The learned directional density at `cell` (per steradian) of local direction `w` (in
    /// the shading frame, `z` = normal); 0 where it learned nothing and below the surface.
    #[inline]
    #[must_use]
    pub fn pdf(&self, cell: usize, w: Vec3A) -> f32 {
        if w.z <= 0.0 {
            return 0.0;
        }
        self.trees.pdf(cell, warp::cosine_hemisphere_inverse(w)) * w.z * FRAC_1_PI
    }

    #[inline]
    #[must_use]
    pub fn has_tree(&self, cell: usize) -> bool {
        self.trees.total(cell) > 0.0
    }

    /// A local direction from `cell`'s learned density (which must have energy) and its
    /// density per steradian.
    #[inline]
    #[must_use]
    pub fn sample(&self, cell: usize, u: Vec2) -> (Vec3A, f32) {
        let (p, density) = self.trees.sample(cell, u);
        let w = warp::cosine_hemisphere(p);
        (w, density * w.z * FRAC_1_PI)
    }

    #[must_use]
    pub fn cells(&self) -> usize {
        self.trees.len()
    }

    #[must_use]
    pub fn stats(&self) -> GuideStats {
        // The trees being filled, and one worker's accumulators for them.
        let fill = self.filling.as_ref().map_or(0, |f| f.bytes() + f.nodes.len() * 64);
        GuideStats {
            cells: self.cells(),
            nodes: self.trees.nodes.len(),
            bytes: self.trees.bytes()
                + fill
                + self.nodes.len() * std::mem::size_of::<SpatialNode>()
                + self.cells() * (std::mem::size_of::<CellEstimate>() + 1 + 2 * 7 * 8),
        }
    }

    /// Starts a training iteration: deposits go to a copy of the frozen trees, refined where
    /// they hold energy.
    pub fn begin_iteration(&mut self) {
        let mut forest = Forest::default();
        for t in 0..self.trees.len() {
            self.trees.refine_into(t, SPLIT_THRESHOLD, MIN_LEAF_SAMPLES, &mut forest);
        }
        self.filling = Some(forest);
    }

    /// Empty accumulators for one worker's deposits in this iteration (none outside one).
    #[must_use]
    pub fn deposits(&self) -> Deposits {
        let Some(forest) = &self.filling else {
            return Deposits::default();
        };
        let cells = self.cells();
        Deposits {
            acc: vec![0; 8 * forest.nodes.len()],
            sums: vec![[0; 7]; cells],
            spread: vec![[0; 7]; cells],
            moments: vec![[0; MIX_CANDIDATES.len()]; cells],
        }
    }

    /// Whether an iteration is running (walks deposit only then).
    #[inline]
    #[must_use]
    pub fn learning(&self) -> bool {
        self.filling.is_some()
    }

    /// Records `value` (an estimate of `f·cos·Lr / pdf` along local direction `w`, summed
    /// over channels) arriving at `cell`. In the cosine-warped square this sums to `∫f·Lr`
    /// over each leaf: the tree's density becomes `f·cos·Lr` per steradian.
    #[inline]
    pub fn deposit_direction(&self, d: &mut Deposits, cell: usize, w: Vec3A, value: f32) {
        if let Some(f) = &self.filling {
            let (node, q) = f.leaf_of(cell, warp::cosine_hemisphere_inverse(w));
            let i = 8 * node + 2 * q;
            d.acc[i] = d.acc[i].wrapping_add(to_fixed(value as f64));
            d.acc[i + 1] += 1;
        }
    }

    /// The probability of sampling `cell`'s tree (the rest: cosine sampling).
    #[inline]
    #[must_use]
    pub fn mix(&self, cell: usize) -> f32 {
        if self.has_tree(cell) { self.mix[cell] } else { 0.0 }
    }

    /// Sets every cell's tree-sampling probability (before learning it, or for good).
    pub fn set_mix(&mut self, alpha: f32) {
        self.mix.iter_mut().for_each(|m| *m = alpha);
    }

    /// Records, for the choice of `cell`'s mixture probability, one direction whose integrand
    /// is `g` (`f·cos·Lr`, summed over channels), drawn with density `p_drawn`, where the tree
    /// has density `p_tree` and cosine sampling `p_cos`.
    #[inline]
    pub fn deposit_moments(&self, d: &mut Deposits, cell: usize, g: f32, p_drawn: f32, p_tree: f32, p_cos: f32) {
        if self.filling.is_none() || !self.learn_mix || !(g > 0.0 && p_drawn > 0.0) {
            return;
        }
        for (m, a) in d.moments[cell].iter_mut().zip(MIX_CANDIDATES) {
            let p = a * p_tree + (1.0 - a) * p_cos;
            *m = m.wrapping_add(to_fixed(f64::from(g) * f64::from(g) / (f64::from(p) * f64::from(p_drawn))));
        }
    }

    /// Records one vertex at `p` and its estimates of outgoing direct and indirect radiance.
    #[inline]
    pub fn deposit_estimates(&self, d: &mut Deposits, cell: usize, p: Vec3A, direct: Vec3A, indirect: Vec3A) {
        if self.filling.is_none() || !(direct.is_finite() && indirect.is_finite()) {
            return;
        }
        let s = &mut d.sums[cell];
        for c in 0..3 {
            s[c] = s[c].wrapping_add(to_fixed(direct[c] as f64));
            s[3 + c] = s[3 + c].wrapping_add(to_fixed(indirect[c] as f64));
        }
        s[6] += 1;
        add_spread(&mut d.spread[cell], p - self.origin);
    }

    /// Ends the iteration `k` (0 first) with everything its walks deposited: cells that
    /// learned enough sample from what they learned, the others keep their tree; estimates
    /// average every iteration's samples so far; cells that received more than
    /// `split_samples·√(2^k)` samples are split.
    pub fn end_iteration(&mut self, k: u32, deposits: Deposits) -> crate::Result<()> {
        let Some(mut filling) = self.filling.take() else {
            return Ok(());
        };
        let cells = self.cells();
        let Deposits { acc, sums, spread, moments } = deposits;
        if acc.len() != 8 * filling.nodes.len() || sums.len() != cells {
            return Err(crate::Error::InvalidOption("deposits of another training iteration".into()));
        }
        // Earlier iterations' directional data carry over with weight `carry` per deposit
        // (compounding: `carry^j` for the iteration j back), the photon seed's do not (its
        // trees hold photon flux of indirect light only).
        let carry = if k > 0 { self.carry } else { 0.0 };
        let mut trees = Forest::default();
        for t in 0..self.trees.len() {
            filling.freeze_tree_blended(t, &acc, carry);
            let samples = spread[t][0];
            if samples >= MIN_TREE_SAMPLES && filling.total(t) > 0.0 {
                filling.copy_into(t, &mut trees);
            } else {
                self.trees.copy_into(t, &mut trees);
            }
        }
        self.trees = trees;
        for (total, new) in self.sums.iter_mut().zip(&sums) {
            for (x, y) in total.iter_mut().zip(new) {
                *x = x.wrapping_add(*y);
            }
        }
        for ((e, known), s) in self.estimates.iter_mut().zip(&mut self.known).zip(&self.sums) {
            let n = s[6];
            if n >= MIN_SAMPLES {
                let mean = |c: usize| (from_fixed(s[c]) / n as f64) as f32;
                e.direct = Vec3A::new(mean(0), mean(1), mean(2));
                e.indirect = Vec3A::new(mean(3), mean(4), mean(5));
                e.from_walks = true;
                *known = true;
            }
        }
        if self.learn_mix {
            for ((mix, m), s) in self.mix.iter_mut().zip(&moments).zip(&spread) {
                let samples = s[0];
                if samples >= MIN_MIX_SAMPLES {
                    let moment = |i: usize| m[i];
                    let open =
                        if samples >= MIN_HIGH_MIX_SAMPLES { MIX_CANDIDATES.len() } else { MIX_CANDIDATES.len() - 1 };
                    let best = (0..open).min_by_key(|&i| moment(i)).unwrap_or(2);
                    // Switch only for a clear gain: the moments are noisy estimates.
                    let current = MIX_CANDIDATES.iter().position(|&a| a == *mix);
                    if current.is_none_or(|c| (moment(best) as f64) < MIX_SWITCH_GAIN * moment(c) as f64) {
                        *mix = MIX_CANDIDATES[best];
                    }
                }
            }
        }
        let limit = (self.split_samples as f64 * 2f64.powf(k as f64 * 0.5)) as u64;
        self.split_cells(&spread, limit, cells)?;
        Ok(())
    }
}

/// How one cell is being split: from its samples' mean and spread on its two widest axes.
#[derive(Clone, Copy, Debug)]
struct Plan {
    /// Samples assumed in the part being split.
    count: u64,
    /// 0: the mean of axis `a`; 1: the mean of `b`; 2: quartile of `a`; 3: quartile of `b`.
    level: u32,
    axes: [usize; 2],
    mean: [f32; 2],
    sd: [f32; 2],
    /// Which side of each axis' mean this part lies on (±1, 0 before that axis was split).
    side: [f32; 2],
}

impl Plan {
    fn from_spread(s: &Spread, origin: Vec3A) -> Option<Self> {
        let count = s[0];
        if count == 0 {
            return None;
        }
        let mean = |a: usize| from_fixed(s[1 + a]) / count as f64;
        let var = |a: usize| (from_fixed(s[4 + a]) / count as f64 - mean(a).powi(2)).max(0.0);
        let mut axes = [0usize, 1, 2];
        axes.sort_by(|&a, &b| var(b).total_cmp(&var(a)));
        let [a, b, _] = axes;
        Some(Self {
            count,
            level: 0,
            axes: [a, b],
            mean: [mean(a) as f32 + origin[a], mean(b) as f32 + origin[b]],
            sd: [var(a).sqrt() as f32, var(b).sqrt() as f32],
            side: [0.0; 2],
        })
    }

    /// The axis and position of this level's plane.
    fn plane(&self) -> (usize, f32) {
        let i = (self.level % 2) as usize;
        (self.axes[i], self.mean[i] + self.side[i] * 0.674 * self.sd[i])
    }

    /// The plan for the part below (`side` −1) or above (+1) this level's plane.
    fn child(&self, side: f32) -> Self {
        let mut c = *self;
        if self.level < 2 {
            c.side[(self.level % 2) as usize] = side;
        }
        c.level += 1;
        c.count /= 2;
        c
    }
}

fn add_spread(s: &mut Spread, p: Vec3A) {
    s[0] += 1;
    for a in 0..3 {
        let x = p[a].max(0.0) as f64;
        s[1 + a] = s[1 + a].wrapping_add(to_fixed(x));
        s[4 + a] = s[4 + a].wrapping_add(to_fixed(x * x));
    }
}

/// The defensive one-sample mixture of the learned density (weight `alpha`) and cosine
/// sampling: its density at `w` (local `cos_theta`), per steradian.
#[inline]
#[must_use]
pub fn mixture_pdf(alpha: f32, learned_pdf: f32, cos_theta: f32) -> f32 {
    alpha * learned_pdf + (1.0 - alpha) * warp::cosine_hemisphere_pdf(cos_theta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::BvhAccel;

    #[test]
    fn cells_follow_the_photons_and_seeds_point_at_the_bright_ceiling() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
        let accel = BvhAccel::build(&scene);
        let map = PhotonMap::build(&scene, &accel, 20_000, 1).unwrap();
        let guide = LearnedGuide::seed(&scene, &map, 100).unwrap();
        assert!(guide.cells() > 20_000 / PHOTONS_PER_CELL as usize, "{} cells", guide.cells());
        let floor = guide.cell(Vec3A::new(0.1, -1.0, 0.1), Vec3A::Y);
        assert!(guide.has_tree(floor));
        // From the floor's centre, light comes mostly from above (the lit ceiling): more of
        // the seed's samples fall within 25° of the normal than cosine sampling's 18%.
        let mut rng = crate::sampler::SampleStream::in_domain(crate::sampler::Domain::Photon, 1, 0, 0);
        let up = (0..10_000).filter(|_| guide.sample(floor, rng.next_2d()).0.z > 0.906).count();
        assert!(up > 3000, "{up} of 10000 within 25°");
        let e = guide.estimate(floor).unwrap();
        assert!(e.direct == Vec3A::ZERO && e.indirect.x > 0.1, "{e:?}");
    }
}
