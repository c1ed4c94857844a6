//! Issue 31's "Done means": a humanoid standing on its left sole (NAO V5 from
//! `../shared/robots/`), perturbed into a true robot (the paper's ±0.05 rad / ±5 cm on every
//! MCPC parameter, legs and neck included), tracked at both grippers, the head and the other
//! sole in a tracker frame fixed to the floor (full poses in mm, 15 µm and 0.15 mrad noise),
//! calibrated through the CLI with `--reference-link l_sole` and otherwise default flags. The
//! truth's poses come from the URDF forward kinematics of the exported true URDF (independent
//! of the MCPC model; held to Pinocchio's by tests/oracle.rs).

use crate::common::cli::*;
use crate::common::*;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::path::{Path, PathBuf};
use treecal::io::{measurements_to_csv_with, AngleUnit, LengthUnit, MeasurementWriteOptions};
use treecal::math::{pose, rotation_from_rpy, Pose, Vec3};
use treecal::measurement::{Measurement, Observation};
use treecal::sim::{true_model, ErrorRanges};
use treecal::tree::{detect_branches_from, KinematicTree};
use treecal::urdf::export_urdf;
use treecal::{load_urdf, McpcModel};

const POSITION_NOISE: f64 = 15e-6;
const ROTATION_NOISE: f64 = 1.5e-4;
const CONFIGURATIONS: usize = 60;
const FRESH: usize = 20;
const REFERENCE: &str = "l_sole";
/// Links on fixed joints (a probe is mounted; a URDF joint origin cannot hold a tool's offset
/// off a movable joint's axis): the backs of the hands, the gaze frame of the head, the sole.
const TOOLS: [&str; 4] = [
    "LHandTouchBack_frame",
    "RHandTouchBack_frame",
    "gaze",
    "r_sole",
];

fn nao() -> PathBuf {
    let relative = "robots/nao/nao.urdf";
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(dir) = std::env::var_os("TREECAL_SHARED_DIR") {
        candidates.push(PathBuf::from(dir).join(relative));
    }
    candidates.push(repo().join("../shared").join(relative));
    candidates.push(PathBuf::from("/work/shared").join(relative));
    match candidates.iter().find(|c| c.is_file()) {
        Some(found) => found.clone(),
        None => panic!("{relative} was not found at any of {candidates:?}; set TREECAL_SHARED_DIR"),
    }
}

/// Each tool's pose relative to the reference link, from the URDF's forward kinematics.
fn relative_poses(tree: &KinematicTree, q: &[f64]) -> Vec<Pose> {
    let pose_of = |name: &str| tree.link_pose(tree.link_id(name).unwrap(), q).unwrap();
    let reference = pose_of(REFERENCE);
    TOOLS
        .iter()
        .map(|t| reference.inverse() * pose_of(t))
        .collect()
}

fn observe(pose: &Pose, rng: &mut ChaCha8Rng) -> Pose {
    let position = Normal::new(0.0, POSITION_NOISE).unwrap();
    let rotation = Normal::new(0.0, ROTATION_NOISE).unwrap();
    let mut draw = |d: &Normal<f64>| Vec3::new(d.sample(rng), d.sample(rng), d.sample(rng));
    let dt = draw(&position);
    let dr = draw(&rotation);
    Pose::from_parts(
        (pose.translation.vector + dt).into(),
        nalgebra::UnitQuaternion::from_scaled_axis(dr) * pose.rotation,
    )
}

/// Mean position (mm) and orientation (deg) error of `calibrated`'s relative forward
/// kinematics against the truth's at `fresh`, per tool.
fn errors(calibrated: &Path, truth: &KinematicTree, fresh: &[Vec<f64>]) -> Vec<(f64, f64)> {
    let tree = load_urdf(calibrated).unwrap_or_else(|e| panic!("{e}")).tree;
    let mut sums = vec![(0.0, 0.0); TOOLS.len()];
    for q in fresh {
        let predicted = relative_poses(&tree, q);
        for (tool, actual) in relative_poses(truth, q).iter().enumerate() {
            let (dp, dr) = pose_difference(actual, &predicted[tool]);
            sums[tool].0 += dp * 1e3 / fresh.len() as f64;
            sums[tool].1 += dr.to_degrees() / fresh.len() as f64;
        }
    }
    sums
}

#[test]
fn a_humanoid_calibrates_from_its_sole() {
    let path = nao();
    let original = std::fs::read_to_string(&path).unwrap();
    let tree = load_urdf(&path).unwrap().tree;
    let tools: Vec<_> = TOOLS.iter().map(|t| tree.link_id(t).unwrap()).collect();
    let reference = tree.link_id(REFERENCE).unwrap();
    let branches = detect_branches_from(&tree, Some(&tools), reference).unwrap();
    let nominal = McpcModel::from_tree(&tree, &branches).unwrap();
    let truth = true_model(&nominal, &ErrorRanges::default(), &mut rng(310)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let true_urdf = dir.path().join("true.urdf");
    std::fs::write(
        &true_urdf,
        export_urdf(&original, "nao.urdf", &tree, &truth)
            .unwrap()
            .urdf,
    )
    .unwrap();
    let true_tree = load_urdf(&true_urdf).unwrap().tree;

    // A tracker on the floor, 2 m away and turned.
    let world_from_reference = pose(
        Vec3::new(2.0, -0.8, 0.4),
        rotation_from_rpy(0.1, -0.05, 2.4),
    );
    let mut rng = rng(311);
    let mut measurements = Vec::new();
    for _ in 0..CONFIGURATIONS {
        let q = random_configuration(&tree, &mut rng);
        for (tool, relative) in relative_poses(&true_tree, &q).iter().enumerate() {
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: Observation::Pose(observe(
                    &(world_from_reference * relative),
                    &mut rng,
                )),
                stage: None,
                session: None,
            });
        }
    }
    let fresh: Vec<Vec<f64>> = (0..FRESH)
        .map(|_| random_configuration(&tree, &mut rng))
        .collect();
    let options = MeasurementWriteOptions {
        length_unit: LengthUnit::Millimetre,
        angle_unit: AngleUnit::Radian,
        three_targets: false,
    };
    let csv = dir.path().join("sole.csv");
    std::fs::write(
        &csv,
        measurements_to_csv_with(&tree, &nominal, &measurements, &options).unwrap(),
    )
    .unwrap();

    let out = dir.path().join("out");
    let run = treecal(&[
        "calibrate",
        "--robot",
        path_str(&path),
        "--measurements",
        path_str(&csv),
        "--reference-link",
        REFERENCE,
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate from the sole");
    assert!(run.stderr.contains("reference link 'l_sole'"), "{run}");
    for role in [
        "coupled 'coupled' (6 joints)",
        "head 'gaze'",
        "leg 'r_sole'",
        "arm 'LHandTouchBack_frame'",
    ] {
        assert!(run.stderr.contains(role), "{role}\n{run}");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["verdict"]["status"], "ok", "{run}");
    let mut table = Vec::new();
    for entry in report["validation"].as_array().unwrap() {
        let mean = entry["after"]["mean_position_mm"].as_f64().unwrap();
        table.push(format!("{} {mean:.4} mm", entry["tool"]));
        assert!(
            mean <= 0.05,
            "validation of {}: {mean} mm\n{run}",
            entry["tool"]
        );
    }
    assert_eq!(table.len(), TOOLS.len());
    // Legs and neck are in Table 2.
    let markdown = std::fs::read_to_string(out.join("report.md")).unwrap();
    for joint in [
        "LAnkleRoll",
        "LHipYawPitch",
        "RKneePitch",
        "HeadYaw",
        "HeadPitch",
    ] {
        assert!(markdown.contains(joint), "{joint} missing from report.md");
    }
    // The exported URDF keeps the original root and reproduces the truth relative to the sole.
    let calibrated = out.join("calibrated.urdf");
    let exported = load_urdf(&calibrated).unwrap().tree;
    assert_eq!(
        exported.link(exported.root()).name,
        tree.link(tree.root()).name
    );
    let fresh_errors = errors(&calibrated, &true_tree, &fresh);
    for (tool, (position, orientation)) in TOOLS.iter().zip(&fresh_errors) {
        table.push(format!("fresh {tool}: {position:.4} mm {orientation:.5}°"));
        assert!(
            *position <= 0.05,
            "{tool}: {position} mm at fresh configurations"
        );
        assert!(
            *orientation <= 3.0 * ROTATION_NOISE.to_degrees(),
            "{tool}: {orientation}°"
        );
    }
    // `export` rebuilds the same model from params.yaml when told the reference link.
    let exported = dir.path().join("exported.urdf");
    let run = treecal(&[
        "export",
        "--robot",
        path_str(&path),
        "--params",
        path_str(&out.join("params.yaml")),
        "--tools",
        &TOOLS.join(","),
        "--reference-link",
        REFERENCE,
        "--out",
        path_str(&exported),
    ]);
    assert_success(&run, "export from the sole");
    for (tool, (position, _)) in TOOLS.iter().zip(errors(&exported, &true_tree, &fresh)) {
        assert!(position <= 0.05, "export: {tool}: {position} mm");
    }
    // Stiffness identification from a sole is refused with what to do.
    let run = treecal(&[
        "calibrate",
        "--robot",
        path_str(&path),
        "--measurements",
        path_str(&csv),
        "--reference-link",
        REFERENCE,
        "--identify-stiffness",
        "--out",
        path_str(&dir.path().join("stiff")),
    ]);
    assert!(!run.success, "{run}");
    assert!(
        run.stderr.contains("needs the URDF root") && run.stderr.contains("--stiffness"),
        "{run}"
    );
    eprintln!("NAO from its left sole:\n{}", table.join("\n"));
}

/// Stiffness of robots/humanoid for the simulated truth: the paper's 5000 N·m/rad joints.
const HUMANOID_STIFFNESS: &str = "gravity_m_per_s2: [0, 0, -9.81]
self_weight: true
joints:
  default: {bending_nm_per_rad: 5000, torsion_nm_per_rad: 5000}
links:
  default: {ea_n: 4.420e7, ei_y_nm2: 2.485e4, ei_z_nm2: 2.485e4, gi_p_nm2: 1.846e4}
";

/// The same humanoid a million times stiffer: rigid for every purpose (`simulate` needs a
/// stiffness file).
const RIGID_HUMANOID_STIFFNESS: &str = "gravity_m_per_s2: [0, 0, -9.81]
self_weight: true
joints:
  default: {bending_nm_per_rad: 5e9, torsion_nm_per_rad: 5e9}
links:
  default: {ea_n: 4.420e13, ei_y_nm2: 2.485e10, ei_z_nm2: 2.485e10, gi_p_nm2: 1.846e10}
";

/// `simulate`, `check` and `plan` on the repository's humanoid standing on its left foot,
/// with tools on both hands, the head and the right foot: a rigid truth (the staged plan)
/// is recovered to the tracker's noise floor.
#[test]
fn simulate_check_and_plan_from_a_foot() {
    simulate_check_and_plan(RIGID_HUMANOID_STIFFNESS, 0.1);
}

/// The same with the paper's compliant joints: the compensated fit from the foot is not at the
/// noise floor yet (0.8–1.5 mm staged, 0.09–0.16 mm simultaneous; from the root 0.02–0.04 mm).
/// The deflection model is not invariant under the root's gauge freedom: the root link's mass
/// and the loads it passes on are placed by the six root-side parameters kept at their URDF
/// values, which the truth perturbs (docs/mcpc.md, "Reference link").
#[test]
#[ignore = "issue 31, not done: compensated fit from a foot 0.8–1.5 mm (the flexibility model depends on the root's gauge)"]
fn simulate_from_a_foot_with_compliant_joints() {
    simulate_check_and_plan(HUMANOID_STIFFNESS, 0.1);
}

fn simulate_check_and_plan(stiffness_yaml: &str, limit_mm: f64) {
    use treecal::workflow::{check, CheckConfig};
    use treecal::workflow::{plan, PlanConfig};
    use treecal::workflow::{simulate, SimulateConfig};
    use treecal::workflow::{RobotSource, StiffnessSource};
    let dir = tempfile::tempdir().unwrap();
    let stiffness = dir.path().join("stiffness.yaml");
    std::fs::write(&stiffness, stiffness_yaml).unwrap();
    let humanoid = RobotSource::File(robot("humanoid/humanoid.urdf"));
    let tools: Vec<String> = ["l_hand", "r_hand", "head", "r_foot"]
        .map(str::to_owned)
        .to_vec();
    let reference = Some("l_foot".to_owned());
    let outcome = simulate(&SimulateConfig {
        robot: humanoid.clone(),
        stiffness: Some(StiffnessSource::File(stiffness)),
        tools: Some(tools.clone()),
        reference_link: reference.clone(),
        poses: 40,
        torso_poses: 16,
        validation_poses: 10,
        trials: 1,
        seed: 31,
        ..SimulateConfig::default()
    })
    .unwrap();
    assert!(
        outcome
            .notes
            .iter()
            .any(|n| n.to_string().contains("reference link 'l_foot'")),
        "{:?}",
        outcome.notes
    );
    let mut table = Vec::new();
    for arm in &outcome.summary.validation {
        let [rigid, compensated] = &arm.after_position_mm;
        table.push(format!(
            "{}: before {:.3} mm, after {:.4} (rigid {:.4}) mm",
            arm.arm, arm.before_position_mm.mean, compensated.mean, rigid.mean
        ));
        // The simulated tracker's noise floor is about 0.04 mm (docs/simulation.md).
        assert!(
            compensated.mean < limit_mm,
            "{}: {} mm after compensation\n{}",
            arm.arm,
            compensated.mean,
            outcome.markdown
        );
    }
    assert_eq!(table.len(), 4);
    eprintln!("humanoid from its left foot:\n{}", table.join("\n"));
    // The simulate report has no parameter table: the notes name the branches (legs and
    // neck calibrated) and the support leg's joints crossed from the foot.
    let notes: Vec<String> = outcome.notes.iter().map(|n| n.to_string()).collect();
    for expected in [
        "coupled 'coupled' (6 joints)",
        "head 'head'",
        "leg 'r_foot' (6 joints)",
        "l_ankle_roll",
        "l_hip_yaw",
    ] {
        assert!(
            notes.iter().any(|n| n.contains(expected)),
            "{expected}\n{notes:?}"
        );
    }

    let checked = check(&CheckConfig {
        robot: humanoid.clone(),
        tools: Some(tools.clone()),
        reference_link: reference.clone(),
        ..CheckConfig::default()
    })
    .unwrap();
    assert!(
        checked
            .notes
            .iter()
            .any(|n| n.text.contains("reference link 'l_foot'")),
        "{:?}",
        checked.notes
    );
    assert!(checked.report.well_conditioned, "{}", checked.text);
    let planned = plan(&PlanConfig {
        robot: humanoid,
        tools: Some(tools),
        reference_link: reference,
        poses: 12,
        candidates: 40,
        ..PlanConfig::default()
    })
    .unwrap();
    assert!(planned
        .notes
        .iter()
        .any(|n| n.to_string().contains("l_foot")));
}
