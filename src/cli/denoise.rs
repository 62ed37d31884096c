//! `zvidpt denoise`: an image denoised by Open Image Denoise into a new file (the noisy
//! estimate stays as it was).
use super::*;

#[derive(Debug, Args)]
pub struct DenoiseArgs {
    /// An EXR written by zvidpt: its R, G, B, guided by its `albedo.*` and `normal.*` layers
    /// where it has them (`render --aov albedo,normal`, or `render --denoise`).
    pub image: PathBuf,
    /// The denoised EXR (never the input).
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub png: PngArgs,
    /// Denoiser threads [default: one per core].
    #[arg(long)]
    pub threads: Option<usize>,
}

/// The auxiliary layers the denoiser reads, as written by `render --aov`.
const AUX: [&str; 6] = ["albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z"];

/// Packs three planes into pixels, if all three are there.
fn pixels3(planes: &[Option<Vec<f32>>]) -> Option<Vec<[f32; 3]>> {
    let [Some(a), Some(b), Some(c)] = planes else { return None };
    Some(a.iter().zip(b).zip(c).map(|((x, y), z)| [*x, *y, *z]).collect())
}

pub fn run_denoise(args: &DenoiseArgs) -> Result<()> {
    let png = args.png.destination(&args.output, false)?;
    let mut outputs = vec![("EXR", args.output.as_path())];
    if let Some(p) = &png {
        outputs.push(("PNG", p.as_path()));
    }
    film::check_outputs(&outputs, &[("noisy image", args.image.as_path())])?;
    let (image, mut meta, aux) = film::read_exr_with(&args.image, &AUX)?;
    let albedo = pixels3(&aux[..3]);
    let normal = pixels3(&aux[3..]);
    let denoiser = crate::denoise::Denoiser::load(args.threads)?;
    let d = denoiser.denoise(image.width, image.height, &image.pixels, albedo.as_deref(), normal.as_deref())?;
    if albedo.is_none() {
        warn!(
            "warning: {} has no albedo/normal layers: denoised from the beauty alone (render with --aov albedo,normal for better results)",
            args.image.display()
        );
    }
    meta.push("denoised_from", args.image.display());
    meta.push("denoiser", d.filter());
    meta.push("denoise_seconds", format!("{:.3}", d.seconds));
    let out = film::Image { pixels: d.pixels, variance: None, ..image };
    let mut staged = vec![film::stage_exr(&args.output, &out, &meta)?];
    if let Some(p) = &png {
        staged.push(film::stage_png(p, &out, args.png.exposure)?);
    }
    film::commit(staged)?;
    out!(
        "{} -> {}: denoised in {:.2} s (guided by {}; {})",
        args.image.display(),
        args.output.display(),
        d.seconds,
        d.guided_by,
        d.library.display()
    );
    Ok(())
}
