//! Checkpoints: a render's exact per-pixel sums so far, written atomically every few seconds
//! (and when SIGINT or SIGTERM arrives), from which `zvidpt render --resume` continues.
//!
//! A checkpoint is a partial render ([`crate::film::stage_sums`]) of samples `first..done`,
//! with the render's description in its metadata. Because the sums are exact integers and each
//! sample's random numbers depend only on (seed, pixel, sample index), the resumed render ends
//! with the same sums, bit for bit, as one that was never stopped.
//!
//! The pre-pass is not stored: a photon map and a learned guide are functions of the scene,
//! the options, the seed and (for a learning integrator) the number of training iterations,
//! which the checkpoint keeps. The resumed render rebuilds them and checks that the training
//! samples in the image come out identical to the checkpoint's.
use crate::film::{self, Metadata};
use crate::film::{Partial, PixelSums, PriorSamples};
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// Metadata key marking a partial file as a checkpoint.
const MARK: &str = "checkpoint";
/// Seconds the render had run when the checkpoint was written (over all its runs).
const SECONDS: &str = "checkpoint_seconds";
/// Training iterations of a learning integrator's pre-pass.
const TRAINING: &str = "training_iterations";

/// How a render keeps a checkpoint.
#[derive(Clone, Debug)]
pub struct CheckpointSettings {
    /// The checkpoint file.
    pub path: PathBuf,
    /// Seconds between checkpoints (0: after every pass).
    pub interval: f64,
    /// What is rendered (scene hash, integrator, options, seed, budget): written into the
    /// checkpoint and compared on resume.
    pub meta: Metadata,
    /// An earlier run's checkpoint to continue.
    pub resume: Option<Resume>,
}

/// A checkpoint read back.
#[derive(Clone, Debug)]
pub struct Resume {
    /// The sums rendered so far.
    pub part: Partial,
    /// Seconds the render had run (a time budget continues with what is left).
    pub seconds: f64,
    /// Training iterations the pre-pass ran, for a learning integrator to run again.
    pub training_iterations: Option<u32>,
}

impl Resume {
    /// Reads the checkpoint at `path`, checking that it belongs to the render `meta`
    /// describes.
    pub fn read(path: &Path, meta: &Metadata) -> Result<Resume> {
        let (part, found) = film::read_partial(path)?;
        if found.get(MARK).is_none() {
            return Err(Error::InvalidOption(format!(
                "{}: a partial render (zvidpt merge's input), not a checkpoint",
                path.display()
            )));
        }
        // Both ways: a key of the checkpoint's render that this one lacks (a flag that applies
        // to one integrator only) differs too.
        let extra = found
            .entries
            .iter()
            .filter(|(k, _)| ![MARK, SECONDS, TRAINING].contains(&k.as_str()) && meta.get(k).is_none())
            .map(|(k, _)| (k.clone(), "(none)".to_string()));
        for (key, want) in meta.entries.iter().cloned().chain(extra) {
            let have = found.get(&key).unwrap_or("(none)");
            if have != want {
                return Err(Error::InvalidOption(format!(
                    "{} is the checkpoint of another render ({key} {have} there, {want} here); \
                     render without --resume to start over",
                    path.display()
                )));
            }
        }
        let seconds = found.get(SECONDS).and_then(|s| s.parse::<f64>().ok()).filter(|s| s.is_finite() && *s >= 0.0);
        let training_iterations = match found.get(TRAINING) {
            None => None,
            Some(t) => Some(t.parse::<u32>().ok().filter(|&t| t <= 16).ok_or_else(|| bad(path, TRAINING))?),
        };
        Ok(Resume { part, seconds: seconds.ok_or_else(|| bad(path, SECONDS))?, training_iterations })
    }
}

fn bad(path: &Path, key: &str) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: format!("not a zvidpt checkpoint (its {key} is missing or wrong)"),
    }
}

/// Whether `path` holds a checkpoint (its header alone is read: the command line checks this
/// before reading a resumed checkpoint whole).
pub fn is_checkpoint(path: &Path) -> bool {
    film::read_partial_header(path).is_ok_and(|(_, m)| m.get(MARK).is_some())
}

/// What a checkpoint records besides its sums.
pub(super) struct Progress {
    pub first: u32,
    pub done: u32,
    pub total_spp: u32,
    pub seconds: f64,
    pub training_iterations: Option<u32>,
}

/// Writes a checkpoint of `sums` (pixel `j` row-major), replacing the previous one at once.
pub(super) fn write(
    settings: &CheckpointSettings,
    size: (u32, u32),
    progress: &Progress,
    sums: impl Fn(usize) -> ([i128; 3], [i128; 3]),
    prior: Option<&PriorSamples>,
    counts: Option<&[u32]>,
) -> Result<()> {
    let mut meta = settings.meta.clone();
    meta.push(MARK, 1);
    meta.push(SECONDS, format!("{:.3}", progress.seconds));
    if let Some(t) = progress.training_iterations {
        meta.push(TRAINING, t);
    }
    let header = [size.0, size.1, progress.first, progress.done - progress.first, progress.total_spp];
    film::commit(vec![film::stage_sums(&settings.path, &meta, header, sums, prior, counts)?])
}

/// Checks that a checkpoint fits this render (size, sample range, training samples).
pub(super) fn check_fits(
    resume: &Resume,
    path: &Path,
    size: (u32, u32),
    first: u32,
    total_spp: u32,
    prior: Option<&PriorSamples>,
) -> Result<()> {
    let p = &resume.part;
    let PixelSums { width, height, .. } = p.sums;
    let fail = |what: String| Err(Error::InvalidOption(format!("{}: {what}", path.display())));
    if (width, height) != size {
        return fail(format!("the checkpoint is {width}x{height}, the render {}x{}", size.0, size.1));
    }
    if p.first != first || p.total_spp != total_spp {
        return fail("the checkpoint is of another sample range".into());
    }
    if p.prior.as_ref() != prior {
        return fail(
            "the rebuilt pre-pass does not match the checkpoint's (its training samples differ); \
             render without --resume to start over"
                .into(),
        );
    }
    Ok(())
}
