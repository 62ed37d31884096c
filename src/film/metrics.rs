use super::Image;
use super::png_out::write_rgb8;
use crate::{Error, Result};
use std::path::Path;

/// Error of an image against a reference (ALGORITHM.md §6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Mean over pixels and channels of `(a − b)²`.
    pub mse: f64,
    /// Mean of `(a − b)² / (b² + 0.01)`.
    pub rel_mse: f64,
}

/// Share of pixels [`trimmed`] leaves out: the worst one in a thousand.
pub const TRIM_FRACTION: f64 = 0.001;

/// MSE and relMSE without the [`TRIM_FRACTION`] of pixels with the largest error (each metric
/// leaves out its own worst pixels; none on images under 1,000 pixels). A single firefly of
/// a heavy-tailed estimator (a caustic, a sub-pixel light) can hold most of an image's squared
/// error, so that two seeds' MSE differ 60×; these figures say how the rest of the image
/// converges. They are not unbiased measures of the expected error: report them beside the
/// plain metrics, never instead of them.
pub fn trimmed(image: &Image, reference: &Image) -> Result<Metrics> {
    same_size(image, reference)?;
    let (mut se, mut rel): (Vec<f64>, Vec<f64>) = image
        .pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(a, b)| {
            (0..3).fold((0.0, 0.0), |(se, rel), c| {
                let d = (f64::from(a[c]) - f64::from(b[c])).powi(2);
                (se + d, rel + d / (f64::from(b[c]).powi(2) + 0.01))
            })
        })
        .unzip();
    let keep = se.len() - (se.len() as f64 * TRIM_FRACTION) as usize;
    let mean_of_best = |v: &mut Vec<f64>| {
        v.sort_unstable_by(f64::total_cmp);
        v[..keep].iter().sum::<f64>() / (3 * keep).max(1) as f64
    };
    Ok(Metrics { mse: mean_of_best(&mut se), rel_mse: mean_of_best(&mut rel) })
}

fn same_size(a: &Image, b: &Image) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::InvalidOption(format!(
            "image sizes differ: {}x{} vs {}x{}",
            a.width, a.height, b.width, b.height
        )));
    }
    Ok(())
}

/// MSE and relMSE of `image` against `reference`.
pub fn metrics(image: &Image, reference: &Image) -> Result<Metrics> {
    metrics_of_rows(image, reference, 0..image.height)
}

/// MSE and relMSE over the pixel rows `rows` only (`zvidpt diff --bands`: where the error is).
pub fn metrics_of_rows(image: &Image, reference: &Image, rows: std::ops::Range<u32>) -> Result<Metrics> {
    same_size(image, reference)?;
    let w = image.width as usize;
    let span = rows.start.min(image.height) as usize * w..rows.end.min(image.height) as usize * w;
    let n = (span.len() * 3).max(1) as f64;
    let (mut se, mut rel) = (0.0f64, 0.0f64);
    for (a, b) in image.pixels[span.clone()].iter().zip(&reference.pixels[span]) {
        for c in 0..3 {
            let d = (a[c] as f64 - b[c] as f64).powi(2);
            se += d;
            rel += d / ((b[c] as f64).powi(2) + 0.01);
        }
    }
    Ok(Metrics { mse: se / n, rel_mse: rel / n })
}

/// The mean of independent renders of the same image (same size): one reference of their
/// combined samples.
pub fn mean_image(images: &[Image]) -> Result<Image> {
    let first = images.first().ok_or_else(|| Error::InvalidOption("no image to average".into()))?;
    for other in &images[1..] {
        same_size(first, other)?;
    }
    let k = images.len() as f64;
    let pixels = (0..first.pixels.len())
        .map(|i| [0, 1, 2].map(|c| (images.iter().map(|im| f64::from(im.pixels[i][c])).sum::<f64>() / k) as f32))
        .collect();
    let spp = images.iter().map(|im| im.spp).fold(0u32, u32::saturating_add);
    Ok(Image { width: first.width, height: first.height, pixels, variance: None, spp })
}

/// The noise of [`mean_image`] of `k ≥ 2` independent renders: the mean over pixels and
/// channels of their unbiased sample variance over `k`. Every MSE against that mean contains
/// this term in expectation, so `mse − reference_noise` estimates the error against the
/// converged image without bias (and may come out below zero when both are tiny). It needs
/// independent renders (different seeds), not one image's variance layer: that layer is the
/// variance of independent samples, which a stratified sampler's pixel is not (at an edge it
/// overstates the noise many times). `None` for fewer than two images.
pub fn reference_noise(images: &[Image]) -> Result<Option<f64>> {
    let k = images.len();
    if k < 2 {
        return Ok(None);
    }
    for other in &images[1..] {
        same_size(&images[0], other)?;
    }
    let sum: f64 = (0..images[0].pixels.len()).map(|i| (0..3).map(|c| noise_of_mean(images, i, c)).sum::<f64>()).sum();
    Ok(Some(sum / (3 * images[0].pixels.len()).max(1) as f64))
}

/// The variance of the mean of `k ≥ 2` independent renders at pixel `i`, channel `c`, from
/// their spread: their unbiased sample variance over `k`.
fn noise_of_mean(images: &[Image], i: usize, c: usize) -> f64 {
    let k = images.len() as f64;
    let mean = images.iter().map(|im| f64::from(im.pixels[i][c])).sum::<f64>() / k;
    images.iter().map(|im| (f64::from(im.pixels[i][c]) - mean).powi(2)).sum::<f64>() / (k - 1.0) / k
}

/// The squared error of the brightest `fraction` of the reference's pixels (by mean over
/// channels; a light seen directly, its sharp reflections) and of the rest, each summed over
/// its pixels and divided by all the image's values, so the two add up to the MSE; with two or
/// more independent references, each less their noise in its pixels (as [`reference_noise`]).
/// The error in the brightest pixels is mostly the pixel footprint's (how often a sample
/// lands on a light smaller than the pixel), the rest the light transport's.
pub fn split_by_brightness(image: &Image, references: &[Image], fraction: f64) -> Result<(f64, f64)> {
    let reference = mean_image(references)?;
    same_size(image, &reference)?;
    let n = image.pixels.len();
    let mut order: Vec<usize> = (0..n).collect();
    let lum = |i: usize| reference.pixels[i].iter().map(|&x| f64::from(x)).sum::<f64>();
    order.sort_unstable_by(|&a, &b| lum(b).total_cmp(&lum(a)));
    let bright = ((n as f64 * fraction.clamp(0.0, 1.0)).round() as usize).min(n);
    let error = |i: usize| {
        (0..3)
            .map(|c| {
                let d = (f64::from(image.pixels[i][c]) - f64::from(reference.pixels[i][c])).powi(2);
                d - if references.len() < 2 { 0.0 } else { noise_of_mean(references, i, c) }
            })
            .sum::<f64>()
    };
    let total = (3 * n).max(1) as f64;
    let (top, rest) = order.split_at(bright);
    Ok((top.iter().map(|&i| error(i)).sum::<f64>() / total, rest.iter().map(|&i| error(i)).sum::<f64>() / total))
}

/// A false-colour PNG of per-pixel relative squared error (mean over channels), on a log scale
/// from 1e-4 (dark blue) to 1 (yellow-white).
pub fn error_map_png(path: &Path, image: &Image, reference: &Image) -> Result<()> {
    same_size(image, reference)?;
    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .zip(&reference.pixels)
        .flat_map(|(a, b)| {
            let e: f64 =
                (0..3).map(|c| (a[c] as f64 - b[c] as f64).powi(2) / ((b[c] as f64).powi(2) + 0.01)).sum::<f64>() / 3.0;
            let t = ((e.max(1e-12).log10() + 4.0) / 4.0).clamp(0.0, 1.0) as f32;
            colormap(t)
        })
        .collect();
    write_rgb8(path, image.width, image.height, &bytes)
}

/// A perceptually ordered dark-blue → magenta → orange → pale-yellow ramp.
fn colormap(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] =
        [[0.0, 0.0, 0.02], [0.25, 0.05, 0.45], [0.72, 0.18, 0.45], [0.98, 0.55, 0.12], [0.99, 0.99, 0.75]];
    let x = t * (STOPS.len() - 1) as f32;
    let i = (x as usize).min(STOPS.len() - 2);
    let f = x - i as f32;
    let c = [0, 1, 2].map(|k| STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f);
    c.map(|v| (v * 255.0 + 0.5) as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mse_and_rel_mse() {
        let a = Image { width: 2, height: 1, pixels: vec![[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]], variance: None, spp: 1 };
        let b = Image { pixels: vec![[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], ..a.clone() };
        let m = metrics(&a, &b).unwrap();
        assert!((m.mse - 0.5).abs() < 1e-12);
        assert!((m.rel_mse - 0.5 / 0.01).abs() < 1e-9);
        assert_eq!(metrics(&a, &a).unwrap().mse, 0.0);
        let c = Image { width: 1, height: 2, ..a.clone() };
        assert!(metrics(&a, &c).is_err());
        assert_eq!(reference_noise(std::slice::from_ref(&b)).unwrap(), None);
        // Two "renders" 0 and 1 of every value: mean 0.5, sample variance 0.5, noise 0.5 / 2.
        let ones = Image { pixels: vec![[1.0; 3]; 2], ..b.clone() };
        let noise = reference_noise(&[b.clone(), ones.clone()]).unwrap().unwrap();
        assert!((noise - 0.25).abs() < 1e-12, "{noise}");
        let mean = mean_image(&[b.clone(), ones]).unwrap();
        assert!(mean.pixels.iter().all(|p| *p == [0.5; 3]) && mean.spp == 2);
        assert!(reference_noise(&[a.clone(), c.clone()]).is_err());
        // a against b: all the error in a's bright pixel, none in the rest; the parts add up.
        let (top, rest) = split_by_brightness(&b, std::slice::from_ref(&a), 0.5).unwrap();
        assert!((top - 0.5).abs() < 1e-12 && rest == 0.0, "{top} {rest}");
        let (all, none) = split_by_brightness(&b, std::slice::from_ref(&a), 1.0).unwrap();
        assert!((all - m.mse).abs() < 1e-12 && none == 0.0);
        // Under 1,000 pixels nothing is left out.
        assert_eq!(trimmed(&a, &b).unwrap(), m);
    }

    #[test]
    fn trimmed_leaves_out_the_worst_pixels() {
        let zero = Image { width: 100, height: 20, pixels: vec![[0.0; 3]; 2000], variance: None, spp: 1 };
        let mut a = zero.clone();
        a.pixels.iter_mut().for_each(|p| *p = [0.1; 3]);
        // Two fireflies in 2,000 pixels: the plain MSE is theirs, the trimmed one the rest's.
        a.pixels[7] = [100.0; 3];
        a.pixels[1500] = [50.0; 3];
        let m = metrics(&a, &zero).unwrap();
        let t = trimmed(&a, &zero).unwrap();
        assert!((m.mse - (1998.0 * 0.01 + 10000.0 + 2500.0) / 2000.0).abs() < 1e-9, "{m:?}");
        assert!((t.mse - 0.01).abs() < 1e-8, "{t:?}");
        assert!((t.rel_mse - 1.0).abs() < 1e-6, "{t:?}");
        // A third firefly stays in.
        a.pixels[3] = [10.0; 3];
        assert!((trimmed(&a, &zero).unwrap().mse - (1997.0 * 0.01 + 100.0) / 1998.0).abs() < 1e-6);
    }
}
