//! URDF import: every robot loads; bad files give clear errors that name the element and line;
//! nothing a user can write makes the importer panic.

use crate::common::*;
use rand::RngExt;
use treecal::tree::{Actuation, JointKind, KinematicTree, Shape};
use treecal::urdf::{load_urdf, parse_urdf, UrdfImport};

// ---------------------------------------------------------------------------------------------
// Helpers: small inline URDFs.
// ---------------------------------------------------------------------------------------------

/// The origin used in messages for inline documents.
const ORIGIN: &str = "test.urdf";

/// A complete document around `body` (the XML declaration is line 1, `<robot>` line 2).
fn doc(body: &str) -> String {
    format!("<?xml version=\"1.0\"?>\n<robot name=\"test\">\n{body}</robot>\n")
}

fn link(name: &str) -> String {
    format!("  <link name=\"{name}\"/>\n")
}

fn links(names: &[&str]) -> String {
    names.iter().map(|n| link(n)).collect()
}

/// A joint with arbitrary inner elements after `<parent>` and `<child>`.
fn joint_with(name: &str, kind: &str, parent: &str, child: &str, inner: &str) -> String {
    format!(
        "  <joint name=\"{name}\" type=\"{kind}\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n{inner}  </joint>\n"
    )
}

fn fixed(name: &str, parent: &str, child: &str) -> String {
    joint_with(name, "fixed", parent, child, "")
}

const LIMIT: &str = "    <limit lower=\"-2\" upper=\"2\" effort=\"10\" velocity=\"1\"/>\n";

/// A revolute joint about z with limits ±2 and `extra` inner elements.
fn revolute_with(name: &str, parent: &str, child: &str, extra: &str) -> String {
    joint_with(
        name,
        "revolute",
        parent,
        child,
        &format!("    <origin xyz=\"0 0 0.1\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 0 1\"/>\n{LIMIT}{extra}"),
    )
}

fn revolute(name: &str, parent: &str, child: &str) -> String {
    revolute_with(name, parent, child, "")
}

fn mimic(joint: &str, multiplier: f64, offset: f64) -> String {
    format!("    <mimic joint=\"{joint}\" multiplier=\"{multiplier}\" offset=\"{offset}\"/>\n")
}

fn parse(text: &str) -> treecal::Result<UrdfImport> {
    parse_urdf(text, ORIGIN)
}

/// Parses `text`, which must load.
#[track_caller]
fn ok(text: &str) -> UrdfImport {
    parse(text).unwrap_or_else(|e| panic!("expected the URDF to load, got: {e}\n{text}"))
}

/// Parses `text`, which must fail, and returns the message (checked to be a lower-case
/// sentence after the location).
#[track_caller]
fn err(text: &str) -> String {
    match parse(text) {
        Ok(import) => panic!(
            "expected an error, but the URDF loaded ({} links, warnings {:?})\n{text}",
            import.tree.links().len(),
            import.warnings
        ),
        Err(e) => {
            let message = e.to_string();
            eprintln!("error: {message}");
            assert_lower_case_sentence(&message);
            message
        }
    }
}

/// The 1-based line of the first occurrence of `needle` in `text`.
#[track_caller]
fn line_of(text: &str, needle: &str) -> usize {
    let at = text
        .find(needle)
        .unwrap_or_else(|| panic!("'{needle}' not in the document"));
    text[..at].matches('\n').count() + 1
}

/// Asserts that `message` is located at the line where `needle` first appears.
#[track_caller]
fn assert_at_line(message: &str, text: &str, needle: &str) {
    let prefix = format!("{ORIGIN}:{}: ", line_of(text, needle));
    assert!(
        message.starts_with(&prefix),
        "expected the message to start with '{prefix}', got: {message}"
    );
}

/// Every 1-based line on which `needle` appears.
fn lines_of(text: &str, needle: &str) -> Vec<usize> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| l.contains(needle))
        .map(|(i, _)| i + 1)
        .collect()
}

/// Asserts that `message` is located at one of `lines` (e.g. either of two duplicates).
#[track_caller]
fn assert_at_one_of(message: &str, lines: &[usize]) {
    assert!(
        lines.len() >= 2,
        "expected duplicates, found lines {lines:?}"
    );
    assert!(
        lines
            .iter()
            .any(|line| message.starts_with(&format!("{ORIGIN}:{line}: "))),
        "expected the message to point at one of lines {lines:?}, got: {message}"
    );
}

#[track_caller]
fn assert_contains(message: &str, expected: &str) {
    assert!(
        message.contains(expected),
        "expected the message to contain \"{expected}\", got: {message}"
    );
}

/// A message is a lower-case sentence after its location prefix.
#[track_caller]
fn assert_lower_case_sentence(message: &str) {
    let sentence = message
        .strip_prefix(ORIGIN)
        .map(|rest| rest.trim_start_matches(|c: char| c == ':' || c.is_ascii_digit()))
        .unwrap_or(message)
        .trim_start();
    let first = sentence.chars().next().expect("empty message");
    assert!(
        !first.is_uppercase(),
        "message should be a lower-case sentence: {message}"
    );
}

/// `world → base_link → l1 → l2` with `j1`, `j2` revolute about z.
fn arm() -> String {
    doc(&format!(
        "{}{}{}{}",
        links(&["world", "base_link", "l1", "l2"]),
        fixed("world_to_base", "world", "base_link"),
        revolute("j1", "base_link", "l1"),
        revolute("j2", "l1", "l2"),
    ))
}

fn joint_id(tree: &KinematicTree, name: &str) -> treecal::tree::JointId {
    tree.joint_id(name).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn minimal_arm_loads() {
    let import = ok(&arm());
    assert!(import.warnings.is_empty(), "{:?}", import.warnings);
    let tree = &import.tree;
    assert_eq!(tree.links().len(), 4);
    assert_eq!(tree.joints().len(), 3);
    assert_eq!(tree.dof_count(), 2);
    assert_eq!(tree.link(tree.root()).name, "world");
    assert_eq!(tree.name(), "test");
}

// ---------------------------------------------------------------------------------------------
// 1. Floating, planar and spherical joints.
// ---------------------------------------------------------------------------------------------

#[test]
fn floating_joint_below_the_root_is_rejected() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["world", "base_link", "object"]),
        fixed("world_to_base", "world", "base_link"),
        joint_with("object_float", "floating", "base_link", "object", ""),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"object_float\"");
    assert_contains(&message, "joint 'object_float' has type floating");
    assert_contains(&message, "which treecal does not support");
}

#[test]
fn planar_joint_below_the_root_is_rejected() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["world", "base_link", "slider"]),
        fixed("world_to_base", "world", "base_link"),
        joint_with("slide_plane", "planar", "base_link", "slider", ""),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"slide_plane\"");
    assert_contains(&message, "joint 'slide_plane' has type planar");
}

#[test]
fn floating_root_joint_is_accepted_as_fixed_with_a_warning() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["world", "base_link", "l1"]),
        joint_with(
            "world_to_base",
            "floating",
            "world",
            "base_link",
            "    <origin xyz=\"0 0 1\"/>\n"
        ),
        revolute("j1", "base_link", "l1"),
    ));
    let import = ok(&text);
    assert_eq!(import.warnings.len(), 1, "{:?}", import.warnings);
    assert_contains(&import.warnings[0], "joint 'world_to_base'");
    assert_contains(&import.warnings[0], "floating");
    assert_contains(&import.warnings[0], "treating it as fixed");
    let tree = &import.tree;
    let root_joint = tree.joint(joint_id(tree, "world_to_base"));
    assert_eq!(root_joint.kind, JointKind::Fixed);
    assert_eq!(root_joint.actuation, Actuation::None);
    assert_eq!(tree.dof_count(), 1);
    // The origin of the floating joint is kept as the fixed placement.
    let poses = tree.link_poses(&[0.0]).unwrap();
    let base = tree.link_id("base_link").unwrap();
    assert!((poses[base.0].translation.vector.z - 1.0).abs() < 1e-12);
}

#[test]
fn planar_root_joint_is_accepted_as_fixed_with_a_warning() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["world", "base_link", "l1"]),
        joint_with("world_plane", "planar", "world", "base_link", ""),
        revolute("j1", "base_link", "l1"),
    ));
    let import = ok(&text);
    assert_eq!(import.warnings.len(), 1, "{:?}", import.warnings);
    assert_contains(
        &import.warnings[0],
        "joint 'world_plane' is planar at the root",
    );
    assert_eq!(import.tree.dof_count(), 1);
}

#[test]
fn spherical_joint_is_rejected() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["world", "base_link", "ball"]),
        fixed("world_to_base", "world", "base_link"),
        joint_with("shoulder_ball", "spherical", "base_link", "ball", ""),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"shoulder_ball\"");
    assert_contains(&message, "joint 'shoulder_ball' has type spherical");
}

#[test]
fn spherical_joint_at_the_root_is_rejected_too() {
    let text = doc(&format!(
        "{}{}",
        links(&["world", "base_link"]),
        joint_with("world_ball", "spherical", "world", "base_link", ""),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"world_ball\"");
    assert_contains(&message, "joint 'world_ball' has type spherical");
}

#[test]
fn unknown_joint_type_is_a_clear_parse_error() {
    let text = doc(&format!(
        "{}{}",
        links(&["world", "base_link"]),
        joint_with("weird", "telescopic", "world", "base_link", ""),
    ));
    let message = err(&text);
    assert!(message.starts_with(ORIGIN), "{message}");
    assert_contains(&message, "telescopic");
}

// ---------------------------------------------------------------------------------------------
// 2. Roots, cycles, links with two parents.
// ---------------------------------------------------------------------------------------------

#[test]
fn multiple_roots_are_rejected_naming_the_roots() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["base_link", "l1", "stray_a", "stray_b", "stray_child"]),
        revolute("j1", "base_link", "l1"),
        fixed("stray_joint", "stray_b", "stray_child"),
    ));
    let message = err(&text);
    assert!(message.starts_with(&format!("{ORIGIN}: ")), "{message}");
    assert_contains(&message, "3 root links (base_link, stray_a, stray_b)");
    assert_contains(&message, "connect all but one");
}

#[test]
fn cycle_where_every_link_has_a_parent_is_rejected() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["a", "b"]),
        fixed("a_to_b", "a", "b"),
        fixed("b_to_a", "b", "a"),
    ));
    let message = err(&text);
    assert!(message.starts_with(ORIGIN), "{message}");
    assert_contains(&message, "cycle");
    // The message names the joints on the cycle so the user can find them, and points at the
    // first of them in the file.
    assert_at_line(&message, &text, "<joint name=\"a_to_b\"");
    assert_contains(&message, "no root link");
    assert_contains(
        &message,
        "joints 'a_to_b', 'b_to_a' form a cycle (a → b → a)",
    );
}

#[test]
fn cycle_hanging_off_a_tree_names_only_the_cycle() {
    // Two roots would be reported first if the cycle had no link without parent, so this
    // robot has one proper root and a separate cycle c → d → e → c with a leaf f below it.
    let text = doc(&format!(
        "{}{}{}{}{}{}",
        links(&["base_link", "l1", "c", "d", "e", "f"]),
        revolute("j1", "base_link", "l1"),
        fixed("c_to_d", "c", "d"),
        fixed("d_to_e", "d", "e"),
        fixed("e_to_c", "e", "c"),
        fixed("e_to_f", "e", "f"),
    ));
    let message = err(&text);
    assert!(message.starts_with(ORIGIN), "{message}");
    assert_contains(&message, "cycle");
    assert_at_line(&message, &text, "<joint name=\"c_to_d\"");
    assert_contains(
        &message,
        "joints 'c_to_d', 'd_to_e', 'e_to_c' form a cycle (c → d → e → c)",
    );
    assert!(
        !message.contains("e_to_f"),
        "the leaf below the cycle is not part of it: {message}"
    );
    assert_contains(&message, "'base_link'");
}

#[test]
fn self_loop_joint_is_rejected() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["base_link", "l1"]),
        revolute("j1", "base_link", "l1"),
        fixed("loop", "l1", "l1"),
    ));
    let message = err(&text);
    assert_contains(&message, "'l1'");
    assert_contains(&message, "'loop'");
}

#[test]
fn link_with_two_parent_joints_is_rejected_naming_both() {
    let text = doc(&format!(
        "{}{}{}{}",
        links(&["base_link", "l1", "l2"]),
        revolute("j1", "base_link", "l1"),
        revolute("j2", "base_link", "l2"),
        fixed("second_parent", "l1", "l2"),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"second_parent\"");
    assert_contains(
        &message,
        "link 'l2' is the child of both joint 'j2' and joint 'second_parent'",
    );
}

// ---------------------------------------------------------------------------------------------
// 3. Unknown links.
// ---------------------------------------------------------------------------------------------

#[test]
fn unknown_parent_link_is_named_with_a_hint() {
    let text = doc(&format!(
        "{}{}",
        links(&["base_link", "l1"]),
        revolute("j1", "base_lnk", "l1"),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"j1\"");
    assert_contains(
        &message,
        "joint 'j1' names parent link 'base_lnk', which does not exist; did you mean 'base_link'?",
    );
}

#[test]
fn unknown_child_link_is_named_with_a_hint() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["base_link", "upper_arm", "forearm"]),
        revolute("shoulder", "base_link", "upper_arm"),
        revolute("elbow", "upper_arm", "forarm"),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"elbow\"");
    assert_contains(
        &message,
        "joint 'elbow' names child link 'forarm', which does not exist; did you mean 'forearm'?",
    );
}

#[test]
fn unknown_link_far_from_every_name_gets_no_hint() {
    let text = doc(&format!(
        "{}{}",
        links(&["base_link", "l1"]),
        revolute("j1", "base_link", "completely_different"),
    ));
    let message = err(&text);
    assert_contains(
        &message,
        "joint 'j1' names child link 'completely_different', which does not exist",
    );
    assert!(!message.contains("did you mean"), "{message}");
}

// ---------------------------------------------------------------------------------------------
// 4. Duplicate names.
// ---------------------------------------------------------------------------------------------

#[test]
fn duplicate_link_name_is_rejected_with_the_line() {
    let text = doc(&format!(
        "{}{}",
        links(&["base_link", "l1", "l1"]),
        revolute("j1", "base_link", "l1"),
    ));
    let message = err(&text);
    assert_at_one_of(&message, &lines_of(&text, "<link name=\"l1\""));
    assert_contains(&message, "link name 'l1' is used twice");
}

#[test]
fn duplicate_joint_name_is_rejected_with_the_line() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["base_link", "l1", "l2"]),
        revolute("j1", "base_link", "l1"),
        revolute("j1", "l1", "l2"),
    ));
    let message = err(&text);
    assert_at_one_of(&message, &lines_of(&text, "<joint name=\"j1\""));
    assert_contains(&message, "joint name 'j1' is used twice");
}

#[test]
fn a_link_and_a_joint_may_share_a_name() {
    // URDF namespaces links and joints separately.
    let text = doc(&format!(
        "{}{}",
        links(&["base_link", "elbow"]),
        revolute("elbow", "base_link", "elbow"),
    ));
    let tree = ok(&text).tree;
    assert_eq!(
        tree.joint(joint_id(&tree, "elbow")).child,
        tree.link_id("elbow").unwrap()
    );
}

// ---------------------------------------------------------------------------------------------
// 5. Non-finite numbers.
// ---------------------------------------------------------------------------------------------

fn arm_with_j2_origin(origin: &str) -> String {
    doc(&format!(
        "{}{}{}",
        links(&["base_link", "l1", "l2"]),
        revolute("j1", "base_link", "l1"),
        joint_with(
            "j2",
            "revolute",
            "l1",
            "l2",
            &format!("    {origin}\n    <axis xyz=\"0 0 1\"/>\n{LIMIT}")
        ),
    ))
}

#[test]
fn nan_in_joint_origin_xyz_is_rejected_with_joint_and_line() {
    let text = arm_with_j2_origin("<origin xyz=\"0 nan 0\" rpy=\"0 0 0\"/>");
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"j2\"");
    assert_contains(&message, "joint 'j2' has a non-finite <origin>");
    assert_contains(&message, "NaN");
}

#[test]
fn inf_in_joint_origin_rpy_is_rejected_with_joint_and_line() {
    let text = arm_with_j2_origin("<origin xyz=\"0 0 0\" rpy=\"0 inf 0\"/>");
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"j2\"");
    assert_contains(&message, "joint 'j2' has a non-finite <origin>");
    assert_contains(&message, "inf");
}

#[test]
fn overflowing_number_in_joint_origin_is_rejected() {
    // 1e400 parses as +inf.
    let text = arm_with_j2_origin("<origin xyz=\"1e400 0 0\"/>");
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"j2\"");
    assert_contains(&message, "joint 'j2' has a non-finite <origin>");
}

#[test]
fn malformed_number_in_joint_origin_is_a_clear_parse_error() {
    let text = arm_with_j2_origin("<origin xyz=\"0 abc 0\"/>");
    let message = err(&text);
    assert!(message.starts_with(ORIGIN), "{message}");
    assert_contains(&message, "0 abc 0");
}

fn link_with_inertial(name: &str, mass: &str, ixx: &str, origin: &str) -> String {
    format!(
        "  <link name=\"{name}\">\n    <inertial>\n      <origin xyz=\"{origin}\"/>\n      <mass value=\"{mass}\"/>\n      <inertia ixx=\"{ixx}\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/>\n    </inertial>\n  </link>\n"
    )
}

fn arm_with_l1(l1: &str) -> String {
    doc(&format!(
        "{}{l1}{}",
        link("base_link"),
        revolute("j1", "base_link", "l1"),
    ))
}

#[test]
fn nan_mass_is_rejected_naming_the_link() {
    let text = arm_with_l1(&link_with_inertial("l1", "nan", "1", "0 0 0"));
    let message = err(&text);
    assert_at_line(&message, &text, "<link name=\"l1\"");
    assert_contains(&message, "link 'l1' has a non-finite value in <inertial>");
}

#[test]
fn nan_inertia_is_rejected_naming_the_link() {
    let text = arm_with_l1(&link_with_inertial("l1", "1", "NaN", "0 0 0"));
    let message = err(&text);
    assert_at_line(&message, &text, "<link name=\"l1\"");
    assert_contains(&message, "link 'l1' has a non-finite value in <inertial>");
}

#[test]
fn inf_inertial_origin_is_rejected_naming_the_link() {
    let text = arm_with_l1(&link_with_inertial("l1", "1", "1", "0 -inf 0"));
    let message = err(&text);
    assert_at_line(&message, &text, "<link name=\"l1\"");
    assert_contains(&message, "link 'l1' has a non-finite value in <inertial>");
}

#[test]
fn negative_mass_is_rejected_naming_the_link() {
    let text = arm_with_l1(&link_with_inertial("l1", "-2", "1", "0 0 0"));
    let message = err(&text);
    assert_at_line(&message, &text, "<link name=\"l1\"");
    assert_contains(&message, "link 'l1' has negative mass -2");
}

#[test]
fn valid_inertial_is_kept() {
    let text = arm_with_l1(&link_with_inertial("l1", "2.5", "0.1", "0 0 0.2"));
    let tree = ok(&text).tree;
    let inertial = tree
        .link(tree.link_id("l1").unwrap())
        .inertial
        .as_ref()
        .unwrap();
    assert_eq!(inertial.mass, 2.5);
    assert!(tree.link(tree.root()).inertial.is_none());
}

#[test]
fn nan_in_visual_origin_is_rejected_naming_the_link() {
    let l1 = "  <link name=\"l1\">\n    <visual>\n      <origin xyz=\"0 0 nan\"/>\n      <geometry><box size=\"1 1 1\"/></geometry>\n    </visual>\n  </link>\n";
    let text = arm_with_l1(l1);
    let message = err(&text);
    assert_at_line(&message, &text, "<link name=\"l1\"");
    assert_contains(&message, "link 'l1' has a non-finite geometry <origin>");
}

// ---------------------------------------------------------------------------------------------
// 6. Axes.
// ---------------------------------------------------------------------------------------------

fn arm_with_j1_axis(axis: &str) -> String {
    doc(&format!(
        "{}{}{}",
        links(&["base_link", "l1", "l2"]),
        joint_with(
            "j1",
            "revolute",
            "base_link",
            "l1",
            &format!(
                "    <origin xyz=\"0.1 0.2 0.3\" rpy=\"0.3 -0.2 0.1\"/>\n    <axis xyz=\"{axis}\"/>\n{LIMIT}"
            )
        ),
        joint_with(
            "j2",
            "fixed",
            "l1",
            "l2",
            "    <origin xyz=\"0.5 0 0\" rpy=\"0 0.4 0\"/>\n"
        ),
    ))
}

#[test]
fn zero_axis_on_revolute_joint_is_rejected() {
    let text = arm_with_j1_axis("0 0 0");
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"j1\"");
    assert_contains(
        &message,
        "joint 'j1' has axis \"0 0 0\", which has no direction",
    );
}

#[test]
fn zero_axis_on_prismatic_joint_is_rejected() {
    let text = arm_with_j1_axis("0 0 0").replace("type=\"revolute\"", "type=\"prismatic\"");
    let message = err(&text);
    assert_contains(&message, "joint 'j1' has axis \"0 0 0\"");
}

#[test]
fn nan_axis_is_rejected() {
    let message = err(&arm_with_j1_axis("0 nan 1"));
    assert_contains(&message, "joint 'j1' has axis");
}

#[test]
fn zero_axis_on_fixed_joint_does_not_matter() {
    let text = doc(&format!(
        "{}{}",
        links(&["base_link", "l1"]),
        joint_with(
            "f",
            "fixed",
            "base_link",
            "l1",
            "    <axis xyz=\"0 0 0\"/>\n"
        ),
    ));
    ok(&text);
}

#[test]
fn non_unit_axis_is_normalised() {
    let scaled = ok(&arm_with_j1_axis("0 0 2")).tree;
    let unit = ok(&arm_with_j1_axis("0 0 1")).tree;
    let axis = scaled.joint(joint_id(&scaled, "j1")).axis;
    assert!(
        (axis.norm() - 1.0).abs() < 1e-15,
        "axis {axis:?} is not unit"
    );
    assert!((axis.z - 1.0).abs() < 1e-15);
    let q = [0.3];
    let a = scaled.link_poses(&q).unwrap();
    let b = unit.link_poses(&q).unwrap();
    for (index, (pa, pb)) in a.iter().zip(&b).enumerate() {
        assert_pose_eq(pa, pb, 1e-12, &scaled.links()[index].name);
    }
    // and the rotation really is 0.3 rad about the (normalised) axis, not 0.6
    let tip = scaled.link_id("l1").unwrap();
    let angle = a[tip.0]
        .rotation
        .angle_to(&scaled.link_poses(&[0.0]).unwrap()[tip.0].rotation);
    assert!((angle - 0.3).abs() < 1e-12, "angle {angle}");
}

#[test]
fn oblique_non_unit_axis_is_normalised() {
    let tree = ok(&arm_with_j1_axis("3 0 4")).tree;
    let axis = tree.joint(joint_id(&tree, "j1")).axis;
    assert!(
        (axis.x - 0.6).abs() < 1e-15 && (axis.z - 0.8).abs() < 1e-15,
        "{axis:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// 7. Mimic joints.
// ---------------------------------------------------------------------------------------------

/// base_link → a → b → c, all revolute; `b_extra`/`c_extra` go inside joints b and c.
fn mimic_chain(a_extra: &str, b_extra: &str, c_extra: &str) -> String {
    doc(&format!(
        "{}{}{}{}",
        links(&["base_link", "la", "lb", "lc"]),
        revolute_with("a", "base_link", "la", a_extra),
        revolute_with("b", "la", "lb", b_extra),
        revolute_with("c", "lb", "lc", c_extra),
    ))
}

#[test]
fn simple_mimic_is_a_dependent_joint() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["base_link", "l1", "l2"]),
        revolute("master", "base_link", "l1"),
        revolute_with("follower", "l1", "l2", &mimic("master", -1.0, 0.1)),
    ));
    let tree = ok(&text).tree;
    assert_eq!(tree.dof_count(), 1);
    let master = joint_id(&tree, "master");
    let follower = joint_id(&tree, "follower");
    assert_eq!(tree.dofs(), &[master]);
    assert_eq!(tree.dof_of(follower), None);
    match tree.joint(follower).actuation {
        Actuation::Mimic {
            master: dof,
            multiplier,
            offset,
        } => {
            assert_eq!(Some(dof), tree.dof_of(master));
            assert_eq!(multiplier, -1.0);
            assert_eq!(offset, 0.1);
        }
        other => panic!("expected a mimic, got {other:?}"),
    }
    for q in [0.0, 0.5, -1.2] {
        assert!((tree.joint_value(master, &[q]) - q).abs() < 1e-15);
        assert!((tree.joint_value(follower, &[q]) - (-q + 0.1)).abs() < 1e-15);
    }
}

#[test]
fn mimic_without_multiplier_and_offset_defaults_to_identity() {
    let text = mimic_chain("", "    <mimic joint=\"a\"/>\n", "");
    let tree = ok(&text).tree;
    assert_eq!(tree.dof_count(), 2);
    let b = joint_id(&tree, "b");
    let q = [0.7, -0.2];
    assert!((tree.joint_value(b, &q) - 0.7).abs() < 1e-15);
}

#[test]
fn mimic_chain_resolves_to_the_independent_joint() {
    // c = 2·b + 0.1, b = 3·a + 0.2  ⇒  c = 6·a + 0.5
    let text = mimic_chain("", &mimic("a", 3.0, 0.2), &mimic("b", 2.0, 0.1));
    let tree = ok(&text).tree;
    assert_eq!(tree.dof_count(), 1);
    let a = joint_id(&tree, "a");
    let c = joint_id(&tree, "c");
    match tree.joint(c).actuation {
        Actuation::Mimic {
            master,
            multiplier,
            offset,
        } => {
            assert_eq!(Some(master), tree.dof_of(a));
            assert!((multiplier - 6.0).abs() < 1e-12, "{multiplier}");
            assert!((offset - 0.5).abs() < 1e-12, "{offset}");
        }
        other => panic!("expected a mimic, got {other:?}"),
    }
    let q = [0.4];
    assert!((tree.joint_value(c, &q) - (6.0 * 0.4 + 0.5)).abs() < 1e-12);
}

#[test]
fn mimic_chain_pointing_down_the_tree_resolves_too() {
    // The independent joint is the deepest one: a = 2·b + 0.1, b = 3·c + 0.2 ⇒ a = 6·c + 0.5.
    let text = mimic_chain(&mimic("b", 2.0, 0.1), &mimic("c", 3.0, 0.2), "");
    let tree = ok(&text).tree;
    assert_eq!(tree.dof_count(), 1);
    let a = joint_id(&tree, "a");
    let b = joint_id(&tree, "b");
    let c = joint_id(&tree, "c");
    assert_eq!(tree.dofs(), &[c]);
    let q = [-0.3];
    assert!((tree.joint_value(b, &q) - (3.0 * -0.3 + 0.2)).abs() < 1e-12);
    assert!((tree.joint_value(a, &q) - (6.0 * -0.3 + 0.5)).abs() < 1e-12);
}

#[test]
fn mimic_cycle_is_rejected() {
    let text = mimic_chain("", &mimic("c", 1.0, 0.0), &mimic("b", 1.0, 0.0));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"b\"");
    assert_contains(&message, "cycle");
    assert_contains(
        &message,
        "mimic joints b → c → b follow each other in a cycle",
    );
}

#[test]
fn mimic_of_itself_is_rejected() {
    let text = mimic_chain("", &mimic("b", 1.0, 0.0), "");
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"b\"");
    assert_contains(&message, "mimic joints b → b follow each other in a cycle");
}

/// urdfdom (check_urdf, Pinocchio) accepts a <mimic> of a joint that does not exist and
/// ignores it; so does treecal, with a warning, and the joint is independent.
#[test]
fn mimic_of_an_unknown_joint_is_a_warning_and_the_joint_is_independent() {
    let text = mimic_chain("", &mimic("aa", 1.0, 0.0), "");
    let import = ok(&text);
    assert_eq!(import.warnings.len(), 1, "{:?}", import.warnings);
    let message = &import.warnings[0];
    assert_contains(
        message,
        "joint 'b' mimics joint 'aa', which does not exist; did you mean 'a'?; treating 'b' as an independent joint",
    );
    let b = joint_id(&import.tree, "b");
    assert!(import.tree.dof_of(b).is_some());
    // near miss of the real joint name
    let text = doc(&format!(
        "{}{}{}",
        links(&["base_link", "l1", "l2"]),
        revolute("l_finger_left", "base_link", "l1"),
        revolute_with(
            "l_finger_right",
            "l1",
            "l2",
            &mimic("l_fingr_left", -1.0, 0.0)
        ),
    ));
    let import = ok(&text);
    assert_contains(
        &import.warnings.join("\n"),
        "mimics joint 'l_fingr_left', which does not exist; did you mean 'l_finger_left'?",
    );
}

#[test]
fn mimic_of_a_fixed_joint_is_rejected() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["base_link", "l1", "l2"]),
        fixed("bracket", "base_link", "l1"),
        revolute_with("follower", "l1", "l2", &mimic("bracket", 1.0, 0.0)),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"follower\"");
    assert_contains(
        &message,
        "joint 'follower' mimics joint 'bracket', which is fixed",
    );
}

#[test]
fn non_finite_mimic_multiplier_is_rejected() {
    let text = mimic_chain(
        "",
        "    <mimic joint=\"a\" multiplier=\"nan\" offset=\"0\"/>\n",
        "",
    );
    let message = err(&text);
    assert!(message.starts_with(ORIGIN), "{message}");
    assert_contains(&message, "'b'");
}

// ---------------------------------------------------------------------------------------------
// 8. Missing meshes.
// ---------------------------------------------------------------------------------------------

#[test]
fn missing_meshes_do_not_matter() {
    let l1 = "  <link name=\"l1\">\n    <visual>\n      <geometry><mesh filename=\"package://nowhere/x.stl\"/></geometry>\n    </visual>\n    <collision>\n      <geometry><mesh filename=\"file:///does/not/exist.dae\" scale=\"0.001 0.001 0.001\"/></geometry>\n    </collision>\n  </link>\n";
    let text = arm_with_l1(l1);
    let import = ok(&text);
    assert!(import.warnings.is_empty(), "{:?}", import.warnings);
    let tree = &import.tree;
    let geometry = &tree.link(tree.link_id("l1").unwrap()).geometry;
    assert_eq!(geometry.visuals.len(), 1);
    assert_eq!(geometry.collisions.len(), 1);
    match &geometry.visuals[0].1 {
        Shape::Mesh { filename, .. } => assert_eq!(filename, "package://nowhere/x.stl"),
        other => panic!("expected a mesh, got {other:?}"),
    }
    // and a file on disk with missing meshes loads too
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("meshes.urdf");
    std::fs::write(&path, &text).unwrap();
    load_urdf(&path).unwrap_or_else(|e| panic!("{e}"));
}

// ---------------------------------------------------------------------------------------------
// 9. Messy real-file features.
// ---------------------------------------------------------------------------------------------

#[test]
fn whitespace_inside_numbers_is_accepted() {
    let text = arm_with_j2_origin("<origin xyz=\"  0.1   0.2\t0.3 \" rpy=\"\n 0   0\t 0.5\n\"/>");
    let tree = ok(&text).tree;
    let j2 = tree.joint(joint_id(&tree, "j2"));
    let t = j2.parent_from_joint.translation.vector;
    assert!((t.x - 0.1).abs() < 1e-15 && (t.y - 0.2).abs() < 1e-15 && (t.z - 0.3).abs() < 1e-15);
    let limit_text = doc(&format!(
        "{}{}",
        links(&["base_link", "l1"]),
        joint_with(
            "j1",
            "revolute",
            "base_link",
            "l1",
            "    <axis xyz=\" 0 0 1 \"/>\n    <limit lower=\" -1.5 \" upper=\"1.5  \" effort=\"1\" velocity=\"1\"/>\n"
        ),
    ));
    let tree = ok(&limit_text).tree;
    let limits = tree.joint(joint_id(&tree, "j1")).limits.unwrap();
    assert_eq!((limits.lower, limits.upper), (-1.5, 1.5));
}

#[test]
fn names_with_slashes_are_accepted() {
    let text = doc(&format!(
        "{}{}{}",
        links(&["r2/base", "r2/left/upper_arm", "r2/left/forearm"]),
        revolute("r2/left/joint0", "r2/base", "r2/left/upper_arm"),
        revolute("r2/left/joint1", "r2/left/upper_arm", "r2/left/forearm"),
    ));
    let tree = ok(&text).tree;
    assert_eq!(tree.dof_count(), 2);
    assert!(tree.link_id("r2/left/forearm").is_ok());
    // and the line finder handles them in messages
    let bad = text.replace(
        "<child link=\"r2/left/forearm\"/>",
        "<child link=\"r2/left/forarm\"/>",
    );
    let message = err(&bad);
    assert_at_line(&message, &bad, "<joint name=\"r2/left/joint1\"");
    assert_contains(&message, "did you mean 'r2/left/forearm'?");
}

#[test]
fn children_declared_before_parents_are_accepted_in_topological_order() {
    let text = doc(&format!(
        "{}{}{}{}{}",
        revolute("j2", "l1", "l2"),
        link("l2"),
        revolute("j1", "base_link", "l1"),
        link("l1"),
        link("base_link"),
    ));
    let tree = ok(&text).tree;
    let names: Vec<&str> = tree.links().iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["base_link", "l1", "l2"]);
    let dofs: Vec<&str> = tree
        .dofs()
        .iter()
        .map(|&j| tree.joint(j).name.as_str())
        .collect();
    assert_eq!(dofs, ["j1", "j2"]);
    assert_topological(&tree, "inline");
}

#[test]
fn leftover_xacro_namespace_and_elements_are_ignored() {
    let text = format!(
        "<?xml version=\"1.0\"?>\n<robot name=\"test\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n  <xacro:property name=\"length\" value=\"0.5\"/>\n  <xacro:macro name=\"unused\" params=\"x\">\n    <link name=\"${{x}}\"/>\n  </xacro:macro>\n{}{}{}</robot>\n",
        links(&["base_link", "l1", "l2"]),
        revolute("j1", "base_link", "l1"),
        revolute("j2", "l1", "l2"),
    );
    let import = ok(&text);
    assert_eq!(import.tree.links().len(), 3);
    assert_eq!(import.tree.dof_count(), 2);
}

#[test]
fn undeclared_xacro_prefix_is_a_clear_error_or_ignored() {
    // No xmlns:xacro declaration at all: urdf-rs may reject the document; either way no panic,
    // and a rejection names the origin.
    let text = doc(&format!(
        "  <xacro:property name=\"length\" value=\"0.5\"/>\n{}{}",
        links(&["base_link", "l1"]),
        revolute("j1", "base_link", "l1"),
    ));
    match parse(&text) {
        Ok(import) => {
            eprintln!("loaded with warnings {:?}", import.warnings);
            assert_eq!(import.tree.links().len(), 2);
        }
        Err(e) => {
            eprintln!("error: {e}");
            assert!(e.to_string().starts_with(ORIGIN), "{e}");
        }
    }
}

#[test]
fn unexpanded_xacro_expression_in_a_number_is_a_clear_error() {
    let text = arm_with_j2_origin("<origin xyz=\"0 0 ${length}\"/>");
    let message = err(&text);
    assert!(message.starts_with(ORIGIN), "{message}");
    assert_contains(&message, "${length}");
}

#[test]
fn comments_transmissions_and_gazebo_elements_are_ignored() {
    let text = doc(&format!(
        "  <!-- a comment with <link name=\"ghost\"/> inside -->\n{}{}  <transmission name=\"t1\"><type>transmission_interface/SimpleTransmission</type><joint name=\"j1\"/></transmission>\n  <gazebo reference=\"l1\"><material>Gazebo/Blue</material></gazebo>\n",
        links(&["base_link", "l1"]),
        revolute("j1", "base_link", "l1"),
    ));
    let tree = ok(&text).tree;
    assert_eq!(tree.links().len(), 2);
    assert!(tree.link_id("ghost").is_err());
}

#[test]
fn single_quoted_attributes_give_lines_too() {
    let text = doc(&format!(
        "{}  <joint name='j1' type='revolute'>\n    <parent link='base_lnk'/>\n    <child link='l1'/>\n  </joint>\n",
        links(&["base_link", "l1"]),
    ));
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name='j1'");
    assert_contains(&message, "did you mean 'base_link'?");
}

// ---------------------------------------------------------------------------------------------
// 10. Not a URDF.
// ---------------------------------------------------------------------------------------------

#[test]
fn not_xml_is_a_clear_error_naming_the_origin() {
    let message = err("this is not xml at all { \"json\": true }");
    assert!(
        message.starts_with(&format!("{ORIGIN}:1: not a readable URDF")),
        "{message}"
    );
    assert_contains(&message, "text before the root element");
}

#[test]
fn empty_string_is_a_clear_error_naming_the_origin() {
    let message = err("");
    assert!(message.starts_with(&format!("{ORIGIN}: ")), "{message}");
    let message = err("   \n\t\n");
    assert!(message.starts_with(&format!("{ORIGIN}: ")), "{message}");
}

#[test]
fn unclosed_xml_is_a_clear_error_naming_the_origin() {
    let message = err("<robot name=\"x\">\n<link name=\"a\">");
    assert_eq!(
        message,
        format!("{ORIGIN}:2: not a readable URDF: element <link> is never closed")
    );
}

#[test]
fn robot_without_links_is_a_clear_error() {
    let message = err("<robot name=\"empty\"></robot>");
    assert_eq!(
        message,
        format!("{ORIGIN}: the robot has no <link> elements")
    );
    let message = err("<robot name=\"empty\"/>");
    assert_eq!(
        message,
        format!("{ORIGIN}: the robot has no <link> elements")
    );
}

#[test]
fn other_root_element_is_a_clear_error() {
    let message = err("<?xml version=\"1.0\"?>\n<sdf version=\"1.6\"><model name=\"m\"/></sdf>");
    assert_eq!(
        message,
        format!("{ORIGIN}:2: not a readable URDF: the root element is <sdf>; a URDF's root element is <robot>")
    );
}

/// A robot whose link `l1` holds `depth` nested unknown elements.
fn deeply_nested(depth: usize) -> String {
    let l1 = format!(
        "  <link name=\"l1\">\n{}{}  </link>\n",
        "<x a=\"1>2\">\n".repeat(depth),
        "</x>\n".repeat(depth)
    );
    arm_with_l1(&l1)
}

#[test]
fn moderately_nested_unknown_elements_are_ignored() {
    let text = deeply_nested(100);
    let tree = ok(&text).tree;
    assert_eq!(tree.links().len(), 2);
}

#[test]
fn absurdly_deep_nesting_is_an_error_not_a_stack_overflow() {
    // urdf-rs recurses per level; without a guard this aborts the process (test threads
    // have 2 MiB stacks and overflowed at about 10 000 levels).
    let text = deeply_nested(100_000);
    let message = err(&text);
    assert!(message.starts_with(&format!("{ORIGIN}:")), "{message}");
    assert_contains(&message, "nested more than 256 levels deep");
    // the line is where the limit is crossed: the link's line + 256 (robot is level 1)
    let line = line_of(&text, "<link name=\"l1\"") + 255;
    assert!(
        message.starts_with(&format!("{ORIGIN}:{line}: ")),
        "{message}"
    );
}

#[test]
fn nesting_scan_skips_comments_cdata_and_quoted_brackets() {
    // 400 unbalanced '<x>' inside a comment, CDATA and attribute values do not count as
    // nesting.
    let noise = format!(
        "  <!-- {} -->\n  <gazebo><![CDATA[{}]]></gazebo>\n  <gazebo reference=\"{}\"/>\n",
        "<x>".repeat(400),
        "<x>".repeat(400),
        "&lt;x&gt;".repeat(10),
    );
    let text = doc(&format!(
        "{noise}{}{}",
        links(&["base_link", "l1"]),
        revolute("j1", "base_link", "l1"),
    ));
    let tree = ok(&text).tree;
    assert_eq!(tree.links().len(), 2);
}

#[test]
fn single_link_robot_loads() {
    let tree = ok(&doc(&link("only"))).tree;
    assert_eq!(tree.links().len(), 1);
    assert_eq!(tree.joints().len(), 0);
    assert_eq!(tree.dof_count(), 0);
    assert_eq!(tree.link_poses(&[]).unwrap().len(), 1);
}

#[test]
fn load_urdf_of_a_missing_file_names_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no_such_robot.urdf");
    let message = load_urdf(&path).unwrap_err().to_string();
    assert_contains(&message, "no_such_robot.urdf");
}

#[test]
fn load_urdf_errors_name_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.urdf");
    let text = doc(&format!(
        "{}{}",
        links(&["base_link", "l1"]),
        revolute("j1", "base_lnk", "l1"),
    ));
    std::fs::write(&path, &text).unwrap();
    let message = load_urdf(&path).unwrap_err().to_string();
    let line = line_of(&text, "<joint name=\"j1\"");
    assert!(
        message.starts_with(&format!("{}:{line}: ", path.display())),
        "{message}"
    );
}

// ---------------------------------------------------------------------------------------------
// 11. Limits.
// ---------------------------------------------------------------------------------------------

fn arm_with_j1_limit(kind: &str, limit: &str) -> String {
    doc(&format!(
        "{}{}",
        links(&["base_link", "l1"]),
        joint_with(
            "j1",
            kind,
            "base_link",
            "l1",
            &format!("    <axis xyz=\"0 0 1\"/>\n    {limit}\n")
        ),
    ))
}

#[test]
fn revolute_lower_above_upper_is_rejected() {
    let text = arm_with_j1_limit(
        "revolute",
        "<limit lower=\"1.5\" upper=\"-1.5\" effort=\"1\" velocity=\"1\"/>",
    );
    let message = err(&text);
    assert_at_line(&message, &text, "<joint name=\"j1\"");
    assert_contains(&message, "joint 'j1' has limits lower=1.5 upper=-1.5");
    assert_contains(&message, "lower must not exceed upper");
}

#[test]
fn prismatic_lower_above_upper_is_rejected() {
    let text = arm_with_j1_limit(
        "prismatic",
        "<limit lower=\"0.2\" upper=\"0.1\" effort=\"1\" velocity=\"1\"/>",
    );
    let message = err(&text);
    assert_contains(&message, "joint 'j1' has limits lower=0.2 upper=0.1");
}

#[test]
fn urdf_1_2_lower_above_upper_is_rejected_naming_the_joint() {
    let text = arm_with_j1_limit(
        "revolute",
        "<limit lower=\"1.5\" upper=\"-1.5\" effort=\"1\" velocity=\"1\"/>",
    )
    .replace(
        "<robot name=\"test\">",
        "<robot name=\"test\" version=\"1.2\">",
    );
    let message = err(&text);
    assert!(message.starts_with(ORIGIN), "{message}");
    assert_contains(&message, "j1");
}

#[test]
fn nan_limit_is_rejected() {
    let text = arm_with_j1_limit(
        "revolute",
        "<limit lower=\"nan\" upper=\"1\" effort=\"1\" velocity=\"1\"/>",
    );
    let message = err(&text);
    assert_contains(&message, "joint 'j1' has a NaN limit (lower=NaN");
}

#[test]
fn equal_limits_are_accepted() {
    let text = arm_with_j1_limit(
        "revolute",
        "<limit lower=\"0.5\" upper=\"0.5\" effort=\"1\" velocity=\"1\"/>",
    );
    let tree = ok(&text).tree;
    let limits = tree.joint(joint_id(&tree, "j1")).limits.unwrap();
    assert_eq!((limits.lower, limits.upper), (0.5, 0.5));
}

#[test]
fn continuous_joint_limits_are_ignored() {
    let text = arm_with_j1_limit(
        "continuous",
        "<limit lower=\"1.5\" upper=\"-1.5\" effort=\"1\" velocity=\"1\"/>",
    );
    let tree = ok(&text).tree;
    assert!(tree.joint(joint_id(&tree, "j1")).limits.is_none());
}

// ---------------------------------------------------------------------------------------------
// 12. Real robots.
// ---------------------------------------------------------------------------------------------

/// Links root first, each joint's parent before its child, and parent/child links agree.
fn assert_topological(tree: &KinematicTree, what: &str) {
    assert!(tree.link(tree.root()).parent_joint.is_none(), "{what}");
    for (index, joint) in tree.joints().iter().enumerate() {
        assert!(
            joint.parent.0 < joint.child.0,
            "{what}: joint '{}' connects link {} to earlier link {}",
            joint.name,
            joint.parent.0,
            joint.child.0
        );
        assert_eq!(
            tree.link(joint.child).parent_joint.map(|j| j.0),
            Some(index),
            "{what}: '{}'",
            joint.name
        );
        assert!(
            tree.link(joint.parent)
                .child_joints
                .iter()
                .any(|j| j.0 == index),
            "{what}: '{}'",
            joint.name
        );
    }
    for link in &tree.links()[1..] {
        assert!(
            link.parent_joint.is_some(),
            "{what}: '{}' has no parent",
            link.name
        );
    }
    // dofs in topological order, each an independent joint
    for (dof, &joint) in tree.dofs().iter().enumerate() {
        assert_eq!(tree.dof_of(joint).map(|d| d.0), Some(dof), "{what}");
    }
    assert!(tree.dofs().windows(2).all(|w| w[0] < w[1]), "{what}");
}

#[test]
fn every_repo_robot_loads_without_warnings() {
    let robots = all_repo_robots();
    assert!(
        robots.len() >= 3,
        "expected robots in robots/, found {robots:?}"
    );
    for path in robots.iter().chain([&robonaut2()]) {
        let import = load_urdf(path).unwrap_or_else(|e| panic!("{e}"));
        let what = path.display().to_string();
        assert!(import.warnings.is_empty(), "{what}: {:?}", import.warnings);
        assert_topological(&import.tree, &what);
        let q = import.tree.zero_configuration();
        for pose in import.tree.link_poses(&q).unwrap() {
            assert!(
                pose.translation.vector.iter().all(|v| v.is_finite()),
                "{what}"
            );
        }
    }
}

#[test]
fn robonaut2_has_the_expected_size_and_topological_order() {
    let tree = load_urdf(&robonaut2()).unwrap().tree;
    assert_eq!(tree.links().len(), 132);
    assert_eq!(tree.joints().len(), 131);
    let revolute = tree
        .joints()
        .iter()
        .filter(|j| j.kind == JointKind::Revolute)
        .count();
    assert_eq!(revolute, 74);
    assert_topological(&tree, "robonaut2");
}

#[test]
fn humanoid_mimic_fingers_follow_their_masters() {
    let tree = load_urdf(&robot("humanoid/humanoid.urdf")).unwrap().tree;
    let mut rng = rng(3);
    let q = random_configuration(&tree, &mut rng);
    for side in ["l", "r"] {
        let master = joint_id(&tree, &format!("{side}_finger_left"));
        let follower = joint_id(&tree, &format!("{side}_finger_right"));
        assert!(tree.dof_of(follower).is_none());
        assert!(
            (tree.joint_value(follower, &q) + tree.joint_value(master, &q)).abs() < 1e-15,
            "{side}"
        );
    }
}

#[test]
fn parse_urdf_and_load_urdf_agree() {
    let path = robot("humanoid/humanoid.urdf");
    let text = std::fs::read_to_string(&path).unwrap();
    let parsed = parse_urdf(&text, "humanoid").unwrap().tree;
    let loaded = load_urdf(&path).unwrap().tree;
    assert_eq!(parsed.links().len(), loaded.links().len());
    let mut rng = rng(11);
    let q = random_configuration(&parsed, &mut rng);
    let a = parsed.link_poses(&q).unwrap();
    let b = loaded.link_poses(&q).unwrap();
    for (index, (pa, pb)) in a.iter().zip(&b).enumerate() {
        assert_eq!(parsed.links()[index].name, loaded.links()[index].name);
        assert_pose_eq(pa, pb, 1e-12, &parsed.links()[index].name);
    }
}

// ---------------------------------------------------------------------------------------------
// 13. Randomly corrupted files never panic.
// ---------------------------------------------------------------------------------------------

/// Byte ranges of numbers (`-0.5`, `1e-3`, `42`) in `text`.
fn number_ranges(text: &str) -> Vec<std::ops::Range<usize>> {
    let bytes = text.as_bytes();
    let is_number_byte =
        |b: u8| b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+' | b'e' | b'E');
    let mut ranges = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = (bytes[i].is_ascii_digit() || bytes[i] == b'-' || bytes[i] == b'.')
            && (i == 0 || matches!(bytes[i - 1], b' ' | b'"' | b'\'' | b'\t' | b'\n'));
        if starts {
            let mut end = i;
            while end < bytes.len() && is_number_byte(bytes[end]) {
                end += 1;
            }
            if bytes[i..end].iter().any(u8::is_ascii_digit) {
                ranges.push(i..end);
            }
            i = end.max(i + 1);
        } else {
            i += 1;
        }
    }
    ranges
}

/// Byte ranges of attribute values (between the quotes of `="..."`).
fn attribute_value_ranges(text: &str) -> Vec<std::ops::Range<usize>> {
    let mut ranges = Vec::new();
    let mut start = 0;
    while let Some(found) = text[start..].find("=\"") {
        let open = start + found + 2;
        let Some(close) = text[open..].find('"') else {
            break;
        };
        ranges.push(open..open + close);
        start = open + close + 1;
    }
    ranges
}

fn pick<T: Clone>(items: &[T], rng: &mut rand::rngs::ChaCha8Rng) -> Option<T> {
    (!items.is_empty()).then(|| items[rng.random_range(0..items.len())].clone())
}

/// Applies one random mutation; returns its description.
fn mutate(text: &mut String, rng: &mut rand::rngs::ChaCha8Rng) -> String {
    match rng.random_range(0..4) {
        0 => {
            let lines: Vec<&str> = text.split_inclusive('\n').collect();
            if lines.is_empty() {
                return "no line to delete".into();
            }
            let victim = rng.random_range(0..lines.len());
            let removed = lines[victim].trim_end().to_owned();
            *text = lines
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != victim)
                .map(|(_, l)| *l)
                .collect();
            format!("deleted line {}: {removed}", victim + 1)
        }
        1 => {
            let Some(range) = pick(&number_ranges(text), rng) else {
                return "no number to replace".into();
            };
            let replacement = ["nan", "1e400", "abc", "", "-inf", "NaN", "1e-400", "0x10"]
                [rng.random_range(0..8)];
            let old = text[range.clone()].to_owned();
            let line = text[..range.start].matches('\n').count() + 1;
            text.replace_range(range, replacement);
            format!("line {line}: replaced number '{old}' with '{replacement}'")
        }
        2 => {
            let ranges = attribute_value_ranges(text);
            let (Some(a), Some(b)) = (pick(&ranges, rng), pick(&ranges, rng)) else {
                return "no attributes to swap".into();
            };
            let (first, second) = if a.start <= b.start { (a, b) } else { (b, a) };
            if first == second {
                return "swapped an attribute with itself".into();
            }
            let (va, vb) = (
                text[first.clone()].to_owned(),
                text[second.clone()].to_owned(),
            );
            let line_a = text[..first.start].matches('\n').count() + 1;
            let line_b = text[..second.start].matches('\n').count() + 1;
            // replace the later one first so the earlier range stays valid
            text.replace_range(second, &va);
            text.replace_range(first, &vb);
            format!("swapped attribute values '{va}' (line {line_a}) and '{vb}' (line {line_b})")
        }
        _ => {
            let mut cut = rng.random_range(0..=text.len());
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            let line = text[..cut].matches('\n').count() + 1;
            text.truncate(cut);
            format!("truncated at byte {cut} (line {line})")
        }
    }
}

#[test]
fn randomly_corrupted_urdfs_never_panic() {
    let original = std::fs::read_to_string(robot("humanoid/humanoid.urdf")).unwrap();
    let reference = parse_urdf(&original, "humanoid.urdf").unwrap();
    assert!(reference.warnings.is_empty());
    // TREECAL_FUZZ_CASES and TREECAL_FUZZ_SEED run a longer or different batch by hand.
    let cases: usize = std::env::var("TREECAL_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300);
    let seed: u64 = std::env::var("TREECAL_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2024);
    let mut rng = rng(seed);
    let (mut loaded, mut rejected) = (0, 0);
    let mut failures = Vec::new();
    for case in 0..cases {
        let mut text = original.clone();
        let count = rng.random_range(1..=3);
        let mutations: Vec<String> = (0..count).map(|_| mutate(&mut text, &mut rng)).collect();
        let outcome = std::panic::catch_unwind(|| {
            let result = parse_urdf(&text, "corrupt.urdf");
            // Whatever loads must be a usable tree with finite forward kinematics.
            if let Ok(import) = &result {
                let tree = &import.tree;
                let q = tree.zero_configuration();
                for pose in tree.link_poses(&q).unwrap() {
                    assert!(pose.translation.vector.iter().all(|v| v.is_finite()));
                    assert!(pose.rotation.coords.iter().all(|v| v.is_finite()));
                }
            }
            result.map(|_| ()).map_err(|e| e.to_string())
        });
        match outcome {
            Ok(Ok(())) => loaded += 1,
            Ok(Err(message)) => {
                rejected += 1;
                if !message.starts_with("corrupt.urdf") || message.len() < 20 {
                    failures.push(format!(
                        "case {case} ({mutations:?}): unclear message: {message}"
                    ));
                }
            }
            Err(panic) => {
                let what = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                failures.push(format!("case {case} ({mutations:?}): panicked: {what}"));
            }
        }
    }
    eprintln!("{cases} corrupted files: {loaded} loaded, {rejected} rejected");
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // The mutations must actually exercise both paths.
    assert!(
        loaded > 10 && rejected > 10,
        "loaded {loaded}, rejected {rejected}"
    );
}

/// urdf-rs fills a missing `<limit>` with zeros; treecal warns and treats the joint as unbounded
/// instead of as a joint that cannot move.
#[test]
fn missing_limit_is_a_warning_not_a_frozen_joint() {
    let text = r#"<robot name="r"><link name="a"/><link name="b"/>
        <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint></robot>"#;
    let import = treecal::parse_urdf(text, "nolimit.urdf").unwrap();
    assert_eq!(import.warnings.len(), 1, "{:?}", import.warnings);
    assert!(import.warnings[0].contains("'j'") && import.warnings[0].contains("no <limit>"));
    assert!(import.tree.joints()[0].limits.is_none());
}
