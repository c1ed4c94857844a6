//! Branch detection on the repository's robots and on Robonaut 2.

use crate::common::*;
use treecal::tree::{detect_branches, DecisionRule, KinematicTree};
use treecal::urdf::load_urdf;

fn names(tree: &KinematicTree, joints: &[treecal::tree::JointId]) -> Vec<String> {
    joints.iter().map(|j| tree.joint(*j).name.clone()).collect()
}

#[test]
fn robonaut2_waist_and_arms_found_without_naming_tools() {
    let tree = load_urdf(&robonaut2()).unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    assert_eq!(names(&tree, &branches.coupled.joints), ["r2/waist/joint0"]);
    let left = &branches.arms[0];
    let right = &branches.arms[1];
    assert_eq!(tree.link(left.tool.unwrap()).name, "r2/left_palm");
    assert_eq!(tree.link(right.tool.unwrap()).name, "r2/right_palm");
    assert_eq!(left.joints.len(), 7);
    assert_eq!(right.joints.len(), 7);
    assert_eq!(branches.selection, DecisionRule::ArmNames);
    assert_eq!(branches.sides, DecisionRule::SideNames);
    assert_eq!(tree.link(branches.divergence).name, "r2/waist_center");
}
