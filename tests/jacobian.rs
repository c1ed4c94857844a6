//! The analytic identification Jacobian against central finite differences of forward
//! kinematics, for every parameter of every robot.

use crate::common::*;
use treecal::kinematics::McpcModel;
use treecal::math::pose_error;
use treecal::tree::detect_branches;

fn check(model: &McpcModel, q: &[f64], what: &str) {
    let step = 1e-6;
    let parameters = model.parameters();
    let analytic = model.tool_jacobians(q);
    let mut perturbed = model.clone();
    for index in 0..parameters.len() {
        let mut plus = parameters.clone();
        plus[index] += step;
        perturbed.set_parameters(&plus).unwrap();
        let up = perturbed.tool_poses(q);
        let mut minus = parameters.clone();
        minus[index] -= step;
        perturbed.set_parameters(&minus).unwrap();
        let down = perturbed.tool_poses(q);
        for (tool, jacobian) in analytic.iter().enumerate() {
            let numeric = pose_error(&up[tool], &down[tool]) / (2.0 * step);
            let column = jacobian.jacobian.column(index);
            let error = (numeric - column).norm();
            let scale = column.norm().max(1.0);
            assert!(
                error <= 1e-6 * scale,
                "{what}: tool {tool}, parameter {index} ({:?}): analytic {column:?} numeric {numeric:?}",
                model.parameter_layout()[index]
            );
        }
    }
    for (tool, jacobian) in analytic.iter().enumerate() {
        assert_pose_eq(&jacobian.pose, &model.tool_pose(tool, q), 1e-12, what);
        let single = model.tool_jacobian(tool, q);
        assert_eq!(single.jacobian, jacobian.jacobian);
    }
    // The buffered form, reused across a second configuration (stale entries overwritten).
    let mut chain = treecal::kinematics::ChainFrames::default();
    let mut jacobians = Vec::new();
    let other: Vec<f64> = q.iter().map(|v| 0.3 - v).collect();
    model.tool_jacobians_into(&other, &mut chain, &mut jacobians);
    model.tool_jacobians_into(q, &mut chain, &mut jacobians);
    assert_eq!(jacobians.len(), analytic.len());
    for (buffered, jacobian) in jacobians.iter().zip(&analytic) {
        assert_eq!(buffered, &jacobian.jacobian, "{what}: tool_jacobians_into");
    }
    // One tool at a time on the same buffers, after the other tools and configurations: the
    // sines of its own chain only are refreshed, and those are all it reads.
    let mut single = nalgebra::DMatrix::zeros(0, 0);
    for (tool, jacobian) in analytic.iter().enumerate().rev() {
        model.tool_jacobian_into((tool + 1) % analytic.len(), &other, &mut chain, &mut single);
        let pose = model.tool_jacobian_into(tool, q, &mut chain, &mut single);
        assert_eq!(
            single, jacobian.jacobian,
            "{what}: tool_jacobian_into, tool {tool}"
        );
        assert_eq!(
            pose, jacobian.pose,
            "{what}: tool_jacobian_into pose, tool {tool}"
        );
    }
    // Only the columns a tool does not write are zeroed: a buffer full of other values (the
    // caller's, say) must still come out exact, for every tool.
    for (tool, jacobian) in analytic.iter().enumerate() {
        single.fill(7.0);
        model.tool_jacobian_into(tool, q, &mut chain, &mut single);
        assert_eq!(
            single, jacobian.jacobian,
            "{what}: filled buffer, tool {tool}"
        );
    }
    for buffered in &mut jacobians {
        buffered.fill(-3.0);
    }
    model.tool_jacobians_into(q, &mut chain, &mut jacobians);
    for (buffered, jacobian) in jacobians.iter().zip(&analytic) {
        assert_eq!(buffered, &jacobian.jacobian, "{what}: filled buffers");
    }
    // The reusing form (what the fit's rows take), after another configuration and with its
    // matrices filled with other values: the same poses and matrices bit for bit.
    let mut reused = Vec::new();
    model.tool_jacobians_reusing(&other, &mut reused);
    for tool in &mut reused {
        tool.jacobian.fill(5.0);
    }
    model.tool_jacobians_reusing(q, &mut reused);
    assert_eq!(reused.len(), analytic.len());
    for (reused, jacobian) in reused.iter().zip(&analytic) {
        assert_eq!(reused.jacobian, jacobian.jacobian, "{what}: reusing");
        assert_eq!(reused.pose, jacobian.pose, "{what}: reusing pose");
    }
}

#[test]
fn jacobian_matches_finite_differences_on_every_robot() {
    for path in all_repo_robots().into_iter().chain([robonaut2()]) {
        let tree = treecal::load_urdf(&path).unwrap().tree;
        let branches = detect_branches(&tree, None).unwrap();
        let model = McpcModel::from_tree(&tree, &branches).unwrap();
        let mut rng = rng(21);
        for _ in 0..5 {
            let q = random_configuration(&tree, &mut rng);
            check(&model, &q, &path.display().to_string());
        }
    }
}

/// Off the nominal geometry too: a model whose parameters are all perturbed.
#[test]
fn jacobian_matches_finite_differences_on_a_perturbed_model() {
    use rand::RngExt;
    let tree = treecal::load_urdf(&robot("dual_arm_prismatic/dual_arm_prismatic.urdf"))
        .unwrap()
        .tree;
    let branches = detect_branches(&tree, None).unwrap();
    let mut model = McpcModel::from_tree(&tree, &branches).unwrap();
    let mut rng = rng(5);
    let perturbed: Vec<f64> = model
        .parameters()
        .iter()
        .map(|p| p + rng.random_range(-0.05..0.05))
        .collect();
    model.set_parameters(&perturbed).unwrap();
    // And seen from a measurement frame away from the base.
    let world_from_base = treecal::math::pose(
        treecal::math::Vec3::new(1.5, -0.3, 0.2),
        treecal::math::rotation_from_rpy(0.3, -0.2, 2.0),
    );
    model.set_world_from_base(&world_from_base);
    let base_model = {
        let mut m = model.clone();
        m.set_world_from_base(&treecal::math::Pose::identity());
        m
    };
    for _ in 0..5 {
        let q = random_configuration(&tree, &mut rng);
        for (tool, pose) in model.tool_poses(&q).iter().enumerate() {
            assert_pose_eq(
                pose,
                &(world_from_base * base_model.tool_pose(tool, &q)),
                1e-12,
                "world frame",
            );
        }
    }
    for _ in 0..5 {
        let q = random_configuration(&tree, &mut rng);
        check(&model, &q, "perturbed dual arm");
    }
}
