//! How the deflected tool poses change with the MCPC parameters
//! (`FlexibilityModel::deflected_pose_derivatives`): equal bit for bit to shifting each
//! parameter and evaluating the deflected chain again, and close to central differences, on
//! the built-in Robonaut (its stiffness file, a payload) and the shared Robonaut 2.

use crate::common::*;
use rand::RngExt;
use treecal::kinematics::{FlexibilityModel, McpcModel, Stiffness};
use treecal::math::pose_error;
use treecal::tree::KinematicTree;

/// The model with every parameter moved by up to `size` (rad, m), so that the derivatives
/// are not taken at the nominal geometry only.
fn perturbed(model: &McpcModel, size: f64, rng: &mut impl RngExt) -> McpcModel {
    let values: Vec<f64> = model
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-size..size))
        .collect();
    let mut moved = model.clone();
    moved.set_parameters(&values).unwrap();
    moved
}

fn check(tree: &KinematicTree, model: &McpcModel, flexibility: &FlexibilityModel, seed: u64) {
    let mut rng = rng(seed);
    let model = perturbed(model, 1e-3, &mut rng);
    let every: Vec<usize> = (0..model.parameter_count()).collect();
    let step = 1e-7;
    let mut largest = 0.0_f64;
    for _ in 0..3 {
        let q = random_configuration(tree, &mut rng);
        let base = flexibility.deflected_tool_poses(tree, &model, &q).unwrap();
        let columns = flexibility
            .deflected_pose_derivatives(tree, &model, &q, &base, &every, step)
            .unwrap();
        assert_eq!(columns.len(), every.len());
        let values = model.parameters();
        for (p, column) in columns.iter().enumerate() {
            let at = |delta: f64| {
                let mut shifted = model.clone();
                shifted.set_parameter(p, values[p] + delta).unwrap();
                flexibility
                    .deflected_tool_poses(tree, &shifted, &q)
                    .unwrap()
            };
            let forward = at(step);
            let (plus, minus) = (at(1e-5), at(-1e-5));
            for (tool, change) in column.iter().enumerate() {
                // The same arithmetic as shifting the parameter: equal bit for bit.
                assert_eq!(*change, pose_error(&forward[tool], &base[tool]) / step);
                let central = pose_error(&plus[tool], &minus[tool]) / 2e-5;
                let error = (change - central).amax() / (1.0 + central.amax());
                largest = largest.max(error);
                assert!(
                    error < 1e-5,
                    "parameter {p}, tool {tool}: {change} vs {central}"
                );
            }
        }
    }
    assert!(largest.is_finite());
}

#[test]
fn pose_derivatives_on_the_built_in_robonaut_with_a_payload() {
    let (tree, model) = TestRobot::load(&robot("robonaut/robonaut.urdf")).tree_and_model();
    let stiffness =
        treecal::io::read_stiffness(&robot("robonaut/stiffness.yaml"), &tree, &model).unwrap();
    let flexibility = FlexibilityModel::new(&tree, &model, &stiffness).unwrap();
    let loaded = flexibility.for_payload(Some(7.5)).unwrap().into_owned();
    // The deflections are not negligible: centimetres at the tools.
    let q = random_configuration(&tree, &mut rng(3));
    let rigid = model.tool_poses(&q);
    let bent = loaded.deflected_tool_poses(&tree, &model, &q).unwrap();
    let size = pose_error(&bent[0], &rigid[0]).fixed_rows::<3>(0).norm();
    assert!(size > 1e-3, "deflection {size} m");
    check(&tree, &model, &loaded, 11);
}

#[test]
fn pose_derivatives_on_the_shared_robonaut_2() {
    let (tree, model) = TestRobot::load(&robonaut2()).tree_and_model();
    let flexibility = FlexibilityModel::new(&tree, &model, &Stiffness::default()).unwrap();
    check(&tree, &model, &flexibility, 12);
}
