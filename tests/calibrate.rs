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
use treecal::calibration::{
    fit_rigid_transform, hold_out, run_calibration, CalibrationInput, IdentificationOptions, Plan,
};
use treecal::io::{
    measurements_to_csv, measurements_to_csv_with, read_stiffness, AngleUnit, LengthUnit,
    MeasurementWriteOptions,
};
use treecal::kinematics::FlexibilityModel;
use treecal::math::{pose_error, Pose, Vec3};
use treecal::measurement::{Measurement, Observation};
use treecal::sim::noise::{observe, NoiseModel, Targets};
use treecal::sim::sampling::{sample_configurations, SamplingOptions};
use treecal::sim::truth::{true_model, ErrorRanges};
use treecal::{detect_branches, load_urdf, Branches, KinematicTree, McpcModel};

/// A robot with its branches and nominal model.
struct Robot {
    tree: KinematicTree,
    branches: Branches,
    nominal: McpcModel,
}

fn robot_at(path: &Path, tools: Option<&[&str]>) -> Robot {
    let tree = load_urdf(path).unwrap_or_else(|e| panic!("{e}")).tree;
    let tools = tools.map(|names| {
        names
            .iter()
            .map(|n| tree.link_id(n).unwrap())
            .collect::<Vec<_>>()
    });
    let branches = detect_branches(&tree, tools.as_deref()).unwrap();
    let nominal = McpcModel::from_tree(&tree, &branches).unwrap();
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
                    tool,
                    q: q.clone(),
                    observation: observe(pose, Targets::Three, &self.noise, rng),
                    stage: stage.map(str::to_owned),
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

/// Item 4 of issue 5: simulated measurements of the built-in Robonaut (paper errors ±0.05 rad /
/// ±5 cm, AT901 noise, gravity deflection) calibrated by the CLI with exact compensation; the
/// exported URDF plus the deflection the calibration models predicts the truth's deflected tool
/// poses at fresh configurations to within the noise.
///
/// "Within the noise": the mean position error is below 3× the RMS error that the parameter
/// covariance predicts at the held-out configurations (`predicted_validation_rms_mm`, about
/// 0.05 mm; `treecal simulate` reports 0.044 mm for its set-up) and below 0.15 mm absolute; the
/// mean orientation error below 3× the orientation noise of a three-target frame
/// (√2·σ/0.1 m ≈ 0.027° for σ ≈ 33 µm). With `--measurement-frame fit` instead, the fitted frame
/// absorbs geometric error the flexibility model cannot, leaving about 1.5 mm (a known
/// limitation), so the data are given in the root frame, as `simulate` writes them.
#[test]
fn round_trip_reaches_the_noise_floor() {
    let robot = built_in();
    let flexibility = built_in_flexibility(&robot);
    let mut rng = rng(51);
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
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--stiffness",
        path_str(&stiffness_path()),
        "--measurement-frame",
        "base",
        "--position-sigma",
        "3.3e-5",
        "--rotation-sigma",
        "4.7e-4",
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate");

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
