//! Writing output files so that a failure never leaves a half-written file behind, and output
//! folders as a set (all files of one run, nothing stale from an earlier one).

use super::output_lock::{aside, lock_output, recover, swap_in};
use crate::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// Writes `contents` to a temporary file next to `path`, then renames it over `path`.
pub fn write_atomically(path: &Path, contents: &[u8]) -> Result<()> {
    write_atomically_with(path, &mut |file| {
        file.write_all(contents).map_err(|source| Error::Io {
            path: path.to_owned(),
            source,
        })
    })
}

/// As [`write_atomically`], with the contents written by `write` (streamed through a
/// buffer); an error from `write` removes the temporary file and leaves `path` untouched.
pub fn write_atomically_with(
    path: &Path,
    write: &mut dyn FnMut(&mut dyn Write) -> Result<()>,
) -> Result<()> {
    let io = |source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let directory = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_owned(),
        _ => std::path::PathBuf::from("."),
    };
    if !directory.exists() {
        std::fs::create_dir_all(&directory).map_err(io)?;
    }
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let temporary = directory.join(format!(".{file_name}.{}.tmp", std::process::id()));
    let result = (|| {
        let file = std::fs::File::create(&temporary).map_err(io)?;
        let mut buffered = std::io::BufWriter::new(file);
        write(&mut buffered)?;
        let file = buffered.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        std::fs::rename(&temporary, path).map_err(io)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

/// Checks, before anything is computed, that `folder` can receive a new set of outputs: it has
/// a name (not `.`, `..` or `/`: the folder is replaced by renaming), is absent or a folder
/// holding only files that `ours` recognises by name (a previous output of the same command),
/// no other run is writing it, and the folder that will hold it is writable.
pub fn check_output_folder(folder: &Path, ours: &dyn Fn(&str) -> bool) -> Result<()> {
    let refuse = |message: String| Error::InvalidData {
        origin: folder.display().to_string(),
        message,
    };
    let io = |path: &Path, source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let name = folder_name(folder)?;
    if folder.exists() {
        if !folder.is_dir() {
            return Err(refuse(
                "is a file, not a folder; give `out` a folder".into(),
            ));
        }
        let mut foreign = Vec::new();
        for entry in std::fs::read_dir(folder).map_err(|e| io(folder, e))? {
            let entry = entry.map_err(|e| io(folder, e))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let is_file = entry.file_type().map(|t| t.is_file()).unwrap_or(false);
            if !is_file || !ours(&name) {
                foreign.push(name);
            }
        }
        if !foreign.is_empty() {
            foreign.sort();
            return Err(refuse(format!(
                "holds {} entr{} treecal did not write ({}); the output replaces the whole folder, so give `out` a new or empty folder, or a previous output of this command",
                foreign.len(),
                if foreign.len() == 1 { "y" } else { "ies" },
                foreign.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
            )));
        }
    }
    let parent = parent_of(folder);
    if parent.is_dir() {
        // Only a probe: the lock is taken again for the swap.
        drop(lock_output(&parent, &name)?);
    }
    check_writable_from(&parent_of(folder))
}

/// Checks, before anything is computed, that files can be written into the folder `folder`:
/// it is not a file, and it or the nearest existing folder above it is writable.
pub fn check_output_dir(folder: &Path) -> Result<()> {
    if folder.exists() && !folder.is_dir() {
        return Err(Error::InvalidData {
            origin: folder.display().to_string(),
            message: "is a file, not a folder; give a folder".into(),
        });
    }
    check_writable_from(folder)
}

/// Checks, before anything is computed, that the file `path` can be written: it names a file
/// (not `.`, `..`, `/` or an existing folder) and the nearest existing folder above it is
/// writable.
pub fn check_output_file(path: &Path) -> Result<()> {
    let refuse = |message: &str| Error::InvalidData {
        origin: path.display().to_string(),
        message: message.into(),
    };
    if path.is_dir() {
        return Err(refuse("is a folder; give a file name to write"));
    }
    match path.file_name() {
        Some(_) if !path.ends_with("..") => {}
        _ => return Err(refuse("names no file; give a file name to write")),
    }
    check_writable_from(&parent_of(path))
}

/// `start`, or the nearest existing folder above it, lets us create entries (probed with a
/// hidden folder, removed at once).
fn check_writable_from(start: &Path) -> Result<()> {
    let io = |path: &Path, source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let mut ancestor = start.to_owned();
    while !ancestor.exists() {
        match ancestor.parent() {
            Some(p) if !p.as_os_str().is_empty() => ancestor = p.to_owned(),
            _ => {
                ancestor = std::path::PathBuf::from(".");
                break;
            }
        }
    }
    if !ancestor.is_dir() {
        return Err(Error::InvalidData {
            origin: start.display().to_string(),
            message: format!("{} is a file, not a folder", ancestor.display()),
        });
    }
    let probe = ancestor.join(format!(".treecal-probe-{}", std::process::id()));
    std::fs::create_dir(&probe).map_err(|e| io(&ancestor, e))?;
    std::fs::remove_dir(&probe).map_err(|e| io(&probe, e))?;
    Ok(())
}

/// The name of the output folder `folder`; an error for `.`, `..` and `/`, which cannot be
/// replaced by renaming.
fn folder_name(folder: &Path) -> Result<String> {
    match folder.file_name() {
        Some(name) if !folder.ends_with("..") => Ok(name.to_string_lossy().into_owned()),
        _ => Err(Error::InvalidData {
            origin: folder.display().to_string(),
            message: "names no folder that can be replaced; give `out` a named folder, e.g. \
                      out/calibrate"
                .into(),
        }),
    }
}

/// Writes `files` (name, contents) as the whole contents of `folder`, all or nothing, safe
/// against a crash and a second run: under a lock beside `folder` (a second run gets an
/// error), after recovering what a killed run left, the files are written into a staging
/// folder beside it, which is then swapped in (atomically where the system can exchange two
/// folders; otherwise by two renames that the next run completes if killed between them);
/// the previous content is removed last. A failure leaves the previous folder as it was and
/// no staging folder behind. Call [`check_output_folder`] first: this does not check what the
/// old folder holds.
pub fn replace_folder(folder: &Path, files: &[(String, Vec<u8>)]) -> Result<()> {
    replace_folder_streamed(folder, files, &[])
}

/// A file of an output folder whose contents `write` streams into it (through a buffer), for
/// outputs too large to hold whole in memory.
pub type StreamedFile<'a> = (&'a str, &'a dyn Fn(&mut dyn Write) -> Result<()>);

/// As [`replace_folder`], with the files of `streamed` written after `files` by their
/// writers; an error from a writer leaves the previous folder as it was, as any other.
pub fn replace_folder_streamed(
    folder: &Path,
    files: &[(String, Vec<u8>)],
    streamed: &[StreamedFile<'_>],
) -> Result<()> {
    let io = |path: &Path, source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let name = folder_name(folder)?;
    let parent = parent_of(folder);
    std::fs::create_dir_all(&parent).map_err(|e| io(&parent, e))?;
    let _lock = lock_output(&parent, &name)?;
    recover(&parent, &name)?;
    let staging = aside(&parent, &name, "new");
    let written = (|| -> Result<()> {
        std::fs::create_dir(&staging).map_err(|e| io(folder, e))?;
        // The whole files on a thread of their own while the streamed ones are rendered.
        std::thread::scope(|scope| {
            let whole = scope.spawn(|| -> std::io::Result<()> {
                for (file, contents) in files {
                    let mut handle = std::fs::File::create(staging.join(file))?;
                    handle.write_all(contents)?;
                    handle.sync_all()?;
                }
                Ok(())
            });
            let streamed = streamed.iter().try_for_each(|(file, write)| {
                write_piped(&staging.join(file), *write, &|e| io(folder, e))
            });
            let whole = whole.join().unwrap_or_else(|_| Err(stopped()));
            streamed.and(whole.map_err(|e| io(folder, e)))
        })
    })();
    if let Err(error) = written {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(error);
    }
    if !folder.exists() {
        if let Err(source) = std::fs::rename(&staging, folder) {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(io(folder, source));
        }
        return Ok(());
    }
    let previous = match swap_in(&staging, folder, &aside(&parent, &name, "old")) {
        Ok(previous) => previous,
        Err(source) => {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(io(folder, source));
        }
    };
    std::fs::remove_dir_all(&previous).map_err(|e| io(&previous, e))
}

/// Bytes a streamed file is rendered into before its writing thread writes them.
const PIPED_BUFFER: usize = 4 << 20;

/// Writes the file `path` from what `write` renders, the rendering on this thread and the
/// system calls (copying into the page cache, the final sync) on another, a few buffers
/// apart; `io` names an I/O error.
fn write_piped(
    path: &Path,
    write: &dyn Fn(&mut dyn Write) -> Result<()>,
    io: &dyn Fn(std::io::Error) -> Error,
) -> Result<()> {
    let mut handle = super::direct_write::DirectFile::create(path, PIPED_BUFFER).map_err(io)?;
    std::thread::scope(|scope| {
        let (sender, buffers) = std::sync::mpsc::sync_channel::<Vec<u8>>(2);
        // Written buffers go back to be filled again (a fresh 4 MB buffer per send cost its
        // page faults).
        let (give_back, returned) = std::sync::mpsc::channel::<Vec<u8>>();
        let writer = scope.spawn(move || -> std::io::Result<()> {
            for mut buffer in buffers {
                handle.write_all(&buffer)?;
                buffer.clear();
                // The renderer may have finished: a buffer nobody takes back is dropped.
                let _ = give_back.send(buffer);
            }
            handle.finish()
        });
        let mut piped = Piped {
            sender,
            returned,
            buffer: Vec::with_capacity(PIPED_BUFFER),
        };
        let rendered = write(&mut piped).and_then(|()| piped.flush().map_err(io));
        drop(piped);
        // The writer's own error first: a render stopped by a failed write reports it.
        let written = writer.join().unwrap_or_else(|_| Err(stopped()));
        written.map_err(io).and(rendered)
    })
}

/// The error of a writing thread that stopped without one of its own.
fn stopped() -> std::io::Error {
    std::io::Error::other("the thread writing the file stopped")
}

/// A [`Write`] that hands full buffers to a writing thread.
struct Piped {
    sender: std::sync::mpsc::SyncSender<Vec<u8>>,
    /// Buffers the writing thread has written, to be filled again.
    returned: std::sync::mpsc::Receiver<Vec<u8>>,
    buffer: Vec<u8>,
}

impl Write for Piped {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        if self.buffer.len() + bytes.len() > PIPED_BUFFER {
            self.send()?;
        }
        self.buffer.extend_from_slice(bytes);
        Ok(bytes.len())
    }

    /// Sends what is buffered.
    fn flush(&mut self) -> std::io::Result<()> {
        self.send()
    }
}

impl Piped {
    fn send(&mut self) -> std::io::Result<()> {
        if self.buffer.is_empty() {
            return Ok(());
        }
        let next = self
            .returned
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(PIPED_BUFFER));
        let full = std::mem::replace(&mut self.buffer, next);
        self.sender.send(full).map_err(|_| stopped())
    }
}

/// The folder holding `path` (`.` for a bare name).
fn parent_of(path: &Path) -> std::path::PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => std::path::PathBuf::from("."),
    }
}

#[cfg(test)]
pub(in crate::io) mod tests {
    use super::*;

    fn ours(name: &str) -> bool {
        name.ends_with(".txt")
    }

    /// The entries of `folder`, sorted (empty when it cannot be read); shared with
    /// `output_lock`'s tests.
    pub(in crate::io) fn names(folder: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(folder)
            .map(|entries| {
                entries
                    .filter_map(|e| e.ok())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        names
    }

    #[test]
    fn a_folder_is_replaced_as_a_set() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|source| Error::Io {
            path: "tempdir".into(),
            source,
        })?;
        let out = dir.path().join("nested").join("out");
        check_output_folder(&out, &ours)?;
        replace_folder(
            &out,
            &[
                ("a.txt".into(), b"1".to_vec()),
                ("b.txt".into(), b"2".to_vec()),
            ],
        )?;
        assert_eq!(names(&out), ["a.txt", "b.txt"]);
        check_output_folder(&out, &ours)?;
        replace_folder(&out, &[("c.txt".into(), b"3".to_vec())])?;
        assert_eq!(names(&out), ["c.txt"], "stale files must go");
        assert_eq!(names(&dir.path().join("nested")), ["out"], "no temporaries");

        std::fs::write(out.join("mine.dat"), "x").map_err(|source| Error::Io {
            path: out.clone(),
            source,
        })?;
        let refused = check_output_folder(&out, &ours);
        assert!(
            refused
                .as_ref()
                .is_err_and(|e| e.to_string().contains("mine.dat")),
            "{refused:?}"
        );
        let file = dir.path().join("file");
        std::fs::write(&file, "x").map_err(|source| Error::Io {
            path: file.clone(),
            source,
        })?;
        assert!(check_output_folder(&file, &ours).is_err());
        Ok(())
    }
}
