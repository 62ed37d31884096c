use super::*;
use std::collections::HashSet;
use std::sync::Mutex;

fn jobs(text: &str) -> Result<Vec<Job>> {
    parse(text, Path::new("jobs.toml"), Path::new("/base"))
}

#[test]
fn defaults_jobs_and_flags() {
    let list = jobs(
        r#"
        [defaults]
        resolution = "64x48"
        no_png = true
        seed = 7

        [[job]]
        scene = "scenes/a"
        output = "out/a.exr"
        integrator = "path"
        spp = 4
        seed = 9
        reference = "ref.exr"

        [[job]]
        scene = "/abs/b.toml"
        output = "/abs/b.exr"
        time = 1.5
        no_png = false
        "#,
    )
    .unwrap();
    assert_eq!(list.len(), 2);
    assert_eq!(list[0].output, Path::new("/base/out/a.exr"));
    assert_eq!(list[0].reference.as_deref(), Some(Path::new("/base/ref.exr")));
    let a = list[0].args.join(" ");
    assert!(a.starts_with("/base/scenes/a -o /base/out/a.exr"), "{a}");
    // The job's seed wins over the default; booleans are bare flags.
    assert!(a.contains("--seed 9") && !a.contains("--seed 7"), "{a}");
    assert!(a.contains("--no-png") && a.contains("--resolution 64x48") && a.contains("--integrator path"), "{a}");
    let b = list[1].args.join(" ");
    assert!(b.contains("--time 1.5") && !b.contains("--no-png") && b.contains("--seed 7"), "{b}");
    assert_ne!(list[0].key(), list[1].key());
}

#[test]
fn a_matrix_expands_with_its_template() {
    let list = jobs(
        r#"
        [[matrix]]
        scenes = ["scenes/cornell-paper", "x/furnace/scene.toml", "y/room.toml"]
        integrators = ["path", "zvidpt"]
        spp = [4, 16]
        output = "out/{scene}-{integrator}-{spp}.exr"
        resolution = "32x24"
        "#,
    )
    .unwrap();
    assert_eq!(list.len(), 12);
    let outputs: HashSet<_> = list.iter().map(|j| j.output.clone()).collect();
    assert_eq!(outputs.len(), 12);
    for name in ["cornell-paper-path-4.exr", "furnace-zvidpt-16.exr", "room-path-16.exr"] {
        assert!(outputs.contains(&Path::new("/base/out").join(name)), "{name} in {outputs:?}");
    }
    assert!(list.iter().all(|j| j.args.contains(&"--resolution".to_string())));
    // Time budgets and seeds too.
    let list = jobs(
        r#"
        [matrix]
        scenes = ["s"]
        time = [1, 2.5]
        seeds = [1, 2]
        output = "t{time}-s{seed}.exr"
        "#,
    )
    .unwrap();
    let names: Vec<_> = list.iter().map(|j| j.output.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["t1-s1.exr", "t1-s2.exr", "t2.5-s1.exr", "t2.5-s2.exr"]);
}

#[test]
fn malformed_job_files_name_the_problem() {
    let cases = [
        ("[[job]]\nscene = \"a\"\n", "no `output`"),
        ("[[job]]\noutput = \"a.exr\"\n", "no `scene`"),
        ("[[job]]\nscene = \"a\"\noutput = \"o.exr\"\n[[job]]\nscene = \"b\"\noutput = \"o.exr\"\n", "both write"),
        // One file by two spellings.
        (
            "[[job]]\nscene = \"a\"\noutput = \"./o.exr\"\n[[job]]\nscene = \"b\"\noutput = \"sub/../o.exr\"\n",
            "both write",
        ),
        ("[matrix]\nscenes = [\"a\", \"b\"]\noutput = \"o.exr\"\n", "needs {scene}"),
        ("[matrix]\nscenes = [\"a\"]\noutput = \"o-{sceen}.exr\"\n", "uses {sceen}"),
        ("[matrix]\nscenes = [\"a\"]\nspp = [4]\noutput = \"o-{scene}-{seed}.exr\"\n", "uses {seed}"),
        ("[matrix]\nscenes = [\"a\"]\nspp = [4]\noutput = \"o-{scene}-{time}.exr\"\n", "uses {time}"),
        ("[matrix]\nscenes = [\"a\"]\nspp = [1]\ntime = [1]\noutput = \"o.exr\"\n", "not both"),
        ("[defaults]\nscene = \"a\"\n", "cannot set `scene`"),
        ("jobs = 3\n", "unknown top-level key"),
        ("", "no jobs"),
        ("[[job]]\nscene = \"a\"\noutput = \"o.exr\"\nspp = [1, 2]\n", "must be a string, number or boolean"),
        ("[[job]\n", "line 1"),
    ];
    for (text, expected) in cases {
        let e = jobs(text).unwrap_err().to_string();
        assert!(e.contains(expected) && e.starts_with("jobs.toml"), "{text:?}: {e}");
    }
}

/// Renders nothing: records what it was asked, fails where told.
struct Fake {
    done: HashSet<PathBuf>,
    fail: HashSet<PathBuf>,
    bad_flag: Option<String>,
    rendered: Mutex<Vec<(PathBuf, Option<usize>)>>,
}

impl Fake {
    fn new() -> Self {
        Self { done: HashSet::new(), fail: HashSet::new(), bad_flag: None, rendered: Mutex::new(Vec::new()) }
    }
}

impl Runner for Fake {
    fn check(&self, job: &Job) -> Result<()> {
        match &self.bad_flag {
            Some(f) if job.args.contains(f) => Err(Error::InvalidOption(format!("unexpected argument '{f}'"))),
            _ => Ok(()),
        }
    }
    fn is_done(&self, job: &Job) -> bool {
        self.done.contains(&job.output)
    }
    fn render(&self, job: &Job, threads: Option<usize>) -> Result<Outcome> {
        self.rendered.lock().unwrap().push((job.output.clone(), threads));
        if self.fail.contains(&job.output) {
            return Err(Error::InvalidScene { path: job.output.clone(), message: "no such scene\nsecond line".into() });
        }
        Ok(Outcome { seconds: 1.0, spp: 4, samples_per_second: 2e6, rays_per_second: 5e6 })
    }
    fn mse(&self, _job: &Job, _reference: &Path) -> Result<f64> {
        Ok(0.25)
    }
}

const THREE: &str = r#"
    [[matrix]]
    scenes = ["a", "b", "c"]
    output = "{scene}.exr"
    reference = "ref.exr"
"#;

#[test]
fn a_failing_job_is_recorded_and_the_rest_go_on() {
    let list = jobs(THREE).unwrap();
    let mut fake = Fake::new();
    fake.fail.insert(PathBuf::from("/base/b.exr"));
    fake.done.insert(PathBuf::from("/base/c.exr"));
    let seen = Mutex::new(0);
    let reports =
        run(&list, &fake, BatchOptions { parallel: 1, threads: None }, &|_| *seen.lock().unwrap() += 1).unwrap();
    assert_eq!(*seen.lock().unwrap(), 3);
    let status: Vec<_> = reports.iter().map(|r| r.status).collect();
    assert_eq!(status, [Status::Rendered, Status::Failed, Status::Skipped]);
    assert_eq!(reports[1].error.as_deref(), Some("/base/b.exr: no such scene"));
    assert_eq!((reports[0].mse, reports[1].mse, reports[2].mse), (Some(0.25), None, Some(0.25)));
    // The skipped job was not rendered again.
    let rendered: Vec<_> = fake.rendered.lock().unwrap().iter().map(|r| r.0.clone()).collect();
    assert_eq!(rendered, [PathBuf::from("/base/a.exr"), PathBuf::from("/base/b.exr")]);
    let csv = summary_csv(&reports);
    assert_eq!(csv.lines().count(), 4);
    assert!(csv.lines().nth(2).unwrap().contains(",failed,") && csv.contains("2.500000e-1"), "{csv}");
    let json: serde_json::Value = serde_json::from_str(&summary_json(&reports)).unwrap();
    assert_eq!(json[1]["status"], "failed");
    assert_eq!(json[0]["spp"], 4);
    assert!(json[1]["spp"].is_null());
    assert!(summary_table(&reports).contains("3 jobs: 1 rendered, 1 skipped, 1 failed"));
}

#[test]
fn a_bad_flag_stops_the_batch_before_any_render() {
    let mut text = THREE.to_string();
    text.push_str("spp_per_pixel = 3\n");
    let list = jobs(&text).unwrap();
    let mut fake = Fake::new();
    fake.bad_flag = Some("--spp-per-pixel".into());
    let e = run(&list, &fake, BatchOptions { parallel: 1, threads: None }, &|_| {}).unwrap_err();
    assert!(e.to_string().starts_with("matrix 1 (a, , ") && e.to_string().contains("--spp-per-pixel"), "{e}");
    assert!(fake.rendered.lock().unwrap().is_empty());
}

#[test]
fn parallel_jobs_share_the_threads_and_keep_the_order() {
    let list = jobs(THREE).unwrap();
    let fake = Fake::new();
    let reports = run(&list, &fake, BatchOptions { parallel: 2, threads: Some(4) }, &|_| {}).unwrap();
    let outputs: Vec<_> = reports.iter().map(|r| r.job.output.clone()).collect();
    assert_eq!(outputs, list.iter().map(|j| j.output.clone()).collect::<Vec<_>>());
    assert!(fake.rendered.lock().unwrap().iter().all(|r| r.1 == Some(2)));
    let reports = run(&list, &fake, BatchOptions { parallel: 1, threads: Some(3) }, &|_| {}).unwrap();
    assert_eq!(reports.len(), 3);
    assert!(fake.rendered.lock().unwrap().iter().skip(3).all(|r| r.1 == Some(3)));
}

/// A job may not write its own job file, whatever the spelling; nor may two jobs write one
/// file through a folder linked under another name.
#[test]
fn outputs_alias_neither_each_other_nor_the_job_file() {
    let dir = std::env::temp_dir().join(format!("zvidpt-batch-alias-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("real")).unwrap();
    let _ = std::fs::remove_file(dir.join("link"));
    std::os::unix::fs::symlink(dir.join("real"), dir.join("link")).unwrap();
    let file = dir.join("jobs.toml");
    std::fs::write(&file, "").unwrap();
    let parse_here = |text: &str| parse(text, &file, &dir).map(|_| ()).unwrap_err().to_string();
    let own = parse_here("[[job]]\nscene = \"a\"\noutput = \"./jobs.toml\"\n");
    assert!(own.contains("the job file itself"), "{own}");
    let linked = parse_here(
        "[[job]]\nscene = \"a\"\noutput = \"real/o.exr\"\n[[job]]\nscene = \"b\"\noutput = \"link/o.exr\"\n",
    );
    assert!(linked.contains("both write"), "{linked}");
    std::fs::remove_dir_all(&dir).unwrap();
}
