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
pub mod lobes;
pub mod quadtree;
pub mod volume;

use crate::geometry::{Frame, Vec2, Vec3A, warp};
use crate::photon::cache::{BUCKETS, bucket_of};
use crate::photon::{Caustics, PhotonMap};
use crate::scene::Scene;
use lobes::{CausticLobes, Lobes};
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
pub(crate) const MIN_TREE_SAMPLES: u64 = 64;
/// A cell's learned estimates replace its photon seed once it has this many samples.
const MIN_SAMPLES: u64 = 16;
/// Thinnest side of a source box, as a fraction of the scene's extent (a box around a flat
/// patch needs some thickness to have a volume).
const MIN_BOX_SIDE: f32 = 1e-3;
/// Largest side of a source box, as a fraction of the scene's extent.
const MAX_SOURCE_SIDE: f32 = 0.5;
/// Most source boxes a scene gets.
pub const MAX_SOURCES: usize = 4;
/// Buckets per axis of the grid that groups caustic exit points into boxes.
const CAUSTIC_GRID: u32 = 8;
/// Most of them that are caustic exits ([`LearnedGuide::add_caustic_sources`]).
pub const MAX_CAUSTIC_SOURCES: usize = 2;
/// A cell whose radiance is at least this fraction of the brightest cell's is a source.
const SOURCE_RADIANCE: f32 = 0.1;
/// A cell aims at a source box only if it brought it at least this share of its energy.
const MIN_SOURCE_SHARE: f64 = 0.1;
/// Photons per cell when the first tree is split by photon positions.
const PHOTONS_PER_CELL: u64 = 200;
/// Deposits a quadrant needs before it is refined (training; photon seed).
pub(crate) const MIN_LEAF_SAMPLES: u32 = 32;
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
    /// Source boxes, and the cells that aim at one.
    pub sources: usize,
    /// Of which caustic exits.
    pub caustic: usize,
    pub aiming: usize,
}

impl std::fmt::Display for GuideStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} cells, {} direction nodes, {:.1} MB", self.cells, self.nodes, self.bytes as f64 / 1e6)?;
        if self.sources > 0 {
            let s = if self.sources == 1 { "" } else { "es" };
            write!(f, "; {} source box{s}", self.sources)?;
            if self.caustic > 0 {
                write!(f, " ({} of caustics)", self.caustic)?;
            }
            write!(f, ", aimed at by {} cells", self.aiming)?;
        }
        Ok(())
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
    /// Per cell: the second-moment estimates of each pair of [`MIX_CANDIDATES`] and
    /// [`BOX_CANDIDATES`] (index `i·BOX_CANDIDATES.len() + j`).
    moments: Vec<[u64; MOMENTS]>,
    /// Per cell: the sum of the directions' one-sample estimates `g/p` and their count (the
    /// first moment that [`Self::moments`] are measured against).
    firsts: Vec<[u64; 2]>,
    /// Per cell: the energy its directions brought from inside each source box, and in all.
    sources: Vec<[u64; MAX_SOURCES + 1]>,
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
        add(&mut self.firsts, &other.firsts);
        add(&mut self.sources, &other.sources);
        self
    }
}

/// A box in world space that a cell's light comes from (learned from where its walks found
/// energy), for a parallax-free mixture component: a uniform point in the box gives a
/// direction from any shading point of the cell, so a bright patch seen from across the room
/// is aimed at wherever in the cell the walk is (a directional tree averages its direction
/// over the cell). The density of that direction is known in closed form: the box is convex,
/// so a ray from `x` crosses it over one segment `[t0, t1]`, and `p(ω) = ∫ t² dt / V`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SourceBox {
    pub lo: Vec3A,
    pub hi: Vec3A,
    inv_volume: f32,
}

impl SourceBox {
    /// The box `[lo, hi]`; `None` unless it has positive, finite volume.
    #[must_use]
    pub fn new(lo: Vec3A, hi: Vec3A) -> Option<Self> {
        let volume = (hi - lo).x * (hi - lo).y * (hi - lo).z;
        let inv_volume = 1.0 / volume;
        (volume > 0.0 && inv_volume.is_finite() && lo.is_finite() && hi.is_finite()).then_some(Self {
            lo,
            hi,
            inv_volume,
        })
    }

    #[inline]
    #[must_use]
    pub fn contains(&self, p: Vec3A) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }

    /// The direction from `x` to the point of the box at `u` (uniform in the unit cube).
    #[inline]
    #[must_use]
    pub fn sample(&self, x: Vec3A, u: Vec3A) -> Option<Vec3A> {
        (self.lo + (self.hi - self.lo) * u - x).try_normalize()
    }

    /// The density per steradian of [`Self::sample`]'s direction `d` (unit) from `x`.
    #[inline]
    #[must_use]
    pub fn pdf(&self, x: Vec3A, d: Vec3A) -> f32 {
        // Components of exactly 0 (a set of measure zero) become tiny, so the slab test
        // never computes 0·∞.
        let d = Vec3A::select(d.abs().cmplt(Vec3A::splat(1e-20)), Vec3A::splat(1e-20), d);
        let inv = d.recip();
        let (ta, tb) = ((self.lo - x) * inv, (self.hi - x) * inv);
        let t0 = ta.min(tb).max_element().max(0.0);
        let t1 = ta.max(tb).min_element();
        if t1 > t0 {
            // (t1³ − t0³)/3, factored so that a thin box far away keeps its precision.
            (t1 - t0) * (t1 * t1 + t1 * t0 + t0 * t0) * (self.inv_volume / 3.0)
        } else {
            0.0
        }
    }
}

/// What a cell's walk aims at besides its tree and cosine sampling: a source box, or, in a
/// cell caustic photons reached, the caustic lobes at the shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Aim<'a> {
    Box(SourceBox),
    Lobes(Lobes<'a>),
}

impl Aim<'_> {
    /// A direction from `x` by `u` (uniform in the unit cube); `None` where there is nothing to
    /// aim at (the walk then draws no direction: its density counts that).
    #[inline]
    #[must_use]
    pub fn sample(&self, x: Vec3A, u: Vec3A) -> Option<Vec3A> {
        match self {
            Aim::Box(b) => b.sample(x, u),
            Aim::Lobes(l) => l.sample(u),
        }
    }

    /// The density per steradian of [`Self::sample`]'s direction `d` (unit) from `x`.
    #[inline]
    #[must_use]
    pub fn pdf(&self, x: Vec3A, d: Vec3A) -> f32 {
        match self {
            Aim::Box(b) => b.pdf(x, d),
            Aim::Lobes(l) => l.pdf(d),
        }
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
    /// The scene's extent (largest side of its bounds).
    extent: f32,
    /// Bright patches that light the scene (from the photon seed), which cells may aim at.
    pub sources: Vec<SourceBox>,
    /// Per cell: the source box it aims at (index + 1; 0: none), and the probability of
    /// aiming at it (starting at `box_mix`, then learned with the tree's).
    cell_source: Vec<u8>,
    box_share: Vec<f32>,
    /// Probability of aiming at a cell's source box (where it has one).
    pub box_mix: f32,
    /// The first `caustic_boxes` of `sources` are caustic exits.
    caustic_boxes: usize,
    /// The caustic photons' lobes, which cells aiming at a caustic box aim at instead (where
    /// in use: [`Self::use_caustic_lobes`]).
    lobes: Option<CausticLobes>,
    caustic_lobes: bool,
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
    /// A cell whose directions' relative second moment `ρ = n·M/S²` in the iteration (`S` the
    /// sum of its `n` one-sample estimates `g/p`, `M` the least second-moment sum of its
    /// candidate mixtures) exceeds this splits at `split_samples·split_moment/ρ` (down to a
    /// quarter): where a cell's best mixture stays far from zero variance, its lobes likely
    /// differ across it (caustics). 0: off.
    pub split_moment: f32,
    /// Weight per deposit of the previous trees' data in each new tree (see
    /// [`Forest::freeze_tree_blended`]).
    pub carry: f32,
}

/// The tree-sampling probabilities a cell chooses from, by the second moment each would have
/// given this iteration's directions (one-sample MIS: a direction drawn with density `p` is
/// weighted `g/(α·p_tree + (1−α)·p_cos)`; its second moment under any `α` is estimated from
/// the same samples by `g²/(p_α·p)`). In the furnace, where cosine sampling is exact, cells
/// choose 0; where light comes from a small bright patch, 0.75 or 0.9. The last candidate is
/// open only to cells whose moments come from at least `MIN_HIGH_MIX_SAMPLES` directions:
/// with a guide learned from one training spp, cells that chose 0.9 left 10% to cosine
/// sampling and their samples were heavy-tailed, failing the path-reference z-test at 5.6 at
/// two seeds. Gated, it lowers cornell-paper's MSE at 32 spp by 5–10% (0.0173/0.0159 against
/// 0.0181/0.0177 at seeds 1/2).
pub const MIX_CANDIDATES: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 0.9];
/// The source-box probabilities a cell with a source box chooses from, the same way (in the
/// furnace, where cosine sampling is exact, cells choose 0).
pub const BOX_CANDIDATES: [f32; 4] = [0.0, 0.15, 0.3, 0.5];
const MOMENTS: usize = MIX_CANDIDATES.len() * BOX_CANDIDATES.len();
/// Directions a cell needs in an iteration before it may choose the last (highest) candidate.
const MIN_HIGH_MIX_SAMPLES: u64 = 1024;
/// A cell changes its probability only when another candidate's estimated second moment is
/// below this fraction of its current one's, and from at least this many directions
/// (0.7 or 0.97 kept the furnace's cells at 0.5: their moments differ by a few percent, yet
/// cosine sampling's exactness there is worth 30× in variance).
const MIX_SWITCH_GAIN: f64 = 1.0;
const MIN_MIX_SAMPLES: u64 = 64;

/// The densities of one direction a walk drew at a vertex, for learning the cell's mixture.
#[derive(Clone, Copy, Debug)]
pub struct DirectionDensities {
    /// The density it was drawn with.
    pub drawn: f32,
    /// The cell's tree's density of it.
    pub tree: f32,
    /// Cosine sampling's.
    pub cosine: f32,
    /// The source box's, where the cell has one.
    pub source: Option<f32>,
}

impl LearnedGuide {
    /// The first guide, from the photon map: space split until a cell holds about
    /// `PHOTONS_PER_CELL` photons, directions from the indirect photons in each cell,
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
        let extent = ((hi - origin).max_element() * 1.001).max(1e-3);
        let mut guide = Self {
            origin,
            extent,
            sources: Vec::new(),
            cell_source: Vec::new(),
            box_share: Vec::new(),
            box_mix: 0.0,
            caustic_boxes: 0,
            lobes: None,
            caustic_lobes: false,
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
            split_moment: 0.0,
            carry: 0.25,
        };
        for b in 0..BUCKETS {
            guide.roots[b] = guide.nodes.len() as u32;
            guide.nodes.push(SpatialNode { child: 0, axis: 0, split: 0.0, cell: b as u32, depth: 0 });
        }
        // Split by photon positions until no cell holds more than PHOTONS_PER_CELL photons.
        let mut cells = BUCKETS;
        let mut last_spread = Vec::new();
        for _round in 0..MAX_SPATIAL_DEPTH {
            let mut spread = vec![[0u64; 7]; cells];
            for i in 0..map.len() {
                let c = guide.cell(map.position(i), map.normal[i]);
                add_spread(&mut spread[c], map.position(i) - guide.origin);
            }
            let before = cells;
            cells = guide.split_cells(&spread, |_| PHOTONS_PER_CELL, cells)?;
            last_spread = spread;
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
        guide.cell_source = vec![0; cells];
        guide.box_share = vec![0.0; cells];
        guide.sources = guide.find_sources(&last_spread);
        guide.mix = vec![0.5; cells];
        Ok(guide)
    }

    /// The bright patches that light the scene, from the photon seed: cells whose radiance
    /// estimate is at least [`SOURCE_RADIANCE`] of the brightest's, each as the box of its
    /// photons (mean ± √3 standard deviations per axis: a uniform box of the same spread),
    /// boxes that touch merged, the [`MAX_SOURCES`] strongest kept (radiance × area).
    /// `spread` must describe the current cells (the last round of splitting found nothing
    /// to split).
    fn find_sources(&self, spread: &[Spread]) -> Vec<SourceBox> {
        if spread.len() != self.cells() {
            return Vec::new();
        }
        let radiance: Vec<f32> = (0..self.cells())
            .map(|c| {
                if self.known[c] && spread[c][0] >= MIN_LEAF_PHOTONS as u64 {
                    crate::geometry::luminance(self.estimates[c].direct + self.estimates[c].indirect)
                } else {
                    0.0
                }
            })
            .collect();
        let top = radiance.iter().copied().fold(0.0f32, f32::max);
        if !(top > 0.0 && top.is_finite()) {
            return Vec::new();
        }
        let boxes = spread
            .iter()
            .zip(&radiance)
            .filter(|&(_, &r)| r >= SOURCE_RADIANCE * top)
            .map(|(s, &r)| {
                let (lo, hi) = self.spread_box(s);
                let side = hi - lo;
                let area = (side.x * side.y).max(side.y * side.z).max(side.z * side.x);
                (lo, hi, r * area)
            })
            .collect();
        self.merge_boxes(boxes, MAX_SOURCES)
    }

    /// The box of the points summed in `s` (mean ± √3 standard deviations per axis: a uniform
    /// box of the same spread), at least [`MIN_BOX_SIDE`] of the extent thick.
    fn spread_box(&self, s: &Spread) -> (Vec3A, Vec3A) {
        let pad = MIN_BOX_SIDE * self.extent;
        let n = s[0].max(1) as f64;
        let (mut lo, mut hi) = (Vec3A::ZERO, Vec3A::ZERO);
        for a in 0..3 {
            let mean = from_fixed(s[1 + a]) / n;
            let sd = (from_fixed(s[4 + a]) / n - mean * mean).max(0.0).sqrt();
            let half = ((3f64.sqrt() * sd) as f32).max(0.5 * pad);
            lo[a] = self.origin[a] + mean as f32 - half;
            hi[a] = self.origin[a] + mean as f32 + half;
        }
        (lo, hi)
    }

    /// Boxes `(lo, hi, strength)` that touch (within a percent of the extent) merged until none
    /// do, those larger than [`MAX_SOURCE_SIDE`] of the extent dropped, the `most` strongest
    /// kept.
    fn merge_boxes(&self, mut boxes: Vec<(Vec3A, Vec3A, f32)>, most: usize) -> Vec<SourceBox> {
        let touch = 0.01 * self.extent;
        loop {
            let mut merged = false;
            'outer: for i in 0..boxes.len() {
                for j in i + 1..boxes.len() {
                    let (a, b) = (boxes[i], boxes[j]);
                    if (a.0 - touch).cmple(b.1).all() && (b.0 - touch).cmple(a.1).all() {
                        boxes[i] = (a.0.min(b.0), a.1.max(b.1), a.2 + b.2);
                        boxes.swap_remove(j);
                        merged = true;
                        break 'outer;
                    }
                }
            }
            if !merged {
                break;
            }
        }
        // A bright region as large as half the scene is no patch to aim at (in a furnace,
        // everything is equally bright): directions there are the tree's business.
        boxes.retain(|b| (b.1 - b.0).max_element() <= MAX_SOURCE_SIDE * self.extent);
        boxes.sort_by(|a, b| b.2.total_cmp(&a.2));
        boxes.into_iter().take(most).filter_map(|(lo, hi, _)| SourceBox::new(lo, hi)).collect()
    }

    /// Caustic sources: boxes around the points caustic photons came from (a box per bucket
    /// of a coarse grid holding at least 8 of them, boxes that touch merged, the
    /// [`MAX_CAUSTIC_SOURCES`] with the most caustic flux kept), ahead of the bright patches
    /// (which fill the rest of [`MAX_SOURCES`]). Every cell that received a caustic photon
    /// through a box aims at the box it received most through, from the first iteration on,
    /// and keeps it (its share learned by the second moments, down to 0): a caustic brings
    /// little of a cell's energy yet most of its variance where directions find it rarely,
    /// so the energy a cell's walks bring from a box, which decides the bright patches, would
    /// drop it. Returns the number of caustic boxes.
    pub fn add_caustic_sources(&mut self, caustics: &Caustics) -> usize {
        let cells = self.cells();
        // The exit points, bucketed by a grid of CAUSTIC_GRID³ over the scene: a box per
        // bucket, so that two specular objects lit from the same cell give two boxes (a
        // receiving cell's own spread would span both).
        let bucket = |y: Vec3A| {
            let g = ((y - self.origin) * (CAUSTIC_GRID as f32 / self.extent)).floor();
            let g = g.clamp(Vec3A::ZERO, Vec3A::splat(CAUSTIC_GRID as f32 - 1.0));
            (g.x as u32, g.y as u32, g.z as u32)
        };
        let mut buckets: std::collections::BTreeMap<(u32, u32, u32), (Spread, f64)> = Default::default();
        for (y, f) in caustics.from.iter().zip(&caustics.flux) {
            let b = buckets.entry(bucket(*y)).or_insert(([0; 7], 0.0));
            add_spread(&mut b.0, *y - self.origin);
            b.1 += f64::from(f.element_sum());
        }
        let boxes = buckets
            .values()
            .filter(|(s, _)| s[0] >= u64::from(MIN_LEAF_PHOTONS))
            .map(|(s, f)| {
                let (lo, hi) = self.spread_box(s);
                (lo, hi, *f as f32)
            })
            .collect();
        let found = self.merge_boxes(boxes, MAX_CAUSTIC_SOURCES);
        if found.is_empty() {
            return 0;
        }
        let mut sources = found.clone();
        sources.extend(self.sources.iter().copied().take(MAX_SOURCES - found.len()));
        self.sources = sources;
        let mut through = vec![[0f64; MAX_CAUSTIC_SOURCES]; cells];
        for (i, (&p, &n)) in caustics.position.iter().zip(&caustics.normal).enumerate() {
            let c = self.cell(p, n);
            if let Some(k) = found.iter().position(|b| b.contains(caustics.from[i])) {
                through[c][k] += f64::from(caustics.flux[i].element_sum());
            }
        }
        for (source, t) in self.cell_source.iter_mut().zip(&through) {
            let (k, most) = t.iter().enumerate().fold((0, 0.0), |b, (k, &f)| if f > b.1 { (k, f) } else { b });
            *source = if most > 0.0 { k as u8 + 1 } else { 0 };
        }
        self.caustic_boxes = found.len();
        self.lobes = CausticLobes::build(caustics, self.origin, self.extent);
        found.len()
    }

    /// Cells that aim at a caustic box aim at the caustic lobes of their shading point instead
    /// ([`lobes`]): the part of the specular object that images the light from there.
    pub fn use_caustic_lobes(&mut self, on: bool) {
        self.caustic_lobes = on;
    }

    /// What `cell`'s walk aims at from `x` (normal `n`), if anything: its source box, or the
    /// caustic lobes at `x` where the box is a caustic one and lobes are in use.
    #[inline]
    #[must_use]
    pub fn aim(&self, cell: usize, x: Vec3A, n: Vec3A) -> Option<Aim<'_>> {
        let b = self.source_box(cell)?;
        match &self.lobes {
            Some(l) if self.caustic_lobes && usize::from(self.cell_source[cell]) <= self.caustic_boxes => {
                Some(Aim::Lobes(l.at(x, n)))
            }
            _ => Some(Aim::Box(*b)),
        }
    }

    /// Sets the probability of aiming at a source box: cells aimed at one by the photon seed
    /// start from it.
    pub fn set_box_mix(&mut self, box_mix: f32) {
        self.box_mix = box_mix;
        for (share, &c) in self.box_share.iter_mut().zip(&self.cell_source) {
            if c != 0 {
                *share = box_mix;
            }
        }
    }

    /// Splits every cell whose `spread` count exceeds `limit(cell)`: at the samples' mean along the
    /// axis they spread most, then — while the parts would still exceed it, assuming samples
    /// halve at each split — at the mean along the second axis, then at the quartiles of the
    /// first and of the second (a normal's ±0.674σ): at most 16 cells from one per call. The
    /// new cells copy their parent's tree and estimates. Returns the number of cells.
    fn split_cells(&mut self, spread: &[Spread], limit: impl Fn(usize) -> u64, cells: usize) -> crate::Result<usize> {
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
            let limit = limit(node.cell as usize);
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
                self.cell_source = parent_of.iter().map(|&p| self.cell_source[p]).collect();
                self.box_share = parent_of.iter().map(|&p| self.box_share[p]).collect();
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
            sources: self.sources.len(),
            caustic: self.caustic_boxes,
            aiming: (0..self.cells()).filter(|&c| self.source_box(c).is_some() && self.box_share[c] > 0.0).count(),
        }
    }

    /// Starts a training iteration: deposits go to a copy of the frozen trees, refined where
    /// they hold energy.
    pub fn begin_iteration(&mut self) {
        self.filling = Some(self.trees.refined(SPLIT_THRESHOLD, MIN_LEAF_SAMPLES));
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
            moments: vec![[0; MOMENTS]; cells],
            firsts: vec![[0; 2]; cells],
            sources: vec![[0; MAX_SOURCES + 1]; cells],
        }
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
    /// is `g` (`f·cos·Lr`, summed over channels), drawn with the densities `p`.
    #[inline]
    pub fn deposit_moments(&self, d: &mut Deposits, cell: usize, g: f32, p: DirectionDensities) {
        let DirectionDensities { drawn: p_drawn, tree: p_tree, cosine: p_cos, source: p_box } = p;
        if self.filling.is_none() || !self.learn_mix {
            return;
        }
        // Every direction counts towards the moments' mean, those that brought nothing too.
        d.firsts[cell][1] += 1;
        if !(g > 0.0 && p_drawn > 0.0) {
            return;
        }
        // Without a box only the β = 0 candidates can be estimated.
        let boxes = if p_box.is_some() { BOX_CANDIDATES.len() } else { 1 };
        let p_box = p_box.unwrap_or(0.0);
        d.firsts[cell][0] = d.firsts[cell][0].wrapping_add(to_fixed(f64::from(g) / f64::from(p_drawn)));
        let m = &mut d.moments[cell];
        for (i, a) in MIX_CANDIDATES.into_iter().enumerate() {
            let mixture = a * p_tree + (1.0 - a) * p_cos;
            for (j, b) in BOX_CANDIDATES.into_iter().enumerate().take(boxes) {
                let p = b * p_box + (1.0 - b) * mixture;
                let k = i * BOX_CANDIDATES.len() + j;
                m[k] = m[k].wrapping_add(to_fixed(f64::from(g) * f64::from(g) / (f64::from(p) * f64::from(p_drawn))));
            }
        }
    }

    /// Records that a direction from `cell` brought energy `value` (as deposited in its tree)
    /// from the point `y`.
    #[inline]
    pub fn deposit_source(&self, d: &mut Deposits, cell: usize, y: Vec3A, value: f32) {
        if self.filling.is_none() || value.is_nan() || value <= 0.0 || self.sources.is_empty() {
            return;
        }
        let e = to_fixed(f64::from(value));
        let s = &mut d.sources[cell];
        s[MAX_SOURCES] = s[MAX_SOURCES].wrapping_add(e);
        for (k, b) in self.sources.iter().enumerate() {
            if b.contains(y) {
                s[k] = s[k].wrapping_add(e);
            }
        }
    }

    /// The box `cell`'s light comes from, if learned and in use.
    #[inline]
    #[must_use]
    pub fn source_box(&self, cell: usize) -> Option<&SourceBox> {
        match self.cell_source[cell] {
            0 => None,
            k if self.box_mix > 0.0 => self.sources.get(k as usize - 1),
            _ => None,
        }
    }

    /// The probability of aiming at `cell`'s source box (where it has one).
    #[inline]
    #[must_use]
    pub fn box_share(&self, cell: usize) -> f32 {
        self.box_share[cell]
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
        let Deposits { acc, sums, spread, moments, firsts, sources } = deposits;
        if acc.len() != 8 * filling.nodes.len() || sums.len() != cells {
            return Err(crate::Error::InvalidOption("deposits of another training iteration".into()));
        }
        // Earlier iterations' directional data carry over with weight `carry` per deposit
        // (compounding: `carry^j` for the iteration j back), the photon seed's do not (its
        // trees hold photon flux of indirect light only).
        let carry = if k > 0 { self.carry } else { 0.0 };
        let mut trees = Forest::default();
        for (t, s) in spread.iter().enumerate() {
            filling.freeze_tree_blended(t, &acc, carry);
            let samples = s[0];
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
            let nb = BOX_CANDIDATES.len();
            for (cell, (m, s)) in moments.iter().zip(&spread).enumerate() {
                let samples = s[0];
                if samples < MIN_MIX_SAMPLES {
                    continue;
                }
                let open =
                    if samples >= MIN_HIGH_MIX_SAMPLES { MIX_CANDIDATES.len() } else { MIX_CANDIDATES.len() - 1 };
                // Box candidates only for a cell that sampled its box in this iteration.
                let boxes = if self.source_box(cell).is_some() { nb } else { 1 };
                let candidates = (0..open).flat_map(|i| (0..boxes).map(move |j| i * nb + j));
                let Some(best) = candidates.min_by_key(|&k| m[k]) else {
                    continue;
                };
                // Switch only for a clear gain: the moments are noisy estimates.
                let current = MIX_CANDIDATES
                    .iter()
                    .position(|&a| a == self.mix[cell])
                    .zip(BOX_CANDIDATES.iter().position(|&b| b == self.box_share[cell]).filter(|&j| j < boxes))
                    .map(|(i, j)| i * nb + j);
                if current.is_none_or(|c| (m[best] as f64) < MIX_SWITCH_GAIN * m[c] as f64) {
                    self.mix[cell] = MIX_CANDIDATES[best / nb];
                    if boxes > 1 {
                        self.box_share[cell] = BOX_CANDIDATES[best % nb];
                    }
                }
            }
        }
        let had_box: Vec<bool> = (0..cells).map(|c| self.source_box(c).is_some()).collect();
        let caustic_boxes = self.caustic_boxes;
        // Each cell aims at the source box that brought it the most energy, if that was at
        // least MIN_SOURCE_SHARE of all it received (from enough directions).
        for ((c, e), n) in self.cell_source.iter_mut().zip(&sources).zip(&spread) {
            if n[0] < MIN_TREE_SAMPLES || e[MAX_SOURCES] == 0 || (*c != 0 && usize::from(*c) <= caustic_boxes) {
                continue;
            }
            let best = (0..MAX_SOURCES).max_by_key(|&k| (e[k], std::cmp::Reverse(k))).unwrap_or(0);
            *c = if (e[best] as f64) >= MIN_SOURCE_SHARE * e[MAX_SOURCES] as f64 && e[best] > 0 {
                best as u8 + 1
            } else {
                0
            };
        }
        // A cell that gets its first box starts from `box_mix`.
        for (share, (&c, &before)) in self.box_share.iter_mut().zip(self.cell_source.iter().zip(&had_box)) {
            if c != 0 && !before {
                *share = self.box_mix;
            }
        }
        let limit = (self.split_samples as f64 * 2f64.powf(k as f64 * 0.5)) as u64;
        let split_moment = f64::from(self.split_moment);
        let cell_limit = |c: usize| {
            if split_moment <= 0.0 {
                return limit;
            }
            let factor = (relative_moment(&firsts[c], &moments[c]) / split_moment).clamp(1.0, MOMENT_SPLIT_MAX);
            (limit as f64 / factor) as u64
        };
        self.split_cells(&spread, cell_limit, cells)?;
        Ok(())
    }
}

/// Most a cell's split count is lowered for its directions' relative second moment
/// ([`LearnedGuide::split_moment`]).
const MOMENT_SPLIT_MAX: f64 = 4.0;

/// A cell's relative second moment `n·M/S²` in one iteration: `S` the sum of its `n`
/// directions' one-sample estimates `g/p`, `M` the lowest of the candidate mixtures' second
/// moment sums (1 where every direction brings the same; 0 where nothing was measured).
fn relative_moment(first: &[u64; 2], moments: &[u64; MOMENTS]) -> f64 {
    let [sum, n] = *first;
    let s = from_fixed(sum);
    let best = moments.iter().copied().filter(|&m| m > 0).min().map_or(0.0, from_fixed);
    if s > 0.0 { n as f64 * best / (s * s) } else { 0.0 }
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

    /// A source box's direction density is normalised over the sphere (uniform directions:
    /// E[4π·p] = 1) and is the density its samples have (E_p[1/p] = the solid angle the box
    /// subtends, which uniform directions measure independently), from outside and inside.
    /// 10⁶ samples each; from outside, 13% of uniform directions meet the box, so the
    /// relative standard errors are about 0.3%; tolerance 1.5% (5 standard errors).
    #[test]
    fn source_box_pdf_is_the_density_of_its_directions() {
        let b = SourceBox::new(Vec3A::new(-0.25, 0.9, -0.2), Vec3A::new(0.25, 1.2, 0.2)).unwrap();
        let mut rng = crate::sampler::SampleStream::in_domain(crate::sampler::Domain::Photon, 3, 0, 0);
        for x in [Vec3A::new(0.1, 0.6, 0.1), Vec3A::new(0.0, 1.0, 0.0)] {
            let n = 1_000_000;
            let (mut integral, mut hits, mut inv) = (0.0f64, 0u64, 0.0f64);
            for _ in 0..n {
                let u = rng.next_2d();
                let (z, phi) = (1.0 - 2.0 * u.x, 2.0 * PI * u.y);
                let r = (1.0 - z * z).max(0.0).sqrt();
                let d = Vec3A::new(r * phi.cos(), r * phi.sin(), z);
                let p = b.pdf(x, d);
                integral += 4.0 * std::f64::consts::PI * f64::from(p) / f64::from(n);
                hits += u64::from(p > 0.0);
                let u = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                let w = b.sample(x, u).unwrap();
                let q = b.pdf(x, w);
                assert!(q > 0.0, "a sampled direction has density {q}");
                inv += 1.0 / f64::from(q) / f64::from(n);
            }
            let omega = 4.0 * std::f64::consts::PI * hits as f64 / f64::from(n);
            eprintln!("from {x}: ∫p = {integral}, E[1/p] = {inv}, Ω = {omega}");
            assert!((integral - 1.0).abs() < 0.015, "from {x}: ∫p = {integral}");
            assert!((inv / omega - 1.0).abs() < 0.015, "from {x}: E[1/p] = {inv}, Ω = {omega}");
        }
        // A direction that misses the box has no density; a degenerate box is refused.
        assert_eq!(b.pdf(Vec3A::ZERO, Vec3A::NEG_Y), 0.0);
        assert!(SourceBox::new(Vec3A::ZERO, Vec3A::new(1.0, 0.0, 1.0)).is_none());
    }

    /// The guide `cornell-paper`'s photon map (`photons`, seed 1) seeds, `knn` per estimate.
    fn cornell_paper_seed(photons: usize, knn: usize) -> LearnedGuide {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
        let accel = BvhAccel::build(&scene.triangles);
        let map = PhotonMap::build(&scene, &accel, photons, 1).unwrap();
        LearnedGuide::seed(&scene, &map, knn).unwrap()
    }

    /// On cornell-paper the photon seed finds one bright patch: the ceiling above the light
    /// (which emits up), thin, covering the light's footprint.
    #[test]
    fn the_source_is_the_ceiling_above_the_light() {
        let guide = cornell_paper_seed(6891, 50);
        assert_eq!(guide.sources.len(), 1, "{:?}", guide.sources);
        let b = guide.sources[0];
        assert!(b.contains(Vec3A::new(0.0, 1.0, 0.0)) && b.hi.y - b.lo.y < 0.01, "{b:?}");
        assert!(b.lo.x < -0.25 && b.hi.x > 0.25 && b.lo.z < -0.2 && b.hi.z > 0.2, "{b:?}");
        assert!(b.hi.x - b.lo.x < 1.2 && b.hi.z - b.lo.z < 1.2, "{b:?}");
    }

    /// On `cornell-materials` the caustic photons give one caustic box, around the glass
    /// sphere (centre (0.1, −0.65, 0.4), radius 0.35), ahead of the bright patches; the floor
    /// beneath the sphere, where its caustic lies, aims at it once boxes are on.
    #[test]
    fn the_floor_under_the_glass_sphere_aims_at_it() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-materials")).unwrap();
        let accel = BvhAccel::build(&scene.triangles);
        let map = PhotonMap::build(&scene, &accel, 6891, 1).unwrap();
        let mut guide = LearnedGuide::seed(&scene, &map, 50).unwrap();
        let patches = guide.sources.clone();
        let caustics = Caustics::trace(&scene, &accel, 10_000, 200_000, 1);
        assert_eq!(guide.add_caustic_sources(&caustics), 1, "{:?}", guide.sources);
        let b = guide.sources[0];
        assert!(b.contains(Vec3A::new(0.1, -0.8, 0.4)), "{b:?}");
        // Within the sphere's bounds and a little more (a box is its points' mean ± √3
        // standard deviations, merged with its neighbours').
        let (lo, hi) = (Vec3A::new(-0.25, -1.0, 0.05), Vec3A::new(0.45, -0.3, 0.75));
        assert!(b.lo.cmpge(lo - 0.2).all() && b.hi.cmple(hi + 0.2).all(), "{b:?}");
        // The bright patches follow it.
        assert_eq!(&guide.sources[1..], &patches[..patches.len().min(MAX_SOURCES - 1)]);
        let below = guide.cell(Vec3A::new(0.1, -1.0, 0.4), Vec3A::Y);
        assert_eq!(guide.source_box(below), None, "boxes are off until box_mix is set");
        guide.set_box_mix(0.3);
        assert_eq!(guide.source_box(below), Some(&b));
        assert_eq!(guide.box_share(below), 0.3);
        // With lobes, the floor just in front of the contact point aims at cones that point up
        // into the sphere (the light comes down through it); without, at the box.
        let x = Vec3A::new(0.1, -1.0, 0.5);
        let at = guide.cell(x, Vec3A::Y);
        assert_eq!(guide.aim(at, x, Vec3A::Y), guide.source_box(at).map(|b| Aim::Box(*b)));
        guide.use_caustic_lobes(true);
        let Some(Aim::Lobes(lobes)) = guide.aim(at, x, Vec3A::Y) else { panic!("no lobes at {x}") };
        assert!(!lobes.is_empty());
        let centre = Vec3A::new(0.1, -0.65, 0.4);
        let mut rng = crate::sampler::SampleStream::in_domain(crate::sampler::Domain::Photon, 3, 0, 0);
        let hits = (0..1000)
            .filter(|_| {
                let d = lobes.sample(Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32())).unwrap();
                // The ray x + t·d meets the sphere.
                let t = (centre - x).dot(d);
                t > 0.0 && (x + d * t - centre).length() < 0.35
            })
            .count();
        assert!(hits > 900, "{hits} of 1000 lobe directions reach the sphere");
    }

    /// The relative second moment is 1 where every direction brings the same, 2 where half
    /// bring nothing and the rest the same (`E[X²]/E[X]²` of such an estimator), and it is
    /// measured with the best candidate mixture.
    #[test]
    fn relative_moment_of_even_and_sparse_directions() {
        // 100 directions, each g/p = 2, every candidate's density the drawn one.
        assert!((relative_moment(&[to_fixed(200.0), 100], &[to_fixed(400.0); MOMENTS]) - 1.0).abs() < 1e-6);
        // Half of them bring nothing.
        assert!((relative_moment(&[to_fixed(100.0), 100], &[to_fixed(200.0); MOMENTS]) - 2.0).abs() < 1e-6);
        // The lowest candidate counts; nothing measured reads 0.
        let mut m = [to_fixed(800.0); MOMENTS];
        m[3] = to_fixed(400.0);
        assert!((relative_moment(&[to_fixed(200.0), 100], &m) - 1.0).abs() < 1e-6);
        assert_eq!(relative_moment(&[0, 100], &[0; MOMENTS]), 0.0);
    }

    /// A cell whose directions' relative second moment is 2 (half bring nothing) and that
    /// received 3000 samples in the first iteration splits where `split_moment` is 1 (its
    /// count lowered to 4000/2) and not where it is off or 4 (whose bound 2 lies below it).
    #[test]
    fn cells_far_from_zero_variance_split_sooner() {
        let cells_after = |split_moment: f32| {
            let mut guide = cornell_paper_seed(6891, 50);
            guide.split_samples = 4000;
            guide.split_moment = split_moment;
            guide.learn_mix = true;
            let p0 = Vec3A::new(0.1, -1.0, 0.1);
            let cell = guide.cell(p0, Vec3A::Y);
            guide.begin_iteration();
            let mut d = guide.deposits();
            let p = DirectionDensities { drawn: 1.0, tree: 1.0, cosine: 1.0, source: None };
            for i in 0..3000u32 {
                let x = p0 + Vec3A::new((i % 50) as f32, 0.0, (i / 50) as f32) * 1e-4;
                assert_eq!(guide.cell(x, Vec3A::Y), cell);
                guide.deposit_estimates(&mut d, cell, x, Vec3A::ONE, Vec3A::ONE);
                guide.deposit_moments(&mut d, cell, (i % 2) as f32, p);
            }
            let before = guide.cells();
            guide.end_iteration(0, d).unwrap();
            (before, guide.cells())
        };
        let (before, off) = cells_after(0.0);
        assert_eq!(off, before);
        assert_eq!(cells_after(4.0).1, before);
        assert!(cells_after(1.0).1 > before);
    }

    #[test]
    fn cells_follow_the_photons_and_seeds_point_at_the_bright_ceiling() {
        let guide = cornell_paper_seed(20_000, 100);
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
