//! Sample rates per pixel: where a render's error is, there its samples go.
//!
//! The image's MSE is the mean over pixels of `σᵢ²/nᵢ` (σᵢ² a pixel's per-sample variance, nᵢ
//! its samples); for a fixed cost `Σ nᵢcᵢ` (cᵢ a sample's cost there) it is least with
//! `nᵢ ∝ σᵢ/√cᵢ` (a Lagrange multiplier: `σᵢ²/(nᵢ²cᵢ)` equal everywhere). With equal costs it
//! is then `(mean σ)²/n̄` against the uniform `mean σ²/n̄`: a caustic or a glossy highlight
//! that holds most of an image's variance in a few pixels makes that ratio large.
//!
//! [`pixel_rates`] turns a variance and a cost estimate per pixel (from an integrator's
//! training passes) into rates of mean 1: pixel `i` takes `⌊k·rᵢ⌋` of the render's first `k` samples per pixel
//! (so any split of the render into sample ranges, passes, parts or a resumed run, takes the
//! same samples). A pixel's rate comes from its *neighbours* of the other parity of a
//! checkerboard (as the training passes' weights do, [`crate::film::PriorSamples`]), never
//! from its own samples: its count is independent of its own estimate, which keeps its mean
//! unbiased (a pixel that happened to meet a firefly would otherwise take more samples that
//! dilute it). Rates are floored (no pixel starves where its neighbours looked smooth) and
//! capped.

/// Half the side of the square of neighbours a pixel's rate comes from (11 × 11 pixels, the
/// other parity's 60 of them).
pub const RADIUS: usize = 5;
/// Least rate, as a fraction of the mean: a bound on how much a pixel can lose where the
/// training's neighbours missed a rare bright path (a firefly in a pixel of rate `r` weighs
/// `1/r²` as much in the squared error). On `cornell-materials`, rates from a 30-spp variance
/// map predicted 2.20× less MSE with a floor of 0.1 and 2.11× with 0.4; on Bitterli's
/// veach-bidir a firefly in a pixel at rate 0.24 held 67% of one render's error.
pub const FLOOR: f64 = 0.4;
/// Most rate before normalisation, as a multiple of the mean.
pub const CAP: f64 = 8.0;
/// No rate is above this (what a part's per-pixel counts are checked against).
pub const MAX_PIXEL_RATE: f32 = 16.0;

/// Rates of mean 1 for a `width × height` image (row-major) whose pixels have per-sample
/// variance estimates `variance` (≥ 0; non-finite ones count as 0) and, optionally, costs
/// per sample `cost` (> 0, e.g. rays): each pixel's rate is `√(v̄/c̄)`, the means `v̄` and `c̄`
/// over its other-parity neighbours within [`RADIUS`], over the image's mean of it, clamped
/// to `[FLOOR, CAP]` and normalised to mean 1. `None` where the estimates say nothing (all
/// zero, or a size mismatch).
#[must_use]
pub fn pixel_rates(width: u32, height: u32, variance: &[f64], cost: Option<&[f64]>) -> Option<Vec<f32>> {
    let (w, h) = (width as usize, height as usize);
    if w == 0 || h == 0 || variance.len() != w * h || cost.is_some_and(|c| c.len() != w * h) {
        return None;
    }
    let v = neighbour_means(w, h, |i| variance[i]);
    let c = cost.map(|c| neighbour_means(w, h, |i| c[i]));
    let sigma: Vec<f64> = (0..w * h)
        .map(|i| {
            let per = c.as_ref().map_or(1.0, |c| c[i]);
            if per > 0.0 { (v[i] / per).sqrt() } else { 0.0 }
        })
        .collect();
    let mean = sigma.iter().sum::<f64>() / sigma.len() as f64;
    if !(mean.is_finite() && mean > 0.0) {
        return None;
    }
    let mut rates: Vec<f64> = sigma.iter().map(|s| (s / mean).clamp(FLOOR, CAP)).collect();
    let norm = rates.iter().sum::<f64>() / rates.len() as f64;
    for r in &mut rates {
        *r /= norm;
    }
    Some(rates.into_iter().map(|r| (r as f32).min(MAX_PIXEL_RATE)).collect())
}

/// Each pixel's mean of `value` (non-finite or negative values as 0) over its neighbours of
/// the other checkerboard parity within [`RADIUS`] (0 where it has none): separable box sums
/// of each parity's values and counts, added directly (no summed-area differences, which lose
/// small values next to a firefly's).
fn neighbour_means(w: usize, h: usize, value: impl Fn(usize) -> f64) -> Vec<f64> {
    let parity = |i: usize| super::passes::parity(i, w as u32);
    let clean = |i: usize| {
        let v = value(i);
        if v.is_finite() && v > 0.0 { v } else { 0.0 }
    };
    let sums: [Vec<f64>; 4] = [
        box_sum(w, h, |i| if parity(i) == 0 { clean(i) } else { 0.0 }),
        box_sum(w, h, |i| if parity(i) == 1 { clean(i) } else { 0.0 }),
        box_sum(w, h, |i| if parity(i) == 0 { 1.0 } else { 0.0 }),
        box_sum(w, h, |i| if parity(i) == 1 { 1.0 } else { 0.0 }),
    ];
    (0..w * h)
        .map(|i| {
            let q = 1 - parity(i);
            let count = sums[2 + q][i];
            if count > 0.0 { sums[q][i] / count } else { 0.0 }
        })
        .collect()
}

/// Sums of `value` over the square of side `2 RADIUS + 1` around each pixel (clipped at the
/// borders), rows then columns.
fn box_sum(w: usize, h: usize, value: impl Fn(usize) -> f64) -> Vec<f64> {
    let data: Vec<f64> = (0..w * h).map(value).collect();
    let mut rows = vec![0.0f64; w * h];
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (x.saturating_sub(RADIUS), (x + RADIUS + 1).min(w));
            rows[y * w + x] = data[y * w + a..y * w + b].iter().sum();
        }
    }
    let mut out = vec![0.0f64; w * h];
    for y in 0..h {
        let (a, b) = (y.saturating_sub(RADIUS), (y + RADIUS + 1).min(h));
        for x in 0..w {
            out[y * w + x] = (a..b).map(|yy| rows[yy * w + x]).sum();
        }
    }
    out
}

/// The samples pixel of rate `rate` has taken after the render's first `k` samples per
/// pixel: `⌊k·rate⌋` (the same in every split of the render into sample ranges).
#[inline]
#[must_use]
pub fn taken(k: u32, rate: f32) -> u64 {
    (f64::from(k) * f64::from(rate)).floor() as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> f64) -> Vec<f64> {
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| f(x, y)).collect()
    }

    /// Rates have mean 1, lie within the floor and cap, and follow the variance: a bright
    /// noisy square takes more samples than the smooth rest.
    #[test]
    fn rates_follow_the_variance() {
        let (w, h) = (64, 48);
        let v = image(w, h, |x, y| if (20..30).contains(&x) && (10..20).contains(&y) { 100.0 } else { 1.0 });
        let r = pixel_rates(w, h, &v, None).unwrap();
        let mean = r.iter().map(|&x| f64::from(x)).sum::<f64>() / r.len() as f64;
        assert!((mean - 1.0).abs() < 1e-5, "mean {mean}");
        assert!(r.iter().all(|&x| (0.0..=MAX_PIXEL_RATE).contains(&x)));
        let at = |x: u32, y: u32| r[(y * w + x) as usize];
        assert!(at(25, 15) > 5.0 * at(60, 40), "{} vs {}", at(25, 15), at(60, 40));
        // Uniform variance: uniform rates.
        let flat = pixel_rates(w, h, &vec![3.0; (w * h) as usize], None).unwrap();
        assert!(flat.iter().all(|&x| (x - 1.0).abs() < 1e-5));
        // Costs: where a sample costs 4 times as much, half the rate (σ/√c).
        let cost = image(w, h, |x, _| if x < 32 { 4.0 } else { 1.0 });
        let r = pixel_rates(w, h, &vec![3.0; (w * h) as usize], Some(&cost)).unwrap();
        let (left, right) = (r[(20 * w + 10) as usize], r[(20 * w + 50) as usize]);
        assert!((left / right - 0.5).abs() < 1e-5, "{left} {right}");
        // Nothing to go by: none.
        assert!(pixel_rates(w, h, &vec![0.0; (w * h) as usize], None).is_none());
        assert!(pixel_rates(w, h, &[1.0], None).is_none());
    }

    /// A pixel's rate does not depend on its own estimate, nor on its parity's (the
    /// normalisation aside): a firefly in one pixel raises its neighbours' rates, not its own.
    #[test]
    fn a_pixels_rate_ignores_its_own_samples() {
        let (w, h) = (32, 32);
        let base = image(w, h, |x, y| 1.0 + f64::from((x * 7 + y * 13) % 5));
        let mut fire = base.clone();
        let i = (16 * w + 16) as usize;
        fire[i] = 1000.0;
        let (a, b) = (pixel_rates(w, h, &base, None).unwrap(), pixel_rates(w, h, &fire, None).unwrap());
        // Relative to a far pixel of the same parity (normalisation scales every rate alike).
        let far = (2 * w + 2) as usize;
        assert!((a[i] / a[far] - b[i] / b[far]).abs() < 1e-4 * a[i] / a[far], "{} {}", a[i], b[i]);
        let next = i + 1;
        assert!(b[next] / b[far] > 2.0 * a[next] / a[far]);
    }

    /// `taken` splits any range of samples the same way: parts add up to the whole.
    #[test]
    fn taken_is_additive_over_ranges() {
        for rate in [0.1f32, 0.37, 1.0, 2.5, 7.99, 16.0] {
            let whole = taken(1000, rate) - taken(0, rate);
            let parts: u64 =
                [0u32, 3, 250, 251, 999, 1000].windows(2).map(|p| taken(p[1], rate) - taken(p[0], rate)).sum();
            assert_eq!(whole, parts);
            assert!((whole as f64 - 1000.0 * f64::from(rate)).abs() <= 1.0);
        }
    }
}
