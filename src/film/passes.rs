//! Samples rendered before the final passes (the learned integrator's training iterations),
//! combined with the final passes by inverse-variance weights.
//!
//! Each pass `k` is an unbiased estimate of every pixel, with a per-sample variance `v_k`
//! that falls as the guide it sampled improves. Weighting pass `k` by `n_k / v_k` (its sample
//! count over its variance) is the best linear combination; weights computed from a pass's own
//! pixel values would correlate with them and bias the image. Here the weight of a pixel on
//! one checkerboard parity (`(x + y)` even or odd) comes from the *other* parity's mean
//! per-sample variance: given the guides, the samples of different pixels are independent, so
//! a pixel's weights are independent of its own values and the combination stays exactly
//! unbiased. (The parities see nearly the same variance, so nothing is lost.)
//!
//! A pass of a few samples per pixel measures its variance badly where it is carried by rare
//! large samples (a light smaller than a pixel, caustics): on Bitterli's veach-mis the 2-spp
//! pass measured 10–29 against the 500 of every later pass, and so weighed as much as 50–90
//! final samples, its noise showing in every pixel it covered. A pass's weight therefore uses
//! the larger of its own variance and the next pass's (training improves the guide, so a pass
//! is not truly better than the one after it): each pass is weighed when its successor has
//! been measured, the last one against the final passes in [`PriorSamples::combine`]. The
//! final passes sample the trained guide, or the path tracer where the learned walk lost
//! (`integrator::zvidpt::Choice`), so the last training pass is no better than they are:
//! weighed by its own variance, a 32-spp pass that saw a sub-pixel light less often than its
//! variance needs took a share of the image above its share of the samples (Bitterli's
//! veach-mis, 32 of 284 spp).
//!
//! A pixel the final passes sample far better than these passes did (a light's image seen
//! through glass over a sliver of it, which the final passes split over many film points and
//! the training met once in hundreds of renders) may leave these passes out altogether
//! ([`PriorSamples::exclude`]), decided from what is independent of the pixel's own samples.
//! Kept in, they weigh as much there as anywhere: most renders read the training's miss over
//! its share of the pixel, and a rare one the training's hit, hundreds of times the pixel.

/// Per-pixel sums (row-major, linear RGB) of passes taken before the final passes, already
/// weighted; [`Self::combine`] adds the final passes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PriorSamples {
    /// Samples per pixel in all passes added.
    pub spp: u32,
    width: u32,
    /// Σ_k w_k · mean_k per pixel.
    weighted: Vec<[f64; 3]>,
    /// Σ_k w_k² · s²_k / n_k per pixel (the variance of `weighted`, from sample variances).
    variance: Vec<[f64; 3]>,
    /// Σ_k w_k for the pixels of each parity.
    weight: [f64; 2],
    /// The last pass's per-sample variance per parity (stands in for a final pass too short
    /// to measure its own).
    last: Option<[f64; 2]>,
    /// The pass added last, not yet weighed: its sample count, sums, sums of squares and
    /// measured variance per parity.
    pending: Option<Pending>,
    /// Per pixel, whether these passes are left out of it ([`Self::exclude`]); empty for none.
    excluded: Vec<bool>,
}

#[derive(Clone, Debug, PartialEq)]
struct Pending {
    spp: u32,
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    variance: [f64; 2],
}

/// The tag of the pixels left out in [`PriorSamples::encode`]'s output (after the pending
/// pass's tag 1; a partial file's per-pixel counts use another).
const EXCLUDED_TAG: u8 = 2;

/// Variances are kept within these bounds, so weights stay finite and positive.
const VARIANCE_RANGE: (f64, f64) = (1e-30, 1e30);

/// Unbiased per-sample variance of `n ≥ 2` samples from their sum and sum of squares (never
/// negative); also the mean. The render loop and the pass weights share it.
#[inline]
#[must_use]
pub fn mean_and_variance(sum: f64, sum_sq: f64, n: f64) -> (f64, f64) {
    let mean = sum / n;
    (mean, ((sum_sq - n * mean * mean) / (n - 1.0)).max(0.0))
}

/// Mean per-sample variance over pixels and channels of a pass of `spp ≥ 2` samples per
/// pixel, from their sums.
#[must_use]
pub fn mean_variance(spp: u32, sum: &[[f64; 3]], sum_sq: &[[f64; 3]]) -> f64 {
    let n = f64::from(spp);
    let total: f64 =
        sum.iter().zip(sum_sq).map(|(s, q)| (0..3).map(|c| mean_and_variance(s[c], q[c], n).1).sum::<f64>()).sum();
    total / (3 * sum.len().max(1)) as f64
}

/// The checkerboard parity of pixel `index` (row-major) of an image `width` wide.
#[inline]
pub(super) fn parity(index: usize, width: u32) -> usize {
    let (x, y) = (index % width as usize, index / width as usize);
    (x + y) & 1
}

/// Mean per-sample variance of each parity's pixels (over channels), from the sums of pixel
/// `i`'s `spp(i)` samples (pixels of fewer than 2 left out). A parity without pixels (a
/// one-pixel image) reports 1 for both, i.e. weights by sample count alone.
fn parity_variance(width: u32, spp: impl Fn(usize) -> u32, sum: &[[f64; 3]], sum_sq: &[[f64; 3]]) -> [f64; 2] {
    let (mut total, mut count) = ([0.0f64; 2], [0u64; 2]);
    for (i, (s, q)) in sum.iter().zip(sum_sq).enumerate() {
        let n = spp(i);
        if n < 2 {
            continue;
        }
        let p = parity(i, width);
        for c in 0..3 {
            total[p] += mean_and_variance(s[c], q[c], f64::from(n)).1;
        }
        count[p] += 3;
    }
    if count[0] == 0 || count[1] == 0 {
        return [1.0; 2];
    }
    let clamp = |v: f64| if v.is_nan() { VARIANCE_RANGE.1 } else { v.clamp(VARIANCE_RANGE.0, VARIANCE_RANGE.1) };
    [clamp(total[0] / count[0] as f64), clamp(total[1] / count[1] as f64)]
}

impl PriorSamples {
    /// Appends these samples to `out` (little-endian; read back by [`Self::decode`]); a pass
    /// not yet weighed is weighed first, as [`Self::finish`] would.
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.spp.to_le_bytes());
        out.extend_from_slice(&self.width.to_le_bytes());
        out.extend_from_slice(&(self.weighted.len() as u64).to_le_bytes());
        for v in self.weight.iter().chain(self.last.unwrap_or([0.0; 2]).iter()) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.push(u8::from(self.last.is_some()));
        for p in self.weighted.iter().chain(&self.variance) {
            for v in p {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        // The pass not yet weighed, if any, follows (files without it end here).
        if let Some(p) = &self.pending {
            out.push(1);
            out.extend_from_slice(&p.spp.to_le_bytes());
            for v in p.variance {
                out.extend_from_slice(&v.to_le_bytes());
            }
            for q in p.sum.iter().chain(&p.sum_sq) {
                for v in q {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        // The pixels left out, if any, follow (files without them end here).
        if self.excluded.iter().any(|&e| e) {
            out.push(EXCLUDED_TAG);
            out.extend(self.excluded.iter().map(|&e| u8::from(e)));
        }
    }

    /// Reads what [`Self::encode`] wrote from the front of `bytes` (advancing it); `None` if it
    /// is malformed or does not hold `pixels` pixels.
    pub fn decode(bytes: &mut &[u8], pixels: usize) -> Option<Self> {
        fn take<const N: usize>(b: &mut &[u8]) -> Option<[u8; N]> {
            let (head, rest) = b.split_first_chunk::<N>()?;
            *b = rest;
            Some(*head)
        }
        let spp = u32::from_le_bytes(take(bytes)?);
        let width = u32::from_le_bytes(take(bytes)?);
        let n = u64::from_le_bytes(take(bytes)?);
        if n != pixels as u64 || width == 0 || n % u64::from(width) != 0 {
            return None;
        }
        let weight = [f64::from_le_bytes(take(bytes)?), f64::from_le_bytes(take(bytes)?)];
        let last = [f64::from_le_bytes(take(bytes)?), f64::from_le_bytes(take(bytes)?)];
        let last = match take::<1>(bytes)? {
            [0] => None,
            [1] => Some(last),
            _ => return None,
        };
        fn read(b: &mut &[u8], count: usize) -> Option<Vec<[f64; 3]>> {
            (0..count)
                .map(|_| {
                    Some([f64::from_le_bytes(take(b)?), f64::from_le_bytes(take(b)?), f64::from_le_bytes(take(b)?)])
                })
                .collect()
        }
        let weighted = read(bytes, pixels)?;
        let variance = read(bytes, pixels)?;
        let pending = match bytes.first() {
            Some(1) => {
                *bytes = &bytes[1..];
                let spp = u32::from_le_bytes(take(bytes)?);
                let variance = [f64::from_le_bytes(take(bytes)?), f64::from_le_bytes(take(bytes)?)];
                let (sum, sum_sq) = (read(bytes, pixels)?, read(bytes, pixels)?);
                let valid = |v: f64| v.is_finite() && v > 0.0;
                if spp < 2 || !variance.iter().all(|&v| valid(v)) {
                    return None;
                }
                Some(Pending { spp, sum, sum_sq, variance })
            }
            _ => None,
        };
        let excluded = match bytes.split_first() {
            Some((&EXCLUDED_TAG, rest)) if rest.len() >= pixels => {
                let (mask, rest) = rest.split_at(pixels);
                if mask.iter().any(|&b| b > 1) {
                    return None;
                }
                *bytes = rest;
                mask.iter().map(|&b| b == 1).collect()
            }
            Some((&EXCLUDED_TAG, _)) => return None,
            _ => Vec::new(),
        };
        Some(Self { spp, width, weighted, variance, weight, last, pending, excluded })
    }

    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            spp: 0,
            width,
            weighted: vec![[0.0; 3]; n],
            variance: vec![[0.0; 3]; n],
            weight: [0.0; 2],
            last: None,
            pending: None,
            excluded: Vec::new(),
        }
    }

    /// Pixels these passes are left out of ([`Self::exclude`]).
    #[must_use]
    pub fn excluded(&self) -> usize {
        self.excluded.iter().filter(|&&e| e).count()
    }

    /// Leaves these passes out of the pixels `pixels` marks (row-major), wherever the final
    /// passes take a sample of them. The marks must not depend on those pixels' own samples
    /// in these passes, or the image is biased. Ignored unless `pixels` covers the image.
    pub fn exclude(&mut self, pixels: &[bool]) {
        if pixels.len() == self.weighted.len() {
            self.excluded = pixels.to_vec();
        }
    }

    /// Pixels covered.
    #[must_use]
    pub fn len(&self) -> usize {
        self.weighted.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.spp == 0
    }

    /// Adds a pass of `spp` samples per pixel given as per-pixel sums and sums of squares;
    /// it is weighed once the next pass (or [`Self::finish`]) comes. A pass of one sample per
    /// pixel cannot measure its variance and is not added (returns false); nor is one whose
    /// size does not match.
    pub fn add_pass(&mut self, spp: u32, sum: &[[f64; 3]], sum_sq: &[[f64; 3]]) -> bool {
        if spp < 2 || sum.len() != self.weighted.len() || sum_sq.len() != sum.len() {
            return false;
        }
        let v = parity_variance(self.width, |_| spp, sum, sum_sq);
        if let Some(p) = self.pending.take() {
            let floor = [p.variance[0].max(v[0]), p.variance[1].max(v[1])];
            self.weigh(p.spp, &p.sum, &p.sum_sq, floor);
        }
        self.pending = Some(Pending { spp, sum: sum.to_vec(), sum_sq: sum_sq.to_vec(), variance: v });
        self.spp += spp;
        self.last = Some(v);
        true
    }

    /// Weighs the pass added last by its own variance (for when no final pass will be
    /// measured; otherwise leave it to [`Self::combine`], which floors it by the final
    /// passes' variance).
    pub fn finish(&mut self) {
        if let Some(p) = self.pending.take() {
            self.weigh(p.spp, &p.sum, &p.sum_sq, p.variance);
        }
    }

    /// Adds a pass to the weighted sums with per-sample variance `v` per parity.
    fn weigh(&mut self, spp: u32, sum: &[[f64; 3]], sum_sq: &[[f64; 3]], v: [f64; 2]) {
        let n = f64::from(spp);
        // A pixel of parity p is weighted by the other parity's variance.
        let w = [n / v[1], n / v[0]];
        for (i, ((acc, var), (s, q))) in
            self.weighted.iter_mut().zip(&mut self.variance).zip(sum.iter().zip(sum_sq)).enumerate()
        {
            let wi = w[parity(i, self.width)];
            for c in 0..3 {
                let (mean, s2) = mean_and_variance(s[c], q[c], n);
                acc[c] += wi * mean;
                var[c] += wi * wi * s2 / n;
            }
        }
        self.weight[0] += w[0];
        self.weight[1] += w[1];
    }

    /// The image: these passes combined with the final passes (`spp` samples per pixel, or
    /// pixel `i`'s `counts[i]` where pixels took different counts, given by their sums).
    /// Returns per-pixel means and, per pixel, the combination's variance times the total
    /// sample count (a per-sample variance, as an unweighted image reports). A pass not yet
    /// weighed is weighed first, as [`Self::finish`] would.
    #[must_use]
    pub fn combine(
        &self,
        spp: u32,
        counts: Option<&[u32]>,
        sum: &[[f64; 3]],
        sum_sq: &[[f64; 3]],
    ) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let count = |i: usize| counts.and_then(|c| c.get(i).copied()).unwrap_or(spp);
        if let Some(p) = &self.pending {
            // The last training pass is weighed by the larger of its variance and the final
            // passes' (per parity, so a pixel's weights still come from the other parity).
            let v = if spp >= 2 { parity_variance(self.width, count, sum, sum_sq) } else { p.variance };
            let floor = [p.variance[0].max(v[0]), p.variance[1].max(v[1])];
            let mut done = Self { pending: None, ..self.clone() };
            done.weigh(p.spp, &p.sum, &p.sum_sq, floor);
            return done.combine(spp, counts, sum, sum_sq);
        }
        let v = if spp >= 2 { parity_variance(self.width, count, sum, sum_sq) } else { self.last.unwrap_or([1.0; 2]) };
        // The training passes together are no better per sample than the final passes: their
        // weight is scaled down (per parity, from the other parity's figures like every
        // weight) until their variance per sample is at least the final passes'. Each pass
        // is floored by its successor's variance as it comes, but a light smaller than a
        // pixel makes an image's variance the luck of meeting it: where every training pass
        // missed it and the final passes met it, the training took almost all the weight
        // and the light's pixels read the training's zero. (Bitterli's water-caustic, 128 ×
        // 128, 8 s: the pixel seeing the light, reference 5,642, read below 1 in every
        // render; the path tracer 6,180–6,250.)
        let scale = |p: usize| {
            if spp < 2 || self.weight[p] <= 0.0 {
                return 1.0;
            }
            let training = f64::from(self.spp) / self.weight[p];
            (training / v[1 - p]).min(1.0)
        };
        let scale = [scale(0), scale(1)];
        // The image's count (the most samples any pixel took): a pixel's variance of the mean
        // times it is what the image reports.
        let total_spp = f64::from(self.spp) + f64::from(spp);
        let mut pixels = vec![[0.0f32; 3]; sum.len()];
        let mut variance = vec![[0.0f32; 3]; sum.len()];
        for (i, (s, q)) in sum.iter().zip(sum_sq).enumerate() {
            let p = parity(i, self.width);
            let spp = count(i);
            let n = f64::from(spp);
            // A pixel of parity p is weighted by the other parity's variance.
            let w = [n / v[1], n / v[0]];
            let out = spp > 0 && self.excluded.get(i).copied().unwrap_or(false);
            let a = if out { 0.0 } else { scale[p] };
            let total = a * self.weight[p] + w[p];
            if total <= 0.0 {
                continue;
            }
            for c in 0..3 {
                let (mean, s2) = match spp {
                    0 => (0.0, 0.0),
                    1 => (s[c], 0.0),
                    _ => mean_and_variance(s[c], q[c], n),
                };
                pixels[i][c] = ((a * self.weighted[i][c] + w[p] * mean) / total) as f32;
                let var_mean =
                    (a * a * self.variance[i][c] + if spp > 0 { w[p] * w[p] * s2 / n } else { 0.0 }) / (total * total);
                variance[i][c] = (var_mean * total_spp) as f32;
            }
        }
        (pixels, variance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pass(values: &[[f64; 3]], spp: u32, spread: f64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        // `spp` samples of value ± spread around each pixel's value (half each way).
        let n = f64::from(spp);
        let sum = values.iter().map(|v| v.map(|x| x * n)).collect();
        let sum_sq = values.iter().map(|v| v.map(|x| n * (x * x + spread * spread))).collect();
        (sum, sum_sq)
    }

    /// A pixel left out takes the final passes alone (their mean and variance); the others
    /// are combined as before, and the marks survive encoding.
    #[test]
    fn excluded_pixels_take_the_final_passes_alone() {
        let (w, h) = (4, 3);
        let mut prior = PriorSamples::new(w, h);
        let (s, q) = pass(&vec![[1.0; 3]; 12], 4, 2.0);
        assert!(prior.add_pass(4, &s, &q));
        let (fs, fq) = pass(&vec![[2.0; 3]; 12], 4, 1.0);
        let kept = prior.combine(4, None, &fs, &fq);
        let mut marks = vec![false; 12];
        marks[5] = true;
        prior.exclude(&marks);
        let mut bytes = Vec::new();
        prior.encode(&mut bytes);
        let decoded = PriorSamples::decode(&mut bytes.as_slice(), 12).expect("decodes");
        assert_eq!(decoded, prior);
        let (pixels, variance) = decoded.combine(4, None, &fs, &fq);
        for i in 0..12 {
            if i == 5 {
                assert!((pixels[i][0] - 2.0).abs() < 1e-6, "{:?}", pixels[i]);
                // Var(mean) = (4/3)/4 of the final pass, × 8 samples.
                assert!((variance[i][0] - 8.0 / 3.0).abs() < 1e-4, "{:?}", variance[i]);
            } else {
                assert_eq!((pixels[i], variance[i]), (kept.0[i], kept.1[i]));
            }
        }
        // A pixel without final samples keeps the training's.
        let counts: Vec<u32> = (0..12).map(|i| if i == 5 { 0 } else { 4 }).collect();
        let (pixels, _) = decoded.combine(4, Some(&counts), &fs, &fq);
        assert!((pixels[5][0] - 1.0).abs() < 1e-6, "{:?}", pixels[5]);
        // Marks of the wrong size are ignored; a truncated mark section is refused.
        let mut other = PriorSamples::new(w, h);
        other.exclude(&[true; 3]);
        assert!(other.excluded.is_empty());
        bytes.pop();
        assert!(PriorSamples::decode(&mut bytes.as_slice(), 12).is_none());
    }

    #[test]
    fn weights_follow_inverse_variance() {
        let (w, h) = (4, 3);
        let mut prior = PriorSamples::new(w, h);
        let a = vec![[1.0; 3]; 12];
        let b = vec![[2.0; 3]; 12];
        // Pass a: 4 spp with per-sample variance ≈ 4·4/3; final b: 4 spp, variance ≈ 4/3.
        let (s, q) = pass(&a, 4, 2.0);
        assert!(prior.add_pass(4, &s, &q));
        let (s, q) = pass(&b, 4, 1.0);
        let (pixels, variance) = prior.combine(4, None, &s, &q);
        // Weights 1/4 : 1 → (1·0.25 + 2·1)/1.25 = 1.8.
        for p in &pixels {
            assert!((p[0] - 1.8).abs() < 1e-5, "{p:?}");
        }
        // Var(mean) = (0.25²·16/3/4 + 1·4/3/4)/1.25² = 4/15; × 8 samples.
        for v in &variance {
            assert!((v[0] - 8.0 * 4.0 / 15.0).abs() < 1e-4, "{v:?}");
        }
        // A one-sample pass is not added (its variance is unknown).
        let (s, q) = pass(&a, 1, 0.0);
        assert!(!prior.add_pass(1, &s, &q));
        assert_eq!(prior.spp, 4);
    }

    /// A pixel's weights never depend on its own values: changing one pixel's samples changes
    /// that pixel's output and the other parity's weights, never another pixel of its parity.
    #[test]
    fn a_pixel_does_not_weight_itself() {
        let (w, h) = (5, 4);
        let base: Vec<[f64; 3]> = (0..20).map(|i| [i as f64 * 0.1, 0.5, 1.0]).collect();
        // The firefly in the training pass (`final_pass` false) or in the final one, which
        // the last training pass's weight also reads.
        let render = |bump: bool, final_pass: bool| {
            let mut prior = PriorSamples::new(w, h);
            let (s, mut q) = pass(&base, 8, 1.0);
            // Pixel 6 (x 1, y 1: even parity) gets a firefly-sized second moment.
            if bump && !final_pass {
                q[6] = q[6].map(|x| x * 50.0);
            }
            prior.add_pass(8, &s, &q);
            let (s, mut q) = pass(&base.iter().map(|v| v.map(|x| x + 0.3)).collect::<Vec<_>>(), 8, 0.5);
            if bump && final_pass {
                q[6] = q[6].map(|x| x * 50.0);
            }
            prior.combine(8, None, &s, &q).0
        };
        for final_pass in [false, true] {
            let (plain, bumped) = (render(false, final_pass), render(true, final_pass));
            for i in 0..20 {
                if parity(i, w) == 0 && i != 6 {
                    assert_eq!(plain[i], bumped[i], "pixel {i} of the same parity moved");
                }
            }
            assert!((0..20).any(|i| parity(i, w) == 1 && plain[i] != bumped[i]), "the other parity's weights follow");
        }
    }

    /// Training passes that all missed a light smaller than a pixel (so they look nearly
    /// noiseless) weigh no more per sample than the final pass that met it, whose variance
    /// that light makes 1000 times theirs: every sample counts alike then. Without the floor
    /// the final pass would weigh 1/1000 per sample of the training's, and the image would
    /// read the training's mean.
    #[test]
    fn training_is_no_better_than_the_final_passes() {
        let (w, h) = (4, 4);
        let mut prior = PriorSamples::new(w, h);
        for _ in 0..2 {
            let (s, q) = pass(&[[1.0; 3]; 16], 8, 0.01);
            assert!(prior.add_pass(8, &s, &q));
        }
        let (s, q) = pass(&[[4.0; 3]; 16], 16, 0.01 * 1000f64.sqrt());
        let (pixels, _) = prior.combine(16, None, &s, &q);
        // 16 training samples of mean 1 and 16 final samples of mean 4, weighted alike: 2.5.
        for p in &pixels {
            assert!((p[0] - 2.5).abs() < 1e-5, "{p:?}");
        }
    }

    /// A pass is weighed by the larger of its variance and its successor's: a 2-spp pass that
    /// measured a tenth of the next pass's variance weighs as a pass of that variance would.
    #[test]
    fn a_pass_is_no_better_than_its_successor() {
        let (w, h) = (4, 2);
        let mut prior = PriorSamples::new(w, h);
        let (s, q) = pass(&[[1.0; 3]; 8], 2, 1.0);
        assert!(prior.add_pass(2, &s, &q));
        let (s, q) = pass(&[[3.0; 3]; 8], 8, 10f64.sqrt());
        assert!(prior.add_pass(8, &s, &q));
        prior.finish();
        // Per-sample variances 2 and 80/7: weights 2·7/80 and 8·7/80 → (1·2 + 3·8)/10 = 2.6;
        // with the first pass's own variance it would be (1·1 + 3·0.7)/1.7 = 1.82.
        let (s, q) = pass(&[[3.0; 3]; 8], 0, 0.0);
        let (pixels, _) = prior.combine(0, None, &s, &q);
        for p in &pixels {
            assert!((p[0] - 2.6).abs() < 1e-5, "{p:?}");
        }
        assert_eq!(prior.spp, 10);
    }

    /// The last training pass is weighed against the final passes the same way: a 2-spp pass
    /// that measured a tenth of the final passes' variance weighs as one of their variance.
    /// Encoded (a checkpoint or part file) before the final passes, it stays unweighed and
    /// gives the same pixels.
    #[test]
    fn the_last_pass_is_no_better_than_the_final_passes() {
        let (w, h) = (4, 2);
        let mut prior = PriorSamples::new(w, h);
        let (s, q) = pass(&[[1.0; 3]; 8], 2, 1.0);
        assert!(prior.add_pass(2, &s, &q));
        let (s, q) = pass(&[[3.0; 3]; 8], 8, 10f64.sqrt());
        // As above: 2.6, where the pass's own variance would give 1.82.
        let (pixels, _) = prior.combine(8, None, &s, &q);
        for p in &pixels {
            assert!((p[0] - 2.6).abs() < 1e-5, "{p:?}");
        }
        let mut bytes = Vec::new();
        prior.encode(&mut bytes);
        let mut rest = bytes.as_slice();
        let back = PriorSamples::decode(&mut rest, 8).unwrap();
        assert!(rest.is_empty() && back == prior);
        assert_eq!(back.combine(8, None, &s, &q), prior.combine(8, None, &s, &q));
        // Cut anywhere, the encoding is refused, never misread.
        for cut in [bytes.len() - 1, bytes.len() - 100, 100] {
            assert!(PriorSamples::decode(&mut &bytes[..cut], 8).is_none(), "cut at {cut}");
        }
    }

    #[test]
    fn one_pixel_images_weight_by_sample_count() {
        let mut prior = PriorSamples::new(1, 1);
        let (s, q) = pass(&[[1.0; 3]], 2, 1.0);
        prior.add_pass(2, &s, &q);
        let (s, q) = pass(&[[4.0; 3]], 6, 3.0);
        let (pixels, _) = prior.combine(6, None, &s, &q);
        assert!((pixels[0][0] - 3.25).abs() < 1e-6, "{pixels:?}");
    }
}
