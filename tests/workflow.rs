//! The library workflows (`treecal::workflow`) against the CLI: the same numbers to the bit,
//! measurements from arrays checked like a CSV, and the CLI grammar shared by the commands.

use crate::common::cli::*;
use crate::common::*;
use rand::RngExt;
use std::path::PathBuf;
use treecal::io::{AngleUnit, LengthUnit, MeasurementTable, ObservationRows};
use treecal::workflow::{
    calibrate, fk, CalibrateConfig, FkConfig, MeasurementSource, PlanSource, RobotSource,
    StiffnessSource,
};

/// The example measurements (three targets, mm and deg, staged labels).
fn example_csv() -> PathBuf {
    robot("robonaut/example/measurements.csv")
}

/// The example's stiffness file (its data are gravity-loaded).
fn stiffness() -> PathBuf {
    robot("robonaut/stiffness.yaml")
}

/// The configuration of the README's example calibration.
fn example_config(measurements: MeasurementSource) -> CalibrateConfig {
    CalibrateConfig {
        measurements,
        stiffness: Some(StiffnessSource::File(stiffness())),
        ..CalibrateConfig::default()
    }
}

/// The example CSV's rows as arrays, numbers parsed as the CSV reader parses them.
fn example_table() -> MeasurementTable {
    let text = std::fs::read_to_string(example_csv()).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(&header[..3], ["id", "stage", "tool"]);
    let observed = header.len() - 9;
    let joint_names: Vec<String> = header[3..observed].iter().map(|s| s.to_string()).collect();
    let (mut ids, mut stages, mut tools, mut joints, mut targets) =
        (vec![], vec![], vec![], vec![], vec![]);
    let number = |cell: &str| {
        if cell.is_empty() {
            f64::NAN
        } else {
            cell.parse::<f64>().unwrap()
        }
    };
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        ids.push(cells[0].to_owned());
        stages.push(cells[1].to_owned());
        tools.push(cells[2].to_owned());
        joints.push(cells[3..observed].iter().map(|c| number(c)).collect());
        let values: Vec<f64> = cells[observed..].iter().map(|c| number(c)).collect();
        targets.push(<[f64; 9]>::try_from(values).unwrap());
    }
    MeasurementTable {
        origin: "measurements (arrays)".into(),
        ids: Some(ids),
        tools,
        joint_names,
        joints,
        observations: ObservationRows::ThreeTargets(targets),
        stages: Some(stages),
        sessions: None,
        points: None,
        length_unit: Some(LengthUnit::Millimetre),
        angle_unit: Some(AngleUnit::Degree),
    }
}

#[test]
fn calibrate_from_a_csv_and_from_arrays_gives_identical_parameters() {
    let from_csv = calibrate(&example_config(MeasurementSource::Csv(example_csv()))).unwrap();
    let from_table = calibrate(&example_config(MeasurementSource::Table(example_table()))).unwrap();
    assert!(from_csv.usable(), "{:?}", from_csv.verdict);
    assert_eq!(from_csv.verdict, from_table.verdict);
    assert_eq!(from_csv.parameters.len(), from_table.parameters.len());
    for (a, b) in from_csv.parameters.iter().zip(&from_table.parameters) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.calibrated.to_bits(), b.calibrated.to_bits(), "{}", a.name);
        assert_eq!(
            a.std_dev.map(f64::to_bits),
            b.std_dev.map(f64::to_bits),
            "{}",
            a.name
        );
    }
    assert_eq!(from_csv.urdf, from_table.urdf);
    assert!(from_csv.urdf.is_some());
    // The reports differ only where they name the source.
    assert_eq!(from_csv.report()["stages"], from_table.report()["stages"]);
    assert!(from_table.report()["context"]["measurements"]
        .as_str()
        .unwrap()
        .starts_with("measurements (arrays)"));
}

/// The library's outcome is what the CLI writes: the same report.md, parameters and URDF.
#[test]
fn calibrate_writes_what_the_cli_writes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cli");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&example_csv()),
        "--stiffness",
        path_str(&stiffness()),
        "-o",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate");
    let calibration = calibrate(&example_config(MeasurementSource::Csv(example_csv()))).unwrap();
    // The CLI ran in the repository root with an absolute path: the same text.
    assert_eq!(
        run.stdout,
        as_cli(&calibration.report_markdown, &run.stdout)
    );
    let written = std::fs::read_to_string(out.join("calibrated.urdf")).unwrap();
    assert_eq!(Some(written), calibration.urdf);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_json_close(&report, &calibration.report(), "report");
    for note in &calibration.notes {
        assert!(
            run.stderr.contains(&format!(
                "treecal: {}",
                as_cli(&note.to_string(), &run.stderr)
            )),
            "{note}\n{run}"
        );
    }
    let library = dir.path().join("library");
    calibration.write(&library).unwrap();
    for (name, bytes) in &calibration.files {
        assert_eq!(&std::fs::read(library.join(name)).unwrap(), bytes, "{name}");
    }
}

/// The same JSON up to the last bit of a number (serde_json's default parser may round the
/// text of report.json one unit in the last place away from the value that was written).
fn assert_json_close(a: &serde_json::Value, b: &serde_json::Value, at: &str) {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= 4.0 * f64::EPSILON * x.abs(),
                "{at}: {x} != {y}"
            );
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}");
            for (i, (x, y)) in x.iter().zip(y).enumerate() {
                assert_json_close(x, y, &format!("{at}[{i}]"));
            }
        }
        (Value::Object(x), Value::Object(y)) => {
            assert_eq!(
                x.keys().collect::<Vec<_>>(),
                y.keys().collect::<Vec<_>>(),
                "{at}"
            );
            for (key, x) in x {
                assert_json_close(x, &y[key], &format!("{at}.{key}"));
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}

/// Errors in arrays name the table, the row id and the column, as a CSV's name the line.
#[test]
fn array_errors_name_the_row_id() {
    let base = example_table();
    let error = |table: MeasurementTable| {
        calibrate(&example_config(MeasurementSource::Table(table)))
            .unwrap_err()
            .to_string()
    };
    let ids = base.ids.as_ref().unwrap().clone();

    let mut table = base.clone();
    table.joints[4][1] = 1e9;
    let message = error(table);
    let place = format!(
        "measurements (arrays), row {}, column '{}'",
        ids[4], base.joint_names[1]
    );
    assert!(message.contains(&place), "{message}");

    let mut table = base.clone();
    if let ObservationRows::ThreeTargets(rows) = &mut table.observations {
        rows[7][3] = f64::NAN;
    }
    let message = error(table);
    assert!(
        message.contains(&format!("row {}, column 'bx'", ids[7])) && message.contains("missing"),
        "{message}"
    );

    let mut table = base.clone();
    table.ids.as_mut().unwrap()[9] = "probe-9".into();
    table.tools[9] = "left_tol".into();
    let message = error(table);
    assert!(
        message.contains("row probe-9, column 'tool'") && message.contains("left_tool"),
        "{message}"
    );

    let mut table = base.clone();
    table.ids.as_mut().unwrap()[3] = ids[2].clone();
    let message = error(table);
    assert!(message.contains("already used"), "{message}");

    let mut table = base.clone();
    table.joints[5].pop();
    let message = error(table);
    assert!(
        message.contains(&format!("row {}", ids[5])) && message.contains("joint values"),
        "{message}"
    );

    let mut table = base.clone();
    table.stages.as_mut().unwrap().pop();
    assert!(error(table).contains("stages"));

    // The unit diagnoses are the CSV's: degrees read as radians are named.
    let mut table = base.clone();
    table.angle_unit = None;
    let message = error(table);
    assert!(message.contains("look like degrees"), "{message}");

    // Contradicting units are named.
    let message = calibrate(&CalibrateConfig {
        length_unit: Some(LengthUnit::Metre),
        ..example_config(MeasurementSource::Table(base.clone()))
    })
    .unwrap_err()
    .to_string();
    assert!(
        message.contains("length unit m given contradicts the table's length unit mm"),
        "{message}"
    );
}

/// Forward kinematics from arrays equals the CLI's `fk` to the last bit, in rad and deg.
#[test]
fn fk_equals_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = robot("robonaut/robonaut.urdf");
    let tree = treecal::load_urdf(&urdf).unwrap().tree;
    let names: Vec<String> = tree
        .dofs()
        .iter()
        .map(|j| tree.joint(*j).name.clone())
        .collect();
    let mut rng = rng(15);
    for (unit, scale, flag) in [
        (AngleUnit::Radian, 1.0, "rad"),
        (AngleUnit::Degree, 180.0 / std::f64::consts::PI, "deg"),
    ] {
        let rows: Vec<Vec<f64>> = (0..6)
            .map(|_| {
                random_configuration(&tree, &mut rng)
                    .iter()
                    .map(|v| v * scale * rng.random_range(0.9..1.0))
                    .collect()
            })
            .collect();
        let mut csv = names.join(",") + "\n";
        for row in &rows {
            let cells: Vec<String> = row.iter().map(|v| format!("{v}")).collect();
            csv += &(cells.join(",") + "\n");
        }
        let joints = dir.path().join(format!("joints_{flag}.csv"));
        std::fs::write(&joints, csv).unwrap();
        let run = treecal(&[
            "fk",
            "--robot",
            path_str(&urdf),
            "--tip",
            "left_tool",
            "--joints",
            path_str(&joints),
            "--angle-unit",
            flag,
        ]);
        assert_success(&run, "fk");
        let poses = fk(&FkConfig {
            robot: RobotSource::File(urdf.clone()),
            tip: "left_tool".into(),
            joint_names: names.clone(),
            joints: rows.clone(),
            angle_unit: unit,
            first_row: 0,
        })
        .unwrap();
        let lines: Vec<&str> = run.stdout.lines().skip(1).collect();
        assert_eq!(lines.len(), poses.len());
        for (line, pose) in lines.iter().zip(&poses) {
            let cells: Vec<f64> = line.split(',').map(|c| c.parse().unwrap()).collect();
            let printed = &cells[names.len()..];
            let t = pose.translation.vector;
            let r = pose.rotation.to_rotation_matrix();
            let mut expected = vec![t.x, t.y, t.z];
            for i in 0..3 {
                for j in 0..3 {
                    expected.push(r[(i, j)]);
                }
            }
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(printed), bits(&expected), "{flag}: {line}");
        }
    }
}

#[test]
fn fk_names_unknown_and_implied_joints() {
    let config = |names: &[&str], rows: Vec<Vec<f64>>| FkConfig {
        robot: RobotSource::BuiltIn,
        tip: "left_tool".into(),
        joint_names: names.iter().map(|s| s.to_string()).collect(),
        joints: rows,
        angle_unit: AngleUnit::Radian,
        first_row: 0,
    };
    let error = fk(&config(&["left_jiont1"], vec![vec![0.1]]))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("left_jiont1") && error.contains("left_joint1"),
        "{error}"
    );
    let error = fk(&config(&["left_joint1"], vec![vec![0.1, 0.2]]))
        .unwrap_err()
        .to_string();
    assert!(error.contains("row 1"), "{error}");
    let error = fk(&config(&["left_joint1"], vec![vec![0.1], vec![f64::NAN]]))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("row 2, joint 'left_joint1'") && error.contains("finite"),
        "{error}"
    );
    // No joints given: every joint at 0, as a CSV without columns.
    let zero = fk(&config(&[], vec![vec![]])).unwrap();
    let tree = treecal::parse_urdf(treecal::workflow::BUILT_IN_ROBONAUT, "r")
        .unwrap()
        .tree;
    let tip = tree.link_id("left_tool").unwrap();
    assert_eq!(
        zero[0],
        tree.link_pose(tip, &tree.zero_configuration()).unwrap()
    );
}

/// `--robot` and the positional robot give the same output; both at once are refused.
#[test]
fn robot_flag_and_positional_robot_agree() {
    let urdf = robot("humanoid/humanoid.urdf");
    let urdf = path_str(&urdf);
    for command in [["inspect"], ["to-mcpc"]] {
        let positional = treecal(&[command[0], urdf]);
        let flag = treecal(&[command[0], "--robot", urdf]);
        assert_success(&positional, command[0]);
        assert_eq!(positional.stdout, flag.stdout, "{}", command[0]);
        let both = treecal(&[command[0], urdf, "--robot", urdf]);
        assert!(
            !both.success && both.stderr.contains("cannot be used with"),
            "{both}"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let joints = dir.path().join("joints.csv");
    std::fs::write(&joints, "left_joint1,torso_joint1\n0.3,-0.2\n").unwrap();
    let fk = |robot: &[&str]| {
        let mut args = vec!["fk"];
        args.extend_from_slice(robot);
        args.extend_from_slice(&["--tip", "left_tool", "--joints", path_str(&joints)]);
        treecal(&args)
    };
    let robonaut = robot_path_text();
    let positional = fk(&[&robonaut]);
    assert_success(&positional, "fk positional");
    assert_eq!(positional.stdout, fk(&["--robot", &robonaut]).stdout);
    // Without a robot: the built-in Robonaut, the same robot.
    assert_eq!(positional.stdout, fk(&[]).stdout);
}

fn robot_path_text() -> String {
    path_str(&robot("robonaut/robonaut.urdf")).to_owned()
}

/// `--plan stagged` lists the choices and suggests the nearest; a .yaml value is still a
/// plan file, and `--plan-file` names one.
#[test]
fn plan_typos_list_the_choices() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let csv = example_csv();
    let stiffness = stiffness();
    let base = [
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--stiffness",
        path_str(&stiffness),
        "-o",
        path_str(&out),
    ];
    let with = |extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        treecal(&args)
    };
    let run = with(&["--plan", "stagged"]);
    assert!(!run.success, "{run}");
    for needle in [
        "invalid value 'stagged'",
        "[possible values: staged, simultaneous]",
        "'staged'",
    ] {
        assert!(run.stderr.contains(needle), "{needle}\n{run}");
    }
    assert!(!out.exists());
    let plan = dir.path().join("all.yaml");
    std::fs::write(
        &plan,
        "stages:\n  - name: everything\n    parameters: all\n",
    )
    .unwrap();
    let file = with(&["--plan-file", path_str(&plan)]);
    assert_success(&file, "--plan-file");
    assert!(file
        .stdout
        .contains(&format!("plan file {}", plan.display())));
    let old = with(&["--plan", path_str(&plan)]);
    assert_success(&old, "--plan FILE");
    assert_eq!(file.stdout, old.stdout);
    let both = with(&["--plan", "staged", "--plan-file", path_str(&plan)]);
    assert!(
        !both.success && both.stderr.contains("cannot be used with"),
        "{both}"
    );
    // The library's PlanSource::File gives the same report.
    let calibration = calibrate(&CalibrateConfig {
        plan: PlanSource::File(plan.clone()),
        ..example_config(MeasurementSource::Csv(example_csv()))
    })
    .unwrap();
    assert_eq!(
        as_cli(&calibration.report_markdown, &file.stdout),
        file.stdout
    );
}

/// Every command writing a file takes `-o`/`--out`; the old `--output` still works.
#[test]
fn out_is_the_output_flag_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    let table = |flag: &str| {
        let path = dir.path().join(format!("table{flag}.yaml"));
        let run = treecal(&["to-mcpc", flag, path_str(&path)]);
        assert_success(&run, flag);
        std::fs::read_to_string(&path).unwrap()
    };
    let short = table("-o");
    assert_eq!(short, table("--out"));
    assert_eq!(short, table("--output"));
}

/// The library's text as the CLI prints it: a `setting` the CLI's text spells as its flag.
fn as_cli(library: &str, cli: &str) -> String {
    treecal::error::name_settings(library, |setting| {
        let flag = format!("--{}", setting.replace('_', "-"));
        cli.contains(&flag).then_some(flag)
    })
}
