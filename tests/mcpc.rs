//! MCPC conversion and forward kinematics against the URDF's own forward kinematics.

use crate::common::*;
use treecal::kinematics::{McpcModel, SINGULARITY_THRESHOLD};
use treecal::tree::detect_branches;
use treecal::urdf::load_urdf;

/// MCPC forward kinematics equals URDF forward kinematics (every frame's link and every tool)
/// at random configurations, to 1e-9 m and 1e-9 rad.
fn check_robot(path: &std::path::Path, configurations: usize) {
    let import = load_urdf(path).unwrap_or_else(|e| panic!("{e}"));
    let tree = import.tree;
    let branches =
        detect_branches(&tree, None).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    for frame in model.frames() {
        assert!(
            frame.beta.abs() <= SINGULARITY_THRESHOLD + 1e-12,
            "{}: |β| too large",
            path.display()
        );
    }
    for tool in model.tools() {
        assert!(tool.beta.abs() <= SINGULARITY_THRESHOLD + 1e-12);
    }
    let mut rng = rng(7);
    for _ in 0..configurations {
        let q = random_configuration(&tree, &mut rng);
        let reference = tree.link_poses(&q).unwrap();
        for (index, link_pose) in model.link_poses(&q).iter().enumerate() {
            let child = tree.joint(model.frames()[index].joint).child;
            assert_pose_eq(link_pose, &reference[child.0], 1e-9, &tree.link(child).name);
        }
        for (index, tool_pose) in model.tool_poses(&q).iter().enumerate() {
            let link = model.tools()[index].link;
            assert_pose_eq(tool_pose, &reference[link.0], 1e-9, &tree.link(link).name);
        }
    }
}

#[test]
fn mcpc_forward_kinematics_matches_urdf_on_every_repo_robot() {
    let robots = all_repo_robots();
    assert!(
        robots.len() >= 3,
        "expected robots in robots/, found {robots:?}"
    );
    for path in robots {
        check_robot(&path, 200);
    }
}

#[test]
fn mcpc_forward_kinematics_matches_urdf_on_robonaut2() {
    check_robot(&robonaut2(), 200);
}
