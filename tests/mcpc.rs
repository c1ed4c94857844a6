//! MCPC conversion and forward kinematics against the URDF's own forward kinematics.

use crate::common::*;
use treecal::kinematics::{ForwardFrames, McpcModel, SINGULARITY_THRESHOLD};
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

/// A random branched robot as URDF text: a torso chain and two arms, with axes and origins
/// drawn to hit the awkward cases (axes exactly or nearly along the previous X, prismatic
/// joints, fixed joints in between, exact quarter turns, mimic joints).
fn random_robot(seed: u64) -> String {
    use rand::RngExt;
    let mut rng = rng(seed);
    let mut joints = String::new();
    let mut links = String::from("<link name=\"base\"/>");
    let mut counter = 0;
    let mut movable: Vec<String> = Vec::new();
    let mut chain = |rng: &mut rand::rngs::ChaCha8Rng,
                     parent: &str,
                     prefix: &str,
                     count: usize,
                     joints: &mut String,
                     links: &mut String,
                     movable: &mut Vec<String>|
     -> String {
        let mut parent = parent.to_owned();
        for _ in 0..count {
            counter += 1;
            let child = format!("{prefix}_link{counter}");
            let kind = match rng.random_range(0..10) {
                0 => "fixed",
                1 => "prismatic",
                2 => "continuous",
                _ => "revolute",
            };
            let quarter = std::f64::consts::FRAC_PI_2;
            let angle = |rng: &mut rand::rngs::ChaCha8Rng| match rng.random_range(0..3) {
                0 => quarter * rng.random_range(-2..=2) as f64,
                1 => 0.0,
                _ => rng.random_range(-3.1..3.1),
            };
            let rpy = [angle(rng), angle(rng), angle(rng)];
            let xyz: [f64; 3] = std::array::from_fn(|_| {
                if rng.random_bool(0.3) {
                    0.0
                } else {
                    rng.random_range(-0.4..0.4)
                }
            });
            let axis = match rng.random_range(0..6) {
                0 => "1 0 0".to_owned(),
                1 => "-1 0 0".to_owned(),
                2 => format!(
                    "1 {} {}",
                    rng.random_range(-1e-9..1e-9),
                    rng.random_range(-1e-9..1e-9)
                ),
                3 => "0 0 1".to_owned(),
                4 => "0 2 0".to_owned(),
                _ => format!(
                    "{} {} {}",
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(0.1..1.0)
                ),
            };
            let mimic = if kind == "revolute" && !movable.is_empty() && rng.random_bool(0.1) {
                format!(
                    "<mimic joint=\"{}\" multiplier=\"{}\" offset=\"{}\"/>",
                    movable[0],
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-0.5..0.5)
                )
            } else {
                String::new()
            };
            *joints += &format!(
                "<joint name=\"{prefix}_j{counter}\" type=\"{kind}\"><parent link=\"{parent}\"/><child link=\"{child}\"/><origin xyz=\"{} {} {}\" rpy=\"{} {} {}\"/><axis xyz=\"{axis}\"/><limit lower=\"-2\" upper=\"2\" effort=\"1\" velocity=\"1\"/>{mimic}</joint>\n",
                xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2]
            );
            *links += &format!("<link name=\"{child}\"/>");
            if kind != "fixed" && mimic.is_empty() {
                movable.push(format!("{prefix}_j{counter}"));
            }
            parent = child;
        }
        parent
    };
    let torso = chain(
        &mut rng,
        "base",
        "torso",
        3,
        &mut joints,
        &mut links,
        &mut movable,
    );
    let left = chain(
        &mut rng,
        &torso,
        "left",
        7,
        &mut joints,
        &mut links,
        &mut movable,
    );
    let right = chain(
        &mut rng,
        &torso,
        "right",
        6,
        &mut joints,
        &mut links,
        &mut movable,
    );
    let tools = format!(
        "<link name=\"left_tool\"/><link name=\"right_tool\"/>
        <joint name=\"left_tool_joint\" type=\"fixed\"><parent link=\"{left}\"/><child link=\"left_tool\"/><origin xyz=\"0.01 0.02 0.1\" rpy=\"0 1.5707963267948966 0.3\"/></joint>
        <joint name=\"right_tool_joint\" type=\"fixed\"><parent link=\"{right}\"/><child link=\"right_tool\"/><origin xyz=\"0 0 0.12\" rpy=\"0.2 0 0\"/></joint>"
    );
    format!("<robot name=\"random{seed}\">{links}{tools}{joints}</robot>")
}

/// MCPC forward kinematics equals URDF forward kinematics on 200 random robots built to sit
/// on and near the MCPC singularity.
#[test]
fn mcpc_forward_kinematics_matches_urdf_on_random_robots() {
    // Reused across robots of different sizes.
    let mut forward = ForwardFrames::default();
    for seed in 0..200 {
        let text = random_robot(seed);
        let tree = treecal::parse_urdf(&text, "random").unwrap().tree;
        let tools = [
            tree.link_id("left_tool").unwrap(),
            tree.link_id("right_tool").unwrap(),
        ];
        let branches = detect_branches(&tree, Some(&tools)).unwrap();
        let model = McpcModel::from_tree(&tree, &branches).unwrap();
        for frame in model.frames() {
            assert!(
                frame.beta.abs() <= SINGULARITY_THRESHOLD + 1e-12,
                "seed {seed}"
            );
        }
        for tool in model.tools() {
            assert!(
                tool.beta.abs() <= SINGULARITY_THRESHOLD + 1e-12,
                "seed {seed}"
            );
        }
        let mut rng = rng(seed + 1000);
        for _ in 0..20 {
            let q = random_configuration(&tree, &mut rng);
            let reference = tree.link_poses(&q).unwrap();
            for (index, link_pose) in model.link_poses(&q).iter().enumerate() {
                let child = tree.joint(model.frames()[index].joint).child;
                assert_pose_eq(
                    link_pose,
                    &reference[child.0],
                    1e-9,
                    &format!("seed {seed} {}", tree.link(child).name),
                );
            }
            for (index, tool_pose) in model.tool_poses(&q).iter().enumerate() {
                assert_pose_eq(
                    tool_pose,
                    &reference[model.tools()[index].link.0],
                    1e-9,
                    &format!("seed {seed} tool"),
                );
                assert_pose_eq(
                    &model.tool_pose(index, &q),
                    tool_pose,
                    1e-12,
                    "tool_pose vs tool_poses",
                );
            }
            // The buffered form, all tools at once and one tool: the same products in the
            // same order, so the same bits.
            model.tool_transforms_into(&q, &mut forward);
            let poses = model.tool_poses(&q);
            assert_eq!(forward.tools.len(), poses.len());
            for (index, transform) in forward.tools.iter().enumerate() {
                assert_eq!(transform.to_pose(), poses[index], "seed {seed}");
                assert_eq!(model.tool_pose(index, &q), poses[index], "seed {seed}");
            }
        }
    }
}

#[test]
fn parameter_counts_follow_4r_2p_6t() {
    let count = |relative: &str| {
        let tree = load_urdf(&robot(relative)).unwrap().tree;
        let branches = detect_branches(&tree, None).unwrap();
        McpcModel::from_tree(&tree, &branches)
            .unwrap()
            .parameter_count()
    };
    assert_eq!(count("robonaut/robonaut.urdf"), 4 * 13 + 6 * 2);
    // torso: prismatic lift + revolute yaw; arms 6 + 6 revolute.
    assert_eq!(
        count("dual_arm_prismatic/dual_arm_prismatic.urdf"),
        4 * 13 + 2 + 6 * 2
    );
}

/// Reading the parameters out and writing them back changes nothing; writing a changed value
/// moves the tool.
#[test]
fn parameter_vector_round_trip() {
    let tree = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    let mut model = McpcModel::from_tree(&tree, &branches).unwrap();
    let q = vec![0.2; tree.dof_count()];
    let before = model.tool_poses(&q);
    let mut parameters = model.parameters();
    model.set_parameters(&parameters).unwrap();
    assert_eq!(model.tool_poses(&q), before);
    let layout = model.parameter_layout();
    let last_x = layout
        .iter()
        .rposition(|(_, kind)| *kind == treecal::kinematics::ParameterKind::X)
        .unwrap();
    parameters[last_x] += 0.01;
    model.set_parameters(&parameters).unwrap();
    let moved = model.tool_poses(&q);
    let shift = (moved[1].translation.vector - before[1].translation.vector).norm();
    assert!((shift - 0.01).abs() < 1e-12, "{shift}");
    assert!(model.set_parameters(&parameters[1..]).is_err());
    parameters[0] = f64::NAN;
    assert!(model.set_parameters(&parameters).is_err());
}

/// Setting parameter `i` changes entry `i` of the parameter vector and nothing else, on a
/// model with every kind of parameter (frames, tools, joint errors, the measurement frame):
/// `set_parameter` finds its entry without the layout.
#[test]
fn set_parameter_changes_its_own_entry_only() {
    let tree = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    let terms = treecal::kinematics::JointErrorTerms {
        offsets: true,
        harmonics: true,
        backlash: false,
    };
    let model = McpcModel::from_tree(&tree, &branches)
        .unwrap()
        .with_joint_errors(terms, None)
        .unwrap()
        .with_frame_parameters();
    let before = model.parameters();
    assert_eq!(before.len(), model.parameter_layout().len());
    for index in 0..before.len() {
        let mut changed = model.clone();
        changed.set_parameter(index, before[index] + 0.125).unwrap();
        let mut expected = before.clone();
        expected[index] += 0.125;
        assert_eq!(changed.parameters(), expected, "parameter {index}");
    }
    assert!(model.clone().set_parameter(before.len(), 0.0).is_err());
}

/// URDF → MCPC → table (YAML text) → URDF → MCPC: the regenerated robot has the same tool
/// poses at random configurations (1e-9) and converts back to the same MCPC parameters.
fn check_round_trip(text: &str, origin: &str, tools: Option<&[&str]>) {
    use treecal::io::{mcpc_table_to_yaml, parse_mcpc_table};
    let tree = treecal::parse_urdf(text, origin).unwrap().tree;
    let branches = branches_with_tools(&tree, tools);
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    let table = treecal::McpcTable::from_model(&tree, &branches, &model).unwrap();
    let yaml = mcpc_table_to_yaml(&table, &["round trip".into()]);
    let table_again = parse_mcpc_table(&yaml, "round-trip.yaml").unwrap();
    let urdf = treecal::urdf_from_mcpc_table(&table_again, "round trip");
    let regenerated = treecal::parse_urdf(&urdf, "regenerated").unwrap().tree;
    let tool_names: Vec<String> = branches
        .tools()
        .iter()
        .map(|t| tree.link(*t).name.clone())
        .collect();
    let regenerated_tools: Vec<_> = tool_names
        .iter()
        .map(|n| regenerated.link_id(n).unwrap())
        .collect();
    let branches_again = detect_branches(&regenerated, Some(&regenerated_tools)).unwrap();
    let model_again = McpcModel::from_tree(&regenerated, &branches_again).unwrap();
    let (a, b) = (model.parameters(), model_again.parameters());
    assert_eq!(a.len(), b.len());
    let layout = model.parameter_layout();
    for (index, (x, y)) in a.iter().zip(&b).enumerate() {
        let difference = if layout[index].1.is_angle() {
            treecal::math::wrap_angle(x - y)
        } else {
            x - y
        };
        assert!(
            difference.abs() < 1e-9,
            "{origin}: parameter {index} ({:?}): {x} vs {y}\n{yaml}\n{text}",
            model.parameter_layout()[index]
        );
    }
    let mut rng = rng(3);
    for _ in 0..50 {
        let q = random_configuration(&tree, &mut rng);
        // The regenerated robot's joints take the original joint values (mimics included).
        let mut q_again = regenerated.zero_configuration();
        for (dof, joint) in regenerated.dofs().iter().enumerate() {
            let original = tree.joint_id(&regenerated.joint(*joint).name).unwrap();
            q_again[dof] = tree.joint_value(original, &q);
        }
        for (tool, name) in branches.tools().iter().zip(&tool_names) {
            let expected = tree.link_pose(*tool, &q).unwrap();
            let got = regenerated
                .link_pose(regenerated.link_id(name).unwrap(), &q_again)
                .unwrap();
            assert_pose_eq(&got, &expected, 1e-9, &format!("{origin}: {name}"));
        }
    }
}

#[test]
fn urdf_to_mcpc_to_urdf_round_trip() {
    for path in all_repo_robots().into_iter().chain([robonaut2()]) {
        let text = std::fs::read_to_string(&path).unwrap();
        check_round_trip(&text, &path.display().to_string(), None);
    }
    for seed in 0..50 {
        check_round_trip(
            &random_robot(seed),
            &format!("random robot {seed}"),
            Some(&["left_tool", "right_tool"]),
        );
    }
}

/// A palm that is the child link of the wrist joint (no fixed tool joint) survives
/// URDF → table → URDF: the table names the palm as the last row's link and as the tool, and
/// the regenerated URDF moves the palm with the wrist joint again (tool poses to 1e-9).
#[test]
fn palm_on_the_wrist_joint_round_trips_through_a_table() {
    let text = humanoid_with_palms_on_wrists();
    let tools = ["l_hand", "r_hand"];
    check_round_trip(&text, "palms on wrists", Some(&tools));

    let tree = treecal::parse_urdf(&text, "palms").unwrap().tree;
    let branches = branches_with_tools(&tree, Some(&tools));
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    let table = treecal::McpcTable::from_model(&tree, &branches, &model).unwrap();
    let carried: Vec<&str> = table
        .branches
        .iter()
        .filter_map(|b| b.carried_tool().map(|t| t.link.as_str()))
        .collect();
    assert_eq!(carried, tools);
    let urdf = treecal::urdf_from_mcpc_table(&table, "palms");
    let regenerated = treecal::parse_urdf(&urdf, "regenerated").unwrap().tree;
    for (tool, joint) in tools.iter().zip(["l_wrist_roll", "r_wrist_roll"]) {
        let parent = regenerated
            .link(regenerated.link_id(tool).unwrap())
            .parent_joint
            .unwrap();
        assert_eq!(regenerated.joint(parent).name, joint, "{urdf}");
    }
}

/// A table whose palm (the last row's link) lies off the wrist axis cannot be a URDF joint's
/// child: the joint then moves a `<palm>_mount` link and the palm hangs below it, at the same
/// pose (1e-9); a tool sharing a name with any other row is still rejected.
#[test]
fn palm_off_the_wrist_axis_gets_a_mount_link() {
    use treecal::io::parse_mcpc_table;
    let text = humanoid_with_palms_on_wrists();
    let tools = ["l_hand", "r_hand"];
    let tree = treecal::parse_urdf(&text, "palms").unwrap().tree;
    let branches = branches_with_tools(&tree, Some(&tools));
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    let mut table = treecal::McpcTable::from_model(&tree, &branches, &model).unwrap();
    let arm = table
        .branches
        .iter_mut()
        .find(|b| b.carried_tool().is_some_and(|t| t.link == "l_hand"))
        .unwrap();
    arm.tool.as_mut().unwrap().x += 0.004;
    let expected = arm.tool.as_ref().unwrap().transform();
    let urdf = treecal::urdf_from_mcpc_table(&table, "off axis");
    let regenerated = treecal::parse_urdf(&urdf, "off axis").unwrap().tree;
    let mount = regenerated.link_id("l_hand_mount").unwrap();
    let palm = regenerated.link_id("l_hand").unwrap();
    let q = regenerated.zero_configuration();
    let base_from_mount = regenerated.link_pose(mount, &q).unwrap();
    let base_from_palm = regenerated.link_pose(palm, &q).unwrap();
    // The mount is the moved wrist frame; the palm sits at the tool transform below it.
    assert_pose_eq(
        &(base_from_mount.inverse() * base_from_palm),
        &expected,
        1e-9,
        "palm below its mount",
    );
    let parent_of_mount = regenerated.link(mount).parent_joint.unwrap();
    assert_eq!(regenerated.joint(parent_of_mount).name, "l_wrist_roll");

    let duplicate = "robot: r\nunits: {angle: deg, length: mm}\nbranches:\n  - name: a\n    rows:\n      - {joint: j1, link: l1, alpha: 0, beta: 0, x: 0, y: 0}\n      - {joint: j2, link: l2, alpha: 0, beta: 0, x: 10, y: 0}\n    tool: {link: l1, alpha: 0, beta: 0, gamma: 0, x: 0, y: 0, z: 5}\n";
    let message = parse_mcpc_table(duplicate, "t.yaml")
        .unwrap_err()
        .to_string();
    assert!(message.contains("'l1' is used twice"), "{message}");
    let carried = duplicate.replace("tool: {link: l1", "tool: {link: l2");
    let table = parse_mcpc_table(&carried, "t.yaml").unwrap();
    assert!(table.branches[0].carried_tool().is_some());
}

/// The failing commands: `to-mcpc` then `from-mcpc` on a robot whose palms are the
/// wrist joints' children (before: "link name 'l_hand' is used twice"); the generated URDF's
/// palms are at the original palm poses (1e-9) at random configurations.
#[test]
fn cli_to_mcpc_and_from_mcpc_keep_a_palm_on_the_wrist_joint() {
    use crate::common::cli::*;
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("palms.urdf");
    let text = humanoid_with_palms_on_wrists();
    std::fs::write(&urdf, &text).unwrap();
    let table = dir.path().join("table.yaml");
    let run = treecal(&[
        "to-mcpc",
        path_str(&urdf),
        "--tools",
        "l_hand,r_hand",
        "-o",
        path_str(&table),
    ]);
    assert_success(&run, "to-mcpc");
    let generated = dir.path().join("generated.urdf");
    let run = treecal(&["from-mcpc", path_str(&table), "-o", path_str(&generated)]);
    assert_success(&run, "from-mcpc");
    let tree = treecal::parse_urdf(&text, "palms").unwrap().tree;
    let regenerated = treecal::load_urdf(&generated).unwrap().tree;
    let mut random = rng(12);
    for _ in 0..20 {
        let q = random_configuration(&tree, &mut random);
        let mut q_again = regenerated.zero_configuration();
        for (dof, joint) in regenerated.dofs().iter().enumerate() {
            let original = tree.joint_id(&regenerated.joint(*joint).name).unwrap();
            q_again[dof] = tree.joint_value(original, &q);
        }
        for palm in ["l_hand", "r_hand"] {
            let expected = tree.link_pose(tree.link_id(palm).unwrap(), &q).unwrap();
            let got = regenerated
                .link_pose(regenerated.link_id(palm).unwrap(), &q_again)
                .unwrap();
            assert_pose_eq(&got, &expected, 1e-9, palm);
        }
    }
}
