//! Caustic lobes: directions in which caustic photons arrived near a shading point.
//!
//! A source box around a glass object aims a receiving cell at the whole object, though from
//! any one point of a caustic only a small part of it images the light (the caustic is that
//! image), and which part moves quickly with the point (parallax close to the object). The
//! lobes follow the point instead: the caustic photons are kept in a sparse grid of small
//! voxels, and at a shading point each photon of its voxel (at most [`MAX_LOBES`], on the side
//! its normal faces) gives a cone around the direction that photon came from, a kernel
//! estimate of the caustic's directions there: each voxel's cones are as wide as its photons'
//! directions spread about their mean (1.5 times it). A photon's own direction
//! carries over to a nearby point better than the direction to its exit point would: light
//! converging to a caustic behind the receiver shifts its direction with the point by the
//! point's offset over the distance to that focus, not to the much closer glass. The mixture
//! of the cones, equally weighted, is a density known in closed form at every direction, so
//! the walk weighs it like any other component; where a voxel holds no photon there is no lobe
//! and nothing is drawn from it.

use crate::geometry::{Frame, Vec2, Vec3A, warp};
use crate::photon::Caustics;
use std::collections::HashMap;
use std::f32::consts::PI;

/// Most lobes at one point (photons of a voxel beyond it are thinned evenly).
pub const MAX_LOBES: usize = 16;
// A voxel's lobes at a point are a 16-bit mask.
const _: () = assert!(MAX_LOBES <= 16);
/// Voxels per side of the scene's extent.
const VOXELS: f32 = 64.0;
/// A voxel's cones' half-angle over its photons' angular spread (a kernel's bandwidth).
const SPREAD_WIDTH: f32 = 1.5;
/// The narrowest and widest cone half-angles (radians).
const MIN_HALF_ANGLE: f32 = 0.15;
const MAX_HALF_ANGLE: f32 = 0.5;
/// A photon's normal must agree with the shading normal by this cosine to count.
const NORMAL_AGREEMENT: f32 = 0.5;

/// The caustic photons' lobes, by voxel of where they landed.
#[derive(Debug, Default)]
pub struct CausticLobes {
    origin: Vec3A,
    inv_voxel: f32,
    /// Voxel → range of `lobes` and `normals`.
    voxels: HashMap<[i32; 3], (u32, u32)>,
    lobes: Vec<Lobe>,
    normals: Vec<Vec3A>,
}

impl CausticLobes {
    /// The lobes of `caustics` over a scene whose bounds start at `origin` with largest side
    /// `extent`; `None` without caustic photons.
    pub fn build(caustics: &Caustics, origin: Vec3A, extent: f32) -> Option<Self> {
        if caustics.position.is_empty() || !extent.is_finite() || extent <= 0.0 {
            return None;
        }
        let inv_voxel = VOXELS / extent;
        let key = |p: Vec3A| {
            let g = ((p - origin) * inv_voxel).floor();
            [g.x as i32, g.y as i32, g.z as i32]
        };
        // Photons grouped by voxel, in a deterministic order (voxel key, then photon index).
        let mut order: Vec<(u32, [i32; 3])> =
            caustics.position.iter().enumerate().map(|(i, &p)| (i as u32, key(p))).collect();
        order.sort_by_key(|&(i, k)| (k, i));
        let mut lobes = Self { origin, inv_voxel, ..Self::default() };
        let mut start = 0;
        let mut axes = Vec::with_capacity(MAX_LOBES);
        while start < order.len() {
            let k = order[start].1;
            let end = start + order[start..].iter().take_while(|o| o.1 == k).count();
            let n = end - start;
            let keep = n.min(MAX_LOBES);
            axes.clear();
            let first = lobes.lobes.len() as u32;
            for j in 0..keep {
                let i = order[start + j * n / keep].0 as usize;
                if let Some(axis) = (caustics.from[i] - caustics.position[i]).try_normalize() {
                    axes.push(axis);
                    lobes.normals.push(caustics.normal[i]);
                }
            }
            // The directions' spread about their mean (radians, small-angle): the cones' width.
            let mean = axes.iter().copied().sum::<Vec3A>().normalize_or_zero();
            let spread = if axes.len() > 1 {
                (axes.iter().map(|a| (*a - mean).length_squared()).sum::<f32>() / axes.len() as f32).sqrt()
            } else {
                0.0
            };
            let half = (SPREAD_WIDTH * spread).clamp(MIN_HALF_ANGLE, MAX_HALF_ANGLE);
            // 1 − cos θ as 2 sin²(θ/2): exact for narrow cones.
            let s = (0.5 * half).sin();
            let one_minus_cos = 2.0 * s * s;
            for &axis in &axes {
                lobes.lobes.push(Lobe { axis, one_minus_cos, density: 1.0 / (2.0 * PI * one_minus_cos) });
            }
            lobes.voxels.insert(k, (first, lobes.lobes.len() as u32));
            start = end;
        }
        Some(lobes)
    }

    /// The lobes at `x` (normal `n`): empty where `x`'s voxel holds no photon on its side.
    #[must_use]
    pub fn at(&self, x: Vec3A, n: Vec3A) -> Lobes<'_> {
        let g = ((x - self.origin) * self.inv_voxel).floor();
        let Some(&(a, b)) = self.voxels.get(&[g.x as i32, g.y as i32, g.z as i32]) else {
            return Lobes::default();
        };
        let (a, b) = (a as usize, b as usize);
        let mut mask = 0u16;
        for (i, normal) in self.normals[a..b].iter().enumerate() {
            if normal.dot(n) >= NORMAL_AGREEMENT {
                mask |= 1 << i;
            }
        }
        Lobes { lobes: &self.lobes[a..b], mask, count: mask.count_ones() }
    }
}

/// One cone of directions, sampled uniformly.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Lobe {
    axis: Vec3A,
    one_minus_cos: f32,
    /// `1 / (2π (1 − cos θ))`: the density per steradian inside the cone.
    density: f32,
}

/// The lobes at one point: an equal-weight mixture of the cones of a voxel that `mask` keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Lobes<'a> {
    lobes: &'a [Lobe],
    mask: u16,
    count: u32,
}

impl Lobes<'_> {
    /// Whether there is nothing to sample.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    fn kept(&self) -> impl Iterator<Item = &Lobe> {
        self.lobes.iter().enumerate().filter(|(i, _)| self.mask >> i & 1 == 1).map(|(_, l)| l)
    }

    /// A direction: the lobe at `u.z` (uniform in [0, 1)), uniform in its cone by `u.x, u.y`.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: Vec3A) -> Option<Vec3A> {
        if self.count == 0 {
            return None;
        }
        let j = ((u.z * self.count as f32) as usize).min(self.count as usize - 1);
        let l = self.kept().nth(j)?;
        let local = warp::uniform_cone(Vec2::new(u.x, u.y), l.one_minus_cos);
        Frame::from_normal(l.axis).to_world(local).try_normalize()
    }

    /// The density per steradian of [`Self::sample`]'s direction `d` (unit).
    #[inline]
    #[must_use]
    pub fn pdf(&self, d: Vec3A) -> f32 {
        if self.count == 0 {
            return 0.0;
        }
        let mut sum = 0.0;
        for l in self.kept() {
            // Inside the cone: 1 − d·axis ≤ 1 − cos θ, with 1 − d·axis as |d − axis|²/2 (no
            // cancellation in narrow cones).
            if 0.5 * (d - l.axis).length_squared() <= l.one_minus_cos {
                sum += l.density;
            }
        }
        sum / self.count as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::{Domain, SampleStream};

    fn lobes() -> CausticLobes {
        let mut caustics = Caustics::default();
        for i in 0..40 {
            let t = i as f32 / 40.0;
            caustics.position.push(Vec3A::new(0.01 * t, 0.0, 0.02 * t));
            caustics.normal.push(Vec3A::Y);
            caustics.flux.push(Vec3A::ONE);
            caustics.from.push(Vec3A::new(0.3 * t - 0.1, 0.2 + 0.5 * t, 0.1));
        }
        CausticLobes::build(&caustics, Vec3A::splat(-1.0), 4.0).unwrap()
    }

    /// The cones' mixture integrates to 1 over the sphere and its samples land where the
    /// density is: the mean of 1/pdf over its own samples is the solid angle it covers, and
    /// a uniform estimate of ∫ pdf dω is 1 (a z-bound of 5 for each, fixed seed).
    #[test]
    fn lobe_density_is_the_density_of_its_samples() {
        let built = lobes();
        let l = built.at(Vec3A::new(0.005, 0.0, 0.01), Vec3A::Y);
        assert_eq!(l.count as usize, MAX_LOBES);
        let mut rng = SampleStream::in_domain(Domain::Photon, 7, 0, 0);
        let n = 400_000;
        let mut outside = 0;
        // ∫ pdf dω by importance sampling from the lobes themselves: E[pdf/pdf] over its
        // support is 1 only if every sample has positive density; and uniform over the
        // sphere: E[4π pdf(ω)] = 1.
        let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let (a, b) = (rng.next_2d(), rng.next_f32());
            let v = f64::from(4.0 * PI * l.pdf(warp::uniform_sphere(a)));
            sum += v;
            sum_sq += v * v;
            let s = l.sample(Vec3A::new(rng.next_f32(), rng.next_f32(), b)).unwrap();
            outside += usize::from(l.pdf(s) == 0.0);
        }
        // Rounding may put a sample on a cone's rim just outside it: rarely.
        assert!(outside <= n / 100_000, "{outside} samples outside every cone");
        let mean = sum / n as f64;
        let sd = ((sum_sq / n as f64 - mean * mean) / n as f64).sqrt();
        assert!((mean - 1.0).abs() < 5.0 * sd, "∫ pdf = {mean} ± {sd}");
        // Samples of one lobe of a known width: the fraction of samples inside a cone half
        // as wide is (1 − cos(θ/2)) / (1 − cos θ) for a uniform cone.
        let one = &l.lobes[0];
        let theta = (1.0 - one.one_minus_cos).acos();
        let single = Lobes { lobes: std::slice::from_ref(one), mask: 1, count: 1 };
        let inside = (0..n)
            .filter(|_| {
                let s = single.sample(Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32())).unwrap();
                s.dot(one.axis) >= (0.5 * theta).cos()
            })
            .count() as f64
            / n as f64;
        let expected = f64::from((1.0 - (0.5 * theta).cos()) / one.one_minus_cos);
        let sd = (expected * (1.0 - expected) / n as f64).sqrt();
        assert!((inside - expected).abs() < 5.0 * sd, "{inside} vs {expected}");
    }

    /// No lobe where no photon landed, or on the other side of the surface.
    #[test]
    fn no_lobes_away_from_the_photons() {
        let mut caustics = Caustics::default();
        caustics.position.push(Vec3A::ZERO);
        caustics.normal.push(Vec3A::Y);
        caustics.flux.push(Vec3A::ONE);
        caustics.from.push(Vec3A::new(0.0, 0.5, 0.0));
        let built = CausticLobes::build(&caustics, Vec3A::splat(-1.0), 4.0).unwrap();
        assert!(!built.at(Vec3A::new(0.001, 0.0, 0.001), Vec3A::Y).is_empty());
        assert!(built.at(Vec3A::new(0.001, 0.0, 0.001), -Vec3A::Y).is_empty());
        assert!(built.at(Vec3A::new(0.5, 0.0, 0.5), Vec3A::Y).is_empty());
        assert_eq!(built.at(Vec3A::new(0.5, 0.0, 0.5), Vec3A::Y).pdf(Vec3A::Y), 0.0);
        assert!(CausticLobes::build(&Caustics::default(), Vec3A::ZERO, 1.0).is_none());
    }
}
