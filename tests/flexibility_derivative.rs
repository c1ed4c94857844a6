//! How the deflected tool poses change with the MCPC parameters
//! (`FlexibilityModel::deflected_pose_derivatives`, analytic): equal to the forward
//! difference of the loads it replaced to 1e-6 relative (measured ≤ 2.2e-7), and to central
//! differences of the deflected tool poses to 1e-8 relative (measured ≤ 1.1e-9; with a
//! reference link, where the whole chain is differenced, 1e-6), at random geometries and
//! configurations, on the built-in Robonaut (its stiffness file, a payload; joint and link
//! compliance, and joint compliance alone) and the shared Robonaut 2.

use crate::common::*;
use rand::RngExt;
use treecal::kinematics::{ComplianceBasis, FlexibilityModel, McpcModel, Stiffness};
use treecal::math::pose_error;
use treecal::tree::KinematicTree;

/// The model with every parameter moved by up to `size` (rad, m), so that the derivatives
/// are not taken at the nominal geometry only.
fn perturbed(model: &McpcModel, size: f64, rng: &mut impl RngExt) -> McpcModel {
    if size == 0.0 {
        return model.clone();
    }
    let values: Vec<f64> = model
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-size..size))
        .collect();
    let mut moved = model.clone();
    moved.set_parameters(&values).unwrap();
    moved
}

/// At three configurations of a perturbed geometry, every column against central differences
/// (step 1e-6: a larger one meets the kinks where a mass changes its nearest segment), within
/// `tolerance` relative to `1 + |column|`.
fn check(
    tree: &KinematicTree,
    model: &McpcModel,
    flexibility: &FlexibilityModel,
    seed: u64,
    tolerance: f64,
) {
    let mut rng = rng(seed);
    let model = perturbed(model, 1e-3, &mut rng);
    let every: Vec<usize> = (0..model.parameter_count()).collect();
    let mut largest = 0.0_f64;
    for _ in 0..3 {
        let q = random_configuration(tree, &mut rng);
        let columns = flexibility
            .deflected_pose_derivatives(tree, &model, &q, &every, 1e-7)
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
            let (plus, minus) = (at(1e-6), at(-1e-6));
            for (tool, change) in column.iter().enumerate() {
                let central = pose_error(&plus[tool], &minus[tool]) / 2e-6;
                let error = (change - central).amax() / (1.0 + central.amax());
                largest = largest.max(error);
                assert!(
                    error < tolerance,
                    "parameter {p}, tool {tool}: {change} vs {central}"
                );
            }
        }
    }
    assert!(largest.is_finite());
    eprintln!("largest disagreement with central differences: {largest:.1e}");
}

/// At three configurations of a geometry perturbed by up to `size` (0: the nominal one, where
/// segments of zero length take the one-sided change), every column of the analytic
/// derivative against the forward difference of the loads it replaced
/// (`deflected_pose_derivatives_by_load_differences`, step 1e-7), within `tolerance` relative
/// to `1 + |column|`; returns the largest disagreement.
fn check_against_load_differences(
    tree: &KinematicTree,
    model: &McpcModel,
    flexibility: &FlexibilityModel,
    (seed, size): (u64, f64),
    tolerance: f64,
) -> f64 {
    let mut rng = rng(seed);
    let model = perturbed(model, size, &mut rng);
    let every: Vec<usize> = (0..model.parameter_count()).collect();
    let mut largest = 0.0_f64;
    for _ in 0..3 {
        let q = random_configuration(tree, &mut rng);
        let analytic = flexibility
            .deflected_pose_derivatives(tree, &model, &q, &every, 1e-7)
            .unwrap();
        let differenced = flexibility
            .deflected_pose_derivatives_by_load_differences(tree, &model, &q, &every, 1e-7)
            .unwrap();
        assert_eq!(analytic.len(), differenced.len());
        for (p, (a, d)) in analytic.iter().zip(&differenced).enumerate() {
            for (tool, (a, d)) in a.iter().zip(d).enumerate() {
                let error = (a - d).amax() / (1.0 + d.amax());
                largest = largest.max(error);
                assert!(error < tolerance, "parameter {p}, tool {tool}: {a} vs {d}");
            }
        }
    }
    assert!(largest.is_finite());
    eprintln!("largest disagreement with the load differences: {largest:.1e}");
    largest
}

#[test]
fn analytic_load_change_matches_the_load_differences() {
    let (tree, model, loaded) = robonaut_loaded(7.5);
    // Perturbed and nominal geometry (zero-length segments at the wrists).
    let largest = check_against_load_differences(&tree, &model, &loaded, (21, 1e-3), 1e-6);
    let nominal = check_against_load_differences(&tree, &model, &loaded, (22, 0.0), 1e-6);
    // Not the same computation: a forward difference disagrees somewhere at its step's error.
    assert!(largest.max(nominal) > 1e-12, "{largest} {nominal}");
}

#[test]
fn analytic_load_change_matches_the_load_differences_on_robonaut_2() {
    let (tree, model) = TestRobot::load(&robonaut2()).tree_and_model();
    let flexibility = FlexibilityModel::new(&tree, &model, &Stiffness::default()).unwrap();
    assert!(
        flexibility.total_mass() > 10.0,
        "{}",
        flexibility.total_mass()
    );
    let loaded = flexibility.for_payload(Some(5.0)).unwrap().into_owned();
    check_against_load_differences(&tree, &model, &loaded, (23, 1e-3), 1e-6);
    check_against_load_differences(&tree, &model, &loaded, (24, 0.0), 1e-6);
}

/// The built-in Robonaut with its stiffness file and `payload` kg at each tool.
fn robonaut_loaded(payload: f64) -> (KinematicTree, McpcModel, FlexibilityModel) {
    let (tree, model) = TestRobot::load(&robot("robonaut/robonaut.urdf")).tree_and_model();
    let stiffness =
        treecal::io::read_stiffness(&robot("robonaut/stiffness.yaml"), &tree, &model).unwrap();
    let flexibility = FlexibilityModel::new(&tree, &model, &stiffness).unwrap();
    let loaded = flexibility.for_payload(Some(payload)).unwrap().into_owned();
    (tree, model, loaded)
}

#[test]
fn pose_derivatives_on_the_built_in_robonaut_with_a_payload() {
    let (tree, model, loaded) = robonaut_loaded(7.5);
    // The deflections are not negligible: centimetres at the tools.
    let q = random_configuration(&tree, &mut rng(3));
    let rigid = model.tool_poses(&q);
    let bent = loaded.deflected_tool_poses(&tree, &model, &q).unwrap();
    let size = pose_error(&bent[0], &rigid[0]).fixed_rows::<3>(0).norm();
    assert!(size > 1e-3, "deflection {size} m");
    check(&tree, &model, &loaded, 11, 1e-8);
}

#[test]
fn pose_derivatives_on_the_shared_robonaut_2() {
    let (tree, model) = TestRobot::load(&robonaut2()).tree_and_model();
    let flexibility = FlexibilityModel::new(&tree, &model, &Stiffness::default()).unwrap();
    check(&tree, &model, &flexibility, 12, 1e-8);
}

#[test]
fn pose_derivatives_with_joint_compliance_only() {
    let (tree, model, loaded) = robonaut_loaded(7.5);
    let basis = ComplianceBasis::new(&loaded);
    let scales: Vec<f64> = basis
        .parameters()
        .iter()
        .map(|p| f64::from(u8::from(p.kind.is_joint())))
        .collect();
    let joints_only = basis.scaled(&scales).unwrap();
    // Joint compliance alone has no kinks: closer still.
    check(&tree, &model, &joints_only, 13, 1e-8);
}

#[test]
fn pose_derivatives_at_another_geometry_and_payload() {
    let (tree, model, loaded) = robonaut_loaded(20.0);
    check(&tree, &model, &loaded, 14, 1e-8);
}

#[test]
fn pose_derivatives_with_a_reference_link() {
    // The measurement frame on a torso link: the path that differences the whole chain.
    let (tree, mut model, loaded) = robonaut_loaded(7.5);
    let frame = 1;
    let link = tree.joint(model.frames()[frame].joint).child;
    model
        .set_reference(Some(treecal::kinematics::ReferenceLink {
            link,
            parent: Some(frame),
            last_from_link: nalgebra::Isometry3::identity(),
        }))
        .unwrap();
    check(&tree, &model, &loaded, 15, 1e-6);
}
