//! `zvidpt info`: an EXR's size, metadata and channel means.
use super::*;

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// An EXR written by zvidpt (or any RGB EXR).
    pub image: PathBuf,
}

pub(super) fn run_info(args: &InfoArgs) -> Result<()> {
    let (image, meta) = film::read_exr(&args.image)?;
    let m = image.mean();
    out_part!(
        "{}: {}x{}, mean RGB ({:.5}, {:.5}, {:.5})",
        args.image.display(),
        image.width,
        image.height,
        m[0],
        m[1],
        m[2]
    );
    // Standard error of the image mean from the per-pixel sample variances.
    match (&image.variance, image.spp) {
        (Some(v), spp) if spp > 1 => {
            let n = v.len() as f64;
            let se = [0, 1, 2].map(|c| (v.iter().map(|p| p[c] as f64).sum::<f64>() / spp as f64).sqrt() / n);
            let mean_var = [0, 1, 2].map(|c| v.iter().map(|p| p[c] as f64).sum::<f64>() / n);
            out!(" ± ({:.5}, {:.5}, {:.5}) (1 s.e.)", se[0], se[1], se[2]);
            out!("  mean per-sample variance ({:.4e}, {:.4e}, {:.4e})", mean_var[0], mean_var[1], mean_var[2]);
        }
        _ => out!(),
    }
    let bad = non_finite_values(&image);
    if bad > 0 {
        out!("  note: {bad} pixel values are NaN or infinite (so is the mean)");
    }
    // Attribute text comes from the file: control characters are shown escaped.
    let printable = |s: &str| -> String {
        s.chars().map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() }).collect()
    };
    for (k, v) in &meta.entries {
        out!("  {} = {}", printable(k), printable(v));
    }
    Ok(())
}
