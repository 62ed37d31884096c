//! `zvidpt diff`: MSE and relMSE of an image against a reference.
use super::*;

#[derive(Debug, Args)]
pub struct DiffArgs {
    /// The image to measure.
    pub image: PathBuf,
    /// The reference image.
    pub reference: PathBuf,
    /// Write a false-colour PNG of per-pixel relative squared error.
    #[arg(long)]
    pub error_map: Option<PathBuf>,
    /// Also print the error of N horizontal bands of rows (top first), each with its share of
    /// the whole image's squared error.
    #[arg(long, value_name = "N")]
    pub bands: Option<u32>,
}

pub(super) fn run_diff(args: &DiffArgs) -> Result<()> {
    let (image, _) = film::read_exr(&args.image)?;
    let (reference, _) = film::read_exr(&args.reference)?;
    if let Some(p) = &args.error_map {
        film::check_outputs(&[("error map", p)], &[("image", &args.image), ("reference", &args.reference)])?;
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
