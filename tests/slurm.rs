//! `zvidpt batch --slurm` on a real Slurm cluster (`.ci/run` starts a single-node one with
//! `.ci/slurm-local`): a job split into a 4-task array and a merge job ends bit-identical to
//! one render on this machine, for the path tracer and the learned integrator; `--status`
//! follows it; a second submission of a finished batch submits nothing. Without `sbatch` on
//! this machine the test says so and passes without running.
mod common;
use common::cli::*;
use std::process::Command;
use std::time::{Duration, Instant};

fn has_sbatch() -> bool {
    Command::new("sbatch").arg("--version").output().is_ok_and(|o| o.status.success())
}

/// Waits until none of `ids` is in Slurm's queue.
fn wait_for(ids: &[String]) {
    let start = Instant::now();
    loop {
        let out = Command::new("squeue").args(["-h", "-o", "%F", "-j", &ids.join(",")]).output().unwrap();
        let listed = String::from_utf8_lossy(&out.stdout);
        if listed.trim().is_empty() {
            return;
        }
        assert!(start.elapsed() < Duration::from_secs(300), "Slurm jobs {ids:?} still queued after 5 minutes");
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn a_slurm_array_merges_into_the_pixels_of_one_render() {
    if !has_sbatch() {
        eprintln!("skipped: no sbatch on this machine (CI starts a single-node cluster with .ci/slurm-local)");
        return;
    }
    let sinfo = Command::new("sinfo").args(["-h", "-o", "%T"]).output().unwrap();
    assert!(
        sinfo.status.success(),
        "sbatch is installed but no cluster answers (start one: .ci/slurm-local start, then export SLURM_CONF): {}",
        String::from_utf8_lossy(&sinfo.stderr)
    );
    let start = Instant::now();
    let dir = scratch("slurm", "cluster");
    let scene = format!("{}/scenes/cornell-paper", env!("CARGO_MANIFEST_DIR"));
    let jobs = dir.join("jobs.toml");
    std::fs::write(
        &jobs,
        format!(
            "[defaults]\nresolution = \"48x36\"\nseed = 11\nno_png = true\n\
             [[matrix]]\nscenes = [\"{scene}\"]\nintegrators = [\"path\", \"zvidpt\"]\nspp = [64]\n\
             output = \"out/{{integrator}}.exr\"\n"
        ),
    )
    .unwrap();
    let o = zvidpt(&["batch", s(&jobs), "--slurm", "--tasks", "4"]);
    assert!(o.status.success(), "{}", text(&o));
    let printed = text(&o);
    // "…: array job 12 (4 tasks of 64 spp), merge job 16 -> …"
    let ids: Vec<String> = printed
        .lines()
        .flat_map(|l| {
            let after = |key: &str| l.split(key).nth(1).and_then(|r| r.split_whitespace().next()).map(String::from);
            [after("array job "), after("merge job ")]
        })
        .flatten()
        .collect();
    assert_eq!(ids.len(), 4, "two array jobs and two merge jobs: {printed}");
    assert!(printed.contains("4 tasks of 64 spp"), "{printed}");
    let o = zvidpt(&["batch", s(&jobs), "--status"]);
    assert!(o.status.success(), "{}", text(&o));
    wait_for(&ids);
    let o = zvidpt(&["batch", s(&jobs), "--status"]);
    assert_eq!(text(&o).lines().filter(|l| l.starts_with("done ")).count(), 2, "{}", text(&o));

    for integrator in ["path", "zvidpt"] {
        let merged = dir.join(format!("out/{integrator}.exr"));
        assert!(merged.exists(), "no {}; logs in {}", merged.display(), dir.join("out").display());
        let single = dir.join(format!("{integrator}-here.exr"));
        let o = zvidpt(&[
            "render",
            &scene,
            "--resolution",
            "48x36",
            "--seed",
            "11",
            "--spp",
            "64",
            "--integrator",
            integrator,
            "--no-png",
            "-q",
            "-o",
            s(&single),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        assert_eq!(bits(&merged), bits(&single), "{integrator}: the Slurm array's image differs from one render's");
        let parts = dir.join(format!("out/{integrator}.exr.slurm/part-0.zvp"));
        assert!(!parts.exists(), "the merge job removes the parts");
    }
    // Finished jobs are not submitted again.
    let o = zvidpt(&["batch", s(&jobs), "--slurm"]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(text(&o).matches("done already").count(), 2, "{}", text(&o));
    eprintln!("Slurm test: {:.1} s", start.elapsed().as_secs_f64());
}
