//! The real-robot corpus: every URDF of the PyPI package `example-robot-data` (69 files in
//! 6.0.0: humanoids, quadrupeds, arms, hands, drones, mobile manipulators).
//!
//! - Every file `check_urdf` accepts loads; the ones treecal refuses are listed in
//!   [`REFUSED`] with the reason (check_urdf refuses them too), and the refusal is checked to be
//!   that one.
//! - Forward kinematics of every link at [`CONFIGURATIONS`] seeded random configurations
//!   equals Pinocchio's to 1e-9 m and rad. All robots go to Pinocchio in one `python3` call.
//!   Mimic joints: treecal computes their values and hands every movable joint's value to the
//!   oracle, which builds the model with `mimic=False` (see tests/oracle/pinocchio_fk.py) and
//!   checks each mimic value independently against the URDF's `<mimic>` element; a mimic of
//!   a joint that does not exist (Alex with Psyonic hands) is an independent joint for both.
//!
//! Skipped with a note without example-robot-data, check_urdf or Pinocchio, unless
//! `TREECAL_REQUIRE_TOOLS=1` (as in CI).

use crate::common::*;
use crate::oracle::{joint_values_json, oracle_available, oracle_script, pose_from_row_major};
use serde_json::{json, Value};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use treecal::load_urdf;
use treecal::tree::KinematicTree;

/// Random configurations per robot.
const CONFIGURATIONS: usize = 5;
/// Position (m) and rotation (rad) tolerance.
const TOLERANCE: f64 = 1e-9;
/// The Debian liburdfdom-tools binary (a different `check_urdf` may come first on PATH).
const CHECK_URDF: &str = "/usr/bin/check_urdf";

/// Corpus files treecal refuses, with the reason. check_urdf refuses each of them too.
const REFUSED: &[(&str, &str)] = &[(
    // A xacro-era stub: `<robot>` holding only a macro call, no links.
    "ur_description/urdf/ur3.urdf",
    "the robot has no <link> elements",
)];

/// Every URDF under `dir`, as paths relative to it, sorted.
fn corpus(dir: &Path) -> Vec<String> {
    fn walk(dir: &Path, found: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                walk(&path, found);
            } else if path.extension().is_some_and(|e| e == "urdf") {
                found.push(path);
            }
        }
    }
    let mut found = Vec::new();
    walk(dir, &mut found);
    let mut relative: Vec<String> = found
        .iter()
        .map(|p| p.strip_prefix(dir).unwrap().to_string_lossy().into_owned())
        .collect();
    relative.sort();
    relative
}

/// Whether check_urdf accepts `path`; `None` (after a note) when it is not installed.
fn check_urdf_accepts(path: &Path) -> Option<bool> {
    if !Path::new(CHECK_URDF).is_file() {
        let message = format!("{CHECK_URDF} is missing (apt-get install liburdfdom-tools)");
        if std::env::var("TREECAL_REQUIRE_TOOLS").is_ok_and(|v| v == "1") {
            panic!("TREECAL_REQUIRE_TOOLS=1 but {message}");
        }
        let _ = writeln!(
            std::io::stderr().lock(),
            "\n!!! SKIPPED: the check_urdf half of tests/corpus.rs: {message}\n"
        );
        return None;
    }
    let output = Command::new(CHECK_URDF)
        .arg(path)
        .stdin(Stdio::null())
        .output()
        .unwrap_or_else(|e| panic!("cannot run {CHECK_URDF}: {e}"));
    Some(output.status.success())
}

#[test]
fn corpus_loads_exactly_what_check_urdf_accepts() {
    let Some(dir) = example_robot_data() else {
        return;
    };
    let files = corpus(&dir);
    assert!(
        files.len() >= 60,
        "expected the 69 URDFs of example-robot-data, found {}",
        files.len()
    );
    let mut problems = Vec::new();
    let mut loaded = 0;
    for file in &files {
        let path = dir.join(file);
        let result = load_urdf(&path);
        let refused = REFUSED.iter().find(|(f, _)| f == file);
        match (&result, refused) {
            (Ok(_), None) => loaded += 1,
            (Err(e), Some((_, reason))) if e.to_string().contains(reason) => {}
            (Err(e), _) => problems.push(format!("{file}: refused: {e}")),
            (Ok(_), Some(_)) => problems.push(format!("{file}: loads but is listed as refused")),
        }
        if let Some(accepted) = check_urdf_accepts(&path) {
            if accepted != result.is_ok() {
                problems.push(format!(
                    "{file}: check_urdf {}, treecal {}",
                    if accepted { "accepts" } else { "refuses" },
                    if result.is_ok() {
                        "loads it"
                    } else {
                        "refuses it"
                    }
                ));
            }
        }
    }
    eprintln!(
        "corpus: {loaded} of {} URDFs load; refused as documented: {REFUSED:?}",
        files.len()
    );
    assert!(problems.is_empty(), "\n{}", problems.join("\n"));
}

/// One robot's share of the batch request.
struct Robot {
    file: String,
    tree: KinematicTree,
    configurations: Vec<Vec<f64>>,
}

#[test]
fn corpus_forward_kinematics_agrees_with_pinocchio() {
    let Some(dir) = example_robot_data() else {
        return;
    };
    if !oracle_available() {
        return;
    }
    let mut rng = rng(20_261_123);
    let robots: Vec<Robot> = corpus(&dir)
        .into_iter()
        .filter(|file| !REFUSED.iter().any(|(f, _)| f == file))
        .map(|file| {
            let tree = load_urdf(&dir.join(&file))
                .unwrap_or_else(|e| panic!("{e}"))
                .tree;
            let configurations = (0..CONFIGURATIONS)
                .map(|_| random_configuration(&tree, &mut rng))
                .collect();
            Robot {
                file,
                tree,
                configurations,
            }
        })
        .collect();
    let request: Vec<Value> = robots
        .iter()
        .map(|r| {
            json!({
                "urdf": dir.join(&r.file),
                "links": r.tree.links().iter().map(|l| l.name.clone()).collect::<Vec<_>>(),
                "configurations": r.configurations.iter()
                    .map(|q| joint_values_json(&r.tree, q)).collect::<Vec<_>>(),
            })
        })
        .collect();
    let results = run_batch(&json!({ "robots": request }).to_string());
    assert_eq!(results.len(), robots.len());

    let (mut worst, mut worst_at, mut poses) = (0.0f64, String::new(), 0usize);
    let mut failures = Vec::new();
    for (robot, result) in robots.iter().zip(&results) {
        let theirs = result["poses"].as_array().expect("oracle: no poses");
        for (c, q) in robot.configurations.iter().enumerate() {
            let ours = robot.tree.link_poses(q).unwrap();
            for (index, link) in robot.tree.links().iter().enumerate() {
                let numbers: Vec<f64> = theirs[c][link.name.as_str()]
                    .as_array()
                    .unwrap_or_else(|| panic!("{}: no pose for '{}'", robot.file, link.name))
                    .iter()
                    .map(|x| x.as_f64().expect("oracle: not a number"))
                    .collect();
                let pinocchio = pose_from_row_major(&numbers, &link.name);
                let (position, angle) = pose_difference(&ours[index], &pinocchio);
                let error = position.max(angle);
                poses += 1;
                if error > worst || error.is_nan() {
                    worst = error;
                    worst_at = format!("{} link '{}' configuration {c}", robot.file, link.name);
                }
                if error.is_nan() || error > TOLERANCE {
                    failures.push(format!(
                        "{}: link '{}', configuration {c}: {position:e} m, {angle:e} rad",
                        robot.file, link.name
                    ));
                }
            }
        }
    }
    eprintln!(
        "corpus FK: {} robots, {poses} link poses, max difference from Pinocchio {worst:.3e} (at {worst_at})",
        robots.len()
    );
    assert!(
        failures.is_empty(),
        "{} link poses differ from Pinocchio beyond {TOLERANCE:e} (first 10):\n{}",
        failures.len(),
        failures
            .iter()
            .take(10)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
}

/// Runs the oracle once in batch mode; its `results`.
fn run_batch(request: &str) -> Vec<Value> {
    let mut child = Command::new("python3")
        .arg(oracle_script())
        .arg("--batch")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start python3: {e}"));
    let mut stdin = child.stdin.take().unwrap();
    let request = request.to_owned();
    let writer = std::thread::spawn(move || stdin.write_all(request.as_bytes()));
    let output = child.wait_with_output().unwrap();
    let _ = writer.join();
    assert!(
        output.status.success(),
        "pinocchio_fk.py --batch failed ({}):\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    let response: Value =
        serde_json::from_slice(&output.stdout).expect("oracle output is not JSON");
    response["results"]
        .as_array()
        .expect("oracle response has no results")
        .clone()
}
