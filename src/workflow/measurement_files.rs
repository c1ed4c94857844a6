//! Several measurement CSVs read as one set: labs record one file per day or per set-up, and
//! each file is then its own measurement session (one measurement frame each,
//! `calibration::sessions`) unless its rows name their session themselves.

use crate::error::{Error, Result};
use crate::io::{read_measurements, MeasurementReadOptions, MeasurementSet};
use crate::kinematics::McpcModel;
use crate::tree::KinematicTree;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The session name of each file: its stem (`day1` for `data/day1.csv`), or the whole path
/// where two files share a stem.
pub(super) fn session_names(paths: &[PathBuf]) -> Vec<String> {
    let stem = |p: &Path| {
        p.file_stem().map_or_else(
            || p.display().to_string(),
            |s| s.to_string_lossy().into_owned(),
        )
    };
    let stems: Vec<String> = paths.iter().map(|p| stem(p)).collect();
    stems
        .iter()
        .zip(paths)
        .map(|(s, p)| {
            if stems.iter().filter(|t| *t == s).count() > 1 {
                p.display().to_string()
            } else {
                s.clone()
            }
        })
        .collect()
}

/// How messages name several files: `a.csv + b.csv`.
pub(super) fn origin(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(" + ")
}

/// The items of every list in order of first appearance (the tools or targets of several
/// files).
pub(super) fn union_in_order<T: PartialEq>(lists: Vec<Vec<T>>) -> Vec<T> {
    let mut all: Vec<T> = Vec::new();
    for item in lists.into_iter().flatten() {
        if !all.contains(&item) {
            all.push(item);
        }
    }
    all
}

/// Reads every file (each as [`read_measurements`] reads one) into one set, in file order.
/// Rows without a `session` get their file's session name ([`session_names`]); row ids that
/// repeat across files are prefixed with it (`day1/12`), said in a note. No file is an error.
pub(super) fn read_files(
    paths: &[PathBuf],
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Result<MeasurementSet> {
    let mut sets = paths
        .iter()
        .map(|path| read_measurements(path, tree, model, options))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .zip(session_names(paths));
    let Some((mut set, name)) = sets.next() else {
        return Err(Error::setting(
            "measurements",
            "no measurement file given: name at least one CSV",
        ));
    };
    let mut labelled = vec![label_session(&mut set, &name)];
    for (mut more, name) in sets {
        labelled.push(label_session(&mut more, &name));
        set.measurements.append(&mut more.measurements);
        set.ids.append(&mut more.ids);
        set.lines.append(&mut more.lines);
        set.warnings.append(&mut more.warnings);
        set.notes.append(&mut more.notes);
    }
    set.notes.push(format!(
        "{} measurement files read as one set, each file its own session (one measurement \
         frame each): {}",
        paths.len(),
        labelled.join(", ")
    ));
    if let Some(note) = prefix_repeated_ids(&mut set) {
        set.notes.push(note);
    }
    Ok(set)
}

/// Gives the rows of one file's `set` without a `session` the file's session `name`; says
/// how many rows the file has and whether it named sessions itself.
fn label_session(set: &mut MeasurementSet, name: &str) -> String {
    let unlabelled = set
        .measurements
        .iter_mut()
        .filter(|m| m.session.is_none())
        .map(|m| m.session = Some(name.to_owned()))
        .count();
    let own = if unlabelled == set.measurements.len() {
        ""
    } else {
        " (sessions from its `session` column)"
    };
    format!("'{name}' {} rows{own}", set.measurements.len())
}

/// Prefixes every id with its row's session when an id occurs in two sessions (files that
/// each number their rows from 1); the note says so.
fn prefix_repeated_ids(set: &mut MeasurementSet) -> Option<String> {
    let mut first_session: HashMap<&str, Option<&str>> = HashMap::new();
    let mut repeated = None;
    for (id, m) in set.ids.iter().zip(&set.measurements) {
        let session = m.session.as_deref();
        match first_session.get(id.as_str()) {
            Some(seen) if *seen != session => {
                repeated = Some(id.clone());
                break;
            }
            Some(_) => {}
            None => {
                first_session.insert(id, session);
            }
        }
    }
    let repeated = repeated?;
    for (id, m) in set.ids.iter_mut().zip(&set.measurements) {
        *id = format!("{}/{id}", m.session.as_deref().unwrap_or(""));
    }
    Some(format!(
        "row id '{repeated}' occurs in more than one file: every id is prefixed with its \
         session, e.g. '{}'",
        set.ids.first().map_or("", String::as_str)
    ))
}
