//! Interruption by SIGINT or SIGTERM, as the binary's signal thread reports it. A render that
//! keeps a checkpoint holds a [`Watch`] while it samples: the first signal then only sets a
//! flag, and the render writes its checkpoint after the pass in progress and returns
//! [`crate::Error::Interrupted`]. Without a watching render the signal thread exits at once.
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering};

/// The signal received (0: none).
static SIGNAL: AtomicI32 = AtomicI32::new(0);
/// Renders watching for a signal right now.
static WATCHERS: AtomicUsize = AtomicUsize::new(0);
/// Whether a render that keeps checkpoints is in its pre-pass (training) right now.
static IN_PREPASS: AtomicBool = AtomicBool::new(false);

/// What an interruption keeps right now, if the signal thread must say it: during the
/// pre-pass of a render that keeps checkpoints, the first checkpoint is not yet written.
#[must_use]
pub fn note() -> Option<&'static str> {
    IN_PREPASS.load(Ordering::SeqCst).then_some(
        "interrupted during the pre-pass (training): no new checkpoint was written (the first comes \
         after it); a checkpoint from an earlier run is kept unchanged, and --resume redoes the pre-pass",
    )
}

/// Held while a render that keeps checkpoints runs its pre-pass (see [`note`]).
#[derive(Debug)]
pub struct Prepass(());

impl Prepass {
    /// Marks the pre-pass as running until dropped.
    #[must_use]
    pub fn new() -> Self {
        IN_PREPASS.store(true, Ordering::SeqCst);
        Prepass(())
    }
}

impl Default for Prepass {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for Prepass {
    fn drop(&mut self) {
        IN_PREPASS.store(false, Ordering::SeqCst);
    }
}

/// Records `signal`; returns whether a watching render will act on it (if not, the caller
/// should exit now).
pub fn request(signal: i32) -> bool {
    SIGNAL.store(signal, Ordering::SeqCst);
    WATCHERS.load(Ordering::SeqCst) > 0
}

/// The signal received, if any.
#[must_use]
pub fn requested() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// Held by a render that writes a checkpoint when interrupted.
#[derive(Debug)]
pub struct Watch(());

impl Watch {
    /// Registers a render that wants a checkpoint on interruption.
    #[must_use]
    pub fn new() -> Self {
        WATCHERS.fetch_add(1, Ordering::SeqCst);
        Watch(())
    }
}

impl Default for Watch {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for Watch {
    fn drop(&mut self) {
        WATCHERS.fetch_sub(1, Ordering::SeqCst);
    }
}
