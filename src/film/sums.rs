//! Exact per-pixel sums of samples and their squares (fixed point, so that any split of a
//! pixel's samples adds up to the same bits), and a render of a range of samples
//! ([`Partial`]) that split renders write and `merge` adds.
use super::Image;
use super::passes::{PriorSamples, mean_and_variance};
use crate::{Error, Result};

/// Fixed-point scale of the per-pixel sums: 2^40.
const FIXED_SCALE: f64 = (1u64 << 40) as f64;

/// Channel-wise sum of two fixed-point channel sums (saturating, as every fixed-point sum).
#[inline]
pub(crate) fn add_fixed(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    std::array::from_fn(|c| a[c].saturating_add(b[c]))
}

/// A sample (or its square) in fixed point, rounded to the nearest 2^-40. Sums of these are
/// exact integers, so the sums of any split of a pixel's samples add up to the same bits as
/// one render's: merged parts give bit-identical pixels. (The rounding moves a sample by at
/// most 4.5e-13, far below an f32 sample's own precision above 1e-5.)
#[inline]
pub(crate) fn to_fixed(x: f64) -> i128 {
    let y = x * FIXED_SCALE;
    if y.abs() < 9.2e18 {
        // Round half away from zero, by the fast 64-bit conversion.
        (y + 0.5f64.copysign(y)) as i64 as i128
    } else {
        // Saturates beyond i128 (never for a finite f32 sample or its square).
        y.round() as i128
    }
}

#[inline]
fn from_fixed(v: i128) -> f64 {
    v as f64 / FIXED_SCALE
}

/// Per-pixel exact sums of samples and of their squares (fixed point), row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct PixelSums {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel summed (with `counts`, the most any pixel took).
    pub spp: u32,
    pub sum: Vec<[i128; 3]>,
    pub sum_sq: Vec<[i128; 3]>,
    /// Each pixel's own sample count where pixels took different counts (adaptive sampling);
    /// empty when every pixel took `spp`.
    pub counts: Vec<u32>,
}

impl PixelSums {
    /// Samples summed in pixel `j` (row-major).
    #[inline]
    #[must_use]
    pub fn count(&self, j: usize) -> u32 {
        self.counts.get(j).copied().unwrap_or(self.spp)
    }

    /// The image's pixels and per-sample variances: the means, or with a learning integrator's
    /// earlier passes, their combination with these sums.
    #[must_use]
    pub fn finish(&self, prior: Option<&PriorSamples>) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let to_f64 = |v: &[[i128; 3]]| -> Vec<[f64; 3]> { v.iter().map(|p| p.map(from_fixed)).collect() };
        if let Some(prior) = prior {
            // Samples from before the passes (training) come in by inverse-variance weights.
            let counts = (!self.counts.is_empty()).then_some(self.counts.as_slice());
            return prior.combine(self.spp, counts, &to_f64(&self.sum), &to_f64(&self.sum_sq));
        }
        (0..self.sum.len()).map(|j| finish_counted(&self.sum[j], &self.sum_sq[j], self.count(j), self.spp)).unzip()
    }
}

/// A pixel's mean and variance from its exact sums of `n` samples, in an image of `spp`
/// samples per pixel: the variance is scaled by `spp / n`, so that divided by the image's
/// `spp`, as every reader of an [`Image`] divides it, it gives this pixel's variance of the
/// mean (adaptive sampling leaves pixels with fewer samples than the image's count).
#[inline]
pub(crate) fn finish_counted(s: &[i128; 3], q: &[i128; 3], n: u32, spp: u32) -> ([f32; 3], [f32; 3]) {
    let (mean, var) = finish_pixel(s, q, n);
    if n == spp || n == 0 {
        return (mean, var);
    }
    let scale = (f64::from(spp) / f64::from(n)) as f32;
    (mean, var.map(|v| v * scale))
}

/// A pixel's mean and per-sample variance from its exact sums of `spp` samples.
#[inline]
pub(crate) fn finish_pixel(s: &[i128; 3], q: &[i128; 3], spp: u32) -> ([f32; 3], [f32; 3]) {
    let n = f64::from(spp);
    let (mut mean, mut var) = ([0.0f32; 3], [0.0f32; 3]);
    for c in 0..3 {
        let (m, v) = match spp {
            0 => (0.0, 0.0),
            1 => (from_fixed(s[c]), 0.0),
            _ => mean_and_variance(from_fixed(s[c]), from_fixed(q[c]), n),
        };
        (mean[c], var[c]) = (m as f32, v as f32);
    }
    (mean, var)
}

/// A render of final samples `first..first + sums.spp` of a `total_spp`-sample render, with
/// what the pre-pass put into the image (each part recomputes the pre-pass, deterministically,
/// so every part holds the same).
#[derive(Clone, Debug, PartialEq)]
pub struct Partial {
    pub first: u32,
    pub total_spp: u32,
    pub sums: PixelSums,
    pub prior: Option<PriorSamples>,
}

impl Partial {
    /// Adds parts that together cover samples `0..total_spp` once each (in any order) into one
    /// whose image is bit-identical to a single render's.
    pub fn merge(mut parts: Vec<Partial>) -> Result<Partial> {
        parts.sort_by_key(|p| p.first);
        let Some(head) = parts.first() else {
            return Err(Error::InvalidOption("no parts to merge".into()));
        };
        let (width, height, total) = (head.sums.width, head.sums.height, head.total_spp);
        let mut next = 0u32;
        for p in &parts {
            if (p.sums.width, p.sums.height, p.total_spp) != (width, height, total) {
                return Err(Error::InvalidOption(format!(
                    "parts differ: {}x{} of {} spp against {}x{} of {} spp",
                    p.sums.width, p.sums.height, p.total_spp, width, height, total
                )));
            }
            if p.prior != head.prior {
                return Err(Error::InvalidOption("parts differ in their pre-pass samples".into()));
            }
            if p.first != next {
                return Err(Error::InvalidOption(if p.first < next {
                    format!("samples {}.. are in two parts", p.first)
                } else {
                    format!("samples {next}..{} are in no part", p.first)
                }));
            }
            next = p.first + p.sums.spp;
        }
        if next != total {
            return Err(Error::InvalidOption(format!("samples {next}..{total} are in no part")));
        }
        // Per-pixel counts (sample rates: each part took its pixels' share of its range) add up.
        let counts = if parts.iter().any(|p| !p.sums.counts.is_empty()) {
            let n = parts[0].sums.sum.len();
            if parts.iter().any(|p| !p.sums.counts.is_empty() && p.sums.counts.len() != n) {
                return Err(Error::InvalidOption("parts differ in their per-pixel counts".into()));
            }
            (0..n).map(|j| parts.iter().map(|p| p.sums.count(j)).fold(0u32, u32::saturating_add)).collect()
        } else {
            Vec::new()
        };
        let mut merged = parts.swap_remove(0);
        let add = |into: &mut [[i128; 3]], from: &[[i128; 3]]| {
            for (acc, v) in into.iter_mut().zip(from) {
                *acc = add_fixed(*acc, *v);
            }
        };
        for p in &parts {
            add(&mut merged.sums.sum, &p.sums.sum);
            add(&mut merged.sums.sum_sq, &p.sums.sum_sq);
        }
        merged.first = 0;
        merged.sums.spp = total;
        merged.sums.counts = counts;
        Ok(merged)
    }

    /// The image of these samples (and the pre-pass's).
    #[must_use]
    pub fn image(&self) -> Image {
        let (pixels, variance) = self.sums.finish(self.prior.as_ref());
        let prior_spp = self.prior.as_ref().map_or(0, |p| p.spp);
        Image {
            width: self.sums.width,
            height: self.sums.height,
            pixels,
            variance: Some(variance),
            spp: self.sums.spp + prior_spp,
        }
    }
}
