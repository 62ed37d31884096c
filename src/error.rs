//! The library's error type. Every variant names what failed and where, so that the binary can
//! print one line that a user can act on.
use std::path::PathBuf;

/// Everything that can go wrong while loading a scene, rendering or writing images.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read, created or renamed.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// An output may not be written where the user asked (it is a link, a device, read-only,
    /// or the same file as another output or an input of the command).
    #[error("{path}: {message}")]
    Output { path: PathBuf, message: String },
    /// The scene file is not valid TOML or does not match the scene schema (unknown keys too).
    #[error("{path}: {message}")]
    SceneSyntax { path: PathBuf, message: String },
    /// The scene parses but describes something we cannot render.
    #[error("{path}: {message}")]
    InvalidScene { path: PathBuf, message: String },
    /// An OBJ or MTL file could not be loaded.
    #[error("{path}: {message}")]
    Mesh { path: PathBuf, message: String },
    /// An EXR or PNG could not be encoded or decoded.
    #[error("{path}: {message}")]
    Image { path: PathBuf, message: String },
    /// A render option is out of range.
    #[error("{0}")]
    InvalidOption(String),
    /// A ray-tracing backend failed or is not available in this build.
    #[error("{0}")]
    Backend(String),
    /// The denoiser (Open Image Denoise) is missing or failed.
    #[error("{0}")]
    Denoiser(String),
    /// SIGINT or SIGTERM stopped the work; what was kept (a checkpoint) is said in `message`.
    #[error("{message}")]
    Interrupted { signal: i32, message: String },
}

/// Shorthand used throughout the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }

    /// Whether this is a write to a pipe whose reader has gone (`zvidpt … | head`): the
    /// command line treats it as a normal end, not a failure.
    #[must_use]
    pub fn is_broken_pipe(&self) -> bool {
        matches!(self, Error::Io { source, .. } if source.kind() == std::io::ErrorKind::BrokenPipe)
    }
}
