//! The simulated second robot of issue 28 end to end through the CLI, as a lab would run it:
//! 6-DoF body poses (roll-pitch-yaw in degrees, millimetres) and two position-only sessions in
//! one training file, a held-out validation file with quaternions in x-y-z-w order, the body
//! 138 mm beyond a tool link with children, series-elastic joints and one 57 mm blunder
//! (`common::second_robot`). Run with default flags and with `--model auto`, with and without
//! the stiffness file.

use crate::common::cli::{assert_success, path_str, treecal, Run};
use crate::common::second_robot::{second_robot, SecondRobot, BLUNDER, TOOL};
use std::path::{Path, PathBuf};
use treecal::measurement::Observation;

/// The joint columns of the arm (the URDF's dof names).
fn joint_names(robot: &SecondRobot) -> Vec<String> {
    robot
        .tree
        .dofs()
        .iter()
        .map(|&j| robot.tree.joint(j).name.clone())
        .collect()
}

/// The training file: `id,session,<joints>,x,y,z,roll,pitch,yaw,residual` in mm and degrees
/// (a Qualisys export's extra `residual` column, not read); position-only rows leave the
/// orientation empty.
fn write_training(robot: &SecondRobot, rows: &[usize], path: &Path) {
    let joints = joint_names(robot);
    let mut text = String::from("# units: length=mm angle=rad rotation=deg\n");
    text.push_str(&format!(
        "id,session,{},x,y,z,roll,pitch,yaw,residual\n",
        joints.join(",")
    ));
    for &i in rows {
        let m = &robot.measurements[i];
        let q: Vec<String> = m.q.iter().map(|v| format!("{v:.6}")).collect();
        let (p, rpy) = match &m.observation {
            Observation::Pose(pose) => {
                let (r, p, y) = pose.rotation.euler_angles();
                (
                    pose.translation.vector,
                    format!(
                        "{:.5},{:.5},{:.5}",
                        r.to_degrees(),
                        p.to_degrees(),
                        y.to_degrees()
                    ),
                )
            }
            Observation::Position(p) => (*p, ",,".to_string()),
            Observation::Contact(_) => unreachable!("the second robot is measured by mocap"),
        };
        text.push_str(&format!(
            "{},{},{},{:.4},{:.4},{:.4},{rpy},0.3\n",
            robot.ids[i],
            m.session.as_deref().unwrap_or(""),
            q.join(","),
            p.x * 1e3,
            p.y * 1e3,
            p.z * 1e3
        ));
    }
    std::fs::write(path, text).unwrap();
}

/// The validation file: `id,session,<joints>,x,y,z,qx,qy,qz,qw` in metres (quaternion x-y-z-w,
/// as ROS prints it).
fn write_validation(robot: &SecondRobot, rows: &[usize], path: &Path) {
    let joints = joint_names(robot);
    let mut text = format!("id,session,{},x,y,z,qx,qy,qz,qw\n", joints.join(","));
    for &i in rows {
        let m = &robot.measurements[i];
        let Observation::Pose(pose) = &m.observation else {
            panic!("validation rows are poses");
        };
        let q: Vec<String> = m.q.iter().map(|v| format!("{v:.6}")).collect();
        let (t, r) = (pose.translation.vector, pose.rotation);
        text.push_str(&format!(
            "{},{},{},{:.7},{:.7},{:.7},{:.9},{:.9},{:.9},{:.9}\n",
            robot.ids[i],
            m.session.as_deref().unwrap_or(""),
            q.join(","),
            t.x,
            t.y,
            t.z,
            r.i,
            r.j,
            r.k,
            r.w
        ));
    }
    std::fs::write(path, text).unwrap();
}

/// The lab's files for the 36/12 split of `seed`: (training, validation).
fn lab_files(robot: &SecondRobot, seed: u64, dir: &Path) -> (PathBuf, PathBuf) {
    let (kept, held) = robot.split(seed);
    let (training, validation) = (dir.join("training.csv"), dir.join("validation.csv"));
    write_training(robot, &kept, &training);
    write_validation(robot, &held, &validation);
    (training, validation)
}

/// `treecal calibrate` on the lab's files with `extra` flags; the run and report.json.
fn calibrate(
    robot: &SecondRobot,
    files: &(PathBuf, PathBuf),
    out: &Path,
    extra: &[&str],
) -> (Run, serde_json::Value) {
    let urdf = robot.urdf.to_str().unwrap();
    let mut args = vec![
        "calibrate",
        "--robot",
        urdf,
        "--measurements",
        path_str(&files.0),
        "--validation",
        path_str(&files.1),
        "--tools",
        TOOL,
        "--out",
        path_str(out),
    ];
    args.extend_from_slice(extra);
    let run = treecal(&args);
    let report = crate::common::cli::report_json_or_null(out);
    (run, report)
}

/// The joint origins (parent_from_joint) of the links below the tool link, by joint name.
fn below_tool(urdf: &Path) -> Vec<(String, treecal::math::Pose)> {
    let tree = treecal::load_urdf(urdf).unwrap().tree;
    [
        "gripper_base_joint",
        "gripper_left_finger_joint",
        "gripper_right_finger_joint",
    ]
    .iter()
    .map(|name| {
        let joint = tree.joint(tree.joint_id(name).unwrap());
        (name.to_string(), joint.parent_from_joint)
    })
    .collect()
}

/// What every run on the second robot's data must show, with or without a stiffness file:
/// the mixed file read (poses and positions), the blunder named on stderr and in report.json
/// with its weight and size, the marker link added and the tool link's children unmoved, the
/// three sessions with their moved frames and both validation figures, and the exported URDF
/// (as written, with its registration) no worse than the registered nominal robot.
fn check_common(robot: &SecondRobot, run: &Run, report: &serde_json::Value, out: &Path) {
    let said = &run.stderr;
    assert!(
        said.contains("28 row(s) have empty roll,pitch,yaw and are read as positions"),
        "{said}"
    );
    assert!(said.contains("not read: 'residual'"), "{said}");
    // The blunder: named with its weight and size on one stderr line and in report.json.
    let blunder = &robot.ids[robot.blunder];
    let line = said
        .lines()
        .find(|l| l.contains("are outliers by the robust"))
        .unwrap_or_else(|| panic!("no outlier warning\n{said}"));
    assert!(
        line.contains(&format!("rows: {blunder} (weight 0.")),
        "{line}"
    );
    let named = report["outliers"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| o["id"] == blunder.as_str())
        .unwrap_or_else(|| panic!("{}", report["outliers"]));
    let size = named["residual_mm"].as_f64().unwrap();
    assert!((size - BLUNDER * 1e3).abs() < 8.0, "{named}");
    assert!(named["weight"].as_f64().unwrap() < 0.5, "{named}");
    // The marker link, and the tool link's children where the URDF had them.
    assert!(
        said.contains("added link 'arm_tool_link_marker' below tool 'arm_tool_link'"),
        "{said}"
    );
    let urdf = out.join("calibrated.urdf");
    let text = std::fs::read_to_string(&urdf).unwrap();
    assert!(
        text.contains("<link name=\"arm_tool_link_marker\""),
        "{text}"
    );
    for ((name, nominal), (_, exported)) in below_tool(&robot.urdf).iter().zip(below_tool(&urdf)) {
        let moved = (nominal.translation.vector - exported.translation.vector).norm();
        let turned = nominal.rotation.angle_to(&exported.rotation);
        assert!(moved < 1e-9 && turned < 1e-9, "{name} moved {moved} m");
    }
    let tree = treecal::load_urdf(&urdf).unwrap().tree;
    let marker = tree.joint(tree.joint_id("arm_tool_link_marker_joint").unwrap());
    let offset = marker.parent_from_joint.translation.vector.norm();
    assert!((offset - 0.1386).abs() < 0.004, "marker {offset} m");
    // Sessions: three frames, the later days moved by millimetres; both validation figures.
    let sessions = &report["sessions"];
    let training = sessions["training"].as_array().unwrap();
    assert_eq!(training.len(), 3, "{sessions}");
    for day in &training[1..] {
        let moved = day["rows_moved_mm"].as_f64().unwrap();
        assert!((5.0..16.0).contains(&moved), "{day}");
    }
    let validation = &sessions["validation"][0];
    assert_eq!(validation["training_frame"], "training", "{sessions}");
    assert!(
        validation["reregistered_rms_mm"].as_f64().is_some(),
        "{sessions}"
    );
    // The exported URDF as written, scored on every validation row.
    let artifact = &report["artifact"];
    let alone = artifact["urdf_alone"]["errors"]["rms_position_mm"]
        .as_f64()
        .unwrap();
    let nominal = artifact["registered_nominal"]["errors"]["rms_position_mm"]
        .as_f64()
        .unwrap();
    assert_eq!(artifact["urdf_alone"]["observations"], 12, "{artifact}");
    assert!(
        alone < nominal,
        "URDF alone {alone} mm, nominal {nominal} mm"
    );
    assert_ne!(report["verdict"]["status"], "failed", "{said}");
    // With compensation, what is written predicts what was validated in memory: the tool
    // link has children, so its weight (and theirs) stays on the arm in both (the marker link
    // takes the measured frame, not the masses).
    if let Some(written) = artifact["with_compensation"]["errors"]["rms_position_mm"].as_f64() {
        let in_memory = report["validation"][0]["after"]["rms_position_mm"]
            .as_f64()
            .unwrap();
        assert!(
            (written - in_memory).abs() < 1e-3 * in_memory,
            "as written {written} mm, validated {in_memory} mm"
        );
    }
}

/// Default flags and `--model auto`, no stiffness file, series-elastic joints. The geometry
/// fit shows model error (σ̂ ≈ 24), so the default lets cross-validation choose as `auto`
/// does: with the 57 mm blunder left out of the choice (its held-out error would be ~7 mm of
/// every candidate's RMS), the geometry with identified joint stiffness wins; the export is
/// the rigid-only URDF (5–8 mm) plus calibrated_compensated.urdf and stiffness.yaml (2.1 mm,
/// the same as validated in memory), and the note on the choice names the model error.
#[test]
fn the_second_robot_with_default_flags_and_model_auto() {
    let robot = second_robot(2028);
    let dir = tempfile::tempdir().unwrap();
    let files = lab_files(&robot, 7, dir.path());
    let (kept, _) = robot.split(7);
    assert!(
        kept.contains(&robot.blunder),
        "the blunder is in the training rows"
    );
    let mut chosen = Vec::new();
    for (name, extra) in [("default", vec![]), ("auto", vec!["--model", "auto"])] {
        let out = dir.path().join(name);
        let (run, report) = calibrate(&robot, &files, &out, &extra);
        assert_success(&run, name);
        check_common(&robot, &run, &report, &out);
        let said = &run.stderr;
        // Under default flags the geometry fit's model error is named (σ̂ ≈ 24) as the reason
        // for the choice; the chosen model's own σ̂ (≈ 8: the mocap noise is twice the
        // declared σ) is under the warning's threshold.
        if name == "default" {
            assert!(
                said.contains(
                    "the geometry fit leaves residuals over 10× the declared noise (model error)"
                ) && said.contains("--model geometry keeps the full geometry"),
                "{said}"
            );
        }
        let cv = &report["model_choice"];
        assert!(cv["rows"].as_array().unwrap().len() >= 6, "{name}: {cv}");
        // The blunder is left out of the choice (not of the RMS column), and the data's
        // series-elastic joints make the identified stiffness the choice.
        assert_eq!(
            cv["left_out_of_choice"],
            serde_json::json!([robot.ids[robot.blunder]]),
            "{name}: {cv}"
        );
        assert_eq!(
            report["model"]["name"], "geometry+identified stiffness",
            "{name}: {cv}"
        );
        let rows = cv["rows"].as_array().unwrap();
        let names: Vec<&str> = rows.iter().map(|r| r["model"].as_str().unwrap()).collect();
        let mut unique = names.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "{names:?}");
        for row in rows {
            let (all, choice) = (
                row["rms_mm"].as_f64().unwrap(),
                row["choice_rms_mm"].as_f64().unwrap(),
            );
            assert!(
                all > choice + 1.0,
                "{name}: the blunder counts in the RMS column: {row}"
            );
        }
        let artifact = &report["artifact"];
        let number = |key: &str| artifact[key]["errors"]["rms_position_mm"].as_f64().unwrap();
        let (alone, compensated) = (number("urdf_alone"), number("with_compensation"));
        assert!((4.0..9.0).contains(&alone), "{name}: {alone} mm");
        assert!(compensated < 0.6 * alone, "{name}: {artifact}");
        assert!(
            out.join("stiffness.yaml").exists() && out.join("calibrated_compensated.urdf").exists()
        );
        eprintln!(
            "{name}: model {} URDF alone {alone:.3} mm",
            report["model"]["name"]
        );
        chosen.push(report["model"]["name"].clone());
    }
    assert_eq!(
        chosen[0], chosen[1],
        "the default under model error chooses as auto"
    );
}

/// With the stiffness file (default flags): the compensated model explains the series-elastic
/// joints; the compensated geometry alone is worse than the nominal robot, so calibrated.urdf
/// holds the rigid-only geometry, and calibrated_compensated.urdf + the file give the
/// compensated figure.
#[test]
fn the_second_robot_with_its_stiffness_file() {
    let robot = second_robot(2028);
    let dir = tempfile::tempdir().unwrap();
    let files = lab_files(&robot, 7, dir.path());
    let out = dir.path().join("stiff");
    let stiffness = robot.stiffness.to_str().unwrap().to_owned();
    let (run, report) = calibrate(&robot, &files, &out, &["--stiffness", &stiffness]);
    assert_success(&run, "--stiffness");
    check_common(&robot, &run, &report, &out);
    let artifact = &report["artifact"];
    let compensated = artifact["with_compensation"]["errors"]["rms_position_mm"]
        .as_f64()
        .unwrap();
    let alone = artifact["urdf_alone"]["errors"]["rms_position_mm"]
        .as_f64()
        .unwrap();
    assert!(compensated < 1.0, "{artifact}");
    assert!(alone > 3.0 * compensated, "{artifact}");
    assert!(out.join("calibrated_compensated.urdf").exists());
    assert!(
        run.stderr
            .contains("calibrated.urdf holds instead the rigid-only geometry"),
        "{}",
        run.stderr
    );
}

/// `treecal simulate` on the second robot's arm (rigid joints: only the joint-angle errors
/// beyond the geometry) writing its measurements, then `treecal calibrate` on them: the
/// simulate run and results.json's true joint errors.
fn simulate_arm(dir: &Path, name: &str, truth: &[&str]) -> (PathBuf, serde_json::Value) {
    let robot = crate::common::repo().join("tests/data/second_robot_arm.urdf");
    let stiffness = crate::common::repo().join("tests/data/second_robot_stiffness.yaml");
    let (out, csv) = (
        dir.join(format!("sim-{name}")),
        dir.join(format!("{name}.csv")),
    );
    let mut args = vec![
        "simulate",
        "--robot",
        path_str(&robot),
        "--stiffness",
        path_str(&stiffness),
        "--joint-stiffness",
        "1e12",
        "--tools",
        TOOL,
        "--plan",
        "simultaneous",
        "--torso-poses",
        "0",
        "--poses",
        "60",
        "--validation-poses",
        "5",
        "--angle-error",
        "0.004",
        "--length-error",
        "0.002",
        "--noise",
        "30+0",
        "--seed",
        "5",
        "--out",
        path_str(&out),
        "--write-measurements",
        path_str(&csv),
    ];
    args.extend_from_slice(truth);
    let run = treecal(&args);
    assert_success(&run, &format!("simulate {name}"));
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    (csv, results)
}

/// `calibrate` on simulated measurements with `extra` flags: report.json.
fn calibrate_simulated(csv: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let robot = crate::common::repo().join("tests/data/second_robot_arm.urdf");
    let mut args = vec![
        "calibrate",
        "--robot",
        path_str(&robot),
        "--measurements",
        path_str(csv),
        "--tools",
        TOOL,
        "--position-sigma",
        "3e-5",
        "--out",
        path_str(out),
    ];
    args.extend_from_slice(extra);
    let run = treecal(&args);
    assert_success(&run, &format!("calibrate {extra:?}"));
    crate::common::cli::report_json(out)
}

/// The calibrated value of every parameter whose name ends with `kind` (` sine`, …), by joint.
fn joint_terms(report: &serde_json::Value, kind: &str) -> Vec<(String, f64)> {
    report["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| {
            let name = p["name"].as_str()?;
            let joint = name.strip_suffix(kind)?.trim().to_owned();
            Some((joint, p["calibrated"].as_f64()?))
        })
        .collect()
}

/// The true joint errors of results.json's first trial: `(joint, value)` of `kind`.
fn truth_terms(results: &serde_json::Value, kind: &str) -> Vec<(String, f64)> {
    results["trials"][0]["truth_joint_errors"]
        .as_array()
        .map_or(&[][..], |a| a.as_slice())
        .iter()
        .filter_map(|j| Some((j["joint"].as_str()?.to_owned(), j[kind].as_f64()?)))
        .collect()
}

/// Every true term of `kind` recovered within `tolerance` (rad), except on the joints in
/// `unseen`.
fn assert_recovered(
    truth: &[(String, f64)],
    found: &[(String, f64)],
    tolerance: f64,
    unseen: &[&str],
) {
    assert!(!truth.is_empty());
    for (joint, value) in truth.iter().filter(|(j, _)| !unseen.contains(&j.as_str())) {
        let (_, got) = found
            .iter()
            .find(|(j, _)| j == joint)
            .unwrap_or_else(|| panic!("{joint} not calibrated: {found:?}"));
        assert!(
            (got - value).abs() < tolerance,
            "{joint}: {got} rad, truth {value} rad"
        );
    }
}

/// `simulate` with a truth that has first-harmonic joint errors or backlash (issue 28 item
/// 8) and without either: `--model auto` chooses harmonics or backlash when the truth has them
/// and neither on plain geometric truth (no false alarm); `--joint-errors` recovers the
/// simulated terms.
#[test]
fn simulated_joint_errors_are_chosen_by_cross_validation_and_recovered() {
    let dir = tempfile::tempdir().unwrap();
    let chosen = |csv: &Path, name: &str| {
        let report = calibrate_simulated(csv, &dir.path().join(name), &["--model", "auto"]);
        let spec = report["model"]["spec"].clone();
        (spec["harmonics"] == true, spec["backlash"] == true, report)
    };
    let (plain, results) = simulate_arm(dir.path(), "plain", &[]);
    assert!(results["trials"][0]["truth_joint_errors"].is_null());
    let (harmonics, backlash, report) = chosen(&plain, "plain-auto");
    assert!(!harmonics && !backlash, "{}", report["model_choice"]);
    // Rigid truth: the identified-stiffness candidate is offered but not chosen.
    assert!(
        report["model_choice"]["rows"]
            .as_array()
            .unwrap()
            .iter()
            .any(|r| r["spec"]["identify_stiffness"] == true),
        "{}",
        report["model_choice"]
    );
    assert_ne!(
        report["model"]["spec"]["identify_stiffness"], true,
        "{}",
        report["model_choice"]
    );
    let (csv, results) = simulate_arm(dir.path(), "harmonics", &["--truth-harmonics", "0.003"]);
    let (harmonics, _, report) = chosen(&csv, "harmonics-auto");
    assert!(harmonics, "{}", report["model_choice"]);
    let report = calibrate_simulated(
        &csv,
        &dir.path().join("harmonics-fit"),
        &["--joint-errors", "harmonics"],
    );
    for kind in ["sine", "cosine"] {
        let found = joint_terms(&report, &format!(" {kind}"));
        assert_recovered(&truth_terms(&results, kind), &found, 2.5e-4, &[]);
    }
    let (csv, results) = simulate_arm(dir.path(), "backlash", &["--truth-backlash", "0.004"]);
    let (_, backlash, report) = chosen(&csv, "backlash-auto");
    assert!(backlash, "{}", report["model_choice"]);
    let report = calibrate_simulated(
        &csv,
        &dir.path().join("backlash-fit"),
        &["--joint-errors", "backlash"],
    );
    // arm_7 turns the tool about its own axis: no gravity torque to sign a backlash by.
    let found = joint_terms(&report, " backlash");
    assert_recovered(
        &truth_terms(&results, "backlash"),
        &found,
        2.5e-4,
        &["arm_7_joint"],
    );
}

/// The training file reads back as written: pose rows as poses (roll-pitch-yaw in degrees),
/// rows with every orientation cell empty as positions, with one note; a row with only some
/// orientation cells empty is an error naming its line and the column.
#[test]
fn a_pose_file_with_position_only_rows_reads_each_row_as_written() {
    let robot = second_robot(2028);
    let dir = tempfile::tempdir().unwrap();
    let (kept, _) = robot.split(7);
    let path = dir.path().join("training.csv");
    write_training(&robot, &kept, &path);
    let text = std::fs::read_to_string(&path).unwrap();
    let options = treecal::io::MeasurementReadOptions {
        tool: Some(TOOL.into()),
        ..Default::default()
    };
    let set =
        treecal::io::parse_measurements(&text, "training", &robot.tree, &robot.nominal, &options)
            .unwrap();
    assert_eq!(set.measurements.len(), kept.len());
    for (read, &i) in set.measurements.iter().zip(&kept) {
        let truth = &robot.measurements[i];
        match (&read.observation, &truth.observation) {
            (Observation::Pose(a), Observation::Pose(b)) => {
                assert!((a.translation.vector - b.translation.vector).norm() < 1e-6);
                assert!(a.rotation.angle_to(&b.rotation) < 1e-6);
            }
            (Observation::Position(a), Observation::Position(b)) => {
                assert!((a - b).norm() < 1e-6)
            }
            other => panic!("row {}: {other:?}", robot.ids[i]),
        }
        assert_eq!(read.session, truth.session);
    }
    assert!(
        set.notes
            .iter()
            .any(|n| n.contains("28 row(s) have empty roll,pitch,yaw")),
        "{:?}",
        set.notes
    );
    // One orientation cell given, two empty: an error at that row, not a position.
    let broken = text.replacen(",,,0.3\n", ",,1.0,0.3\n", 1);
    let error =
        treecal::io::parse_measurements(&broken, "training", &robot.tree, &robot.nominal, &options)
            .unwrap_err()
            .to_string();
    assert!(
        error.contains("training:") && error.contains("roll") && error.contains("missing"),
        "{error}"
    );
}

/// Writes the lab's files (training.csv, validation.csv of split seed 7, the URDF and the
/// stiffness file's paths in paths.txt) into the folder `TREECAL_SECOND_ROBOT_DIR`, for runs
/// of the CLI by hand (docs/identification.md's measurements); ignored by default.
#[test]
#[ignore = "writes files for manual runs; set TREECAL_SECOND_ROBOT_DIR"]
fn write_the_second_robot_lab_files() {
    let Some(dir) = std::env::var_os("TREECAL_SECOND_ROBOT_DIR") else {
        return;
    };
    let dir = PathBuf::from(dir);
    std::fs::create_dir_all(&dir).unwrap();
    let robot = second_robot(2028);
    lab_files(&robot, 7, &dir);
    let paths = format!("{}\n{}\n", robot.urdf.display(), robot.stiffness.display());
    std::fs::write(dir.join("paths.txt"), paths).unwrap();
}
