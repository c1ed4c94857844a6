//! `treecal from-mcpc` and `urdf_from_mcpc_table`: the committed Robonaut URDF is exactly what
//! the generator makes of Table 1, shows Table 1 again under `inspect`, has the table's forward
//! kinematics, passes urdfdom's `check_urdf`; bad tables are refused with clear messages.

use crate::common::cli::*;
use crate::common::*;
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Stdio};
use treecal::io::{parse_mcpc_table, read_mcpc_table};
use treecal::kinematics::{FrameKind, McpcTable, SINGULARITY_THRESHOLD};
use treecal::math::{pose, rot_z, translation, Pose, Vec3};
use treecal::{parse_urdf, urdf_from_mcpc_table};

const TABLE1: &str = "robots/robonaut/table1.yaml";
const ROBONAUT: &str = "robots/robonaut/robonaut.urdf";

fn table1() -> McpcTable {
    read_mcpc_table(&repo().join(TABLE1)).unwrap_or_else(|e| panic!("{e}"))
}

// ---------------------------------------------------------------------------------------------
// 1. The committed URDF is the generator's output.

#[test]
fn committed_robonaut_urdf_is_regenerated_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("robonaut.urdf");
    let run = treecal(&["from-mcpc", TABLE1, "-o", path_str(&out)]);
    assert!(run.success, "from-mcpc failed\n{run}");
    assert!(run.stdout.is_empty(), "{run}");
    assert!(run.stderr.contains("wrote"), "{run}");
    let generated = std::fs::read(&out).unwrap();
    let committed = std::fs::read(repo().join(ROBONAUT)).unwrap();
    if generated != committed {
        let generated = String::from_utf8_lossy(&generated);
        let committed = String::from_utf8_lossy(&committed);
        let first = generated
            .lines()
            .zip(committed.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| generated.lines().count().min(committed.lines().count()));
        panic!(
            "{ROBONAUT} differs from `treecal from-mcpc {TABLE1}` from line {}:\n  committed: {:?}\n  generated: {:?}\n\
             regenerate it with: cargo run -- from-mcpc {TABLE1} -o {ROBONAUT}",
            first + 1,
            committed.lines().nth(first),
            generated.lines().nth(first)
        );
    }

    // The library gives the same text, named by the table's file name only.
    let text = urdf_from_mcpc_table(&table1(), "table1.yaml");
    assert_eq!(text.as_bytes(), &committed[..]);
}

#[test]
fn generator_output_does_not_depend_on_the_table_path() {
    // Same table through an absolute path and a copy elsewhere: same bytes.
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(repo().join(TABLE1), dir.path().join("table1.yaml")).unwrap();
    let out = dir.path().join("a.urdf");
    let run = treecal(&[
        "from-mcpc",
        path_str(&dir.path().join("table1.yaml")),
        "--output",
        path_str(&out),
    ]);
    assert!(run.success, "{run}");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(repo().join(ROBONAUT)).unwrap()
    );
}

// ---------------------------------------------------------------------------------------------
// 2. `inspect` shows Table 1 again.

#[test]
fn inspect_of_generated_robonaut_shows_table1() {
    let run = treecal(&["inspect", ROBONAUT, "--format", "json"]);
    assert!(run.success, "{run}");
    let report: Value =
        serde_json::from_str(&run.stdout).unwrap_or_else(|e| panic!("JSON: {e}\n{run}"));
    assert_eq!(report["mcpc"]["parameter_count"], 64);
    let rows = report["mcpc"]["rows"].as_array().unwrap();
    let row_named = |name: &str| -> &Value {
        rows.iter()
            .find(|r| r["name"] == name)
            .unwrap_or_else(|| panic!("inspect has no row '{name}'"))
    };
    let number = |row: &Value, key: &str| -> f64 {
        row[key]
            .as_f64()
            .unwrap_or_else(|| panic!("row {}: {key} is {}", row["name"], row[key]))
    };
    #[track_caller]
    fn close(got: f64, want: f64, what: &str) {
        assert!(
            (got - want).abs() <= 1e-6,
            "{what}: inspect shows {got}, Table 1 has {want}"
        );
    }

    let singular = ["left_joint1", "right_joint1", "right_joint2"];
    let table = table1();
    let mut compared = 0;
    let mut table_rows = 0;
    for branch in &table.branches {
        for row in &branch.rows {
            table_rows += 1;
            let shown = row_named(&row.joint);
            let reparametrised = shown["reparametrised"].as_bool().unwrap();
            assert_eq!(
                reparametrised,
                singular.contains(&row.joint.as_str()),
                "{}: reparametrised",
                row.joint
            );
            if reparametrised {
                let beta = number(shown, "beta_deg");
                assert!(beta.abs() <= 45.0, "{}: β = {beta}°", row.joint);
                continue;
            }
            let what = |p: &str| format!("{} {p}", row.joint);
            close(
                number(shown, "alpha_deg"),
                row.alpha.to_degrees(),
                &what("α"),
            );
            close(number(shown, "beta_deg"), row.beta.to_degrees(), &what("β"));
            close(number(shown, "x_mm"), row.x * 1e3, &what("x"));
            close(number(shown, "y_mm"), row.y * 1e3, &what("y"));
            assert!(shown["gamma_deg"].is_null() && shown["z_mm"].is_null());
            compared += 1;
        }
        if let Some(tool) = &branch.tool {
            table_rows += 1;
            let shown = row_named(&tool.link);
            assert_eq!(shown["kind"], "tool");
            assert_eq!(shown["reparametrised"], false, "{}", tool.link);
            let what = |p: &str| format!("{} {p}", tool.link);
            close(
                number(shown, "alpha_deg"),
                tool.alpha.to_degrees(),
                &what("α"),
            );
            close(
                number(shown, "beta_deg"),
                tool.beta.to_degrees(),
                &what("β"),
            );
            close(
                number(shown, "gamma_deg"),
                tool.gamma.to_degrees(),
                &what("γ"),
            );
            close(number(shown, "x_mm"), tool.x * 1e3, &what("x"));
            close(number(shown, "y_mm"), tool.y * 1e3, &what("y"));
            close(number(shown, "z_mm"), tool.z * 1e3, &what("z"));
            compared += 1;
        }
    }
    assert_eq!(table_rows, 13 + 2, "Table 1 has 13 joints and 2 tools");
    assert_eq!(
        rows.len(),
        table_rows,
        "inspect shows one row per table row"
    );
    assert_eq!(compared, table_rows - singular.len());
    // Every row, re-parametrised or not, is off the singularity.
    for row in rows {
        let beta = number(row, "beta_deg");
        assert!(
            beta.abs() <= SINGULARITY_THRESHOLD.to_degrees() + 1e-9,
            "{}: β = {beta}°",
            row["name"]
        );
    }
}

/// Table 1 values as printed (deg, mm), straight from the YAML text, against the SI table
/// `read_mcpc_table` returns: guards the unit conversion the other tests rely on.
#[test]
fn table1_is_read_in_si_units() {
    let table = table1();
    assert_eq!(table.robot, "robonaut");
    assert_eq!(table.base_link, "base_link");
    let names: Vec<&str> = table.branches.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, ["torso", "left", "right"]);
    let left = &table.branches[1];
    assert_eq!(left.parent.as_deref(), Some("torso"));
    assert_eq!(left.rows.len(), 6);
    assert_eq!(table.branches[2].rows.len(), 5);
    assert!((left.rows[0].beta - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert!((left.rows[0].x - 0.110).abs() < 1e-15);
    assert!((left.rows[4].y + 0.300).abs() < 1e-15);
    assert!((left.rows[0].limits.1 - 170f64.to_radians()).abs() < 1e-15);
    let tool = left.tool.as_ref().unwrap();
    assert!((tool.gamma + std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert!((tool.z - 0.145).abs() < 1e-15);
}

// ---------------------------------------------------------------------------------------------
// 3. The generated URDF has the table's forward kinematics.

/// Root-from-link of every table link (rows and tools) at configuration `q` of `tree`,
/// composed from the table alone: base → parent branches' rows → rows (T_row · motion) → tool.
fn table_link_poses(table: &McpcTable, joint_value: impl Fn(&str) -> f64) -> Vec<(String, Pose)> {
    let mut poses: Vec<(String, Pose)> = Vec::new();
    // Pose of each branch's last moved frame, by branch name.
    let mut branch_end: Vec<(&str, Pose)> = Vec::new();
    for branch in &table.branches {
        let mut current = match &branch.parent {
            None => Pose::identity(),
            Some(parent) => {
                branch_end
                    .iter()
                    .find(|(n, _)| n == parent)
                    .unwrap_or_else(|| panic!("parent '{parent}' not composed yet"))
                    .1
            }
        };
        for row in &branch.rows {
            let value = joint_value(&row.joint);
            let motion = match row.kind {
                FrameKind::Revolute => pose(Vec3::zeros(), rot_z(value)),
                FrameKind::Prismatic => translation(0.0, 0.0, value),
            };
            current = current * row.transform() * motion;
            poses.push((row.link.clone(), current));
        }
        branch_end.push((&branch.name, current));
        if let Some(tool) = &branch.tool {
            poses.push((tool.link.clone(), current * tool.transform()));
        }
    }
    poses
}

/// Generates the URDF of `table`, loads it, and compares its FK with the table's at random
/// configurations.
fn check_generated_fk(table: &McpcTable, expected_links: usize) {
    let text = urdf_from_mcpc_table(table, "x");
    let import = parse_urdf(&text, "generated").unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert!(import.warnings.is_empty(), "{:?}", import.warnings);
    let tree = import.tree;
    assert_eq!(tree.name(), table.robot);
    assert_eq!(tree.link(tree.root()).name, table.base_link);
    let rows: usize = table.branches.iter().map(|b| b.rows.len()).sum();
    assert_eq!(tree.dof_count(), rows);

    let mut rng = rng(2017);
    for _ in 0..100 {
        let q = random_configuration(&tree, &mut rng);
        let value = |joint: &str| tree.joint_value(tree.joint_id(joint).unwrap(), &q);
        let expected = table_link_poses(table, value);
        assert_eq!(expected.len(), expected_links);
        let poses = tree.link_poses(&q).unwrap();
        for (link, want) in &expected {
            let id = tree.link_id(link).unwrap();
            assert_pose_eq(&poses[id.0], want, 1e-9, link);
            // link_pose walks a different path through the same data.
            assert_pose_eq(&tree.link_pose(id, &q).unwrap(), want, 1e-9, link);
        }
    }
    // The joint limits and types come through too.
    for branch in &table.branches {
        for row in &branch.rows {
            let joint = tree.joint(tree.joint_id(&row.joint).unwrap());
            let limits = joint.limits.unwrap();
            assert!((limits.lower - row.limits.0).abs() < 1e-12, "{}", row.joint);
            assert!((limits.upper - row.limits.1).abs() < 1e-12, "{}", row.joint);
            let prismatic = joint.kind == treecal::tree::JointKind::Prismatic;
            assert_eq!(prismatic, row.kind == FrameKind::Prismatic, "{}", row.joint);
        }
    }
}

#[test]
fn generated_urdf_forward_kinematics_equals_table1() {
    check_generated_fk(&table1(), 13 + 2);
}

/// A table with what Table 1 lacks: prismatic rows, a branch hanging from an arm, a tool with
/// every parameter non-zero, metres and radians.
const EXOTIC_TABLE: &str = "\
robot: exotic
base_link: ground
units: {angle: rad, length: m}
branches:
  - name: column
    rows:
      - {joint: lift, link: carriage, type: prismatic, alpha: 0.1, beta: -0.2, limits: [0, 0.8]}
      - {joint: turn, link: turret, alpha: 0.3, beta: 0.25, x: 0.05, y: -0.02}
  - name: arm
    parent: column
    rows:
      - {joint: a1, link: a1_link, alpha: -1.2, beta: 0.4, x: 0.3, y: 0.1}
      - {joint: a2, link: a2_link, type: prismatic, alpha: 1.5707963267948966, beta: 0, limits: [-0.1, 0.2]}
      - {joint: a3, link: a3_link, alpha: 0.7, beta: 1.5707963267948966, x: -0.15, y: 0.2}
    tool: {link: gripper, alpha: 0.2, beta: -0.3, gamma: 1.1, x: 0.01, y: 0.02, z: 0.12}
  - name: wrist_camera
    parent: arm
    rows:
      - {joint: c1, link: c1_link, alpha: 2.0, beta: -0.9, x: 0.0, y: 0.05, limits: [-1, 1]}
    tool: {link: camera, alpha: 0, beta: 0, gamma: 0, x: 0, y: 0, z: 0.03}
  - name: other
    parent: column
    rows:
      - {joint: o1, link: o1_link, alpha: 3.0, beta: -1.5, x: -0.3, y: 0.0}
    tool: {link: other_tool, alpha: -2.5, beta: 1.2, gamma: -3.0, x: 0.1, y: -0.1, z: 0.0}
";

#[test]
fn generated_urdf_forward_kinematics_equals_table_with_prismatic_rows_and_nested_branches() {
    let table = parse_mcpc_table(EXOTIC_TABLE, "exotic.yaml").unwrap_or_else(|e| panic!("{e}"));
    check_generated_fk(&table, 7 + 3);
}

// ---------------------------------------------------------------------------------------------
// 4. Bad tables: clear messages, nothing written.

const GOOD_TABLE: &str = "\
robot: r
units: {angle: deg, length: mm}
branches:
  - name: torso
    rows:
      - {joint: j1, link: l1, alpha: 0, beta: 0, x: 0, y: 0}
      - {joint: j2, link: l2, alpha: -90, beta: 0, x: 0, y: -385}
";

/// Writes `yaml` as `name` in a fresh directory, runs `from-mcpc` on it, and checks the failure:
/// exit 1, `treecal: error:` naming the file and every needle (`{file}` stands for the path),
/// no output file.
#[track_caller]
fn assert_table_rejected(name: &str, yaml: &str, needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join(name);
    std::fs::write(&table, yaml).unwrap();
    let out = dir.path().join("out.urdf");
    let run = treecal(&["from-mcpc", path_str(&table), "-o", path_str(&out)]);
    let file = path_str(&table);
    assert!(!run.success, "{name}: expected failure\n{run}");
    assert_eq!(run.code, Some(1), "{name}\n{run}");
    assert!(
        run.stderr.starts_with(&format!("treecal: error: {file}")),
        "{name}: stderr should start with 'treecal: error: {file}'\n{run}"
    );
    for needle in needles {
        let needle = needle.replace("{file}", file);
        assert!(
            run.stderr.contains(&needle),
            "{name}: stderr should contain {needle:?}\n{run}"
        );
    }
    assert!(!run.stderr.contains("panicked"), "{run}");
    assert!(run.stdout.is_empty(), "{run}");
    assert!(!out.exists(), "{name}: output written despite the error");
    let files: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(files, [name], "{name}: stray files");
}

#[test]
fn good_table_is_accepted() {
    // The base of the error cases below is itself valid.
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("good.yaml");
    std::fs::write(&table, GOOD_TABLE).unwrap();
    let out = dir.path().join("out.urdf");
    let run = treecal(&["from-mcpc", path_str(&table), "-o", path_str(&out)]);
    assert!(run.success, "{run}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("from good.yaml"), "source note");
    let tree = parse_urdf(&text, "out.urdf").unwrap().tree;
    assert_eq!(tree.dof_count(), 2);
    // Default limits ±180° when the table gives none.
    let limits = tree.joint(tree.joint_id("j1").unwrap()).limits.unwrap();
    assert!((limits.upper - std::f64::consts::PI).abs() < 1e-12);
}

#[test]
fn unknown_units_are_rejected() {
    assert_table_rejected(
        "grad.yaml",
        &GOOD_TABLE.replace("angle: deg", "angle: grad"),
        &["units.angle", "'grad'", "deg or rad"],
    );
    assert_table_rejected(
        "inch.yaml",
        &GOOD_TABLE.replace("length: mm", "length: inch"),
        &["units.length", "'inch'", "mm or m"],
    );
}

#[test]
fn misspelt_key_is_rejected_with_its_line() {
    assert_table_rejected(
        "alpah.yaml",
        &GOOD_TABLE.replacen("alpha: -90", "alpah: -90", 1),
        &["{file}:7:", "unknown key 'alpah'", "'alpha'"],
    );
    assert_table_rejected(
        "branch_key.yaml",
        &GOOD_TABLE.replace("    rows:", "    rowz:"),
        &["unknown key 'rowz'"],
    );
    assert_table_rejected(
        "top_key.yaml",
        &format!("{GOOD_TABLE}joint_limit: [-1, 1]\n"),
        &["unknown key 'joint_limit'"],
    );
}

#[test]
fn parent_must_be_listed_before() {
    let yaml = "\
robot: r
units: {angle: deg, length: mm}
branches:
  - name: left
    parent: torso
    rows:
      - {joint: a1, link: al1, alpha: 0, beta: 0, x: 0, y: 0}
  - name: torso
    rows:
      - {joint: j1, link: l1, alpha: 0, beta: 0, x: 0, y: 0}
";
    assert_table_rejected(
        "order.yaml",
        yaml,
        &["branch 'left'", "'torso'", "not listed before it"],
    );
    assert_table_rejected(
        "noparent.yaml",
        &format!(
            "{GOOD_TABLE}  - name: left\n    parent: torsoo\n    rows:\n      - {{joint: a1, link: al1, alpha: 0, beta: 0, x: 0, y: 0}}\n"
        ),
        &["'torsoo'", "not listed before it"],
    );
}

#[test]
fn duplicate_names_are_rejected() {
    assert_table_rejected(
        "dup_joint.yaml",
        &GOOD_TABLE.replace("joint: j2", "joint: j1"),
        &["joint name 'j1' is used twice"],
    );
    assert_table_rejected(
        "dup_link.yaml",
        &GOOD_TABLE.replace("link: l2", "link: l1"),
        &["link name 'l1' is used twice"],
    );
    assert_table_rejected(
        "dup_base.yaml",
        &GOOD_TABLE.replace("link: l2", "link: base_link"),
        &["link name 'base_link' is used twice"],
    );
}

#[test]
fn prismatic_row_with_x_is_rejected() {
    assert_table_rejected(
        "prismatic_x.yaml",
        &GOOD_TABLE.replace(
            "{joint: j2, link: l2, alpha: -90, beta: 0, x: 0, y: -385}",
            "{joint: j2, link: l2, type: prismatic, alpha: -90, beta: 0, x: 12, limits: [0, 300]}",
        ),
        &["prismatic joint 'j2'", "x or y"],
    );
    assert_table_rejected(
        "prismatic_nolimits.yaml",
        &GOOD_TABLE.replace(
            "{joint: j2, link: l2, alpha: -90, beta: 0, x: 0, y: -385}",
            "{joint: j2, link: l2, type: prismatic, alpha: -90, beta: 0}",
        ),
        &["prismatic joint 'j2' needs limits"],
    );
    assert_table_rejected(
        "helical.yaml",
        &GOOD_TABLE.replace(
            "{joint: j2, link: l2,",
            "{joint: j2, link: l2, type: helical,",
        ),
        &["'j2'", "'helical'", "revolute or prismatic"],
    );
}

#[test]
fn revolute_row_without_y_is_rejected() {
    assert_table_rejected(
        "no_y.yaml",
        &GOOD_TABLE.replace(", y: -385}", "}"),
        &["revolute joint 'j2' needs both x and y"],
    );
}

#[test]
fn malformed_yaml_names_file_and_line() {
    let broken = GOOD_TABLE.replace(
        "      - {joint: j2, link: l2, alpha: -90, beta: 0, x: 0, y: -385}",
        "      - {joint: j2, link: l2, alpha: -90, beta: 0, x: 0, y: -385",
    );
    // The parser notices at the end of the document (line 8).
    assert_table_rejected("broken.yaml", &broken, &["{file}:8:"]);
    let bad_number = GOOD_TABLE.replace("alpha: -90", "alpha: minus ninety");
    assert_table_rejected("word.yaml", &bad_number, &["{file}:7:"]);
    assert_table_rejected("tab.yaml", "robot: r\n\tunits: x\n", &["{file}:2:"]);
    assert_table_rejected("empty.yaml", "", &["{file}"]);
}

#[test]
fn missing_table_file_is_named() {
    assert_table_rejected_missing();
}

fn assert_table_rejected_missing() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("nosuch.yaml");
    let out = dir.path().join("out.urdf");
    let run = treecal(&["from-mcpc", path_str(&table), "-o", path_str(&out)]);
    assert!(!run.success, "{run}");
    assert!(
        run.stderr
            .starts_with(&format!("treecal: error: {}", path_str(&table))),
        "{run}"
    );
    assert!(!out.exists());
}

#[test]
fn failed_run_leaves_an_existing_output_alone() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("bad.yaml");
    std::fs::write(&table, GOOD_TABLE.replace("angle: deg", "angle: grad")).unwrap();
    let out = dir.path().join("out.urdf");
    std::fs::write(&out, "previous contents").unwrap();
    let run = treecal(&["from-mcpc", path_str(&table), "-o", path_str(&out)]);
    assert!(!run.success, "{run}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous contents");
}

// ---------------------------------------------------------------------------------------------
// 5. urdfdom's check_urdf accepts the generated file.

/// The Debian liburdfdom-tools binary. Named by full path: a `check_urdf` from a Python
/// environment may come first on PATH.
const CHECK_URDF: &str = "/usr/bin/check_urdf";

#[test]
fn check_urdf_accepts_generated_robonaut() {
    if !Path::new(CHECK_URDF).exists() {
        let problem = format!("{CHECK_URDF} not found (Debian/Ubuntu package liburdfdom-tools)");
        if std::env::var("TREECAL_REQUIRE_TOOLS").is_ok_and(|v| v == "1") {
            panic!(
                "TREECAL_REQUIRE_TOOLS=1 but {problem}\n\
                 install it with: sudo apt-get install liburdfdom-tools"
            );
        }
        eprintln!(
            "\n!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!\n\
             !!! SKIPPED: urdfdom check_urdf on {ROBONAUT} (tests/from_mcpc.rs)\n\
             !!! reason: {problem}\n\
             !!! enable it with: sudo apt-get install liburdfdom-tools\n\
             !!! (set TREECAL_REQUIRE_TOOLS=1 to make this a failure instead of a skip)\n\
             !!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!!\n"
        );
        return;
    }
    let output = Command::new(CHECK_URDF)
        .arg(repo().join(ROBONAUT))
        .stdin(Stdio::null())
        .output()
        .unwrap_or_else(|e| panic!("cannot run {CHECK_URDF}: {e}"));
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "{CHECK_URDF} {ROBONAUT} failed ({}):\n{stdout}\n{stderr}",
        output.status
    );
    // check_urdf prints the tree: the root and both tools must be in it.
    assert!(stdout.contains("robot name is: robonaut"), "{stdout}");
    assert!(stdout.contains("root Link: base_link"), "{stdout}");
    for link in ["left_tool", "right_tool"] {
        assert!(
            stdout.contains(link),
            "check_urdf tree lacks {link}:\n{stdout}"
        );
    }
}
