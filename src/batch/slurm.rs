//! Scale-out on Slurm (`zvidpt batch JOBS.toml --slurm`): each job becomes a job array whose
//! tasks render sample ranges (`zvidpt render --samples A..B`, each keeping a checkpoint, so a
//! requeued task resumes), and a merge job that runs once every task succeeded
//! (`--dependency=afterok`) and writes the output, bit-identical to one render on one machine.
//! A job with a time budget, a noise target or first-hit AOVs cannot be split by samples: it
//! is one task.
//!
//! Each job's scripts, part files and Slurm logs live in `OUTPUT.slurm/`; its job ids are kept
//! in `OUTPUT.slurm/submitted`, so that a rerun does not submit again what is still queued,
//! and `zvidpt batch --status` reports progress from the part and checkpoint files.
use super::Job;
use crate::film::read_partial_header;
use crate::{Error, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// How jobs are submitted.
#[derive(Clone, Debug)]
pub struct SlurmOptions {
    /// Array tasks per job (sample ranges), at most its sample count.
    pub tasks: u32,
    /// CPUs each task asks for (and renders with).
    pub cpus_per_task: u32,
    /// Extra `sbatch` arguments (`--partition=…`, `--account=…`, `--time=…`).
    pub sbatch_args: Vec<String>,
    /// The `zvidpt` executable the tasks run (it must be reachable from the compute nodes).
    pub exe: PathBuf,
    /// The folder the tasks run in (relative paths in the jobs are taken from it).
    pub workdir: PathBuf,
}

/// How a job is split.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Split {
    /// Sample ranges of an `spp`-sample render, one per task, then a merge.
    Samples {
        /// Samples per pixel of the whole render.
        spp: u32,
        /// Array tasks, each a contiguous range of the samples.
        tasks: u32,
    },
    /// One task renders the whole job (time budget or AOVs).
    Whole,
}

/// The value following `flag` in a job's arguments (the job file gives every flag as
/// `--flag value`).
fn flag_value<'a>(job: &'a Job, flag: &str) -> Option<&'a str> {
    job.args.iter().position(|a| a == flag).and_then(|i| job.args.get(i + 1)).map(String::as_str)
}

/// How `job` is split into `tasks` tasks.
pub fn split_of(job: &Job, tasks: u32) -> Result<Split> {
    if job.args.iter().any(|a| a == "--samples") {
        return Err(Error::InvalidOption(format!("{}: a job with `samples` is already a part", job.origin)));
    }
    let aov = flag_value(job, "--aov").is_some_and(|v| v.split(',').any(|a| a.trim() != "variance"));
    if job.args.iter().any(|a| a == "--time" || a == "--noise-target") || aov {
        return Ok(Split::Whole);
    }
    let spp = match flag_value(job, "--spp") {
        Some(v) => v.parse().map_err(|_| Error::InvalidOption(format!("{}: spp `{v}`", job.origin)))?,
        None => crate::render::DEFAULT_SPP,
    };
    Ok(Split::Samples { spp, tasks: tasks.clamp(1, spp.max(1)) })
}

/// Samples `a..b` of task `i` of `n` over `spp` (the shell scripts compute the same).
#[must_use]
pub fn task_range(i: u32, n: u32, spp: u32) -> (u32, u32) {
    let at = |k: u32| (u64::from(k) * u64::from(spp) / u64::from(n)) as u32;
    (at(i), at(i + 1))
}

/// The folder of a job's scripts, parts and logs.
#[must_use]
pub fn folder(job: &Job) -> PathBuf {
    let mut name = job.output.as_os_str().to_owned();
    name.push(".slurm");
    PathBuf::from(name)
}

fn part_path(job: &Job, i: u32) -> PathBuf {
    folder(job).join(format!("part-{i}.zvp"))
}

/// A word for `sh`, single-quoted (newlines and every other byte but NUL stand for
/// themselves inside single quotes; NUL is refused before any script is written).
fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', "'\\''"))
}

/// Text for a comment line of a script: control characters (a newline would end the comment
/// and start a command) written as escapes.
fn comment(s: &str) -> String {
    s.chars().flat_map(|c| if c.is_control() { c.escape_default().collect::<Vec<_>>() } else { vec![c] }).collect()
}

/// Refuses a job whose words cannot stand in a shell script: a NUL byte has no quoting.
pub(crate) fn check_scriptable(job: &Job, options: &SlurmOptions) -> Result<()> {
    let words = job.args.iter().map(String::as_str).chain([job.origin.as_str()]);
    let paths = [&job.output, &options.exe, &options.workdir].map(|p| p.to_string_lossy().into_owned());
    if words.chain(paths.iter().map(String::as_str)).any(|w| w.contains('\0')) {
        return Err(Error::InvalidOption(format!(
            "{}: a NUL byte in the job cannot be written into a Slurm script",
            comment(&job.origin)
        )));
    }
    Ok(())
}

/// The job's render arguments without the output and the PNG options (a part writes none;
/// the merge writes the PNG).
fn part_args(job: &Job) -> Vec<String> {
    let mut out = Vec::new();
    let mut it = job.args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "-o" | "--png" | "--exposure" => {
                it.next();
            }
            "--no-png" | "--resume" => {}
            _ => out.push(a.clone()),
        }
    }
    out
}

/// The scripts of a job: the task script (an array task or the whole render) and, for a
/// split job, the merge script.
#[must_use]
pub fn scripts(job: &Job, split: &Split, options: &SlurmOptions) -> (String, Option<String>) {
    let exe = quote(&options.exe.display().to_string());
    let threads = options.cpus_per_task.to_string();
    let head = format!(
        "#!/bin/sh\n# zvidpt batch --slurm: {} -> {}\nset -eu\n",
        comment(&job.origin),
        comment(&job.output.display().to_string())
    );
    match split {
        Split::Whole => {
            let mut words: Vec<String> = vec![exe, "render".into()];
            words.extend(job.args.iter().map(|a| quote(a)));
            words.extend(["--resume", "--threads", &threads, "--quiet", "--job-key"].map(quote));
            words.push(quote(&job.key()));
            (format!("{head}exec {}\n", words.join(" ")), None)
        }
        Split::Samples { spp, tasks } => {
            let dir = folder(job).display().to_string();
            let mut words: Vec<String> = vec![exe.clone(), "render".into()];
            words.extend(part_args(job).iter().map(|a| quote(a)));
            words.push("-o".into());
            words.push(format!("{}\"$i\"'.zvp'", quote(&format!("{dir}/part-"))));
            words.extend(["--samples".to_string(), "\"$a..$b\"".into()]);
            words.extend(["--resume", "--threads", &threads, "--quiet"].map(quote));
            let task = format!(
                "{head}i=${{SLURM_ARRAY_TASK_ID:?not run as a Slurm array task}}\n\
                 a=$(( i * {spp} / {tasks} ))\nb=$(( (i + 1) * {spp} / {tasks} ))\nexec {}\n",
                words.join(" ")
            );
            let parts: Vec<String> = (0..*tasks).map(|i| quote(&part_path(job, i).display().to_string())).collect();
            let mut merge: Vec<String> =
                vec![exe, "merge".into(), "-o".into(), quote(&job.output.display().to_string())];
            let mut it = job.args.iter();
            while let Some(a) = it.next() {
                match a.as_str() {
                    "--png" | "--exposure" => {
                        merge.push(quote(a));
                        if let Some(v) = it.next() {
                            merge.push(quote(v));
                        }
                    }
                    "--no-png" => merge.push(quote(a)),
                    _ => {}
                }
            }
            merge.extend(["--job-key".to_string(), quote(&job.key())]);
            merge.extend(parts.iter().cloned());
            let merge = format!(
                "{head}{}\n# The output holds every sample: the parts go.\nrm -f {}\n",
                merge.join(" "),
                parts.join(" ")
            );
            (task, Some(merge))
        }
    }
}

/// What was submitted for one job.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Submitted {
    /// The array job (or the single render's job).
    pub render: String,
    /// The merge job, for a split render.
    pub merge: Option<String>,
    /// How the job was split into tasks.
    pub split: Split,
}

/// Runs `sbatch` with `args`; returns the job id.
fn sbatch(args: &[String]) -> Result<String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .output()
        .map_err(|e| Error::InvalidOption(format!("cannot run sbatch (is Slurm installed here?): {e}")))?;
    let text = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(Error::InvalidOption(format!("sbatch failed: {}", err.lines().next().unwrap_or("").trim())));
    }
    // `--parsable` prints `id` or `id;cluster`.
    let id = text.trim().split(';').next().unwrap_or("").to_string();
    if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
        return Err(Error::InvalidOption(format!("sbatch printed no job id: {}", text.trim())));
    }
    Ok(id)
}

/// The ids of `ids` that are still in Slurm's queue (pending or running).
fn queued(ids: &[&str]) -> Vec<String> {
    let Ok(out) = Command::new("squeue").args(["-h", "-o", "%F", "-j", &ids.join(",")]).output() else {
        return Vec::new();
    };
    let text = String::from_utf8_lossy(&out.stdout);
    let mut found: Vec<String> =
        text.lines().map(|l| l.trim().to_string()).filter(|l| ids.contains(&l.as_str())).collect();
    found.sort_by_key(|id| id.parse::<u64>().unwrap_or(u64::MAX));
    found.dedup();
    found
}

/// What an earlier submission recorded (`OUTPUT.slurm/submitted`: `key=value` lines).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct Record {
    ids: Vec<String>,
    tasks: Option<u32>,
}

fn record(job: &Job) -> Record {
    let mut r = Record::default();
    let Ok(text) = std::fs::read_to_string(folder(job).join("submitted")) else { return r };
    for line in text.lines() {
        match line.split_once('=') {
            Some(("render" | "merge", id)) if !id.is_empty() && id.bytes().all(|b| b.is_ascii_digit()) => {
                r.ids.push(id.to_string());
            }
            Some(("tasks", n)) => r.tasks = n.parse().ok(),
            _ => {}
        }
    }
    r
}

/// Submits `job`, unless an earlier submission of it is still queued (then `Ok(None)`).
pub fn submit(job: &Job, options: &SlurmOptions) -> Result<Option<Submitted>> {
    let split = split_of(job, options.tasks)?;
    check_scriptable(job, options)?;
    if !queued_jobs(job).is_empty() {
        return Ok(None);
    }
    let dir = folder(job);
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let (task, merge) = scripts(job, &split, options);
    let write = |name: &str, text: &str| -> Result<PathBuf> {
        let p = dir.join(name);
        crate::film::write_atomically(&p, |w| {
            use std::io::Write as _;
            w.write_all(text.as_bytes()).map_err(|e| Error::io(&p, e))
        })?;
        Ok(p)
    };
    let task_script = write("render.sh", &task)?;
    let name = format!("zvidpt-{}", &job.key()[..8]);
    let mut common = vec![
        format!("--job-name={name}"),
        format!("--chdir={}", options.workdir.display()),
        format!("--cpus-per-task={}", options.cpus_per_task),
    ];
    common.extend(options.sbatch_args.iter().cloned());
    let mut args = common.clone();
    if let Split::Samples { tasks, .. } = split {
        args.push(format!("--array=0-{}", tasks - 1));
        args.push(format!("--output={}", dir.join("render-%a.log").display()));
    } else {
        args.push(format!("--output={}", dir.join("render.log").display()));
    }
    args.push(task_script.display().to_string());
    let render = sbatch(&args)?;
    let merge = match merge {
        None => None,
        Some(text) => {
            let script = write("merge.sh", &text)?;
            let mut args = common;
            args[2] = "--cpus-per-task=1".into();
            args.push(format!("--dependency=afterok:{render}"));
            args.push(format!("--output={}", dir.join("merge.log").display()));
            args.push(script.display().to_string());
            Some(sbatch(&args)?)
        }
    };
    let mut text = format!("render={render}\n");
    if let Some(m) = &merge {
        text.push_str(&format!("merge={m}\n"));
    }
    if let Split::Samples { tasks, .. } = split {
        text.push_str(&format!("tasks={tasks}\n"));
    }
    write("submitted", &text)?;
    Ok(Some(Submitted { render, merge, split }))
}

/// A job's progress, from its files.
#[derive(Clone, Debug, PartialEq)]
pub struct Progress {
    /// Samples per pixel done (in finished parts and checkpoints), and the total (`None`
    /// for a time budget).
    pub spp_done: u32,
    /// Samples per pixel the job renders in all (`None` for a time budget).
    pub spp_total: Option<u32>,
    /// Parts finished, of all (split jobs).
    pub parts: Option<(u32, u32)>,
}

/// Progress of a job that is not finished, read from its part and checkpoint files.
#[must_use]
pub fn progress(job: &Job, tasks: u32) -> Progress {
    let spp_of = |p: &Path| read_partial_header(p).map_or(0, |(h, _)| h.spp);
    let checkpoint = |p: &Path| {
        let mut name = p.as_os_str().to_owned();
        name.push(".checkpoint");
        PathBuf::from(name)
    };
    let split = split_of(job, tasks).unwrap_or(Split::Whole);
    match split {
        Split::Samples { spp, tasks } => {
            // The task count the job was submitted with.
            let tasks = record(job).tasks.unwrap_or(tasks);
            let (mut done, mut finished) = (0, 0);
            for i in 0..tasks {
                let part = part_path(job, i);
                if part.exists() {
                    finished += 1;
                    done += spp_of(&part);
                } else {
                    done += spp_of(&checkpoint(&part));
                }
            }
            if finished == 0 && done == 0 {
                // Not split (yet): a plain render's checkpoint.
                done = spp_of(&checkpoint(&job.output));
            }
            Progress { spp_done: done, spp_total: Some(spp), parts: Some((finished, tasks)) }
        }
        Split::Whole => Progress {
            spp_done: spp_of(&checkpoint(&job.output)),
            spp_total: flag_value(job, "--spp").and_then(|v| v.parse().ok()),
            parts: None,
        },
    }
}

/// Job ids recorded for `job` that are still queued.
#[must_use]
pub fn queued_jobs(job: &Job) -> Vec<String> {
    let ids = record(job).ids;
    if ids.is_empty() {
        return ids;
    }
    queued(&ids.iter().map(String::as_str).collect::<Vec<_>>())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(args: &[&str]) -> Job {
        let mut all = vec!["scene".to_string(), "-o".into(), "/tmp/x/out.exr".into()];
        all.extend(args.iter().map(|s| s.to_string()));
        Job { origin: "job 1".into(), output: "/tmp/x/out.exr".into(), args: all, reference: None }
    }

    #[test]
    fn task_ranges_cover_every_sample_once() {
        for (n, spp) in [(4, 64), (3, 10), (7, 7), (5, 1000), (1, 1)] {
            let mut next = 0;
            for i in 0..n {
                let (a, b) = task_range(i, n, spp);
                assert_eq!(a, next);
                assert!(b > a, "{n} tasks of {spp}: task {i} is empty");
                next = b;
            }
            assert_eq!(next, spp);
        }
    }

    #[test]
    fn the_shell_computes_the_same_ranges() {
        let options = SlurmOptions {
            tasks: 3,
            cpus_per_task: 1,
            sbatch_args: vec![],
            exe: "/bin/echo".into(),
            workdir: ".".into(),
        };
        let j = job(&["--spp", "10", "--no-png", "--exposure", "1.5"]);
        let split = split_of(&j, 3).unwrap();
        assert_eq!(split, Split::Samples { spp: 10, tasks: 3 });
        let (task, merge) = scripts(&j, &split, &options);
        for i in 0..3 {
            // `exec /bin/echo …` prints the render's arguments.
            let out =
                Command::new("sh").arg("-c").arg(&task).env("SLURM_ARRAY_TASK_ID", i.to_string()).output().unwrap();
            let line = String::from_utf8(out.stdout).unwrap();
            let (a, b) = task_range(i, 3, 10);
            assert!(line.contains(&format!("--samples {a}..{b}")), "{line}");
            assert!(line.contains(&format!("-o /tmp/x/out.exr.slurm/part-{i}.zvp")), "{line}");
            assert!(!line.contains("--exposure") && !line.contains("--no-png"), "{line}");
        }
        let merge = merge.unwrap();
        assert!(merge.contains("'--exposure' '1.5'") && merge.contains("'--no-png'"), "{merge}");
        assert!(merge.contains(&j.key()));
    }

    #[test]
    fn time_budgets_and_aovs_are_not_split() {
        assert_eq!(split_of(&job(&["--time", "10"]), 4).unwrap(), Split::Whole);
        assert_eq!(split_of(&job(&["--aov", "albedo,normal"]), 4).unwrap(), Split::Whole);
        assert_eq!(split_of(&job(&["--aov", "variance"]), 4).unwrap(), Split::Samples { spp: 64, tasks: 4 });
        assert_eq!(split_of(&job(&["--spp", "2"]), 4).unwrap(), Split::Samples { spp: 2, tasks: 2 });
        assert!(split_of(&job(&["--samples", "0..4"]), 4).is_err());
    }

    /// Every field of a job reaches the scripts as data: a newline in the job's origin or
    /// output (both also in the comment line) starts no command, and the render still gets
    /// the output's name intact; a NUL byte is refused.
    #[test]
    fn job_fields_cannot_inject_commands() {
        let dir = std::env::temp_dir().join(format!("zvidpt-slurm-inject-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let marker = dir.join("INJECTED");
        let evil = format!("x\ntouch {}\n#", marker.display());
        let output = format!("/tmp/x/out{evil}.exr");
        let mut j = job(&["--time", "5", "--label", &evil]);
        j.origin = format!("job {evil}");
        j.output = output.clone().into();
        j.args[2] = output.clone();
        let options = SlurmOptions {
            tasks: 2,
            cpus_per_task: 1,
            sbatch_args: vec![],
            exe: "/bin/echo".into(),
            workdir: ".".into(),
        };
        let (task, merge) = scripts(&j, &split_of(&j, 2).unwrap(), &options);
        assert!(merge.is_none());
        let out = Command::new("sh").arg("-c").arg(&task).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(!marker.exists(), "a job field ran a command:\n{task}");
        assert!(String::from_utf8(out.stdout).unwrap().contains(&output), "the output's name reaches the render");
        // The split form and its merge script too.
        let mut j = job(&["--spp", "8", "--label", &evil]);
        j.origin = format!("job {evil}");
        let (task, merge) = scripts(&j, &split_of(&j, 2).unwrap(), &options);
        for script in [task, merge.unwrap()] {
            Command::new("sh").arg("-c").arg(&script).env("SLURM_ARRAY_TASK_ID", "0").output().unwrap();
            assert!(!marker.exists(), "a job field ran a command:\n{script}");
        }
        let mut nul = job(&["--label", "a\0b"]);
        nul.origin = "job 2".into();
        assert!(check_scriptable(&nul, &options).unwrap_err().to_string().contains("NUL"));
        assert!(check_scriptable(&job(&[]), &options).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn quoting_survives_the_shell() {
        let word = "it's a \"path\" with $HOME and `x`";
        let out = Command::new("sh").arg("-c").arg(format!("printf %s {}", quote(word))).output().unwrap();
        assert_eq!(String::from_utf8(out.stdout).unwrap(), word);
    }
}
