//! Checks shared by the workflows: counts and ranges of settings (bounds from
//! [`crate::limits`], named by their command-line flags), and outputs that would overwrite an input.

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// `value` of `flag` as a count from 1 to `max`.
pub fn count(flag: &str, value: usize, max: usize) -> Result<usize> {
    if value == 0 {
        return Err(Error::InvalidData {
            origin: flag.into(),
            message: "must be at least 1".into(),
        });
    }
    crate::limits::check_count(value, max, flag, "(the value)")
}

/// `--position-sigma` (m) and `--rotation-sigma` (rad) within their bounds: a tiny sigma
/// overflows the weighted cost, a huge one hides every residual.
pub fn sigmas(position: f64, rotation: f64) -> Result<()> {
    use crate::limits::{check_range, POSITION_SIGMA, ROTATION_SIGMA};
    check_range(position, POSITION_SIGMA, "--position-sigma", "m")?;
    check_range(rotation, ROTATION_SIGMA, "--rotation-sigma", "rad")?;
    Ok(())
}

/// Refuses to write `output` when it is one of `inputs` (the same file, also through symbolic links): the
/// write would replace the input, which the user most likely did not mean.
pub fn refuse_overwrite(output: &Path, inputs: &[&Path]) -> Result<()> {
    let Some(target) = resolved(output) else {
        return Ok(());
    };
    for input in inputs {
        if resolved(input).is_some_and(|i| i == target) {
            return Err(Error::InvalidData {
                origin: output.display().to_string(),
                message: format!(
                    "the output is the input file {}; writing it would replace the input: \
                     choose another output path",
                    input.display()
                ),
            });
        }
    }
    Ok(())
}

/// [`refuse_overwrite`] for every file a command writes into `directory`: the `names` given,
/// and any file ending in `extension`.
pub fn refuse_overwrite_in(
    directory: &Path,
    names: &[&str],
    extension: &str,
    inputs: &[&Path],
) -> Result<()> {
    for name in names {
        refuse_overwrite(&directory.join(name), inputs)?;
    }
    for input in inputs {
        let written_kind = input.extension().is_some_and(|e| e == extension);
        let inside = input
            .parent()
            .map(|p| {
                if p.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    p
                }
            })
            .and_then(resolved)
            .zip(resolved(directory))
            .is_some_and(|(parent, directory)| parent == directory);
        if written_kind && inside {
            return Err(Error::InvalidData {
                origin: directory.display().to_string(),
                message: format!(
                    "the output folder holds the input file {}, and .{extension} files in it \
                     are overwritten: choose another output folder",
                    input.display()
                ),
            });
        }
    }
    Ok(())
}

/// The absolute path without symbolic links: of the file if it exists, else of its folder
/// joined with its name; `None` when neither exists (then it cannot be an input).
fn resolved(path: &Path) -> Option<PathBuf> {
    if let Ok(path) = path.canonicalize() {
        return Some(path);
    }
    let name = path.file_name()?;
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    parent.canonicalize().ok().map(|p| p.join(name))
}
