//! Shared helpers: robot paths, seeded random configurations, pose comparison.

#![allow(dead_code)]

pub mod cli;
pub mod fixture;
pub mod fuzz;
pub mod second_robot;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};
use treecal::math::Pose;
use treecal::tree::KinematicTree;

pub use fixture::{robonaut_model, robot_model, TestRobot};

/// The repository root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A robot in `robots/`.
pub fn robot(relative: &str) -> PathBuf {
    repo().join("robots").join(relative)
}

/// The shared NASA Robonaut 2 description, read in place (never copied into the repository):
/// `$TREECAL_SHARED_DIR/robots/…`, else `../shared/robots/…` next to the checkout, else
/// `/work/shared/robots/…`.
pub fn robonaut2() -> PathBuf {
    let relative = "robots/robonaut2/robonaut2.urdf";
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(dir) = std::env::var_os("TREECAL_SHARED_DIR") {
        candidates.push(PathBuf::from(dir).join(relative));
    }
    candidates.push(repo().join("../shared").join(relative));
    candidates.push(PathBuf::from("/work/shared").join(relative));
    match candidates.iter().find(|c| c.is_file()) {
        Some(found) => found.clone(),
        None => panic!(
            "the shared Robonaut 2 description was not found at any of {candidates:?}; \
             set TREECAL_SHARED_DIR to the folder that holds robots/robonaut2/robonaut2.urdf"
        ),
    }
}

/// Every URDF in `robots/` (recursively).
pub fn all_repo_robots() -> Vec<PathBuf> {
    let mut found = Vec::new();
    collect(&repo().join("robots"), &mut found);
    found.sort();
    found
}

fn collect(dir: &Path, found: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect(&path, found);
        } else if path.extension().is_some_and(|e| e == "urdf") {
            found.push(path);
        }
    }
}

/// A seeded, version-stable RNG.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A random configuration: within limits where bounded, within ±π (or ±1 m) otherwise.
pub fn random_configuration(tree: &KinematicTree, rng: &mut ChaCha8Rng) -> Vec<f64> {
    tree.dofs()
        .iter()
        .map(|&j| {
            let joint = tree.joint(j);
            let (lower, upper) = match joint.limits {
                Some(l) if l.lower.is_finite() && l.upper.is_finite() && l.upper > l.lower => {
                    (l.lower, l.upper)
                }
                _ if joint.kind == treecal::tree::JointKind::Prismatic => (-1.0, 1.0),
                _ => (-std::f64::consts::PI, std::f64::consts::PI),
            };
            rng.random_range(lower..upper)
        })
        .collect()
}

/// Position distance (m) and rotation angle (rad) between two poses.
pub fn pose_difference(a: &Pose, b: &Pose) -> (f64, f64) {
    (
        (a.translation.vector - b.translation.vector).norm(),
        a.rotation.angle_to(&b.rotation),
    )
}

/// Asserts two poses agree to `tolerance` metres and radians.
#[track_caller]
pub fn assert_pose_eq(a: &Pose, b: &Pose, tolerance: f64, what: &str) {
    let (position, angle) = pose_difference(a, b);
    assert!(
        position <= tolerance && angle <= tolerance,
        "{what}: poses differ by {position:e} m and {angle:e} rad\n{a}\n{b}"
    );
}

/// The branches of `tree`, with the named tool links if given (as `--tools` does).
pub fn branches_with_tools(tree: &KinematicTree, tools: Option<&[&str]>) -> treecal::Branches {
    let tools = tools.map(|names| {
        names
            .iter()
            .map(|n| tree.link_id(n).unwrap_or_else(|e| panic!("{e}")))
            .collect::<Vec<_>>()
    });
    treecal::detect_branches(tree, tools.as_deref()).unwrap_or_else(|e| panic!("{e}"))
}

/// The `robots/` folder of the PyPI package `example-robot-data` (installed by `.ci/run` from
/// `tests/oracle/requirements.txt`): `$TREECAL_EXAMPLE_ROBOT_DATA` if set, else found through
/// `python3` (the package installs under `site-packages/cmeel.prefix/share/example-robot-data`).
/// `None` (after a note) when it is not installed; panics instead with `TREECAL_REQUIRE_TOOLS=1`.
pub fn example_robot_data() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("TREECAL_EXAMPLE_ROBOT_DATA") {
        return Some(PathBuf::from(dir));
    }
    let probe = std::process::Command::new("python3")
        .args([
            "-c",
            "import sysconfig; print(sysconfig.get_paths()['purelib'])",
        ])
        .stdin(std::process::Stdio::null())
        .output();
    let found = probe.ok().and_then(|output| {
        let purelib = String::from_utf8_lossy(&output.stdout).trim().to_owned();
        let dir = PathBuf::from(purelib).join("cmeel.prefix/share/example-robot-data/robots");
        dir.is_dir().then_some(dir)
    });
    if found.is_none() {
        let message = "the PyPI package example-robot-data is not installed \
                       (python3 -m pip install -r tests/oracle/requirements.txt)";
        if std::env::var("TREECAL_REQUIRE_TOOLS").is_ok_and(|v| v == "1") {
            panic!("TREECAL_REQUIRE_TOOLS=1 but {message}");
        }
        eprintln!("note: skipped: {message}");
    }
    found
}

/// A URDF of `example-robot-data`, by its path under `robots/`
/// (e.g. `"talos_data/robots/talos_reduced.urdf"`); `None` as [`example_robot_data`].
pub fn example_robot(relative: &str) -> Option<PathBuf> {
    example_robot_data().map(|dir| dir.join(relative))
}

/// `robots/humanoid` with each palm (`l_hand`, `r_hand`) as the child link of its wrist roll
/// joint, as on real humanoids: the `*_wrist_roll_link` links and the fixed `*_hand_joint`s are
/// removed, and the wrist roll joints get oblique origins (and, on the right, an oblique axis),
/// so the palm frames are neither aligned with nor offset along the axis in a trivial way. The
/// fingers are removed, so the palms are leaf links.
pub fn humanoid_with_palms_on_wrists() -> String {
    let mut text = std::fs::read_to_string(robot("humanoid/humanoid.urdf")).unwrap();
    for (side, rpy, axis) in [
        ("l", "0.3 -0.2 0.7", "0 0 1"),
        ("r", "-0.25 0.15 -0.6", "0.6 0 0.8"),
    ] {
        let remove = |text: &mut String, start: &str, end: &str| {
            let from = text.find(start).unwrap_or_else(|| panic!("{start}"));
            let to = from + text[from..].find(end).unwrap() + end.len();
            text.replace_range(from..to, "");
        };
        remove(
            &mut text,
            &format!("<link name=\"{side}_wrist_roll_link\">"),
            "</link>",
        );
        remove(
            &mut text,
            &format!("<joint name=\"{side}_hand_joint\" type=\"fixed\">"),
            "</joint>",
        );
        let old = format!(
            "<child link=\"{side}_wrist_roll_link\"/>\n    <origin xyz=\"0 0 -0.03\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 0 1\"/>"
        );
        let new = format!(
            "<child link=\"{side}_hand\"/>\n    <origin xyz=\"0 0 -0.06\" rpy=\"{rpy}\"/>\n    <axis xyz=\"{axis}\"/>"
        );
        assert!(text.contains(&old), "{old}");
        text = text.replace(&old, &new);
        // The fingers go: a palm with child links keeps its place and gets a marker link on
        // export (tests/export.rs, `tool_with_children_*`); these palms are leaves.
        for finger in ["left", "right"] {
            remove(
                &mut text,
                &format!("<joint name=\"{side}_finger_{finger}\""),
                "</joint>",
            );
            remove(
                &mut text,
                &format!("<link name=\"{side}_finger_{finger}_link\">"),
                "</link>",
            );
        }
    }
    text
}

/// The built-in Robonaut with its stiffness file and collision checker: what the simulation
/// tests (tests/simulate.rs, tests/robust.rs) run trials on.
pub struct SimulatedRobot {
    pub tree: KinematicTree,
    pub branches: treecal::Branches,
    pub nominal: treecal::McpcModel,
    pub flexibility: treecal::kinematics::FlexibilityModel,
    pub checker: treecal::sim::CollisionChecker,
}

impl SimulatedRobot {
    /// A trial set-up whose model flexibility equals the truth's.
    pub fn setup(&self) -> treecal::sim::Setup<'_> {
        treecal::sim::Setup {
            tree: &self.tree,
            branches: &self.branches,
            nominal: &self.nominal,
            truth_flexibility: &self.flexibility,
            model_flexibility: &self.flexibility,
            checker: Some(&self.checker),
        }
    }
}

/// [`SimulatedRobot`] for `robots/robonaut/`.
pub fn simulated_robonaut() -> SimulatedRobot {
    let tree = treecal::load_urdf(&robot("robonaut/robonaut.urdf"))
        .unwrap()
        .tree;
    let branches = treecal::detect_branches(&tree, None).unwrap();
    let nominal = treecal::McpcModel::from_tree(&tree, &branches).unwrap();
    let stiffness =
        treecal::io::read_stiffness(&robot("robonaut/stiffness.yaml"), &tree, &nominal).unwrap();
    let flexibility =
        treecal::kinematics::FlexibilityModel::new(&tree, &nominal, &stiffness).unwrap();
    let checker = treecal::sim::CollisionChecker::new(&tree).unwrap();
    SimulatedRobot {
        tree,
        branches,
        nominal,
        flexibility,
        checker,
    }
}

/// A rigid simultaneous calibration in the root frame with the given noise (m, rad).
pub fn rigid_simultaneous_run(
    tree: &KinematicTree,
    branches: &treecal::Branches,
    nominal: &treecal::McpcModel,
    sigmas: [f64; 2],
    data: &[treecal::measurement::Measurement],
    validation: &[treecal::measurement::Measurement],
) -> treecal::Result<treecal::calibration::CalibrationRun> {
    let options = treecal::calibration::IdentificationOptions {
        position_sigma: sigmas[0],
        rotation_sigma: sigmas[1],
        ..Default::default()
    };
    let plan = treecal::calibration::Plan::simultaneous();
    let input = treecal::calibration::CalibrationInput {
        tree,
        branches,
        nominal,
        flexibility: None,
        plan: &plan,
        options: &options,
        measurement_frame: treecal::calibration::MeasurementFrame::Base,
        diagnose_columns: true,
    };
    treecal::calibration::run_calibration(&input, data, validation)
}
