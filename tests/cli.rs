//! The `treecal` command line: help, `inspect`, `fk`. (`from-mcpc` is in `from_mcpc.rs`.)
//!
//! Every test runs the real binary (`CARGO_BIN_EXE_treecal`) and looks at exit status, stdout
//! and stderr, as a user would.

use crate::common::cli::*;
use crate::common::*;
use serde_json::Value;
use std::path::Path;
use treecal::load_urdf;

// ---------------------------------------------------------------------------------------------
// help

#[test]
fn help_lists_commands_and_options() {
    let run = treecal(&["--help"]);
    assert_success(&run, "treecal --help");
    for needle in ["inspect", "fk", "from-mcpc", "--help", "--version"] {
        assert!(run.stdout.contains(needle), "--help lacks {needle}\n{run}");
    }

    let cases: &[(&str, &[&str])] = &[
        (
            "inspect",
            &[
                "--tools", "--format", "[ROBOT]", "--robot", "text", "yaml", "json",
            ],
        ),
        (
            "fk",
            &[
                "--tip",
                "--joints",
                "-o, --out",
                "--angle-unit",
                "rad",
                "deg",
                "[ROBOT]",
                "--robot",
            ],
        ),
        ("from-mcpc", &["-o, --out", "<TABLE>"]),
    ];
    for (command, options) in cases {
        let run = treecal(&[command, "--help"]);
        assert_success(&run, &format!("treecal {command} --help"));
        assert!(
            run.stderr.is_empty(),
            "{command} --help wrote stderr\n{run}"
        );
        for option in *options {
            assert!(
                run.stdout.contains(option),
                "treecal {command} --help does not mention {option}\n{run}"
            );
        }
        // `treecal help <command>` is the same text.
        let via_help = treecal(&["help", command]);
        assert_success(&via_help, &format!("treecal help {command}"));
        assert_eq!(via_help.stdout, run.stdout, "treecal help {command}");
    }
}

#[test]
fn no_arguments_prints_help_and_fails() {
    let run = treecal(&[]);
    assert!(!run.success, "treecal without arguments should fail\n{run}");
    assert!(
        run.stderr.contains("Usage:") || run.stdout.contains("Usage:"),
        "{run}"
    );
}

// ---------------------------------------------------------------------------------------------
// inspect

const ROBONAUT_FORMULA: &str = "4·13 revolute + 2·0 prismatic + 6·2 tools = 64";

#[test]
fn inspect_built_in_robonaut_from_any_directory() {
    // Run outside the repository: the built-in robot must not depend on the working directory.
    let dir = tempfile::tempdir().unwrap();
    let run = treecal_in(Some(dir.path()), &["inspect"]);
    assert_success(&run, "treecal inspect");
    assert!(run.stdout.starts_with("robot 'robonaut'"), "{run}");
    assert!(
        run.stdout
            .contains(&format!("parameters: {ROBONAUT_FORMULA}")),
        "{run}"
    );
    for name in [
        "torso_joint2",
        "left_joint6",
        "right_joint5",
        "left_tool",
        "right_tool",
    ] {
        assert!(run.stdout.contains(name), "inspect lacks {name}\n{run}");
    }
    // The built-in robot is the committed file.
    let from_file = treecal(&["inspect", "robots/robonaut/robonaut.urdf"]);
    assert_success(&from_file, "treecal inspect robonaut.urdf");
    assert_eq!(from_file.stdout, run.stdout);
}

#[test]
fn inspect_yaml_and_json() {
    let json = treecal(&["inspect", "--format", "json"]);
    assert_success(&json, "inspect --format json");
    let value: Value = serde_json::from_str(&json.stdout)
        .unwrap_or_else(|e| panic!("inspect JSON does not parse: {e}\n{json}"));
    assert_eq!(value["robot"], "robonaut");
    assert_eq!(value["root"], "base_link");
    assert_eq!(value["degrees_of_freedom"], 13);
    assert_eq!(value["mcpc"]["parameter_count"], 64);
    assert_eq!(value["mcpc"]["parameter_formula"], ROBONAUT_FORMULA);
    assert_eq!(value["mcpc"]["rows"].as_array().unwrap().len(), 13 + 2);
    let names: Vec<&str> = value["branches"]["list"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["torso", "left_arm", "right_arm"]);

    let yaml = treecal(&["inspect", "--format", "yaml"]);
    assert_success(&yaml, "inspect --format yaml");
    assert!(
        yaml.stdout
            .starts_with("schema_version: treecal.inspect/1\nrobot:"),
        "{yaml}"
    );
    assert!(yaml.stdout.contains("parameter_count: 64"), "{yaml}");
    assert!(yaml.stdout.contains("robonaut"), "{yaml}");

    let bad = treecal(&["inspect", "--format", "xml"]);
    assert!(!bad.success, "--format xml should fail\n{bad}");
    assert!(bad.stderr.contains("xml"), "{bad}");
}

fn inspect_json(args: &[&str]) -> Value {
    let run = treecal(args);
    assert_success(&run, &args.join(" "));
    serde_json::from_str(&run.stdout).unwrap_or_else(|e| panic!("JSON: {e}\n{run}"))
}

fn strings(value: &Value) -> Vec<&str> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("not an array: {value}"))
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect()
}

#[test]
fn inspect_humanoid_detects_torso_and_hands() {
    let value = inspect_json(&[
        "inspect",
        "robots/humanoid/humanoid.urdf",
        "--format",
        "json",
    ]);
    let list = value["branches"]["list"].as_array().unwrap();
    assert_eq!(list.len(), 3, "{list:?}");
    assert_eq!(list[0]["role"], "coupled");
    assert_eq!(strings(&list[0]["joints"]), ["waist_yaw", "waist_pitch"]);
    assert_eq!(list[1]["tool"], "l_hand");
    assert_eq!(list[2]["tool"], "r_hand");
    assert_eq!(list[1]["joints"].as_array().unwrap().len(), 7);
    assert_eq!(list[2]["joints"].as_array().unwrap().len(), 7);

    // The text form says the same.
    let text = treecal(&["inspect", "robots/humanoid/humanoid.urdf"]);
    assert_success(&text, "inspect humanoid");
    assert!(
        text.stdout
            .contains("torso      2 joints: waist_yaw, waist_pitch"),
        "{text}"
    );
    assert!(text.stdout.contains("→ tool 'l_hand'"), "{text}");
    assert!(text.stdout.contains("→ tool 'r_hand'"), "{text}");
}

#[test]
fn inspect_humanoid_with_three_named_tools() {
    let value = inspect_json(&[
        "inspect",
        "robots/humanoid/humanoid.urdf",
        "--tools",
        "l_hand,r_hand,camera",
        "--format",
        "json",
    ]);
    let list = value["branches"]["list"].as_array().unwrap();
    let arms: Vec<&Value> = list.iter().filter(|b| b["role"] != "coupled").collect();
    assert_eq!(arms.len(), 3, "{list:?}");
    let tools: Vec<&str> = arms.iter().map(|b| b["tool"].as_str().unwrap()).collect();
    assert_eq!(tools, ["l_hand", "r_hand", "camera"]);
    assert_eq!(strings(&arms[2]["joints"]), ["neck_yaw", "neck_pitch"]);
    // Three tools in the parameter count.
    let formula = value["mcpc"]["parameter_formula"].as_str().unwrap();
    assert!(formula.contains("6·3 tools"), "{formula}");

    // Spaces after the commas are tolerated.
    let run = treecal(&[
        "inspect",
        "robots/humanoid/humanoid.urdf",
        "--tools",
        "l_hand, r_hand, camera",
    ]);
    assert_success(&run, "--tools with spaces");
    assert!(run.stdout.contains("→ tool 'camera'"), "{run}");
}

#[test]
fn inspect_unknown_tool_is_named() {
    let run = treecal(&[
        "inspect",
        "robots/humanoid/humanoid.urdf",
        "--tools",
        "nosuch",
    ]);
    assert_error(&run, &["'nosuch'"], "--tools nosuch");
    assert!(!run.stderr.contains("did you mean"), "{run}");

    let run = treecal(&[
        "inspect",
        "robots/humanoid/humanoid.urdf",
        "--tools",
        "l_hnd,r_hand",
    ]);
    assert_error(
        &run,
        &["'l_hnd'", "did you mean 'l_hand'?"],
        "--tools l_hnd,r_hand",
    );
}

#[test]
fn inspect_missing_robot_file_is_named() {
    let run = treecal(&["inspect", "robots/nosuch/nosuch.urdf"]);
    assert_error(&run, &["robots/nosuch/nosuch.urdf"], "inspect missing file");
}

/// Measurements of another robot than the one loaded (no `--robot`: the built-in Robonaut)
/// name the robot used and the flag that gives the right one.
#[test]
fn measurements_of_another_robot_name_the_robot_used() {
    let dir = tempfile::tempdir().unwrap();
    let rigid = dir.path().join("rigid.yaml");
    std::fs::write(&rigid, "self_weight: false\n").unwrap();
    let csv = dir.path().join("humanoid.csv");
    let run = treecal(&[
        "simulate",
        "--robot",
        "robots/humanoid/humanoid.urdf",
        "--stiffness",
        path_str(&rigid),
        "--trials",
        "1",
        "--write-measurements",
        path_str(&csv),
        "--out",
        path_str(&dir.path().join("sim")),
    ]);
    assert_success(&run, "simulate the humanoid");
    let out = dir.path().join("out");
    assert_error(
        &treecal(&[
            "calibrate",
            "--measurements",
            path_str(&csv),
            "--out",
            path_str(&out),
        ]),
        &[
            "humanoid.csv: tool column: unknown link",
            "of robot 'robonaut'; the tool column",
            "measurements of another robot: give its URDF with --robot",
        ],
        "another robot's measurements",
    );
}

/// `-` is not standard input or output: every command refuses it with the flag it was given
/// to, before reading anything (treecal names and hashes its input files).
#[test]
fn a_dash_for_a_file_is_refused_with_its_flag() {
    for (args, needle) in [
        (
            &["calibrate", "--measurements", "-"][..],
            "--measurements: '-'",
        ),
        (
            &["calibrate", "--measurements", "m.csv", "--validation=-"][..],
            "--validation: '-'",
        ),
        (&["fk", "--joints", "-"][..], "--joints: '-'"),
        (&["inspect", "-"][..], "the command line: '-'"),
    ] {
        let run = treecal(args);
        assert_error(
            &run,
            &[
                needle,
                "is not supported",
                "save the stream to a file first",
            ],
            &args.join(" "),
        );
    }
}

// ---------------------------------------------------------------------------------------------
// fk

const POSE_COLUMNS: [&str; 12] = [
    "x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33",
];

/// Parses a CSV produced by `treecal fk` into header and rows.
fn read_csv(text: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let header = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_owned)
        .collect();
    let rows = reader
        .records()
        .map(|r| r.unwrap().iter().map(str::to_owned).collect())
        .collect();
    (header, rows)
}

fn number(text: &str) -> f64 {
    text.parse()
        .unwrap_or_else(|e| panic!("'{text}' is not a number: {e}"))
}

/// The input of the main fk test: a comment column and a misspelt joint column, a comment line,
/// a blank line, a quoted field with a comma.
const JOINTS_CSV: &str = "left_joint1,left_joint2,comment,left_jiont3\n\
# a comment line\n\
0.1,0.2,first,0.3\n\
\n\
-0.5,1.25,\"a, b\",7\n";

/// `(left_joint1, left_joint2, comment, left_jiont3)` of the rows of [`JOINTS_CSV`].
const JOINTS_ROWS: [[&str; 4]; 2] = [
    ["0.1", "0.2", "first", "0.3"],
    ["-0.5", "1.25", "a, b", "7"],
];

/// Checks `treecal fk` output against `KinematicTree::link_pose`; `scale` converts the CSV's
/// angles to radians.
fn check_fk_output(output: &str, scale: f64) {
    let tree = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let tip = tree.link_id("left_tool").unwrap();
    let dof = |name: &str| tree.dof_of(tree.joint_id(name).unwrap()).unwrap().0;

    let (header, rows) = read_csv(output);
    let mut expected_header: Vec<&str> =
        vec!["left_joint1", "left_joint2", "comment", "left_jiont3"];
    expected_header.extend(POSE_COLUMNS);
    assert_eq!(header, expected_header, "output header\n{output}");
    assert_eq!(rows.len(), JOINTS_ROWS.len(), "{output}");

    for (row, input) in rows.iter().zip(JOINTS_ROWS) {
        assert_eq!(row.len(), 16, "{row:?}");
        // Input columns, the unknown ones included, pass through unchanged.
        assert_eq!(&row[..4], &input[..], "input columns passed through");
        let mut q = tree.zero_configuration();
        q[dof("left_joint1")] = number(input[0]) * scale;
        q[dof("left_joint2")] = number(input[1]) * scale;
        // The misspelt column is not left_joint3: that joint stays at 0.
        let pose = tree.link_pose(tip, &q).unwrap();
        let t = pose.translation.vector;
        let r = pose.rotation.to_rotation_matrix();
        let mut expected = vec![t.x, t.y, t.z];
        for i in 0..3 {
            for j in 0..3 {
                expected.push(r[(i, j)]);
            }
        }
        for (k, (cell, want)) in row[4..].iter().zip(&expected).enumerate() {
            let got = number(cell);
            assert!(
                (got - want).abs() <= 1e-12,
                "column {}: {got} vs {want} (q = {q:?})",
                POSE_COLUMNS[k]
            );
        }
    }
}

fn write(dir: &Path, name: &str, contents: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

#[test]
fn fk_appends_poses_and_passes_unknown_columns_through() {
    let dir = tempfile::tempdir().unwrap();
    let joints = write(dir.path(), "joints.csv", JOINTS_CSV);
    let run = treecal(&[
        "fk",
        "robots/robonaut/robonaut.urdf",
        "--tip",
        "left_tool",
        "--joints",
        path_str(&joints),
    ]);
    assert_success(&run, "fk");
    check_fk_output(&run.stdout, 1.0);
    // Both unmatched columns are named on stderr, the typo among them.
    for column in ["'left_jiont3'", "'comment'"] {
        assert!(
            run.stderr.contains(column) && run.stderr.contains("matches no joint"),
            "stderr should name {column}\n{run}"
        );
    }
    assert!(!run.stderr.contains("'left_joint1'"), "{run}");
    assert!(!run.stderr.contains("error"), "{run}");
}

#[test]
fn fk_angle_unit_deg() {
    let dir = tempfile::tempdir().unwrap();
    let joints = write(dir.path(), "joints.csv", JOINTS_CSV);
    let run = treecal(&[
        "fk",
        "robots/robonaut/robonaut.urdf",
        "--tip",
        "left_tool",
        "--joints",
        path_str(&joints),
        "--angle-unit",
        "deg",
    ]);
    assert_success(&run, "fk --angle-unit deg");
    check_fk_output(&run.stdout, std::f64::consts::PI / 180.0);

    // deg and rad really differ (a unit mix-up would go unnoticed otherwise).
    let rad = treecal(&[
        "fk",
        "robots/robonaut/robonaut.urdf",
        "--tip",
        "left_tool",
        "--joints",
        path_str(&joints),
    ]);
    assert_success(&rad, "fk rad");
    assert_ne!(rad.stdout, run.stdout);
}

#[test]
fn fk_output_file() {
    let dir = tempfile::tempdir().unwrap();
    let joints = write(dir.path(), "joints.csv", JOINTS_CSV);
    let out = dir.path().join("out.csv");
    let run = treecal(&[
        "fk",
        "robots/robonaut/robonaut.urdf",
        "--tip",
        "left_tool",
        "--joints",
        path_str(&joints),
        "-o",
        path_str(&out),
    ]);
    assert_success(&run, "fk -o");
    assert!(
        run.stdout.is_empty(),
        "with -o nothing goes to stdout\n{run}"
    );
    let written = std::fs::read_to_string(&out).unwrap();
    check_fk_output(&written, 1.0);

    // --output, relative to the working directory, into a directory that does not exist yet;
    // an existing file is replaced.
    let run = treecal_in(
        Some(dir.path()),
        &[
            "fk",
            path_str(&robot("robonaut/robonaut.urdf")),
            "--tip",
            "left_tool",
            "--joints",
            "joints.csv",
            "--output",
            "sub/out.csv",
        ],
    );
    assert_success(&run, "fk --output sub/out.csv");
    let written_again = std::fs::read_to_string(dir.path().join("sub/out.csv")).unwrap();
    assert_eq!(written_again, written);
    // No temporary files left behind.
    let leftovers: Vec<_> = std::fs::read_dir(dir.path().join("sub"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers, ["out.csv"]);
}

/// Runs fk with `-o out.csv` on `csv` (written as `name`) and returns the run; asserts that
/// no output file appeared.
fn fk_failing(name: &str, csv: Option<&str>, tip: &str) -> (Run, String) {
    let dir = tempfile::tempdir().unwrap();
    let joints = dir.path().join(name);
    if let Some(csv) = csv {
        std::fs::write(&joints, csv).unwrap();
    }
    let out = dir.path().join("out.csv");
    let run = treecal(&[
        "fk",
        "robots/robonaut/robonaut.urdf",
        "--tip",
        tip,
        "--joints",
        path_str(&joints),
        "-o",
        path_str(&out),
    ]);
    assert!(
        !out.exists(),
        "{name}: output written despite the error\n{run}"
    );
    let files: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        files.iter().all(|f| f == name),
        "{name}: stray files {files:?}"
    );
    (run, path_str(&joints).to_owned())
}

#[test]
fn fk_non_numeric_value_names_file_line_and_column() {
    // Line 5: header, comment, row, blank line, bad row.
    let (run, path) = fk_failing(
        "bad.csv",
        Some("left_joint1,left_joint2\n# comment\n0.1,0.2\n\n0.3,abc\n"),
        "left_tool",
    );
    assert_error(
        &run,
        &[&format!("{path}:5:left_joint2"), "'abc'"],
        "non-numeric",
    );

    // The same with Windows line endings.
    let (run, path) = fk_failing(
        "crlf.csv",
        Some("left_joint1,left_joint2\r\n0.1,0.2\r\n0.3,0.4\r\nx,0.5\r\n"),
        "left_tool",
    );
    assert_error(&run, &[&format!("{path}:4:left_joint1"), "'x'"], "CRLF");

    // Comments before the header, and comment lines between rows.
    let (run, path) = fk_failing(
        "comments.csv",
        Some("# recorded 2017\n# by hand\nleft_joint1\n0\n# next\n# two\n1\n--1\n"),
        "left_tool",
    );
    assert_error(
        &run,
        &[&format!("{path}:8:left_joint1"), "'--1'"],
        "comments",
    );

    // A quoted field spanning two lines: the next row starts on line 4.
    let (run, path) = fk_failing(
        "multiline.csv",
        Some("left_joint1,comment\n0.1,\"two\nlines\"\n1e,c\n"),
        "left_tool",
    );
    assert_error(
        &run,
        &[&format!("{path}:4:left_joint1"), "'1e'"],
        "multi-line field",
    );
}

#[test]
fn fk_non_finite_values_are_errors() {
    for value in ["nan", "NaN", "inf", "-inf"] {
        let (run, path) = fk_failing(
            "nan.csv",
            Some(&format!("left_joint1\n0\n{value}\n")),
            "left_tool",
        );
        assert_error(
            &run,
            &[&format!("{path}:3:left_joint1"), "finite"],
            &format!("value {value}"),
        );
    }
}

#[test]
fn fk_bad_input_files() {
    let (run, path) = fk_failing("missing.csv", None, "left_tool");
    assert_error(&run, &[&path], "missing joints file");

    let (run, path) = fk_failing("empty.csv", Some("# only a comment\n\n"), "left_tool");
    assert_error(&run, &[&path, "empty"], "empty joints file");

    let (run, path) = fk_failing(
        "short.csv",
        Some("left_joint1,left_joint2\n0.1,0.2\n0.3\n"),
        "left_tool",
    );
    assert_error(&run, &[&format!("{path}:3"), "fields"], "short row");

    let (run, path) = fk_failing(
        "twice.csv",
        Some("# joints\nleft_joint1,left_joint1\n0.1,0.2\n"),
        "left_tool",
    );
    assert_error(
        &run,
        &[&format!("{path}:2"), "'left_joint1'", "twice"],
        "duplicate column",
    );
}

#[test]
fn fk_unknown_tip_is_named() {
    let (run, _) = fk_failing("joints.csv", Some(JOINTS_CSV), "left_tol");
    assert_error(
        &run,
        &["'left_tol'", "did you mean 'left_tool'?"],
        "unknown tip",
    );
    let (run, _) = fk_failing("joints.csv", Some(JOINTS_CSV), "nosuch");
    assert_error(&run, &["'nosuch'"], "unknown tip");
}

#[test]
fn fk_mimic_and_fixed_columns_are_reported_unused() {
    let dir = tempfile::tempdir().unwrap();
    // Same master value, different mimic values: the mimic column must not matter.
    let joints = write(
        dir.path(),
        "fingers.csv",
        "l_finger_left,l_finger_right,l_hand_joint\n0.3,0.9,5\n0.3,-0.2,0\n",
    );
    let run = treecal(&[
        "fk",
        "robots/humanoid/humanoid.urdf",
        "--tip",
        "l_finger_right_link",
        "--joints",
        path_str(&joints),
    ]);
    assert_success(&run, "fk with a mimic column");
    assert!(
        run.stderr.contains("'l_finger_right' is a mimic joint") && run.stderr.contains("not used"),
        "the mimic column should be reported as not used\n{run}"
    );
    assert!(
        run.stderr.contains("'l_hand_joint' is a fixed joint"),
        "the fixed-joint column should be reported as not used\n{run}"
    );
    assert!(!run.stderr.contains("'l_finger_left'"), "{run}");

    let (_, rows) = read_csv(&run.stdout);
    assert_eq!(rows.len(), 2);
    assert_eq!(
        rows[0][3..],
        rows[1][3..],
        "pose depends on the mimic column"
    );

    // And the pose is the tree's, with the mimic joint following its master.
    let tree = load_urdf(&robot("humanoid/humanoid.urdf")).unwrap().tree;
    let mut q = tree.zero_configuration();
    q[tree
        .dof_of(tree.joint_id("l_finger_left").unwrap())
        .unwrap()
        .0] = 0.3;
    let pose = tree
        .link_pose(tree.link_id("l_finger_right_link").unwrap(), &q)
        .unwrap();
    let t = pose.translation.vector;
    for (cell, want) in rows[0][3..6].iter().zip([t.x, t.y, t.z]) {
        assert!((number(cell) - want).abs() <= 1e-12, "{cell} vs {want}");
    }
}

// ---------------------------------------------------------------------------------------------
// to-mcpc

/// `to-mcpc` then `from-mcpc` gives a robot whose tool poses equal the original's.
#[test]
fn to_mcpc_then_from_mcpc_reproduces_the_tools() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("humanoid.yaml");
    let urdf = dir.path().join("humanoid_mcpc.urdf");
    let run = treecal(&[
        "to-mcpc",
        "robots/humanoid/humanoid.urdf",
        "-o",
        path_str(&table),
    ]);
    assert_success(&run, "to-mcpc");
    let text = std::fs::read_to_string(&table).unwrap();
    assert!(text.starts_with("# MCPC table of humanoid.urdf"), "{text}");
    assert!(
        text.contains("phi: 90"),
        "a re-parametrised row shows its phi\n{text}"
    );
    let run = treecal(&["from-mcpc", path_str(&table), "-o", path_str(&urdf)]);
    assert_success(&run, "from-mcpc");

    let original = load_urdf(&robot("humanoid/humanoid.urdf")).unwrap().tree;
    let regenerated = load_urdf(&urdf).unwrap().tree;
    let mut rng = rng(11);
    for _ in 0..20 {
        let q = random_configuration(&original, &mut rng);
        let q_again: Vec<f64> = regenerated
            .dofs()
            .iter()
            .map(|j| {
                let name = &regenerated.joint(*j).name;
                original.joint_value(original.joint_id(name).unwrap(), &q)
            })
            .collect();
        for tool in ["l_hand", "r_hand"] {
            let expected = original
                .link_pose(original.link_id(tool).unwrap(), &q)
                .unwrap();
            let got = regenerated
                .link_pose(regenerated.link_id(tool).unwrap(), &q_again)
                .unwrap();
            assert_pose_eq(&got, &expected, 1e-9, tool);
        }
    }
}

#[test]
fn to_mcpc_of_the_built_in_robot_goes_to_stdout() {
    let run = treecal(&["to-mcpc"]);
    assert_success(&run, "to-mcpc");
    assert!(run.stdout.contains("joint: \"left_joint2\""), "{run}");
    let table = treecal::io::parse_mcpc_table(&run.stdout, "stdout").unwrap();
    assert_eq!(table.branches.len(), 3);
}

// ---------------------------------------------------------------------------------------------
// simulate

#[test]
fn simulate_same_seed_gives_identical_results() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let measurements = dir.path().join("m.csv");
    let run = treecal(&[
        "simulate",
        "--out",
        path_str(&a),
        "--write-measurements",
        path_str(&measurements),
    ]);
    assert_success(&run, "simulate");
    assert!(run.stdout.contains("| left_arm | position (mm) |"), "{run}");
    let run = treecal(&["simulate", "--out", path_str(&b)]);
    assert_success(&run, "simulate again");
    let first = std::fs::read(a.join("results.json")).unwrap();
    assert_eq!(first, std::fs::read(b.join("results.json")).unwrap());
    for file in [
        "summary.md",
        "left_arm_position.svg",
        "right_arm_orientation.svg",
    ] {
        assert!(a.join(file).is_file(), "{file}");
    }
    let csv = std::fs::read_to_string(&measurements).unwrap();
    assert!(
        csv.starts_with("id,stage,tool,torso_joint1,"),
        "{}",
        &csv[..80]
    );
    assert_eq!(csv.lines().count(), 1 + 2 * (20 + 10));
    let run = treecal(&["simulate", "--seed", "1", "--out", path_str(&b)]);
    assert_success(&run, "another seed");
    assert_ne!(first, std::fs::read(b.join("results.json")).unwrap());
}

#[test]
fn simulate_without_noise_removes_the_error() {
    let dir = tempfile::tempdir().unwrap();
    let run = treecal(&[
        "simulate",
        "--noise",
        "0",
        "--plan",
        "simultaneous",
        "--out",
        path_str(dir.path()),
    ]);
    assert_success(&run, "noise-free");
    let results: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("results.json")).unwrap())
            .unwrap();
    for arm in results["trials"][0]["validation"].as_array().unwrap() {
        let removed = arm["position_removed_percent"]["compensated"]
            .as_f64()
            .unwrap();
        assert!(removed > 99.99, "{removed}");
    }
}

#[test]
fn simulate_rejects_bad_flags() {
    let dir = tempfile::tempdir().unwrap();
    let out = path_str(dir.path());
    let run = treecal(&["simulate", "--poses", "-3", "--out", out]);
    assert!(!run.success && run.stderr.contains("--poses"), "{run}");
    assert_error(
        &treecal(&["simulate", "--robot", "nosuch.urdf", "--out", out]),
        &["nosuch.urdf"],
        "unknown robot",
    );
    assert_error(
        &treecal(&[
            "simulate",
            "--robot",
            "robots/humanoid/humanoid.urdf",
            "--stiffness",
            "robots/robonaut/stiffness.yaml",
            "--out",
            out,
        ]),
        &["stiffness.yaml"],
        "stiffness of another robot",
    );
    // A robot of its own needs a stiffness file; the error says how to simulate it rigid, and
    // that advice works.
    let humanoid = ["simulate", "--robot", "robots/humanoid/humanoid.urdf"];
    assert_error(
        &treecal(&[&humanoid[..], &["--out", out]].concat()),
        &[
            "--stiffness: a robot given with --robot needs its stiffness file",
            "`self_weight: false`",
        ],
        "no stiffness file",
    );
    let rigid = dir.path().join("rigid.yaml");
    std::fs::write(&rigid, "self_weight: false\n").unwrap();
    let rigid_out = dir.path().join("rigid");
    let args = [
        "--stiffness",
        path_str(&rigid),
        "--trials",
        "1",
        "--out",
        path_str(&rigid_out),
    ];
    assert_success(&treecal(&[&humanoid[..], &args].concat()), "a rigid robot");
    assert_error(
        &treecal(&["simulate", "--noise", "loud", "--out", out]),
        // The library names the setting (`noise`); the CLI spells it as its flag.
        &["treecal: error: --noise: 'loud' is not a noise model"],
        "bad noise",
    );
    assert_error(
        &treecal(&["simulate", "--targets", "2", "--out", out]),
        &["--targets"],
        "two targets",
    );
    assert_error(
        &treecal(&["simulate", "--model-stiffness-scale", "0", "--out", out]),
        &["--model-stiffness-scale"],
        "zero scale",
    );
    assert!(
        !dir.path().join("results.json").exists(),
        "no output after errors"
    );
}

fn plan_csv(path: &std::path::Path) -> (Vec<String>, Vec<Vec<String>>) {
    read_csv(&std::fs::read_to_string(path).unwrap())
}

#[test]
fn plan_writes_poses_and_compares_with_random() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("poses.csv");
    let args = [
        "plan",
        "--poses",
        "8",
        "--candidates",
        "200",
        "--seed",
        "4",
        "-o",
        path_str(&out),
    ];
    let run = treecal(&args);
    assert_success(&run, "plan");
    assert!(
        run.stdout.contains("planned") && run.stdout.contains("random"),
        "{run}"
    );
    let (header, rows) = plan_csv(&out);
    assert_eq!(header[0], "tool");
    assert!(header.contains(&"torso_joint1".to_owned()), "{header:?}");
    // One row per tool per configuration.
    assert_eq!(rows.len(), 16);
    assert_eq!(rows[0][0], "left_tool");
    assert_eq!(rows[1][0], "right_tool");
    // Same seed, same file.
    let first = std::fs::read(&out).unwrap();
    assert_success(&treecal(&args), "plan again");
    assert_eq!(first, std::fs::read(&out).unwrap());
}

#[test]
fn plan_staged_labels_torso_then_arms() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("staged.csv");
    let run = treecal(&[
        "plan",
        "--poses",
        "6",
        "--torso-poses",
        "4",
        "--candidates",
        "150",
        "--stage",
        "staged",
        "--criterion",
        "d",
        "-o",
        path_str(&out),
    ]);
    assert_success(&run, "plan --stage staged");
    let (header, rows) = plan_csv(&out);
    assert_eq!(&header[..2], ["stage", "tool"]);
    let stages: Vec<&str> = rows.iter().map(|r| r[0].as_str()).collect();
    assert_eq!(stages[..8], ["torso"; 8]);
    assert_eq!(stages[8..], ["arms"; 12]);
}

#[test]
fn plan_bad_arguments_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.csv");
    let run = treecal(&[
        "plan",
        "--poses",
        "5",
        "--workspace",
        "0,0,1",
        "-o",
        path_str(&out),
    ]);
    assert_error(&run, &["--workspace", "six numbers"], "short workspace");
    let run = treecal(&[
        "plan",
        "--poses",
        "5",
        "--candidates",
        "50",
        "--workspace",
        "20,20,20,21,21,21",
        "-o",
        path_str(&out),
    ]);
    assert_error(&run, &["workspace box"], "unreachable workspace");
    let run = treecal(&["plan", "--poses", "0", "-o", path_str(&out)]);
    assert_error(&run, &["--poses"], "no poses");
    assert!(!out.exists());
}

#[test]
fn simulate_with_planned_poses() {
    let dir = tempfile::tempdir().unwrap();
    let run = treecal(&[
        "simulate",
        "--poses-from",
        "planned",
        "--candidates",
        "100",
        "--poses",
        "10",
        "--torso-poses",
        "6",
        "--out",
        path_str(dir.path()),
    ]);
    assert_success(&run, "simulate --poses-from planned");
    assert!(run.stdout.contains("planned from 100 candidates"), "{run}");
}
