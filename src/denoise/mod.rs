//! Denoising with Intel Open Image Denoise 2.x (`RT` filter, HDR), loaded at run time, so the
//! binary builds and runs without it and says in one line how to get it where it is missing.
//!
//! The auxiliary images are prefiltered as OIDN recommends for final frames: the albedo and
//! the normal each by their own `RT` filter, then the beauty with both and `cleanAux` set. The
//! denoised image is an approximation (biased, by design): it is always written beside the
//! noisy estimate, never in its place.
// The library's entry points: every public item documented (`cargo doc`).
#![warn(missing_docs)]
mod oidn;

use crate::{Error, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The library's file name on this platform (its 2.x ABI).
#[cfg(target_os = "macos")]
const LIBRARY: &str = "libOpenImageDenoise.2.dylib";
#[cfg(target_os = "windows")]
const LIBRARY: &str = "OpenImageDenoise.dll";
#[cfg(not(any(target_os = "macos", target_os = "windows")))]
const LIBRARY: &str = "libOpenImageDenoise.so.2";

/// How to get the library, for the error where it is missing.
pub const HOW_TO_GET: &str = "`pip install pyoidn` (its wheel ships Open Image Denoise 2 with the CPU device), or set OIDN_DIR to the folder holding";

/// A denoised image and what it took.
#[derive(Clone, Debug)]
pub struct Denoised {
    /// Row-major RGB.
    pub pixels: Vec<[f32; 3]>,
    /// Seconds the filters took (prefiltering included; loading the library not).
    pub seconds: f64,
    /// The library used.
    pub library: PathBuf,
    /// Which auxiliary images guided it: `albedo+normal`, `albedo` or `none`.
    pub guided_by: &'static str,
}

impl Denoised {
    /// The filter that made it, as the image's metadata names it.
    #[must_use]
    pub fn filter(&self) -> String {
        format!("Open Image Denoise RT, hdr, cleanAux, guided by {}", self.guided_by)
    }
}

/// Where to look for the library, in order: `OIDN_DIR` (the file itself, or a folder holding
/// it or a `lib/` holding it), the system's loader path (by name), and `pyoidn`'s wheel (found
/// by asking `python3` where the package lives).
#[must_use]
pub fn candidates() -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Some(dir) = std::env::var_os("OIDN_DIR").map(PathBuf::from) {
        if dir.is_file() {
            out.push(dir.clone());
        }
        out.push(dir.join(LIBRARY));
        out.push(dir.join("lib").join(LIBRARY));
    }
    out.push(PathBuf::from(LIBRARY));
    if let Some(p) = pyoidn_folder() {
        out.push(p.join("oidn").join("lib").join(LIBRARY));
    }
    out
}

/// The folder of the `pyoidn` package, if `python3` has one (without importing it).
fn pyoidn_folder() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args(["-c", "import importlib.util as u; s = u.find_spec('pyoidn'); print(s.submodule_search_locations[0] if s else '')"])
        .stdin(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .output()
        .ok()?;
    let text = String::from_utf8(out.stdout).ok()?;
    let dir = text.trim();
    (out.status.success() && !dir.is_empty()).then(|| PathBuf::from(dir))
}

/// Denoises with Open Image Denoise.
pub struct Denoiser {
    oidn: oidn::Oidn,
}

impl Denoiser {
    /// Loads the first library of [`candidates`] that opens a CPU device, on `threads` threads
    /// (`None`: all cores).
    pub fn load(threads: Option<usize>) -> Result<Self> {
        let mut tried = Vec::new();
        for path in candidates() {
            // A bare name is the loader's to find; a path must exist.
            if path.components().count() > 1 && !path.exists() {
                continue;
            }
            match oidn::Oidn::load(&path, threads.unwrap_or(0)) {
                Ok(oidn) => return Ok(Self { oidn }),
                Err(e) => tried.push(format!("{}: {e}", path.display())),
            }
        }
        let tried = if tried.is_empty() { String::new() } else { format!(" (tried {})", tried.join("; ")) };
        Err(Error::Denoiser(format!("Open Image Denoise 2 is not installed: {HOW_TO_GET} {LIBRARY}{tried}")))
    }

    /// The library in use.
    #[must_use]
    pub fn library(&self) -> &Path {
        &self.oidn.path
    }

    /// Denoises `color` (`width × height`, row-major, linear HDR) guided by the first-hit
    /// `albedo` and `normal` where given (a normal needs an albedo, as OIDN's `RT` filter
    /// does). Negative and non-finite values (an unbiased estimator's signed samples) enter
    /// the filter as 0.
    pub fn denoise(
        &self,
        width: u32,
        height: u32,
        color: &[[f32; 3]],
        albedo: Option<&[[f32; 3]]>,
        normal: Option<&[[f32; 3]]>,
    ) -> Result<Denoised> {
        use oidn::Image::{Input, Output};
        let (w, h) = (width as usize, height as usize);
        let n = w * h;
        let sizes_match =
            color.len() == n && albedo.is_none_or(|a| a.len() == n) && normal.is_none_or(|a| a.len() == n);
        if !sizes_match {
            return Err(Error::Denoiser(format!("the beauty and its auxiliary images are not all {width}x{height}")));
        }
        let fail = |e: String| Error::Denoiser(e);
        let start = Instant::now();
        let clean = |v: &[[f32; 3]], lo: f32| -> Vec<[f32; 3]> {
            v.iter().map(|p| p.map(|c| if c.is_finite() { c.max(lo) } else { 0.0 })).collect()
        };
        let beauty = clean(color, 0.0);
        // The auxiliary images, each denoised by itself first (OIDN's recommended prefilter).
        let prefilter = |name: &'static std::ffi::CStr, image: &[[f32; 3]]| -> Result<Vec<[f32; 3]>> {
            let mut out = vec![[0.0f32; 3]; n];
            self.oidn.run("RT", w, h, &mut [Input(name, image), Output(c"output", &mut out)], &[]).map_err(fail)?;
            Ok(out)
        };
        let albedo = albedo.map(|a| prefilter(c"albedo", &clean(a, 0.0))).transpose()?;
        let normal = match (&albedo, normal) {
            (Some(_), Some(nrm)) => Some(prefilter(c"normal", &clean(nrm, -1.0))?),
            _ => None,
        };
        let mut out = vec![[0.0f32; 3]; n];
        let mut images = vec![Input(c"color", &beauty)];
        if let Some(a) = &albedo {
            images.push(Input(c"albedo", a));
        }
        if let Some(nrm) = &normal {
            images.push(Input(c"normal", nrm));
        }
        images.push(Output(c"output", &mut out));
        let flags = [(c"hdr", true), (c"cleanAux", albedo.is_some())];
        self.oidn.run("RT", w, h, &mut images, &flags).map_err(fail)?;
        let guided_by = match (&albedo, &normal) {
            (Some(_), Some(_)) => "albedo+normal",
            (Some(_), None) => "albedo",
            _ => "none",
        };
        Ok(Denoised {
            pixels: out,
            seconds: start.elapsed().as_secs_f64(),
            library: self.library().to_path_buf(),
            guided_by,
        })
    }
}
