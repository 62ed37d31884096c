//! `zvidpt batch` end to end: a job file with a matrix and a failing job renders what it can,
//! records the failure, writes its summaries and exits non-zero; a rerun skips every finished
//! job (resume) and leaves their files untouched; an edited scene renders again.
mod common;
use common::cli::*;
use std::path::Path;

fn modified(p: &Path) -> std::time::SystemTime {
    std::fs::metadata(p).unwrap().modified().unwrap()
}

#[test]
fn batch_renders_records_failures_and_resumes() {
    let dir = scratch("batch", "resume");
    // A copy of a shipped scene, to edit later.
    let scene = dir.join("paper");
    std::fs::create_dir_all(&scene).unwrap();
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-paper");
    for f in ["scene.toml", "box.obj", "box.mtl", "light.obj"] {
        std::fs::copy(shipped.join(f), scene.join(f)).unwrap();
    }
    let jobs = dir.join("jobs.toml");
    std::fs::write(
        &jobs,
        r#"
[defaults]
resolution = "24x18"
no_png = true
seed = 3

[[matrix]]
scenes = ["paper"]
integrators = ["path", "zvidpt"]
spp = [2, 4]
output = "out/{scene}-{integrator}-{spp}.exr"
reference = "out/paper-path-4.exr"

[[job]]
scene = "missing-scene"
output = "out/missing.exr"
spp = 2
"#,
    )
    .unwrap();
    let first = zvidpt(&["batch", jobs.to_str().unwrap()]);
    let log = text(&first);
    assert_eq!(first.status.code(), Some(1), "{log}");
    assert!(log.contains("error: 1 of 5 jobs failed"), "{log}");
    assert!(log.contains("5 jobs: 4 rendered, 0 skipped, 1 failed"), "{log}");
    // Stderr is a pipe here: progress is JSON lines, one per pass and one per job.
    let events: Vec<serde_json::Value> =
        String::from_utf8_lossy(&first.stderr).lines().filter_map(|l| serde_json::from_str(l).ok()).collect();
    let count = |e: &str| events.iter().filter(|v| v["event"] == e).count();
    assert_eq!(count("job"), 5, "{log}");
    assert!(count("pass") >= 4, "{log}");
    assert!(events.iter().any(|v| v["event"] == "job" && v["status"] == "failed" && v["error"].is_string()), "{log}");
    for name in ["paper-path-2", "paper-path-4", "paper-zvidpt-2", "paper-zvidpt-4"] {
        assert!(dir.join(format!("out/{name}.exr")).is_file(), "{name}: {log}");
    }
    assert!(!dir.join("out/missing.exr").exists());
    let csv = std::fs::read_to_string(dir.join("summary.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 6, "{csv}");
    // [[job]] tables come first, then the matrix.
    assert!(rows[1].contains(",failed,") && rows[1].contains("missing-scene"), "{csv}");
    // The path job compared with itself has MSE 0; the others have one.
    assert!(rows[3].contains(",0.000000e0,"), "{csv}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json.as_array().unwrap().len(), 5);
    assert_eq!(json[1]["status"], "rendered");
    assert!(json[1]["rays_per_second"].as_f64().unwrap() > 0.0);
    assert!(json[1]["mse"].as_f64().unwrap() > 0.0 && json[4]["mse"].as_f64().unwrap() > 0.0);

    // Rerun: every finished job is skipped and its file untouched; the failure fails again.
    let before = modified(&dir.join("out/paper-zvidpt-4.exr"));
    let second = zvidpt(&["batch", jobs.to_str().unwrap()]);
    let log = text(&second);
    assert_eq!(second.status.code(), Some(1), "{log}");
    assert!(log.contains("5 jobs: 0 rendered, 4 skipped, 1 failed"), "{log}");
    assert_eq!(modified(&dir.join("out/paper-zvidpt-4.exr")), before);

    // An edited scene (same flags) renders again.
    let toml = std::fs::read_to_string(scene.join("scene.toml")).unwrap();
    std::fs::write(scene.join("scene.toml"), toml.replace("fov_y = 45.0", "fov_y = 44.0")).unwrap();
    std::fs::write(
        &jobs,
        std::fs::read_to_string(&jobs)
            .unwrap()
            .replace("[[job]]\nscene = \"missing-scene\"\noutput = \"out/missing.exr\"\nspp = 2\n", ""),
    )
    .unwrap();
    let third = zvidpt(&["batch", jobs.to_str().unwrap(), "--parallel", "2"]);
    let log = text(&third);
    assert!(third.status.success(), "{log}");
    assert!(log.contains("4 jobs: 4 rendered, 0 skipped, 0 failed"), "{log}");
}

#[test]
fn a_malformed_job_file_renders_nothing() {
    let dir = scratch("batch", "malformed");
    let jobs = dir.join("jobs.toml");
    let scene = format!("{}/scenes/cornell-paper", env!("CARGO_MANIFEST_DIR"));
    std::fs::write(&jobs, format!("[[job]]\nscene = \"{scene}\"\noutput = \"a.exr\"\nsamples = 4\n")).unwrap();
    let out = zvidpt(&["batch", jobs.to_str().unwrap()]);
    let log = text(&out);
    assert_eq!(out.status.code(), Some(1), "{log}");
    assert!(log.starts_with("error: job 1: ") && log.contains("--samples") && log.lines().count() == 1, "{log}");
    assert!(!dir.join("a.exr").exists() && !dir.join("summary.csv").exists());
    let out = zvidpt(&["batch", jobs.to_str().unwrap().replace("jobs", "nothing").as_str()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out).starts_with("error: ") && text(&out).contains("nothing.toml"), "{}", text(&out));
}
