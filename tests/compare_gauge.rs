//! `treecal compare` removes the change of measurement frame before it judges parameters
//! (docs/workflows.md, "Compare"): two calibrations of one simulated Robonaut, each data set in
//! its own tracker frame, list no parameter (the first joint frames no longer carry the two
//! frames' difference, which listed several at many σ before); a 6 mrad tilt of one joint
//! between the two data sets is listed, and the tools moved.

use crate::common::{random_configuration, rng, robot};
use rand::RngExt;
use std::path::{Path, PathBuf};
use treecal::math::{pose, Pose, Vec3};
use treecal::measurement::{Measurement, Observation};
use treecal::sim::{true_model, ErrorRanges};
use treecal::workflow::{
    calibrate, compare, CalibrateConfig, CompareConfig, MeasurementSource, ModelChoice, ModelLevel,
    RobotSource,
};
use treecal::{detect_branches, load_urdf, McpcModel};

/// Tracker noise: position (m) and rotation (rad) standard deviations, as declared.
const NOISE: [f64; 2] = [3e-4, 1e-3];

/// Identification postures per data set (validation: a third of it).
const POSTURES: usize = 36;

/// The tilt of one joint's axis between the two data sets of the drift case (rad).
const TILT: f64 = 0.006;

/// The parameter the drift case tilts.
const TILTED: &str = "left_joint3 alpha";

/// Gaussian noise by Box–Muller (version-stable: only uniform draws).
fn gaussian(rng: &mut rand::rngs::ChaCha8Rng, sigma: f64) -> f64 {
    let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
    sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Robonaut's URDF, tree and nominal model.
fn robonaut() -> (PathBuf, treecal::tree::KinematicTree, McpcModel) {
    let urdf = robot("robonaut/robonaut.urdf");
    let tree = load_urdf(&urdf).unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    let nominal = McpcModel::from_tree(&tree, &branches).unwrap();
    (urdf, tree, nominal)
}

/// Noisy 6-DoF tool poses of `truth` in the tracker frame `world_from_base`.
fn rows(
    tree: &treecal::tree::KinematicTree,
    truth: &McpcModel,
    world_from_base: &Pose,
    count: usize,
    rng: &mut rand::rngs::ChaCha8Rng,
) -> Vec<Measurement> {
    let mut out = Vec::new();
    for _ in 0..count {
        let q = random_configuration(tree, rng);
        for (tool, tool_pose) in truth.tool_poses(&q).iter().enumerate() {
            let measured = world_from_base * tool_pose;
            let position = measured.translation.vector
                + Vec3::new(
                    gaussian(rng, NOISE[0]),
                    gaussian(rng, NOISE[0]),
                    gaussian(rng, NOISE[0]),
                );
            let turn = nalgebra::UnitQuaternion::from_scaled_axis(Vec3::new(
                gaussian(rng, NOISE[1]),
                gaussian(rng, NOISE[1]),
                gaussian(rng, NOISE[1]),
            ));
            out.push(Measurement {
                tool,
                q: q.clone(),
                observation: Observation::Pose(pose(position, turn * measured.rotation)),
                stage: None,
                payload: None,
                session: None,
            });
        }
    }
    out
}

/// One lab's calibration of `truth`, measured in `world_from_base`, written to `out`.
fn calibrated(truth: &McpcModel, world_from_base: Pose, seed: u64, out: &Path) {
    let (urdf, tree, nominal) = robonaut();
    let mut rng = rng(seed);
    let dir = out.parent().unwrap();
    let name = out.file_name().unwrap().to_string_lossy();
    let write = |rows: &[Measurement], file: &str| {
        let path = dir.join(format!("{name}_{file}.csv"));
        let text = treecal::io::measurements_to_csv(&tree, &nominal, rows).unwrap();
        std::fs::write(&path, text).unwrap();
        path
    };
    let training = write(
        &rows(&tree, truth, &world_from_base, POSTURES, &mut rng),
        "training",
    );
    let validation = write(
        &rows(&tree, truth, &world_from_base, POSTURES / 3, &mut rng),
        "validation",
    );
    calibrate(&CalibrateConfig {
        robot: RobotSource::File(urdf),
        measurements: MeasurementSource::Csv(training),
        validation: Some(MeasurementSource::Csv(validation)),
        position_sigma: NOISE[0],
        rotation_sigma: NOISE[1],
        model: ModelChoice::Level(ModelLevel::Geometry),
        ..Default::default()
    })
    .unwrap()
    .write(out)
    .unwrap();
}

/// The true robot: a well-made Robonaut (tenths of a degree, a couple of millimetres off).
fn truth() -> McpcModel {
    let (_, _, nominal) = robonaut();
    let ranges = ErrorRanges {
        angle: 0.004,
        length: 0.002,
    };
    true_model(&nominal, &ranges, &mut rng(5)).unwrap()
}

/// Two trackers metres apart and turned: each data set has its own measurement frame.
fn trackers() -> [Pose; 2] {
    [
        pose(
            Vec3::new(1.9, -0.7, 0.05),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.6),
        ),
        pose(
            Vec3::new(-1.2, 2.4, 0.4),
            nalgebra::UnitQuaternion::from_euler_angles(0.1, -0.2, 2.1),
        ),
    ]
}

/// How many parameters B as calibrated (in its own measurement frame) differs from A by more
/// than 3 combined σ: what compare listed before it re-expressed B.
fn listed_as_calibrated(a: &Path, b: &Path) -> usize {
    let parameters = |dir: &Path| {
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
        report["parameters"].as_array().unwrap().clone()
    };
    let (pa, pb) = (parameters(a), parameters(b));
    pa.iter()
        .zip(&pb)
        .filter(|(x, y)| {
            assert_eq!(x["name"], y["name"]);
            let (Some(sa), Some(sb)) = (x["std_dev"].as_f64(), y["std_dev"].as_f64()) else {
                return false;
            };
            let change = y["calibrated"].as_f64().unwrap() - x["calibrated"].as_f64().unwrap();
            change.abs() > 3.0 * sa.hypot(sb)
        })
        .count()
}

#[test]
fn compare_lists_no_parameter_for_two_measurement_frames_and_the_tilted_joint_for_a_drift() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, drifted) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("drifted"),
    );
    let truth = truth();
    let [first, second] = trackers();
    calibrated(&truth, first, 11, &a);
    calibrated(&truth, second, 12, &b);
    let (_, tree, _) = robonaut();
    let mut tilted = truth.clone();
    let index = (0..tilted.parameter_count())
        .find(|&p| tilted.parameter_name(&tree, p) == TILTED)
        .unwrap();
    tilted
        .set_parameter(index, truth.parameters()[index] + TILT)
        .unwrap();
    calibrated(&tilted, second, 13, &drifted);
    let run = |b: &Path| {
        compare(&CompareConfig {
            a: a.clone(),
            b: b.to_owned(),
            k: 3.0,
        })
        .unwrap()
    };

    // The same robot: before, the first joint frames differed by the change of frame.
    let before = listed_as_calibrated(&a, &b);
    let same = run(&b);
    let r = &same.report;
    let frame = r.frame_change.as_ref().unwrap();
    eprintln!(
        "same robot: {before} listed as calibrated, {} re-expressed {:?}; frame change {frame:?}",
        r.moved.len(),
        r.moved
            .iter()
            .map(|m| (&m.name, m.sigmas))
            .collect::<Vec<_>>()
    );
    assert!(before >= 2, "{before}: the scenario shows no false alarm");
    assert!(r.moved.len() <= 1, "{:#?}", r.moved);
    assert!(frame.residual_mm < 1e-6, "{frame:?}");
    assert_eq!(frame.parameters, r.parameters_judged, "{frame:?}");
    assert!(
        same.markdown.contains("did not move beyond the noise"),
        "{}",
        same.markdown
    );
    assert!(same
        .markdown
        .contains("B is re-expressed in A's measurement frame"));

    // A drift: the tilted joint is listed first, and the tools moved.
    let drift = run(&drifted);
    let r = &drift.report;
    eprintln!(
        "drift: {} listed as calibrated, {} re-expressed {:?}",
        listed_as_calibrated(&a, &drifted),
        r.moved.len(),
        r.moved
            .iter()
            .map(|m| (&m.name, m.sigmas))
            .collect::<Vec<_>>()
    );
    assert_eq!(r.moved.first().map(|m| m.name.as_str()), Some(TILTED));
    let change = r.moved[0].change;
    assert!((change - TILT).abs() < 0.2 * TILT, "{change}");
    assert!(
        drift.markdown.contains("**The tools moved:**"),
        "{}",
        drift.markdown
    );
}
