//! `zvidpt converge`: MSE against a reference over integrators, sample counts and seeds; time to a target MSE; equal-time images.
use super::*;

#[derive(Debug, Args)]
pub struct ConvergeArgs {
    /// Scene file, or a folder holding `scene.toml`.
    #[arg(default_value = DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Integrators to compare, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "path,jensen,zvidpt-collision,zvidpt-terminal")]
    pub integrators: Vec<IntegratorKind>,
    /// Samples per pixel to measure at, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16,32,64,100")]
    pub spp: Vec<u32>,
    /// Independent runs (seeds) per integrator and spp.
    #[arg(long, default_value_t = 4)]
    pub runs: u32,
    /// Reference EXR (see `zvidpt reference`).
    #[arg(long)]
    pub reference: PathBuf,
    /// Output folder for runs.csv and converge.csv.
    #[arg(short, long, default_value = "converge")]
    pub output: PathBuf,
    /// First seed; run r uses seed + r.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Instead of the spp sweep: the seconds each integrator needs to reach this MSE (spp
    /// doubled from 1, then log–log interpolation), mean ± s.e. over the runs.
    #[arg(long)]
    pub time_to_mse: Option<f64>,
    /// Also render every integrator for this many seconds and write DIR/equal_time.png, the
    /// images side by side with the spp each reached and its MSE.
    #[arg(long)]
    pub equal_time: Option<f64>,
    /// Largest spp tried by --time-to-mse.
    #[arg(long, default_value_t = 65536)]
    pub max_spp: u32,
    #[command(flatten)]
    pub photon: PhotonArgs,
}

pub(super) fn check_converge_options(args: &ConvergeArgs) -> Result<()> {
    if args.runs == 0 || args.spp.is_empty() || args.spp.contains(&0) || args.integrators.is_empty() {
        return Err(Error::InvalidOption(
            "--runs, --spp and --integrators need at least one positive value each".into(),
        ));
    }
    if args.max_spp == 0 {
        return Err(Error::InvalidOption("--max-spp must be at least 1".into()));
    }
    if args.seed.checked_add(u64::from(args.runs) - 1).is_none() {
        return Err(Error::InvalidOption(format!(
            "--seed {} with --runs {}: run r uses seed + r, which would pass the largest seed",
            args.seed, args.runs
        )));
    }
    args.photon.check()?;
    Ok(())
}

pub(super) fn run_converge(args: &ConvergeArgs) -> Result<()> {
    check_converge_options(args)?;
    args.machine.backend.check_available()?;
    // The output folder is checked before any render, not after the last.
    if args.output.exists() && !args.output.is_dir() {
        return Err(Error::Output {
            path: args.output.clone(),
            message: "is not a folder (converge writes its tables and plots into the folder -o names)".into(),
        });
    }
    std::fs::create_dir_all(&args.output).map_err(|e| Error::io(&args.output, e))?;
    film::check_writable(&args.output.join("runs.csv"))?;
    let scene = load_at(&args.scene, args.machine.resolution)?;
    let (reference, ref_meta) = film::read_exr(&args.reference)?;
    if (reference.width, reference.height) != (scene.camera.width, scene.camera.height) {
        return Err(Error::InvalidOption(format!(
            "the reference is {}x{} but the scene renders at {}x{} (use --resolution)",
            reference.width, reference.height, scene.camera.width, scene.camera.height
        )));
    }
    let hash = format!("{:016x}", scene.content_hash());
    if ref_meta.get("scene_hash").is_some_and(|h| h != hash) {
        return Err(Error::InvalidOption(format!("{} was rendered from a different scene", args.reference.display())));
    }
    if let Some(seconds) = args.equal_time {
        equal_time_image(args, &scene, &reference, seconds)?;
    }
    if let Some(target) = args.time_to_mse {
        return run_time_to_mse(args, &scene, &reference, target);
    }
    let mut runs = Vec::new();
    for &integrator in &args.integrators {
        let name = flag_name(integrator);
        for &spp in &args.spp {
            for r in 0..args.runs {
                let seed = args.seed + u64::from(r);
                let (stats, metrics) = measure(args, &scene, &reference, integrator, spp, seed)?;
                warn!(
                    "{name} {spp} spp seed {seed}: MSE {:.4e} relMSE {:.4e} in {:.2} s",
                    metrics.mse, metrics.rel_mse, stats.seconds
                );
                runs.push(crate::converge::Run {
                    integrator: name.clone(),
                    spp,
                    seed,
                    seconds: stats.seconds,
                    prepass_seconds: stats.prepass_seconds,
                    metrics,
                });
            }
        }
    }
    let summary = crate::converge::summarise(&runs);
    crate::converge::write_csv(&args.output, &runs, &summary)?;
    crate::converge::plot(&args.output, &scene.name, &summary)?;
    out!(
        "{:<18} {:>5} {:>12} {:>10} {:>12} {:>9} {:>9}",
        "integrator",
        "spp",
        "MSE",
        "± s.e.",
        "relMSE",
        "seconds",
        "pre-pass"
    );
    for s in &summary {
        out!(
            "{:<18} {:>5} {:>12.4e} {:>10.2e} {:>12.4e} {:>9.3} {:>9.3}",
            s.integrator,
            s.spp,
            s.mse.0,
            s.mse.1,
            s.rel_mse.0,
            s.seconds.0,
            s.prepass_seconds
        );
    }
    out!("-> {} (runs.csv, converge.csv, mse_vs_spp.png/svg, mse_vs_seconds.png/svg)", args.output.display());
    Ok(())
}

impl ConvergeArgs {
    /// The render settings of one convergence render: a sample count or a time budget.
    fn settings(&self, spp: Option<u32>, time_limit: Option<f64>, seed: u64) -> RenderSettings {
        RenderSettings {
            samples: None,
            progress_json: false,
            checkpoint: None,
            spp,
            time_limit,
            seed,
            threads: self.machine.threads,
            tile_size: 32,
            progress: false,
            light_sampling: self.photon.light_sampling,
            noise_target: None,
        }
    }
}

/// One convergence point: `integrator` at `spp` with `seed`, and its error against `reference`.
fn measure(
    args: &ConvergeArgs,
    scene: &Scene,
    reference: &Image,
    integrator: IntegratorKind,
    spp: u32,
    seed: u64,
) -> Result<(RenderStats, crate::film::Metrics)> {
    let settings = args.settings(Some(spp), None, seed);
    let (image, stats, _) = render_scene(scene, &args.photon.integrator(integrator), args.machine.backend, &settings)?;
    let metrics = film::metrics(&image, reference)?;
    Ok((stats, metrics))
}

pub(super) fn run_time_to_mse(args: &ConvergeArgs, scene: &Scene, reference: &Image, target: f64) -> Result<()> {
    if !(target.is_finite() && target > 0.0) {
        return Err(Error::InvalidOption("--time-to-mse must be a positive MSE".into()));
    }
    let mut rows = Vec::new();
    out!(
        "{:<18} {:>10} {:>10} {:>9}  (target MSE {target:.4e}, {} runs)",
        "integrator",
        "seconds",
        "± s.e.",
        "spp",
        args.runs
    );
    for &integrator in &args.integrators {
        let name = flag_name(integrator);
        let mut seconds = Vec::new();
        let mut spps = Vec::new();
        for r in 0..args.runs {
            let seed = args.seed + u64::from(r);
            let t = crate::converge::time_to_mse(
                |spp| {
                    let (stats, m) = measure(args, scene, reference, integrator, spp, seed)?;
                    warn!("{name} seed {seed} {spp} spp: MSE {:.4e} in {:.2} s", m.mse, stats.seconds);
                    Ok((stats.seconds, m.mse))
                },
                target,
                args.max_spp,
            )?;
            if !t.reached {
                warn!("warning: {name} seed {seed} did not reach the target within {} spp", args.max_spp);
            }
            seconds.push(t.seconds);
            spps.push(t.spp as f64);
            rows.push((name.clone(), seed, t));
        }
        let (m, se) = crate::converge::mean_and_se(&seconds);
        out!("{:<18} {:>10.3} {:>10.3} {:>9.0}", name, m, se, crate::converge::mean_and_se(&spps).0);
    }
    std::fs::create_dir_all(&args.output).map_err(|e| Error::io(&args.output, e))?;
    let path = args.output.join("time_to_mse.csv");
    film::write_atomically(&path, |w| {
        use std::io::Write;
        let io = |e| Error::io(&path, e);
        writeln!(w, "integrator,seed,target_mse,seconds,spp,reached").map_err(io)?;
        for (name, seed, t) in &rows {
            writeln!(w, "{name},{seed},{target:e},{:.4},{},{}", t.seconds, t.spp, t.reached).map_err(io)?;
        }
        Ok(())
    })?;
    out!("-> {}", path.display());
    Ok(())
}

fn equal_time_image(args: &ConvergeArgs, scene: &Scene, reference: &Image, seconds: f64) -> Result<()> {
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(Error::InvalidOption("--equal-time must be a positive number of seconds".into()));
    }
    let mut shots = Vec::new();
    for &integrator in &args.integrators {
        let name = flag_name(integrator);
        let settings = args.settings(None, Some(seconds), args.seed);
        let (image, stats, _) =
            render_scene(scene, &args.photon.integrator(integrator), args.machine.backend, &settings)?;
        let m = film::metrics(&image, reference)?;
        out!("equal time {seconds} s: {name} {} spp, MSE {:.4e}, relMSE {:.4e}", stats.spp, m.mse, m.rel_mse);
        shots.push((format!("{name}\n{} spp, MSE {:.2e}", stats.spp, m.mse), image));
    }
    std::fs::create_dir_all(&args.output).map_err(|e| Error::io(&args.output, e))?;
    let path = args.output.join("equal_time.png");
    let refs: Vec<(String, &Image)> = shots.iter().map(|(c, i)| (c.clone(), i)).collect();
    crate::plot::side_by_side(&path, &refs)?;
    out!("-> {}", path.display());
    Ok(())
}
