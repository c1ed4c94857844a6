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
