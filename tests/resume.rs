//! Checkpoints and `zvidpt render --resume`: a render killed mid-way (SIGKILL, SIGTERM or
//! SIGINT) and resumed ends with pixels and variances bit-identical to an uninterrupted render,
//! for the path tracer and for the learned integrator (whose pre-pass is rebuilt); SIGTERM and
//! SIGINT write the checkpoint, leave no temporary file and exit 143 and 130; a rerun of an
//! interrupted batch continues; a checkpoint of another render is refused.
mod common;
use common::cli::*;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};
use zvidpt::film::{read_exr, read_partial};

fn scene() -> String {
    format!("{}/scenes/cornell-paper", env!("CARGO_MANIFEST_DIR"))
}

/// Asserts that two images hold the same pixels and variances, bit for bit.
fn assert_same_bits(a: &Path, b: &Path, what: &str) {
    let (x, y) = (bits(a), bits(b));
    assert_eq!(x.len(), y.len());
    let differ = x.iter().zip(&y).filter(|(p, q)| p != q).count();
    assert_eq!(differ, 0, "{what}: {differ} of {} values differ between {} and {}", x.len(), a.display(), b.display());
}

/// Files whose names start with a dot (the temporary files of atomic writes).
fn hidden_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect()
}

/// Samples per pixel the checkpoint at `path` holds (0 while there is none).
fn checkpoint_spp(path: &Path) -> u32 {
    read_partial(path).map_or(0, |(p, _)| p.sums.spp)
}

/// Waits until `child`'s checkpoint holds at least `spp` samples per pixel.
fn wait_for_checkpoint(child: &mut Child, path: &Path, spp: u32) {
    let start = Instant::now();
    while checkpoint_spp(path) < spp {
        assert!(child.try_wait().unwrap().is_none(), "the render ended before its checkpoint reached {spp} spp");
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint after two minutes");
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn render_args<'a>(scene: &'a str, integrator: &'a str, spp: &'a str, out: &'a Path) -> Vec<&'a str> {
    vec![
        "render",
        scene,
        "--integrator",
        integrator,
        "--resolution",
        "32x24",
        "--seed",
        "7",
        "--spp",
        spp,
        "-q",
        "--no-png",
        "-o",
        s(out),
    ]
}

fn killed_and_resumed(integrator: &str, spp: &str) {
    let dir = scratch("resume", &format!("kill-{integrator}"));
    let scene = scene();
    let whole = dir.join("whole.exr");
    let o = zvidpt(&[&render_args(&scene, integrator, spp, &whole)[..], &["--no-checkpoint"][..]].concat());
    assert!(o.status.success(), "{}", text(&o));

    let out = dir.join("killed.exr");
    let checkpoint = dir.join("killed.exr.checkpoint");
    let mut child = bin()
        .args([&render_args(&scene, integrator, spp, &out)[..], &["--checkpoint-every", "0"][..]].concat())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for_checkpoint(&mut child, &checkpoint, 8);
    child.kill().unwrap(); // SIGKILL: no chance to clean up
    child.wait().unwrap();
    assert!(!out.exists(), "the render was killed before it finished");
    let kept = checkpoint_spp(&checkpoint);
    assert!(kept >= 8 && kept < spp.parse::<u32>().unwrap(), "checkpoint of {kept} spp");

    let o = zvidpt(&[&render_args(&scene, integrator, spp, &out)[..], &["--resume"][..]].concat());
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("resuming"), "{}", text(&o));
    assert_same_bits(&out, &whole, &format!("{integrator} resumed"));
    assert!(!checkpoint.exists(), "a finished render removes its checkpoint");
    let (_, meta) = read_exr(&out).unwrap();
    assert!(meta.get("resumed_at_spp").is_some_and(|n| n.parse::<u32>().unwrap() >= kept));
}

#[test]
fn path_killed_and_resumed_is_bit_identical() {
    killed_and_resumed("path", "1024");
}

#[test]
fn learned_killed_and_resumed_is_bit_identical() {
    // Training iterations are rebuilt from scratch on resume, and must match the checkpoint's.
    killed_and_resumed("zvidpt", "256");
}

/// Sends `signal` once the render has finished a pass (it says so in a JSON line).
/// Runs `zvidpt` with `args` (which ask for `--progress-json`), sends it `signal` once it has
/// reported two passes, and returns its exit code and the lines it wrote after that.
fn signal_after_two_passes(args: &[&str], signal: &str) -> (Option<i32>, Vec<String>) {
    let mut child = bin().args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let mut passes = 0;
    while passes < 2 {
        let line = lines.next().expect("the render reports its passes").unwrap();
        passes += usize::from(line.contains("\"event\":\"pass\""));
    }
    send_signal(child.id(), signal);
    let rest: Vec<String> = lines.map(Result::unwrap).collect();
    (child.wait().unwrap().code(), rest)
}

fn signalled(signal: &str, code: i32) {
    let dir = scratch("resume", &format!("signal-{signal}"));
    let scene = scene();
    let whole = dir.join("whole.exr");
    let o = zvidpt(&[&render_args(&scene, "path", "1024", &whole)[..], &["--no-checkpoint"][..]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let out = dir.join("stopped.exr");
    let checkpoint = dir.join("stopped.exr.checkpoint");
    // No checkpoint before the signal: the one it writes is the only one.
    let args = [&render_args(&scene, "path", "1024", &out)[..], &["--progress-json"][..]].concat();
    let (status, rest) = signal_after_two_passes(&args, signal);
    assert_eq!(status, Some(code), "{signal}: {rest:?}");
    assert!(rest.iter().any(|l| l.contains("kept in")), "{rest:?}");
    assert!(!out.exists());
    assert!(checkpoint_spp(&checkpoint) >= 8);
    assert_eq!(hidden_files(&dir), Vec::<String>::new(), "temporary files left behind");
    let o = zvidpt(&[&render_args(&scene, "path", "1024", &out)[..], &["--resume"][..]].concat());
    assert!(o.status.success(), "{}", text(&o));
    assert_same_bits(&out, &whole, signal);
}

/// SIGTERM during the pre-pass (the learned integrator's training), before any checkpoint
/// exists: exit 143 with a line saying what was kept, and no file left behind.
#[test]
fn sigterm_during_training_says_what_was_kept() {
    let dir = scratch("resume", "signal-training");
    let scene = scene();
    let out = dir.join("stopped.exr");
    let mut args = render_args(&scene, "zvidpt", "4096", &out);
    args.extend(["--train-spp", "4000", "--progress-json"]);
    let mut child = bin().args(&args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    while !lines.next().expect("the render reports its pre-pass").unwrap().contains("\"event\":\"prepass\"") {}
    send_signal(child.id(), "TERM");
    let rest: Vec<String> = lines.map(Result::unwrap).collect();
    assert_eq!(child.wait().unwrap().code(), Some(143), "{rest:?}");
    assert!(rest.iter().any(|l| l.contains("during the pre-pass") && l.contains("checkpoint")), "{rest:?}");
    assert!(!out.exists());
    assert_eq!(hidden_files(&dir), Vec::<String>::new(), "temporary files left behind");
}

#[test]
fn sigterm_writes_the_checkpoint_and_exits_143() {
    signalled("TERM", 143);
}

#[test]
fn sigint_writes_the_checkpoint_and_exits_130() {
    signalled("INT", 130);
}

#[test]
fn a_checkpoint_continues_only_its_own_render() {
    let dir = scratch("resume", "refuse");
    let scene = scene();
    let out = dir.join("a.exr");
    let checkpoint = dir.join("a.exr.checkpoint");
    let mut child = bin()
        .args([&render_args(&scene, "path", "4096", &out)[..], &["--checkpoint-every", "0"][..]].concat())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for_checkpoint(&mut child, &checkpoint, 4);
    child.kill().unwrap();
    child.wait().unwrap();
    let before = std::fs::read(&checkpoint).unwrap();
    // Another seed: refused, and the checkpoint stays.
    let mut args = render_args(&scene, "path", "4096", &out);
    args[7] = "8";
    args.push("--resume");
    let o = zvidpt(&args);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("seed 7 there, 8 here"), "{}", text(&o));
    assert_eq!(std::fs::read(&checkpoint).unwrap(), before);
    // A checkpoint is not a part to merge.
    let o = zvidpt(&["merge", "-o", s(&dir.join("m.exr")), "--no-png", s(&checkpoint)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("checkpoint of an unfinished part"), "{}", text(&o));
    // A file that is not a checkpoint is never replaced by one.
    let precious = dir.join("notes.txt");
    std::fs::write(&precious, "mine").unwrap();
    let o = zvidpt(&[&render_args(&scene, "path", "4", &out)[..], &["--checkpoint", s(&precious)][..]].concat());
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o).contains("not a zvidpt checkpoint"), "{}", text(&o));
    assert_eq!(std::fs::read(&precious).unwrap(), b"mine");
}

#[test]
fn an_interrupted_batch_continues_when_run_again() {
    let dir = scratch("resume", "batch");
    let scene = scene();
    let jobs = dir.join("jobs.toml");
    let job = |name: &str| {
        format!(
            "[[job]]\nscene = \"{scene}\"\noutput = \"{name}.exr\"\nintegrator = \"path\"\nspp = 1024\nseed = 7\n\
             resolution = \"32x24\"\nno_png = true\ncheckpoint_every = 0\n"
        )
    };
    std::fs::write(&jobs, format!("{}{}", job("one"), job("two"))).unwrap();
    let whole = dir.join("whole.exr");
    let o = zvidpt(&[&render_args(&scene, "path", "1024", &whole)[..], &["--no-checkpoint"][..]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let checkpoint = dir.join("one.exr.checkpoint");
    let mut child = bin().args(["batch", s(&jobs)]).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    wait_for_checkpoint(&mut child, &checkpoint, 8);
    send_signal(child.id(), "TERM");
    assert_eq!(child.wait().unwrap().code(), Some(143));
    assert!(!dir.join("two.exr").exists(), "no job starts after SIGTERM");
    assert!(!dir.join("summary.csv").exists());
    let o = zvidpt(&["batch", s(&jobs)]);
    assert!(o.status.success(), "{}", text(&o));
    assert_same_bits(&dir.join("one.exr"), &whole, "the resumed job");
    assert_same_bits(&dir.join("two.exr"), &whole, "the next job");
    assert!(!checkpoint.exists());
}

/// A render to a noise target, stopped by SIGTERM and resumed, stops at the same pass as one
/// run straight through: the same bits (the target's rule reads the restored sums).
#[test]
fn a_render_to_a_noise_target_resumes_to_the_same_stop() {
    resumed_to_the_same_stop("noise-target", &["--noise-target", "0.1"]);
}

/// The same with adaptive sampling: the checkpoint (taken after two passes, when pixels
/// judged from 4 samples on already hold different counts) keeps each pixel's sample count,
/// and the resumed render stops every pixel where the uninterrupted one did (the same bits,
/// the per-pixel counts in the `spp` layer included).
#[test]
fn an_adaptive_render_resumes_to_the_same_stop() {
    resumed_to_the_same_stop("adaptive", &["--noise-target", "0.1", "--adaptive", "--min-spp", "4"]);
}

fn resumed_to_the_same_stop(name: &str, flags: &[&str]) {
    let dir = scratch("resume", name);
    let scene = scene();
    let target = [flags, &["--progress-json"][..]].concat();
    let whole = dir.join("whole.exr");
    let o =
        zvidpt(&[&render_args(&scene, "path", "1000000", &whole)[..], &target[..], &["--no-checkpoint"][..]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let out = dir.join("stopped.exr");
    let args = [&render_args(&scene, "path", "1000000", &out)[..], &target[..]].concat();
    let (status, rest) = signal_after_two_passes(&args, "TERM");
    assert_eq!(status, Some(143), "{rest:?}");
    assert!(!out.exists());
    let o = zvidpt(&[&render_args(&scene, "path", "1000000", &out)[..], &target[..], &["--resume"][..]].concat());
    assert!(o.status.success(), "{}", text(&o));
    assert_same_bits(&out, &whole, name);
    if flags.contains(&"--adaptive") {
        let layer = |p: &std::path::Path| {
            zvidpt::film::read_exr_with(p, &["spp"]).unwrap().2.into_iter().next().flatten().expect("an spp layer")
        };
        let (a, b) = (layer(&out), layer(&whole));
        assert_eq!(a, b);
        assert!(a.iter().any(|&n| n != a[0]), "every pixel took the same samples");
    }
}
