//! `zvidpt batch`: runs a job file through [`crate::batch`], each job as `zvidpt render` with
//! the job's flags, and writes the summary.
use super::*;
use crate::batch::{self, BatchOptions, Job, Outcome, Report, Runner, Status, slurm};

// The flags' doc comments are their `--help` text, where TOML table names are not links.
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(Debug, Args)]
pub struct BatchArgs {
    /// The job file (TOML: [defaults], [[job]] tables, [[matrix]] tables; docs/batch.md).
    pub jobs: PathBuf,
    /// Jobs rendered at once, each with its share of the threads.
    #[arg(long, default_value_t = 1)]
    pub parallel: usize,
    /// Threads in all [default: one per core].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder for summary.csv and summary.json [default: the job file's folder].
    #[arg(long)]
    pub summary_dir: Option<PathBuf>,
    /// List the jobs (and which would be skipped) without rendering.
    #[arg(long)]
    pub dry_run: bool,
    /// Submit the jobs to Slurm instead of rendering here: each job as an array of
    /// --tasks sample ranges plus a merge job that runs when they all succeeded (a job with a
    /// time budget or first-hit AOVs as one task). Prints the job ids; see --status.
    #[arg(long, conflicts_with_all = ["dry_run", "status"])]
    pub slurm: bool,
    /// Array tasks per job (--slurm).
    #[arg(long, default_value_t = 4, requires = "slurm")]
    pub tasks: u32,
    /// CPUs per Slurm task; each task renders with as many threads (--slurm).
    #[arg(long, default_value_t = 1, requires = "slurm")]
    pub cpus_per_task: u32,
    /// An extra sbatch argument, e.g. --sbatch-arg=--partition=gpu (repeatable; --slurm).
    #[arg(long, allow_hyphen_values = true, requires = "slurm", value_name = "ARG")]
    pub sbatch_arg: Vec<String>,
    /// Report each job's progress from its output, part and checkpoint files (and which
    /// Slurm jobs of it are still queued), without rendering.
    #[arg(long, conflicts_with = "dry_run")]
    pub status: bool,
}

pub(super) fn check_batch_options(args: &BatchArgs) -> Result<()> {
    if args.parallel == 0 {
        return Err(Error::InvalidOption("--parallel must be at least 1".into()));
    }
    if args.threads == Some(0) {
        return Err(Error::InvalidOption("--threads must be at least 1".into()));
    }
    if args.tasks == 0 || args.cpus_per_task == 0 {
        return Err(Error::InvalidOption("--tasks and --cpus-per-task must be at least 1".into()));
    }
    Ok(())
}

/// `--status`: each job's state from its files.
fn report_status(jobs: &[Job], runner: &Renders, tasks: u32) -> Result<()> {
    out!("{:<34}  {:<12}  {:<40}  job", "state", "queued", "output");
    for job in jobs {
        let queued = slurm::queued_jobs(job);
        let state = if runner.is_done(job) {
            "done".to_string()
        } else {
            let p = slurm::progress(job, tasks);
            let total = p.spp_total.map_or(String::new(), |t| format!("/{t}"));
            match p.parts {
                Some((n, m)) if n == m && !queued.is_empty() => format!("{n}/{n} parts, merging"),
                Some((n, m)) if n == m => format!("{n}/{n} parts, merge failed: see merge.log"),
                Some((k, n)) if k > 0 || p.spp_done > 0 => format!("{}{total} spp, {k}/{n} parts", p.spp_done),
                _ if p.spp_done > 0 => format!("{}{total} spp (checkpoint)", p.spp_done),
                _ if !queued.is_empty() => "queued".to_string(),
                _ => "not started".to_string(),
            }
        };
        let queued = if queued.is_empty() { "-".to_string() } else { queued.join(",") };
        out!("{:<34}  {:<12}  {:<40}  {}", state, queued, job.output.display().to_string(), job.origin);
    }
    Ok(())
}

/// `--slurm`: submits every job not done yet.
fn submit_all(args: &BatchArgs, jobs: &[Job], runner: &Renders) -> Result<()> {
    for job in jobs {
        runner.check(job).map_err(|e| Error::InvalidOption(format!("{}: {e}", job.origin)))?;
        slurm::split_of(job, args.tasks)?;
    }
    let exe = std::env::current_exe().map_err(|e| Error::io("the zvidpt executable", e))?;
    let workdir = std::env::current_dir().map_err(|e| Error::io("the current folder", e))?;
    let options = slurm::SlurmOptions {
        tasks: args.tasks,
        cpus_per_task: args.cpus_per_task,
        sbatch_args: args.sbatch_arg.clone(),
        exe,
        workdir,
    };
    for job in jobs {
        if runner.is_done(job) {
            out!("{}: done already ({})", job.origin, job.output.display());
            continue;
        }
        if let Some(parent) = job.output.parent().filter(|p| !p.as_os_str().is_empty() && !p.exists()) {
            std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        }
        match slurm::submit(job, &options).map_err(|e| Error::InvalidOption(format!("{}: {e}", job.origin)))? {
            None => {
                out!("{}: still queued from an earlier submission ({})", job.origin, slurm::queued_jobs(job).join(","))
            }
            Some(s) => match (&s.split, &s.merge) {
                (slurm::Split::Samples { spp, tasks }, Some(m)) => out!(
                    "{}: array job {} ({tasks} tasks of {spp} spp), merge job {m} -> {}",
                    job.origin,
                    s.render,
                    job.output.display()
                ),
                _ => out!("{}: job {} (one task) -> {}", job.origin, s.render, job.output.display()),
            },
        }
    }
    Ok(())
}

/// `zvidpt render`'s arguments alone, for parsing a job.
#[derive(Debug, Parser)]
#[command(name = "zvidpt render", no_binary_name = true)]
struct RenderLine {
    #[command(flatten)]
    args: RenderArgs,
}

fn render_args(job: &Job) -> Result<RenderArgs> {
    let mut line = RenderLine::try_parse_from(&job.args)
        .map_err(|e| Error::InvalidOption(e.to_string().lines().next().unwrap_or("").trim().to_string()))?
        .args;
    if line.job_key.is_some() {
        return Err(Error::InvalidOption("`job_key` is set by the batch itself".into()));
    }
    line.job_key = Some(job.key());
    Ok(line)
}

/// Jobs run as `zvidpt render`.
struct Renders {
    /// Progress bars only when one job runs at a time.
    quiet: bool,
    /// Machine-readable progress (stderr is not a terminal).
    json: bool,
}

impl Runner for Renders {
    fn check(&self, job: &Job) -> Result<()> {
        check_render_options(&render_args(job)?)
    }

    fn is_done(&self, job: &Job) -> bool {
        let Ok(args) = render_args(job) else { return false };
        let Ok((_, meta)) = film::read_exr(&args.output) else { return false };
        if meta.get("job") != args.job_key.as_deref() {
            return false;
        }
        // The same flags on an edited scene render anew.
        render::load_scene(&args)
            .is_ok_and(|s| meta.get("scene_hash") == Some(format!("{:016x}", s.content_hash()).as_str()))
    }

    fn render(&self, job: &Job, threads: Option<usize>) -> Result<Outcome> {
        let mut args = render_args(job)?;
        if args.machine.threads.is_none() {
            args.machine.threads = threads;
        }
        args.quiet |= self.quiet;
        args.progress_json = self.json;
        // A rerun of the batch continues an interrupted render.
        args.resume = !args.no_checkpoint;
        // The job file asked for this output: its folder is made if missing.
        if let Some(parent) = args.output.parent().filter(|p| !p.as_os_str().is_empty() && !p.exists()) {
            std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        }
        let stats = run_render(&args)?;
        Ok(Outcome {
            seconds: stats.seconds,
            spp: stats.spp,
            samples_per_second: stats.samples_per_second(),
            rays_per_second: stats.rays_per_second(),
        })
    }

    fn mse(&self, job: &Job, reference: &Path) -> Result<f64> {
        let (image, _) = film::read_exr(&job.output)?;
        let (reference, _) = film::read_exr(reference)?;
        Ok(film::metrics(&image, &reference)?.mse)
    }
}

pub fn run_batch(args: &BatchArgs) -> Result<()> {
    check_batch_options(args)?;
    let jobs = batch::load(&args.jobs)?;
    use std::io::IsTerminal as _;
    let json_progress = !std::io::stderr().is_terminal();
    let runner = Renders { quiet: args.parallel > 1, json: json_progress };
    if args.status {
        return report_status(&jobs, &runner, args.tasks);
    }
    if args.slurm {
        return submit_all(args, &jobs, &runner);
    }
    if args.dry_run {
        for job in &jobs {
            runner.check(job).map_err(|e| Error::InvalidOption(format!("{}: {e}", job.origin)))?;
            let state = if runner.is_done(job) { "done" } else { "to render" };
            out!("{:<10} {}  zvidpt render {}", state, job.origin, job.args.join(" "));
        }
        return Ok(());
    }
    let summary_dir = match &args.summary_dir {
        Some(d) => d.clone(),
        None => match args.jobs.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        },
    };
    let (csv, json) = (summary_dir.join("summary.csv"), summary_dir.join("summary.json"));
    if let Some(job) = jobs.iter().find(|j| film::same_file(&j.output, &csv) || film::same_file(&j.output, &json)) {
        return Err(Error::InvalidOption(format!(
            "{}: writes {}, the batch's own summary (choose another output or --summary-dir)",
            job.origin,
            job.output.display()
        )));
    }
    // Fail before hours of rendering if the summary cannot be written.
    film::check_writable(&csv)?;
    film::check_writable(&json)?;
    let total = jobs.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let progress = |r: &Report| {
        let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        let what = match (r.status, &r.error) {
            (Status::Failed, Some(e)) => format!("failed: {e}"),
            (s, _) => s.name().to_string(),
        };
        if json_progress {
            let line = serde_json::json!({
                "event": "job",
                "index": n,
                "jobs": total,
                "job": r.job.origin,
                "output": r.job.output.display().to_string(),
                "status": r.status.name(),
                "seconds": r.outcome.map(|o| o.seconds),
                "error": r.error,
            });
            warn!("{line}");
        } else {
            warn!("[{n}/{total}] {} {}: {what}", r.job.origin, r.job.output.display());
        }
    };
    let options = BatchOptions { parallel: args.parallel, threads: args.threads };
    let reports = batch::run(&jobs, &runner, options, &progress)?;
    film::commit(vec![
        film::stage(&csv, |w| {
            use std::io::Write as _;
            w.write_all(batch::summary_csv(&reports).as_bytes()).map_err(|e| Error::io(&csv, e))
        })?,
        film::stage(&json, |w| {
            use std::io::Write as _;
            w.write_all(batch::summary_json(&reports).as_bytes()).map_err(|e| Error::io(&json, e))
        })?,
    ])?;
    out_part!("{}", batch::summary_table(&reports));
    out!("summary: {}, {}", csv.display(), json.display());
    let failed = reports.iter().filter(|r| r.status == Status::Failed).count();
    if failed > 0 {
        return Err(Error::InvalidOption(format!("{failed} of {total} jobs failed (see {})", csv.display())));
    }
    Ok(())
}
