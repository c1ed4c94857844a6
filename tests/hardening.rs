//! Hostile inputs (issue 12): each one that used to panic, hang, truncate silently or write a
//! wrong file, in its minimal form, plus the limits of `treecal::limits` on good data (no false
//! alarms) and the replay of the fuzzers' findings (`tests/data/fuzz/<target>/`).

use crate::common::cli::*;
use crate::common::*;
use std::path::{Path, PathBuf};
use treecal::calibration::{identify, IdentificationOptions, Rigid};
use treecal::io::{
    mcpc_table_to_yaml, parse_csv, parse_mcpc_table, parse_measurements, parse_parameters,
    parse_plan, parse_stiffness, AngleUnit, LengthUnit, MeasurementReadOptions,
};
use treecal::limits;
use treecal::math::Vec3;
use treecal::measurement::{targets_problem, Measurement, Observation};
use treecal::{detect_branches, load_urdf, parse_urdf, urdf_from_mcpc_table, McpcModel};

fn robonaut_text() -> String {
    std::fs::read_to_string(robot("robonaut/robonaut.urdf")).unwrap()
}

fn example_measurements() -> String {
    std::fs::read_to_string(robot("robonaut/example/measurements.csv")).unwrap()
}

fn tracker_units() -> MeasurementReadOptions {
    MeasurementReadOptions {
        length_unit: Some(LengthUnit::Millimetre),
        angle_unit: Some(AngleUnit::Degree),
        ..Default::default()
    }
}

/// The example measurement CSV with field `column` of data row `row` (0-based) replaced.
fn example_with(row: usize, column: &str, value: &str) -> String {
    let text = example_measurements();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let header: Vec<&str> = lines[1].split(',').collect();
    let index = header.iter().position(|h| *h == column).unwrap();
    let mut fields: Vec<String> = lines[2 + row].split(',').map(str::to_owned).collect();
    fields[index] = value.to_owned();
    lines[2 + row] = fields.join(",");
    lines.join("\n") + "\n"
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

// ---------------------------------------------------------------------------------------------
// panics and hangs

/// 1e200 mm in a target coordinate: panicked in the gravity loads with --stiffness, hung in
/// the SVD without; now the reader names the place and the limit.
#[test]
fn huge_target_coordinate_is_refused_where_it_is_read() {
    let (tree, model) = robonaut_model();
    let text = example_with(3, "bx", "1e200");
    let error = parse_measurements(&text, "m.csv", &tree, &model, &tracker_units())
        .unwrap_err()
        .to_string();
    assert!(error.starts_with("m.csv:6:bx: "), "{error}");
    assert!(error.contains("Limits"), "{error}");
    // The command, with and without --stiffness: a clean error, exit code 1.
    let dir = tempfile::tempdir().unwrap();
    let csv = write(dir.path(), "m.csv", &text);
    let out = dir.path().join("out");
    let base = [
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--length-unit",
        "mm",
        "--angle-unit",
        "deg",
        "--out",
        path_str(&out),
    ];
    assert_error(&treecal(&base), &["m.csv:6:bx"], "calibrate 1e200");
    let mut with_stiffness = base.to_vec();
    with_stiffness.extend(["--stiffness", "robots/robonaut/stiffness.yaml"]);
    assert_error(
        &treecal(&with_stiffness),
        &["m.csv:6:bx"],
        "calibrate 1e200 --stiffness",
    );
}

/// Values that pass every reader check but overflow in the fit end with an error, not in an
/// endless SVD.
#[test]
fn overflow_in_the_fit_is_an_error_not_a_hang() {
    let (tree, model) = robonaut_model();
    let q = tree.zero_configuration();
    let measurements: Vec<Measurement> = (0..2)
        .map(|tool| Measurement {
            payload: None,
            tool,
            q: q.clone(),
            observation: Observation::Position(Vec3::repeat(1e200)),
            stage: None,
            session: None,
        })
        .collect();
    let free: Vec<usize> = (0..model.parameter_count()).collect();
    let error = identify(
        &model,
        &measurements,
        None,
        &Rigid,
        &free,
        &IdentificationOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(error.contains("not finite"), "{error}");
    // A sigma that overflows the cost, as --position-sigma 1e-300 did ("rank 0/32").
    let pose = tree
        .link_pose(model.tools()[0].link, &q)
        .unwrap()
        .translation
        .vector;
    let near = vec![Measurement {
        payload: None,
        tool: 0,
        q,
        observation: Observation::Position(pose + Vec3::repeat(1e-3)),
        stage: None,
        session: None,
    }];
    let options = IdentificationOptions {
        position_sigma: 1e-300,
        ..IdentificationOptions::default()
    };
    let error = identify(&model, &near, None, &Rigid, &free, &options)
        .unwrap_err()
        .to_string();
    assert!(error.contains("not finite"), "{error}");
}

#[test]
fn sigma_flags_have_a_range() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        "robots/robonaut/example/measurements.csv",
        "--position-sigma",
        "1e-300",
        "--out",
        path_str(&out),
    ]);
    assert_error(&run, &["--position-sigma", "1e-300"], "calibrate sigma");
    assert!(!out.exists(), "nothing may be written");
    let run = treecal(&["check", "--rotation-sigma", "1e300"]);
    assert_error(&run, &["--rotation-sigma"], "check sigma");
}

/// A URDF origin of 1e308 hung the solver; now it is refused at load, naming the line.
#[test]
fn huge_urdf_numbers_are_refused_at_load() {
    let text = robonaut_text().replacen(
        "<origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>",
        "<origin xyz=\"1e308 0 0\" rpy=\"0 0 0\"/>",
        1,
    );
    let error = parse_urdf(&text, "r.urdf").unwrap_err().to_string();
    assert!(error.contains("r.urdf:"), "{error}");
    assert!(
        error.contains("1e308") || error.contains("100000000"),
        "{error}"
    );
    assert!(error.contains("Limits"), "{error}");
    let text = robonaut_text().replacen("<mass value=\"20\"/>", "<mass value=\"1e300\"/>", 1);
    let error = parse_urdf(&text, "r.urdf").unwrap_err().to_string();
    assert!(error.contains("<mass value>"), "{error}");
}

#[test]
fn simulate_angle_error_beyond_a_half_turn_is_refused() {
    let run = treecal(&[
        "simulate",
        "--angle-error",
        "1e308",
        "--out",
        "/nonexistent",
    ]);
    assert_error(&run, &["--angle-error", "1e308"], "simulate --angle-error");
    // The library refuses it too, instead of panicking in the random range.
    let (_, model) = robonaut_model();
    let ranges = treecal::sim::ErrorRanges {
        angle: 1e308,
        length: 0.05,
    };
    assert!(treecal::sim::true_model(&model, &ranges, &mut rng(1)).is_err());
}

#[test]
fn long_names_neither_panic_inspect_nor_pass_the_loader() {
    let long = "j".repeat(70_000);
    let text = robonaut_text().replace("\"left_joint1\"", &format!("\"{long}\""));
    let error = parse_urdf(&text, "r.urdf").unwrap_err().to_string();
    assert!(error.contains("70000 characters"), "{error}");
    assert!(error.len() < 1_000, "the message must not repeat the name");
    // A long name within the limit: inspect prints it (the column just overflows).
    let dir = tempfile::tempdir().unwrap();
    let name = "j".repeat(900);
    let path = write(
        dir.path(),
        "r.urdf",
        &robonaut_text().replace("\"left_joint1\"", &format!("\"{name}\"")),
    );
    let run = treecal(&["inspect", path_str(&path)]);
    assert_success(&run, "inspect with a 900-character joint name");
    assert!(run.stdout.contains(&name));
}

#[test]
fn collinearity_test_fails_on_non_finite_targets() {
    let a = Vec3::zeros();
    let b = Vec3::new(0.1, 0.0, 0.0);
    assert!(targets_problem(&a, &b, &Vec3::new(0.0, 0.1, 0.0)).is_none());
    for bad in [f64::NAN, f64::INFINITY] {
        let c = Vec3::new(bad, 0.1, 0.0);
        assert!(targets_problem(&a, &b, &c).is_some(), "{bad}");
    }
    // Finite but far apart: the cross product overflows to NaN.
    let far = Vec3::new(1e200, 1e200, 0.0);
    assert!(targets_problem(&a, &Vec3::new(-1e200, 1e200, 0.0), &far).is_some());
}

// ---------------------------------------------------------------------------------------------
// sizes

#[test]
fn candidate_and_pose_counts_have_limits() {
    let run = treecal(&[
        "plan",
        "--poses",
        "20",
        "--candidates",
        "4294967295",
        "-o",
        "x.csv",
    ]);
    assert_error(&run, &["--candidates", "4294967295", "100000"], "plan");
    let run = treecal(&[
        "simulate",
        "--poses-from",
        "planned",
        "--candidates",
        "4294967295",
    ]);
    assert_error(&run, &["--candidates"], "simulate --candidates");
    let run = treecal(&["simulate", "--trials", "4294967295"]);
    assert_error(&run, &["--trials"], "simulate --trials");
}

/// A 10,000-joint chain took 5 GB in `check`; now the loader refuses it at once.
#[test]
fn joint_count_is_limited() {
    let chain = |joints: usize| {
        let mut text = String::from("<robot name=\"chain\">\n<link name=\"l0\"/>\n");
        for i in 1..=joints {
            text += &format!(
                "<link name=\"l{i}\"/>\n<joint name=\"j{i}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{i}\"/><origin xyz=\"0 0 0.01\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>\n",
                i - 1
            );
        }
        text + "</robot>\n"
    };
    let error = parse_urdf(&chain(10_000), "chain.urdf")
        .unwrap_err()
        .to_string();
    assert!(error.contains("10000 joints"), "{error}");
    assert!(parse_urdf(&chain(limits::MAX_JOINTS), "chain.urdf").is_ok());
}

/// A 1 GiB URDF peaked at 6.7 GB; files above the limit are refused before they are read.
#[test]
fn file_sizes_are_checked_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.urdf");
    let file = std::fs::File::create(&path).unwrap();
    file.set_len(limits::MAX_URDF_BYTES + 1).unwrap(); // sparse: no disk, no time
    let error = load_urdf(&path).unwrap_err().to_string();
    assert!(error.contains("bytes, more than the limit"), "{error}");
    let run = treecal(&["inspect", path_str(&path)]);
    assert_error(&run, &["more than the limit"], "inspect big.urdf");
}

/// A 200 KB plan file took 80 s in the YAML parser; deep nesting is refused before parsing.
#[test]
fn yaml_nesting_is_limited() {
    let deep = format!("stages: {}{}\n", "[".repeat(100_000), "]".repeat(100_000));
    let error = parse_plan(&deep, "plan.yaml").unwrap_err().to_string();
    assert!(error.starts_with("plan.yaml:1: "), "{error}");
    assert!(error.contains("nests more than"), "{error}");
    let block: String = (0..2_000)
        .map(|level| format!("{}- \n", " ".repeat(level)))
        .collect();
    assert!(parse_plan(&block, "plan.yaml").is_err());
    // The documented plan reads.
    let plan = "stages:\n  - name: torso\n    parameters: coupled\n    measurements: torso\n  - name: arms\n    parameters: arms\n    measurements: arms\n";
    assert_eq!(parse_plan(plan, "plan.yaml").unwrap().stages.len(), 2);
}

#[test]
fn csv_line_numbers_are_right_with_every_line_break() {
    let text = "# comment\r\n\r\na,b\r\n1,2\n\n# c\n3,4\r5,6\r# d\r7,8";
    let table = parse_csv(text, "t.csv").unwrap();
    assert_eq!(table.header_line, 3);
    let lines: Vec<usize> = table.records.iter().map(|(l, _)| *l).collect();
    assert_eq!(lines, [4, 7, 8, 10]);
    // Many rows: every record keeps its own line.
    let many: String = std::iter::once("a,b\n".to_owned())
        .chain((0..20_000).map(|i| format!("{i},{i}\n# note\n")))
        .collect();
    let table = parse_csv(&many, "t.csv").unwrap();
    assert_eq!(table.records.len(), 20_000);
    assert_eq!(table.records[19_999].0, 2 + 2 * 19_999);
}

/// A file with CR-only line breaks and a `#` comment read as empty (the comment swallowed
/// the rest).
#[test]
fn cr_only_files_with_comments_read() {
    let text = "# lengths in m\rleft_joint1,left_joint2\r0.1,0.2\r0.3,0.4\r";
    let table = parse_csv(text, "cr.csv").unwrap();
    assert_eq!(table.headers, ["left_joint1", "left_joint2"]);
    assert_eq!(table.records.len(), 2);
    assert_eq!(table.records[1].0, 4);
    // The example measurements with CR line breaks read as with LF.
    let (tree, model) = robonaut_model();
    let lf = example_measurements();
    let cr = lf.replace('\n', "\r");
    let a = parse_measurements(&lf, "m.csv", &tree, &model, &tracker_units()).unwrap();
    let b = parse_measurements(&cr, "m.csv", &tree, &model, &tracker_units()).unwrap();
    assert_eq!(a, b);
}

// ---------------------------------------------------------------------------------------------
// wrong outputs

#[test]
fn duplicated_rows_are_accepted_with_one_warning() {
    let (tree, model) = robonaut_model();
    let text = example_measurements();
    let clean = parse_measurements(&text, "m.csv", &tree, &model, &tracker_units()).unwrap();
    assert!(clean.warnings.is_empty(), "{:?}", clean.warnings);
    let mut lines: Vec<&str> = text.lines().collect();
    let copy = lines[4].replacen("3,", "999,", 1);
    lines.push(&copy);
    let doubled = lines.join("\n");
    let set = parse_measurements(&doubled, "m.csv", &tree, &model, &tracker_units()).unwrap();
    assert_eq!(set.measurements.len(), clean.measurements.len() + 1);
    assert_eq!(set.warnings.len(), 1, "{:?}", set.warnings);
    assert!(
        set.warnings[0].starts_with("m.csv:63: the row repeats line 5"),
        "{:?}",
        set.warnings
    );
}

#[test]
fn from_mcpc_escapes_names() {
    let text = std::fs::read_to_string(robot("robonaut/table1.yaml")).unwrap();
    let text = text
        .replacen("robot: robonaut", "robot: \"r<&\\\"'>\"", 1)
        .replace("link: left_link1,", "link: \"left&<link1>\",");
    let table = parse_mcpc_table(&text, "t.yaml").unwrap();
    let urdf = urdf_from_mcpc_table(&table, "a--b.yaml");
    assert!(
        urdf.contains("name=\"r&lt;&amp;&quot;&apos;&gt;\""),
        "{urdf}"
    );
    assert!(urdf.contains("a- -b.yaml"));
    let import = parse_urdf(&urdf, "generated.urdf").unwrap();
    assert_eq!(import.tree.name(), "r<&\"'>");
    assert!(import.tree.link_id("left&<link1>").is_ok());
}

#[test]
fn to_mcpc_output_reads_back_with_any_printable_name() {
    let (tree, model) = robonaut_model();
    let branches = detect_branches(&tree, None).unwrap();
    let mut table = treecal::McpcTable::from_model(&tree, &branches, &model).unwrap();
    table.robot = "a\"b\\c\u{2028}d\u{feff}".into();
    let yaml = mcpc_table_to_yaml(&table, &["header".into()]);
    let back = parse_mcpc_table(&yaml, "t.yaml").unwrap();
    assert_eq!(back.robot, table.robot);
    // "Unbounded" limits as real URDFs write them (±1e16) go through to-mcpc and back.
    let text = robonaut_text().replacen("<limit lower=\"", "<limit lower=\"-1e16\" x=\"", 1);
    let tree = parse_urdf(&text, "r.urdf").unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    let table = treecal::McpcTable::from_model(&tree, &branches, &model).unwrap();
    let yaml = mcpc_table_to_yaml(&table, &[]);
    let back = parse_mcpc_table(&yaml, "t.yaml").unwrap();
    let rows = back.branches.iter().flat_map(|b| &b.rows);
    assert_eq!(rows.filter(|r| r.limits.0 < -0.99e16).count(), 1);
    // Control characters cannot reach a table: the URDF loader refuses them.
    let text = robonaut_text().replace("\"left_joint1\"", "\"left&#9;joint1\"");
    let error = parse_urdf(&text, "r.urdf").unwrap_err().to_string();
    assert!(error.contains("control characters"), "{error}");
}

#[test]
fn outputs_never_overwrite_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = write(dir.path(), "r.urdf", &robonaut_text());
    let before = std::fs::read(&urdf).unwrap();
    let run = treecal(&["to-mcpc", path_str(&urdf), "-o", path_str(&urdf)]);
    assert_error(&run, &["replace the input"], "to-mcpc r.urdf -o r.urdf");
    // Another spelling of the same path.
    let other = dir.path().join(".").join("r.urdf");
    let run = treecal(&["to-mcpc", path_str(&urdf), "-o", path_str(&other)]);
    assert_error(&run, &["replace the input"], "to-mcpc via ./");
    let table = write(dir.path(), "t.yaml", "x");
    let run = treecal(&["from-mcpc", path_str(&table), "-o", path_str(&table)]);
    assert_error(&run, &["replace the input"], "from-mcpc");
    let joints = write(dir.path(), "j.csv", "left_joint1\n0\n");
    let run = treecal(&[
        "fk",
        path_str(&urdf),
        "--tip",
        "left_tool",
        "--joints",
        path_str(&joints),
        "-o",
        path_str(&joints),
    ]);
    assert_error(&run, &["replace the input"], "fk");
    let params = write(dir.path(), "params.yaml", "parameters: []\n");
    let run = treecal(&[
        "export",
        "--robot",
        path_str(&urdf),
        "--params",
        path_str(&params),
        "-o",
        path_str(&params),
    ]);
    assert_error(&run, &["replace the input"], "export");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&params),
        "--out",
        path_str(dir.path()),
    ]);
    assert_error(&run, &["replace the input"], "calibrate --out");
    assert_eq!(std::fs::read(&urdf).unwrap(), before);
    // A different output is written.
    let run = treecal(&[
        "to-mcpc",
        path_str(&urdf),
        "-o",
        path_str(&dir.path().join("t2.yaml")),
    ]);
    assert_success(&run, "to-mcpc to another file");
}

// ---------------------------------------------------------------------------------------------
// magnitudes in every reader

#[test]
fn yaml_numbers_are_bounded_with_their_place() {
    let (tree, model) = robonaut_model();
    let params = "parameters:\n  - name: left_joint1 alpha\n    calibrated: 1e300\n";
    let error = parse_parameters(params, "p.yaml", &tree, &model)
        .unwrap_err()
        .to_string();
    assert!(error.starts_with("p.yaml:2:"), "{error}");
    assert!(error.contains("beyond the limit"), "{error}");
    let stiffness = "payloads:\n  left_tool: {mass_kg: 1e9}\n";
    let error = parse_stiffness(stiffness, "s.yaml", &tree, &model)
        .unwrap_err()
        .to_string();
    assert!(error.contains("s.yaml:2:"), "{error}");
    assert!(error.contains("mass_kg"), "{error}");
    let stiffness = "joints:\n  default: {bending_nm_per_rad: 1e-300}\n";
    let error = parse_stiffness(stiffness, "s.yaml", &tree, &model)
        .unwrap_err()
        .to_string();
    assert!(error.contains("bending_nm_per_rad"), "{error}");
    let table = std::fs::read_to_string(robot("robonaut/table1.yaml"))
        .unwrap()
        .replacen("alpha: -90", "alpha: 1e300", 1);
    let error = parse_mcpc_table(&table, "t.yaml").unwrap_err().to_string();
    assert!(
        error.contains("torso_joint2") && error.contains("alpha"),
        "{error}"
    );
    // The repository's own files read (no false alarms).
    let table = std::fs::read_to_string(robot("robonaut/table1.yaml")).unwrap();
    assert!(parse_mcpc_table(&table, "t.yaml").is_ok());
    let stiffness = std::fs::read_to_string(robot("robonaut/stiffness.yaml")).unwrap();
    assert!(parse_stiffness(&stiffness, "s.yaml", &tree, &model).is_ok());
}

#[test]
fn joint_values_are_bounded() {
    let (tree, _) = robonaut_model();
    let table = parse_csv("left_joint1\n1e300\n", "j.csv").unwrap();
    let error = treecal::io::configurations(&table, &tree, 1.0, "j.csv")
        .unwrap_err()
        .to_string();
    assert!(error.starts_with("j.csv:2:left_joint1: "), "{error}");
    let table = parse_csv("left_joint1\n359\n", "j.csv").unwrap();
    assert!(treecal::io::configurations(&table, &tree, 1.0_f64.to_radians(), "j.csv").is_ok());
}

/// The limits reject none of the 69 real URDFs of example-robot-data.
#[test]
fn real_robots_are_within_the_limits() {
    let Some(root) = example_robot_data() else {
        return;
    };
    let mut checked = 0;
    let mut stack = vec![root];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "urdf") {
                if let Err(error) = load_urdf(&path) {
                    let message = error.to_string();
                    assert!(!message.contains("Limits"), "{}: {message}", path.display());
                    assert!(
                        !message.contains("control char"),
                        "{}: {message}",
                        path.display()
                    );
                }
                checked += 1;
            }
        }
    }
    assert!(checked >= 50, "only {checked} URDFs found");
}

// ---------------------------------------------------------------------------------------------
// fuzz findings

/// Every input the fuzz targets found (and every seed kept next to them) runs through its
/// target's entry without a panic; see fuzz/README.md.
#[test]
fn fuzz_findings_replay() {
    let root = repo().join("tests/data/fuzz");
    let mut replayed = 0;
    for target in crate::common::fuzz::TARGETS {
        let Ok(entries) = std::fs::read_dir(root.join(target)) else {
            continue;
        };
        for entry in entries.flatten() {
            let data = std::fs::read(entry.path()).unwrap();
            crate::common::fuzz::run(target, &data);
            replayed += 1;
        }
    }
    // The repository's own files, as the fuzzers' seeds.
    crate::common::fuzz::run("urdf", robonaut_text().as_bytes());
    crate::common::fuzz::run(
        "mcpc_table",
        &std::fs::read(robot("robonaut/table1.yaml")).unwrap(),
    );
    eprintln!("replayed {replayed} fuzz inputs");
}
