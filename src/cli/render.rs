//! `zvidpt render`: options, their checks, the render and its outputs.
use super::*;
use crate::render::checkpoint::{CheckpointSettings, Resume, is_checkpoint};

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file (TOML, Mitsuba 3 `.xml`, pbrt-v4 `.pbrt`), or a folder holding `scene.toml`,
    /// `scene.xml`, `scene.pbrt` or `pbrt/scene-v4.pbrt` (the first found).
    #[arg(default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub machine: MachineArgs,
    #[command(flatten)]
    pub scene_args: SceneArgs,
    /// Output EXR (linear float RGB, per-pixel variance, render metadata).
    #[arg(short, long, default_value = "render.exr")]
    pub output: PathBuf,
    #[command(flatten)]
    pub png: PngArgs,
    /// Samples per pixel [default: the scene's (Mitsuba's `sample_count`), else 64; unlimited
    /// when --time is given].
    #[arg(long)]
    pub spp: Option<u32>,
    /// Render only samples A..B of every pixel (of an --spp render) into a partial file at
    /// -o, for `zvidpt merge` (a Slurm array task's share, say). Parts of 0..spp merge into
    /// pixels bit-identical to one render.
    #[arg(long, value_parser = parse_sample_range, value_name = "A..B")]
    pub samples: Option<(u32, u32)>,
    /// Time budget in seconds: render whole passes until it is used up.
    #[arg(long, allow_negative_numbers = true)]
    pub time: Option<f64>,
    /// Stop once the image's estimated relative error (the root of its predicted relMSE:
    /// each pixel's variance of the mean over its squared value + 0.01, averaged) is at most
    /// E (0.05: 5%), judged after every pass from --min-spp on; with --spp or --time, whichever
    /// comes first. Without either, the render runs until it gets there.
    #[arg(long, value_name = "E", allow_negative_numbers = true)]
    pub noise_target: Option<f64>,
    /// Samples per pixel before the noise target is first judged.
    #[arg(long, default_value_t = 16, requires = "noise_target")]
    pub min_spp: u32,
    /// Adaptive sampling: with --noise-target, each pixel stops taking samples once the
    /// relative error estimated for it from its eight neighbours (never from its own samples,
    /// which would bias it) is at most E; the render ends when every pixel has stopped (or at
    /// --spp / --time). Writes each pixel's sample count as the layer `spp`.
    #[arg(long, requires = "noise_target")]
    pub adaptive: bool,
    /// Light-transport algorithm (`zvidpt` by default: far ahead of the path tracer on
    /// indirectly lit scenes, and it falls back to path tracing where its probe finds it
    /// losing; docs/results.md).
    #[arg(long, value_enum, default_value_t = IntegratorKind::Zvidpt)]
    pub integrator: IntegratorKind,
    #[command(flatten)]
    pub photon: PhotonArgs,
    /// Random seed; the same seed, scene and flags give the same image bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Tile side in pixels (does not change the image).
    #[arg(long, default_value_t = 32)]
    pub tile_size: u32,
    /// Extra EXR layers, comma-separated: albedo (albedo.R/G/B), normal (normal.X/Y/Z, world
    /// space, facing the camera), depth (Z, distance to the first hit), spp (per-pixel sample
    /// count), variance (variance.R/G/B, always written). From 9 jittered camera rays per pixel.
    #[arg(long, value_enum, value_delimiter = ',')]
    pub aov: Vec<Aov>,
    /// Also denoise the image with Intel Open Image Denoise (`RT` filter guided by the first
    /// hit's albedo and normal, prefiltered): written as the EXR's `denoised.R/G/B` layers and
    /// as a second PNG (the PNG's name + `-denoised`). The image itself stays the noisy,
    /// unbiased estimate. Needs the library: `pip install pyoidn`, or OIDN_DIR.
    #[arg(long)]
    pub denoise: bool,
    /// Checkpoint file: the render's sums so far, rewritten atomically every
    /// --checkpoint-every seconds and on SIGINT/SIGTERM, removed when the render is done
    /// [default: the EXR's path + .checkpoint].
    #[arg(long, value_name = "PATH", conflicts_with = "no_checkpoint")]
    pub checkpoint: Option<PathBuf>,
    /// Seconds between checkpoints (0: after every pass).
    #[arg(long, default_value_t = 60.0, value_name = "SECONDS")]
    pub checkpoint_every: f64,
    /// Keep no checkpoint (an interrupted render is lost).
    #[arg(long)]
    pub no_checkpoint: bool,
    /// Continue from the checkpoint of an interrupted run of this same render (same scene,
    /// options and seed); the pixels come out bit-identical to an uninterrupted render. Without
    /// a checkpoint, renders from the start.
    #[arg(long, conflicts_with = "no_checkpoint")]
    pub resume: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    /// Set by `zvidpt batch`: the job's fingerprint, kept in the metadata so that a rerun of
    /// the batch skips this render.
    #[arg(long, hide = true)]
    pub job_key: Option<String>,
    /// Set by `zvidpt batch` when its stderr is not a terminal: one JSON line per pass.
    #[arg(long, hide = true)]
    pub progress_json: bool,
}

/// An auxiliary layer of the EXR.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Aov {
    Albedo,
    Normal,
    Depth,
    Variance,
    Spp,
}

/// The denoised PNG beside `png`: its name + `-denoised`.
fn denoised_name(png: &Path) -> PathBuf {
    let stem = png.file_stem().map_or_else(|| "image".into(), |s| s.to_string_lossy().into_owned());
    png.with_file_name(format!("{stem}-denoised.png"))
}

pub(super) fn check_render_options(args: &RenderArgs) -> Result<()> {
    if args.samples.is_some() && args.denoise {
        return Err(Error::InvalidOption(
            "--denoise applies to a whole image: merge the parts, then `zvidpt denoise` the merged image (with --aov albedo,normal in the merge)".into(),
        ));
    }
    if args.samples.is_some() && args.aov.iter().any(|a| *a != Aov::Variance) {
        return Err(Error::InvalidOption(
            "--aov layers are written by `zvidpt merge`'s image, not by a --samples part".into(),
        ));
    }
    if args.spp == Some(0) {
        return Err(Error::InvalidOption("--spp must be at least 1".into()));
    }
    // The training's samples go into the image: more of them than the render asks for in all
    // is a contradiction, not a budget.
    if let (Some(t), Some(n)) = (args.photon.train_spp, args.spp)
        && t > n
        && matches!(args.integrator, IntegratorKind::Zvidpt | IntegratorKind::Jensen)
    {
        return Err(Error::InvalidOption(format!(
            "--train-spp {t} is more than --spp {n}: training samples count towards the render's samples (default: half of them)"
        )));
    }
    if let Some(e) = args.noise_target {
        if !(e.is_finite() && e > 0.0) {
            return Err(Error::InvalidOption(format!("--noise-target must be a positive relative error, got {e}")));
        }
        if args.samples.is_some() {
            return Err(Error::InvalidOption(
                "--noise-target with --samples: the parts of one render would stop at different counts; render it whole"
                    .into(),
            ));
        }
    }
    if !args.png.exposure.is_finite() {
        return Err(Error::InvalidOption("--exposure must be finite".into()));
    }
    if let Some(t) = args.time
        && !(t.is_finite() && t > 0.0)
    {
        return Err(Error::InvalidOption(format!("--time must be a positive number of seconds, got {t}")));
    }
    if args.machine.threads == Some(0) {
        return Err(Error::InvalidOption("--threads must be at least 1".into()));
    }
    if !(args.checkpoint_every.is_finite() && args.checkpoint_every >= 0.0) {
        return Err(Error::InvalidOption(format!(
            "--checkpoint-every must be a number of seconds, 0 or more, got {}",
            args.checkpoint_every
        )));
    }
    if let Some((a, b)) = args.samples {
        // A part holds exact sums for `merge`, not an image: an image's name would mislead.
        if args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr") || e.eq_ignore_ascii_case("png")) {
            return Err(Error::InvalidOption(format!(
                "-o {}: a part of a render (--samples) is not an image; name it .zvp (zvidpt merge writes the image)",
                args.output.display()
            )));
        }
        let Some(n) = args.spp else {
            return Err(Error::InvalidOption("--samples A..B needs --spp N, the whole render's sample count".into()));
        };
        if args.time.is_some() {
            return Err(Error::InvalidOption("--samples cannot be used with --time".into()));
        }
        if !(a < b && b <= n) {
            return Err(Error::InvalidOption(format!(
                "--samples {a}..{b} must lie within 0..{n} (--spp) and hold a sample"
            )));
        }
    }
    args.photon.check()
}

/// The scene as the command line sets it up (its resolution overridden).
pub(super) fn load_scene(args: &RenderArgs) -> Result<Scene> {
    let mut scene = Scene::load_with(locate_scene(&args.scene), &args.scene_args.import_options())?;
    if let Some((w, h)) = args.machine.resolution {
        scene.set_resolution(w, h)?;
    }
    if let Some(d) = args.scene_args.max_depth {
        scene.render.max_depth = Some(d);
    }
    Ok(scene)
}

/// Renders as the command line says; returns what it measured.
pub fn run_render(args: &RenderArgs) -> Result<RenderStats> {
    check_render_options(args)?;
    // A partial render is a file of sums: no PNG. Fail before rendering if an output cannot
    // be written or would replace what it must not.
    let png = args.png.destination(&args.output, args.samples.is_some())?;
    args.machine.backend.check_available()?;
    let loading = std::time::Instant::now();
    let scene = load_scene(args)?;
    let load_seconds = loading.elapsed().as_secs_f64();
    let mut outputs = vec![("EXR", args.output.as_path())];
    if let Some(p) = &png {
        outputs.push(("PNG", p.as_path()));
    }
    let denoised_png = png.as_deref().filter(|_| args.denoise).map(denoised_name);
    if let Some(p) = &denoised_png {
        outputs.push(("denoised PNG", p.as_path()));
    }
    let checkpoint_path = checkpoint_path(args);
    if let Some(p) = &checkpoint_path {
        outputs.push(("checkpoint", p.as_path()));
    }
    let inputs: Vec<(&str, &Path)> = scene.sources.iter().map(|s| ("scene's file", s.as_path())).collect();
    film::check_outputs(&outputs, &inputs)?;
    let checkpoint = match &checkpoint_path {
        Some(path) => Some(checkpoint_settings(args, &scene, path)?),
        None => None,
    };
    // Warnings only once every option is known to be valid, so a failed run prints one line.
    for w in &scene.warnings {
        warn!("warning: {w}");
    }
    if let Some(d) = scene.render.max_depth
        && !matches!(args.integrator, IntegratorKind::Path | IntegratorKind::Jensen | IntegratorKind::Zvidpt)
    {
        warn!(
            "warning: a max depth ({d}) is honoured by path, jensen and zvidpt only: {} counts paths of every length",
            flag_name(args.integrator)
        );
    }
    if scene.render.max_depth == Some(0) {
        warn!(
            "warning: a max depth of 0 counts no path segment at all: the image is black (1: emitters seen directly)"
        );
    }
    if let Some(c) = &checkpoint {
        match &c.resume {
            Some(r) => warn!("resuming {} after {} spp ({:.1} s)", c.path.display(), r.part.sums.spp, r.seconds),
            // (Batches and Slurm tasks always ask to resume: no note for them.)
            None if args.resume && !args.quiet && args.job_key.is_none() => {
                warn!("note: no checkpoint at {}: rendering from the start", c.path.display());
            }
            None if c.path.exists() => warn!(
                "warning: replacing the checkpoint of an interrupted render at {} (--resume continues it)",
                c.path.display()
            ),
            None => {}
        }
    }
    let settings = RenderSettings {
        spp: args.spp.or(if args.time.is_some() || args.noise_target.is_some() {
            None
        } else {
            Some(scene.render.spp.unwrap_or(crate::render::DEFAULT_SPP))
        }),
        time_limit: args.time,
        seed: args.seed,
        threads: args.machine.threads,
        tile_size: args.tile_size,
        progress: !args.quiet,
        light_sampling: args.photon.light_sampling,
        samples: args.samples,
        progress_json: args.progress_json,
        checkpoint,
        noise_target: args.noise_target.map(|error| crate::render::NoiseTarget {
            error,
            min_spp: args.min_spp,
            per_pixel: args.adaptive,
        }),
    };
    // The denoiser is found before the render, not after it.
    let denoiser = if args.denoise { Some(crate::denoise::Denoiser::load(args.machine.threads)?) } else { None };
    let integrator = args.integrator;
    let want = |a: Aov| args.aov.contains(&a);
    let first_hit = want(Aov::Albedo) || want(Aov::Normal) || want(Aov::Depth) || args.denoise;
    let (image, stats, backend, aovs) = render_scene_with_aovs(
        &scene,
        &args.photon.integrator(integrator),
        args.machine.backend,
        &settings,
        first_hit,
    )?;
    // Layers named as tev and Open Image Denoise's tools expect (albedo.R, normal.X, Z).
    let mut layers: Vec<(String, Vec<f32>)> = Vec::new();
    if let Some(a) = &aovs {
        for (kind, prefix, names, values) in
            [(Aov::Albedo, "albedo", ["R", "G", "B"], &a.albedo), (Aov::Normal, "normal", ["X", "Y", "Z"], &a.normal)]
        {
            if want(kind) {
                for (c, name) in names.iter().enumerate() {
                    layers.push((format!("{prefix}.{name}"), values.iter().map(|v| v[c]).collect()));
                }
            }
        }
        if want(Aov::Depth) {
            layers.push(("Z".into(), a.depth.clone()));
        }
    }
    if let Some(counts) = &stats.pixel_counts {
        layers.push(("spp".into(), counts.iter().map(|&n| (n + stats.prior_spp) as f32).collect()));
    } else if want(Aov::Spp) {
        layers.push(("spp".into(), vec![image.spp as f32; image.pixels.len()]));
    }
    let denoised = match (&denoiser, &aovs) {
        (Some(d), Some(a)) => {
            Some(d.denoise(image.width, image.height, &image.pixels, Some(&a.albedo), Some(&a.normal))?)
        }
        _ => None,
    };
    if let Some(d) = &denoised {
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            layers.push((format!("denoised.{name}"), d.pixels.iter().map(|v| v[c]).collect()));
        }
    }

    // What makes the render this render (the checkpoint's identity: every setting that
    // changes pixels), then what this run measured.
    let mut meta = render_identity(args, &scene);
    meta.push("scene", scene.path.display());
    meta.push("seconds", format!("{:.3}", stats.total_seconds()));
    meta.push("prepass_seconds", format!("{:.3}", stats.prepass_seconds));
    if let Some(p) = &stats.prepass {
        meta.push("prepass", p);
    }
    meta.push("threads", stats.threads);
    if stats.prior_spp > 0 {
        // The image averages these pre-pass (training) samples with the `spp` final ones.
        meta.push("final_spp", stats.spp);
        meta.push("training_spp_in_image", stats.prior_spp);
    }
    meta.push("rays", stats.rays);
    if let Some((e, _)) = stats.noise {
        meta.push("relative_error", format!("{e:.5}"));
    }
    if let Some(d) = &denoised {
        meta.push("denoiser", format!("{}: layers denoised.R/G/B", d.filter()));
        meta.push("denoise_seconds", format!("{:.3}", d.seconds));
    }
    if let Some(key) = &args.job_key {
        meta.push("job", key);
    }
    if stats.resumed_spp > 0 {
        meta.push("resumed_at_spp", stats.resumed_spp);
    }
    if args.samples.is_some() {
        meta.push("spp_total", args.spp.unwrap_or(0));
    }
    // Both images or neither.
    let mut staged = vec![match &stats.partial {
        Some(part) => film::stage_partial(&args.output, part, &meta)?,
        None => film::stage_exr_with(&args.output, &image, &meta, layers)?,
    }];
    if let Some(p) = &png {
        staged.push(film::stage_png(p, &image, args.png.exposure)?);
    }
    if let (Some(p), Some(d)) = (&denoised_png, &denoised) {
        let denoised_image = film::Image {
            width: image.width,
            height: image.height,
            pixels: d.pixels.clone(),
            variance: None,
            spp: image.spp,
        };
        staged.push(film::stage_png(p, &denoised_image, args.png.exposure)?);
    }
    film::commit(staged)?;
    // The image holds every sample now: the checkpoint has served.
    if let Some(c) = &settings.checkpoint
        && let Err(e) = std::fs::remove_file(&c.path)
        && e.kind() != std::io::ErrorKind::NotFound
    {
        warn!("warning: the render is written, but its checkpoint {} could not be removed: {e}", c.path.display());
    }
    if stats.non_finite > 0 {
        warn!("warning: {} samples were NaN or infinite and were dropped", stats.non_finite);
    }
    // The images are written: a closed or full standard output no longer fails the command.
    let summary = || -> Result<()> {
        out!(
            "scene: {} triangles, loaded in {:.2} s; {backend} built in {:.2} s{}",
            scene.triangles.len(),
            load_seconds,
            stats.build_seconds,
            crate::io::peak_memory_bytes().map_or(String::new(), |b| format!("; peak memory {} MiB", b >> 20)),
        );
        if let Some(p) = &stats.prepass {
            out!("pre-pass: {p}");
        }
        out!(
            "{} {}x{}, {} spp{}, {:.2} s{}, {:.2} M samples/s, {:.2} M rays/s ({}, {}, {} threads) -> {}{}",
            scene.name,
            image.width,
            image.height,
            stats.spp,
            if stats.prior_spp > 0 {
                format!(" (+{} training spp in the image)", stats.prior_spp)
            } else {
                String::new()
            },
            stats.seconds,
            if stats.prepass.is_some() { format!(" (pre-pass {:.2} s)", stats.prepass_seconds) } else { String::new() },
            stats.samples_per_second() / 1e6,
            stats.rays_per_second() / 1e6,
            meta.get("integrator").unwrap_or("?"),
            backend,
            stats.threads,
            args.output.display(),
            png.as_ref().map_or(String::new(), |p| format!(", {}", p.display())),
        );
        if stats.checkpoints > 0 {
            out!(
                "checkpoints: {} in {:.3} s ({:.2}% of the render)",
                stats.checkpoints,
                stats.checkpoint_seconds,
                100.0 * stats.checkpoint_seconds / stats.seconds.max(1e-9)
            );
        }
        if let (Some((e, met)), Some(target)) = (stats.noise, args.noise_target) {
            out!(
                "noise: estimated relative error {e:.4} after {} spp ({} the target {target})",
                stats.spp,
                if met { "meets" } else { "short of" }
            );
        }
        if let Some((lo, mean, hi)) = stats.pixel_spp {
            if args.adaptive {
                out!("adaptive sampling: {mean:.1} samples per pixel on average (fewest {lo}, most {hi}; layer spp)");
            } else {
                out!(
                    "samples shared by the training's error (--allocation): {mean:.1} per pixel on average (fewest {lo}, most {hi}; layer spp)"
                );
            }
        }
        if let Some(d) = &denoised {
            out!(
                "denoised in {:.2} s (Open Image Denoise, guided by {}; {}) -> layers denoised.R/G/B{}",
                d.seconds,
                d.guided_by,
                d.library.display(),
                denoised_png.as_ref().map_or(String::new(), |p| format!(", {}", p.display()))
            );
        }
        Ok(())
    };
    if let Err(e) = summary()
        && !e.is_broken_pipe()
    {
        warn!("warning: the images are written, but the summary could not be printed: {e}");
    }
    Ok(stats)
}

/// Where the checkpoint goes, if one is kept.
pub(super) fn checkpoint_path(args: &RenderArgs) -> Option<PathBuf> {
    if args.no_checkpoint {
        return None;
    }
    Some(args.checkpoint.clone().unwrap_or_else(|| {
        let mut name = args.output.as_os_str().to_owned();
        name.push(".checkpoint");
        PathBuf::from(name)
    }))
}

/// What makes two renders the same render: everything that changes the pixels (not threads,
/// tiles or output names). A checkpoint carries it and is continued only by its equal.
pub(super) fn render_identity(args: &RenderArgs, scene: &Scene) -> Metadata {
    let mut meta = Metadata::default();
    meta.push("scene_hash", format!("{:016x}", scene.content_hash()));
    meta.push("resolution", format!("{}x{}", scene.camera.width, scene.camera.height));
    meta.push("integrator", flag_name(args.integrator));
    meta.push("backend", args.machine.backend.resolved_name());
    meta.push("seed", args.seed);
    meta.push("spp", args.spp.or(scene.render.spp).map_or("-".into(), |n| n.to_string()));
    meta.push("max_depth", scene.render.max_depth.map_or("-".into(), |n| n.to_string()));
    meta.push("time", args.time.map_or("-".into(), |t| t.to_string()));
    if let Some(e) = args.noise_target {
        meta.push("noise_target", e);
        meta.push("min_spp", args.min_spp);
        if args.adaptive {
            meta.push("adaptive", 1);
        }
    }
    meta.push("samples", args.samples.map_or("-".into(), |(a, b)| format!("{a}..{b}")));
    args.photon.describe(args.integrator, &mut meta);
    meta.push("version", crate::VERSION);
    meta
}

/// The checkpoint of this render: where, how often, and what to continue (`--resume`).
fn checkpoint_settings(args: &RenderArgs, scene: &Scene, path: &Path) -> Result<CheckpointSettings> {
    let meta = render_identity(args, scene);
    let exists = std::fs::symlink_metadata(path).is_ok();
    // Only a checkpoint may be replaced by one: never a file the user did not ask to write.
    if exists && !is_checkpoint(path) {
        return Err(Error::Output {
            path: path.to_path_buf(),
            message: "exists and is not a zvidpt checkpoint; not replacing it (choose another --checkpoint, or --no-checkpoint)"
                .into(),
        });
    }
    let resume = if args.resume && exists { Some(Resume::read(path, &meta)?) } else { None };
    Ok(CheckpointSettings { path: path.to_path_buf(), interval: args.checkpoint_every, meta, resume })
}

/// `A..B` (sample indices, B exclusive).
fn parse_sample_range(s: &str) -> std::result::Result<(u32, u32), String> {
    let (a, b) = s.split_once("..").ok_or_else(|| format!("expected A..B, e.g. 0..64, got '{s}'"))?;
    let parse = |t: &str| t.trim().parse::<u32>().map_err(|e| format!("'{t}' in '{s}': {e}"));
    let (a, b) = (parse(a)?, parse(b)?);
    if a >= b {
        return Err(format!("'{s}' holds no sample (A must be below B)"));
    }
    Ok((a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Flags of `render` that cannot change a pixel: outputs, PNG tone, threads, tiles,
    /// checkpoint handling, messages, AOV layers beside the image, strictness (which only
    /// turns warnings into errors).
    const NEUTRAL: &[&str] = &[
        "output",
        "png",
        "no-png",
        "exposure",
        "threads",
        "tile-size",
        "aov",
        "denoise",
        "checkpoint",
        "checkpoint-every",
        "no-checkpoint",
        "resume",
        "quiet",
        "job-key",
        "progress-json",
        "strict",
        "help",
    ];

    /// Every other flag of `render`, the integrator it applies to and a value other than its
    /// default. A flag added without an entry in one of the two lists fails the test below.
    const PIXEL: &[(&str, &str, &str)] = &[
        ("integrator", "path", "jensen"),
        ("spp", "path", "9"),
        ("samples", "path", "0..4"),
        ("time", "path", "3"),
        ("noise-target", "path", "0.5"),
        ("min-spp", "path", "3"),
        // (A switch: set by its name alone.)
        ("adaptive", "path", ""),
        ("seed", "path", "7"),
        // (`auto` is Embree where it is compiled in: `bvh` is the other choice.)
        ("backend", "path", "bvh"),
        ("resolution", "path", "16x12"),
        ("define", "path", "max_depth=3"),
        ("max-depth", "path", "3"),
        ("light-sampling", "path", "area"),
        ("mis", "path", "all"),
        ("photons", "jensen", "1000"),
        ("knn", "jensen", "20"),
        ("guide-grid", "jensen", "2x8"),
        ("guide-floor", "jensen", "0.1"),
        ("guide-cache", "jensen", "off"),
        ("pixel-grid", "zvidpt-terminal", "1x1"),
        ("q-max", "zvidpt-terminal", "0.5"),
        ("q-kappa", "zvidpt-terminal", "2"),
        ("guide", "zvidpt-terminal", "all"),
        ("learned-guide", "jensen", "on"),
        ("roulette", "zvidpt", "albedo"),
        ("split-samples", "zvidpt", "100"),
        ("split-moment", "zvidpt", "0"),
        ("train-spp", "zvidpt", "8"),
        ("guide-mix", "zvidpt", "0.5"),
        ("learn-mix", "zvidpt", "off"),
        ("guide-carry", "zvidpt", "0.5"),
        ("box-mix", "zvidpt", "0.1"),
        ("caustic-photons", "zvidpt", "0"),
        ("caustic-lobes", "zvidpt", "off"),
        ("allocation", "zvidpt", "uniform"),
        ("window", "zvidpt", "3"),
        ("max-split", "zvidpt", "4"),
        ("roulette-cv", "zvidpt", "off"),
        ("fallback", "zvidpt", "off"),
        ("min-survival", "zvidpt", "0.5"),
        ("defensive", "zvidpt", "0.1"),
        ("seen-strata", "zvidpt", "1"),
        ("seen-probe", "zvidpt", "off"),
    ];

    fn identity(args: &[&str]) -> Vec<(String, String)> {
        // A Mitsuba scene, so that `-D` has a `<default>` to change.
        let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-mitsuba");
        let all = [&["zvidpt", "render", scene][..], args].concat();
        let Command::Render(r) = crate::cli::parse_from(all).unwrap().command else { unreachable!() };
        render_identity(&r, &load_scene(&r).unwrap()).entries
    }

    /// `args` with `flag` set to `value` (replaced where it is given already; an empty value
    /// sets a switch).
    fn with<'a>(args: &[&'a str], flag: &'a str, value: &'a str) -> Vec<&'a str> {
        let mut out = args.to_vec();
        if value.is_empty() {
            out.push(flag);
            return out;
        }
        match out.iter().position(|a| *a == flag) {
            Some(i) => out[i + 1] = value,
            None => out.extend([flag, value]),
        }
        out
    }

    /// What makes a render this render, by construction: every flag of `render` is either
    /// known not to change pixels or changes the identity that `--resume`, `merge` and the
    /// output's metadata compare. (`--max-depth`, `--train-spp` and `--learned-guide` did
    /// not: a resume or a merge mixed two renders.)
    #[test]
    fn every_pixel_changing_flag_is_in_the_identity() {
        use clap::CommandFactory as _;
        let cli = Cli::command();
        let render = cli.find_subcommand("render").unwrap();
        for arg in render.get_arguments() {
            let Some(long) = arg.get_long() else { continue };
            let known = NEUTRAL.contains(&long) || PIXEL.iter().any(|(f, _, _)| *f == long);
            assert!(known, "--{long}: add it to NEUTRAL or PIXEL (does it change pixels?)");
        }
        for (flag, integrator, value) in PIXEL {
            // Without Embree compiled in, `auto` is `bvh`: there is no other backend to pick.
            if *flag == "backend" && !crate::accel::EMBREE_AVAILABLE {
                continue;
            }
            // (--min-spp and --adaptive mean something only with a noise target.)
            let base_args: &[&str] = if *flag == "min-spp" || *flag == "adaptive" {
                &["--spp", "8", "--integrator", integrator, "--noise-target", "0.5"]
            } else {
                &["--spp", "8", "--integrator", integrator]
            };
            let base = identity(base_args);
            let flag = format!("--{flag}");
            let changed = identity(&with(base_args, &flag, value));
            assert_ne!(base, changed, "{flag} {value} ({integrator}) leaves the render's identity as it was");
        }
    }
}
