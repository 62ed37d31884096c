//! `zvidpt merge`: partial renders of sample ranges into one image, bit-identical to a single
//! render of all the samples.
use super::*;
use crate::film::Partial;

#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Partial renders (`zvidpt render --samples A..B`) covering 0..spp once each.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// Output EXR.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub png: PngArgs,
    /// Set by `zvidpt batch --slurm`'s merge job: the batch job's fingerprint, kept in the
    /// metadata so that a rerun of the batch skips this render.
    #[arg(long, hide = true)]
    pub job_key: Option<String>,
}

/// Metadata that differs between parts of one render (timings, machine, range).
const PER_PART: [&str; 10] = [
    "seconds",
    "prepass_seconds",
    "prepass",
    "rays",
    "threads",
    "samples",
    "version",
    "job",
    "final_spp",
    "resumed_at_spp",
];

pub fn run_merge(args: &MergeArgs) -> Result<()> {
    let png = args.png.destination(&args.output, false)?;
    let mut outputs = vec![("EXR", args.output.as_path())];
    if let Some(p) = &png {
        outputs.push(("PNG", p.as_path()));
    }
    let inputs: Vec<(&str, &Path)> = args.parts.iter().map(|p| ("part", p.as_path())).collect();
    film::check_outputs(&outputs, &inputs)?;
    let mut parts = Vec::with_capacity(args.parts.len());
    let mut head: Option<(PathBuf, Metadata)> = None;
    let (mut seconds, mut rays) = (0.0f64, 0u64);
    for path in &args.parts {
        let (part, meta) = film::read_partial(path)?;
        if meta.get("checkpoint").is_some() {
            return Err(Error::InvalidOption(format!(
                "{} is the checkpoint of an unfinished part: finish it with `zvidpt render ... --resume`",
                path.display()
            )));
        }
        seconds += meta.get("seconds").and_then(|s| s.parse::<f64>().ok()).unwrap_or(0.0);
        rays += meta.get("rays").and_then(|s| s.parse::<u64>().ok()).unwrap_or(0);
        match &head {
            None => head = Some((path.clone(), meta)),
            Some((first, m)) => {
                // Same scene, integrator, flags and seed: everything but the per-part facts.
                let keep = |m: &Metadata| -> Vec<(String, String)> {
                    m.entries.iter().filter(|(k, _)| !PER_PART.contains(&k.as_str())).cloned().collect()
                };
                let (a, b) = (keep(m), keep(&meta));
                if a != b {
                    let differ = a
                        .iter()
                        .find(|e| !b.contains(e))
                        .or_else(|| b.iter().find(|e| !a.contains(e)))
                        .map_or_else(String::new, |(k, _)| format!(" ({k})"));
                    return Err(Error::InvalidOption(format!(
                        "{} and {} are parts of different renders{differ}",
                        first.display(),
                        path.display()
                    )));
                }
            }
        }
        parts.push(part);
    }
    let (_, head_meta) = head.ok_or_else(|| Error::InvalidOption("no parts".into()))?;
    let count = parts.len();
    let merged = Partial::merge(parts)?;
    let image = merged.image();
    let mut meta = Metadata::default();
    for (k, v) in &head_meta.entries {
        if !PER_PART.contains(&k.as_str()) && k != "spp_total" {
            meta.push(k, v);
        }
    }
    if merged.prior.is_some() {
        meta.push("final_spp", merged.total_spp);
    }
    meta.push("merged_parts", count);
    meta.push("seconds", format!("{seconds:.3}"));
    meta.push("rays", rays);
    meta.push("version", crate::VERSION);
    if let Some(key) = &args.job_key {
        meta.push("job", key);
    }
    let mut staged = vec![film::stage_exr(&args.output, &image, &meta)?];
    if let Some(p) = &png {
        staged.push(film::stage_png(p, &image, args.png.exposure)?);
    }
    film::commit(staged)?;
    out!(
        "merged {count} parts, {}x{}, {} spp -> {}{}",
        image.width,
        image.height,
        merged.total_spp,
        args.output.display(),
        png.as_ref().map_or(String::new(), |p| format!(", {}", p.display()))
    );
    Ok(())
}
