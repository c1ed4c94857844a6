//! Checks shared by the workflows: counts and ranges of settings (bounds from
//! [`crate::limits`], named by their settings), and outputs that cannot be written or
//! would overwrite an input.

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// `value` of `setting` as a count from 1 to `max`.
pub fn count(setting: &str, value: usize, max: usize) -> Result<usize> {
    if value == 0 {
        return Err(Error::setting(setting, "must be at least 1"));
    }
    crate::limits::check_count(value, max, setting, "(the value)").map_err(|error| match error {
        Error::InvalidData { message, .. } => Error::setting(setting, message),
        other => other,
    })
}

/// `position_sigma` (m) and `rotation_sigma` (rad) within their bounds: a tiny sigma
/// overflows the weighted cost, a huge one hides every residual.
pub fn sigmas(position: f64, rotation: f64) -> Result<()> {
    use crate::limits::{check_range, POSITION_SIGMA, ROTATION_SIGMA};
    check_range(position, POSITION_SIGMA, "position_sigma", "m")?;
    check_range(rotation, ROTATION_SIGMA, "rotation_sigma", "rad")?;
    Ok(())
}

/// Something a command writes.
#[derive(Debug, Clone, Copy)]
pub enum Output<'a> {
    /// A file, written atomically.
    File(&'a Path),
    /// A folder the command writes its files into, or replaces as a whole.
    Folder(&'a Path),
}

/// Checks a command's outputs before anything is computed (a run must not fail at its end
/// over an output it could have refused at once): each can be written (a file: not a folder
/// nor `.`; a folder: not a file; the nearest existing folder writable), and none is one of
/// `inputs` or, for a folder, holds one anywhere below it (the output would replace or
/// delete the input), compared as absolute paths without symbolic links. Every command and
/// binding passes all of its input files here.
pub fn check_outputs(outputs: &[Output<'_>], inputs: &[&Path]) -> Result<()> {
    for output in outputs {
        match *output {
            Output::File(path) => crate::io::check_output_file(path)?,
            Output::Folder(path) => crate::io::check_output_dir(path)?,
        }
        let (Output::File(path) | Output::Folder(path)) = *output;
        let Some(target) = resolved(path) else {
            continue;
        };
        for input in inputs {
            let Some(input_path) = resolved(input) else {
                continue;
            };
            let message = match output {
                Output::File(_) if input_path == target => format!(
                    "the output is the input file {}; writing it would replace the input: \
                     choose another output path",
                    input.display()
                ),
                Output::Folder(_) if input_path.starts_with(&target) => format!(
                    "the output folder holds the input file {}; writing the outputs would \
                     replace the input or delete it: choose another output folder, or move \
                     the input",
                    input.display()
                ),
                _ => continue,
            };
            return Err(Error::InvalidData {
                origin: path.display().to_string(),
                message,
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

/// The rows (their `stage` labels, named by `ids`) that no stage of `plan` uses: the label (or
/// the lack of one) matches no stage while every stage selects by label. One message naming
/// each label and its first rows; `None` when every row is used.
pub fn unused_stage_rows(
    plan: &crate::calibration::Plan,
    labels: &[Option<&str>],
    ids: &[String],
) -> Option<String> {
    let used: Vec<&str> = plan
        .stages
        .iter()
        .map(|s| s.measurements.as_deref())
        .collect::<Option<Vec<_>>>()?;
    let mut unused: Vec<(Option<&str>, Vec<&str>)> = Vec::new();
    for (index, &label) in labels.iter().enumerate() {
        if label.is_some_and(|l| used.contains(&l)) {
            continue;
        }
        let id = ids.get(index).map_or("?", String::as_str);
        match unused.iter_mut().find(|(l, _)| *l == label) {
            Some((_, rows)) => rows.push(id),
            None => unused.push((label, vec![id])),
        }
    }
    if unused.is_empty() {
        return None;
    }
    let parts: Vec<String> = unused
        .iter()
        .map(|(label, rows)| {
            let shown: Vec<&str> = rows.iter().take(5).copied().collect();
            let more = if rows.len() > 5 { ", …" } else { "" };
            let (what, hint) = match label {
                Some(label) => (
                    format!("labelled '{label}'"),
                    crate::error::did_you_mean(label, used.iter().copied()),
                ),
                None => ("without a stage label".into(), String::new()),
            };
            format!(
                "{} rows {what} (rows {}{more}{hint})",
                rows.len(),
                shown.join(", ")
            )
        })
        .collect();
    Some(format!(
        "rows used by no stage of the plan (its stages use {}) are left out: {}; fix the \
         labels or the plan's `measurements:`",
        used.iter()
            .map(|l| format!("'{l}'"))
            .collect::<Vec<_>>()
            .join(", "),
        parts.join("; ")
    ))
}
