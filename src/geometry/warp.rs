//! Sampling warps from `[0,1)²` to directions and points, each with its density.
use super::Vec2;
use glam::Vec3A;
use std::f32::consts::{FRAC_1_PI, TAU};

/// Cosine-weighted hemisphere around +z via the *cosine warp* `sinθ = √u`, `φ = 2πv`
/// (ALGORITHM.md §2 uses the same map for the guide grid, so a uniform grid cell in `(u, v)`
/// is a cosine-weighted patch of the hemisphere).
#[inline]
#[must_use]
pub fn cosine_hemisphere(u: Vec2) -> Vec3A {
    let sin_theta = u.x.sqrt();
    let cos_theta = (1.0 - u.x).max(0.0).sqrt();
    let (s, c) = (TAU * u.y).sin_cos();
    Vec3A::new(c * sin_theta, s * sin_theta, cos_theta)
}

/// Inverse of [`cosine_hemisphere`]: the `(u, v)` that maps to local direction `w` (`w.z ≥ 0`).
#[inline]
#[must_use]
pub fn cosine_hemisphere_inverse(w: Vec3A) -> Vec2 {
    let u = (w.x * w.x + w.y * w.y).clamp(0.0, 1.0);
    // The polynomial atan2 (4e-7 rad): this runs at every guided vertex and deposit.
    let mut phi = super::fastmath::atan2(w.y, w.x);
    if phi < 0.0 {
        phi += TAU;
    }
    Vec2::new(u, (phi / TAU).min(1.0 - f32::EPSILON))
}

/// Solid-angle density of [`cosine_hemisphere`]: `cosθ/π` above the surface, 0 below.
#[inline]
#[must_use]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform direction on the unit sphere by the cylindrical equal-area map `cosθ = 1 − 2u`,
/// `φ = 2πv`: equal areas of the square are equal solid angles, so a density `p` over the
/// square is `p/(4π)` per steradian.
#[inline]
#[must_use]
pub fn uniform_sphere(u: Vec2) -> Vec3A {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (TAU * u.y).sin_cos();
    Vec3A::new(r * c, r * s, z)
}

/// A direction uniform in the cone about +z whose half-angle θ has `1 − cos θ = one_minus_cos`
/// (given so, not as cos θ, to keep narrow cones exact); density `1 / (2π·one_minus_cos)`.
#[inline]
#[must_use]
pub fn uniform_cone(u: Vec2, one_minus_cos: f32) -> Vec3A {
    let one_minus_cos = u.x * one_minus_cos;
    let cos = 1.0 - one_minus_cos;
    let sin = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3A::new(sin * phi.cos(), sin * phi.sin(), cos)
}

/// Inverse of [`uniform_sphere`]: the point of the square that maps to unit direction `w`.
#[inline]
#[must_use]
pub fn uniform_sphere_inverse(w: Vec3A) -> Vec2 {
    let u = ((1.0 - w.z) * 0.5).clamp(0.0, 1.0 - f32::EPSILON);
    let mut phi = super::fastmath::atan2(w.y, w.x);
    if phi < 0.0 {
        phi += TAU;
    }
    Vec2::new(u, (phi / TAU).clamp(0.0, 1.0 - f32::EPSILON))
}

/// Uniform point on the unit disk (polar: `r = √u`, `φ = 2πv`); density `1/π`.
#[inline]
#[must_use]
pub fn uniform_disk(u: Vec2) -> Vec2 {
    let r = u.x.sqrt();
    let (s, c) = (TAU * u.y).sin_cos();
    Vec2::new(r * c, r * s)
}

/// Uniform point on a triangle as barycentrics `(b0, b1, b2)`; density `1/area`.
#[inline]
#[must_use]
pub fn uniform_triangle(u: Vec2) -> [f32; 3] {
    let su = u.x.sqrt();
    let b0 = 1.0 - su;
    let b1 = u.y * su;
    [b0, b1, 1.0 - b0 - b1]
}

/// Sample of the linear density `∝ (1−x)·a + x·b` on `[0,1]` (`a, b ≥ 0`), by inverting its
/// CDF in the form that does not divide by `b − a`.
#[inline]
#[must_use]
pub fn linear(u: f32, a: f32, b: f32) -> f32 {
    if a == b {
        return u;
    }
    let x = u * (a + b) / (a + (a * a + u * (b * b - a * a)).max(0.0).sqrt());
    x.min(1.0)
}

/// Sample of the bilinear density on `[0,1]²` with corner weights `w = [w00, w10, w01, w11]`
/// (`w_xy`, all ≥ 0, not all zero): `y` from its linear marginal, then `x` given `y`.
#[inline]
#[must_use]
pub fn bilinear(u: Vec2, w: [f32; 4]) -> Vec2 {
    let y = linear(u.y, w[0] + w[1], w[2] + w[3]);
    let x = linear(u.x, (1.0 - y) * w[0] + y * w[2], (1.0 - y) * w[1] + y * w[3]);
    Vec2::new(x, y)
}

/// Density of [`bilinear`] at `p`: the bilinear interpolant over its mean.
#[inline]
#[must_use]
pub fn bilinear_pdf(p: Vec2, w: [f32; 4]) -> f32 {
    let sum = w[0] + w[1] + w[2] + w[3];
    if sum <= 0.0 {
        return 1.0;
    }
    let value =
        (1.0 - p.x) * (1.0 - p.y) * w[0] + p.x * (1.0 - p.y) * w[1] + (1.0 - p.x) * p.y * w[2] + p.x * p.y * w[3];
    4.0 * value / sum
}

/// Picks an item with probability ∝ its weight from a short list without building a CDF (the
/// per-call, allocation-free counterpart of [`Discrete`]): `total` is the weights' sum, `u` in
/// `[0, 1)`. Returns the item and its probability; zero-weight items are never picked (the last
/// positive one takes any rounding rest); `None` when no weight is positive.
#[inline]
#[must_use]
pub fn pick_by_weight(weights: &[f32], total: f32, u: f32) -> Option<(usize, f32)> {
    pick_by_weight_reusing(weights, total, u).map(|(i, p, _)| (i, p))
}

/// As [`pick_by_weight`], also returning `u` rescaled to `[0, 1)` within the picked item's
/// share: uniform again and independent of the pick, so one number can pick and then place.
#[inline]
#[must_use]
pub fn pick_by_weight_reusing(weights: &[f32], total: f32, u: f32) -> Option<(usize, f32, f32)> {
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let target = u * total;
    let mut acc = 0.0;
    let mut pick = None;
    for (i, &w) in weights.iter().enumerate() {
        if w > 0.0 {
            pick = Some((i, acc));
            acc += w;
            if target < acc {
                break;
            }
        }
    }
    pick.map(|(i, below)| (i, weights[i] / total, ((target - below) / weights[i]).clamp(0.0, 1.0 - f32::EPSILON)))
}

/// A discrete distribution over `n` items by weight, sampled by inverting its CDF.
#[derive(Clone, Debug, Default)]
pub struct Discrete {
    cdf: Vec<f32>,
    pmf: Vec<f32>,
}

impl Discrete {
    /// Builds from non-negative weights; `None` when they sum to zero (or any is not finite).
    #[must_use]
    pub fn new(weights: &[f32]) -> Option<Self> {
        if weights.iter().any(|w| !w.is_finite() || *w < 0.0) {
            return None;
        }
        let total: f64 = weights.iter().map(|&w| w as f64).sum();
        if total <= 0.0 {
            return None;
        }
        let mut acc = 0.0f64;
        let mut cdf = Vec::with_capacity(weights.len());
        for &w in weights {
            acc += w as f64;
            cdf.push((acc / total) as f32);
        }
        // The last entry must be exactly one so that every u < 1 finds a bucket.
        *cdf.last_mut().unwrap() = 1.0;
        let pmf = weights.iter().map(|&w| (w as f64 / total) as f32).collect();
        Some(Self { cdf, pmf })
    }

    /// Picks an item with probability ∝ its weight; returns the item and its probability.
    #[inline]
    #[must_use]
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let i = self.cdf.partition_point(|&c| c <= u).min(self.cdf.len() - 1);
        // Zero-weight items are never picked: skip any bucket of zero width.
        (i, self.pmf[i])
    }

    /// As [`Self::sample`], also returning `u` rescaled to be uniform again within the
    /// picked item's interval (for use as a further number).
    #[inline]
    #[must_use]
    pub fn sample_reusing(&self, u: f32) -> (usize, f32, f32) {
        let (i, p) = self.sample(u);
        let below = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let rest = if p > 0.0 { ((u - below) / (self.cdf[i] - below)).clamp(0.0, 1.0 - f32::EPSILON) } else { 0.5 };
        (i, p, rest)
    }

    #[inline]
    #[must_use]
    pub fn pmf(&self, i: usize) -> f32 {
        self.pmf[i]
    }

    #[must_use]
    pub fn len(&self) -> usize {
        self.pmf.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.pmf.is_empty()
    }
}

/// pbrt-v4's equal-area octahedral map (Clarberg 2008) from a unit direction to `[0, 1]²`:
/// the upper hemisphere (`z ≥ 0`) fills the inner diamond, the lower one the corners.
#[must_use]
pub fn equal_area_sphere_to_square(d: Vec3A) -> Vec2 {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let (a, b) = (x.max(y), x.min(y));
    let b = if a == 0.0 { 0.0 } else { b / a };
    let mut phi = b.atan() * std::f32::consts::FRAC_2_PI;
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        std::mem::swap(&mut u, &mut v);
        u = 1.0 - u;
        v = 1.0 - v;
    }
    Vec2::new((u.copysign(d.x) + 1.0) * 0.5, (v.copysign(d.y) + 1.0) * 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;
    use crate::stats::chi_square_critical;
    use std::f64::consts::PI;

    /// The sphere map and its inverse agree, and equal areas of the square are equal solid
    /// angles: the share of 100,000 directions with `z > 0.6` is 0.2 within 5 standard
    /// deviations (0.0063).
    #[test]
    fn uniform_sphere_round_trips_and_is_uniform() {
        let mut rng = SampleStream::new(3, 0, 0);
        let (n, mut above) = (100_000, 0u32);
        for _ in 0..n {
            let u = rng.next_2d();
            let w = uniform_sphere(u);
            assert!((w.length() - 1.0).abs() < 1e-5);
            let back = uniform_sphere_inverse(w);
            assert!((back - u).abs().max_element() < 1e-3 || (back.y - u.y).abs() > 0.999, "{u} -> {w} -> {back}");
            above += u32::from(w.z > 0.6);
        }
        let share = f64::from(above) / f64::from(n);
        assert!((share - 0.2).abs() < 5.0 * (0.2f64 * 0.8 / f64::from(n)).sqrt(), "share {share}");
    }

    /// Midpoint rule over the sphere in (cosθ, φ): ∫ pdf dω = 1 for the cosine warp.
    #[test]
    fn cosine_pdf_integrates_to_one() {
        let (n_mu, n_phi) = (2000, 64);
        let mut sum = 0.0f64;
        for i in 0..n_mu {
            let mu = -1.0 + (i as f64 + 0.5) * 2.0 / n_mu as f64;
            sum += cosine_hemisphere_pdf(mu as f32) as f64 * (2.0 / n_mu as f64) * 2.0 * PI;
        }
        let _ = n_phi;
        assert!((sum - 1.0).abs() < 1e-4, "integral {sum}");
    }

    /// Histogram over (cosθ, φ) cells against the pdf integrated over each cell.
    #[test]
    fn cosine_samples_follow_pdf_chi_square() {
        let (n_mu, n_phi, n) = (10usize, 12usize, 200_000usize);
        let mut hist = vec![0f64; n_mu * n_phi];
        let mut rng = SampleStream::new(7, 0, 0);
        for _ in 0..n {
            let w = cosine_hemisphere(rng.next_2d());
            assert!(w.z >= 0.0 && (w.length() - 1.0).abs() < 1e-5);
            let i = ((w.z as f64 * n_mu as f64) as usize).min(n_mu - 1);
            let mut phi = (w.y as f64).atan2(w.x as f64);
            if phi < 0.0 {
                phi += 2.0 * PI;
            }
            let j = ((phi / (2.0 * PI) * n_phi as f64) as usize).min(n_phi - 1);
            hist[i * n_phi + j] += 1.0;
        }
        // Cell i spans cosθ ∈ [i/n_mu, (i+1)/n_mu]: ∫ cosθ/π dω = (c1² − c0²)/2 / n_phi.
        let mut chi2 = 0.0;
        for i in 0..n_mu {
            let (c0, c1) = (i as f64 / n_mu as f64, (i + 1) as f64 / n_mu as f64);
            let p = (c1 * c1 - c0 * c0) / n_phi as f64;
            for j in 0..n_phi {
                let e = p * n as f64;
                chi2 += (hist[i * n_phi + j] - e).powi(2) / e;
            }
        }
        let crit = chi_square_critical(n_mu * n_phi - 1, 1e-4);
        assert!(chi2 < crit, "chi2 {chi2} >= {crit}");
    }

    #[test]
    fn cosine_inverse_round_trips() {
        let mut rng = SampleStream::new(3, 1, 2);
        for _ in 0..10_000 {
            let u = rng.next_2d();
            let back = cosine_hemisphere_inverse(cosine_hemisphere(u));
            assert!((back - u).abs().max_element() < 1e-3, "{u} -> {back}");
        }
    }

    /// Barycentric samples: uniform over the triangle, checked on a grid of (b1, b2) cells whose
    /// expected mass is the cell's area inside the triangle (also integrates the pdf to one).
    #[test]
    fn triangle_samples_uniform_chi_square() {
        let (g, n) = (8usize, 200_000usize);
        let mut hist = vec![0f64; g * g];
        let mut rng = SampleStream::new(11, 0, 0);
        for _ in 0..n {
            let b = uniform_triangle(rng.next_2d());
            assert!(b.iter().all(|&x| (-1e-6..=1.0 + 1e-6).contains(&x)));
            assert!((b[0] + b[1] + b[2] - 1.0).abs() < 1e-5);
            let i = ((b[1] * g as f32) as usize).min(g - 1);
            let j = ((b[2] * g as f32) as usize).min(g - 1);
            hist[i * g + j] += 1.0;
        }
        // Cell ∩ {b1 + b2 ≤ 1}, exactly: below the diagonal, on it (half), or above it.
        let mut total_p = 0.0;
        let mut chi2 = 0.0;
        let mut dof = 0;
        for i in 0..g {
            for j in 0..g {
                let fraction = match (i + j + 1).cmp(&g) {
                    std::cmp::Ordering::Less => 1.0,
                    std::cmp::Ordering::Equal => 0.5,
                    std::cmp::Ordering::Greater => 0.0,
                };
                let p = fraction / (g * g) as f64 / 0.5;
                total_p += p;
                let e = p * n as f64;
                if e > 5.0 {
                    chi2 += (hist[i * g + j] - e).powi(2) / e;
                    dof += 1;
                } else {
                    assert!(hist[i * g + j] <= 3.0 * e + 10.0);
                }
            }
        }
        assert!((total_p - 1.0).abs() < 1e-12, "pdf integrates to {total_p}");
        let crit = chi_square_critical(dof - 1, 1e-4);
        assert!(chi2 < crit, "chi2 {chi2} >= {crit}");
    }

    /// Bilinear warp: 8×8 cell histogram against the density integrated over each cell (for a
    /// bilinear function the midpoint rule is exact), chi-square at 1e-4; the pdf integrates
    /// to one; degenerate corners (zeros, equal weights) stay inside the square.
    #[test]
    fn bilinear_samples_follow_pdf_chi_square() {
        for w in [[1.0, 2.0, 0.5, 4.0], [0.01, 0.01, 1.0, 0.2], [0.0, 1.0, 0.0, 0.0], [3.0, 3.0, 3.0, 3.0]] {
            let cells = 8usize;
            let n = 200_000usize;
            let mut hist = vec![0f64; cells * cells];
            let mut rng = SampleStream::new(9, 0, 0);
            for _ in 0..n {
                let p = bilinear(rng.next_2d(), w);
                assert!((0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y), "{w:?}: {p}");
                let (i, j) =
                    (((p.x * cells as f32) as usize).min(cells - 1), ((p.y * cells as f32) as usize).min(cells - 1));
                hist[j * cells + i] += 1.0;
            }
            let (mut chi2, mut total) = (0.0, 0.0);
            let mut dof = 0;
            for j in 0..cells {
                for i in 0..cells {
                    let mid = Vec2::new((i as f32 + 0.5) / cells as f32, (j as f32 + 0.5) / cells as f32);
                    let p = bilinear_pdf(mid, w) as f64 / (cells * cells) as f64;
                    total += p;
                    let e = p * n as f64;
                    if e > 0.0 {
                        chi2 += (hist[j * cells + i] - e).powi(2) / e;
                        dof += 1;
                    } else {
                        assert_eq!(hist[j * cells + i], 0.0);
                    }
                }
            }
            assert!((total - 1.0).abs() < 1e-5, "{w:?}: pdf integrates to {total}");
            let bound = chi_square_critical(dof - 1, 1e-4);
            assert!(chi2 < bound, "{w:?}: chi-square {chi2} ≥ {bound}");
        }
    }

    #[test]
    fn pick_by_weight_follows_the_weights() {
        let w = [0.0, 1.0, 0.0, 3.0, 0.0];
        assert_eq!(pick_by_weight(&w, 4.0, 0.0), Some((1, 0.25)));
        assert_eq!(pick_by_weight(&w, 4.0, 0.2499), Some((1, 0.25)));
        assert_eq!(pick_by_weight(&w, 4.0, 0.25), Some((3, 0.75)));
        // Rounding past the end falls on the last positive weight, never on a zero one.
        assert_eq!(pick_by_weight(&w, 3.9, 0.9999), Some((3, 3.0 / 3.9)));
        assert_eq!(pick_by_weight(&[0.0, 0.0], 0.0, 0.5), None);
    }

    #[test]
    fn discrete_picks_by_weight() {
        let d = Discrete::new(&[1.0, 0.0, 3.0]).unwrap();
        assert_eq!(d.sample(0.0).0, 0);
        assert_eq!(d.sample(0.2499).0, 0);
        assert_eq!(d.sample(0.25).0, 2);
        assert_eq!(d.sample(0.999_999).0, 2);
        assert!((d.pmf(2) - 0.75).abs() < 1e-7);
        assert!(Discrete::new(&[0.0, 0.0]).is_none());
        assert!(Discrete::new(&[f32::NAN]).is_none());
    }
}
