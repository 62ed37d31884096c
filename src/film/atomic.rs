//! Output files appear whole or not at all, and only where the user asked for them.
//!
//! Each file is written to a temporary file in its destination's folder, flushed and synced
//! (*staged*); then all files of one command are renamed into place together (*committed*).
//! If any stage or rename fails, every destination is left as it was (replaced files are
//! restored from a backup taken by rename) and no temporary file stays behind. Temporary
//! files in flight are registered, so a signal handler can remove them
//! ([`remove_pending_files`]); a commit holds the registry's lock, so a signal waits for it
//! to finish and never leaves a new EXR beside a stale PNG.
//!
//! A destination that exists must be a regular, writable file: the rename would otherwise
//! replace a symbolic link (not its target), a device node, a FIFO or a read-only file.
use crate::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Temporary and backup files that exist right now (removed by [`remove_pending_files`]).
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Creates `path` as a registered temporary file. Registry and creation happen under one
/// lock: a signal handler either runs first (and the file is never created) or sees it.
fn create_registered(path: &Path) -> std::io::Result<std::fs::File> {
    let mut list = pending();
    list.push(path.to_path_buf());
    std::fs::File::create(path)
}

fn unregister(list: &mut Vec<PathBuf>, path: &Path) {
    if let Some(i) = list.iter().position(|p| p == path) {
        list.swap_remove(i);
    }
}

/// Removes every temporary file this process has in flight and returns how many. For a
/// signal handler: it waits for a commit in progress (backups exist only within one), so
/// the outputs stay consistent, and it keeps the registry locked, so no new file starts.
pub fn remove_pending_files() -> usize {
    let mut list = pending();
    let n = list.len();
    for p in list.drain(..) {
        let _ = std::fs::remove_file(&p);
    }
    // Keep the lock: the process is about to exit and must not start another file.
    std::mem::forget(list);
    n
}

/// The part of a temporary file's name that stands for its destination: the name itself, or
/// for a long one (whose temporary name would pass the file system's 255 bytes) its first 150
/// bytes and a hash of the whole.
fn stem(path: &Path) -> String {
    let name = path.file_name().map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    if name.len() <= 200 {
        return name;
    }
    let mut cut = 150;
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    format!("{}~{hash:016x}", &name[..cut])
}

/// This machine's name (several machines may write into one shared folder: a Slurm array).
fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname").map_or_else(|_| "host".into(), |h| h.trim().to_string())
}

/// A temporary sibling of `path` owned by this process: `.NAME.HOST-PID.SUFFIX`.
fn sibling(path: &Path, suffix: &str) -> PathBuf {
    path.with_file_name(format!(".{}.{}-{}.{suffix}", stem(path), host(), std::process::id()))
}

/// Removes temporary and backup siblings of `path` left by processes of this machine that
/// no longer run (a render killed by SIGKILL or a power cut cannot remove its own); those of
/// live processes and of other machines stay.
fn remove_stale_siblings(path: &Path) {
    let Some(dir) = path.parent().map(|d| if d.as_os_str().is_empty() { Path::new(".") } else { d }) else {
        return;
    };
    let prefix = format!(".{}.{}-", stem(path), host());
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(&prefix) else { continue };
        let Some((pid, suffix)) = rest.split_once('.') else { continue };
        let (Ok(pid), true) = (pid.parse::<u32>(), matches!(suffix, "tmp" | "bak")) else { continue };
        if pid != std::process::id() && !Path::new("/proc").join(pid.to_string()).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

fn refuse(path: &Path, message: &str) -> Error {
    Error::Output { path: path.to_path_buf(), message: message.to_string() }
}

/// Checks that `path` may be replaced: it does not exist, or it is a regular file the user
/// may write. Symbolic links, folders, devices, FIFOs and sockets are refused.
pub fn check_destination(path: &Path) -> Result<()> {
    if path.as_os_str().is_empty() {
        return Err(refuse(path, "empty output path"));
    }
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::io(path, e)),
        Ok(m) => {
            let t = m.file_type();
            if t.is_symlink() {
                Err(refuse(path, "is a symbolic link; not replacing it (name the file it points to)"))
            } else if t.is_dir() {
                Err(refuse(path, "is a folder"))
            } else if !t.is_file() {
                Err(refuse(path, "is not a regular file (a device, FIFO or socket); not replacing it"))
            } else if m.permissions().readonly() {
                Err(refuse(path, "is read-only; not replacing it"))
            } else {
                Ok(())
            }
        }
    }
}

/// A file written to its temporary sibling, waiting for [`commit`].
#[derive(Debug)]
pub struct Staged {
    tmp: PathBuf,
    dest: PathBuf,
}

impl Drop for Staged {
    fn drop(&mut self) {
        // Not committed (an error elsewhere): the temporary file goes.
        if !self.tmp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.tmp);
            unregister(&mut pending(), &self.tmp);
        }
    }
}

/// Writes `path`'s future content through `write` into a temporary file beside it (flushed
/// and synced). Nothing at `path` changes until [`commit`].
pub fn stage(path: &Path, write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> Result<()>) -> Result<Staged> {
    check_destination(path)?;
    remove_stale_siblings(path);
    let tmp = sibling(path, "tmp");
    let file = create_registered(&tmp);
    let staged = Staged { tmp: tmp.clone(), dest: path.to_path_buf() };
    let file = file.map_err(|e| Error::io(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    write(&mut w)?;
    w.flush().map_err(|e| Error::io(path, e))?;
    w.get_ref().sync_all().map_err(|e| Error::io(path, e))?;
    Ok(staged)
}

/// Moves every staged file into place, together: if one rename fails, the files already
/// moved are taken back and the destinations they replaced restored.
pub fn commit(mut files: Vec<Staged>) -> Result<()> {
    let mut list = pending();
    // Checked again: a destination may have changed while the files were being written.
    for f in &files {
        check_destination(&f.dest)?;
    }
    // (destination, its backup if it existed) for each file moved so far.
    let mut moved: Vec<(PathBuf, Option<PathBuf>)> = Vec::new();
    let mut failure = None;
    for f in &files {
        // One file alone is replaced by one rename, atomic on its own: at every instant the
        // destination holds the old or the new content (a checkpoint survives SIGKILL).
        let backup = if files.len() > 1 && f.dest.exists() {
            let b = sibling(&f.dest, "bak");
            if let Err(e) = std::fs::rename(&f.dest, &b) {
                failure = Some(Error::io(&f.dest, e));
                break;
            }
            list.push(b.clone());
            Some(b)
        } else {
            None
        };
        if let Err(e) = std::fs::rename(&f.tmp, &f.dest) {
            if let Some(b) = &backup {
                let _ = std::fs::rename(b, &f.dest);
                unregister(&mut list, b);
            }
            failure = Some(Error::io(&f.dest, e));
            break;
        }
        moved.push((f.dest.clone(), backup));
    }
    match failure {
        None => {
            for (_, backup) in moved {
                if let Some(b) = backup {
                    let _ = std::fs::remove_file(&b);
                    unregister(&mut list, &b);
                }
            }
            for f in &mut files {
                unregister(&mut list, &f.tmp);
                f.tmp = PathBuf::new();
            }
            Ok(())
        }
        Some(e) => {
            for (dest, backup) in moved.into_iter().rev() {
                let _ = std::fs::remove_file(&dest);
                if let Some(b) = backup {
                    let _ = std::fs::rename(&b, &dest);
                    unregister(&mut list, &b);
                }
            }
            drop(list);
            // Dropping `files` removes the temporary files still left.
            Err(e)
        }
    }
}

/// Writes `path` through `write`, atomically (one file staged and committed).
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> Result<()>,
) -> Result<()> {
    commit(vec![stage(path, write)?])
}

/// Fails early, before a long render, if `path` cannot be written (its folder is missing or
/// read-only, or it is not a regular writable file). Leaves nothing behind.
pub fn check_writable(path: &Path) -> Result<()> {
    check_destination(path)?;
    let tmp = sibling(path, "tmp");
    let result = create_registered(&tmp).map(drop).map_err(|e| Error::io(path, e));
    let _ = std::fs::remove_file(&tmp);
    unregister(&mut pending(), &tmp);
    result
}

/// The identity of a path for comparing outputs and inputs: the same existing file (by
/// device and inode, so hard links and `./a` vs `a` match), or the same name in the same
/// canonical folder.
fn identity(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

fn canonical_name(path: &Path) -> Option<PathBuf> {
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    Some(std::fs::canonicalize(parent).ok()?.join(path.file_name()?))
}

/// A path's one spelling for comparing outputs: its folder resolved (links, `.`, `..`) where
/// it exists, else the path made absolute with `.` and `..` folded lexically. `./a`,
/// `sub/../a` and `LINK/a` (LINK a link to this folder) give the same key.
#[must_use]
pub fn path_key(path: &Path) -> PathBuf {
    if let Some(c) = canonical_name(path) {
        return c;
    }
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for c in absolute.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// Whether two paths name the same file (existing or to be created).
#[must_use]
pub fn same_file(a: &Path, b: &Path) -> bool {
    if a == b {
        return true;
    }
    if let (Some(x), Some(y)) = (identity(a), identity(b)) {
        return x == y;
    }
    matches!((canonical_name(a), canonical_name(b)), (Some(x), Some(y)) if x == y)
}

/// Checks a command's outputs before any work: each may be replaced ([`check_writable`]),
/// no two are the same file, and none is one of the command's `inputs`. `outputs` pairs
/// each path with what it is, for the message.
pub fn check_outputs(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)]) -> Result<()> {
    for (i, (what, path)) in outputs.iter().enumerate() {
        for (other, earlier) in &outputs[..i] {
            if same_file(path, earlier) {
                return Err(refuse(path, &format!("is both the {other} and the {what}; give them different names")));
            }
        }
        for (input, p) in inputs {
            if same_file(path, p) {
                return Err(refuse(path, &format!("the {what} would overwrite the {input}, an input of this command")));
            }
        }
    }
    for (_, path) in outputs {
        check_writable(path)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("zvidpt-atomic-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect()
    }

    /// A killed render's temporary file (its process gone) is removed by the next write of
    /// the same output; a live process's, another output's and another machine's stay. A
    /// name of 250 bytes can be written (its temporary name is shortened).
    #[test]
    fn stale_temporaries_go_and_long_names_work() {
        let dir = scratch("stale");
        let out = dir.join("x.exr");
        // A pid beyond the kernel's limit never runs.
        let dead = dir.join(format!(".x.exr.{}-4194305.tmp", host()));
        let live = dir.join(format!(".x.exr.{}-1.tmp", host()));
        let other_machine = dir.join(".x.exr.elsewhere-4194305.tmp");
        let other_output = dir.join(format!(".y.exr.{}-4194305.tmp", host()));
        for f in [&dead, &live, &other_machine, &other_output] {
            std::fs::write(f, "left").unwrap();
        }
        commit(vec![stage(&out, |w| w.write_all(b"new").map_err(|e| Error::io(&out, e))).unwrap()]).unwrap();
        assert!(!dead.exists(), "the dead process's temporary file stayed");
        assert!(live.exists() && other_machine.exists() && other_output.exists());
        let long = dir.join(format!("{}.exr", "é".repeat(123)));
        assert!(long.file_name().unwrap().len() >= 250);
        commit(vec![stage(&long, |w| w.write_all(b"long").map_err(|e| Error::io(&long, e))).unwrap()]).unwrap();
        assert_eq!(std::fs::read_to_string(&long).unwrap(), "long");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failed_file_leaves_every_destination_as_it_was() {
        let dir = scratch("together");
        let (a, b) = (dir.join("a.exr"), dir.join("a.png"));
        std::fs::write(&a, "old a").unwrap();
        std::fs::write(&b, "old b").unwrap();
        let first = stage(&a, |w| w.write_all(b"new a").map_err(|e| Error::io(&a, e))).unwrap();
        let second = stage(&b, |_| Err(Error::InvalidOption("encoder failed".into())));
        assert!(second.is_err());
        drop(first);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "old b");
        assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
        // Both staged: both replaced, no backups left.
        let files = vec![
            stage(&a, |w| w.write_all(b"new a").map_err(|e| Error::io(&a, e))).unwrap(),
            stage(&b, |w| w.write_all(b"new b").map_err(|e| Error::io(&b, e))).unwrap(),
        ];
        commit(files).unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
        assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
        // Other tests run alongside and register their own files: only this folder's count.
        assert!(!pending().iter().any(|p| p.starts_with(&dir)), "{:?}", pending());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failed_rename_restores_the_files_already_moved() {
        let dir = scratch("rollback");
        let (a, b) = (dir.join("a.exr"), dir.join("b.png"));
        std::fs::write(&a, "old a").unwrap();
        let files = vec![
            stage(&a, |w| w.write_all(b"new a").map_err(|e| Error::io(&a, e))).unwrap(),
            stage(&b, |w| w.write_all(b"new b").map_err(|e| Error::io(&b, e))).unwrap(),
        ];
        // The second destination becomes a folder before the commit: its rename must fail.
        std::fs::create_dir(&b).unwrap();
        assert!(commit(files).is_err());
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert!(b.is_dir());
        assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn links_special_and_read_only_files_are_not_replaced() {
        let dir = scratch("refuse");
        let target = dir.join("target.exr");
        std::fs::write(&target, "keep").unwrap();
        let link = dir.join("link.exr");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        assert!(check_writable(&link).unwrap_err().to_string().contains("symbolic link"));
        assert!(write_atomically(&link, |_| Ok(())).is_err());
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert!(check_writable(Path::new("/dev/null")).unwrap_err().to_string().contains("not a regular file"));
        let ro = dir.join("ro.exr");
        std::fs::write(&ro, "keep").unwrap();
        let mut perm = std::fs::metadata(&ro).unwrap().permissions();
        perm.set_readonly(true);
        std::fs::set_permissions(&ro, perm).unwrap();
        assert!(check_writable(&ro).unwrap_err().to_string().contains("read-only"));
        assert_eq!(std::fs::read_to_string(&ro).unwrap(), "keep");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep");
        assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn outputs_must_differ_from_each_other_and_from_inputs() {
        let dir = scratch("same");
        let a = dir.join("a.exr");
        std::fs::write(&a, "input").unwrap();
        let dotted = dir.join(".").join("a.exr");
        let err = check_outputs(&[("error map", &dotted)], &[("image", &a)]).unwrap_err();
        assert!(err.to_string().contains("would overwrite the image"), "{err}");
        let x = dir.join("x.png");
        let err = check_outputs(&[("EXR", &x), ("PNG", &dir.join("./x.png"))], &[]).unwrap_err();
        assert!(err.to_string().contains("is both the EXR and the PNG"), "{err}");
        check_outputs(&[("EXR", &dir.join("x.exr")), ("PNG", &x)], &[("image", &a)]).unwrap();
        assert!(leftovers(&dir).is_empty());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
