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

fn load(relative: &str) -> KinematicTree {
    load_urdf(&robot(relative)).unwrap().tree
}

fn tool_names(tree: &KinematicTree, branches: &treecal::Branches) -> Vec<String> {
    branches
        .tools()
        .iter()
        .map(|t| tree.link(*t).name.clone())
        .collect()
}

#[test]
fn robonaut_table1_branches() {
    let tree = load("robonaut/robonaut.urdf");
    let branches = detect_branches(&tree, None).unwrap();
    assert_eq!(
        names(&tree, &branches.coupled.joints),
        ["torso_joint1", "torso_joint2"]
    );
    assert_eq!(tool_names(&tree, &branches), ["left_tool", "right_tool"]);
    assert_eq!(branches.arms[0].joints.len(), 6);
    assert_eq!(branches.arms[1].joints.len(), 5);
    assert_eq!(branches.arms[0].name, "left_arm");
}

#[test]
fn humanoid_ignores_head_legs_and_fingers() {
    let tree = load("humanoid/humanoid.urdf");
    let branches = detect_branches(&tree, None).unwrap();
    assert_eq!(
        names(&tree, &branches.coupled.joints),
        ["waist_yaw", "waist_pitch"]
    );
    assert_eq!(tool_names(&tree, &branches), ["l_hand", "r_hand"]);
    assert_eq!(branches.arms[0].joints.len(), 7);
    assert_eq!(branches.sides, DecisionRule::SideNames);
    for arm in &branches.arms {
        for joint in names(&tree, &arm.joints) {
            assert!(
                !joint.contains("finger") && !joint.contains("hip"),
                "{joint}"
            );
        }
    }
}

#[test]
fn dual_arm_prismatic_torso() {
    let tree = load("dual_arm_prismatic/dual_arm_prismatic.urdf");
    let branches = detect_branches(&tree, None).unwrap();
    assert_eq!(
        names(&tree, &branches.coupled.joints),
        ["torso_lift", "torso_yaw"]
    );
    assert_eq!(tool_names(&tree, &branches), ["left_tool", "right_tool"]);
}

#[test]
fn named_tools_are_ordered_left_then_right() {
    let tree = load("humanoid/humanoid.urdf");
    let tools = [
        tree.link_id("r_hand").unwrap(),
        tree.link_id("l_hand").unwrap(),
    ];
    let branches = detect_branches(&tree, Some(&tools)).unwrap();
    assert_eq!(branches.selection, DecisionRule::GivenTools);
    assert_eq!(tool_names(&tree, &branches), ["l_hand", "r_hand"]);
}

#[test]
fn three_named_tools_share_the_torso() {
    let tree = load("humanoid/humanoid.urdf");
    let tools: Vec<_> = ["l_hand", "r_hand", "camera"]
        .iter()
        .map(|n| tree.link_id(n).unwrap())
        .collect();
    let branches = detect_branches(&tree, Some(&tools)).unwrap();
    assert_eq!(branches.arms.len(), 3);
    assert_eq!(branches.sides, DecisionRule::NoSides);
    assert_eq!(
        names(&tree, &branches.coupled.joints),
        ["waist_yaw", "waist_pitch"]
    );
    assert_eq!(
        names(&tree, &branches.arms[2].joints),
        ["neck_yaw", "neck_pitch"]
    );
    let model = treecal::McpcModel::from_tree(&tree, &branches).unwrap();
    assert_eq!(model.tools().len(), 3);
    assert_eq!(model.parameter_count(), 4 * (2 + 7 + 7 + 2) + 6 * 3);
}

#[test]
fn a_single_tool_makes_a_serial_robot() {
    let tree = load("humanoid/humanoid.urdf");
    let tools = [tree.link_id("l_foot").unwrap()];
    let branches = detect_branches(&tree, Some(&tools)).unwrap();
    assert!(branches.coupled.joints.is_empty());
    assert_eq!(branches.arms[0].joints.len(), 6);
}

#[test]
fn tools_on_one_chain_are_refused() {
    let tree = load("humanoid/humanoid.urdf");
    let tools = [
        tree.link_id("l_hand").unwrap(),
        tree.link_id("chest").unwrap(),
    ];
    let message = detect_branches(&tree, Some(&tools))
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("'chest'") && message.contains("'l_hand'"),
        "{message}"
    );
    let twice = [tools[0], tools[0]];
    let message = detect_branches(&tree, Some(&twice))
        .unwrap_err()
        .to_string();
    assert!(message.contains("named twice"), "{message}");
}

/// Arms without side names: left is the tip with the larger y at the zero configuration.
#[test]
fn sides_from_y_when_names_do_not_say() {
    let arm = |name: &str, y: f64| {
        format!(
            r#"<joint name="{name}1" type="revolute"><parent link="torso"/><child link="{name}_a"/><origin xyz="0 {y} 0.5"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
            <link name="{name}_a"/>
            <joint name="{name}2" type="revolute"><parent link="{name}_a"/><child link="{name}_tool"/><origin xyz="0 0 -0.3"/><axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
            <link name="{name}_tool"/>"#
        )
    };
    let text = format!(
        r#"<robot name="plain"><link name="base"/><link name="torso"/>
        <joint name="spin" type="continuous"><parent link="base"/><child link="torso"/><axis xyz="0 0 1"/></joint>
        {}{}</robot>"#,
        arm("a", -0.2),
        arm("b", 0.2)
    );
    let tree = treecal::parse_urdf(&text, "plain").unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    assert_eq!(branches.sides, DecisionRule::SideY);
    assert_eq!(tool_names(&tree, &branches), ["b_tool", "a_tool"]);
    assert_eq!(names(&tree, &branches.coupled.joints), ["spin"]);
}
