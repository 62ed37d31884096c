//! Pixel reconstruction filters, applied by filter importance sampling: a pixel's camera rays
//! leave through film points around its centre distributed as the filter (separable, per
//! axis), so that the pixel's expected value is the filter-weighted mean of the radiance
//! around it, `∫ f·L / ∫ f` — the value Mitsuba 3 and pbrt-v4 converge to when they weigh
//! splatted samples by the filter and divide by the weights' sum. As theirs, the filter is
//! cut at the rendered image's edges (a film point is never outside the image).
//!
//! The box filter of radius ½ is the plain uniform point in the pixel (bit-identical to
//! renders before filters existed). Other filters are tabulated per axis at
//! [`FILTER_BINS`] bins over `[−r, r]` and sampled exactly from the piecewise-constant table:
//! the filter used is that table (within 1e-5 of the formula's mean over each bin).
use crate::geometry::{UVec2, Vec2};
use std::sync::Arc;

/// Bins of a tabulated filter axis.
pub const FILTER_BINS: usize = 1024;

/// A reconstruction filter's shape (radii in pixels, per axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FilterShape {
    /// Constant over `[−r, r]`.
    Box {
        /// Half-width per axis.
        radius: [f32; 2],
    },
    /// `max(0, e^{−x²/2σ²} − e^{−r²/2σ²})` over `[−r, r]` (Mitsuba 3's and pbrt-v4's).
    Gaussian {
        /// Standard deviation `σ`.
        stddev: f32,
        /// Truncation radius per axis.
        radius: [f32; 2],
    },
    /// `max(0, 1 − |x|/r)` (Mitsuba's `tent`, pbrt's `triangle`).
    Tent {
        /// Where it reaches 0, per axis.
        radius: [f32; 2],
    },
}

impl FilterShape {
    /// The box of radius ½: one pixel.
    pub const PIXEL: FilterShape = FilterShape::Box { radius: [0.5, 0.5] };

    /// Half-width of the filter's support per axis, in pixels.
    #[must_use]
    pub fn radius(&self) -> [f32; 2] {
        match *self {
            FilterShape::Box { radius } | FilterShape::Gaussian { radius, .. } | FilterShape::Tent { radius } => radius,
        }
    }

    /// Whether the radii (and σ) are finite, positive and at most 16 pixels.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        let ok = |x: f32| x.is_finite() && x > 0.0 && x <= 16.0;
        self.radius().into_iter().all(ok)
            && match *self {
                FilterShape::Gaussian { stddev, .. } => ok(stddev),
                _ => true,
            }
    }

    /// The filter's value along one axis at offset `x` (radius `r`).
    fn eval(&self, x: f64, r: f64) -> f64 {
        if x.abs() > r {
            return 0.0;
        }
        match *self {
            FilterShape::Box { .. } => 1.0,
            FilterShape::Gaussian { stddev, .. } => {
                let a = -0.5 / (f64::from(stddev) * f64::from(stddev));
                ((a * x * x).exp() - (a * r * r).exp()).max(0.0)
            }
            FilterShape::Tent { .. } => (1.0 - x.abs() / r).max(0.0),
        }
    }
}

/// One axis's table: the filter's cumulative share at the bins' edges.
#[derive(Debug, PartialEq)]
struct Axis {
    radius: f32,
    cdf: Vec<f32>,
}

impl Axis {
    fn new(shape: &FilterShape, radius: f32) -> Self {
        let r = f64::from(radius);
        let width = 2.0 * r / FILTER_BINS as f64;
        // Each bin's weight: the filter's mean over the bin (8-point midpoint rule).
        let weights: Vec<f64> = (0..FILTER_BINS)
            .map(|i| (0..8).map(|k| shape.eval(-r + width * (i as f64 + (k as f64 + 0.5) / 8.0), r)).sum::<f64>())
            .collect();
        let total: f64 = weights.iter().sum();
        let mut cdf = Vec::with_capacity(FILTER_BINS + 1);
        let mut sum = 0.0;
        cdf.push(0.0);
        for w in weights {
            sum += w;
            cdf.push((sum / total) as f32);
        }
        *cdf.last_mut().expect("bins") = 1.0;
        Self { radius, cdf }
    }

    /// The cumulative share at offset `x`.
    fn share(&self, x: f32) -> f32 {
        let t = ((x + self.radius) / (2.0 * self.radius) * FILTER_BINS as f32).clamp(0.0, FILTER_BINS as f32);
        let i = (t as usize).min(FILTER_BINS - 1);
        self.cdf[i] + (self.cdf[i + 1] - self.cdf[i]) * (t - i as f32)
    }

    /// An offset in `[lo, hi]` (within the radius) distributed as the filter there, from `u`.
    fn sample(&self, u: f32, lo: f32, hi: f32) -> f32 {
        let (a, b) = (self.share(lo.max(-self.radius)), self.share(hi.min(self.radius)));
        let target = a + u * (b - a);
        // The last edge at or below the target, in a bin of positive weight.
        let i = self.cdf.partition_point(|&c| c <= target).clamp(1, FILTER_BINS) - 1;
        let (c0, c1) = (self.cdf[i], self.cdf[i + 1]);
        let within = if c1 > c0 { ((target - c0) / (c1 - c0)).clamp(0.0, 1.0) } else { 0.5 };
        let x = -self.radius + 2.0 * self.radius * (i as f32 + within) / FILTER_BINS as f32;
        x.clamp(lo.max(-self.radius), hi.min(self.radius))
    }
}

/// A filter ready to sample: its shape and, unless it is the one-pixel box, its tables.
#[derive(Clone, Debug)]
pub struct PixelFilter {
    /// The filter's shape.
    pub shape: FilterShape,
    tables: Option<Arc<[Axis; 2]>>,
}

impl PartialEq for PixelFilter {
    fn eq(&self, other: &Self) -> bool {
        self.shape == other.shape
    }
}

impl Default for PixelFilter {
    fn default() -> Self {
        Self::new(FilterShape::PIXEL)
    }
}

impl PixelFilter {
    /// The filter of `shape` (which must be [`FilterShape::is_valid`]).
    #[must_use]
    pub fn new(shape: FilterShape) -> Self {
        let tables = (shape != FilterShape::PIXEL).then(|| {
            let [rx, ry] = shape.radius();
            Arc::new([Axis::new(&shape, rx), Axis::new(&shape, ry)])
        });
        Self { shape, tables }
    }

    /// The film point (in pixels) for pixel `pixel` of a `size` image and `u` in `[0, 1)²`:
    /// the pixel's centre plus an offset distributed as the filter, cut to the image.
    #[inline]
    #[must_use]
    pub fn film_point(&self, pixel: UVec2, size: UVec2, u: Vec2) -> Vec2 {
        let Some(t) = &self.tables else { return pixel.as_vec2() + u };
        let centre = pixel.as_vec2() + 0.5;
        let (lo, hi) = (-centre, size.as_vec2() - centre);
        centre + Vec2::new(t[0].sample(u.x, lo.x, hi.x), t[1].sample(u.y, lo.y, hi.y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gaussian() -> FilterShape {
        FilterShape::Gaussian { stddev: 0.5, radius: [2.0, 1.5] }
    }

    /// Film points follow the filter: a histogram of 400k offsets of an inner pixel against the
    /// formula's share per bin (32 bins per axis, χ² at a false-alarm rate of 1e-4), and the
    /// same points stay inside the image at its corner, distributed as the filter cut there.
    #[test]
    fn film_points_follow_the_filter() {
        use crate::sampler::SampleStream;
        use crate::stats::chi_square_critical;
        for shape in [gaussian(), FilterShape::Tent { radius: [1.0, 2.0] }, FilterShape::Box { radius: [1.5, 0.5] }] {
            let f = PixelFilter::new(shape);
            let mut rng = SampleStream::new(5, 0, 0);
            for (pixel, axis) in [(UVec2::new(10, 10), 0), (UVec2::new(10, 10), 1), (UVec2::new(0, 0), 0)] {
                let size = UVec2::new(20, 20);
                let r = f64::from(shape.radius()[axis]);
                let centre = f64::from(pixel.as_vec2()[axis]) + 0.5;
                let (lo, hi) = ((-centre).max(-r), (20.0 - centre).min(r));
                let n = 400_000;
                let bins = 32;
                let mut h = vec![0f64; bins];
                for _ in 0..n {
                    let p = f.film_point(pixel, size, rng.next_2d());
                    assert!(p.x >= 0.0 && p.y >= 0.0 && p.x <= 20.0 && p.y <= 20.0, "{p}");
                    let o = f64::from(p[axis]) - centre;
                    assert!(o >= lo - 1e-4 && o <= hi + 1e-4, "{shape:?}: offset {o} outside [{lo}, {hi}]");
                    let k = (((o - lo) / (hi - lo)) * bins as f64).clamp(0.0, bins as f64 - 1.0) as usize;
                    h[k] += 1.0;
                }
                let integral = |a: f64, b: f64| {
                    (0..200).map(|k| shape.eval(a + (b - a) * (k as f64 + 0.5) / 200.0, r)).sum::<f64>() * (b - a)
                        / 200.0
                };
                let total = integral(lo, hi);
                let mut stat = 0.0;
                for (k, &got) in h.iter().enumerate() {
                    let a = lo + (hi - lo) * k as f64 / bins as f64;
                    let want = integral(a, a + (hi - lo) / bins as f64) / total * f64::from(n);
                    stat += (got - want).powi(2) / want.max(1e-9);
                }
                let critical = chi_square_critical(bins - 1, 1e-4);
                assert!(stat < critical, "{shape:?} pixel {pixel} axis {axis}: χ² {stat:.1} ≥ {critical:.1}");
            }
        }
    }

    /// The one-pixel box is the plain point in the pixel.
    #[test]
    fn the_pixel_box_is_the_uniform_point() {
        let f = PixelFilter::default();
        let u = Vec2::new(0.25, 0.75);
        assert_eq!(f.film_point(UVec2::new(3, 4), UVec2::new(8, 8), u), Vec2::new(3.25, 4.75));
        assert!(FilterShape::Gaussian { stddev: 0.5, radius: [2.0, 2.0] }.is_valid());
        assert!(!FilterShape::Gaussian { stddev: 0.0, radius: [2.0, 2.0] }.is_valid());
        assert!(!FilterShape::Tent { radius: [f32::NAN, 1.0] }.is_valid());
    }

    /// The test above has power: a Gaussian claimed with σ 0.55 against points of σ 0.5.
    #[test]
    fn a_wrong_filter_is_caught() {
        use crate::sampler::SampleStream;
        let f = PixelFilter::new(gaussian());
        let wrong = FilterShape::Gaussian { stddev: 0.55, radius: [2.0, 1.5] };
        let mut rng = SampleStream::new(6, 0, 0);
        let (n, bins) = (400_000, 32);
        let mut h = vec![0f64; bins];
        for _ in 0..n {
            let o = f64::from(f.film_point(UVec2::new(10, 10), UVec2::new(20, 20), rng.next_2d()).x) - 10.5;
            h[(((o + 2.0) / 4.0) * bins as f64).clamp(0.0, bins as f64 - 1.0) as usize] += 1.0;
        }
        let integral = |a: f64, b: f64| {
            (0..200).map(|k| wrong.eval(a + (b - a) * (k as f64 + 0.5) / 200.0, 2.0)).sum::<f64>() * (b - a) / 200.0
        };
        let total = integral(-2.0, 2.0);
        let stat: f64 = h
            .iter()
            .enumerate()
            .map(|(k, &got)| {
                let a = -2.0 + 4.0 * k as f64 / bins as f64;
                let want = integral(a, a + 4.0 / bins as f64) / total * f64::from(n);
                (got - want).powi(2) / want.max(1e-9)
            })
            .sum();
        assert!(stat > crate::stats::chi_square_critical(bins - 1, 1e-4), "χ² {stat:.1}");
    }
}
