//! What makes replacing an output folder safe against crashes and a second run: a lock beside
//! the folder, the recovery of what a killed run left, and the swap itself.
//!
//! Beside an output folder `out` a run creates `.out.lock` (held with `flock`, so a killed
//! run's lock is released by the kernel), `.out.new-PID` (the staging folder being written)
//! and, where the atomic exchange is unavailable, `.out.old-PID` (the previous folder during
//! the two renames). Under the lock no other run can be writing `out`, so every staging or
//! previous folder found then was left by a killed run: a previous folder is put back when
//! `out` is missing (the kill fell between the two renames), the rest removed.

use crate::error::{Error, Result};
use std::fs::File;
use std::path::{Path, PathBuf};

/// An output folder locked against a second run; unlocked (and the lock file removed) on drop.
#[derive(Debug)]
pub struct OutputLock {
    path: PathBuf,
    // Held for its flock; closing it releases the lock.
    _file: File,
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Removed while still locked: a run that opened it meanwhile sees another inode
        // after locking, and starts over on a new file.
        let _ = std::fs::remove_file(&self.path);
    }
}

/// The lock file of the output folder `name` in `parent`.
fn lock_path(parent: &Path, name: &str) -> PathBuf {
    parent.join(format!(".{name}.lock"))
}

/// Locks the output folder `name` in `parent` (which exists) or says which run holds it.
pub fn lock_output(parent: &Path, name: &str) -> Result<OutputLock> {
    let path = lock_path(parent, name);
    let io = |source| Error::Io {
        path: path.clone(),
        source,
    };
    for _ in 0..100 {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(&path)
            .map_err(io)?;
        if !try_lock(&file).map_err(io)? {
            let holder = std::fs::read_to_string(&path).unwrap_or_default();
            return Err(Error::InvalidData {
                origin: parent.join(name).display().to_string(),
                message: format!(
                    "another treecal run{} is writing this output folder (lock {}); wait for it \
                     to finish or choose another output folder",
                    match holder.trim() {
                        "" => String::new(),
                        pid => format!(" (process {pid})"),
                    },
                    path.display()
                ),
            });
        }
        if same_file(&file, &path) {
            use std::io::Write;
            let mut writer = &file;
            let _ = writer.set_len(0);
            let _ = writer.write_all(std::process::id().to_string().as_bytes());
            return Ok(OutputLock { path, _file: file });
        }
        // The holder removed the file as we opened it: lock the new one.
    }
    Err(io(std::io::Error::other(
        "could not lock the output folder",
    )))
}

#[cfg(unix)]
fn try_lock(file: &File) -> std::io::Result<bool> {
    use rustix::fs::{flock, FlockOperation};
    match flock(file, FlockOperation::NonBlockingLockExclusive) {
        Ok(()) => Ok(true),
        Err(rustix::io::Errno::WOULDBLOCK) => Ok(false),
        Err(e) => Err(e.into()),
    }
}

// Without flock (not unix) the folder is not locked; the swap is still crash-safe.
#[cfg(not(unix))]
fn try_lock(_: &File) -> std::io::Result<bool> {
    Ok(true)
}

#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_: &File, path: &Path) -> bool {
    path.exists()
}

/// The staging folder (`new`) or previous folder (`old`) of this process.
pub(crate) fn aside(parent: &Path, name: &str, kind: &str) -> PathBuf {
    parent.join(format!(".{name}.{kind}-{}", std::process::id()))
}

/// Under the lock: puts back a previous folder when `name` is missing and removes every other
/// staging or previous folder of `name` in `parent` (all left by killed runs).
pub fn recover(parent: &Path, name: &str) -> Result<()> {
    let io = |path: &Path, source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let new_prefix = format!(".{name}.new-");
    let old_prefix = format!(".{name}.old-");
    let mut staging = Vec::new();
    let mut previous = Vec::new();
    for entry in std::fs::read_dir(parent).map_err(|e| io(parent, e))? {
        let entry = entry.map_err(|e| io(parent, e))?;
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let pid_like = |prefix: &str| {
            file_name
                .strip_prefix(prefix)
                .is_some_and(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_digit()))
        };
        if pid_like(&new_prefix) {
            staging.push(entry.path());
        } else if pid_like(&old_prefix) {
            previous.push(entry.path());
        }
    }
    let folder = parent.join(name);
    if !folder.exists() {
        // The newest previous folder is the last output that was complete.
        previous.sort_by_key(|p| std::fs::metadata(p).and_then(|m| m.modified()).ok());
        if let Some(last) = previous.pop() {
            std::fs::rename(&last, &folder).map_err(|e| io(&last, e))?;
        }
    }
    for stale in staging.iter().chain(&previous) {
        std::fs::remove_dir_all(stale).map_err(|e| io(stale, e))?;
    }
    Ok(())
}

/// Swaps the complete folder `staging` in for `folder` (which exists) so that one of the two
/// always exists under `folder`'s name; on return `staging` holds the previous content.
pub fn swap_in(staging: &Path, folder: &Path, previous: &Path) -> std::io::Result<PathBuf> {
    if exchange(staging, folder)? {
        return Ok(staging.to_owned());
    }
    // Two renames: a kill between them leaves only `previous`, which the next run's
    // `recover` puts back.
    std::fs::rename(folder, previous)?;
    if let Err(error) = std::fs::rename(staging, folder) {
        let _ = std::fs::rename(previous, folder);
        return Err(error);
    }
    Ok(previous.to_owned())
}

/// Atomically exchanges `a` and `b` (Linux `renameat2(RENAME_EXCHANGE)`); `false` when the
/// system or file system cannot.
#[cfg(any(target_os = "linux", target_os = "android"))]
fn exchange(a: &Path, b: &Path) -> std::io::Result<bool> {
    use rustix::fs::{renameat_with, RenameFlags, CWD};
    match renameat_with(CWD, a, CWD, b, RenameFlags::EXCHANGE) {
        Ok(()) => Ok(true),
        Err(rustix::io::Errno::INVAL | rustix::io::Errno::NOSYS | rustix::io::Errno::NOTSUP) => {
            Ok(false)
        }
        Err(e) => Err(e.into()),
    }
}

#[cfg(not(any(target_os = "linux", target_os = "android")))]
fn exchange(_: &Path, _: &Path) -> std::io::Result<bool> {
    Ok(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::io::write::tests::names;

    #[test]
    fn a_second_lock_is_refused_and_a_dropped_one_leaves_nothing() -> std::io::Result<()> {
        let dir = tempfile::tempdir()?;
        let first = lock_output(dir.path(), "out");
        assert!(first.is_ok(), "{first:?}");
        let second = lock_output(dir.path(), "out");
        let message = second.map(|_| ()).unwrap_err().to_string();
        assert!(
            message.contains("another treecal run")
                && message.contains(&format!("process {}", std::process::id())),
            "{message}"
        );
        // Another folder in the same parent is independent.
        assert!(lock_output(dir.path(), "other").is_ok());
        drop(first);
        assert_eq!(names(dir.path()), Vec::<String>::new());
        assert!(lock_output(dir.path(), "out").is_ok());
        Ok(())
    }

    #[test]
    fn recovery_puts_back_the_previous_folder_and_removes_leftovers() -> std::io::Result<()> {
        let dir = tempfile::tempdir()?;
        // A run killed between its two renames: no `out`, its previous and staging folders.
        std::fs::create_dir(dir.path().join(".out.old-4000000"))?;
        std::fs::write(dir.path().join(".out.old-4000000/a.txt"), "old")?;
        std::fs::create_dir(dir.path().join(".out.new-4000000"))?;
        // A run killed while writing, and another output's folder that must stay.
        std::fs::create_dir(dir.path().join(".out.new-4000001"))?;
        std::fs::create_dir(dir.path().join(".other.new-4000001"))?;
        recover(dir.path(), "out").map_err(std::io::Error::other)?;
        assert_eq!(names(dir.path()), [".other.new-4000001", "out"]);
        assert_eq!(
            std::fs::read_to_string(dir.path().join("out/a.txt"))?,
            "old"
        );
        // With `out` present, previous folders are leftovers too.
        std::fs::create_dir(dir.path().join(".out.old-4000002"))?;
        recover(dir.path(), "out").map_err(std::io::Error::other)?;
        assert_eq!(names(dir.path()), [".other.new-4000001", "out"]);
        Ok(())
    }

    #[test]
    fn the_swap_keeps_one_folder_under_the_name() -> std::io::Result<()> {
        let dir = tempfile::tempdir()?;
        let (staging, folder) = (dir.path().join(".out.new-1"), dir.path().join("out"));
        std::fs::create_dir(&staging)?;
        std::fs::write(staging.join("n.txt"), "new")?;
        std::fs::create_dir(&folder)?;
        std::fs::write(folder.join("o.txt"), "old")?;
        let previous = swap_in(&staging, &folder, &dir.path().join(".out.old-1"))?;
        assert_eq!(names(&folder), ["n.txt"]);
        assert_eq!(names(&previous), ["o.txt"]);
        Ok(())
    }
}
