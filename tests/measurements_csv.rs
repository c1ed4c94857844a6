//! The measurement CSV: writer → reader round trips, units, the three-target frame, and one
//! bad-input test per error, each checking that the message names file, line and column.

use crate::common::*;
use rand::RngExt;
use treecal::io::{
    measurements_to_csv, measurements_to_csv_with, parse_measurements, read_measurements,
    AngleUnit, LengthUnit, MeasurementReadOptions, MeasurementSet, MeasurementWriteOptions,
    ObservationKind,
};
use treecal::kinematics::McpcModel;
use treecal::math::{Pose, Vec3};
use treecal::measurement::{targets_on, Measurement, Observation};
use treecal::tree::KinematicTree;
use treecal::Error;

/// Measurements at random configurations, alternating tools, observing the URDF tool frame.
fn simulated(tree: &KinematicTree, model: &McpcModel, seed: u64, poses: bool) -> Vec<Measurement> {
    let mut rng = rng(seed);
    (0..12)
        .map(|i| {
            let q = random_configuration(tree, &mut rng);
            let tool = i % model.tools().len();
            let pose = tree.link_pose(model.tools()[tool].link, &q).unwrap();
            Measurement {
                payload: None,
                tool,
                q,
                observation: if poses {
                    Observation::Pose(pose)
                } else {
                    Observation::Position(pose.translation.vector)
                },
                stage: (i % 3 != 0).then(|| ["torso", "arms"][i % 2].to_owned()),
                session: None,
            }
        })
        .collect()
}

fn assert_close(a: f64, b: f64, what: &str) {
    assert!(
        (a - b).abs() <= 1e-12 * (1.0 + a.abs().max(b.abs())),
        "{what}: {a} vs {b}"
    );
}

fn assert_pose_close(a: &Pose, b: &Pose, what: &str) {
    for i in 0..3 {
        assert_close(a.translation.vector[i], b.translation.vector[i], what);
    }
    let angle = a.rotation.angle_to(&b.rotation);
    assert!(angle < 1e-12, "{what}: rotations differ by {angle} rad");
}

fn assert_same(read: &MeasurementSet, written: &[Measurement]) {
    assert_eq!(read.measurements.len(), written.len());
    for (index, (r, w)) in read.measurements.iter().zip(written).enumerate() {
        assert_eq!(r.tool, w.tool, "row {index}");
        assert_eq!(r.stage, w.stage, "row {index}");
        assert_eq!(r.q.len(), w.q.len());
        for (a, b) in r.q.iter().zip(&w.q) {
            assert_close(*a, *b, &format!("row {index} q"));
        }
        match (&r.observation, &w.observation) {
            (Observation::Pose(a), Observation::Pose(b)) => {
                assert_pose_close(a, b, &format!("row {index}"))
            }
            (Observation::Position(a), Observation::Position(b)) => {
                for i in 0..3 {
                    assert_close(a[i], b[i], &format!("row {index} position"));
                }
            }
            other => panic!("row {index}: observation kinds differ: {other:?}"),
        }
    }
}

fn parse(text: &str, options: &MeasurementReadOptions) -> treecal::Result<MeasurementSet> {
    let (tree, model) = robonaut_model();
    parse_measurements(text, "bad.csv", &tree, &model, options)
}

/// Parses `text` on Robonaut and returns the error message, which must start with `place`.
fn error(text: &str, options: &MeasurementReadOptions, place: &str) -> String {
    let message = match parse(text, options) {
        Ok(set) => panic!("expected an error at {place}, read {set:?}"),
        Err(e) => e.to_string(),
    };
    assert!(
        message.starts_with(&format!("{place}: ")),
        "the message should start with '{place}: ': {message}"
    );
    message
}

const HEADER: &str = "id,stage,tool,torso_joint1,torso_joint2,left_joint1,left_joint2,left_joint3,left_joint4,left_joint5,left_joint6,x,y,z";
const ROW: &str = "1,arms,left_tool,0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8,1,2,3";

/// A one-row left-arm file with the cell of column `column` replaced by `value`.
fn with_cell(column: &str, value: &str) -> String {
    let index = HEADER.split(',').position(|c| c == column).unwrap();
    let mut cells: Vec<&str> = ROW.split(',').collect();
    cells[index] = value;
    format!("{HEADER}\n# a comment line\n{}\n", cells.join(","))
}

#[test]
fn round_trips_positions_and_poses() {
    for robot in [
        "robonaut/robonaut.urdf",
        "dual_arm_prismatic/dual_arm_prismatic.urdf",
    ] {
        let (tree, model) = robot_model(robot);
        for poses in [false, true] {
            let written = simulated(&tree, &model, 5, poses);
            let text = measurements_to_csv(&tree, &model, &written).unwrap();
            let options = MeasurementReadOptions::default();
            let read = parse_measurements(&text, "round.csv", &tree, &model, &options).unwrap();
            assert_same(&read, &written);
            let expected = if poses {
                ObservationKind::Pose
            } else {
                ObservationKind::Position
            };
            assert_eq!(read.observation, expected);
            assert_eq!(
                read.ids,
                (1..=12).map(|i| i.to_string()).collect::<Vec<_>>()
            );
            assert_eq!(read.lines, (2..=13).collect::<Vec<_>>());
            assert!(read.warnings.is_empty(), "{:?}", read.warnings);
        }
    }
}

#[test]
fn round_trips_in_millimetres_degrees_and_three_targets() {
    let (tree, model) = robot_model("dual_arm_prismatic/dual_arm_prismatic.urdf");
    let written = simulated(&tree, &model, 8, true);
    for three_targets in [false, true] {
        let write = MeasurementWriteOptions {
            length_unit: LengthUnit::Millimetre,
            angle_unit: AngleUnit::Degree,
            three_targets,
        };
        let text = measurements_to_csv_with(&tree, &model, &written, &write).unwrap();
        assert!(text.starts_with("# units: length=mm angle=deg\n"), "{text}");
        let read_options = MeasurementReadOptions {
            length_unit: Some(LengthUnit::Millimetre),
            angle_unit: Some(AngleUnit::Degree),
            ..Default::default()
        };
        let read = parse_measurements(&text, "mm.csv", &tree, &model, &read_options).unwrap();
        assert_same(&read, &written);
        assert_eq!(
            read.lines[0], 3,
            "the unit comment is line 1, the header line 2"
        );
        let kind = if three_targets {
            ObservationKind::ThreeTargets
        } else {
            ObservationKind::Pose
        };
        assert_eq!(read.observation, kind);
        // Without flags the units comment decides; a flag against it is an error; without the
        // comment the same numbers read in metres and radians are other measurements.
        let from_comment =
            parse_measurements(&text, "mm.csv", &tree, &model, &Default::default()).unwrap();
        assert_same(&from_comment, &written);
        let against = MeasurementReadOptions {
            angle_unit: Some(AngleUnit::Radian),
            ..Default::default()
        };
        let conflict = parse_measurements(&text, "mm.csv", &tree, &model, &against)
            .unwrap_err()
            .to_string();
        assert!(
            conflict.starts_with("mm.csv:1: `angle_unit` rad contradicts"),
            "{conflict}"
        );
        let bare = text.split_once('\n').unwrap().1;
        let wrong = parse_measurements(bare, "mm.csv", &tree, &model, &Default::default());
        assert!(wrong.is_err() || wrong.unwrap().measurements != read.measurements);
    }
    let positions = simulated(&tree, &model, 9, false);
    let write = MeasurementWriteOptions {
        three_targets: true,
        ..Default::default()
    };
    let message = measurements_to_csv_with(&tree, &model, &positions, &write)
        .unwrap_err()
        .to_string();
    assert!(message.contains("three targets"), "{message}");
}

#[test]
fn default_writer_output_is_unchanged() {
    let (tree, model) = robonaut_model();
    let written = simulated(&tree, &model, 2, true);
    let text = measurements_to_csv(&tree, &model, &written).unwrap();
    let first = text.lines().next().unwrap();
    assert!(first.starts_with("id,stage,tool,torso_joint1,"), "{first}");
    assert!(first.ends_with(",x,y,z,qw,qx,qy,qz"), "{first}");
    let same = measurements_to_csv_with(&tree, &model, &written, &Default::default()).unwrap();
    assert_eq!(text, same);
}

#[test]
fn unit_flags_scale_lengths_and_angles() {
    let (tree, model) = robot_model("dual_arm_prismatic/dual_arm_prismatic.urdf");
    let text = "tool,torso_lift,torso_yaw,left_j1,left_j2,left_j3,left_j4,left_j5,left_j6,x,y,z\n\
                left_tool,100,90,0,0,0,0,0,0,1000,-250,2.5\n";
    let dof = |name: &str| tree.dof_of(tree.joint_id(name).unwrap()).unwrap().0;
    let cases = [
        (
            LengthUnit::Metre,
            AngleUnit::Radian,
            100.0,
            90.0,
            [1000.0, -250.0, 2.5],
        ),
        (
            LengthUnit::Millimetre,
            AngleUnit::Radian,
            0.1,
            90.0,
            [1.0, -0.25, 0.0025],
        ),
        (
            LengthUnit::Millimetre,
            AngleUnit::Degree,
            0.1,
            std::f64::consts::FRAC_PI_2,
            [1.0, -0.25, 0.0025],
        ),
        (
            LengthUnit::Metre,
            AngleUnit::Degree,
            100.0,
            std::f64::consts::FRAC_PI_2,
            [1000.0, -250.0, 2.5],
        ),
    ];
    for (length_unit, angle_unit, lift, yaw, position) in cases {
        let options = MeasurementReadOptions {
            length_unit: Some(length_unit),
            angle_unit: Some(angle_unit),
            ..Default::default()
        };
        let set = parse_measurements(text, "units.csv", &tree, &model, &options).unwrap();
        let m = &set.measurements[0];
        assert_close(m.q[dof("torso_lift")], lift, "prismatic joint");
        assert_close(m.q[dof("torso_yaw")], yaw, "revolute joint");
        let Observation::Position(p) = m.observation else {
            panic!("expected a position")
        };
        for i in 0..3 {
            assert_close(p[i], position[i], "position");
        }
        assert_eq!(
            set.ids,
            ["1"],
            "without an id column the id is the row number"
        );
        assert_eq!(m.stage, None);
    }
    assert!("mm".parse::<LengthUnit>().is_ok() && "deg".parse::<AngleUnit>().is_ok());
    let message = "cm".parse::<LengthUnit>().unwrap_err().to_string();
    assert!(
        message.starts_with("`length_unit`: ") && message.contains("m or mm"),
        "{message}"
    );
}

#[test]
fn three_targets_give_the_frame_they_were_placed_on() {
    let (tree, model) = robonaut_model();
    let mut rng = rng(31);
    let header = "tool,torso_joint1,torso_joint2,left_joint1,left_joint2,left_joint3,left_joint4,left_joint5,left_joint6,ax,ay,az,bx,by,bz,cx,cy,cz";
    for _ in 0..50 {
        let translation = Vec3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
        );
        let axis = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let pose = Pose::new(translation, axis * rng.random_range(0.0..3.0));
        // B along x at 0.1 m; C anywhere in the x-y half-plane y > 0, not only on y.
        let [a, b, _] = targets_on(&pose);
        let c_local = Vec3::new(
            rng.random_range(-0.2..0.2),
            rng.random_range(0.05..0.2),
            0.0,
        );
        let c = pose * nalgebra::Point3::from(c_local);
        let cells: Vec<String> = [a, b, c.coords]
            .iter()
            .flat_map(|t| t.iter().map(|v| format!("{}", v * 1e3)).collect::<Vec<_>>())
            .collect();
        let text = format!("{header}\nleft_tool,0,0,0,0,0,0,0,0,{}\n", cells.join(","));
        let options = MeasurementReadOptions {
            length_unit: Some(LengthUnit::Millimetre),
            ..Default::default()
        };
        let set = parse_measurements(&text, "targets.csv", &tree, &model, &options).unwrap();
        assert_eq!(set.observation, ObservationKind::ThreeTargets);
        let Observation::Pose(read) = &set.measurements[0].observation else {
            panic!("three targets give a pose")
        };
        assert_pose_close(read, &pose, "three-target frame");
    }
}

#[test]
fn every_bad_value_is_reported_at_its_line_and_column() {
    let strict = MeasurementReadOptions {
        strict_limits: true,
        ..Default::default()
    };
    let plain = MeasurementReadOptions::default();
    let cases: Vec<(String, &MeasurementReadOptions, &str, &str)> = vec![
        (with_cell("y", ""), &plain, "bad.csv:3:y", "the value is missing"),
        (with_cell("left_joint2", "abc"), &plain, "bad.csv:3:left_joint2", "'abc' is not a number"),
        (with_cell("x", "NaN"), &plain, "bad.csv:3:x", "not a finite number"),
        (with_cell("left_joint4", "inf"), &plain, "bad.csv:3:left_joint4", "not a finite number"),
        (with_cell("z", "-1e400"), &plain, "bad.csv:3:z", "not a finite number"),
        (with_cell("torso_joint1", "3.1"), &strict, "bad.csv:3:torso_joint1", "outside the limits of joint 'torso_joint1' [-2.9670597283903604, 2.9670597283903604] rad"),
        (with_cell("tool", "left_tol"), &plain, "bad.csv:3:tool", "did you mean 'left_tool'?; the tools are 'left_tool', 'right_tool'"),
        (with_cell("left_joint6", ""), &plain, "bad.csv:3:left_joint6", "tool 'left_tool' moves with joint 'left_joint6'"),
        (with_cell("id", ""), &plain, "bad.csv:3:id", "the id is empty"),
        (format!("{HEADER}\n{ROW}\n\n{ROW}\n"), &plain, "bad.csv:4:id", "id '1' was already used on line 2"),
        (HEADER.replace(",left_joint6", "") + "\n" + &ROW.replace(",0.8,", ",") + "\n", &plain, "bad.csv:2:left_joint6", "has no column 'left_joint6'"),
        (HEADER.replace(",tool", "") + "\n" + &ROW.replace(",left_tool", "") + "\n", &plain, "bad.csv:1", "no 'tool' column; add one naming the measured tool link of each row (one of 'left_tool', 'right_tool'), or name the one measured tool with `tools`"),
        (HEADER.replace(",z", "") + "\n" + &ROW.replace(",3", "") + "\n", &plain, "bad.csv:1", "the observation columns x,y are not a complete layout; give exactly x,y,z (a position); x,y,z with qw,qx,qy,qz"),
        (format!("{HEADER},qw\n{ROW},1\n"), &plain, "bad.csv:1", "x,y,z,qw are not a complete layout"),
        (HEADER.replace(",x,y,z", "") + "\n" + &ROW.replace(",1,2,3", "") + "\n", &plain, "bad.csv:1", "no observation columns"),
        (format!("{HEADER},qw,qx,qy,qz\n{ROW},0.5,0.5,0.5,0.6\n"), &plain, "bad.csv:2:qw", "check the column names"),
        (format!("{HEADER},qw,qx,qy,qz\n{ROW},0,0,0,0\n"), &plain, "bad.csv:2:qw", "norm 0.000000"),
        (format!("{HEADER}\n{ROW},4\n"), &plain, "bad.csv:2", "row has 15 fields but the header has 14"),
        (format!("{HEADER}\n{ROW}\n").replace(',', ";"), &plain, "bad.csv:1", "separated by semicolons, not commas"),
        (format!("{HEADER}\n{ROW}\n").replace(',', "\t"), &plain, "bad.csv:1", "separated by tabs, not commas"),
        (String::new(), &plain, "bad.csv", "the file is empty"),
        (
            "# only a comment\n\n".into(),
            &plain,
            "bad.csv",
            "the file has no header row, only comment (`#`) and blank lines; it needs a header row (tool, joint names, observation columns)",
        ),
        (format!("# made today\n{HEADER}\n"), &plain, "bad.csv", "no data rows"),
        (
            format!("# units: m\n{HEADER}\n"),
            &plain,
            "bad.csv:1",
            "'m' in the units comment is not key=value",
        ),
    ];
    for (text, options, place, expected) in cases {
        let message = error(&text, options, place);
        assert!(
            message.contains(expected),
            "expected '{expected}' in: {message}"
        );
    }
    // The tools scan (the first read of `calibrate`) says what a measurement file needs too.
    let message = treecal::io::measured_tool_names("# only a comment\n", "bad.csv")
        .unwrap_err()
        .to_string();
    assert!(message.contains("observation columns"), "{message}");
}

#[test]
fn collinear_and_coincident_targets_are_errors() {
    let header = "id,tool,torso_joint1,torso_joint2,left_joint1,left_joint2,left_joint3,left_joint4,left_joint5,left_joint6,ax,ay,az,bx,by,bz,cx,cy,cz";
    let joints = "left_tool,0,0,0,0,0,0,0,0";
    let good = format!("{header}\nA7,{joints},0,0,0,100,0,0,0,100,0\n");
    let mm = MeasurementReadOptions {
        length_unit: Some(LengthUnit::Millimetre),
        ..Default::default()
    };
    let set = parse(&good, &mm).unwrap();
    assert_eq!(set.ids, ["A7"]);
    let cases = [
        // C on the line AB.
        ("0,0,0,100,0,0,250,0,0", "collinear"),
        // C 0.4° off the line AB.
        ("0,0,0,100,0,0,100,0.7,0", "collinear"),
        // C on the far side of A, on the line.
        ("0,0,0,100,0,0,-50,0,0", "collinear"),
        // B within 1 mm of A.
        (
            "0,0,0,0.5,0,0,0,100,0",
            "targets A and B are 0.500 mm apart",
        ),
        ("10,10,10,10,10,10,10,10,10", "coincident"),
    ];
    for (targets, expected) in cases {
        let text = format!("{header}\n# comment\nA7,{joints},{targets}\n");
        let message = match parse(&text, &mm) {
            Ok(_) => panic!("{targets} should be rejected"),
            Err(e) => e.to_string(),
        };
        assert!(
            message.starts_with("bad.csv:3:ax..cz: collinear or coincident targets"),
            "{message}"
        );
        assert!(
            message.contains(expected),
            "expected '{expected}' in: {message}"
        );
    }
    // 0.6° off the line is accepted.
    let text = format!("{header}\nA7,{joints},0,0,0,100,0,0,100,1.05,0\n");
    assert!(parse(&text, &mm).is_ok());
}

#[test]
fn limits_warn_unless_strict() {
    let text = with_cell("left_joint3", "-170.5");
    let degrees = MeasurementReadOptions {
        angle_unit: Some(AngleUnit::Degree),
        ..Default::default()
    };
    let set = parse(&text, &degrees).unwrap();
    assert_eq!(set.warnings.len(), 1, "{:?}", set.warnings);
    assert_eq!(
        set.warnings[0],
        "bad.csv:3:left_joint3: -170.5 deg is outside the limits of joint 'left_joint3' [-170, 170] deg"
    );
    let strict = MeasurementReadOptions {
        strict_limits: true,
        ..degrees.clone()
    };
    let message = error(&text, &strict, "bad.csv:3:left_joint3");
    assert!(
        message.contains("-170.5 deg is outside the limits"),
        "{message}"
    );
    // Within the limits (and at a limit, within 1e-9 rad) nothing is said.
    let inside = with_cell("left_joint3", "-170");
    assert!(parse(&inside, &strict).unwrap().warnings.is_empty());
    let at_limit = with_cell("left_joint3", "-2.9670597283903606");
    assert!(parse(&at_limit, &strict).unwrap().warnings.is_empty());
}

#[test]
fn continuous_joints_have_no_limits() {
    let (tree, model) = robot_model("dual_arm_prismatic/dual_arm_prismatic.urdf");
    let text =
        "tool,torso_lift,torso_yaw,right_j1,right_j2,right_j3,right_j4,right_j5,right_j6,x,y,z\n\
                right_tool,0.1,0,0,0,0,0,0,40,1,2,3\n";
    let options = MeasurementReadOptions {
        strict_limits: true,
        ..Default::default()
    };
    let set = parse_measurements(text, "c.csv", &tree, &model, &options).unwrap();
    assert!(set.warnings.is_empty());
    // The prismatic lift is limited to [0, 0.4] m, i.e. [0, 400] mm.
    let text = text.replace("0.1,", "500,");
    let options = MeasurementReadOptions {
        length_unit: Some(LengthUnit::Millimetre),
        ..Default::default()
    };
    let set = parse_measurements(&text, "c.csv", &tree, &model, &options).unwrap();
    assert_eq!(
        set.warnings,
        ["c.csv:2:torso_lift: 500 mm is outside the limits of joint 'torso_lift' [0, 400] mm"]
    );
}

#[test]
fn joints_off_the_tool_chain_may_be_missing_or_empty() {
    let (tree, model) = robonaut_model();
    // Right-arm columns present but empty for a left-tool row; absent entirely in another file.
    let header = format!("{HEADER},right_joint1");
    let text = format!("{header}\n{ROW},\n2,,right_tool,0,0,0,0,0,0,0,0,1,2,3,0.5\n");
    let message = error(&text, &Default::default(), "bad.csv:3:right_joint2");
    assert!(
        message.contains("has no column 'right_joint2'"),
        "{message}"
    );
    let set = parse(&format!("{header}\n{ROW},\n"), &Default::default()).unwrap();
    let right = tree
        .dof_of(tree.joint_id("right_joint1").unwrap())
        .unwrap()
        .0;
    assert_eq!(set.measurements[0].q[right], 0.0);
    assert_eq!(set.measurements[0].stage.as_deref(), Some("arms"));
    assert_eq!(
        set.measurements[0].tool,
        model
            .tool_of_link(tree.link_id("left_tool").unwrap())
            .unwrap()
    );
    let left6 = tree
        .dof_of(tree.joint_id("left_joint6").unwrap())
        .unwrap()
        .0;
    assert_eq!(set.measurements[0].q[left6], 0.8);
}

#[test]
fn mimic_joint_columns_name_their_master() {
    let (tree, model) = robot_model("humanoid/humanoid.urdf");
    let tools: Vec<&str> = model
        .tools()
        .iter()
        .map(|t| tree.link(t.link).name.as_str())
        .collect();
    // A mimic column (a joint-state dump has them) is not read, and the note says why; what is
    // left is the missing chain joints.
    let text = format!("tool,l_finger_right,x,y,z\n{},0.1,1,2,3\n", tools[0]);
    let message = parse_measurements(&text, "h.csv", &tree, &model, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        message.starts_with("h.csv:2:") && message.contains("has no column"),
        "{message}"
    );
    let one = Measurement {
        tool: 0,
        q: tree.zero_configuration(),
        observation: Observation::Position(Vec3::new(1.0, 2.0, 3.0)),
        stage: None,
        payload: None,
        session: None,
    };
    let mut full = measurements_to_csv(&tree, &model, &[one]).unwrap();
    full = full.replacen(",x,", ",l_finger_right,x,", 1);
    let mut lines: Vec<String> = full.lines().map(str::to_owned).collect();
    let at = lines[0]
        .split(',')
        .position(|c| c == "l_finger_right")
        .unwrap();
    let mut fields: Vec<&str> = lines[1].split(',').collect();
    fields.insert(at, "0.1");
    lines[1] = fields.join(",");
    let set = parse_measurements(
        &lines.join("\n"),
        "h.csv",
        &tree,
        &model,
        &Default::default(),
    )
    .unwrap();
    assert_eq!(set.notes.len(), 1, "{:?}", set.notes);
    assert!(
        set.notes[0]
            .contains("'l_finger_right' (a mimic joint: its value follows 'l_finger_left')"),
        "{:?}",
        set.notes
    );
}

/// Columns that are neither joints nor measurement columns are not read, with ONE note listing
/// them (a misspelled joint with its likely name, a fixed joint); `--ignore-columns` silences
/// the note for the columns it lists; clean files get no note.
#[test]
fn ignored_columns_are_skipped_and_others_are_errors() {
    let text = format!("timestamp,{HEADER},tracker_rms\n12:00:01,{ROW},0.01\n");
    let set = parse(&text, &Default::default()).unwrap();
    assert_eq!(set.measurements.len(), 1);
    assert_eq!(
        set.notes,
        ["bad.csv:1: 2 column(s) neither a joint of 'robonaut' nor a measurement column, not read: 'timestamp', 'tracker_rms'; list them with `ignore_columns` to silence this note"]
    );
    let only_one = MeasurementReadOptions {
        ignore_columns: vec!["timestamp".into()],
        ..Default::default()
    };
    let set = parse(&text, &only_one).unwrap();
    assert!(
        set.notes[0].contains("not read: 'tracker_rms';"),
        "{:?}",
        set.notes
    );
    let both = MeasurementReadOptions {
        ignore_columns: vec!["timestamp".into(), "tracker_rms".into(), "absent".into()],
        ..Default::default()
    };
    let set = parse(&text, &both).unwrap();
    assert_eq!(set.measurements.len(), 1);
    assert!(set.notes.is_empty());
    assert_eq!(
        set.warnings,
        ["bad.csv: column 'absent' is to be ignored but the file has no such column"]
    );
    // A non-numeric value in an ignored column is not read.
    let set = parse(&text.replace("0.01", "n/a"), &both).unwrap();
    assert_eq!(set.measurements.len(), 1);
    let misspelled = parse(
        &format!("{HEADER},left_jiont2\n{ROW},0\n"),
        &Default::default(),
    )
    .unwrap();
    assert!(
        misspelled.notes[0].contains("'left_jiont2'; did you mean 'left_joint2'?"),
        "{:?}",
        misspelled.notes
    );
    let fixed = parse(
        &format!("{HEADER},left_tool_joint\n{ROW},0\n"),
        &Default::default(),
    )
    .unwrap();
    assert!(
        fixed.notes[0].contains("'left_tool_joint' (a fixed joint)"),
        "{:?}",
        fixed.notes
    );
    // Misspelled in place of a needed joint: the error names the column that was not read.
    let swapped = format!("{HEADER}\n{ROW}\n").replacen("left_joint6", "left_jiont6", 1);
    let message = parse(&swapped, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("has no column 'left_joint6'")
            && message.contains("rename the file's column 'left_jiont6'"),
        "{message}"
    );
    assert!(parse(&format!("{HEADER}\n{ROW}\n"), &Default::default())
        .unwrap()
        .notes
        .is_empty());
}

#[test]
fn reading_a_file_names_it() {
    let (tree, model) = robonaut_model();
    let dir = std::env::temp_dir().join(format!("treecal-measurements-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("m.csv");
    std::fs::write(&path, with_cell("x", "oops")).unwrap();
    let message = read_measurements(&path, &tree, &model, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        message.starts_with(&format!("{}:3:x: 'oops'", path.display())),
        "{message}"
    );
    std::fs::write(&path, with_cell("x", "1.5")).unwrap();
    assert!(read_measurements(&path, &tree, &model, &Default::default()).is_ok());
    let missing = dir.join("missing.csv");
    let err = read_measurements(&missing, &tree, &model, &Default::default()).unwrap_err();
    assert!(
        matches!(err, Error::Io { .. }) && err.to_string().contains("missing.csv"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn corrupted_files_never_panic() {
    let (tree, model) = robonaut_model();
    let base = measurements_to_csv(&tree, &model, &simulated(&tree, &model, 3, true)).unwrap();
    let junk = [
        "",
        "nan",
        "-inf",
        "abc",
        "1e999",
        "\"",
        "\"a,b\"",
        "0x10",
        "--1",
        "left_tool",
        "1,2",
        "right_tool",
        "3.2",
        "#",
        " ",
        "é",
    ];
    let mut rng = rng(77);
    let (mut ok, mut err) = (0, 0);
    for _ in 0..400 {
        let mut lines: Vec<String> = base.lines().map(str::to_owned).collect();
        for _ in 0..rng.random_range(1..4) {
            let line = rng.random_range(0..lines.len());
            match rng.random_range(0..5) {
                0 => {
                    let mut cells: Vec<String> =
                        lines[line].split(',').map(str::to_owned).collect();
                    let cell = rng.random_range(0..cells.len());
                    cells[cell] = junk[rng.random_range(0..junk.len())].to_owned();
                    lines[line] = cells.join(",");
                }
                1 => {
                    lines.remove(line);
                }
                2 => {
                    let copy = lines[line].clone();
                    lines.insert(rng.random_range(0..=lines.len()), copy);
                }
                3 => {
                    let mut cut = rng.random_range(0..=lines[line].len());
                    while !lines[line].is_char_boundary(cut) {
                        cut -= 1;
                    }
                    lines[line].truncate(cut);
                }
                _ => {
                    // Leave the text unchanged: some files stay valid.
                }
            }
            if lines.is_empty() {
                break;
            }
        }
        let text = lines.join("\n");
        match parse_measurements(&text, "fuzz.csv", &tree, &model, &Default::default()) {
            Ok(set) => {
                ok += 1;
                assert_eq!(set.measurements.len(), set.lines.len());
                assert!(set
                    .measurements
                    .iter()
                    .all(|m| m.q.iter().all(|v| v.is_finite())));
            }
            Err(e) => {
                err += 1;
                let message = e.to_string();
                assert!(message.starts_with("fuzz.csv"), "{message}");
            }
        }
    }
    assert!(ok > 10 && err > 100, "{ok} accepted, {err} rejected");
}

/// Prismatic joint values logged in metres beside a tracker in millimetres:
/// `joint_length=m` in the units comment (or `--joint-length-unit m`) reads them right.
#[test]
fn prismatic_values_may_have_their_own_unit() {
    let (tree, model) = robot_model("dual_arm_prismatic/dual_arm_prismatic.urdf");
    let written = simulated(&tree, &model, 8, true);
    let write = MeasurementWriteOptions {
        length_unit: LengthUnit::Millimetre,
        angle_unit: AngleUnit::Degree,
        three_targets: false,
    };
    let text = measurements_to_csv_with(&tree, &model, &written, &write).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let header: Vec<String> = lines[1].split(',').map(str::to_owned).collect();
    let prismatic: Vec<usize> = header
        .iter()
        .enumerate()
        .filter(|(_, name)| {
            tree.joint_id(name)
                .is_ok_and(|j| tree.joint(j).kind == treecal::tree::JointKind::Prismatic)
        })
        .map(|(column, _)| column)
        .collect();
    assert!(!prismatic.is_empty());
    for line in &mut lines[2..] {
        let mut fields: Vec<String> = line.split(',').map(str::to_owned).collect();
        for &column in &prismatic {
            let mm: f64 = fields[column].parse().unwrap();
            fields[column] = format!("{}", mm / 1e3);
        }
        *line = fields.join(",");
    }
    lines[0] = "# units: length=mm angle=deg joint_length=m".into();
    let metres = lines.join("\n");
    let read = parse_measurements(&metres, "j.csv", &tree, &model, &Default::default()).unwrap();
    assert_same(&read, &written);
    assert_eq!(read.units.joint_length, LengthUnit::Metre);
    // The same through the option, with the comment silent about it.
    lines[0] = "# units: length=mm angle=deg".into();
    let flag = MeasurementReadOptions {
        joint_length_unit: Some(LengthUnit::Metre),
        ..Default::default()
    };
    let read = parse_measurements(&lines.join("\n"), "j.csv", &tree, &model, &flag).unwrap();
    assert_same(&read, &written);
}

/// Joint values in the wrong angle unit are one diagnosis naming `--angle-unit`, not a warning
/// per value; a few values outside their limits stay warnings, at most five listed.
#[test]
fn angle_unit_mistakes_are_one_diagnosis() {
    let (tree, model) = robot_model("robonaut/robonaut.urdf");
    let written = simulated(&tree, &model, 5, true);
    let degrees = MeasurementWriteOptions {
        angle_unit: AngleUnit::Degree,
        ..Default::default()
    };
    let text = measurements_to_csv_with(&tree, &model, &written, &degrees).unwrap();
    let bare = text.split_once('\n').unwrap().1;
    let error = parse_measurements(bare, "d.csv", &tree, &model, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        error.starts_with("d.csv: ") && error.contains("look like degrees; give `angle_unit` deg"),
        "{error}"
    );
    // Read with its units comment, the same file is fine and warns of nothing.
    let read = parse_measurements(&text, "d.csv", &tree, &model, &Default::default()).unwrap();
    assert!(read.warnings.is_empty(), "{:?}", read.warnings);

    let radians = measurements_to_csv(&tree, &model, &written).unwrap();
    let as_degrees = MeasurementReadOptions {
        angle_unit: Some(AngleUnit::Degree),
        ..Default::default()
    };
    let error = parse_measurements(&radians, "r.csv", &tree, &model, &as_degrees)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("look like radians; give `angle_unit` rad"),
        "{error}"
    );

    // Seven values just outside their limits: warnings, five listed and the rest counted.
    let mut lines: Vec<String> = radians.lines().map(str::to_owned).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let column = header.iter().position(|h| *h == "left_joint2").unwrap();
    let joint = tree.joint(tree.joint_id("left_joint2").unwrap());
    let upper = joint.limits.unwrap().upper;
    let rows = lines.len();
    for line in &mut lines[1..rows.min(8)] {
        let mut fields: Vec<String> = line.split(',').map(str::to_owned).collect();
        fields[column] = format!("{}", upper + 0.01);
        *line = fields.join(",");
    }
    let read = parse_measurements(
        &lines.join("\n"),
        "l.csv",
        &tree,
        &model,
        &Default::default(),
    )
    .unwrap();
    assert_eq!(read.warnings.len(), 6, "{:?}", read.warnings);
    assert!(
        read.warnings[5].contains("2 more joint values"),
        "{:?}",
        read.warnings
    );
}
