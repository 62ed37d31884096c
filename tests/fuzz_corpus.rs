//! Replays every fuzz corpus and crash reproducer (`fuzz/corpus/TARGET`, `fuzz/artifacts/
//! TARGET`) through the same entry points the fuzz targets call: none may panic. Fuzzing
//! itself (coverage-guided, libFuzzer via cargo-fuzz on stable with `-s none`) is described
//! in docs/cli.md ("Errors and limits", fuzzing).
use std::path::Path;

fn replay(target: &str, run: fn(&[u8])) -> usize {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut n = 0;
    for dir in [root.join("corpus").join(target), root.join("artifacts").join(target)] {
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        let mut files: Vec<_> = entries.map(|e| e.unwrap().path()).filter(|p| p.is_file()).collect();
        files.sort();
        for f in files {
            // (A fuzzer running meanwhile may replace corpus files.)
            let Ok(data) = std::fs::read(&f) else { continue };
            let result = std::panic::catch_unwind(|| run(&data));
            assert!(result.is_ok(), "{target}: {} panics", f.display());
            n += 1;
        }
    }
    n
}

#[test]
fn scene_corpus() {
    assert!(replay("scene_toml", zvidpt::fuzzing::scene_toml) >= 5);
}

#[test]
fn obj_corpus() {
    assert!(replay("obj", zvidpt::fuzzing::obj) >= 3);
}

#[test]
fn pbrt_corpus() {
    assert!(replay("pbrt", zvidpt::fuzzing::pbrt) >= 5);
}

#[test]
fn mitsuba_corpus() {
    assert!(replay("mitsuba", zvidpt::fuzzing::mitsuba) >= 5);
}

#[test]
fn ply_corpus() {
    assert!(replay("ply", zvidpt::fuzzing::ply) >= 3);
}

#[test]
fn exr_metadata_corpus() {
    assert!(replay("exr_metadata", zvidpt::fuzzing::exr_metadata) >= 3);
}

#[test]
fn exr_corpus() {
    assert!(replay("exr", zvidpt::fuzzing::exr) >= 1);
}

#[test]
fn image_corpus() {
    assert!(replay("image", zvidpt::fuzzing::image) >= 4);
}

#[test]
fn cli_corpus() {
    assert!(replay("cli", zvidpt::fuzzing::cli) >= 5);
}

#[test]
fn slurm_script_corpus() {
    assert!(replay("slurm_script", zvidpt::fuzzing::slurm_script) >= 3);
}
