//! Microfacet distributions in the local shading frame (+z the normal): GGX (Trowbridge–Reitz)
//! and Beckmann, each with its normal density `D`, Smith's masking `G1` (exact for both) and a
//! masking–shadowing `G` that is height-correlated (pbrt-v4's and our default) or separable,
//! `G1(wi)·G1(wo)` (Mitsuba 3's); and sampling of the normals visible from a direction, whose
//! density is `G1(wi)·max(0, wi·m)·D(m) / wi.z`. GGX's visible normals are sampled as in Heitz
//! 2018 ("Sampling the GGX Distribution of Visible Normals"); Beckmann's by inverting the
//! visible slopes' distribution numerically (Heitz and d'Eon 2014 describe the set-up).
use crate::geometry::{Vec2, Vec3A};
use std::f32::consts::{PI, TAU};

/// The shape of a microfacet distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
#[repr(u8)]
pub enum Distribution {
    /// GGX (Trowbridge–Reitz): long tails.
    #[default]
    Ggx,
    /// Beckmann: a Gaussian of slopes (Mitsuba 3's default).
    Beckmann,
}

/// How masking and shadowing combine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
#[repr(u8)]
pub enum Masking {
    /// Height-correlated, `1/(1 + Λ(wi) + Λ(wo))` (Heitz 2014; pbrt-v4).
    #[default]
    Correlated,
    /// Separable, `G1(wi)·G1(wo)` (Mitsuba 3).
    Separable,
}

/// A microfacet distribution of roughness `alpha` (the `α` of Walter et al. 2007; Mitsuba's
/// `alpha`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    pub alpha: f32,
    pub distribution: Distribution,
    pub masking: Masking,
}

/// `1/√π`.
const FRAC_1_SQRT_PI: f64 = 0.564_189_583_547_756_3;

impl Microfacet {
    /// Roughness below which a surface is treated as smooth (a delta lobe) by the materials.
    pub const MIN_ALPHA: f32 = 1e-3;

    /// A distribution of roughness `alpha` (the materials treat one below
    /// [`Microfacet::MIN_ALPHA`] as smooth; the functions here need `alpha > 0`).
    #[must_use]
    pub fn new(distribution: Distribution, masking: Masking, alpha: f32) -> Self {
        Self { alpha, distribution, masking }
    }

    /// GGX with height-correlated masking.
    #[must_use]
    pub fn ggx(alpha: f32) -> Self {
        Self::new(Distribution::Ggx, Masking::Correlated, alpha)
    }

    /// The same distribution with roughness `alpha`.
    #[must_use]
    pub fn with_alpha(self, alpha: f32) -> Self {
        Self::new(self.distribution, self.masking, alpha)
    }

    /// Density of microfacet normals `m` per projected area: `∫ D(m)·m.z dm = 1`.
    #[inline]
    #[must_use]
    pub fn d(&self, m: Vec3A) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let cos2 = m.z * m.z;
        let sin2 = m.x * m.x + m.y * m.y;
        match self.distribution {
            Distribution::Ggx => {
                let t = sin2 / a2 + cos2;
                1.0 / (PI * a2 * t * t)
            }
            Distribution::Beckmann => {
                let e = (-sin2 / (cos2 * a2)).exp();
                if e == 0.0 { 0.0 } else { e / (PI * a2 * cos2 * cos2) }
            }
        }
    }

    /// Smith's `Λ(w)`.
    #[inline]
    #[must_use]
    pub fn lambda(&self, w: Vec3A) -> f32 {
        let cos2 = w.z * w.z;
        if cos2 <= 0.0 {
            return f32::INFINITY;
        }
        let sin2 = w.x * w.x + w.y * w.y;
        match self.distribution {
            Distribution::Ggx => 0.5 * ((1.0 + self.alpha * self.alpha * sin2 / cos2).sqrt() - 1.0),
            Distribution::Beckmann => {
                if sin2 <= 0.0 {
                    return 0.0;
                }
                // a = cot θ / α; Λ = (e^{-a²}/(a√π) − erfc(a)) / 2, below 1e-9 beyond a = 4.
                let a = f64::from(w.z.abs()) / (f64::from(self.alpha) * f64::from(sin2).sqrt());
                if a > 4.5 {
                    return 0.0;
                }
                (0.5 * ((-a * a).exp() * FRAC_1_SQRT_PI / a - libm::erfc(a))) as f32
            }
        }
    }

    /// Smith's masking of `w`, seen through microfacet `m`.
    #[inline]
    #[must_use]
    pub fn g1(&self, w: Vec3A, m: Vec3A) -> f32 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// Masking–shadowing of `wi` and `wo` (both on the side `m` faces).
    #[inline]
    #[must_use]
    pub fn g(&self, wi: Vec3A, wo: Vec3A, m: Vec3A) -> f32 {
        if wi.dot(m) * wi.z <= 0.0 || wo.dot(m) * wo.z <= 0.0 {
            return 0.0;
        }
        let (li, lo) = (self.lambda(wi), self.lambda(wo));
        match self.masking {
            Masking::Correlated => 1.0 / (1.0 + li + lo),
            Masking::Separable => 1.0 / ((1.0 + li) * (1.0 + lo)),
        }
    }

    /// A microfacet normal visible from `wi` (`wi.z > 0`), with density
    /// [`Microfacet::visible_pdf`].
    #[must_use]
    pub fn sample_visible(&self, wi: Vec3A, u: Vec2) -> Vec3A {
        match self.distribution {
            Distribution::Ggx => self.sample_visible_ggx(wi, u),
            Distribution::Beckmann => self.sample_visible_beckmann(wi, u),
        }
    }

    fn sample_visible_ggx(&self, wi: Vec3A, u: Vec2) -> Vec3A {
        // Stretch to the unit-roughness configuration.
        let vh = Vec3A::new(self.alpha * wi.x, self.alpha * wi.y, wi.z).normalize();
        // An orthonormal basis around vh.
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3A::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3A::X };
        let t2 = vh.cross(t1);
        // A point on the projected disc, its far half compressed by the view.
        let r = u.x.sqrt();
        let (s, c) = (TAU * u.y).sin_cos();
        let p1 = r * c;
        let mut p2 = r * s;
        let h = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - h) * (1.0 - p1 * p1).max(0.0).sqrt() + h * p2;
        let p3 = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        let nh = p1 * t1 + p2 * t2 + p3 * vh;
        // Unstretch.
        Vec3A::new(self.alpha * nh.x, self.alpha * nh.y, nh.z.max(1e-7)).normalize()
    }

    /// Beckmann's visible normals (see [`BeckmannView`]).
    fn sample_visible_beckmann(&self, wi: Vec3A, u: Vec2) -> Vec3A {
        let frame = BeckmannView::new(self.alpha, wi);
        frame.normal(frame.slope_x(u.x), BeckmannView::slope_y(u.y))
    }

    /// `f` of the normals [`Microfacet::sample_visible`] gives from `wi` at the midpoints of an
    /// `n × n` grid over its square, row by row (`u.x` outer): the same normals, bit for bit,
    /// but for Beckmann each of the `n` values of `u.x` and of `u.y` is inverted once, not `n`
    /// times (a rough plastic's coat table is such a grid per incidence).
    pub fn for_visible_grid(&self, wi: Vec3A, n: usize, mut f: impl FnMut(Vec3A)) {
        let mid = |k: usize| (k as f32 + 0.5) / n as f32;
        match self.distribution {
            Distribution::Ggx => {
                for a in 0..n {
                    for b in 0..n {
                        f(self.sample_visible_ggx(wi, Vec2::new(mid(a), mid(b))));
                    }
                }
            }
            Distribution::Beckmann => {
                let frame = BeckmannView::new(self.alpha, wi);
                let ys: Vec<f64> = (0..n).map(|b| BeckmannView::slope_y(mid(b))).collect();
                for a in 0..n {
                    let x = frame.slope_x(mid(a));
                    for &y in &ys {
                        f(frame.normal(x, y));
                    }
                }
            }
        }
    }

    /// Density (solid angle of `m`) of [`Microfacet::sample_visible`] from `wi`.
    #[inline]
    #[must_use]
    pub fn visible_pdf(&self, wi: Vec3A, m: Vec3A) -> f32 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        self.g1(wi, m) * wi.dot(m).max(0.0) * self.d(m) / wi.z
    }
}

/// The `x` in `[lo, hi]` where the increasing `f` (returning its value and derivative) meets
/// `target`: Newton's steps, bisection when a step leaves the bracket, until the value is
/// within 1e-13 of the target's scale or the bracket is 1e-13 wide (the ends when the target
/// lies beyond them).
fn solve_increasing(mut lo: f64, mut hi: f64, target: f64, f: impl Fn(f64) -> (f64, f64)) -> f64 {
    let tolerance = 1e-13 * target.abs().max(f(hi).0.abs()).max(1e-300);
    let mut x = 0.0f64.clamp(lo, hi);
    for _ in 0..100 {
        let (v, dv) = f(x);
        let err = v - target;
        if err.abs() <= tolerance {
            return x;
        }
        if err > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        if hi - lo <= 1e-13 * (1.0 + x.abs()) {
            break;
        }
        let step = x - err / dv;
        x = if step > lo && step < hi && step.is_finite() { step } else { 0.5 * (lo + hi) };
    }
    x
}

/// Beckmann's visible normals from one direction, in slopes: stretched to unit roughness and
/// turned so that `wi` lies in the xz-plane at angle `θ`, a normal `m ∝ (−x, −y, 1)` is visible
/// when `x < cot θ`, and visible slopes have the density `∝ e^{−x²−y²}·(cot θ − x)` there. So
/// `y` is a standard Gaussian over `√2` (`erf(y) = 2u − 1`), and `x` has the cumulative
/// `C(x) = cot θ·(√π/2)·(1 + erf x) + e^{−x²}/2`, inverted numerically to 1e-12 relative: the
/// density sampled is the formula's.
struct BeckmannView {
    alpha: f64,
    cos_phi: f64,
    sin_phi: f64,
    /// `cot θ`, or `None` at normal incidence (where the weight `cot θ − x` is constant).
    cot: Option<f64>,
}

impl BeckmannView {
    fn new(alpha: f32, wi: Vec3A) -> Self {
        let alpha = f64::from(alpha);
        let (sx, sy, sz) = (alpha * f64::from(wi.x), alpha * f64::from(wi.y), f64::from(wi.z));
        let sin = (sx * sx + sy * sy).sqrt();
        let (cos_phi, sin_phi) = if sin > 0.0 { (sx / sin, sy / sin) } else { (1.0, 0.0) };
        let cot = if sin <= 1e-12 * sz { None } else { Some(sz / sin) };
        Self { alpha, cos_phi, sin_phi, cot }
    }

    /// The slope along the view's azimuth for the sample `u1`.
    fn slope_x(&self, u1: f32) -> f64 {
        let u1 = f64::from(u1);
        match self.cot {
            None => {
                solve_increasing(-6.0, 6.0, 2.0 * u1 - 1.0, |x| (libm::erf(x), 2.0 * FRAC_1_SQRT_PI * (-x * x).exp()))
            }
            Some(cot) => {
                let half_sqrt_pi = 0.5 / FRAC_1_SQRT_PI;
                let cdf = |x: f64| cot * half_sqrt_pi * (1.0 + libm::erf(x)) + 0.5 * (-x * x).exp();
                let total = cdf(cot);
                solve_increasing(-6.0, cot.min(6.0), u1 * total, |x| (cdf(x), (-x * x).exp() * (cot - x)))
            }
        }
    }

    /// The slope across the view's azimuth for the sample `u2` (the same from every view).
    fn slope_y(u2: f32) -> f64 {
        let u2 = f64::from(u2);
        solve_increasing(-6.0, 6.0, 2.0 * u2 - 1.0, |y| (libm::erf(y), 2.0 * FRAC_1_SQRT_PI * (-y * y).exp()))
    }

    /// The normal of the slopes `(x, y)`: turned back and unstretched.
    fn normal(&self, x: f64, y: f64) -> Vec3A {
        let (px, py) =
            (self.alpha * (self.cos_phi * x - self.sin_phi * y), self.alpha * (self.sin_phi * x + self.cos_phi * y));
        Vec3A::new(-px as f32, -py as f32, 1.0).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;

    const BOTH: [Distribution; 2] = [Distribution::Ggx, Distribution::Beckmann];

    fn dir(theta: f32, phi: f32) -> Vec3A {
        Vec3A::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    /// `∫ D(m) m.z dm = 1` and `∫ visible_pdf dm = 1`, by a midpoint rule in (cos θ, φ)
    /// (errors of the rule: below 1e-3 at these grids for α ≥ 0.1).
    #[test]
    fn densities_integrate_to_one() {
        for (distribution, alpha) in [0.1, 0.3, 0.7, 1.0].into_iter().flat_map(|a| BOTH.map(|d| (d, a))) {
            let mf = Microfacet::new(distribution, Masking::Correlated, alpha);
            let wi = dir(1.0, 0.4);
            let (n_t, n_p) = (4000, 64);
            let (mut proj, mut vis) = (0.0f64, 0.0f64);
            for i in 0..n_t {
                // Fine near the pole, where D peaks: cosθ = 1 − x², x uniform.
                let x = (i as f64 + 0.5) / n_t as f64;
                let cos = 1.0 - x * x;
                let jac = 2.0 * x / n_t as f64;
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                for j in 0..n_p {
                    let phi = TAU as f64 * (j as f64 + 0.5) / n_p as f64;
                    let m = Vec3A::new((sin * phi.cos()) as f32, (sin * phi.sin()) as f32, cos as f32);
                    let dw = jac * TAU as f64 / n_p as f64;
                    proj += f64::from(mf.d(m)) * cos * dw;
                    vis += f64::from(mf.visible_pdf(wi, m)) * dw;
                }
            }
            assert!((proj - 1.0).abs() < 2e-3, "{distribution:?} alpha {alpha}: ∫D cos = {proj}");
            assert!((vis - 1.0).abs() < 2e-3, "{distribution:?} alpha {alpha}: ∫ visible pdf = {vis}");
        }
    }

    /// The grid walk gives the normals of `sample_visible` at the grid's midpoints, bit for bit.
    #[test]
    fn visible_grid_is_sample_visible() {
        for (distribution, alpha) in [0.05, 0.3].into_iter().flat_map(|a| BOTH.map(|d| (d, a))) {
            let mf = Microfacet::new(distribution, Masking::Correlated, alpha);
            for wi in [Vec3A::Z, dir(0.7, 0.4), dir(1.5, 2.0)] {
                let n = 7;
                let mut grid = Vec::new();
                mf.for_visible_grid(wi, n, |m| grid.push(m));
                let mid = |k: usize| (k as f32 + 0.5) / n as f32;
                let each: Vec<Vec3A> =
                    (0..n * n).map(|k| mf.sample_visible(wi, Vec2::new(mid(k / n), mid(k % n)))).collect();
                assert_eq!(grid, each, "{distribution:?} alpha {alpha} wi {wi}");
            }
        }
    }

    /// Visible normals face the viewer and lie in the upper hemisphere.
    #[test]
    fn visible_normals_are_visible() {
        let mut rng = SampleStream::new(3, 0, 0);
        for (distribution, alpha) in [0.01, 0.2, 1.0].into_iter().flat_map(|a| BOTH.map(|d| (d, a))) {
            let mf = Microfacet::new(distribution, Masking::Correlated, alpha);
            for k in 0..2000 {
                let wi = dir(1.5 * (k as f32 / 2000.0), 6.0 * rng.next_f32());
                let m = mf.sample_visible(wi, rng.next_2d());
                assert!(m.z > 0.0 && wi.dot(m) >= -1e-5 && m.is_normalized(), "{wi} {m}");
            }
        }
    }
}
