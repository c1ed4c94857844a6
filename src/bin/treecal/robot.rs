//! Loading the robot a command works on: a URDF path, or the built-in Robonaut.

use std::path::Path;
use treecal::io::{mesh_file_loader, package_dirs};
use treecal::sim::collision::{CollisionChecker, CollisionOptions};
use treecal::urdf::{load_urdf, parse_urdf, UrdfImport};
use treecal::{detect_branches, Branches, KinematicTree, Result};

/// The Robonaut generated from the paper's Table 1, built into the binary so that the main
/// commands work from any directory.
pub const BUILT_IN_ROBONAUT: &str = include_str!("../../../robots/robonaut/robonaut.urdf");

/// The built-in Robonaut's stiffness file (the paper's section 5.2 set-up).
pub const BUILT_IN_STIFFNESS: &str = include_str!("../../../robots/robonaut/stiffness.yaml");

/// Loads `path`, or the built-in Robonaut when `None`; prints loader warnings on stderr.
pub fn load(path: Option<&Path>) -> Result<UrdfImport> {
    let import = match path {
        Some(path) => load_urdf(path)?,
        None => parse_urdf(BUILT_IN_ROBONAUT, "built-in robonaut.urdf")?,
    };
    for warning in &import.warnings {
        eprintln!("treecal: warning: {warning}");
    }
    Ok(import)
}

/// Detects branches, with the tool links named by the user if any.
pub fn branches(import: &UrdfImport, tools: Option<&[String]>) -> Result<Branches> {
    let tree = &import.tree;
    let tools = tools
        .map(|names| {
            names
                .iter()
                .map(|n| tree.link_id(n.trim()))
                .collect::<Result<Vec<_>>>()
        })
        .transpose()?;
    detect_branches(tree, tools.as_deref())
}

/// The URDF text of `path`, or of the built-in Robonaut, with the name to use in messages.
pub fn original_text(path: Option<&Path>) -> Result<(String, String)> {
    match path {
        Some(path) => Ok((
            treecal::limits::read_text(path, treecal::limits::MAX_URDF_BYTES)?,
            path.display().to_string(),
        )),
        None => Ok((
            BUILT_IN_ROBONAUT.to_owned(),
            "built-in robonaut.urdf".to_owned(),
        )),
    }
}

/// The self-collision checker of the robot loaded from `path` (built-in: `None`), with its STL
/// and OBJ meshes resolved next to the URDF or through `ROS_PACKAGE_PATH`; prints which meshes
/// were left out.
pub fn checker(path: Option<&Path>, tree: &KinematicTree) -> Result<CollisionChecker> {
    let directory = path
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let search = std::env::var("ROS_PACKAGE_PATH").unwrap_or_default();
    let loader = mesh_file_loader(directory, package_dirs(&search));
    let checker = CollisionChecker::with_meshes(tree, &CollisionOptions::default(), &loader)?;
    let skipped = checker.skipped_mesh_files();
    if !skipped.is_empty() {
        let mut names: Vec<&str> = skipped.iter().map(String::as_str).collect();
        names.dedup();
        let shown = names.len().min(5);
        eprintln!(
            "treecal: warning: {} collision meshes are not checked (not found, or not STL/OBJ; \
             package:// names are searched in ROS_PACKAGE_PATH): {}{}",
            skipped.len(),
            names[..shown].join(", "),
            if names.len() > shown { ", …" } else { "" }
        );
    }
    Ok(checker)
}
