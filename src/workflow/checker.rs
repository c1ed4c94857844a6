//! The self-collision checker of a robot, with its collision meshes found as ROS finds them.

use super::source::RobotSource;
use super::Note;
use crate::io::{mesh_file_loader, package_dirs};
use crate::sim::collision::{CollisionChecker, CollisionOptions};
use crate::sim::sampling::{sample_configurations, SamplingOptions};
use crate::tree::KinematicTree;
use crate::Result;
use rand::SeedableRng;
use std::path::{Path, PathBuf};

/// How many random configurations decide that a link pair always collides.
const ALWAYS_COLLIDING_SAMPLES: usize = 100;

/// The self-collision checker of `robot`, its STL, OBJ and COLLADA meshes resolved next to the
/// URDF or, for `package://` names, in `package_paths` and then `ROS_PACKAGE_PATH`. Meshes left
/// out, and link pairs that collide everywhere (and are therefore not checked), go to `notes`.
pub fn collision_checker(
    robot: &RobotSource,
    tree: &KinematicTree,
    package_paths: &[PathBuf],
    notes: &mut Vec<Note>,
) -> Result<CollisionChecker> {
    let directory = robot
        .path()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let search = std::env::var("ROS_PACKAGE_PATH").unwrap_or_default();
    let mut directories = package_paths.to_vec();
    directories.extend(package_dirs(&search));
    let loader = mesh_file_loader(directory, directories);
    let mut checker = CollisionChecker::with_meshes(tree, &CollisionOptions::default(), &loader)?;
    if let Some(line) = skipped_meshes(&checker) {
        notes.push(Note::warning(line));
    }
    if checker.loaded_meshes() > 0 {
        ignore_always_colliding(&mut checker, tree, notes);
    }
    Ok(checker)
}

/// Meshes of neighbouring links often overlap by design; such pairs would reject every
/// configuration. A robot that cannot be sampled (no limits) is left as it is.
fn ignore_always_colliding(
    checker: &mut CollisionChecker,
    tree: &KinematicTree,
    notes: &mut Vec<Note>,
) {
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(0);
    let samples = sample_configurations(
        tree,
        None,
        ALWAYS_COLLIDING_SAMPLES,
        &mut rng,
        &SamplingOptions::default(),
        &[],
    )
    .unwrap_or_default();
    let poses: Vec<_> = samples
        .iter()
        .filter_map(|q| tree.link_poses(q).ok())
        .collect();
    let removed = checker.ignore_pairs_always_colliding(&poses);
    if !removed.is_empty() {
        let names: Vec<String> = removed
            .iter()
            .map(|(a, b)| format!("{}–{}", tree.link(*a).name, tree.link(*b).name))
            .collect();
        notes.push(Note::info(format!(
            "{} link pairs collide at all {} random configurations (their collision meshes overlap by design) and are not checked: {}",
            removed.len(),
            poses.len(),
            names.join(", ")
        )));
    }
}

/// One line naming every mesh left out, first the ones not found, then the unreadable ones
/// with their reasons; `None` if none.
fn skipped_meshes(checker: &CollisionChecker) -> Option<String> {
    let skipped = checker.skipped_mesh_files();
    if skipped.is_empty() {
        return None;
    }
    let unreadable = checker.unreadable_meshes();
    let mut missing: Vec<String> = skipped
        .iter()
        .filter(|name| !unreadable.iter().any(|(u, _)| u == *name))
        .cloned()
        .collect();
    missing.sort_unstable();
    missing.dedup();
    let mut unread: Vec<String> = unreadable
        .iter()
        .map(|(name, reason)| format!("{name} ({reason})"))
        .collect();
    unread.sort_unstable();
    unread.dedup();
    let mut parts = Vec::new();
    if !missing.is_empty() {
        parts.push(format!(
            "{} files not found (package:// names are searched in --package-path, then ROS_PACKAGE_PATH): {}",
            missing.len(),
            missing.join(", ")
        ));
    }
    if !unread.is_empty() {
        parts.push(format!(
            "{} files unreadable: {}",
            unread.len(),
            unread.join(", ")
        ));
    }
    Some(format!(
        "{} of {} collision meshes are not checked; {}",
        skipped.len(),
        skipped.len() + checker.loaded_meshes(),
        parts.join("; ")
    ))
}
