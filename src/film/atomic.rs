//! Output files appear whole or not at all: they are written to a temporary file in the same
//! folder and renamed over the destination.
use crate::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

fn temporary_path(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Writes `path` through `write`, atomically. On any error the temporary file is removed and
/// the destination is left as it was.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> Result<()>,
) -> Result<()> {
    if path.is_dir() {
        return Err(Error::io(path, std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a directory")));
    }
    let tmp = temporary_path(path);
    let file = std::fs::File::create(&tmp).map_err(|e| Error::io(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    let result = write(&mut w)
        .and_then(|()| w.flush().map_err(|e| Error::io(path, e)))
        .and_then(|()| w.get_ref().sync_all().map_err(|e| Error::io(path, e)))
        .and_then(|()| std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Fails early, before a long render, if `path` cannot be written (its folder is missing or
/// read-only, or it names a folder). Leaves nothing behind.
pub fn check_writable(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::io(path, std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a directory")));
    }
    let tmp = temporary_path(path);
    std::fs::File::create(&tmp).map_err(|e| Error::io(path, e))?;
    let _ = std::fs::remove_file(&tmp);
    Ok(())
}
