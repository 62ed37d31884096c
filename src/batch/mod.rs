//! Batch rendering: a job file of renders, run one after another (or a few at a time), each
//! skipped when its output already holds the same render, each failure recorded while the rest
//! go on, and a summary at the end (`zvidpt batch`).
//!
//! A job file is TOML:
//!
//! ```toml
//! [defaults]                 # render flags every job gets unless it sets them itself
//! resolution = "256x192"
//! no_png = true
//!
//! [[job]]
//! scene = "scenes/cornell-paper"
//! output = "out/paper-path.exr"
//! integrator = "path"
//! spp = 64
//! reference = "ref.exr"      # not a render flag: the summary reports the MSE against it
//!
//! [[matrix]]                 # scenes × integrators × budgets (× seeds)
//! scenes = ["scenes/cornell-paper", "scenes/cornell-classic"]
//! integrators = ["path", "zvidpt"]
//! spp = [16, 64]             # or time = [10, 20] (seconds); seeds = [1, 2] optional
//! output = "out/{scene}-{integrator}-{spp}.exr"
//! ```
//!
//! Jobs run in the order `[[job]]` tables first, then each matrix's expansion (scenes, then
//! integrators, budgets and seeds innermost). Every other key is a `zvidpt render` flag (`no_png = true` is `--no-png`, `seed = 3` is
//! `--seed 3`), checked by the render command's own parser before any job starts. Relative
//! paths (scene, output, reference, png) are taken from the job file's folder, so a batch
//! runs the same from anywhere.
//!
//! The renderer itself is reached through [`Runner`], so that this module holds the batch
//! logic and the command line only wires it to `zvidpt render`.
// The library's entry points: every public item documented (`cargo doc`).
#![warn(missing_docs)]
pub mod slurm;

use crate::{Error, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Largest job file read (a job file is text written by people or scripts).
pub const MAX_JOB_FILE_BYTES: u64 = 4 << 20;
/// Most jobs one file may expand to.
pub const MAX_JOBS: usize = 100_000;

/// One render of a batch.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// Where in the job file it comes from, for messages (`job 3`, `matrix 1`).
    pub origin: String,
    /// The output EXR (resolved against the job file's folder).
    pub output: PathBuf,
    /// `zvidpt render`'s arguments: the scene, `-o OUTPUT`, then flags in the file's order
    /// (defaults first, each overridden by the job's own value).
    pub args: Vec<String>,
    /// A reference image for the summary's MSE.
    pub reference: Option<PathBuf>,
}

impl Job {
    /// A fingerprint of what the job renders (its arguments), written into the output's
    /// metadata: a rerun skips a job whose output carries the same one.
    #[must_use]
    pub fn key(&self) -> String {
        // FNV-1a over the arguments, separated by a byte no argument holds.
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for a in &self.args {
            for b in a.bytes().chain([0x1f]) {
                h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
            }
        }
        format!("{h:016x}")
    }
}

/// What a finished render reports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outcome {
    /// Wall-clock seconds of the render.
    pub seconds: f64,
    /// Samples per pixel rendered.
    pub spp: u32,
    /// Camera samples per second.
    pub samples_per_second: f64,
    /// Rays traced per second.
    pub rays_per_second: f64,
}

/// How a batch reaches the renderer.
pub trait Runner: Sync {
    /// Checks a job's arguments without rendering (unknown flags, bad values).
    fn check(&self, job: &Job) -> Result<()>;
    /// Whether `job`'s output already holds this render (its metadata carries the job's key
    /// and the scene is unchanged).
    fn is_done(&self, job: &Job) -> bool;
    /// Renders `job` with `threads` threads (`None`: all) and writes its output.
    fn render(&self, job: &Job, threads: Option<usize>) -> Result<Outcome>;
    /// The MSE of `job`'s output against `reference`.
    fn mse(&self, job: &Job, reference: &Path) -> Result<f64>;
}

/// How a job ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// It rendered and wrote its output.
    Rendered,
    /// Its output already held this render.
    Skipped,
    /// It stopped with an error.
    Failed,
}

impl Status {
    /// The status as the summary writes it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Status::Rendered => "rendered",
            Status::Skipped => "skipped",
            Status::Failed => "failed",
        }
    }
}

/// One line of the summary.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// The job.
    pub job: Job,
    /// How it ended.
    pub status: Status,
    /// Wall-clock seconds of the whole job (render, outputs, MSE).
    pub wall_seconds: f64,
    /// What its render reported, if it rendered.
    pub outcome: Option<Outcome>,
    /// Its MSE against the job's reference, if it has one.
    pub mse: Option<f64>,
    /// The error's one line, for a failed job (or a failed MSE of a rendered one).
    pub error: Option<String>,
}

/// Reads and expands a job file.
pub fn load(path: &Path) -> Result<Vec<Job>> {
    let text = crate::io::read_text(path, MAX_JOB_FILE_BYTES, "job file")?;
    let base = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    parse(&text, path, &base)
}

fn syntax(path: &Path, message: impl Into<String>) -> Error {
    Error::SceneSyntax { path: path.to_path_buf(), message: message.into() }
}

/// Expands the text of a job file (`path` names it in errors; relative paths are taken from
/// `base`).
pub fn parse(text: &str, path: &Path, base: &Path) -> Result<Vec<Job>> {
    let table: toml::Table = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
        let message = e.message().trim().replace('\n', " ");
        syntax(path, line.map_or(message.clone(), |l| format!("line {l}: {message}")))
    })?;
    let mut defaults = toml::Table::new();
    let mut job_tables: Vec<(String, toml::Table)> = Vec::new();
    let mut matrices: Vec<toml::Table> = Vec::new();
    for (key, value) in &table {
        match (key.as_str(), value) {
            ("defaults", toml::Value::Table(t)) => defaults = t.clone(),
            ("job", toml::Value::Array(list)) => {
                for (i, v) in list.iter().enumerate() {
                    let toml::Value::Table(t) = v else {
                        return Err(syntax(path, format!("job {}: expected a table ([[job]])", i + 1)));
                    };
                    job_tables.push((format!("job {}", i + 1), t.clone()));
                }
            }
            ("matrix", toml::Value::Table(t)) => matrices.push(t.clone()),
            ("matrix", toml::Value::Array(list)) => {
                for (i, v) in list.iter().enumerate() {
                    let toml::Value::Table(t) = v else {
                        return Err(syntax(path, format!("matrix {}: expected a table ([[matrix]])", i + 1)));
                    };
                    matrices.push(t.clone());
                }
            }
            ("defaults" | "job" | "matrix", _) => {
                return Err(syntax(path, format!("`{key}` must be a table ([{key}] or [[{key}]])")));
            }
            _ => {
                return Err(syntax(
                    path,
                    format!("unknown top-level key `{key}` (expected [defaults], [[job]] and [[matrix]])"),
                ));
            }
        }
    }
    for key in ["scene", "output", "reference"] {
        if defaults.contains_key(key) {
            return Err(syntax(path, format!("[defaults] cannot set `{key}`: each job names its own")));
        }
    }
    let mut jobs = Vec::new();
    for (origin, t) in job_tables {
        jobs.push(make_job(path, base, &origin, &defaults, &t)?);
    }
    for (m, t) in matrices.iter().enumerate() {
        expand_matrix(path, base, &format!("matrix {}", m + 1), &defaults, t, &mut jobs)?;
    }
    if jobs.is_empty() {
        return Err(syntax(path, "no jobs: add [[job]] tables or a [[matrix]]"));
    }
    // Two jobs writing one file would overwrite each other (and the second would skip), by
    // any spelling of it (`./a`, `sub/../a`, a linked folder); and none may write the job file.
    let mut outputs: Vec<(PathBuf, &Path, &str)> =
        jobs.iter().map(|j| (crate::film::path_key(&j.output), j.output.as_path(), j.origin.as_str())).collect();
    outputs.sort();
    for w in outputs.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(syntax(
                path,
                format!(
                    "{} and {} both write {} (as {} and {})",
                    w[0].2,
                    w[1].2,
                    w[0].0.display(),
                    w[0].1.display(),
                    w[1].1.display()
                ),
            ));
        }
    }
    if let Some((_, out, origin)) = outputs.iter().find(|(_, out, _)| crate::film::same_file(out, path)) {
        return Err(syntax(path, format!("{origin} writes {}: the job file itself", out.display())));
    }
    Ok(jobs)
}

/// A string, integer or float as text (for output templates and flags).
fn scalar(value: &toml::Value) -> Option<String> {
    match value {
        toml::Value::String(s) => Some(s.clone()),
        toml::Value::Integer(i) => Some(i.to_string()),
        toml::Value::Float(f) => Some(f.to_string()),
        _ => None,
    }
}

fn resolve(base: &Path, p: &str) -> PathBuf {
    let p = Path::new(p);
    if p.is_absolute() { p.to_path_buf() } else { base.join(p) }
}

/// Keys whose values are paths, taken from the job file's folder.
const PATH_FLAGS: [&str; 1] = ["png"];

/// One job from its table (and the defaults).
fn make_job(path: &Path, base: &Path, origin: &str, defaults: &toml::Table, t: &toml::Table) -> Result<Job> {
    let text_of = |key: &str| -> Result<Option<String>> {
        match t.get(key) {
            None => Ok(None),
            Some(toml::Value::String(s)) if !s.is_empty() => Ok(Some(s.clone())),
            Some(_) => Err(syntax(path, format!("{origin}: `{key}` must be a non-empty string"))),
        }
    };
    let scene = text_of("scene")?.ok_or_else(|| syntax(path, format!("{origin}: no `scene`")))?;
    let output = text_of("output")?.ok_or_else(|| syntax(path, format!("{origin}: no `output`")))?;
    let reference = text_of("reference")?.map(|r| resolve(base, &r));
    let output = resolve(base, &output);
    let mut args = vec![resolve(base, &scene).display().to_string(), "-o".into(), output.display().to_string()];
    // Defaults first (unless the job sets the key), then the job's own flags.
    let flags = defaults.iter().filter(|(k, _)| !t.contains_key(*k)).chain(t.iter());
    for (key, value) in flags {
        if matches!(key.as_str(), "scene" | "output" | "reference") {
            continue;
        }
        if matches!(key.as_str(), "o" | "help" | "version") || key.contains(char::is_whitespace) {
            return Err(syntax(path, format!("{origin}: `{key}` cannot be set in a job file")));
        }
        let flag = format!("--{}", key.replace('_', "-"));
        match value {
            toml::Value::Boolean(true) => args.push(flag),
            toml::Value::Boolean(false) => {}
            v => {
                let Some(mut text) = scalar(v) else {
                    return Err(syntax(path, format!("{origin}: `{key}` must be a string, number or boolean")));
                };
                if PATH_FLAGS.contains(&key.as_str()) {
                    text = resolve(base, &text).display().to_string();
                }
                args.push(flag);
                args.push(text);
            }
        }
    }
    Ok(Job { origin: origin.to_string(), output, args, reference })
}

/// The name a scene path gives in output templates: its file stem, or the folder's name for
/// a folder or a `scene.toml`.
fn scene_name(scene: &str) -> String {
    let p = Path::new(scene);
    let stem = p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    if stem == "scene" || p.extension().is_none() {
        let folder = if p.extension().is_none() { p } else { p.parent().unwrap_or(p) };
        if let Some(name) = folder.file_name() {
            return name.to_string_lossy().into_owned();
        }
    }
    stem
}

/// Expands one `[[matrix]]`: scenes × integrators × budgets × seeds.
fn expand_matrix(
    path: &Path,
    base: &Path,
    origin: &str,
    defaults: &toml::Table,
    t: &toml::Table,
    jobs: &mut Vec<Job>,
) -> Result<()> {
    let list = |key: &str| -> Result<Option<Vec<String>>> {
        match t.get(key) {
            None => Ok(None),
            Some(toml::Value::Array(a)) if !a.is_empty() => a
                .iter()
                .map(|v| {
                    scalar(v).ok_or_else(|| {
                        syntax(path, format!("{origin}: `{key}` holds a value that is not a string or number"))
                    })
                })
                .collect::<Result<Vec<_>>>()
                .map(Some),
            Some(_) => Err(syntax(path, format!("{origin}: `{key}` must be a non-empty list"))),
        }
    };
    let scenes = list("scenes")?.ok_or_else(|| syntax(path, format!("{origin}: no `scenes` list")))?;
    let integrators = list("integrators")?.unwrap_or_else(|| vec![String::new()]);
    let (budget_key, budgets) = match (list("spp")?, list("time")?) {
        (Some(_), Some(_)) => return Err(syntax(path, format!("{origin}: give `spp` or `time`, not both"))),
        (Some(s), None) => ("spp", s),
        (None, Some(s)) => ("time", s),
        (None, None) => ("", vec![String::new()]),
    };
    let seeds = list("seeds")?.unwrap_or_else(|| vec![String::new()]);
    let Some(toml::Value::String(template)) = t.get("output") else {
        return Err(syntax(
            path,
            format!("{origin}: `output` must be a template string, e.g. \"out/{{scene}}-{{integrator}}.exr\""),
        ));
    };
    // Every `{field}` of the template must have a value here (one left out would silently
    // become "").
    let defined = |name: &str| match name {
        "scene" => true,
        "integrator" => t.contains_key("integrators"),
        "spp" | "time" => budget_key == name,
        "seed" => t.contains_key("seeds"),
        _ => false,
    };
    let mut rest = template.as_str();
    while let Some(open) = rest.find('{') {
        let Some(len) = rest[open..].find('}') else { break };
        let name = &rest[open + 1..open + len];
        if !defined(name) {
            return Err(syntax(
                path,
                format!(
                    "{origin}: `output` uses {{{name}}}, which this matrix gives no value \
                     ({{scene}} always; {{integrator}}, {{spp}}, {{time}}, {{seed}} with their lists)"
                ),
            ));
        }
        rest = &rest[open + len + 1..];
    }
    let count = scenes.len() * integrators.len() * budgets.len() * seeds.len();
    if jobs.len() + count > MAX_JOBS {
        return Err(syntax(path, format!("{origin} expands to more than {MAX_JOBS} jobs")));
    }
    // The template field each varying list needs, so that no two jobs share an output.
    for (key, field, values) in [
        ("scenes", "{scene}", &scenes),
        ("integrators", "{integrator}", &integrators),
        (budget_key, if budget_key == "spp" { "{spp}" } else { "{time}" }, &budgets),
        ("seeds", "{seed}", &seeds),
    ] {
        if values.len() > 1 && !template.contains(field) {
            return Err(syntax(
                path,
                format!("{origin}: `output` needs {field}: `{key}` has several values and each job needs its own file"),
            ));
        }
    }
    let shared: toml::Table = t
        .iter()
        .filter(|(k, _)| !matches!(k.as_str(), "scenes" | "integrators" | "spp" | "time" | "seeds" | "output"))
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    for scene in &scenes {
        for integrator in &integrators {
            for budget in &budgets {
                for seed in &seeds {
                    let output = template
                        .replace("{scene}", &scene_name(scene))
                        .replace("{integrator}", integrator)
                        .replace("{spp}", if budget_key == "spp" { budget } else { "" })
                        .replace("{time}", if budget_key == "time" { budget } else { "" })
                        .replace("{seed}", seed);
                    let mut job = shared.clone();
                    job.insert("scene".into(), toml::Value::String(scene.clone()));
                    job.insert("output".into(), toml::Value::String(output));
                    if !integrator.is_empty() {
                        job.insert("integrator".into(), toml::Value::String(integrator.clone()));
                    }
                    if !budget_key.is_empty() {
                        job.insert(budget_key.into(), toml::Value::String(budget.clone()));
                    }
                    if !seed.is_empty() {
                        job.insert("seed".into(), toml::Value::String(seed.clone()));
                    }
                    let label = format!("{origin} ({scene}, {integrator}, {budget_key} {budget})");
                    jobs.push(make_job(path, base, &label, defaults, &job)?);
                }
            }
        }
    }
    Ok(())
}

/// Options of a batch run.
#[derive(Clone, Copy, Debug)]
pub struct BatchOptions {
    /// Jobs run at once (each with its share of the threads).
    pub parallel: usize,
    /// Threads in all (`None`: one per core).
    pub threads: Option<usize>,
}

/// Runs every job (checked first: a malformed job stops the batch before anything renders);
/// `report` is called as each job ends. Returns one report per job, in the jobs' order, with
/// the MSE of each job that names a reference (computed after the last job).
pub fn run(
    jobs: &[Job],
    runner: &dyn Runner,
    options: BatchOptions,
    report: &(dyn Fn(&Report) + Sync),
) -> Result<Vec<Report>> {
    for job in jobs {
        runner.check(job).map_err(|e| Error::InvalidOption(format!("{}: {e}", job.origin)))?;
    }
    let parallel = options.parallel.clamp(1, jobs.len().max(1));
    let total = options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let threads = (parallel > 1).then(|| (total / parallel).max(1)).or(options.threads);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<std::sync::Mutex<Option<Report>>> = jobs.iter().map(|_| std::sync::Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for _ in 0..parallel {
            scope.spawn(|| {
                // After SIGINT or SIGTERM no job starts (the running ones keep checkpoints).
                while crate::render::interrupt::requested().is_none() {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(job) = jobs.get(i) else { break };
                    let r = run_one(job, runner, threads);
                    report(&r);
                    *results[i].lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(r);
                }
            });
        }
    });
    if let Some(signal) = crate::render::interrupt::requested() {
        let finished = results
            .iter()
            .filter(|r| r.lock().is_ok_and(|r| r.as_ref().is_some_and(|r| r.status != Status::Failed)))
            .count();
        return Err(Error::Interrupted {
            signal,
            message: format!(
                "interrupted: {finished} of {} jobs done; run the batch again to continue (renders resume from their checkpoints)",
                jobs.len()
            ),
        });
    }
    let mut reports: Vec<Report> = results
        .into_iter()
        .zip(jobs)
        .map(|(r, job)| {
            r.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner).unwrap_or_else(|| Report {
                job: job.clone(),
                status: Status::Failed,
                wall_seconds: 0.0,
                outcome: None,
                mse: None,
                error: Some("the job did not run (a worker stopped)".into()),
            })
        })
        .collect();
    // Errors against references once every job has run, so that a reference may be one of
    // the batch's own renders.
    for r in &mut reports {
        if r.status != Status::Failed
            && let Some(reference) = &r.job.reference
        {
            match runner.mse(&r.job, reference) {
                Ok(m) => r.mse = Some(m),
                Err(e) => r.error = Some(format!("MSE: {}", one_line(&e))),
            }
        }
    }
    Ok(reports)
}

fn one_line(e: &Error) -> String {
    e.to_string().lines().next().unwrap_or("").trim().to_string()
}

fn run_one(job: &Job, runner: &dyn Runner, threads: Option<usize>) -> Report {
    let start = Instant::now();
    let mut report =
        Report { job: job.clone(), status: Status::Rendered, wall_seconds: 0.0, outcome: None, mse: None, error: None };
    if runner.is_done(job) {
        report.status = Status::Skipped;
    } else {
        match runner.render(job, threads) {
            Ok(o) => report.outcome = Some(o),
            Err(e) => {
                report.status = Status::Failed;
                report.error = Some(one_line(&e));
            }
        }
    }
    report.wall_seconds = start.elapsed().as_secs_f64();
    report
}

/// The summary as CSV (a header and one row per job).
#[must_use]
pub fn summary_csv(reports: &[Report]) -> String {
    let quote = |s: &str| {
        if s.contains([',', '"', '\n']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
    };
    let mut out =
        String::from("job,output,status,seconds,wall_seconds,spp,samples_per_second,rays_per_second,mse,error\n");
    for r in reports {
        let o = r.outcome;
        let row = [
            quote(&r.job.origin),
            quote(&r.job.output.display().to_string()),
            r.status.name().to_string(),
            o.map_or(String::new(), |o| format!("{:.3}", o.seconds)),
            format!("{:.3}", r.wall_seconds),
            o.map_or(String::new(), |o| o.spp.to_string()),
            o.map_or(String::new(), |o| format!("{:.0}", o.samples_per_second)),
            o.map_or(String::new(), |o| format!("{:.0}", o.rays_per_second)),
            r.mse.map_or(String::new(), |m| format!("{m:.6e}")),
            quote(r.error.as_deref().unwrap_or("")),
        ];
        out.push_str(&row.join(","));
        out.push('\n');
    }
    out
}

/// The summary as JSON (an array of objects, numbers absent as `null`).
#[must_use]
pub fn summary_json(reports: &[Report]) -> String {
    let rows: Vec<serde_json::Value> = reports
        .iter()
        .map(|r| {
            let o = r.outcome;
            serde_json::json!({
                "job": r.job.origin,
                "output": r.job.output.display().to_string(),
                "status": r.status.name(),
                "seconds": o.map(|o| o.seconds),
                "wall_seconds": r.wall_seconds,
                "spp": o.map(|o| o.spp),
                "samples_per_second": o.map(|o| o.samples_per_second),
                "rays_per_second": o.map(|o| o.rays_per_second),
                "mse": r.mse,
                "error": r.error,
                "args": r.job.args,
            })
        })
        .collect();
    let mut text = serde_json::to_string_pretty(&rows).unwrap_or_else(|_| "[]".into());
    text.push('\n');
    text
}

/// The summary as a table for a terminal.
#[must_use]
pub fn summary_table(reports: &[Report]) -> String {
    let width = reports.iter().map(|r| r.job.output.display().to_string().len()).max().unwrap_or(6).clamp(6, 60);
    let mut out = format!(
        "{:<width$}  {:<8}  {:>9}  {:>6}  {:>10}  {:>10}  {:>11}  error\n",
        "output", "status", "seconds", "spp", "M samp/s", "M rays/s", "MSE"
    );
    for r in reports {
        let o = r.outcome;
        out.push_str(&format!(
            "{:<width$}  {:<8}  {:>9}  {:>6}  {:>10}  {:>10}  {:>11}  {}\n",
            r.job.output.display().to_string(),
            r.status.name(),
            o.map_or("-".into(), |o| format!("{:.2}", o.seconds)),
            o.map_or("-".into(), |o| o.spp.to_string()),
            o.map_or("-".into(), |o| format!("{:.2}", o.samples_per_second / 1e6)),
            o.map_or("-".into(), |o| format!("{:.2}", o.rays_per_second / 1e6)),
            r.mse.map_or("-".into(), |m| format!("{m:.4e}")),
            r.error.as_deref().unwrap_or(""),
        ));
    }
    let failed = reports.iter().filter(|r| r.status == Status::Failed).count();
    let skipped = reports.iter().filter(|r| r.status == Status::Skipped).count();
    out.push_str(&format!(
        "{} jobs: {} rendered, {} skipped, {} failed\n",
        reports.len(),
        reports.len() - failed - skipped,
        skipped,
        failed
    ));
    out
}

#[cfg(test)]
mod tests;
