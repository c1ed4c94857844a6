//! Cross-check of treecal's forward kinematics against an independent implementation:
//! Pinocchio, through `tests/oracle/pinocchio_fk.py`.
//!
//! For every robot in `robots/` and for Robonaut 2, at 50 seeded random configurations, both
//! the URDF forward kinematics (`KinematicTree::link_poses`, every link) and the MCPC model
//! (`McpcModel::tool_poses` and `McpcModel::link_poses`) must agree with Pinocchio to 1e-9 m
//! and 1e-9 rad.
//!
//! Needs `python3` with Pinocchio (`python3 -m pip install -r tests/oracle/requirements.txt`).
//! Without it the tests print a note and pass, unless `TREECAL_REQUIRE_TOOLS=1` is set (as in
//! CI), in which case they fail.

use crate::common::*;
use serde_json::{json, Value};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use treecal::math::Pose;
use treecal::tree::KinematicTree;
use treecal::{detect_branches, load_urdf, McpcModel};

/// Number of random configurations per robot.
const CONFIGURATIONS: usize = 50;
/// Position (m) and rotation (rad) tolerance.
const TOLERANCE: f64 = 1e-9;
/// At most this many individual disagreements are listed in a failure message.
const MAX_LISTED: usize = 10;

pub(crate) fn oracle_script() -> PathBuf {
    repo().join("tests/oracle/pinocchio_fk.py")
}

/// Whether the oracle can run. Returns `false` (after a loud note) when python3 or Pinocchio
/// is missing, and panics instead if `TREECAL_REQUIRE_TOOLS=1`.
pub(crate) fn oracle_available() -> bool {
    let probe = Command::new("python3")
        .args(["-c", "import pinocchio"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output();
    let problem = match probe {
        Ok(output) if output.status.success() => return true,
        Ok(output) => format!(
            "`python3 -c \"import pinocchio\"` failed ({}): {}",
            output.status,
            String::from_utf8_lossy(&output.stderr)
                .lines()
                .rev()
                .find(|l| !l.trim().is_empty())
                .unwrap_or("")
                .trim()
        ),
        Err(e) => format!("cannot run python3: {e}"),
    };
    let required = std::env::var("TREECAL_REQUIRE_TOOLS").is_ok_and(|v| v == "1");
    if required {
        panic!(
            "TREECAL_REQUIRE_TOOLS=1 but the Pinocchio oracle is unavailable: {problem}\n\
             install it with: python3 -m pip install -r tests/oracle/requirements.txt"
        );
    }
    // Written straight to the process's stderr, not with `eprintln!`: libtest captures
    // `eprintln!` output of passing tests, and a skip must not go unnoticed.
    let _ = writeln!(
        std::io::stderr().lock(),
        "\n!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!\n\
         !!! SKIPPED: forward-kinematics cross-check against Pinocchio (tests/oracle.rs)\n\
         !!! reason: {problem}\n\
         !!! enable it with: python3 -m pip install -r tests/oracle/requirements.txt\n\
         !!! (set TREECAL_REQUIRE_TOOLS=1 to make this a failure instead of a skip)\n\
         !!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!\n"
    );
    false
}

/// Runs the oracle once for a whole batch of configurations; returns, per configuration,
/// root_from_link of every requested link, in `links` order.
pub(crate) fn pinocchio_poses(
    urdf: &Path,
    tree: &KinematicTree,
    links: &[String],
    configurations: &[Vec<f64>],
) -> Vec<Vec<Pose>> {
    let joint_values: Vec<Value> = configurations
        .iter()
        .map(|q| joint_values_json(tree, q))
        .collect();
    let request = json!({ "links": links, "configurations": joint_values }).to_string();

    let mut child = Command::new("python3")
        .arg(oracle_script())
        .arg(urdf)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start python3 {}: {e}", oracle_script().display()));
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || stdin.write_all(request.as_bytes()));
    let output = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap_or_else(|e| {
        panic!(
            "{}: writing the request to the oracle failed: {e}\nstderr:\n{}",
            urdf.display(),
            String::from_utf8_lossy(&output.stderr)
        )
    });
    assert!(
        output.status.success(),
        "{}: pinocchio_fk.py failed ({}):\n{}",
        urdf.display(),
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );

    let response: Value = serde_json::from_slice(&output.stdout)
        .unwrap_or_else(|e| panic!("{}: oracle output is not JSON: {e}", urdf.display()));
    let poses = response["poses"]
        .as_array()
        .unwrap_or_else(|| panic!("{}: oracle response has no \"poses\" list", urdf.display()));
    assert_eq!(poses.len(), configurations.len(), "{}", urdf.display());
    poses
        .iter()
        .map(|per_link| {
            links
                .iter()
                .map(|link| {
                    let numbers: Vec<f64> = per_link[link.as_str()]
                        .as_array()
                        .unwrap_or_else(|| panic!("oracle: no pose for link '{link}'"))
                        .iter()
                        .map(|x| x.as_f64().expect("oracle: non-numeric matrix entry"))
                        .collect();
                    pose_from_row_major(&numbers, link)
                })
                .collect()
        })
        .collect()
}

/// The value of every movable joint (mimic joints included, computed by treecal) by name.
pub(crate) fn joint_values_json(tree: &KinematicTree, q: &[f64]) -> Value {
    let mut values = serde_json::Map::new();
    for (index, joint) in tree.joints().iter().enumerate() {
        if joint.kind.is_movable() {
            let id = treecal::tree::JointId(index);
            values.insert(joint.name.clone(), json!(tree.joint_value(id, q)));
        }
    }
    Value::Object(values)
}

/// A 4×4 homogeneous transform, row-major, as a pose.
pub(crate) fn pose_from_row_major(m: &[f64], link: &str) -> Pose {
    assert_eq!(
        m.len(),
        16,
        "oracle: pose of '{link}' has {} entries",
        m.len()
    );
    assert!(
        m[12] == 0.0 && m[13] == 0.0 && m[14] == 0.0 && m[15] == 1.0,
        "oracle: pose of '{link}' has bottom row {:?}",
        &m[12..]
    );
    let rotation = nalgebra::Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    let orthonormality = (rotation.transpose() * rotation - nalgebra::Matrix3::identity()).norm();
    assert!(
        orthonormality < 1e-12,
        "oracle: rotation of '{link}' is off orthonormal by {orthonormality:e}"
    );
    let rotation = nalgebra::UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(rotation),
    );
    Pose::from_parts(nalgebra::Translation3::new(m[3], m[7], m[11]), rotation)
}

/// A pose at full precision: translation and quaternion (x, y, z, w).
fn show(pose: &Pose) -> String {
    format!(
        "p = {:?}, quat_xyzw = {:?}",
        pose.translation.vector.as_slice(),
        pose.rotation.coords.as_slice()
    )
}

/// Largest differences seen for one kind of comparison, and every disagreement.
#[derive(Default)]
struct Tally {
    position: f64,
    rotation: f64,
    compared: usize,
    failures: Vec<String>,
}

impl Tally {
    fn compare(&mut self, what: &str, configuration: usize, q: &[f64], ours: &Pose, theirs: &Pose) {
        let (position, rotation) = pose_difference(ours, theirs);
        self.position = self.position.max(position);
        self.rotation = self.rotation.max(rotation);
        self.compared += 1;
        // `!(x <= tol)` also catches NaN.
        if !(position <= TOLERANCE && rotation <= TOLERANCE) {
            self.failures.push(format!(
                "{what}, configuration #{configuration}: {position:e} m, {rotation:e} rad\n  \
                 q = {q:?}\n  treecal:   {}\n  pinocchio: {}",
                show(ours),
                show(theirs)
            ));
        }
    }
}

fn check_robot(path: &Path) -> Vec<String> {
    let robot = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tree = load_urdf(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .tree;
    let branches =
        detect_branches(&tree, None).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let model = McpcModel::from_tree(&tree, &branches)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));

    let mut rng = rng(20_240_531);
    let configurations: Vec<Vec<f64>> = (0..CONFIGURATIONS)
        .map(|_| random_configuration(&tree, &mut rng))
        .collect();
    // Every link, in tree order (so index = LinkId).
    let links: Vec<String> = tree.links().iter().map(|l| l.name.clone()).collect();
    let oracle = pinocchio_poses(path, &tree, &links, &configurations);

    let mut urdf_fk = Tally::default();
    let mut mcpc_tools = Tally::default();
    let mut mcpc_links = Tally::default();
    for (c, (q, theirs)) in configurations.iter().zip(&oracle).enumerate() {
        let ours = tree.link_poses(q).unwrap();
        for (index, link) in tree.links().iter().enumerate() {
            let what = format!("{robot}: URDF FK of link '{}'", link.name);
            urdf_fk.compare(&what, c, q, &ours[index], &theirs[index]);
        }
        for (t, pose) in model.tool_poses(q).iter().enumerate() {
            let link = model.tools()[t].link;
            let what = format!("{robot}: MCPC tool {t} (link '{}')", tree.link(link).name);
            mcpc_tools.compare(&what, c, q, pose, &theirs[link.0]);
        }
        for (f, pose) in model.link_poses(q).iter().enumerate() {
            let joint = tree.joint(model.frames()[f].joint);
            let what = format!(
                "{robot}: MCPC frame {f} (joint '{}', link '{}')",
                joint.name,
                tree.link(joint.child).name
            );
            mcpc_links.compare(&what, c, q, pose, &theirs[joint.child.0]);
        }
    }

    eprintln!(
        "oracle {robot}: {} links, {} dofs, {} MCPC frames, {} tools, {CONFIGURATIONS} configurations",
        tree.links().len(),
        tree.dof_count(),
        model.frames().len(),
        model.tools().len()
    );
    for (name, tally) in [
        ("URDF link_poses", &urdf_fk),
        ("MCPC tool_poses", &mcpc_tools),
        ("MCPC link_poses", &mcpc_links),
    ] {
        eprintln!(
            "oracle {robot}:   {name:<16} max |Δp| = {:.3e} m, max |Δθ| = {:.3e} rad over {} poses, {} above {TOLERANCE:e}",
            tally.position,
            tally.rotation,
            tally.compared,
            tally.failures.len()
        );
    }
    assert!(urdf_fk.compared > 0 && mcpc_tools.compared > 0 && mcpc_links.compared > 0);

    [urdf_fk, mcpc_tools, mcpc_links]
        .into_iter()
        .flat_map(|t| t.failures)
        .collect()
}

fn check_robots(paths: &[PathBuf]) {
    let failures: Vec<String> = paths.iter().flat_map(|p| check_robot(p)).collect();
    if !failures.is_empty() {
        let listed: Vec<&str> = failures
            .iter()
            .take(MAX_LISTED)
            .map(|s| s.as_str())
            .collect();
        panic!(
            "{} poses disagree with Pinocchio beyond {TOLERANCE:e} m / rad (first {}):\n{}",
            failures.len(),
            listed.len(),
            listed.join("\n")
        );
    }
}

#[test]
fn oracle_pinocchio_agrees_on_every_repo_robot() {
    if !oracle_available() {
        return;
    }
    let robots = all_repo_robots();
    assert!(
        robots.len() >= 3,
        "expected robots in robots/, found {robots:?}"
    );
    check_robots(&robots);
}

#[test]
fn oracle_pinocchio_agrees_on_robonaut2() {
    if !oracle_available() {
        return;
    }
    check_robots(&[robonaut2()]);
}
