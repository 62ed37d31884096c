//! `zvidpt diff`: MSE and relMSE of an image against a reference.
use super::*;

#[derive(Debug, Args)]
pub struct DiffArgs {
    /// The image to measure.
    pub image: PathBuf,
    /// The reference image.
    pub reference: PathBuf,
    /// More references: independent renders of the same image (other seeds). Their mean is
    /// the reference, and the spread between them measures its noise, which every MSE against
    /// it contains: `diff` then also prints the MSE less that noise.
    #[arg(value_name = "MORE_REFERENCES")]
    pub more_references: Vec<PathBuf>,
    /// Write a false-colour PNG of per-pixel relative squared error.
    #[arg(long)]
    pub error_map: Option<PathBuf>,
    /// Also print the error of N horizontal bands of rows (top first), each with its share of
    /// the whole image's squared error.
    #[arg(long, value_name = "N")]
    pub bands: Option<u32>,
    /// Also print the error of the reference's brightest FRACTION of pixels (e.g. 0.003: a
    /// light smaller than a pixel seen directly, whose error is the pixel footprint's) apart
    /// from the rest's (the light transport's); the two add up to the MSE (less the references'
    /// noise, with several).
    #[arg(long, value_name = "FRACTION")]
    pub bright: Option<f64>,
}

pub(super) fn run_diff(args: &DiffArgs) -> Result<()> {
    let (image, _) = film::read_exr(&args.image)?;
    let mut references = vec![film::read_exr(&args.reference)?.0];
    for path in &args.more_references {
        references.push(film::read_exr(path)?.0);
    }
    let noise = film::reference_noise(&references)?;
    let reference = film::mean_image(&references)?;
    if let Some(p) = &args.error_map {
        let mut inputs = vec![("image", args.image.as_path()), ("reference", args.reference.as_path())];
        inputs.extend(args.more_references.iter().map(|r| ("reference", r.as_path())));
        film::check_outputs(&[("error map", p)], &inputs)?;
    }
    let m = film::metrics(&image, &reference)?;
    if let Some(p) = &args.error_map {
        film::error_map_png(p, &image, &reference)?;
    }
    let t = film::trimmed(&image, &reference)?;
    out!(
        "MSE {:.6e}  relMSE {:.6e}  (without the worst {}% of pixels: MSE {:.6e}  relMSE {:.6e})",
        m.mse,
        m.rel_mse,
        100.0 * film::TRIM_FRACTION,
        t.mse,
        t.rel_mse
    );
    if let Some(noise) = noise {
        out!(
            "reference noise {noise:.6e} (from {} independent references)  MSE less it {:.6e}  (the expected error against the converged image)",
            1 + args.more_references.len(),
            m.mse - noise
        );
    }
    if let Some(f) = args.bright {
        if !(f > 0.0 && f < 1.0) {
            return Err(Error::InvalidOption("--bright must lie strictly between 0 and 1".into()));
        }
        let (top, rest) = film::split_by_brightness(&image, &references, f)?;
        out!("brightest {:.3}% of the reference's pixels: MSE {top:.6e}  the rest: MSE {rest:.6e}", 100.0 * f);
    }
    for (what, img, path) in [("image", &image, &args.image), ("reference", &reference, &args.reference)] {
        let bad = non_finite_values(img);
        if bad > 0 {
            warn!("note: the {what} {} has {bad} NaN or infinite pixel values: the errors are NaN", path.display());
        }
    }
    if let Some(n) = args.bands {
        if n == 0 || n > image.height {
            return Err(Error::InvalidOption(format!("--bands must lie in 1..={} (the image's rows)", image.height)));
        }
        for k in 0..n {
            let rows = k * image.height / n..(k + 1) * image.height / n;
            let b = film::metrics_of_rows(&image, &reference, rows.clone())?;
            let share =
                b.mse * f64::from(rows.end - rows.start) / (m.mse * f64::from(image.height)).max(f64::MIN_POSITIVE);
            out!(
                "rows {:>4}..{:<4} MSE {:.4e}  relMSE {:.4e}  share {:5.1}%",
                rows.start,
                rows.end,
                b.mse,
                b.rel_mse,
                100.0 * share
            );
        }
    }
    Ok(())
}
