//! `zvidpt reference`: a high-spp path-traced reference, skipped when up to date.
use super::*;

#[derive(Debug, Args)]
pub struct ReferenceArgs {
    /// Scene file, or a folder holding `scene.toml`.
    #[arg(default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Samples per pixel.
    #[arg(long, default_value_t = 4096)]
    pub spp: u32,
    /// Output EXR (with a PNG beside it).
    #[arg(short, long, default_value = "reference.exr")]
    pub output: PathBuf,
    /// Random seed (kept apart from the seeds `converge` uses).
    #[arg(long, default_value_t = 1_000_003)]
    pub seed: u64,
    /// Render even if an up-to-date reference exists.
    #[arg(long)]
    pub force: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

pub(super) fn check_reference_options(args: &ReferenceArgs) -> Result<()> {
    if args.spp == 0 {
        return Err(Error::InvalidOption("--spp must be at least 1".into()));
    }
    Ok(())
}

pub(super) fn run_reference(args: &ReferenceArgs) -> Result<()> {
    check_reference_options(args)?;
    args.machine.backend.check_available()?;
    let scene = load_at(&args.scene, args.machine.resolution)?;
    let hash = format!("{:016x}", scene.content_hash());
    let up_to_date = !args.force
        && args.output.is_file()
        && film::read_exr(&args.output).is_ok_and(|(image, meta)| {
            meta.get("scene_hash") == Some(hash.as_str())
                && image.spp == args.spp
                && meta.get("integrator") == Some("path")
                && image.variance.is_some()
                && meta.get("seed") == Some(args.seed.to_string().as_str())
        });
    if up_to_date {
        out!("{}: up to date ({} spp, scene {hash}); --force renders it again", args.output.display(), args.spp);
        return Ok(());
    }
    let png = args.output.with_extension("png");
    if film::same_file(&png, &args.output) {
        return Err(Error::InvalidOption(format!(
            "-o {} names the EXR, and the PNG beside it would be the same file: use -o NAME.exr",
            args.output.display()
        )));
    }
    check_derived_png(&png)?;
    let inputs: Vec<(&str, &Path)> = scene.sources.iter().map(|s| ("scene's file", s.as_path())).collect();
    film::check_outputs(&[("EXR", &args.output), ("PNG", &png)], &inputs)?;
    let settings = RenderSettings {
        samples: None,
        progress_json: false,
        checkpoint: None,
        spp: Some(args.spp),
        time_limit: None,
        seed: args.seed,
        threads: args.machine.threads,
        tile_size: 32,
        progress: !args.quiet,
        light_sampling: LightSampling::default(),
        noise_target: None,
    };
    let photon = PhotonArgs::default_for_path();
    let (image, stats, backend) =
        render_scene(&scene, &photon.integrator(IntegratorKind::Path), args.machine.backend, &settings)?;
    let mut meta = Metadata::default();
    meta.push("scene", scene.path.display());
    meta.push("scene_hash", &hash);
    meta.push("integrator", "path");
    photon.describe(IntegratorKind::Path, &mut meta);
    meta.push("backend", backend);
    meta.push("seed", args.seed);
    meta.push("seconds", format!("{:.3}", stats.seconds));
    meta.push("threads", stats.threads);
    meta.push("version", crate::VERSION);
    film::commit(vec![film::stage_exr(&args.output, &image, &meta)?, film::stage_png(&png, &image, 0.0)?])?;
    out!(
        "{}: reference {}x{}, {} spp, {:.1} s ({}, {} threads)",
        args.output.display(),
        image.width,
        image.height,
        stats.spp,
        stats.seconds,
        backend,
        stats.threads
    );
    Ok(())
}
