//! Joint-angle errors (offsets, harmonics, backlash) and the measurement frame as parameters:
//! analytic Jacobian columns against central finite differences, the offsets folded into the
//! geometry, and the gravity-torque signs of the backlash.

use crate::common::*;
use rand::RngExt;
use treecal::kinematics::{GravitySigns, JointErrorTerms, McpcModel};
use treecal::math::pose_error;
use treecal::tree::detect_branches;

const ALL: JointErrorTerms = JointErrorTerms {
    offsets: true,
    harmonics: true,
    backlash: true,
};

/// Every robot in `robots/` with every joint-error term and the frame parameters, all
/// perturbed.
fn extended_models() -> Vec<(treecal::tree::KinematicTree, McpcModel)> {
    let mut rng = rng(5);
    all_repo_robots()
        .into_iter()
        .map(|path| {
            let tree = treecal::load_urdf(&path).unwrap().tree;
            let branches = detect_branches(&tree, None).unwrap();
            let nominal = McpcModel::from_tree(&tree, &branches).unwrap();
            let gravity = GravitySigns::new(&tree, &nominal).unwrap();
            let mut model = nominal
                .with_joint_errors(ALL, Some(gravity))
                .unwrap()
                .with_frame_parameters();
            let values: Vec<f64> = model
                .parameters()
                .iter()
                .map(|v| v + rng.random_range(-0.03..0.03))
                .collect();
            model.set_parameters(&values).unwrap();
            (tree, model)
        })
        .collect()
}

#[test]
fn joint_error_and_frame_columns_match_finite_differences() {
    let step = 1e-6;
    for (tree, model) in extended_models() {
        let mut rng = rng(8);
        let base = model.frames().len() * 4 + 6 * model.tools().len();
        assert!(model.parameter_count() > base, "{}", tree.name());
        for _ in 0..4 {
            let q = random_configuration(&tree, &mut rng);
            let analytic = model.tool_jacobians(&q);
            let parameters = model.parameters();
            let mut perturbed = model.clone();
            for index in 0..parameters.len() {
                let mut plus = parameters.clone();
                plus[index] += step;
                perturbed.set_parameters(&plus).unwrap();
                let up = perturbed.tool_poses(&q);
                let mut minus = parameters.clone();
                minus[index] -= step;
                perturbed.set_parameters(&minus).unwrap();
                let down = perturbed.tool_poses(&q);
                for (tool, jacobian) in analytic.iter().enumerate() {
                    let numeric = pose_error(&up[tool], &down[tool]) / (2.0 * step);
                    let column = jacobian.jacobian.column(index);
                    let error = (numeric - column).norm();
                    assert!(
                        error <= 1e-6 * column.norm().max(1.0),
                        "{}: tool {tool}, {}: analytic {column:?} numeric {numeric:?}",
                        tree.name(),
                        model.parameter_name(&tree, index)
                    );
                }
            }
            for (tool, jacobian) in analytic.iter().enumerate() {
                assert_pose_eq(&jacobian.pose, &model.tool_pose(tool, &q), 1e-12, "pose");
                assert_eq!(model.tool_jacobian(tool, &q).jacobian, jacobian.jacobian);
            }
        }
    }
}

#[test]
fn offsets_fold_into_the_geometry_without_changing_forward_kinematics() {
    for (tree, model) in extended_models() {
        let absorbed = model.with_offsets_absorbed();
        for frame in 0..model.frames().len() {
            assert_eq!(absorbed.joint_error_values(frame)[0].unwrap_or(0.0), 0.0);
        }
        let mut rng = rng(3);
        for _ in 0..5 {
            let q = random_configuration(&tree, &mut rng);
            for (a, b) in model.tool_poses(&q).iter().zip(absorbed.tool_poses(&q)) {
                assert_pose_eq(a, &b, 1e-9, tree.name());
            }
            for (a, b) in model.link_poses(&q).iter().zip(absorbed.link_poses(&q)) {
                assert_pose_eq(a, &b, 1e-9, tree.name());
            }
        }
    }
}

/// The backlash sign follows the gravity torque: the torque is minus the derivative of the
/// potential energy of the links the joint carries.
#[test]
fn gravity_torques_are_the_derivative_of_the_potential_energy() {
    let path = robot("humanoid/humanoid.urdf");
    let tree = treecal::load_urdf(&path).unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    let gravity = GravitySigns::new(&tree, &model).unwrap();
    let potential = |q: &[f64]| -> f64 {
        let poses = tree.link_poses(q).unwrap();
        tree.links()
            .iter()
            .zip(&poses)
            .filter_map(|(link, pose)| {
                let i = link.inertial.as_ref()?;
                let com = pose * nalgebra::Point3::from(i.center_of_mass());
                Some(i.mass * 9.80665 * com.z)
            })
            .sum()
    };
    let mut rng = rng(4);
    for _ in 0..5 {
        let q = random_configuration(&tree, &mut rng);
        let torques = gravity.torques(&q).unwrap();
        let signs = gravity.signs(&q);
        for (frame, f) in model.frames().iter().enumerate() {
            let Some(dof) = tree.dof_of(f.joint) else {
                continue;
            };
            let step = 1e-6;
            let mut up = q.clone();
            up[dof.0] += step;
            let mut down = q.clone();
            down[dof.0] -= step;
            let expected = -(potential(&up) - potential(&down)) / (2.0 * step);
            assert!(
                (torques[frame] - expected).abs() < 1e-5 * expected.abs().max(1.0),
                "{}: {} vs {expected}",
                tree.joint(f.joint).name,
                torques[frame]
            );
            if expected.abs() > 1e-6 {
                assert_eq!(signs[frame], expected.signum());
            }
        }
    }
}

#[test]
fn backlash_without_inertials_is_refused_with_the_joint_named() {
    let path = robot("humanoid/humanoid.urdf");
    let text = std::fs::read_to_string(&path).unwrap();
    let stripped = regex_free_strip(&text);
    let tree = treecal::parse_urdf(&stripped, "stripped").unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    let error = GravitySigns::new(&tree, &model).unwrap_err().to_string();
    assert!(error.contains("carries no link with a mass"), "{error}");
}

/// The URDF text without its `<inertial>` elements.
fn regex_free_strip(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(start) = rest.find("<inertial>") {
        out.push_str(&rest[..start]);
        let end = rest[start..].find("</inertial>").unwrap() + start + "</inertial>".len();
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// Issue 28 item 3 with joint-angle errors: a robot whose joints turn by harmonic errors. The
/// URDF cannot carry them, so joint_errors.yaml goes with it; the URDF plus the written file is
/// scored as written (and again here, from the texts alone) and reproduces the in-memory
/// validation figure; the URDF alone is never worse than the registered nominal robot: here
/// (postures near one pose) the calibrated geometry alone would be, so calibrated.urdf holds
/// the rigid-only geometry.
#[test]
fn joint_errors_yaml_with_the_urdf_is_what_was_validated() {
    use rand_distr::{Distribution, Normal};
    use treecal::io::{measurements_to_csv_with, AngleUnit, LengthUnit, MeasurementWriteOptions};
    use treecal::math::Pose;
    use treecal::measurement::{Measurement, Observation};
    use treecal::sim::{with_joint_errors, JointErrorRanges};
    use treecal::workflow::{
        calibrate, CalibrateConfig, MeasurementFrameChoice, MeasurementSource, RobotSource,
    };
    let path = robot("robonaut/robonaut.urdf");
    let tree = treecal::load_urdf(&path).unwrap().tree;
    let branches = branches_with_tools(&tree, None);
    let nominal = McpcModel::from_tree(&tree, &branches).unwrap();
    let mut rng = rng(2807);
    let ranges = JointErrorRanges {
        harmonics: 0.004,
        ..Default::default()
    };
    let truth = with_joint_errors(&nominal, &tree, &ranges, &mut rng).unwrap();
    let noise = Normal::new(0.0, 2e-5).unwrap();
    let tilt = Normal::new(0.0, 2e-4).unwrap();
    let mut measure = |count: usize| -> Vec<Measurement> {
        let mut out = Vec::new();
        for _ in 0..count {
            // Postures near one pose (as a lab's often are): sin q ≈ q and cos q ≈ 1 alias
            // with the geometry, so the fit splits them between the URDF and the file.
            let q: Vec<f64> = random_configuration(&tree, &mut rng)
                .iter()
                .map(|v| 0.5 + 0.15 * v)
                .collect();
            for (tool, pose) in truth.tool_poses(&q).iter().enumerate() {
                let d = nalgebra::Vector3::new(
                    noise.sample(&mut rng),
                    noise.sample(&mut rng),
                    noise.sample(&mut rng),
                );
                let r = nalgebra::Vector3::new(
                    tilt.sample(&mut rng),
                    tilt.sample(&mut rng),
                    tilt.sample(&mut rng),
                );
                out.push(Measurement {
                    payload: None,
                    tool,
                    q: q.clone(),
                    observation: Observation::Pose(Pose::from_parts(
                        (pose.translation.vector + d).into(),
                        nalgebra::UnitQuaternion::from_scaled_axis(r) * pose.rotation,
                    )),
                    stage: None,
                    session: None,
                });
            }
        }
        out
    };
    let (data, validation) = (measure(40), measure(15));
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, rows: &[Measurement]| {
        let options = MeasurementWriteOptions {
            length_unit: LengthUnit::Millimetre,
            angle_unit: AngleUnit::Radian,
            three_targets: false,
        };
        let text = measurements_to_csv_with(&tree, &nominal, rows, &options).unwrap();
        let file = dir.path().join(name);
        std::fs::write(&file, text).unwrap();
        MeasurementSource::Csv(file)
    };
    let config = CalibrateConfig {
        robot: RobotSource::File(path.clone()),
        measurements: write("data.csv", &data),
        validation: Some(write("validation.csv", &validation)),
        measurement_frame: MeasurementFrameChoice::Base,
        harmonics: true,
        position_sigma: 2e-5,
        rotation_sigma: 2e-4,
        ..CalibrateConfig::default()
    };
    let outcome = calibrate(&config).unwrap_or_else(|e| panic!("{e}"));
    let report = outcome.report();
    let artifact = &report["artifact"];
    let rms = |key: &str| artifact[key]["errors"]["rms_position_mm"].as_f64().unwrap();
    let (alone, paired, before) = (
        rms("urdf_alone"),
        rms("with_compensation"),
        rms("registered_nominal"),
    );
    let codes: Vec<&str> = outcome
        .verdict
        .reasons
        .iter()
        .map(|r| r.code.as_str())
        .collect();
    assert!(!codes.contains(&"urdf-alone-worse"), "{codes:?}");
    assert!(alone <= before, "{alone} vs {before}");
    // Here the calibrated geometry alone would be worse: calibrated.urdf is the rigid-only fit.
    assert!(codes.contains(&"rigid-only-urdf"), "{codes:?}");
    let in_memory = report["validation_strata"]["strata"][0]["rms_position_mm"]
        .as_f64()
        .unwrap();
    assert!(
        (in_memory - paired).abs() < 1e-6 * paired,
        "{in_memory} vs {paired}"
    );
    assert!(
        paired < 0.1,
        "{paired} mm: the harmonics were not recovered"
    );
    let file = |name: &str| {
        outcome
            .files
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, b)| String::from_utf8(b.clone()).unwrap())
    };
    let pair_urdf = "calibrated_compensated.urdf";
    assert_eq!(
        artifact["with_compensation"]["files"].as_str().unwrap(),
        format!("{pair_urdf} + joint_errors.yaml")
    );
    // Again from the texts alone: the URDF's links at q + sine·sin q + cosine·cos q.
    let urdf = treecal::urdf::parse_urdf(&file(pair_urdf).unwrap(), pair_urdf)
        .unwrap()
        .tree;
    let yaml = file("joint_errors.yaml").unwrap();
    let mut terms = std::collections::HashMap::new();
    for line in yaml
        .lines()
        .filter(|l| l.starts_with("  ") && l.contains('{'))
    {
        let (name, rest) = line.trim().split_once(':').unwrap();
        let mut t = [0.0; 2];
        for part in rest
            .trim()
            .trim_matches(|c| c == '{' || c == '}')
            .split(',')
        {
            let (k, v) = part.split_once(':').unwrap();
            let v: f64 = v.trim().parse().unwrap();
            match k.trim() {
                "sine" => t[0] = v,
                "cosine" => t[1] = v,
                other => panic!("unexpected term {other}"),
            }
        }
        terms.insert(name.to_string(), t);
    }
    assert!(!terms.is_empty());
    let sum: f64 = validation
        .iter()
        .map(|m| {
            let q: Vec<f64> = urdf
                .dofs()
                .iter()
                .map(|&j| {
                    let name = &urdf.joint(j).name;
                    let i = tree
                        .dofs()
                        .iter()
                        .position(|&k| &tree.joint(k).name == name)
                        .unwrap();
                    let [s, c] = terms.get(name).copied().unwrap_or([0.0; 2]);
                    m.q[i] + s * m.q[i].sin() + c * m.q[i].cos()
                })
                .collect();
            let link = urdf
                .link_id(&tree.link(nominal.tools()[m.tool].link).name)
                .unwrap();
            let p = (Pose::identity() * urdf.link_pose(link, &q).unwrap())
                .translation
                .vector;
            let Observation::Pose(measured) = &m.observation else {
                unreachable!()
            };
            (measured.translation.vector - p).norm_squared()
        })
        .sum();
    let again = (sum / validation.len() as f64).sqrt() * 1e3;
    assert!(
        (again - paired).abs() < 1e-6 * paired,
        "{again} vs {paired}"
    );
}
