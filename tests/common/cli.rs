//! Helpers for the tests that run the `zvidpt` binary.
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `zvidpt ARGS` to completion.
pub fn zvidpt(args: &[&str]) -> Output {
    bin().args(args).output().expect("binary runs")
}

/// The `zvidpt` binary as a command (no backtraces in its error lines).
pub fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_zvidpt"));
    c.env_remove("RUST_BACKTRACE");
    c
}

/// An empty folder `zvidpt-TEST-NAME-PID` in the temporary folder, removed with what it
/// holds when the test ends (passed or failed).
pub fn scratch(test: &str, name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("zvidpt-{test}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    Scratch(d)
}

/// A test's scratch folder ([`scratch`]): a path, removed when dropped.
#[derive(Debug)]
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for Scratch {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Standard output and error together, for assertion messages.
pub fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// An EXR's pixels and variances as bits.
pub fn bits(path: &Path) -> Vec<u32> {
    let (img, _) = zvidpt::film::read_exr(path).unwrap();
    img.pixels.iter().chain(img.variance.as_ref().unwrap()).flat_map(|p| p.map(f32::to_bits)).collect()
}

/// Sends `signal` (`TERM`, `INT`, …) to process `pid` through the shell's `kill` builtin
/// (`/bin/kill` comes from procps, which a minimal Debian lacks; `sh` is always there).
pub fn send_signal(pid: u32, signal: &str) {
    let status = Command::new("sh").arg("-c").arg(format!("kill -{signal} {pid}")).status().expect("sh runs");
    assert!(status.success(), "kill -{signal} {pid} failed");
}
