//! `treecal calibrate` end to end: a synthetic robot measured with noise is calibrated through
//! the CLI and the exported URDF is compared with the truth; the parameter covariance against a
//! dense brute force and a Monte Carlo; bad input fails cleanly and writes nothing; the
//! held-out validation fifth.

use crate::common::cli::*;
use crate::common::*;
use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde_json::Value;
use std::path::Path;
use treecal::calibration::{fit_rigid_transform, hold_out};
use treecal::io::{
    measurements_to_csv, measurements_to_csv_with, read_stiffness, AngleUnit, LengthUnit,
    MeasurementWriteOptions,
};
use treecal::kinematics::FlexibilityModel;
use treecal::math::{pose_error, Pose, Vec3};
use treecal::measurement::{Measurement, Observation};
use treecal::sim::{observe, NoiseModel, Targets};
use treecal::sim::{sample_configurations, SamplingOptions};
use treecal::sim::{true_model, ErrorRanges};
use treecal::{load_urdf, Branches, KinematicTree, McpcModel};

/// A robot with its branches and nominal model.
struct Robot {
    tree: KinematicTree,
    branches: Branches,
    nominal: McpcModel,
}

fn robot_at(path: &Path, tools: Option<&[&str]>) -> Robot {
    let tree = load_urdf(path).unwrap_or_else(|e| panic!("{e}")).tree;
    let crate::common::TestRobot {
        tree,
        branches,
        model: nominal,
    } = crate::common::TestRobot::from_tree(tree, tools);
    Robot {
        tree,
        branches,
        nominal,
    }
}

fn built_in() -> Robot {
    robot_at(&robot("robonaut/robonaut.urdf"), None)
}

fn stiffness_path() -> std::path::PathBuf {
    robot("robonaut/stiffness.yaml")
}

/// The flexibility model `treecal calibrate --stiffness robots/robonaut/stiffness.yaml` builds
/// (on the nominal geometry; gravity in the measurement frame, the CLI's default).
fn built_in_flexibility(robot: &Robot) -> FlexibilityModel {
    let stiffness = read_stiffness(&stiffness_path(), &robot.tree, &robot.nominal).unwrap();
    FlexibilityModel::new(&robot.tree, &robot.nominal, &stiffness)
        .unwrap()
        .with_gravity_in_measurement_frame()
}

fn configurations(robot: &Robot, count: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    sample_configurations(
        &robot.tree,
        None,
        count,
        rng,
        &SamplingOptions::default(),
        &[],
    )
    .unwrap()
}

/// Torso configurations as `treecal simulate` draws them: the arms locked at `locks` random
/// configurations, the torso moving.
fn torso_configurations(
    robot: &Robot,
    count: usize,
    locks: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Vec<f64>> {
    let torso = robot.branches.coupled.dofs(&robot.tree);
    let locks = configurations(robot, locks, rng);
    (0..count)
        .map(|k| {
            let lock = &locks[k % locks.len()];
            let fixed: Vec<(usize, f64)> = (0..robot.tree.dof_count())
                .filter(|d| !torso.contains(d))
                .map(|d| (d, lock[d]))
                .collect();
            sample_configurations(
                &robot.tree,
                None,
                1,
                rng,
                &SamplingOptions::default(),
                &fixed,
            )
            .unwrap()
            .remove(0)
        })
        .collect()
}

/// How a synthetic tracker sees the truth.
struct Tracker<'a> {
    /// Where the robot's root frame is in the tracker frame.
    world_from_base: Pose,
    /// Where the measured frame (three targets) sits on each tool.
    tool_from_target: Pose,
    /// The truth's deflection, if any.
    flexibility: Option<&'a FlexibilityModel>,
    noise: NoiseModel,
}

impl Tracker<'_> {
    /// The noise-free frame the targets define at `q`, in the tracker frame.
    fn true_targets(&self, robot: &Robot, truth: &McpcModel, q: &[f64]) -> Vec<Pose> {
        let tools = match self.flexibility {
            Some(f) => f.deflected_tool_poses(&robot.tree, truth, q).unwrap(),
            None => truth.tool_poses(q),
        };
        tools
            .iter()
            .map(|t| self.world_from_base * t * self.tool_from_target)
            .collect()
    }

    /// Three-target observations of every tool at every configuration, labelled `stage`.
    fn measure(
        &self,
        robot: &Robot,
        truth: &McpcModel,
        configurations: &[Vec<f64>],
        stage: Option<&str>,
        rng: &mut ChaCha8Rng,
    ) -> Vec<Measurement> {
        let mut measurements = Vec::new();
        for q in configurations {
            for (tool, pose) in self.true_targets(robot, truth, q).iter().enumerate() {
                measurements.push(Measurement {
                    payload: None,
                    tool,
                    q: q.clone(),
                    observation: observe(pose, Targets::Three, &self.noise, rng),
                    stage: stage.map(str::to_owned),
                    session: None,
                });
            }
        }
        measurements
    }
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// What a simulated round trip leaves for the checks: the robot, its flexibility model, the
/// truth, the random stream (for fresh validation configurations) and the directory whose
/// `out/` holds the calibration.
struct RoundTrip {
    robot: Robot,
    flexibility: FlexibilityModel,
    truth: McpcModel,
    rng: ChaCha8Rng,
    dir: tempfile::TempDir,
}

/// A truth with paper-size errors, deflected under gravity and measured by an AT901-class
/// tracker with three targets (10 torso configurations at 2 locks, 25 arm configurations, in the
/// root frame), written as CSV and calibrated by the CLI with exact compensation and `extra`
/// flags into `dir/out`.
fn round_trip(seed: u64, extra: &[&str]) -> RoundTrip {
    let robot = built_in();
    let flexibility = built_in_flexibility(&robot);
    let mut rng = rng(seed);
    let truth = true_model(&robot.nominal, &ErrorRanges::default(), &mut rng).unwrap();
    let tracker = Tracker {
        world_from_base: Pose::identity(),
        tool_from_target: Pose::identity(),
        flexibility: Some(&flexibility),
        noise: NoiseModel::at901(),
    };
    let torso = torso_configurations(&robot, 10, 2, &mut rng);
    let arms = configurations(&robot, 25, &mut rng);
    let mut measurements = tracker.measure(&robot, &truth, &torso, Some("torso"), &mut rng);
    measurements.extend(tracker.measure(&robot, &truth, &arms, Some("arms"), &mut rng));
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("m.csv");
    std::fs::write(
        &csv,
        measurements_to_csv(&robot.tree, &robot.nominal, &measurements).unwrap(),
    )
    .unwrap();
    let out = dir.path().join("out");
    let stiffness = stiffness_path();
    let mut args = vec![
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--stiffness",
        path_str(&stiffness),
        "--position-sigma",
        "3.3e-5",
        "--rotation-sigma",
        "4.7e-4",
        "--out",
        path_str(&out),
    ];
    args.extend_from_slice(extra);
    let run = treecal(&args);
    assert_success(&run, "calibrate");
    // Good data: verdict ok, and no false alarm.
    assert!(!run.stderr.contains("treecal: warning"), "{run}");
    assert_eq!(
        read_json(&out.join("report.json"))["verdict"]["status"],
        "ok",
        "{run}"
    );
    RoundTrip {
        robot,
        flexibility,
        truth,
        rng,
        dir,
    }
}

/// Item 4 of issue 5: simulated measurements of the built-in Robonaut (paper errors ±0.05 rad /
/// ±5 cm, AT901 noise, gravity deflection) calibrated by the CLI with exact compensation; the
/// exported URDF plus the deflection the calibration models predicts the truth's deflected tool
/// poses at fresh configurations to within the noise.
///
/// "Within the noise": the mean position error is below 3× the RMS error that the parameter
/// covariance predicts at the held-out configurations (`predicted_validation_rms_mm`, about
/// 0.05 mm; `treecal simulate` reports 0.044 mm for its set-up) and below 0.15 mm absolute; the
/// mean orientation error below 3× the orientation noise of a three-target frame
/// (√2·σ/0.1 m ≈ 0.027° for σ ≈ 33 µm). The data are given in the root frame, as `simulate`
/// writes them; the next test fits the frame instead.
#[test]
fn round_trip_reaches_the_noise_floor() {
    let RoundTrip {
        robot,
        flexibility,
        truth,
        mut rng,
        dir,
    } = round_trip(51, &["--measurement-frame", "base"]);
    let out = dir.path().join("out");

    let calibrated = robot_at(&out.join("calibrated.urdf"), None);
    let model = &calibrated.nominal;
    let validation = configurations(&robot, 30, &mut rng);
    let (mut position_mm, mut orientation_deg) = (Vec::new(), Vec::new());
    for q in &validation {
        let actual = flexibility
            .deflected_tool_poses(&robot.tree, &truth, q)
            .unwrap();
        // The URDF is the rigid geometry; the calibration predicts the deflection on top.
        let predicted = flexibility
            .deflected_tool_poses(&robot.tree, model, q)
            .unwrap();
        for (a, p) in actual.iter().zip(&predicted) {
            let (position, angle) = pose_difference(a, p);
            position_mm.push(position * 1e3);
            orientation_deg.push(angle.to_degrees());
        }
    }
    let report = read_json(&out.join("report.json"));
    let predicted_rms = report["predicted_validation_rms_mm"].as_f64().unwrap();
    let (position, orientation) = (mean(&position_mm), mean(&orientation_deg));
    let orientation_noise_deg = (std::f64::consts::SQRT_2 * 33e-6 / 0.1).to_degrees();
    eprintln!(
        "round trip: mean {position:.4} mm, {orientation:.5}° at {} configurations; predicted \
         RMS {predicted_rms:.4} mm; orientation noise {orientation_noise_deg:.5}°",
        validation.len()
    );
    assert!(
        position < 3.0 * predicted_rms && position < 0.15,
        "mean position error {position} mm against a predicted RMS of {predicted_rms} mm"
    );
    assert!(
        orientation < 3.0 * orientation_noise_deg,
        "mean orientation error {orientation}° against noise {orientation_noise_deg}°"
    );

    // The report's own validation (held-out fifth, against noisy measurements) agrees.
    for arm in report["validation"].as_array().unwrap() {
        let removed = arm["position_removed_percent"].as_f64().unwrap();
        assert!(removed > 99.5, "{}: {removed} % removed", arm["arm"]);
        // Orientation: the % removed is noise-bound (a few degrees before, the three-target
        // noise after, on only five held-out configurations: 98.9 % here), so the error after
        // is held to the noise instead.
        let after = arm["after"]["mean_orientation_deg"].as_f64().unwrap();
        assert!(
            after < 3.0 * orientation_noise_deg,
            "{}: {after}° after calibration on the held-out configurations",
            arm["arm"]
        );
    }
}

/// The Debian liburdfdom-tools binary (a different `check_urdf` may come first on PATH).
const CHECK_URDF: &str = "/usr/bin/check_urdf";

/// `check_urdf` accepts `path`; skipped with a loud note when it is missing, unless
/// `TREECAL_REQUIRE_TOOLS=1`.
fn check_urdf_accepts(path: &Path) {
    if !Path::new(CHECK_URDF).exists() {
        let problem = format!("{CHECK_URDF} not found (Debian/Ubuntu package liburdfdom-tools)");
        if std::env::var("TREECAL_REQUIRE_TOOLS").is_ok_and(|v| v == "1") {
            panic!("TREECAL_REQUIRE_TOOLS=1 but {problem}");
        }
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr(),
            "\n!!! SKIPPED: check_urdf on the calibrated Robonaut 2 (tests/calibrate.rs): {problem}\n"
        );
        return;
    }
    let output = std::process::Command::new(CHECK_URDF)
        .arg(path)
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "check_urdf refuses {}:\n{}{}",
        path.display(),
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Item 4 of issue 5 on NASA's Robonaut 2 (74 joints, the palms as tools): a rigid robot off by
/// ±0.01 rad / ±1 cm, measured by a tracker 3 m away and turned, targets 2 cm off the palm
/// origin, three-target rows in mm and deg, staged plan, measurement frame fitted.
///
/// The fitted measurement frame and the identified target frames are a gauge the data cannot
/// tell from the robot's base, so the calibrated targets' positions (root frame) are compared
/// with the true ones after the best rigid transform between the two sets; the residual RMS
/// must be at the noise level (σ ≈ 33 µm per coordinate; below 3σ = 0.1 mm).
#[test]
fn robonaut2_staged_fit_through_the_cli() {
    let path = robonaut2();
    let tools = ["r2/left_palm", "r2/right_palm"];
    let robot = robot_at(&path, Some(&tools));
    let mut rng = rng(52);
    let ranges = ErrorRanges {
        angle: 0.01,
        length: 0.01,
    };
    let truth = true_model(&robot.nominal, &ranges, &mut rng).unwrap();
    let world_from_base = Pose::new(Vec3::new(3.0, 0.5, -1.0), Vec3::new(0.1, -0.2, 2.5));
    let tracker = Tracker {
        world_from_base,
        tool_from_target: Pose::new(Vec3::new(0.02, -0.01, 0.015), Vec3::new(0.0, 0.3, 0.0)),
        flexibility: None,
        // The tracker at the origin of its own frame, the robot about 3 m away.
        noise: NoiseModel {
            tracker: [0.0; 3],
            ..NoiseModel::at901()
        },
    };
    let torso = torso_configurations(&robot, 10, 2, &mut rng);
    let arms = configurations(&robot, 30, &mut rng);
    let mut measurements = tracker.measure(&robot, &truth, &torso, Some("torso"), &mut rng);
    measurements.extend(tracker.measure(&robot, &truth, &arms, Some("arms"), &mut rng));

    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("m.csv");
    let options = MeasurementWriteOptions {
        length_unit: LengthUnit::Millimetre,
        angle_unit: AngleUnit::Degree,
        three_targets: true,
    };
    std::fs::write(
        &csv,
        measurements_to_csv_with(&robot.tree, &robot.nominal, &measurements, &options).unwrap(),
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = treecal(&[
        "calibrate",
        "--robot",
        path_str(&path),
        "--tools",
        "r2/left_palm,r2/right_palm",
        "--measurements",
        path_str(&csv),
        "--length-unit",
        "mm",
        "--angle-unit",
        "deg",
        "--position-sigma",
        "3.3e-5",
        "--rotation-sigma",
        "4.7e-4",
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate robonaut 2");
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["verdict"]["status"], "ok", "{run}");
    assert!(!run.stderr.contains("treecal: warning"), "{run}");
    assert_eq!(report["context"]["plan"], "staged", "{report}");

    let calibrated_path = out.join("calibrated.urdf");
    let calibrated = robot_at(&calibrated_path, Some(&tools));
    let base_tracker = Tracker {
        world_from_base: Pose::identity(),
        ..tracker
    };
    let (mut predicted, mut actual) = (Vec::new(), Vec::new());
    for q in configurations(&robot, 30, &mut rng) {
        for (p, a) in calibrated
            .nominal
            .tool_poses(&q)
            .iter()
            .zip(base_tracker.true_targets(&robot, &truth, &q))
        {
            predicted.push(p.translation.vector);
            actual.push(a.translation.vector);
        }
    }
    let gauge = fit_rigid_transform(&predicted, &actual).unwrap();
    let rms = (predicted
        .iter()
        .zip(&actual)
        .map(|(p, a)| {
            (gauge * nalgebra::Point3::from(*p) - nalgebra::Point3::from(*a)).norm_squared()
        })
        .sum::<f64>()
        / predicted.len() as f64)
        .sqrt();
    let before = (robot
        .nominal
        .tool_poses(&measurements[0].q)
        .iter()
        .zip(base_tracker.true_targets(&robot, &truth, &measurements[0].q))
        .map(|(p, a)| (p.translation.vector - a.translation.vector).norm())
        .fold(0.0, f64::max))
        * 1e3;
    eprintln!(
        "robonaut 2: residual RMS {:.4} mm after the gauge fit ({:.1} mm before calibration)",
        rms * 1e3,
        before
    );
    assert!(rms < 1e-4, "residual RMS {rms} m after the gauge fit");
    check_urdf_accepts(&calibrated_path);
}

/// Position and rotation noise of the uncertainty tests (m, rad), and the σ's they assume.
const POSITION_SIGMA: f64 = 3e-5;
const ROTATION_SIGMA: f64 = 3e-4;

/// Exact poses of the nominal robot with Gaussian noise of the assumed σ's added as the
/// residual sees it (`[p_m − p; log(R_m·Rᵀ)]`), unlabelled.
fn noisy_poses(
    robot: &Robot,
    configurations: &[Vec<f64>],
    rng: &mut ChaCha8Rng,
) -> Vec<Measurement> {
    let position = Normal::new(0.0, POSITION_SIGMA).unwrap();
    let rotation = Normal::new(0.0, ROTATION_SIGMA).unwrap();
    let mut measurements = Vec::new();
    for q in configurations {
        for (tool, pose) in robot.nominal.tool_poses(q).iter().enumerate() {
            let dp = Vec3::from_fn(|_, _| position.sample(rng));
            let dr = Vec3::from_fn(|_, _| rotation.sample(rng));
            let mut measured = *pose;
            measured.translation.vector += dp;
            measured.rotation = nalgebra::UnitQuaternion::from_scaled_axis(dr) * pose.rotation;
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: Observation::Pose(measured),
                stage: None,
                session: None,
            });
        }
    }
    measurements
}

fn rigid_simultaneous(
    robot: &Robot,
    measurements: &[Measurement],
) -> treecal::calibration::CalibrationRun {
    let sigmas = [POSITION_SIGMA, ROTATION_SIGMA];
    rigid_simultaneous_run(
        &robot.tree,
        &robot.branches,
        &robot.nominal,
        sigmas,
        measurements,
        &[],
    )
    .unwrap()
}

/// The covariance the identification reports is `σ̂²·(JᵀWJ)⁻¹` at the solution, computed here
/// densely from the model's Jacobian and the residuals (full rank: the data are poses in the
/// root frame), and the standard deviations of `CalibrationRun.parameters` are its diagonal.
#[test]
fn covariance_matches_a_dense_brute_force() {
    let robot = built_in();
    let mut rng = rng(53);
    let q = configurations(&robot, 20, &mut rng);
    let measurements = noisy_poses(&robot, &q, &mut rng);
    let run = rigid_simultaneous(&robot, &measurements);
    let id = &run.report.stages.last().unwrap().identification;
    let model = &run.report.model;
    let n = id.free.len();
    assert_eq!(id.rank, n, "the set-up must be full rank");

    let rows = 6 * measurements.len();
    let mut jacobian = DMatrix::zeros(rows, n);
    let mut residual = nalgebra::DVector::zeros(rows);
    for (i, m) in measurements.iter().enumerate() {
        let tool = model.tool_jacobian(m.tool, &m.q);
        let Observation::Pose(measured) = &m.observation else {
            unreachable!()
        };
        let error = pose_error(measured, &tool.pose);
        for k in 0..6 {
            let weight = 1.0
                / if k < 3 {
                    POSITION_SIGMA
                } else {
                    ROTATION_SIGMA
                };
            residual[6 * i + k] = error[k] * weight;
            for (column, &p) in id.free.iter().enumerate() {
                jacobian[(6 * i + k, column)] = tool.jacobian[(k, p)] * weight;
            }
        }
    }
    let scale_squared = residual.norm_squared() / (rows - n) as f64;
    let information = jacobian.transpose() * &jacobian;
    let expected = information.try_inverse().unwrap() * scale_squared;
    let reported = id.covariance.as_ref().unwrap();
    let mut worst: f64 = 0.0;
    for a in 0..n {
        for b in 0..n {
            let gap = (reported[(a, b)] - expected[(a, b)]).abs()
                / (expected[(a, a)] * expected[(b, b)]).sqrt();
            worst = worst.max(gap);
        }
    }
    eprintln!(
        "covariance: worst relative gap {worst:e}; σ̂ {} (brute force {})",
        id.residual_scale,
        scale_squared.sqrt()
    );
    assert!(worst < 1e-6, "covariance differs by {worst:e} (relative)");

    for (k, &p) in id.free.iter().enumerate() {
        let sd = run.parameters[p].std_dev.unwrap();
        let want = expected[(k, k)].sqrt();
        assert!(
            (sd - want).abs() <= 1e-6 * want,
            "{}: std dev {sd} against {want}",
            run.parameters[p].name
        );
    }
}

/// The predicted standard deviations describe the actual spread: 30 calibrations from the same
/// configurations with fresh noise; the empirical standard deviation of every parameter is
/// within a factor 1.5 of the predicted one (the sampling error of a standard deviation from 30
/// samples is about 13 %).
#[test]
fn standard_deviations_match_a_monte_carlo() {
    const SEEDS: u64 = 30;
    let robot = built_in();
    let q = configurations(&robot, 20, &mut rng(54));
    let runs: Vec<_> = (0..SEEDS)
        .map(|seed| rigid_simultaneous(&robot, &noisy_poses(&robot, &q, &mut rng(1000 + seed))))
        .collect();
    let count = runs[0].parameters.len();
    let mut ratios = Vec::new();
    for p in 0..count {
        let values: Vec<f64> = runs.iter().map(|r| r.parameters[p].calibrated).collect();
        let average = mean(&values);
        let empirical = (values.iter().map(|v| (v - average).powi(2)).sum::<f64>()
            / (values.len() - 1) as f64)
            .sqrt();
        let predicted = mean(
            &runs
                .iter()
                .map(|r| r.parameters[p].std_dev.unwrap())
                .collect::<Vec<_>>(),
        );
        ratios.push((empirical / predicted, runs[0].parameters[p].name.clone()));
    }
    let (low, high) = ratios
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), (r, _)| {
            (l.min(*r), h.max(*r))
        });
    eprintln!(
        "monte carlo: empirical / predicted std dev over {count} parameters: {low:.3} … {high:.3}, mean {:.3}",
        mean(&ratios.iter().map(|r| r.0).collect::<Vec<_>>())
    );
    for (ratio, name) in &ratios {
        assert!(
            (1.0 / 1.5..1.5).contains(ratio),
            "{name}: empirical / predicted std dev = {ratio}"
        );
    }
}

/// `treecal simulate --write-measurements` (one trial: 10 torso + 20 arm configurations, two
/// tools, poses): the measurement file of the CLI tests below.
fn simulated_csv(dir: &Path) -> std::path::PathBuf {
    let csv = dir.join("m.csv");
    let run = treecal(&[
        "simulate",
        "--trials",
        "1",
        "--write-measurements",
        path_str(&csv),
        "--out",
        path_str(&dir.join("simulate")),
    ]);
    assert_success(&run, "simulate");
    csv
}

fn calibrate_into(out: &Path, extra: &[&str]) -> Run {
    let mut args = vec!["calibrate", "--out", path_str(out)];
    args.extend_from_slice(extra);
    treecal(&args)
}

/// Bad input fails with one clear error and leaves `--out` untouched: the command computes
/// everything before it writes anything.
#[test]
fn bad_input_fails_cleanly_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulated_csv(dir.path());
    let m = path_str(&csv);
    let out = dir.path().join("out");
    let check = |extra: &[&str], needles: &[&str], what: &str| {
        let run = calibrate_into(&out, extra);
        assert_error(&run, needles, what);
        assert!(!out.exists(), "{what}: {} was created", out.display());
    };

    let missing = dir.path().join("missing.csv");
    check(
        &["--measurements", path_str(&missing)],
        &["missing.csv"],
        "missing measurements",
    );

    // A bad cell: line 3 (the second data row), column `torso_joint2` (the fifth).
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    assert_eq!(header[4], "torso_joint2");
    let mut cells: Vec<String> = lines[2].split(',').map(str::to_owned).collect();
    cells[4] = "abc".into();
    lines[2] = cells.join(",");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
    check(
        &["--measurements", path_str(&bad)],
        &["bad.csv:3:torso_joint2", "'abc'"],
        "bad cell",
    );

    // Too few configurations to hold out a fifth (and keep some to identify from).
    let few = dir.path().join("few.csv");
    std::fs::write(
        &few,
        text.lines().take(5).collect::<Vec<_>>().join("\n") + "\n",
    )
    .unwrap();
    check(
        &["--measurements", path_str(&few)],
        &["too few to hold out", "--validation"],
        "too few configurations",
    );

    let no_plan = dir.path().join("nonexistent.yaml");
    check(
        &["--measurements", m, "--plan", path_str(&no_plan)],
        &["nonexistent.yaml"],
        "missing plan",
    );
    for sigma in ["--position-sigma", "--rotation-sigma"] {
        check(&["--measurements", m, sigma, "0"], &[sigma], sigma);
    }

    // Fails only in the calibration, after everything was read and the fifth held out.
    let plan = dir.path().join("plan.yaml");
    std::fs::write(
        &plan,
        "stages:\n  - name: all\n    parameters: all\n    measurements: nosuchstage\n",
    )
    .unwrap();
    check(
        &["--measurements", m, "--plan", path_str(&plan)],
        &["nosuchstage"],
        "plan naming no rows",
    );
    // Fails on the validation file, read after the measurements.
    check(
        &["--measurements", m, "--validation", path_str(&bad)],
        &["bad.csv:3:torso_joint2"],
        "bad validation file",
    );
}

/// `treecal export --params out/params.yaml` rebuilds `out/calibrated.urdf` byte for byte.
#[test]
fn export_of_the_parameter_file_reproduces_the_calibrated_urdf() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulated_csv(dir.path());
    let out = dir.path().join("out");
    let run = calibrate_into(
        &out,
        &[
            "--measurements",
            path_str(&csv),
            "--stiffness",
            path_str(&stiffness_path()),
            "--measurement-frame",
            "base",
        ],
    );
    assert_success(&run, "calibrate");
    let exported = dir.path().join("exported.urdf");
    let run = treecal(&[
        "export",
        "--params",
        path_str(&out.join("params.yaml")),
        "-o",
        path_str(&exported),
    ]);
    assert_success(&run, "export");
    let a = std::fs::read(out.join("calibrated.urdf")).unwrap();
    let b = std::fs::read(&exported).unwrap();
    assert!(a == b, "export of params.yaml differs from calibrated.urdf");
}

/// Without `--validation`, a seeded fifth of the configurations is held out: whole
/// configurations (both tools), never torso rows, the same for the same seed; report.json says
/// how many.
#[test]
fn a_seeded_fifth_is_held_out() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulated_csv(dir.path());
    let robot = built_in();
    let set = treecal::io::read_measurements(
        &csv,
        &robot.tree,
        &robot.nominal,
        &treecal::io::MeasurementReadOptions::default(),
    )
    .unwrap();
    let all = set.measurements;
    let arm_configurations = all
        .iter()
        .filter(|m| m.stage.as_deref() == Some("arms"))
        .count()
        / 2;
    assert_eq!(arm_configurations, 20);
    for seed in [0, 1, 7] {
        let (identification, validation) = hold_out(&all, 0.2, seed).unwrap();
        assert_eq!(identification.len() + validation.len(), all.len());
        assert!(validation
            .iter()
            .all(|m| m.stage.as_deref() == Some("arms")));
        let mut held: Vec<&[f64]> = validation.iter().map(|m| m.q.as_slice()).collect();
        held.dedup();
        assert_eq!(held.len(), 4, "seed {seed}: a fifth of 20 configurations");
        for q in &held {
            let tools: Vec<usize> = validation
                .iter()
                .filter(|m| m.q == *q)
                .map(|m| m.tool)
                .collect();
            assert_eq!(tools, [0, 1], "seed {seed}: whole configurations");
            assert!(
                identification.iter().all(|m| m.q != *q),
                "seed {seed}: a held-out configuration is also identified from"
            );
        }
        let again = hold_out(&all, 0.2, seed).unwrap();
        assert_eq!((identification, validation), again, "seed {seed}");
    }
    assert_ne!(
        hold_out(&all, 0.2, 0).unwrap().1,
        hold_out(&all, 0.2, 1).unwrap().1,
        "different seeds hold out different configurations"
    );

    let reports: Vec<String> = ["a", "b"]
        .iter()
        .map(|name| {
            let out = dir.path().join(name);
            // The simulated robot deflects by centimetres: compensated, or the verdict fails.
            let stiffness = stiffness_path();
            let run = calibrate_into(
                &out,
                &[
                    "--measurements",
                    path_str(&csv),
                    "--stiffness",
                    path_str(&stiffness),
                    "--seed",
                    "3",
                ],
            );
            assert_success(&run, "calibrate");
            assert!(
                run.stderr.contains("8 of 60 observations held out"),
                "{run}"
            );
            let report = read_json(&out.join("report.json"));
            assert!(
                report["context"]["validation"]
                    .as_str()
                    .unwrap()
                    .starts_with("8 of 60 observations held out"),
                "{report}"
            );
            for arm in report["validation"].as_array().unwrap() {
                assert_eq!(arm["observations"], 4, "{arm}");
            }
            std::fs::read_to_string(out.join("report.json")).unwrap()
        })
        .collect();
    assert_eq!(reports[0], reports[1], "the same seed, the same report");
}

/// The same round trip with the measurement frame fitted (`--measurement-frame fit`; the
/// default `auto` would see that the data are in the root frame) instead of given: the
/// closed-form fit is off by the geometric errors (centimetres, a degree), which rigid
/// kinematics absorbs but the deflections do not; the joint refinement of the frame brings the
/// calibrated robot, placed in the refined frame, to the noise floor again (without it: about
/// 1.5 mm). Compared in the measurement frame, where the data live.
#[test]
fn round_trip_with_a_fitted_frame_reaches_the_noise_floor() {
    let RoundTrip {
        robot,
        flexibility,
        truth,
        mut rng,
        dir,
    } = round_trip(52, &["--measurement-frame", "fit"]);
    let out = dir.path().join("out");
    let report = read_json(&out.join("report.json"));
    let refinement = &report["frame_refinement"];
    assert!(refinement.is_object(), "no frame refinement: {report}");
    let frame = &report["measurement_frame"];
    let xyz: Vec<f64> = (0..3).map(|i| frame["xyz"][i].as_f64().unwrap()).collect();
    let rpy: Vec<f64> = (0..3).map(|i| frame["rpy"][i].as_f64().unwrap()).collect();
    let world_from_base = Pose::from_parts(
        nalgebra::Translation3::new(xyz[0], xyz[1], xyz[2]),
        treecal::math::rotation_from_rpy(rpy[0], rpy[1], rpy[2]),
    );
    let mut model = robot_at(&out.join("calibrated.urdf"), None).nominal;
    model.set_world_from_base(&world_from_base);
    let placed = flexibility.with_gravity_in_measurement_frame();
    let validation = configurations(&robot, 30, &mut rng);
    let mut position_mm = Vec::new();
    for q in &validation {
        let actual = flexibility
            .deflected_tool_poses(&robot.tree, &truth, q)
            .unwrap();
        let predicted = placed.deflected_tool_poses(&robot.tree, &model, q).unwrap();
        for (a, p) in actual.iter().zip(&predicted) {
            position_mm.push(pose_difference(a, p).0 * 1e3);
        }
    }
    let predicted_rms = report["predicted_validation_rms_mm"].as_f64().unwrap();
    let position = mean(&position_mm);
    eprintln!(
        "fitted-frame round trip: mean {position:.4} mm; predicted RMS {predicted_rms:.4} mm; refinement {refinement}"
    );
    assert!(
        position < 3.0 * predicted_rms && position < 0.15,
        "mean position error {position} mm against a predicted RMS of {predicted_rms} mm"
    );
}

/// Plan files: the staged plan written out reads back as `Plan::staged()`; unknown stage kinds,
/// empty plans and broken YAML are errors naming the file (and line where known).
#[test]
fn plan_files_are_read_and_bad_ones_named() {
    use treecal::calibration::Plan;
    use treecal::io::parse_plan;
    let staged = "stages:\n  - name: torso\n    parameters: coupled\n    measurements: torso\n  - name: arms\n    parameters: arms\n    measurements: arms\n";
    assert_eq!(parse_plan(staged, "p.yaml").unwrap(), Plan::staged());
    let all = "stages:\n  - name: all\n    parameters: all\n";
    assert_eq!(parse_plan(all, "p.yaml").unwrap(), Plan::simultaneous());
    let unknown = "stages:\n  - name: x\n    parameters: everything\n";
    let message = parse_plan(unknown, "p.yaml").unwrap_err().to_string();
    assert!(message.starts_with("p.yaml:"), "{message}");
    assert!(message.contains("everything"), "{message}");
    let empty = "stages: []\n";
    let message = parse_plan(empty, "p.yaml").unwrap_err().to_string();
    assert!(message.contains("no stages"), "{message}");
    let broken = "stages: [\n";
    assert!(parse_plan(broken, "p.yaml")
        .unwrap_err()
        .to_string()
        .starts_with("p.yaml"));
}
