//! Loading the robot a command works on: a URDF path, or the built-in Robonaut.

use std::path::{Path, PathBuf};
use treecal::io::{mesh_file_loader, package_dirs};
use treecal::sim::collision::{CollisionChecker, CollisionOptions};
use treecal::urdf::UrdfImport;
use treecal::workflow::{MeasurementSource, RobotSource};
use treecal::{Branches, KinematicTree, Result};

pub use treecal::workflow::source::BUILT_IN_STIFFNESS;

/// Loads `path`, or the built-in Robonaut when `None`; prints loader warnings on stderr.
pub fn load(path: Option<&Path>) -> Result<UrdfImport> {
    let robot = RobotSource::from_path(path.map(Path::to_path_buf)).load()?;
    for note in robot.notes() {
        eprintln!("treecal: {note}");
    }
    Ok(robot.import)
}

/// Detects branches, with the tool links named by the user if any.
pub fn branches(import: &UrdfImport, tools: Option<&[String]>) -> Result<Branches> {
    treecal::workflow::source::branches(import, tools)
}

/// Detects branches from the tools the user named, else from the links the measurement CSV's
/// `tool` column names.
pub fn measured_branches(
    import: &UrdfImport,
    tools: Option<&[String]>,
    measurements: &Path,
) -> Result<Branches> {
    let source = MeasurementSource::Csv(measurements.to_path_buf());
    treecal::workflow::source::measured_branches(import, tools, &source)
}

/// The self-collision checker of the robot loaded from `path` (built-in: `None`), with its
/// STL, OBJ and COLLADA meshes resolved next to the URDF or, for `package://` names, in
/// `package_paths` (`--package-path`) and then `ROS_PACKAGE_PATH`; prints one line naming the
/// meshes that could not be found or read.
pub fn checker(
    path: Option<&Path>,
    tree: &KinematicTree,
    package_paths: &[PathBuf],
) -> Result<CollisionChecker> {
    let directory = path
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let search = std::env::var("ROS_PACKAGE_PATH").unwrap_or_default();
    let mut directories = package_paths.to_vec();
    directories.extend(package_dirs(&search));
    let loader = mesh_file_loader(directory, directories);
    let mut checker = CollisionChecker::with_meshes(tree, &CollisionOptions::default(), &loader)?;
    if let Some(line) = skipped_meshes_line(&checker) {
        eprintln!("{line}");
    }
    if checker.loaded_meshes() > 0 {
        // Meshes of neighbouring links often overlap by design; such pairs would reject every
        // configuration. A robot that cannot be sampled (no limits) is left as it is.
        let mut rng = <rand::rngs::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
        let options = treecal::sim::sampling::SamplingOptions::default();
        let samples = treecal::sim::sampling::sample_configurations(
            tree,
            None,
            ALWAYS_COLLIDING_SAMPLES,
            &mut rng,
            &options,
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
            eprintln!(
                "treecal: note: {} link pairs collide at all {} random configurations (their collision meshes overlap by design) and are not checked: {}",
                removed.len(),
                poses.len(),
                names.join(", ")
            );
        }
    }
    Ok(checker)
}

/// How many random configurations decide that a link pair always collides.
const ALWAYS_COLLIDING_SAMPLES: usize = 100;

/// One warning line naming every mesh left out, first the ones not found, then the unreadable
/// ones with their reasons; `None` if none.
fn skipped_meshes_line(checker: &CollisionChecker) -> Option<String> {
    let skipped = checker.skipped_mesh_files();
    if skipped.is_empty() {
        return None;
    }
    let unreadable = checker.unreadable_meshes();
    let mut missing: Vec<&str> = skipped
        .iter()
        .map(String::as_str)
        .filter(|name| !unreadable.iter().any(|(u, _)| u == name))
        .collect();
    missing.sort_unstable();
    missing.dedup();
    let mut unread: Vec<String> = unreadable
        .iter()
        .map(|(name, reason)| format!("{name} ({reason})"))
        .collect();
    unread.sort_unstable();
    unread.dedup();
    let list = |names: Vec<String>| names.join(", ");
    let mut parts = Vec::new();
    if !missing.is_empty() {
        parts.push(format!(
            "{} files not found (package:// names are searched in --package-path, then ROS_PACKAGE_PATH): {}",
            missing.len(),
            list(missing.iter().map(|s| s.to_string()).collect())
        ));
    }
    if !unread.is_empty() {
        parts.push(format!(
            "{} files unreadable: {}",
            unread.len(),
            list(unread)
        ));
    }
    Some(format!(
        "treecal: warning: {} of {} collision meshes are not checked; {}",
        skipped.len(),
        skipped.len() + checker.loaded_meshes(),
        parts.join("; ")
    ))
}
