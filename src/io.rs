//! Bounded file reads: every reader of user files goes through them, so a FIFO, a device or
//! a file larger than its limit is a clear error, never a hang or an abort.
use crate::{Error, Result};
use std::path::Path;

/// Opens `path` for reading if it is a regular file, without ever blocking: the file is
/// opened non-blocking (opening a FIFO for reading would wait for a writer, forever) and its
/// kind checked on the open file itself (no window for it to be swapped after a check).
/// `what` names it in the error.
pub fn open_regular(path: &Path, what: &str) -> Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt as _;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        let article = if what.starts_with(['a', 'e', 'i', 'o', 'u', 'A', 'E', 'I', 'O', 'U']) { "an" } else { "a" };
        return Err(Error::io(
            path,
            std::io::Error::other(format!("not a regular file ({article} {what} must be one)")),
        ));
    }
    Ok(file)
}

/// Reads a whole file after checking that it is a regular file (a FIFO or device would hang
/// or never end) of at most `limit` bytes. `what` names it in the error.
pub fn read_bounded(path: &Path, limit: u64, what: &str) -> Result<Vec<u8>> {
    use std::io::Read as _;
    let file = open_regular(path, what)?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    let too_big = |size: u64| {
        Error::io(path, std::io::Error::other(format!("{size} bytes: larger than the {limit}-byte limit for a {what}")))
    };
    if meta.len() > limit {
        return Err(too_big(meta.len()));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_big(bytes.len() as u64));
    }
    Ok(bytes)
}

/// Reads a text file with [`read_bounded`]; a byte sequence that is not UTF-8 is reported
/// with its line.
pub fn read_text(path: &Path, limit: u64, what: &str) -> Result<String> {
    let bytes = read_bounded(path, limit, what)?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count() + 1;
        Error::io(path, std::io::Error::other(format!("line {line}: not UTF-8 text: is this a {what}?")))
    })
}

/// A size in bytes for a message: MiB below a GiB, else GiB with one decimal.
#[must_use]
pub fn human_bytes(bytes: u64) -> String {
    if bytes < 1 << 30 {
        format!("{} MiB", bytes.div_ceil(1 << 20))
    } else {
        format!("{:.1} GiB", bytes as f64 / f64::from(1u32 << 30))
    }
}

/// Bytes this process may still allocate, where the system says: the smaller of the
/// memory the kernel reports available (`MemAvailable`) and what is left of the address-space
/// limit (`ulimit -v`) beyond the process's present size. `None` where neither is known.
#[must_use]
pub fn memory_available() -> Option<u64> {
    let field = |text: &str, name: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(name))?;
        line.split_whitespace().nth(1)?.parse::<u64>().ok().map(|kib| kib * 1024)
    };
    let available = std::fs::read_to_string("/proc/meminfo").ok().and_then(|t| field(&t, "MemAvailable:"));
    let headroom = std::fs::read_to_string("/proc/self/limits").ok().and_then(|limits| {
        let line = limits.lines().find(|l| l.starts_with("Max address space"))?;
        let limit: u64 = line.split_whitespace().nth(3)?.parse().ok()?;
        let size = std::fs::read_to_string("/proc/self/status").ok().and_then(|t| field(&t, "VmSize:"))?;
        Some(limit.saturating_sub(size))
    });
    match (available, headroom) {
        (Some(a), Some(h)) => Some(a.min(h)),
        (a, h) => a.or(h),
    }
}

/// The memory left, where it is known and less than `need` bytes: a buffer of `need` bytes
/// would not fit (an allocation that fails aborts the process, so callers refuse first).
#[must_use]
pub fn memory_short_of(need: u64) -> Option<u64> {
    memory_available().filter(|&free| need > free)
}

/// The process's peak resident memory (Linux's `VmHWM`), where the system reports it.
#[must_use]
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
