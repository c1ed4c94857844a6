//! Mocap-native measurements (docs/file-formats.md, section 4): several points on one body
//! without editing the URDF (marker links added at load time and written by the export), and
//! the three orientation encodings, on simulated truth.

use crate::common::*;
use rand::RngExt;
use std::fmt::Write;
use std::path::Path;
use treecal::math::{rpy_from_rotation, Pose};
use treecal::measurement::Observation;
use treecal::workflow::{
    calibrate, export, CalibrateConfig, ExportConfig, MeasurementFrameChoice, MeasurementSource,
    RobotSource,
};
use treecal::{parse_urdf, KinematicTree, McpcModel};

/// The body the points are on: it carries `left_tool`, which must stay where it is.
const BODY: &str = "left_link6";
/// The points' true places on [`BODY`] (m).
const POINTS: [(&str, [f64; 3]); 3] = [
    ("P1", [0.03, 0.01, 0.12]),
    ("P2", [-0.04, 0.05, 0.10]),
    ("P3", [0.02, -0.06, 0.15]),
];

fn robonaut_text() -> String {
    std::fs::read_to_string(robot("robonaut/robonaut.urdf")).unwrap()
}

/// The true robot: the Robonaut with the points as links on [`BODY`] and every MCPC joint
/// parameter perturbed by a seeded ±3 mm / ±3 mrad; its tools are the points.
fn truth() -> (KinematicTree, McpcModel) {
    let mut text = robonaut_text();
    let mut links = String::new();
    for (name, [x, y, z]) in POINTS {
        let _ = write!(
            links,
            "  <link name=\"{BODY}_{name}\"/>\n  <joint name=\"{BODY}_{name}_joint\" type=\"fixed\">\n    <parent link=\"{BODY}\"/>\n    <child link=\"{BODY}_{name}\"/>\n    <origin xyz=\"{x} {y} {z}\" rpy=\"0 0 0\"/>\n  </joint>\n"
        );
    }
    let end = text.rfind("</robot>").unwrap();
    text.insert_str(end, &links);
    let tree = parse_urdf(&text, "truth").unwrap().tree;
    let names: Vec<String> = POINTS.iter().map(|(n, _)| format!("{BODY}_{n}")).collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let branches = branches_with_tools(&tree, Some(&names));
    let mut model = McpcModel::from_tree(&tree, &branches).unwrap();
    let mut values = model.parameters();
    let mut random = rng(0x28_10);
    let tools_start = model.tool_parameter_offset(0);
    for value in &mut values[..tools_start] {
        *value += random.random_range(-0.003..0.003);
    }
    model.set_parameters(&values).unwrap();
    (tree, model)
}

/// Noise-free positions of every point at `count` random configurations, as a CSV with a
/// `tool` and a `point` column, in the root frame (m, rad), with one extra column a tracker
/// writes.
fn points_csv(tree: &KinematicTree, model: &McpcModel, count: usize) -> String {
    let joints: Vec<&str> = tree
        .dofs()
        .iter()
        .map(|j| tree.joint(*j).name.as_str())
        .collect();
    let mut text = format!("id,tool,point,{},x,y,z,residual_mm\n", joints.join(","));
    let mut random = rng(0x28_11);
    for row in 0..count {
        let q = random_configuration(tree, &mut random);
        for (t, pose) in model.tool_poses(&q).iter().enumerate() {
            let p = pose.translation.vector;
            let values: Vec<String> = q.iter().map(|v| v.to_string()).collect();
            let _ = writeln!(
                text,
                "{row}-{t},{BODY},{},{},{},{},{},0.1",
                POINTS[t].0,
                values.join(","),
                p.x,
                p.y,
                p.z
            );
        }
    }
    text
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Three points on a body that carries another link, measured against the plain URDF: the
/// points become marker links (named in a note), the calibration finds the true positions of
/// every point at new configurations, the exported URDF has the point links where the truth has
/// them, the link below the body keeps its nominal offset, the extra column is one note, and
/// `treecal export` from params.yaml with the plain URDF gives the same file.
#[test]
fn several_points_on_one_body_calibrate_to_truth_and_export_as_links() {
    let (truth_tree, truth_model) = truth();
    let dir = tempfile::tempdir().unwrap();
    let csv = write(
        dir.path(),
        "points.csv",
        &points_csv(&truth_tree, &truth_model, 40),
    );
    let urdf = write(dir.path(), "robonaut.urdf", &robonaut_text());
    let config = CalibrateConfig {
        robot: RobotSource::File(urdf.clone()),
        measurements: MeasurementSource::Csv(csv),
        measurement_frame: MeasurementFrameChoice::Base,
        ..CalibrateConfig::default()
    };
    let result = calibrate(&config).unwrap();
    assert!(result.usable(), "{:?}", result.verdict);
    let notes: Vec<String> = result.notes.iter().map(|n| n.to_string()).collect();
    let named = notes
        .iter()
        .filter(|n| n.contains("measured point(s)"))
        .count();
    assert_eq!(named, 1, "{notes:#?}");
    assert!(
        notes
            .iter()
            .any(|n| n.contains("'left_link6_P1' on 'left_link6'")),
        "{notes:#?}"
    );
    let extra: Vec<&String> = notes.iter().filter(|n| n.contains("residual_mm")).collect();
    assert_eq!(extra.len(), 1, "{notes:#?}");

    let exported_text = result.urdf.clone().unwrap();
    let exported = parse_urdf(&exported_text, "calibrated").unwrap().tree;
    let nominal = parse_urdf(&robonaut_text(), "nominal").unwrap().tree;
    assert_eq!(exported.links().len(), nominal.links().len() + POINTS.len());
    let mut random = rng(0x28_12);
    let mut worst = 0.0f64;
    for _ in 0..20 {
        let q = random_configuration(&nominal, &mut random);
        let truth_poses = truth_model.tool_poses(&q);
        let poses = exported.link_poses(&q).unwrap();
        for (t, (name, _)) in POINTS.iter().enumerate() {
            let link = format!("{BODY}_{name}");
            let got = poses[exported.link_id(&link).unwrap().0].translation.vector;
            worst = worst.max((got - truth_poses[t].translation.vector).norm());
        }
    }
    assert!(worst < 1e-6, "points off the truth by {worst} m");
    let tool_joint = |tree: &KinematicTree| {
        let link = tree.link(tree.link_id("left_tool").unwrap());
        tree.joint(link.parent_joint.unwrap()).parent_from_joint
    };
    assert_eq!(tool_joint(&exported), tool_joint(&nominal));

    let out = dir.path().join("out");
    result.write(&out).unwrap();
    let params = std::fs::read_to_string(out.join("params.yaml")).unwrap();
    assert!(
        params.contains("added_links:") && params.contains("reason: point"),
        "{params}"
    );
    let again = export(&ExportConfig {
        robot: RobotSource::File(urdf),
        parameters: out.join("params.yaml"),
        ..ExportConfig::default()
    })
    .unwrap();
    assert_eq!(again.urdf(), exported_text);
}

/// Clean point data with no extra column: no note beyond the points, no warning.
#[test]
fn clean_point_data_raise_no_alarm() {
    let (truth_tree, truth_model) = truth();
    let dir = tempfile::tempdir().unwrap();
    let text = points_csv(&truth_tree, &truth_model, 30)
        .replace(",residual_mm", "")
        .replace(",0.1\n", "\n");
    let csv = write(dir.path(), "points.csv", &text);
    let config = CalibrateConfig {
        measurements: MeasurementSource::Csv(csv),
        measurement_frame: MeasurementFrameChoice::Base,
        ..CalibrateConfig::default()
    };
    let result = calibrate(&config).unwrap();
    assert!(result.usable(), "{:?}", result.verdict);
    let warnings: Vec<String> = result
        .notes
        .iter()
        .filter(|n| n.level == treecal::workflow::NoteLevel::Warning)
        .map(|n| n.to_string())
        .collect();
    assert!(warnings.is_empty(), "{warnings:#?}");
}

/// The rows of a pose CSV (quaternion, m, rad) rewritten with the orientation as a rotation
/// matrix, or as roll-pitch-yaw in degrees (`rotation=deg`), or as a quaternion written x, y, z,
/// w: every encoding reads back to the same poses and calibrates to the same parameters.
#[test]
fn every_orientation_encoding_reads_and_calibrates_the_same() {
    let (tree, mut model) = robonaut();
    let mut values = model.parameters();
    let mut random = rng(0x28_13);
    for value in &mut values {
        *value += random.random_range(-0.002..0.002);
    }
    model.set_parameters(&values).unwrap();
    let header_joints: Vec<&str> = tree
        .dofs()
        .iter()
        .map(|j| tree.joint(*j).name.as_str())
        .collect();
    let mut rows: Vec<(String, Vec<f64>, Pose)> = Vec::new();
    for row in 0..30 {
        let q = random_configuration(&tree, &mut random);
        for (t, pose) in model.tool_poses(&q).iter().enumerate() {
            let tool = tree.link(model.tools()[t].link).name.clone();
            rows.push((format!("{row}-{tool}"), q.clone(), *pose));
            let _ = t;
        }
    }
    let file = |header: &str, orientation: &dyn Fn(&Pose) -> Vec<f64>, units: &str| {
        let mut text = format!(
            "{units}id,tool,{},x,y,z,{header}\n",
            header_joints.join(",")
        );
        for (id, q, pose) in &rows {
            let tool = id.split_once('-').unwrap().1;
            let p = pose.translation.vector;
            let mut cells: Vec<String> = q.iter().map(|v| v.to_string()).collect();
            cells.extend([p.x, p.y, p.z].iter().map(|v| v.to_string()));
            cells.extend(orientation(pose).iter().map(|v| v.to_string()));
            let _ = writeln!(text, "{id},{tool},{}", cells.join(","));
        }
        text
    };
    let quaternion = file(
        "qw,qx,qy,qz",
        &|p| {
            let q = p.rotation.quaternion();
            vec![q.w, q.i, q.j, q.k]
        },
        "",
    );
    let xyzw = file(
        "qx,qy,qz,qw",
        &|p| {
            let q = p.rotation.quaternion();
            vec![q.i, q.j, q.k, q.w]
        },
        "",
    );
    let matrix = file(
        "r11,r12,r13,r21,r22,r23,r31,r32,r33",
        &|p| {
            let m = p.rotation.to_rotation_matrix();
            let m = m.matrix();
            (0..3)
                .flat_map(|r| (0..3).map(move |c| m[(r, c)]))
                .collect()
        },
        "",
    );
    let rpy = file(
        "roll,pitch,yaw",
        &|p| rpy_from_rotation(&p.rotation).map(f64::to_degrees).to_vec(),
        "# units: rotation=deg\n",
    );
    let read = |text: &str| {
        treecal::io::parse_measurements(text, "m.csv", &tree, &model, &Default::default()).unwrap()
    };
    let reference = read(&quaternion);
    for (what, text) in [("xyzw", &xyzw), ("matrix", &matrix), ("rpy", &rpy)] {
        let set = read(text);
        assert_eq!(set.measurements.len(), reference.measurements.len());
        for (a, b) in set.measurements.iter().zip(&reference.measurements) {
            let (Observation::Pose(a), Observation::Pose(b)) = (&a.observation, &b.observation)
            else {
                panic!("{what}: not a pose");
            };
            let (position, angle) = pose_difference(a, b);
            assert!(
                position < 1e-12 && angle < 1e-9,
                "{what}: {position} {angle}"
            );
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let calibrated = |name: &str, text: &str| {
        let config = CalibrateConfig {
            measurements: MeasurementSource::Csv(write(dir.path(), name, text)),
            measurement_frame: MeasurementFrameChoice::Base,
            ..CalibrateConfig::default()
        };
        calibrate(&config).unwrap().parameters
    };
    let from_quaternion = calibrated("q.csv", &quaternion);
    let from_rpy = calibrated("rpy.csv", &rpy);
    for (a, b) in from_quaternion.iter().zip(&from_rpy) {
        assert!(
            (a.calibrated - b.calibrated).abs() < 1e-8,
            "{}: {} vs {}",
            a.name,
            a.calibrated,
            b.calibrated
        );
    }
    // Close to the truth: these are noise-free poses.
    for (estimate, truth) in from_quaternion.iter().zip(model.parameters()) {
        assert!(
            (estimate.calibrated - truth).abs() < 1e-6,
            "{}",
            estimate.name
        );
    }
}

/// A matrix that is not a rotation is an error naming file, line and columns.
#[test]
fn a_rotation_matrix_that_is_not_one_is_named() {
    let (tree, model) = robonaut();
    let joints: Vec<&str> = tree
        .dofs()
        .iter()
        .map(|j| tree.joint(*j).name.as_str())
        .collect();
    let zeros = vec!["0"; joints.len()].join(",");
    let text = format!(
        "tool,{},x,y,z,r11,r12,r13,r21,r22,r23,r31,r32,r33\nleft_tool,{zeros},1,2,3,1,0,0,0,1,0,0,0,1\nleft_tool,{zeros},1,2,3,2,0,0,0,1,0,0,0,1\n",
        joints.join(",")
    );
    let error = treecal::io::parse_measurements(&text, "m.csv", &tree, &model, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        error.starts_with("m.csv:3:r11..r33: r11..r33 is not a rotation matrix"),
        "{error}"
    );
}

fn robonaut() -> (KinematicTree, McpcModel) {
    let tree = parse_urdf(&robonaut_text(), "robonaut").unwrap().tree;
    let branches = branches_with_tools(&tree, None);
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    (tree, model)
}

/// The CSV of [`points_csv`] as arrays (Python's `treecal.Measurements`): `points` and
/// `sessions` columns carried by the table.
fn points_table(text: &str, sessions: bool) -> treecal::io::MeasurementTable {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let joints = header.len() - 7;
    let (mut ids, mut tools, mut points, mut values, mut positions, mut labels) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        ids.push(cells[0].to_owned());
        tools.push(cells[1].to_owned());
        points.push(cells[2].to_owned());
        let number = |c: &str| c.parse::<f64>().unwrap();
        values.push(cells[3..3 + joints].iter().map(|c| number(c)).collect());
        let p: Vec<f64> = cells[3 + joints..6 + joints]
            .iter()
            .map(|c| number(c))
            .collect();
        positions.push([p[0], p[1], p[2]]);
        let posture: usize = cells[0].split('-').next().unwrap().parse().unwrap();
        labels.push(if posture % 2 == 0 { "even" } else { "odd" }.to_owned());
    }
    treecal::io::MeasurementTable {
        origin: "points (arrays)".into(),
        ids: Some(ids),
        tools,
        joint_names: header[3..3 + joints]
            .iter()
            .map(|s| s.to_string())
            .collect(),
        joints: values,
        observations: treecal::io::ObservationRows::Positions(positions),
        stages: None,
        sessions: sessions.then_some(labels),
        points: Some(points),
        length_unit: None,
        angle_unit: None,
    }
}

/// Arrays with a `points` column calibrate exactly as the CSV with a `point` column (marker
/// links added alike); with `sessions`, one measurement frame per session is fitted.
#[test]
fn a_table_carries_points_and_sessions_like_a_csv() {
    let (truth_tree, truth_model) = truth();
    let dir = tempfile::tempdir().unwrap();
    let text = points_csv(&truth_tree, &truth_model, 30);
    let csv = write(dir.path(), "points.csv", &text);
    let urdf = write(dir.path(), "robonaut.urdf", &robonaut_text());
    let config = |measurements| CalibrateConfig {
        robot: RobotSource::File(urdf.clone()),
        measurements,
        measurement_frame: MeasurementFrameChoice::Base,
        ..CalibrateConfig::default()
    };
    let from_csv = calibrate(&config(MeasurementSource::Csv(csv))).unwrap();
    let table = MeasurementSource::Table(points_table(&text, false));
    let from_table = calibrate(&config(table)).unwrap();
    assert!(from_table.usable(), "{:?}", from_table.verdict);
    assert_eq!(from_csv.parameters.len(), from_table.parameters.len());
    for (a, b) in from_csv.parameters.iter().zip(&from_table.parameters) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.calibrated.to_bits(), b.calibrated.to_bits(), "{}", a.name);
    }
    assert_eq!(from_csv.urdf, from_table.urdf);
    let sessions = MeasurementSource::Table(points_table(&text, true));
    let with_sessions = calibrate(&config(sessions)).unwrap();
    assert!(with_sessions.usable(), "{:?}", with_sessions.verdict);
    let report = with_sessions.report();
    let training = report["sessions"]["training"]
        .as_array()
        .unwrap_or_else(|| panic!("{}", report["sessions"]));
    assert_eq!(training.len(), 2);
}
