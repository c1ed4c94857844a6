//! The self-collision checker of a robot, with its collision meshes found as ROS finds them.

use super::source::RobotSource;
use super::Note;
use crate::io::{mesh_file_loader, package_dirs};
use crate::sim::{sample_configurations, SamplingOptions};
use crate::sim::{CollisionCheck, CollisionChecker, CollisionOptions};
use crate::tree::{KinematicTree, LinkId};
use crate::{Error, Result};
use rand::SeedableRng;
use std::path::{Path, PathBuf};

/// How many random configurations decide that a link pair always collides.
const ALWAYS_COLLIDING_SAMPLES: usize = 100;

/// The fraction of random configurations in which a pair that collides counts as colliding
/// always (MoveIt's setup assistant's default).
const MOSTLY_COLLIDING: f64 = 0.95;

/// The self-collision checker of `robot` for `check`: with [`CollisionCheck::Meshes`] its
/// STL, OBJ and COLLADA meshes are resolved next to the URDF or, for `package://` names, in
/// `package_paths` and then `ROS_PACKAGE_PATH`, and a mesh that cannot be used is an error
/// naming the files and the flags; with `PrimitivesOnly` meshes are left out, with `Off`
/// nothing is checked (both said in `notes`). Link pairs that collide everywhere (and are
/// therefore not checked) go to `notes`.
pub fn collision_checker(
    robot: &RobotSource,
    tree: &KinematicTree,
    package_paths: &[PathBuf],
    check: CollisionCheck,
    notes: &mut Vec<Note>,
) -> Result<CollisionChecker> {
    let mut checker = match check {
        CollisionCheck::Off => {
            notes.push(Note::warning(
                "`collision_check` off: configurations are not checked for self-collision",
            ));
            return Ok(CollisionChecker::disabled(tree));
        }
        CollisionCheck::PrimitivesOnly => {
            let checker = CollisionChecker::with_options(tree, &CollisionOptions::default())?;
            if checker.skipped_meshes() > 0 {
                notes.push(Note::warning(format!(
                    "`collision_check` primitives-only: {} collision meshes are not checked, \
                     only the primitive shapes",
                    checker.skipped_meshes()
                )));
            }
            checker
        }
        CollisionCheck::Meshes => {
            let directory = robot
                .path()
                .and_then(Path::parent)
                .map(Path::to_path_buf)
                .unwrap_or_default();
            let search = std::env::var("ROS_PACKAGE_PATH").unwrap_or_default();
            let mut directories = package_paths.to_vec();
            directories.extend(package_dirs(&search));
            let loader = mesh_file_loader(directory, directories);
            let checker =
                CollisionChecker::with_meshes(tree, &CollisionOptions::default(), &loader)?;
            if let Some(line) = skipped_meshes(&checker) {
                return Err(Error::InvalidRobot {
                    origin: robot
                        .path()
                        .map_or_else(|| tree.name().to_owned(), |p| p.display().to_string()),
                    message: format!(
                        "{line}. Configurations would not be checked for self-collision against \
                         these links: make the meshes available (`package_path` DIR names a \
                         folder holding their package), or choose a weaker check explicitly \
                         with `collision_check` primitives-only or `collision_check` off \
                         (stated in the output)"
                    ),
                });
            }
            checker
        }
    };
    // Primitive shapes overlap by design as meshes do (Atlas's coarse hip and ankle boxes):
    // with either, a pair that collides everywhere would reject every configuration.
    ignore_always_colliding(&mut checker, tree, notes);
    if checker.pair_count() == 0 {
        notes.push(Note::warning(nothing_checked(tree, &checker)));
    }
    Ok(checker)
}

/// The warning for a check that has no link pair to test: the URDF has no `<collision>`
/// shapes, or they sit on one link or on neighbours only. A plan run on the robot would then
/// come with no protection at all, so it is said loudly, not only in the statement.
fn nothing_checked(tree: &KinematicTree, checker: &CollisionChecker) -> String {
    format!(
        "'{}' has {} collision shape(s) and no pair of non-adjacent links that both have one: \
         configurations are NOT checked for self-collision; add `<collision>` elements to the \
         URDF's links (or give the meshes with `package_path`), or say `collision_check` off to \
         accept unchecked configurations",
        tree.name(),
        checker.shape_count()
    )
}

/// The self-collision check of generated contact configurations ([`collision_checker`] with
/// the hands of `model`'s tools allowed to touch in a `touch`); `None` with `check` off.
pub fn contact_collisions(
    robot: &RobotSource,
    tree: &KinematicTree,
    model: &crate::McpcModel,
    (package_paths, check): (&[PathBuf], CollisionCheck),
    notes: &mut Vec<Note>,
) -> Result<Option<crate::sim::ContactCollisions>> {
    let mut checker = collision_checker(robot, tree, package_paths, check, notes)?;
    if check == CollisionCheck::Off {
        return Ok(None);
    }
    // Shapes that overlap by design (an ankle's or a hip's coarse boxes) would reject nearly
    // every contact configuration: as MoveIt's setup assistant, drop the pairs that collide in
    // the zero configuration ("default") or in 95 % of random samples ("always").
    let zero: Vec<Vec<crate::math::Pose>> = tree
        .link_poses(&tree.zero_configuration())
        .into_iter()
        .collect();
    let removed_default = checker.ignore_pairs_always_colliding(&zero);
    let samples = random_link_poses(tree);
    let removed_mostly = checker.ignore_pairs_mostly_colliding(&samples, MOSTLY_COLLIDING);
    let removed = pair_names(tree, removed_default.iter().chain(&removed_mostly));
    if !removed.is_empty() {
        notes.push(Note::info(format!(
            "{} link pairs collide in the zero configuration or in {:.0} % of {} random ones \
             (their shapes overlap by design) and are not checked for contact configurations: \
             {}",
            removed.len(),
            MOSTLY_COLLIDING * 100.0,
            samples.len(),
            removed.join(", ")
        )));
    }
    Ok(Some(crate::sim::ContactCollisions::new(
        tree, model, checker,
    )))
}

/// What the outputs say about the self-collision check, e.g. `meshes (12 shapes, 8 of them
/// meshes)`.
pub fn collision_statement(check: CollisionCheck, checker: &CollisionChecker) -> String {
    match check {
        CollisionCheck::Meshes => format!(
            "meshes ({} collision shapes, {} of them meshes)",
            checker.shape_count(),
            checker.loaded_meshes()
        ),
        CollisionCheck::PrimitivesOnly => format!(
            "primitives-only ({} primitive shapes; {} collision meshes NOT checked)",
            checker.shape_count(),
            checker.skipped_meshes()
        ),
        CollisionCheck::Off => "off (configurations NOT checked for self-collision)".into(),
    }
}

/// Shapes of neighbouring links often overlap by design (meshes of a compact wrist, the
/// coarse hip boxes of a humanoid: Atlas's collide in 96–99 of 100 random configurations);
/// such pairs would reject nearly every configuration. As MoveIt's setup assistant, the pairs
/// that collide in [`MOSTLY_COLLIDING`] (95 %) of [`ALWAYS_COLLIDING_SAMPLES`] seeded random
/// configurations are not checked. A robot that cannot be sampled (no limits) is left as it
/// is.
fn ignore_always_colliding(
    checker: &mut CollisionChecker,
    tree: &KinematicTree,
    notes: &mut Vec<Note>,
) {
    let poses = random_link_poses(tree);
    let removed = checker.ignore_pairs_mostly_colliding(&poses, MOSTLY_COLLIDING);
    if !removed.is_empty() {
        notes.push(Note::info(format!(
            "{} link pairs collide in at least {:.0} % of {} random configurations (their collision shapes overlap by design) and are not checked: {}",
            removed.len(),
            MOSTLY_COLLIDING * 100.0,
            poses.len(),
            pair_names(tree, &removed).join(", ")
        )));
    }
}

/// The link poses of [`ALWAYS_COLLIDING_SAMPLES`] seeded random configurations (none for a
/// robot that cannot be sampled).
fn random_link_poses(tree: &KinematicTree) -> Vec<Vec<crate::math::Pose>> {
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(0);
    sample_configurations(
        tree,
        None,
        ALWAYS_COLLIDING_SAMPLES,
        &mut rng,
        &SamplingOptions::default(),
        &[],
    )
    .unwrap_or_default()
    .iter()
    .filter_map(|q| tree.link_poses(q).ok())
    .collect()
}

/// `a–b` for each link pair.
fn pair_names<'a>(
    tree: &KinematicTree,
    pairs: impl IntoIterator<Item = &'a (LinkId, LinkId)>,
) -> Vec<String> {
    pairs
        .into_iter()
        .map(|(a, b)| format!("{}–{}", tree.link(*a).name, tree.link(*b).name))
        .collect()
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
        .map(|(name, reason)| format!("{name} ({})", reason_text(reason, name)))
        .collect();
    unread.sort_unstable();
    unread.dedup();
    let mut parts = Vec::new();
    if !missing.is_empty() {
        parts.push(format!(
            "{} files not found (package:// names are searched in `package_path`, then ROS_PACKAGE_PATH): {}",
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
        "{} of {} collision meshes cannot be used; {}",
        skipped.len(),
        skipped.len() + checker.loaded_meshes(),
        parts.join("; ")
    ))
}

/// `reason` with the `{path:?}` that mesh-loader 0.1 leaves unformatted in some messages
/// ("unsupported or unrecognized file type {path:?}") replaced by the file's name.
fn reason_text(reason: &str, name: &str) -> String {
    reason.replace("{path:?}", &format!("'{name}'"))
}
