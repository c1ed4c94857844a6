//! Measurement sessions (issue 28, item 6): one measurement frame per session, fitted with the
//! geometry; validation in the training frame and re-registered. On the simulated second robot
//! (`common::second_robot`).

use crate::common::second_robot::{second_robot, SecondRobot, SESSIONS};
use treecal::calibration::{fit_session_frame, Sessions};
use treecal::calibration::{
    run_calibration, CalibrationInput, CalibrationRun, IdentificationOptions, MeasurementFrame,
    Plan, Status,
};
use treecal::kinematics::FlexibilityModel;
use treecal::math::{pose, Pose, Vec3};
use treecal::measurement::{Measurement, Observation};
use treecal::Branches;

/// Calibrates the second robot from `training` (with the true stiffness when `stiffness`),
/// validating on `validation`.
fn calibrate(
    robot: &SecondRobot,
    training: &[Measurement],
    validation: &[Measurement],
    stiffness: bool,
) -> CalibrationRun {
    let tool = robot
        .tree
        .link_id(crate::common::second_robot::TOOL)
        .unwrap();
    let branches: Branches = treecal::detect_branches(&robot.tree, Some(&[tool])).unwrap();
    let text = std::fs::read_to_string(&robot.stiffness).unwrap();
    let parsed =
        treecal::io::parse_stiffness(&text, "stiffness", &robot.tree, &robot.nominal).unwrap();
    let flexibility = FlexibilityModel::new(&robot.tree, &robot.nominal, &parsed)
        .unwrap()
        .with_gravity_in_measurement_frame();
    let options = IdentificationOptions {
        position_sigma: crate::common::second_robot::NOISE[0],
        rotation_sigma: crate::common::second_robot::NOISE[1],
        ..Default::default()
    };
    let plan = Plan::simultaneous();
    let input = CalibrationInput {
        tree: &robot.tree,
        branches: &branches,
        nominal: &robot.nominal,
        flexibility: stiffness.then_some(&flexibility),
        plan: &plan,
        options: &options,
        measurement_frame: MeasurementFrame::Auto,
        diagnose_columns: true,
    };
    run_calibration(&input, training, validation).unwrap()
}

/// RMS validation position error after calibration over every arm (mm).
fn validation_rms(run: &CalibrationRun) -> f64 {
    let errors: Vec<f64> = run
        .validation
        .iter()
        .flat_map(|a| a.position_mm[1].iter().copied())
        .collect();
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt()
}

/// Translation (m) and rotation (rad) between two frames.
fn distance(a: &Pose, b: &Pose) -> (f64, f64) {
    let d = a.inverse() * b;
    (d.translation.vector.norm(), d.rotation.angle())
}

/// The data: 48 poses and two position-only sessions, frames moved by 8 mm and 0.5°; the
/// sessions fitted with the geometry recover both moved frames (to a fraction of a
/// millimetre) and reach the validation noise floor, while one frame for every row leaves
/// millimetres. With the true stiffness, so that only the frames differ between the fits.
#[test]
fn sessions_recover_the_moved_frames_and_one_frame_does_notably_worse() {
    let robot = second_robot(28);
    assert_eq!(Sessions::of(&robot.measurements).names.len(), 3);
    for s in 1..3 {
        let truth = &robot.session_from_first[s];
        let moved = robot.rows_moved(s, truth);
        assert!((6e-3..10e-3).contains(&moved), "day {s} moved {moved} m");
        let turned = truth.rotation.angle().to_degrees();
        assert!((turned - 0.475).abs() < 0.03, "turned {turned}°");
    }
    let (kept, held) = robot.split(3);
    let validation = robot.rows(&held, true);
    let with = calibrate(&robot, &robot.rows(&kept, true), &validation, true);
    let without = calibrate(
        &robot,
        &robot.rows(&kept, false),
        &robot.rows(&held, false),
        true,
    );
    let sessions = with.sessions.as_ref().expect("the sessions are reported");
    assert!(sessions.converged, "{sessions:?}");
    assert_eq!(sessions.frames.len(), 3);
    for (frame, truth) in sessions.frames.iter().zip(&robot.session_from_first) {
        // Where the session measured (the frames' origin is metres away).
        let (_, r) = distance(&frame.session_from_first, truth);
        let s = SESSIONS
            .iter()
            .position(|n| frame.name.as_deref() == Some(n))
            .unwrap();
        let off = robot.rows_moved(s, &(frame.session_from_first * truth.inverse()));
        assert!(off < 0.3e-3, "{:?}: {} mm off", frame.name, off * 1e3);
        assert!(
            r.to_degrees() < 0.03,
            "{:?}: {}° off",
            frame.name,
            r.to_degrees()
        );
        assert_eq!(frame.determined, 6);
    }
    assert!(without.sessions.is_none());
    let (good, bad) = (validation_rms(&with), validation_rms(&without));
    eprintln!("validation RMS: sessions {good:.3} mm, one frame {bad:.3} mm");
    assert!(good < 0.6, "sessions: {good} mm");
    assert!(
        bad > 2.0 * good && bad > good + 0.5,
        "one frame {bad} mm vs {good} mm"
    );
    // Rigid (no stiffness: the series-elastic joints leave millimetres): the sessions still
    // settle and still beat one frame for every row.
    let rigid = calibrate(&robot, &robot.rows(&kept, true), &validation, false);
    let rigid_one = calibrate(
        &robot,
        &robot.rows(&kept, false),
        &robot.rows(&held, false),
        false,
    );
    assert!(rigid.sessions.as_ref().unwrap().converged);
    let (good, bad) = (validation_rms(&rigid), validation_rms(&rigid_one));
    eprintln!("rigid validation RMS: sessions {good:.3} mm, one frame {bad:.3} mm");
    assert!(good < bad, "rigid: sessions {good} mm, one frame {bad} mm");
    // The blunder is named, not silently absorbed.
    assert!(with
        .outliers
        .iter()
        .any(|o| o.index == kept.iter().position(|&i| i == robot.blunder).unwrap()));
    // The sessions are named with their rows and frames; nothing is wrong with them.
    let note = with.findings.iter().find(|f| f.code == "sessions").unwrap();
    assert_eq!(note.status, Status::Ok, "{}", note.message);
    for name in SESSIONS {
        assert!(note.message.contains(name), "{}", note.message);
    }
}

/// The second robot with its third session left out of training: the robot, the training
/// rows (kept, without day 3), the held-out rows (`SecondRobot::split`), and day 3's rows.
fn without_day3() -> (SecondRobot, Vec<usize>, Vec<usize>, Vec<usize>) {
    let robot = second_robot(29);
    let (kept, held) = robot.split(4);
    let day3: Vec<usize> = (0..robot.measurements.len())
        .filter(|&i| robot.measurements[i].session.as_deref() == Some(SESSIONS[2]))
        .collect();
    let training: Vec<usize> = kept.into_iter().filter(|i| !day3.contains(i)).collect();
    (robot, training, held, day3)
}

/// A held-out session the training never saw: the training frame (the first session's) carries
/// its moved frame into the figure, the re-registration (six frame parameters refitted, the
/// geometry fixed) removes it; the pose session's held-out rows use their own training frame.
/// The second robot trained without its third session, which is held out with the pose
/// session's held-out rows; `bump` (m) is added to the x of the first day-3 row.
fn run_with_a_new_session(bump: f64) -> (SecondRobot, CalibrationRun, Vec<Measurement>) {
    let (robot, training, held, day3) = without_day3();
    let validation: Vec<usize> = held.into_iter().chain(day3).collect();
    let mut validation_rows = robot.rows(&validation, true);
    let first_day3 = validation_rows
        .iter_mut()
        .find(|m| m.session.as_deref() == Some(SESSIONS[2]))
        .unwrap();
    if let Observation::Position(p) = &mut first_day3.observation {
        p.x += bump;
    }
    let run = calibrate(&robot, &robot.rows(&training, true), &validation_rows, true);
    (robot, run, validation_rows)
}

/// How far (m) the re-registered frame of day 3 is from the true one, where day 3 measured.
fn day3_frame_error(robot: &SecondRobot, found: &Pose, validation_rows: &[Measurement]) -> f64 {
    // The frame's origin is two metres from the robot, where a hundredth of a degree is a
    // third of a millimetre: compare the frames where the session measured.
    let truth = robot.session_from_first[2];
    validation_rows
        .iter()
        .filter(|m| m.session.as_deref() == Some(SESSIONS[2]))
        .map(|m| {
            let Observation::Position(p) = m.observation else {
                panic!("day 3 has positions");
            };
            let first = truth.inverse() * nalgebra::Point3::from(p);
            (found * first - truth * first).norm()
        })
        .fold(0.0, f64::max)
}

/// A held-out session the training never saw: the training frame (the first session's) carries
/// its moved frame into the figure, the re-registration (six frame parameters refitted, the
/// geometry fixed) removes it; the pose session's held-out rows use their own training frame.
#[test]
fn a_new_session_is_reported_in_the_training_frame_and_re_registered() {
    let (robot, run, validation_rows) = run_with_a_new_session(0.0);
    let sessions = run.sessions.as_ref().unwrap();
    assert_eq!(sessions.frames.len(), 2);
    let [first, new] = &sessions.validation[..] else {
        panic!("{:?}", sessions.validation);
    };
    assert_eq!(first.name.as_deref(), Some(SESSIONS[0]));
    assert!(first.seen_in_training);
    assert!(first.training_frame_rms < 0.6e-3, "{first:?}");
    assert_eq!(new.name.as_deref(), Some(SESSIONS[2]));
    assert!(!new.seen_in_training);
    assert_eq!(new.refitted_parameters, 6);
    assert!(new.training_frame_rms > 4e-3, "{new:?}");
    assert!(new.reregistered_rms < 0.6e-3, "{new:?}");
    let moved = day3_frame_error(&robot, &new.session_from_first, &validation_rows);
    assert!(moved < 0.5e-3, "{moved} m");
    let note = run
        .findings
        .iter()
        .find(|f| f.code == "validation-sessions")
        .unwrap();
    assert!(note.message.contains("re-registered"), "{}", note.message);
    // Day 3 was measured in another frame: every validation figure counts it re-registered
    // (in the training frame it is over 4 mm), and a note says so.
    assert!(new.moved() && !first.moved());
    let rms = validation_rms(&run);
    assert!(rms < 0.6, "validation RMS {rms} mm");
    let moved = run
        .findings
        .iter()
        .find(|f| f.code == "validation-session-moved")
        .expect("the moved session is named");
    assert!(moved.message.contains(SESSIONS[2]), "{}", moved.message);
    let failed: Vec<&str> = run
        .findings
        .iter()
        .filter(|f| f.status == Status::Failed)
        .map(|f| f.message.as_str())
        .collect();
    assert!(failed.is_empty(), "{failed:?}");
}

/// A new session measured in the training frame (held-out rows of the first day under a new
/// name) is not taken for a moved one: it counts in the training frame, no note.
#[test]
fn a_new_session_in_the_training_frame_is_not_re_registered() {
    let (robot, training, held, _) = without_day3();
    let first_day: Vec<usize> = held
        .into_iter()
        .filter(|&i| robot.measurements[i].session.as_deref() == Some(SESSIONS[0]))
        .collect();
    let mut validation = robot.rows(&first_day, true);
    for m in &mut validation {
        m.session = Some("day9".into());
    }
    let run = calibrate(&robot, &robot.rows(&training, true), &validation, true);
    let sessions = run.sessions.as_ref().unwrap();
    let [new] = &sessions.validation[..] else {
        panic!("{:?}", sessions.validation);
    };
    assert!(!new.seen_in_training && !new.moved(), "{new:?}");
    assert!(run
        .findings
        .iter()
        .all(|f| f.code != "validation-session-moved"));
    let rms = validation_rms(&run);
    assert!(rms < 0.6, "validation RMS {rms} mm");
}

/// A gross blunder among a new session's validation rows (0.1 m on one row) does not drag its
/// re-registered frame: the frame stays where the clean rows put it, and the blunder still
/// counts in the session's figure.
#[test]
fn a_blunder_in_a_new_session_does_not_drag_its_re_registration() {
    let (robot, run, validation_rows) = run_with_a_new_session(0.1);
    let sessions = run.sessions.as_ref().unwrap();
    let new = &sessions.validation[1];
    let moved = day3_frame_error(&robot, &new.session_from_first, &validation_rows);
    assert!(moved < 0.5e-3, "{moved} m");
    let rows = new.rows as f64;
    let blunder_alone = 0.1 / rows.sqrt();
    assert!(
        new.reregistered_rms > 0.9 * blunder_alone,
        "every row counts: {new:?}"
    );
}

/// One labelled session: nothing to fit, no warning, the same result as without the label.
#[test]
fn one_session_changes_nothing() {
    let robot = second_robot(30);
    let pose_rows: Vec<usize> = (0..48).collect();
    let (kept, held): (Vec<usize>, Vec<usize>) = pose_rows.iter().partition(|&&i| i % 4 != 0);
    let labelled = calibrate(
        &robot,
        &robot.rows(&kept, true),
        &robot.rows(&held, true),
        false,
    );
    let plain = calibrate(
        &robot,
        &robot.rows(&kept, false),
        &robot.rows(&held, false),
        false,
    );
    assert_eq!(
        labelled.report.model.parameters(),
        plain.report.model.parameters()
    );
    let sessions = labelled.sessions.as_ref().unwrap();
    assert_eq!(sessions.frames.len(), 1);
    assert_eq!(sessions.rounds, 0);
    assert!(labelled
        .findings
        .iter()
        .filter(|f| f.code.contains("session"))
        .all(|f| f.status == Status::Ok));
    // One session is said as one frame, without rounds of frame fits that did not run.
    let said: Vec<&str> = labelled
        .findings
        .iter()
        .filter(|f| f.code == "sessions")
        .map(|f| f.message.as_str())
        .collect();
    assert!(
        said.iter()
            .any(|m| m.starts_with("1 measurement session, in one measurement frame")),
        "{said:#?}"
    );
    assert!(said.iter().all(|m| !m.contains("round(s)")), "{said:#?}");
}

/// The frame block's fit recovers a known frame exactly from noiseless poses and positions,
/// and says how many directions two positions leave determined.
#[test]
fn a_session_frame_is_recovered_from_poses_and_from_positions() {
    let truth = pose(
        Vec3::new(0.004, -0.007, 0.003),
        nalgebra::UnitQuaternion::from_euler_angles(0.004, -0.006, 0.009),
    );
    let predicted: Vec<Pose> = (0..6)
        .map(|k| {
            let k = k as f64;
            pose(
                Vec3::new(0.3 * k.cos(), 0.2 * k.sin(), 0.1 * k),
                nalgebra::UnitQuaternion::from_euler_angles(0.3 * k, -0.2, 0.1 * k),
            )
        })
        .collect();
    let measure = |poses: bool| -> Vec<Measurement> {
        predicted
            .iter()
            .map(|p| Measurement {
                tool: 0,
                q: Vec::new(),
                observation: if poses {
                    Observation::Pose(truth * p)
                } else {
                    Observation::Position((truth * p).translation.vector)
                },
                stage: None,
                payload: None,
                session: Some("s".into()),
            })
            .collect()
    };
    let options = IdentificationOptions::default();
    for poses in [true, false] {
        let measured = measure(poses);
        let refs: Vec<&Measurement> = measured.iter().collect();
        let (fitted, determined) = fit_session_frame(&predicted, &refs, &[], &options);
        let (t, r) = distance(&fitted, &truth);
        assert!(t < 1e-12 && r < 1e-12, "poses {poses}: {t}, {r}");
        assert_eq!(determined, 6);
    }
    let measured = measure(false);
    let refs: Vec<&Measurement> = measured.iter().take(2).collect();
    let (_, determined) = fit_session_frame(&predicted[..2], &refs, &[], &options);
    assert_eq!(
        determined, 5,
        "two points leave the turn about their line free"
    );
}

/// The `session` column is read and written.
#[test]
fn the_session_column_round_trips_through_the_csv() {
    let robot = second_robot(31);
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<usize> = (40..60).collect();
    let paths = robot.write_csv(&rows, true, dir.path(), "data");
    assert_eq!(paths.len(), 2);
    let mut read = Vec::new();
    for path in &paths {
        let text = std::fs::read_to_string(path).unwrap();
        assert!(text.lines().next().unwrap().ends_with(",session"), "{text}");
        let set = treecal::io::parse_measurements(
            &text,
            "data",
            &robot.tree,
            &robot.nominal,
            &Default::default(),
        )
        .unwrap();
        read.extend(set.measurements);
    }
    let sessions: Vec<Option<String>> = read.iter().map(|m| m.session.clone()).collect();
    let expected: Vec<Option<String>> = rows
        .iter()
        .map(|&i| robot.measurements[i].session.clone())
        .collect();
    assert_eq!(sessions, expected);
}

/// End to end through `calibrate` (a CSV with a `session` column, every row a position):
/// report.json's `sessions` block, report.md's Sessions section and the stderr notes name every
/// session with its rows and its frame from the first, and each validation session's two
/// figures.
#[test]
fn the_report_names_every_session_with_its_rows_and_frame() {
    let robot = second_robot(32);
    let dir = tempfile::tempdir().unwrap();
    // One observation layout per file: the pose session's rows as positions of the body.
    let mut positions = robot.clone_rows_as_positions();
    // The blunder stays in: it must not disturb the session frames.
    let (kept, held) = robot.split(6);
    let write = |rows: &[usize], name: &str| {
        let data: Vec<Measurement> = rows.iter().map(|&i| positions[i].clone()).collect();
        let text = treecal::io::measurements_to_csv(&robot.tree, &robot.nominal, &data).unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let (training, validation) = (write(&kept, "training.csv"), write(&held, "validation.csv"));
    positions.clear();
    let config = treecal::workflow::CalibrateConfig {
        robot: treecal::workflow::RobotSource::File(robot.urdf.clone()),
        measurements: treecal::workflow::MeasurementSource::Csv(training),
        validation: Some(treecal::workflow::MeasurementSource::Csv(validation)),
        tools: Some(vec![crate::common::second_robot::TOOL.into()]),
        position_sigma: 3e-4,
        ..Default::default()
    };
    let result = treecal::workflow::calibrate(&config).unwrap();
    let report = result.report();
    let sessions = &report["sessions"];
    let training = sessions["training"].as_array().unwrap();
    assert_eq!(training.len(), 3, "{sessions}");
    // Rigid fit of series-elastic joints: the frames carry part of the model error, so only
    // roughly (the truth moves the rows by 7-8 mm).
    for (row, name) in training.iter().zip(SESSIONS) {
        assert_eq!(row["name"], name);
        let moved = row["rows_moved_mm"].as_f64().unwrap();
        if name == SESSIONS[0] {
            assert_eq!(moved, 0.0);
        } else {
            assert!((3.0..20.0).contains(&moved), "{row}");
        }
    }
    assert_eq!(training[0]["rows"], 36);
    assert_eq!(training[1]["rows"], 14);
    let validation = sessions["validation"].as_array().unwrap();
    assert_eq!(validation.len(), 1);
    assert_eq!(validation[0]["training_frame"], "training");
    assert_eq!(validation[0]["refitted_parameters"], 6);
    assert!(result.report_markdown.contains("## Sessions"));
    assert!(result.report_markdown.contains("| 'day2_points' | 14 |"));
    // registration.yaml holds the first session's frame: the report says what scores the
    // other sessions' rows of "calibrated.urdf + registration.yaml as written".
    let first = format!(
        "registration.yaml is the first session's frame ('{}')",
        SESSIONS[0]
    );
    assert!(
        result.report_markdown.contains(&first)
            && result
                .report_markdown
                .contains("`sessions.training[].session_from_first`"),
        "{}",
        result.report_markdown
    );
    let said: Vec<&str> = result.notes.iter().map(|n| n.text.as_str()).collect();
    assert!(
        said.iter()
            .any(|t| t.contains("3 measurement sessions")
                && t.contains("'day3_points' 14 rows (frame")),
        "{said:#?}"
    );
    assert!(
        said.iter()
            .any(|t| t.contains("re-registered (6 frame parameters")),
        "{said:#?}"
    );
}

/// Writes the rows `indices` of `positions` to `path` as a measurement CSV: only those of
/// `session` when given, with their `session` labels when `labelled`.
fn write_rows(
    robot: &SecondRobot,
    positions: &[Measurement],
    (indices, session, labelled): (&[usize], Option<&str>, bool),
    path: &std::path::Path,
) {
    let rows: Vec<Measurement> = indices
        .iter()
        .map(|&i| positions[i].clone())
        .filter(|m| session.is_none() || m.session.as_deref() == session)
        .map(|mut m| {
            if !labelled {
                m.session = None;
            }
            m
        })
        .collect();
    let text = treecal::io::measurements_to_csv(&robot.tree, &robot.nominal, &rows).unwrap();
    std::fs::write(path, text).unwrap();
}

/// One file per session, as labs record them: the three sessions of the second robot written
/// as `day1_poses.csv`, `day2_points.csv`, `day3_points.csv` without a `session` column (each
/// numbering its rows from 1) and given as three `measurements` files calibrate exactly as one
/// file with the `session` column: the same sessions (named by the files), the same frames and
/// the same validation figures. The repeated row ids are prefixed with their session, and a
/// note says how the files were read.
#[test]
fn one_file_per_session_calibrates_as_a_session_column() {
    use treecal::workflow::{calibrate, CalibrateConfig, MeasurementSource, RobotSource};
    let robot = second_robot(33);
    let dir = tempfile::tempdir().unwrap();
    let positions = robot.clone_rows_as_positions();
    let (kept, held) = robot.split(6);
    let write = |indices: &[usize], session: Option<&str>, labelled: bool, name: &str| {
        let path = dir.path().join(name);
        write_rows(&robot, &positions, (indices, session, labelled), &path);
        path
    };
    let per_session: Vec<_> = SESSIONS
        .iter()
        .map(|s| write(&kept, Some(s), false, &format!("{s}.csv")))
        .collect();
    let one_file = write(&kept, None, true, "training.csv");
    let validation = write(&held, None, true, "validation.csv");
    let run = |measurements: MeasurementSource| {
        calibrate(&CalibrateConfig {
            robot: RobotSource::File(robot.urdf.clone()),
            measurements,
            validation: Some(MeasurementSource::Csv(validation.clone())),
            tools: Some(vec![crate::common::second_robot::TOOL.into()]),
            position_sigma: 3e-4,
            // The geometry alone: no cross-validation (the model error of the rigid fit of
            // series-elastic joints would start one), the comparison is the same.
            model: treecal::workflow::ModelChoice::Level(treecal::workflow::ModelLevel::Geometry),
            ..Default::default()
        })
        .unwrap()
    };
    let files = run(MeasurementSource::from_paths(per_session));
    let column = run(MeasurementSource::Csv(one_file));
    let (a, b) = (files.report(), column.report());
    assert_eq!(a["sessions"]["training"], b["sessions"]["training"]);
    assert_eq!(a["sessions"]["training"].as_array().unwrap().len(), 3);
    assert_eq!(
        a["artifact"]["urdf_alone"]["errors"],
        b["artifact"]["urdf_alone"]["errors"]
    );
    let said: Vec<&str> = files.notes.iter().map(|n| n.text.as_str()).collect();
    for text in [
        "3 measurement files read as one set, each file its own session",
        "'day2_points' 14 rows",
        "every id is prefixed with its session, e.g. 'day1_poses/1'",
    ] {
        assert!(said.iter().any(|t| t.contains(text)), "{text}: {said:#?}");
    }
}

/// The CLI takes `--measurements` and `--validation` more than once (each file a session, as
/// `one_file_per_session_calibrates_as_a_session_column` shows through the library); a camera
/// or contact calibration reads one file each and says so before reading anything.
#[test]
fn measurements_and_validation_files_repeat_on_the_command_line() {
    use crate::common::cli::*;
    let robot = second_robot(34);
    let dir = tempfile::tempdir().unwrap();
    let positions = robot.clone_rows_as_positions();
    let (kept, held) = robot.split(6);
    let write = |indices: &[usize], session: Option<&str>, name: &str| {
        let path = dir.path().join(name);
        write_rows(&robot, &positions, (indices, session, false), &path);
        path_str(&path).to_owned()
    };
    let files: Vec<String> = SESSIONS
        .iter()
        .map(|s| write(&kept, Some(s), &format!("{s}.csv")))
        .collect();
    let validation = write(&held, None, "held.csv");
    let out = dir.path().join("out");
    let urdf = robot.urdf.display().to_string();
    let mut args = vec!["calibrate", "--robot", &urdf, "--tools", "arm_tool_link"];
    args.extend(["--model", "geometry", "--position-sigma", "0.3"]);
    for file in &files {
        args.extend(["--measurements", file.as_str()]);
    }
    args.extend(["--validation", validation.as_str(), "--out", path_str(&out)]);
    let run = treecal(&args);
    assert!(
        run.stderr.contains("3 measurement files read as one set"),
        "{run}"
    );
    assert!(out.join("report.json").exists(), "{run}");
    let report = report_json(&out);
    let names: Vec<&str> = report["sessions"]["training"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, SESSIONS);
    let run = treecal(&[
        "calibrate",
        "--contacts",
        &files[0],
        "--contact-setup",
        &files[1],
        "--measurements",
        &files[0],
        "--measurements",
        &files[1],
        "--out",
        path_str(&out),
    ]);
    assert_error(
        &run,
        &[
            "--measurements",
            "given 2 times",
            "with --contacts it takes one file",
        ],
        "contacts with two measurement files",
    );
}

/// The artifact table ("validated as written") scores the registered nominal robot as the
/// run's "before" does: on a new validation session measured in another frame, re-registered
/// with the nominal's own frame (not the calibrated model's). Trained without day 3 through
/// `calibrate`, validated on held-out rows and day 3 (moved): the artifact's nominal row equals
/// the run's "before" over every validation row, and the calibrated rows are re-registered too.
#[test]
fn the_artifact_table_scores_the_nominal_with_its_own_re_registration() {
    use treecal::workflow::{calibrate, CalibrateConfig, MeasurementSource, RobotSource};
    let (robot, training, held, day3) = without_day3();
    let dir = tempfile::tempdir().unwrap();
    let positions = robot.clone_rows_as_positions();
    let validation: Vec<usize> = held.into_iter().chain(day3).collect();
    let (train_csv, validation_csv) = (dir.path().join("t.csv"), dir.path().join("v.csv"));
    write_rows(&robot, &positions, (&training, None, true), &train_csv);
    write_rows(
        &robot,
        &positions,
        (&validation, None, true),
        &validation_csv,
    );
    let config = CalibrateConfig {
        robot: RobotSource::File(robot.urdf.clone()),
        measurements: MeasurementSource::Csv(train_csv),
        validation: Some(MeasurementSource::Csv(validation_csv)),
        stiffness: Some(treecal::workflow::StiffnessSource::File(
            robot.stiffness.clone(),
        )),
        tools: Some(vec![crate::common::second_robot::TOOL.into()]),
        position_sigma: crate::common::second_robot::NOISE[0],
        rotation_sigma: crate::common::second_robot::NOISE[1],
        ..Default::default()
    };
    let result = calibrate(&config).unwrap();
    let report = result.report();
    let moved = report["sessions"]["validation"]
        .as_array()
        .unwrap()
        .iter()
        .any(|s| s["training_frame"] == "moved");
    assert!(moved, "{}", report["sessions"]);
    let before: Vec<f64> = report["validation"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|arm| arm["rows"].as_array().unwrap().iter())
        .map(|row| row["position_mm"]["before"].as_f64().unwrap())
        .collect();
    let run_before = (before.iter().map(|e| e * e).sum::<f64>() / before.len() as f64).sqrt();
    let nominal = &report["artifact"]["registered_nominal"];
    let artifact_before = nominal["errors"]["rms_position_mm"].as_f64().unwrap();
    assert_eq!(
        nominal["observations"].as_u64().unwrap() as usize,
        before.len()
    );
    assert!(
        (artifact_before - run_before).abs() < 1e-9,
        "artifact nominal {artifact_before} mm, run before {run_before} mm"
    );
    // The calibrated files as written count day 3 re-registered too (the compensation file
    // with them: the joints are series-elastic).
    let written = report["artifact"]["with_compensation"]["errors"]["rms_position_mm"]
        .as_f64()
        .unwrap();
    assert!(
        written < 1.0,
        "calibrated.urdf + its files as written: {written} mm"
    );
    eprintln!("artifact: nominal {artifact_before} mm, as written {written} mm");
}
