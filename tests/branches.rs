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

/// (file, torso joints, left (or only) tool, right tool, joints per arm).
type Expected = (
    &'static str,
    &'static [&'static str],
    &'static str,
    Option<&'static str>,
    usize,
);

/// What a roboticist names on one real robot: the torso (coupled-branch) joints, the two tool
/// links (left, right) and the joints per arm. `None` for the right tool: a single arm.
///
/// Decisions where "arm" is ambiguous:
/// - the tool of an arm with a multi-fingered hand is the palm (or hand) link where the
///   fingers branch off; a gripper's opening joint (`gripper_left_joint`, `l_gripper_joint`,
///   `jointGripper`) belongs to the hand, not the arm, so Talos' tool is its wrist
///   force-torque flange `wrist_*_ft_tool_link` with or without the gripper's fingers modelled;
/// - Alex's `LeftGripperYaw` is a wrist joint (the seventh arm joint), so its tool is
///   `LeftGripperYawLink`, rigidly holding the hand (nub, Psyonic or Sake palm);
/// - Centauro's arms end in ball-shaped soft hands (`ball1`, `ball2`), left by +y;
/// - an arm on a legged base (ANYmal + Kinova, B1 + Z1) is a single-arm robot: legs are never
///   arms, the base does not move during calibration, so there is no torso;
/// - a single-arm robot with a lift (TIAGo) is one arm whose chain starts at the lift.
const BRANCHED: &[Expected] = &[
    // humanoids
    (
        "talos_data/robots/talos_full_v2.urdf",
        &["torso_1_joint", "torso_2_joint"],
        "wrist_left_ft_tool_link",
        Some("wrist_right_ft_tool_link"),
        7,
    ),
    (
        "talos_data/robots/talos_full_v2_box.urdf",
        &["torso_1_joint", "torso_2_joint"],
        "wrist_left_ft_tool_link",
        Some("wrist_right_ft_tool_link"),
        7,
    ),
    (
        "talos_data/robots/talos_reduced.urdf",
        &["torso_1_joint", "torso_2_joint"],
        "wrist_left_ft_tool_link",
        Some("wrist_right_ft_tool_link"),
        7,
    ),
    (
        "talos_data/robots/talos_reduced_box.urdf",
        &["torso_1_joint", "torso_2_joint"],
        "wrist_left_ft_tool_link",
        Some("wrist_right_ft_tool_link"),
        7,
    ),
    (
        "talos_data/robots/talos_reduced_corrected.urdf",
        &["torso_1_joint", "torso_2_joint"],
        "wrist_left_ft_tool_link",
        Some("wrist_right_ft_tool_link"),
        7,
    ),
    (
        "romeo_description/urdf/romeo.urdf",
        &["TrunkYaw"],
        "l_gripper",
        Some("r_gripper"),
        7,
    ),
    (
        "romeo_description/urdf/romeo_small.urdf",
        &["TrunkYaw"],
        "l_gripper",
        Some("r_gripper"),
        7,
    ),
    (
        "romeo_description/urdf/romeo_laas_small.urdf",
        &["TrunkYaw"],
        "l_wrist",
        Some("r_wrist"),
        7,
    ),
    (
        "icub_description/robots/icub.urdf",
        &["torso_pitch", "torso_roll", "torso_yaw"],
        "l_hand",
        Some("r_hand"),
        7,
    ),
    (
        "icub_description/robots/icub_reduced.urdf",
        &["torso_pitch", "torso_roll", "torso_yaw"],
        "l_hand",
        Some("r_hand"),
        7,
    ),
    (
        "g1_description/urdf/g1_29dof_rev_1_0.urdf",
        &["waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint"],
        "left_rubber_hand",
        Some("right_rubber_hand"),
        7,
    ),
    (
        "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf",
        &["waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint"],
        "left_hand_palm_link",
        Some("right_hand_palm_link"),
        7,
    ),
    (
        "alex_description/urdf/alex_nub_hands.urdf",
        &["SpineYaw", "SpineRoll", "SpinePitch"],
        "LeftGripperYawLink",
        Some("RightGripperYawLink"),
        7,
    ),
    (
        "alex_description/urdf/alex_psyonic_hands.urdf",
        &["SpineYaw", "SpineRoll", "SpinePitch"],
        "LeftGripperYawLink",
        Some("RightGripperYawLink"),
        7,
    ),
    (
        "alex_description/urdf/alex_sake_hands.urdf",
        &["SpineYaw", "SpineRoll", "SpinePitch"],
        "LeftSakePalmLink",
        Some("RightSakePalmLink"),
        7,
    ),
    (
        "human_description/robots/human.urdf",
        &[
            "middle_lumbar_Z",
            "middle_lumbar_X",
            "middle_thoracic_Z",
            "middle_thoracic_X",
            "middle_thoracic_Y",
        ],
        "left_hand",
        Some("right_hand"),
        8,
    ),
    (
        "simple_humanoid_description/urdf/simple_humanoid.urdf",
        &["WAIST_P", "WAIST_R", "CHEST"],
        "l_wrist",
        Some("r_wrist"),
        7,
    ),
    (
        "simple_humanoid_description/urdf/simple_humanoid_classical.urdf",
        &["WAIST_P", "WAIST_R", "CHEST"],
        "l_wrist",
        Some("r_wrist"),
        7,
    ),
    (
        "centauro_description/urdf/centauro.urdf",
        &["torso_yaw"],
        "ball1",
        Some("ball2"),
        6,
    ),
    // dual-arm
    (
        "baxter_description/urdf/baxter.urdf",
        &[],
        "left_hand_link",
        Some("right_hand_link"),
        7,
    ),
    (
        "pr2_description/urdf/pr2.urdf",
        &["torso_lift_joint"],
        "l_gripper_palm_link",
        Some("r_gripper_palm_link"),
        7,
    ),
    (
        "tiago_description/robots/tiago_dual.urdf",
        &["torso_lift_joint"],
        "hand_left_palm_link",
        Some("hand_right_palm_link"),
        7,
    ),
    (
        "tiago_pro_description/robots/tiago_pro.urdf",
        &["torso_lift_joint"],
        "arm_left_tool_link",
        Some("arm_right_tool_link"),
        7,
    ),
    // an arm on a legged base: one arm
    (
        "anymal_b_simple_description/robots/anymal-kinova.urdf",
        &[],
        "j2s6s200_end_effector",
        None,
        6,
    ),
    (
        "b1_description/urdf/b1-z1.urdf",
        &[],
        "gripperStator",
        None,
        6,
    ),
    // single arms, for the record
    (
        "tiago_description/robots/tiago.urdf",
        &[],
        "hand_palm_link",
        None,
        8,
    ),
    (
        "tiago_description/robots/tiago_no_hand.urdf",
        &[],
        "arm_tool_link",
        None,
        8,
    ),
    (
        "panda_description/urdf/panda.urdf",
        &[],
        "panda_hand",
        None,
        7,
    ),
    (
        "ur_description/urdf/ur5_robot.urdf",
        &[],
        "ee_link",
        None,
        6,
    ),
];

/// Checks one robot's automatic branches against the table; the problem, if any.
fn check_branches(
    file: &str,
    tree: &KinematicTree,
    (torso, left, right, joints): (&[&str], &str, Option<&str>, usize),
) -> Option<String> {
    let branches = match detect_branches(tree, None) {
        Ok(b) => b,
        Err(e) => return Some(format!("{file}: {e}")),
    };
    let found_torso = names(tree, &branches.coupled.joints);
    let found_tools = tool_names(tree, &branches);
    let expected_tools: Vec<String> = std::iter::once(left)
        .chain(right)
        .map(String::from)
        .collect();
    let lengths: Vec<usize> = branches.arms.iter().map(|a| a.joints.len()).collect();
    let ok = found_torso == torso
        && found_tools == expected_tools
        && lengths.iter().all(|&n| n == joints)
        && branches.selection != DecisionRule::GivenTools;
    (!ok).then(|| {
        format!(
            "{file}: torso {found_torso:?}, tools {found_tools:?}, arm joints {lengths:?} (rule: {}, sides: {}); expected torso {torso:?}, tools {expected_tools:?}, {joints} joints per arm",
            branches.selection, branches.sides
        )
    })
}

#[test]
fn real_robots_torso_and_arms_are_found_as_a_roboticist_names_them() {
    let Some(dir) = example_robot_data() else {
        return;
    };
    let mut problems = Vec::new();
    for &(file, torso, left, right, joints) in BRANCHED {
        let tree = load_urdf(&dir.join(file))
            .unwrap_or_else(|e| panic!("{e}"))
            .tree;
        problems.extend(check_branches(file, &tree, (torso, left, right, joints)));
    }
    let repo: &[Expected] = &[
        (
            "humanoid/humanoid.urdf",
            &["waist_yaw", "waist_pitch"],
            "l_hand",
            Some("r_hand"),
            7,
        ),
        (
            "dual_arm_prismatic/dual_arm_prismatic.urdf",
            &["torso_lift", "torso_yaw"],
            "left_tool",
            Some("right_tool"),
            6,
        ),
    ];
    // robots/robonaut (paper Table 1, arms of 6 and 5 joints): robonaut_table1_branches.
    for &(file, torso, left, right, joints) in repo {
        let tree = load(file);
        problems.extend(check_branches(file, &tree, (torso, left, right, joints)));
    }
    let tree = load_urdf(&robonaut2()).unwrap().tree;
    problems.extend(check_branches(
        "robonaut2",
        &tree,
        (
            &["r2/waist/joint0"],
            "r2/left_palm",
            Some("r2/right_palm"),
            7,
        ),
    ));
    assert!(problems.is_empty(), "\n{}", problems.join("\n"));
}

/// Legs are never arms: a robot with only legs (and drones with no chains) is refused with a
/// message that says what was found and how to name the tools.
#[test]
fn legged_robots_and_drones_have_no_automatic_arms() {
    let Some(dir) = example_robot_data() else {
        return;
    };
    for (file, expected) in [
        (
            "go2_description/urdf/go2.urdf",
            "no arm found: the chains ending at",
        ),
        (
            "solo_description/robots/solo12.urdf",
            "named like legs, heads, fingers or wheels",
        ),
        (
            "anymal_b_simple_description/robots/anymal.urdf",
            "'LF_FOOT'",
        ),
        (
            "iris_description/robots/iris.urdf",
            "no chain of two or more movable joints",
        ),
    ] {
        let tree = load_urdf(&dir.join(file)).unwrap().tree;
        let message = detect_branches(&tree, None).unwrap_err().to_string();
        assert!(
            message.contains(expected) && message.contains("`tools`"),
            "{file}: {message}"
        );
    }
    // --tools overrides: two feet named by the user make a two-"arm" robot.
    let tree = load_urdf(&dir.join("go2_description/urdf/go2.urdf"))
        .unwrap()
        .tree;
    let tools = [
        tree.link_id("FR_foot").unwrap(),
        tree.link_id("FL_foot").unwrap(),
    ];
    let branches = detect_branches(&tree, Some(&tools)).unwrap();
    assert_eq!(branches.selection, DecisionRule::GivenTools);
    assert_eq!(tool_names(&tree, &branches), ["FL_foot", "FR_foot"]);
}

/// `--tools` overrides the automatic choice on a real robot: TIAGo++ with fingertips named.
#[test]
fn given_tools_override_the_automatic_choice() {
    let Some(path) = example_robot("tiago_description/robots/tiago_dual.urdf") else {
        return;
    };
    let tree = load_urdf(&path).unwrap().tree;
    let tools = [
        tree.link_id("arm_right_tool_link").unwrap(),
        tree.link_id("arm_left_tool_link").unwrap(),
    ];
    let branches = detect_branches(&tree, Some(&tools)).unwrap();
    assert_eq!(branches.selection, DecisionRule::GivenTools);
    assert_eq!(
        tool_names(&tree, &branches),
        ["arm_left_tool_link", "arm_right_tool_link"]
    );
    assert_eq!(names(&tree, &branches.coupled.joints), ["torso_lift_joint"]);
}
