//! Writing output files so that a failure never leaves a half-written file behind, and output
//! folders as a set (all files of one run, nothing stale from an earlier one).

use crate::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// Writes `contents` to a temporary file next to `path`, then renames it over `path`.
pub fn write_atomically(path: &Path, contents: &[u8]) -> Result<()> {
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
        let mut file = std::fs::File::create(&temporary)?;
        file.write_all(contents)?;
        file.sync_all()?;
        std::fs::rename(&temporary, path)
    })();
    if let Err(source) = result {
        let _ = std::fs::remove_file(&temporary);
        return Err(io(source));
    }
    Ok(())
}

/// Checks, before anything is computed, that `folder` can receive a new set of outputs: it is
/// absent, or a folder holding only files that `ours` recognises by name (a previous output of
/// the same command), and the folder that will hold it is writable.
pub fn check_output_folder(folder: &Path, ours: &dyn Fn(&str) -> bool) -> Result<()> {
    let refuse = |message: String| Error::InvalidData {
        origin: folder.display().to_string(),
        message,
    };
    let io = |path: &Path, source| Error::Io {
        path: path.to_owned(),
        source,
    };
    if folder.exists() {
        if !folder.is_dir() {
            return Err(refuse(
                "is a file, not a folder; give --out a folder".into(),
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
                "holds {} entr{} treecal did not write ({}); the output replaces the whole folder, so give --out a new or empty folder, or a previous output of this command",
                foreign.len(),
                if foreign.len() == 1 { "y" } else { "ies" },
                foreign.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
            )));
        }
    }
    // The nearest existing ancestor must let us create the temporary folder.
    let mut ancestor = parent_of(folder);
    while !ancestor.exists() {
        match ancestor.parent() {
            Some(p) if !p.as_os_str().is_empty() => ancestor = p.to_owned(),
            _ => {
                ancestor = std::path::PathBuf::from(".");
                break;
            }
        }
    }
    let probe = ancestor.join(format!(".treecal-probe-{}", std::process::id()));
    std::fs::create_dir(&probe).map_err(|e| io(&ancestor, e))?;
    std::fs::remove_dir(&probe).map_err(|e| io(&probe, e))?;
    Ok(())
}

/// Writes `files` (name, contents) as the whole contents of `folder`, all or nothing: they are
/// written into a temporary folder beside it, which then replaces `folder` (renamed over it;
/// the previous folder is removed after the swap). A failure leaves the previous folder as it
/// was and no temporary folder behind. Call [`check_output_folder`] first: this does not
/// check what the old folder holds.
pub fn replace_folder(folder: &Path, files: &[(String, Vec<u8>)]) -> Result<()> {
    let io = |path: &Path, source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let parent = parent_of(folder);
    std::fs::create_dir_all(&parent).map_err(|e| io(&parent, e))?;
    let name = folder
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let id = std::process::id();
    let staging = parent.join(format!(".{name}.new-{id}"));
    let previous = parent.join(format!(".{name}.old-{id}"));
    let _ = std::fs::remove_dir_all(&staging);
    let written = (|| -> std::io::Result<()> {
        std::fs::create_dir(&staging)?;
        for (file, contents) in files {
            let mut handle = std::fs::File::create(staging.join(file))?;
            handle.write_all(contents)?;
            handle.sync_all()?;
        }
        Ok(())
    })();
    if let Err(source) = written {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(io(folder, source));
    }
    let had_previous = folder.exists();
    if had_previous {
        if let Err(source) = std::fs::rename(folder, &previous) {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(io(folder, source));
        }
    }
    if let Err(source) = std::fs::rename(&staging, folder) {
        if had_previous {
            let _ = std::fs::rename(&previous, folder);
        }
        let _ = std::fs::remove_dir_all(&staging);
        return Err(io(folder, source));
    }
    if had_previous {
        std::fs::remove_dir_all(&previous).map_err(|e| io(&previous, e))?;
    }
    Ok(())
}

/// The folder holding `path` (`.` for a bare name).
fn parent_of(path: &Path) -> std::path::PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => std::path::PathBuf::from("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ours(name: &str) -> bool {
        name.ends_with(".txt")
    }

    fn names(folder: &Path) -> Vec<String> {
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
