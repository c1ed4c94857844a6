//! `export_urdf` and `treecal export`: a calibrated model written into the original URDF
//! reproduces the model's forward kinematics, keeps every link off the modelled chains where
//! it was relative to its parent, changes no byte but the rewritten `<origin>`/`<axis>`
//! values, loads again, passes urdfdom's `check_urdf` and agrees with Pinocchio.

use crate::common::cli::*;
use crate::common::*;
use rand::RngExt;
use std::collections::HashSet;
use std::path::Path;
use std::process::{Command, Stdio};
use treecal::math::Pose;
use treecal::urdf::{export_urdf, AddedReason, ExportReport};
use treecal::{parse_urdf, Branches, KinematicTree, McpcModel};

/// Random configurations per robot.
const CONFIGURATIONS: usize = 50;
/// Position (m) and rotation-matrix entry tolerance of the exported forward kinematics.
const TOLERANCE: f64 = 1e-9;
/// The Debian liburdfdom-tools binary (a different `check_urdf` may come first on PATH).
const CHECK_URDF: &str = "/usr/bin/check_urdf";

/// Largest translation difference (m) and largest rotation-matrix entry difference: unlike
/// `angle_to`, which reads 0 below about 1e-8 rad, this sees differences down to rounding.
fn pose_gap(a: &Pose, b: &Pose) -> (f64, f64) {
    let position = (a.translation.vector - b.translation.vector).norm();
    let rotation = (a.rotation.to_rotation_matrix().matrix()
        - b.rotation.to_rotation_matrix().matrix())
    .abs()
    .max();
    (position, rotation)
}

#[track_caller]
fn assert_close(a: &Pose, b: &Pose, tolerance: f64, what: &str) {
    let (position, rotation) = pose_gap(a, b);
    assert!(
        position <= tolerance && rotation <= tolerance,
        "{what}: poses differ by {position:e} m and {rotation:e} (rotation entries)\n{a}\n{b}"
    );
}

struct Case {
    text: String,
    tree: KinematicTree,
    branches: Branches,
    model: McpcModel,
}

/// Loads `text`, detects branches (with `tools` if given) and perturbs every MCPC parameter
/// by a seeded uniform ±0.05 rad / ±0.05 m (`seed` `None`: the nominal model).
fn case(text: String, tools: Option<&[&str]>, seed: Option<u64>) -> Case {
    let tree = parse_urdf(&text, "case")
        .unwrap_or_else(|e| panic!("{e}"))
        .tree;
    let branches = branches_with_tools(&tree, tools);
    let mut model = McpcModel::from_tree(&tree, &branches).unwrap();
    if let Some(seed) = seed {
        let mut rng = rng(seed);
        let mut values = model.parameters();
        // ±0.05 rad for angles, ±0.05 m for lengths: the same number in SI units.
        for value in values.iter_mut() {
            *value += rng.random_range(-0.05..0.05);
        }
        model.set_parameters(&values).unwrap();
    }
    Case {
        text,
        tree,
        branches,
        model,
    }
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Exports, reloads, and checks (a) model poses, (b) off-chain links and (c) byte identity.
fn export_and_check(case: &Case, what: &str) -> (ExportReport, KinematicTree) {
    let report = export_urdf(&case.text, what, &case.tree, &case.model)
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let exported = parse_urdf(&report.urdf, "exported")
        .unwrap_or_else(|e| panic!("{what}: the export does not load again: {e}"))
        .tree;
    let (tree, model) = (&case.tree, &case.model);
    assert_eq!(
        exported.links().len(),
        tree.links().len() + report.added_links.len(),
        "{what}"
    );
    for b in tree.joints() {
        let a = exported.joint(exported.joint_id(&b.name).unwrap());
        let name = |e: &KinematicTree, l| e.link(l).name.clone();
        assert_eq!(
            (name(&exported, a.parent), name(&exported, a.child)),
            (name(tree, b.parent), name(tree, b.child)),
            "{what}: joint '{}' connects other links",
            b.name
        );
        assert_eq!(
            (a.kind, a.limits, a.actuation),
            (b.kind, b.limits, b.actuation),
            "{what}: joint changed beyond its origin and axis"
        );
    }

    let tool_links: HashSet<usize> = model.tools().iter().map(|t| t.link.0).collect();
    let mut on_chains = tool_links.clone();
    on_chains.extend(model.frames().iter().map(|f| tree.joint(f.joint).child.0));

    // (a) every modelled link and tool where the calibrated model puts it.
    let mut rng = rng(0xE4_0127);
    let mut worst = 0.0f64;
    for _ in 0..CONFIGURATIONS {
        let q = random_configuration(tree, &mut rng);
        let poses = exported.link_poses(&q).unwrap();
        for (t, tool_pose) in model.tool_poses(&q).iter().enumerate() {
            let link = measured_link(&report, &exported, tree, model, t);
            assert_close(
                &poses[link.0],
                tool_pose,
                TOLERANCE,
                &format!("{what}: tool {t}"),
            );
            let (p, r) = pose_gap(&poses[link.0], tool_pose);
            worst = worst.max(p).max(r);
        }
        for (f, link_pose) in model.link_poses(&q).iter().enumerate() {
            let link = tree.joint(model.frames()[f].joint).child;
            let marked = report
                .added_links
                .iter()
                .any(|a| a.tool == tree.link(link).name);
            if !tool_links.contains(&link.0) || marked {
                let name = &tree.link(link).name;
                assert_close(
                    &poses[link.0],
                    link_pose,
                    TOLERANCE,
                    &format!("{what}: {name}"),
                );
            }
        }
    }
    eprintln!("{what}: worst tool pose difference {worst:e}");

    // (b) links off the chains keep their placement on their parent link, bit for bit.
    for b in tree.joints() {
        let a = exported.joint(exported.joint_id(&b.name).unwrap());
        if !on_chains.contains(&b.child.0) {
            assert_eq!(
                (a.parent_from_joint, a.axis),
                (b.parent_from_joint, b.axis),
                "{what}: joint '{}' is off the modelled chains and must not move",
                a.name
            );
        }
    }
    let changed: HashSet<&str> = report.changes.iter().map(|c| c.joint.as_str()).collect();
    for joint in tree.joints() {
        if !changed.contains(joint.name.as_str()) {
            let exported_joint = exported.joint(exported.joint_id(&joint.name).unwrap());
            assert_eq!(exported_joint.parent_from_joint, joint.parent_from_joint);
        }
    }

    // (c) nothing but origin/axis attribute values differs, besides the links added at the end.
    assert_same_but_origins(
        &case.text,
        &without_added_links(&report.urdf),
        report.changes.len(),
        what,
    );
    (report, exported)
}

/// The link of the exported tree that carries the measured frame of tool `t`: the marker link
/// added below it, if any, else the tool link itself.
fn measured_link(
    report: &ExportReport,
    exported: &KinematicTree,
    tree: &KinematicTree,
    model: &McpcModel,
    t: usize,
) -> treecal::tree::LinkId {
    let name = &tree.link(model.tools()[t].link).name;
    match report.added_links.iter().find(|a| &a.tool == name) {
        Some(added) => exported.link_id(&added.link).unwrap(),
        None => model.tools()[t].link,
    }
}

/// The exported text without the links the export added before `</robot>`.
fn without_added_links(urdf: &str) -> String {
    let Some(start) = urdf.find("<!-- Added by treecal export") else {
        return urdf.to_owned();
    };
    let line_start = urdf[..start].rfind('\n').map_or(0, |n| n + 1);
    let end = urdf.rfind("</robot").unwrap();
    let end_line = urdf[..end].rfind('\n').map_or(0, |n| n + 1);
    format!("{}{}", &urdf[..line_start], &urdf[end_line..])
}

/// Masks the values of `xyz` and `rpy` attributes.
fn mask(line: &str) -> String {
    let mut out = String::new();
    let mut rest = line;
    loop {
        let next = ["xyz=", "rpy="]
            .iter()
            .filter_map(|k| rest.find(k).map(|i| (i, k.len())))
            .min();
        let Some((at, key_len)) = next else {
            out.push_str(rest);
            return out;
        };
        let value_start = at + key_len;
        let quote = rest[value_start..].chars().next().unwrap();
        let close = value_start + 1 + rest[value_start + 1..].find(quote).unwrap();
        out.push_str(&rest[..value_start]);
        out.push('#');
        rest = &rest[close + 1..];
    }
}

#[track_caller]
fn assert_same_but_origins(original: &str, exported: &str, changes: usize, what: &str) {
    let a: Vec<&str> = original.split('\n').collect();
    let b: Vec<&str> = exported.split('\n').collect();
    assert_eq!(a.len(), b.len(), "{what}: line count changed");
    let mut differing = 0;
    for (number, (x, y)) in a.iter().zip(&b).enumerate() {
        if x != y {
            differing += 1;
            assert!(
                (y.contains("<origin") || y.contains("<axis")) && mask(x) == mask(y),
                "{what}: line {} changed beyond origin/axis values:\n- {x}\n+ {y}",
                number + 1
            );
        }
    }
    assert!(
        differing <= 2 * changes,
        "{what}: {differing} lines changed"
    );
    assert_eq!(differing > 0, changes > 0, "{what}");
}

fn check_urdf_accepts(text: &str, what: &str) {
    if !Path::new(CHECK_URDF).exists() {
        let problem = format!("{CHECK_URDF} not found (Debian/Ubuntu package liburdfdom-tools)");
        if std::env::var("TREECAL_REQUIRE_TOOLS").is_ok_and(|v| v == "1") {
            panic!("TREECAL_REQUIRE_TOOLS=1 but {problem}");
        }
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr().lock(),
            "\n!!! SKIPPED: check_urdf on the export of {what} (tests/export.rs): {problem}\n\
             !!! (set TREECAL_REQUIRE_TOOLS=1 to make this a failure instead of a skip)\n"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exported.urdf");
    std::fs::write(&path, text).unwrap();
    let output = Command::new(CHECK_URDF)
        .arg(&path)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{what}: check_urdf refuses the export:\n{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

/// (f) Pinocchio reads the exported file and finds the model's tool poses (at the marker links
/// the export added, where it added them).
fn pinocchio_agrees(case: &Case, report: &ExportReport, what: &str) {
    let exported_text = &report.urdf;
    if !crate::oracle::oracle_available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exported.urdf");
    std::fs::write(&path, exported_text).unwrap();
    let links: Vec<String> = case
        .model
        .tools()
        .iter()
        .map(|t| {
            let name = case.tree.link(t.link).name.clone();
            match report.added_links.iter().find(|a| a.tool == name) {
                Some(added) => added.link.clone(),
                None => name,
            }
        })
        .collect();
    let mut rng = rng(0x0AC1E);
    let configurations: Vec<Vec<f64>> = (0..10)
        .map(|_| random_configuration(&case.tree, &mut rng))
        .collect();
    let poses = crate::oracle::pinocchio_poses(&path, &case.tree, &links, &configurations);
    for (q, per_link) in configurations.iter().zip(&poses) {
        for (t, (model_pose, oracle_pose)) in
            case.model.tool_poses(q).iter().zip(per_link).enumerate()
        {
            assert_close(
                oracle_pose,
                model_pose,
                TOLERANCE,
                &format!("{what}: tool {t}"),
            );
        }
    }
}

fn full_check(text: String, tools: Option<&[&str]>, seed: u64, what: &str) {
    let calibrated = case(text.clone(), tools, Some(seed));
    let (report, _) = export_and_check(&calibrated, what);
    assert!(
        !report.changes.is_empty(),
        "{what}: a perturbed model must change joints"
    );
    check_urdf_accepts(&report.urdf, what);
    pinocchio_agrees(&calibrated, &report, what);

    // (d) the nominal model gives the file back unchanged.
    let nominal = case(text.clone(), tools, None);
    let (report, exported) = export_and_check(&nominal, &format!("{what} (nominal)"));
    assert_eq!(
        report.changes,
        vec![],
        "{what}: nominal export changed joints"
    );
    assert!(
        report.urdf == text,
        "{what}: nominal export is not the original text"
    );
    let mut rng = rng(3);
    for _ in 0..5 {
        let q = random_configuration(&nominal.tree, &mut rng);
        let (a, b) = (
            exported.link_poses(&q).unwrap(),
            nominal.tree.link_poses(&q).unwrap(),
        );
        for (x, y) in a.iter().zip(&b) {
            assert_close(x, y, 1e-12, what);
        }
    }
}

#[test]
fn robonaut_export_reproduces_the_calibrated_model() {
    full_check(read(&robot("robonaut/robonaut.urdf")), None, 1, "robonaut");
}

#[test]
fn humanoid_export_keeps_head_legs_and_mimic_fingers_attached() {
    full_check(read(&robot("humanoid/humanoid.urdf")), None, 2, "humanoid");
}

#[test]
fn dual_arm_prismatic_export_reproduces_the_calibrated_model() {
    let text = read(&robot("dual_arm_prismatic/dual_arm_prismatic.urdf"));
    full_check(text, None, 3, "dual_arm_prismatic");
}

#[test]
fn robonaut2_export_reproduces_the_calibrated_model() {
    full_check(read(&robonaut2()), None, 4, "robonaut2");
}

/// Robonaut with elements urdf-rs drops, comments and CDATA that look like joints, single
/// quotes, attributes in another order, an `<origin>` without `rpy` and a joint without
/// `<origin>` (both edited by insertion, so the line check is replaced by a masked diff).
fn decorated_robonaut() -> String {
    let text = read(&robot("robonaut/robonaut.urdf"));
    let extra = r#"  <!-- <joint name="left_joint2"><origin xyz="9 9 9"/></joint> -->
  <transmission name="left_joint2_transmission">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="left_joint2"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>
    <actuator name="left_motor2"><mechanicalReduction>100</mechanicalReduction></actuator>
  </transmission>
  <gazebo reference="left_link2"><material>Gazebo/Grey</material><![CDATA[<joint name="left_joint3"><origin xyz="1 2 3"/></joint>]]></gazebo>
</robot>"#;
    let text = text.replacen("</robot>", extra, 1);
    let text = text.replacen(
        "<origin xyz=\"0 -0.135 0\" rpy=\"0 0 0\"/>",
        "<origin  rpy='0 0 0'\n      xyz='0 -0.135 0' ></origin>",
        1,
    );
    // torso_joint1's origin is the identity: the same robot without it.
    let text = text.replacen(
        "<child link=\"torso_link1\"/>\n    <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>",
        "<child link=\"torso_link1\"/>",
        1,
    );
    assert!(text.contains("rpy='0 0 0'") && !text.contains("torso_link1\"/>\n    <origin"));
    text
}

#[test]
fn export_edits_in_place_and_keeps_elements_urdf_rs_drops() {
    let text = decorated_robonaut();
    let calibrated = case(text.clone(), None, Some(5));
    let report = export_urdf(&text, "decorated", &calibrated.tree, &calibrated.model).unwrap();
    let out = &report.urdf;
    for kept in [
        "<transmission name=\"left_joint2_transmission\">",
        "<joint name=\"left_joint2\"><hardwareInterface>",
        "<![CDATA[<joint name=\"left_joint3\"><origin xyz=\"1 2 3\"/></joint>]]>",
        "<!-- <joint name=\"left_joint2\"><origin xyz=\"9 9 9\"/></joint> -->",
        "<gazebo reference=\"left_link2\">",
    ] {
        assert!(out.contains(kept), "lost: {kept}");
    }
    // The single-quoted origin was rewritten in place, keeping its quotes and order.
    assert!(out.contains("<origin  rpy='"), "{out}");
    assert!(out.contains("' ></origin>"));
    // The joint without an origin got one.
    let torso = &out[out.find("<joint name=\"torso_joint1\"").unwrap()..];
    let torso = &torso[..torso.find("</joint>").unwrap()];
    assert!(torso.contains("<origin xyz=\""), "{torso}");
    // Masking every xyz/rpy value and deleting the inserted origin gives the original back.
    let inserted_start =
        out.find("<joint name=\"torso_joint1\"").unwrap() + torso.find('>').unwrap() + 1;
    let inserted_end = inserted_start + out[inserted_start + 1..].find('\n').unwrap() + 1;
    let without_insert = format!("{}{}", &out[..inserted_start], &out[inserted_end..]);
    assert_eq!(mask(&without_insert), mask(&text));
    // And it is the calibrated robot.
    let exported = parse_urdf(out, "exported").unwrap().tree;
    let mut rng = rng(6);
    for _ in 0..CONFIGURATIONS {
        let q = random_configuration(&calibrated.tree, &mut rng);
        let poses = exported.link_poses(&q).unwrap();
        for (t, tool_pose) in calibrated.model.tool_poses(&q).iter().enumerate() {
            let link = calibrated.model.tools()[t].link;
            assert_close(&poses[link.0], tool_pose, TOLERANCE, "decorated");
        }
    }
    check_urdf_accepts(out, "decorated robonaut");
}

/// Where every link of a URDF exported from `model` must be at `q`: the links of the modelled
/// chains where the model puts them, each added marker link at its tool's calibrated frame,
/// and every other link (tool links with children included) at its nominal offset from its
/// parent link's expected pose.
fn expected_link_poses(
    tree: &KinematicTree,
    model: &McpcModel,
    report: &ExportReport,
    exported: &KinematicTree,
    q: &[f64],
) -> Vec<(String, Pose)> {
    let mut expected: Vec<Option<Pose>> = vec![None; tree.links().len()];
    expected[0] = Some(Pose::identity());
    for (f, pose) in model.link_poses(q).into_iter().enumerate() {
        expected[tree.joint(model.frames()[f].joint).child.0] = Some(pose);
    }
    for (index, joint) in tree.joints().iter().enumerate() {
        if expected[joint.child.0].is_none() {
            let value = tree.joint_value(treecal::tree::JointId(index), q);
            expected[joint.child.0] =
                Some(expected[joint.parent.0].unwrap() * joint.parent_from_child(value));
        }
    }
    let mut named: Vec<(String, Pose)> = tree
        .links()
        .iter()
        .zip(expected)
        .map(|(l, p)| (l.name.clone(), p.unwrap()))
        .collect();
    for (t, pose) in model.tool_poses(q).into_iter().enumerate() {
        let link = measured_link(report, exported, tree, model, t);
        let name = exported.link(link).name.clone();
        match named.iter_mut().find(|(n, _)| *n == name) {
            Some(entry) => entry.1 = pose,
            None => named.push((name, pose)),
        }
    }
    named
}

/// Tool links with child links (the Robonaut's `left_link6` and `right_link5`, each carrying
/// the rest of its arm): the measured tool frames (every parameter perturbed, centimetres off)
/// go into added `<tool>_marker` links; every link of the exported URDF (FK at random
/// configurations, by name) is where the calibrated model puts it, and the links below the tool
/// keep their nominal offsets to their parents, bit for bit.
#[test]
fn tool_with_children_keeps_its_links_and_gets_a_marker_link() {
    let text = read(&robot("robonaut/robonaut.urdf"));
    let tools = ["left_link6", "right_link5"];
    let calibrated = case(text, Some(&tools), Some(7));
    let (tree, model) = (&calibrated.tree, &calibrated.model);
    let report = export_urdf(&calibrated.text, "robonaut", tree, model).unwrap();
    let added: Vec<(&str, &str, AddedReason)> = report
        .added_links
        .iter()
        .map(|a| (a.link.as_str(), a.parent.as_str(), a.reason))
        .collect();
    assert_eq!(
        added,
        [
            ("left_link6_marker", "left_link6", AddedReason::Marker),
            ("right_link5_marker", "right_link5", AddedReason::Marker)
        ]
    );
    assert!(report.changes.iter().all(|c| c.new_axis.is_none()));
    let exported = parse_urdf(&report.urdf, "exported").unwrap().tree;
    let mut random = rng(0x28_04);
    let mut worst = 0.0f64;
    for _ in 0..CONFIGURATIONS {
        let q = random_configuration(tree, &mut random);
        let poses = exported.link_poses(&q).unwrap();
        let expected = expected_link_poses(tree, model, &report, &exported, &q);
        assert_eq!(expected.len(), exported.links().len());
        for (name, pose) in &expected {
            let link = exported.link_id(name).unwrap();
            assert_close(&poses[link.0], pose, TOLERANCE, name);
            worst = worst.max(pose_gap(&poses[link.0], pose).0);
        }
    }
    eprintln!("every link: worst position difference {worst:e} m");
    // Below the modelled chains nothing moved relative to its parent: the tool links' own
    // fixed joints and everything beneath them keep their text.
    let framed: HashSet<usize> = model
        .frames()
        .iter()
        .map(|f| tree.joint(f.joint).child.0)
        .collect();
    for joint in tree
        .joints()
        .iter()
        .filter(|j| !framed.contains(&j.child.0))
    {
        let again = exported.joint(exported.joint_id(&joint.name).unwrap());
        assert_eq!(
            again.parent_from_joint, joint.parent_from_joint,
            "{}",
            joint.name
        );
    }
    // The marker links are the tools' measured frames, far from the tool links.
    for (t, link) in report.added_links.iter().enumerate() {
        assert!(link.offset_mm > 10.0, "{link:?}");
        assert_eq!(link.tool, tools[t]);
    }
    check_urdf_accepts(&report.urdf, "robonaut, tools with children");
    // Exported again from its own output the marker links are updated, not added twice.
    let again = parse_urdf(&report.urdf, "again").unwrap().tree;
    let branches = branches_with_tools(&again, Some(&tools));
    let mut model_again = McpcModel::from_tree(&again, &branches).unwrap();
    model_again.set_parameters(&model.parameters()).unwrap();
    let second = export_urdf(&report.urdf, "again", &again, &model_again).unwrap();
    assert!(second.added_links.is_empty());
    let reloaded = parse_urdf(&second.urdf, "second").unwrap().tree;
    let q = random_configuration(tree, &mut random);
    let poses = reloaded.link_poses(&q).unwrap();
    for (t, tool_pose) in model_again.tool_poses(&q).iter().enumerate() {
        let link = reloaded.link_id(&format!("{}_marker", tools[t])).unwrap();
        assert_close(&poses[link.0], tool_pose, TOLERANCE, "second export");
    }
}

/// A mimic joint with an offset on a modelled chain: the exported origin is the pose at joint
/// value 0, not at q = 0 (where the mimic joint sits at its offset).
#[test]
fn mimic_joint_with_offset_on_a_chain_exports_exactly() {
    let text = read(&robot("robonaut/robonaut.urdf"));
    let anchor = "<child link=\"left_link5\"/>";
    assert!(text.contains(anchor));
    let text = text.replacen(
        anchor,
        "<child link=\"left_link5\"/>\n    <mimic joint=\"left_joint4\" multiplier=\"0.7\" offset=\"0.3\"/>",
        1,
    );
    full_check(text, None, 11, "robonaut with a mimic elbow");
}

#[test]
fn export_refuses_text_that_is_not_the_tree_s_urdf() {
    let calibrated = case(read(&robot("robonaut/robonaut.urdf")), None, Some(8));
    let other = read(&robot("humanoid/humanoid.urdf"));
    let error = export_urdf(&other, "humanoid.urdf", &calibrated.tree, &calibrated.model)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("humanoid.urdf") && error.contains("no <joint name="),
        "{error}"
    );
}

// ---------------------------------------------------------------------------------------------
// treecal export

fn params_yaml(case: &Case, skip: Option<usize>) -> String {
    let mut text = String::from("# calibrated parameters\nunits: SI\nparameters:\n");
    for (i, value) in case.model.parameters().iter().enumerate() {
        if Some(i) == skip {
            continue;
        }
        text.push_str(&format!(
            "  - name: {}\n    nominal: 0\n    calibrated: {value:?}\n    std_dev: 1e-5\n",
            case.model.parameter_name(&case.tree, i)
        ));
    }
    text
}

#[test]
fn cli_export_writes_the_calibrated_urdf() {
    let urdf = robot("robonaut/robonaut.urdf");
    let calibrated = case(read(&urdf), None, Some(9));
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("params.yaml");
    std::fs::write(&params, params_yaml(&calibrated, Some(0))).unwrap();
    let out = dir.path().join("out/calibrated.urdf");
    let run = treecal(&[
        "export",
        "--robot",
        path_str(&urdf),
        "--params",
        path_str(&params),
        "-o",
        path_str(&out),
    ]);
    assert_success(&run, "export");
    assert!(run.stderr.contains("wrote"), "{run}");
    let missing = calibrated.model.parameter_name(&calibrated.tree, 0);
    assert!(
        run.stderr.contains("warning") && run.stderr.contains(&missing),
        "the missing parameter is named\n{run}"
    );
    // The first parameter kept its nominal value; everything else is the calibrated model.
    let mut expected = calibrated.model.clone();
    let mut values = expected.parameters();
    values[0] = McpcModel::from_tree(&calibrated.tree, &calibrated.branches)
        .unwrap()
        .parameters()[0];
    expected.set_parameters(&values).unwrap();
    let exported = parse_urdf(&read(&out), "out").unwrap().tree;
    let mut rng = rng(10);
    for _ in 0..10 {
        let q = random_configuration(&calibrated.tree, &mut rng);
        let poses = exported.link_poses(&q).unwrap();
        for (t, tool_pose) in expected.tool_poses(&q).iter().enumerate() {
            assert_close(
                &poses[expected.tools()[t].link.0],
                tool_pose,
                TOLERANCE,
                "cli",
            );
        }
    }
}

#[test]
fn cli_export_refuses_unknown_parameter_names() {
    let urdf = robot("robonaut/robonaut.urdf");
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("params.yaml");
    std::fs::write(
        &params,
        "parameters:\n  - name: left_joint1 alpah\n    calibrated: 0.1\n",
    )
    .unwrap();
    let out = dir.path().join("out.urdf");
    let run = treecal(&[
        "export",
        "--robot",
        path_str(&urdf),
        "--params",
        path_str(&params),
        "-o",
        path_str(&out),
    ]);
    assert_error(
        &run,
        &[
            "params.yaml:2:11",
            "left_joint1 alpah",
            "did you mean 'left_joint1 alpha'",
        ],
        "unknown parameter",
    );
    assert!(!out.exists(), "nothing is written on error");

    std::fs::write(&params, "parameters:\n  - name: left_joint1 alpha\n").unwrap();
    let run = treecal(&[
        "export",
        "--params",
        path_str(&params),
        "-o",
        path_str(&out),
    ]);
    assert_error(&run, &["params.yaml", "calibrated"], "missing value");
}

// ---------------------------------------------------------------------------------------------
// Tools carried by a revolute joint, off its axis (a palm on the wrist joint)

/// How far a tool's calibrated origin lies off the axis of the last joint (m).
fn off_axis(model: &McpcModel, tool: usize) -> f64 {
    model.tools()[tool]
        .constant_transform()
        .translation
        .vector
        .xy()
        .norm()
}

/// Palms as the wrist joints' children, every parameter perturbed (the palms end up
/// centimetres off the wrist axes): refused by default with a way out; exported with the
/// offsets dropped when they are within the given tolerances (orientation exact, position off
/// by exactly the reported offset); when asked, exported with the palms where the calibrated
/// wrist joints put them (every modelled link, palms included, at the model's pose to 1e-9:
/// a palm carries meshes and inertia) and `<palm>_marker` links at the exact tool frames
/// (1e-9); `check_urdf` accepts both files; exported again, the markers are rewritten in place.
#[test]
fn palm_on_the_wrist_joint_is_exported_dropped_or_with_an_added_link() {
    use treecal::urdf::{export_urdf_with, ExportOptions};
    let tools = ["l_hand", "r_hand"];
    let calibrated = case(humanoid_with_palms_on_wrists(), Some(&tools), Some(21));
    let (tree, model) = (&calibrated.tree, &calibrated.model);
    let offsets: Vec<f64> = (0..2).map(|t| off_axis(model, t)).collect();
    assert!(offsets.iter().all(|&d| d > 1e-3), "{offsets:?}");

    let message = export_urdf(&calibrated.text, "palms", tree, model)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("l_hand")
            && message.contains("`add_tool_links`")
            && message.contains("l_hand_marker"),
        "{message}"
    );

    // Dropped: within a (generous) tolerance of 10 cm.
    let mut options = ExportOptions::default();
    for tool in tools {
        options.tool_tolerances.insert(tool.into(), 0.1);
    }
    let report = export_urdf_with(&calibrated.text, "palms", tree, model, &options).unwrap();
    assert_eq!(report.dropped.len(), 2, "{:?}", report.dropped);
    assert!(report.added_links.is_empty());
    for (dropped, offset) in report.dropped.iter().zip(&offsets) {
        assert!(
            (dropped.offset_mm - offset * 1e3).abs() < 1e-9,
            "{dropped:?}"
        );
        assert_eq!(dropped.tolerance_mm, 100.0);
    }
    let exported = parse_urdf(&report.urdf, "dropped").unwrap().tree;
    let mut random = rng(22);
    for _ in 0..CONFIGURATIONS {
        let q = random_configuration(tree, &mut random);
        let poses = exported.link_poses(&q).unwrap();
        for (t, tool_pose) in model.tool_poses(&q).iter().enumerate() {
            let got = &poses[model.tools()[t].link.0];
            let (position, rotation) = pose_gap(got, tool_pose);
            assert!(rotation < TOLERANCE, "orientation is exported exactly");
            assert!(
                (position - offsets[t]).abs() < TOLERANCE,
                "{position} vs {}",
                offsets[t]
            );
        }
    }
    check_urdf_accepts(&report.urdf, "palms, offsets dropped");

    // Added links at the exact calibrated frames.
    let options = ExportOptions {
        add_tool_links: true,
        ..ExportOptions::default()
    };
    let report = export_urdf_with(&calibrated.text, "palms", tree, model, &options).unwrap();
    assert!(report.dropped.is_empty());
    let added: Vec<&str> = report.added_links.iter().map(|a| a.link.as_str()).collect();
    assert_eq!(added, ["l_hand_marker", "r_hand_marker"]);
    for (link, offset) in report.added_links.iter().zip(&offsets) {
        assert_eq!(link.reason, treecal::urdf::AddedReason::OffAxis);
        assert!((link.offset_mm - offset * 1e3).abs() < 1e-9, "{link:?}");
    }
    // The wrist joints keep their axes: only origins change.
    assert!(
        report.changes.iter().all(|c| c.new_axis.is_none()),
        "{:?}",
        report.changes
    );
    let exported = parse_urdf(&report.urdf, "added").unwrap().tree;
    assert_eq!(exported.links().len(), tree.links().len() + 2);
    let mut random = rng(23);
    for _ in 0..CONFIGURATIONS {
        let q = random_configuration(tree, &mut random);
        let poses = exported.link_poses(&q).unwrap();
        for (t, tool_pose) in model.tool_poses(&q).iter().enumerate() {
            let link = exported.link_id(added[t]).unwrap();
            assert_close(&poses[link.0], tool_pose, TOLERANCE, added[t]);
        }
        // Every modelled link, the palms too, is where the model puts it.
        for (f, link_pose) in model.link_poses(&q).iter().enumerate() {
            let link = tree.joint(model.frames()[f].joint).child;
            let name = &tree.link(link).name;
            let exported_link = exported.link_id(name).unwrap();
            assert_close(&poses[exported_link.0], link_pose, TOLERANCE, name);
        }
    }
    check_urdf_accepts(&report.urdf, "palms, tool links added");
    // Exported again, the palms now have child links (the markers): the markers are rewritten
    // in place (at the tool frames to 1e-9) and nothing is added a second time.
    let again = parse_urdf(&report.urdf, "again").unwrap().tree;
    let branches = branches_with_tools(&again, Some(&tools));
    let mut model_again = McpcModel::from_tree(&again, &branches).unwrap();
    model_again.set_parameters(&model.parameters()).unwrap();
    let second = export_urdf_with(&report.urdf, "again", &again, &model_again, &options).unwrap();
    assert!(second.added_links.is_empty(), "{:?}", second.added_links);
    let twice = parse_urdf(&second.urdf, "twice").unwrap().tree;
    assert_eq!(twice.links().len(), again.links().len());
    let mut random = rng(25);
    for _ in 0..10 {
        let q = random_configuration(tree, &mut random);
        let poses = twice.link_poses(&q).unwrap();
        for (t, tool_pose) in model_again.tool_poses(&q).iter().enumerate() {
            let marker = twice.link_id(&format!("{}_marker", tools[t])).unwrap();
            assert_close(&poses[marker.0], tool_pose, TOLERANCE, tools[t]);
        }
    }

    // A palm put back on its axis exports exactly, with nothing dropped or added.
    let mut on_axis = case(humanoid_with_palms_on_wrists(), Some(&tools), Some(21));
    let mut values = on_axis.model.parameters();
    for t in 0..2 {
        let transform = on_axis.model.tools()[t].constant_transform();
        let along = treecal::math::Vec3::new(0.0, 0.0, transform.translation.vector.z);
        let local = transform.rotation.inverse() * along;
        let offset = on_axis.model.tool_parameter_offset(t);
        values[offset + 3..offset + 6].copy_from_slice(local.as_slice());
    }
    on_axis.model.set_parameters(&values).unwrap();
    let (report, _) = export_and_check(&on_axis, "palms on their axes");
    assert!(report.dropped.is_empty() && report.added_links.is_empty());
}

/// The tolerance from a calibration's standard deviations: 3·√(σx² + σy² + σz² + |t|²·Σσ²_angles);
/// a tool without position standard deviations keeps the strict 1e-9 m; angles without one
/// count as exact.
#[test]
fn export_tolerance_is_three_sigma_of_the_tool_origin() {
    use treecal::urdf::ExportOptions;
    let tools = ["l_hand", "r_hand"];
    let c = case(humanoid_with_palms_on_wrists(), Some(&tools), Some(21));
    let mut std_devs = vec![Some(1e-4); c.model.parameter_count()];
    let right = c.model.tool_parameter_offset(1);
    std_devs[right + 4] = None; // the right palm's y
    let left = c.model.tool_parameter_offset(0);
    std_devs[left] = None; // the left palm's alpha: held, exact
    let options = ExportOptions::with_uncertainty(&c.tree, &c.model, &std_devs, false);
    let t = c.model.parameters()[left + 3..left + 6]
        .iter()
        .map(|v| v * v)
        .sum::<f64>();
    let expected = 3.0 * (3.0e-8 + t * 2.0e-8).sqrt();
    assert!((options.tolerance("l_hand") - expected).abs() < 1e-15);
    assert_eq!(
        options.tolerance("r_hand"),
        treecal::urdf::ON_AXIS_TOLERANCE
    );
}

/// The palms-on-wrists humanoid, rigid, simulated (one trial, AT901 noise) with `errors`
/// (`--angle-error`, `--length-error`) and calibrated through the CLI with `extra` flags.
fn palms_through_the_cli(dir: &Path, errors: &str, extra: &[&str]) -> (Run, std::path::PathBuf) {
    let urdf = dir.join("palms.urdf");
    std::fs::write(&urdf, humanoid_with_palms_on_wrists()).unwrap();
    // A rigid robot: no self-weight, no payload, so `calibrate` needs no --stiffness.
    let stiffness = dir.join("stiffness.yaml");
    std::fs::write(
        &stiffness,
        "gravity_m_per_s2: [0, 0, -9.81]\nself_weight: false\npayloads: {}\njoints:\n  default: {bending_nm_per_rad: 5000, torsion_nm_per_rad: 5000}\nlinks:\n  default: {ea_n: 4.420e7, ei_y_nm2: 2.485e4, ei_z_nm2: 2.485e4, gi_p_nm2: 1.846e4}\n",
    )
    .unwrap();
    let csv = dir.join(format!("m{errors}.csv"));
    let run = treecal(&[
        "simulate",
        "--robot",
        path_str(&urdf),
        "--stiffness",
        path_str(&stiffness),
        "--tools",
        "l_hand,r_hand",
        "--trials",
        "1",
        "--angle-error",
        errors,
        "--length-error",
        errors,
        "--write-measurements",
        path_str(&csv),
        "--out",
        path_str(&dir.join("simulate")),
    ]);
    assert_success(&run, "simulate");
    let out = dir.join(format!("out{errors}"));
    let mut args = vec![
        "calibrate",
        "--robot",
        path_str(&urdf),
        "--tools",
        "l_hand,r_hand",
        "--measurements",
        path_str(&csv),
        "--measurement-frame",
        "base",
        "--out",
        path_str(&out),
    ];
    args.extend_from_slice(extra);
    (treecal(&args), out)
}

/// The calibrated model of `params` (a params.yaml text) on the palms-on-wrists humanoid.
fn palms_model(params: &str) -> (KinematicTree, McpcModel) {
    let tree = parse_urdf(&humanoid_with_palms_on_wrists(), "palms")
        .unwrap()
        .tree;
    let branches = branches_with_tools(&tree, Some(&["l_hand", "r_hand"]));
    let mut model = McpcModel::from_tree(&tree, &branches).unwrap();
    let values = treecal::io::parse_parameters(params, "params", &tree, &model).unwrap();
    model.set_parameters(&values.values).unwrap();
    (tree, model)
}

/// `urdf`'s `<palm>_marker` links are at `params`' calibrated tool frames (1e-9).
fn assert_added_links_exact(urdf: &str, params: &str) {
    let (tree, model) = palms_model(params);
    let with_links = parse_urdf(urdf, "with links").unwrap().tree;
    let mut random = rng(24);
    for _ in 0..10 {
        let q = random_configuration(&tree, &mut random);
        let poses = with_links.link_poses(&q).unwrap();
        for (name, tool_pose) in ["l_hand_marker", "r_hand_marker"]
            .iter()
            .zip(model.tool_poses(&q))
        {
            let link = with_links.link_id(name).unwrap();
            assert_close(&poses[link.0], &tool_pose, TOLERANCE, name);
        }
    }
}

/// `treecal calibrate` on the palms-on-wrists humanoid. A true robot with the palms on the
/// wrist axes (no kinematic errors, AT901 noise): the calibrated palm origin lies off the axis
/// by noise only, which the export drops and reports; the palms stay the wrist joints' children;
/// `export --add-tool-links` from params.yaml then has nothing to add, and from a params.yaml
/// without standard deviations it adds `<palm>_marker` links at the exact calibrated tool
/// frames (1e-9), refusing without the flag.
#[test]
fn palm_on_the_wrist_joint_calibrates_and_exports_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let (run, out) = palms_through_the_cli(dir.path(), "0", &[]);
    assert_success(&run, "calibrate");
    assert!(run.stderr.contains("moved onto the axis"), "{run}");
    let calibrated = parse_urdf(&read(&out.join("calibrated.urdf")), "calibrated")
        .unwrap()
        .tree;
    for (palm, joint) in [("l_hand", "l_wrist_roll"), ("r_hand", "r_wrist_roll")] {
        let parent = calibrated
            .link(calibrated.link_id(palm).unwrap())
            .parent_joint
            .unwrap();
        assert_eq!(calibrated.joint(parent).name, joint);
    }
    let robot = dir.path().join("palms.urdf");
    let robot = path_str(&robot);
    let tools = "l_hand,r_hand";
    let exported = dir.path().join("exported.urdf");
    let params = out.join("params.yaml");
    let run = treecal(&[
        "export",
        "--robot",
        robot,
        "--tools",
        tools,
        "--params",
        path_str(&params),
        "--add-tool-links",
        "-o",
        path_str(&exported),
    ]);
    assert_success(&run, "export");
    assert_eq!(read(&exported), read(&out.join("calibrated.urdf")));
    let params = read(&params);
    let stripped: String = params
        .lines()
        .filter(|l| !l.trim_start().starts_with("std_dev"))
        .map(|l| format!("{l}\n"))
        .collect();
    let bare = dir.path().join("bare.yaml");
    std::fs::write(&bare, &stripped).unwrap();
    let run = treecal(&[
        "export",
        "--robot",
        robot,
        "--tools",
        tools,
        "--params",
        path_str(&bare),
        "-o",
        path_str(&exported),
    ]);
    assert_error(
        &run,
        &["l_hand", "--add-tool-links"],
        "export without std_dev",
    );
    let run = treecal(&[
        "export",
        "--robot",
        robot,
        "--tools",
        tools,
        "--params",
        path_str(&bare),
        "--add-tool-links",
        "-o",
        path_str(&exported),
    ]);
    assert_success(&run, "export --add-tool-links");
    assert!(run.stderr.contains("added link 'l_hand_marker'"), "{run}");
    assert_added_links_exact(&read(&exported), &params);
}

/// A true robot whose palms sit centimetres off the wrist axes (`simulate`'s default errors, as
/// a mocap marker body on a leaf wrist link): `calibrate` adds the `<palm>_marker` links at
/// the calibrated tool frames by default (1e-9) and says so; `export` of the same params.yaml
/// without `--add-tool-links` refuses, naming the palm and the flag.
#[test]
fn palm_off_the_wrist_axis_gets_added_tool_links() {
    let dir = tempfile::tempdir().unwrap();
    let (run, out) = palms_through_the_cli(dir.path(), "0.05", &[]);
    assert_success(&run, "calibrate");
    for palm in ["l_hand", "r_hand"] {
        assert!(
            run.stderr.contains(&format!("added link '{palm}_marker'")),
            "{run}"
        );
    }
    let calibrated = read(&out.join("calibrated.urdf"));
    assert_added_links_exact(&calibrated, &read(&out.join("params.yaml")));
    let robot = dir.path().join("palms.urdf");
    let exported = dir.path().join("exported.urdf");
    let export = |extra: &[&str]| {
        let mut args = vec![
            "export",
            "--robot",
            path_str(&robot),
            "--tools",
            "l_hand,r_hand",
            "--params",
        ];
        let params = out.join("params.yaml");
        let params = path_str(&params).to_owned();
        args.push(&params);
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", path_str(&exported)]);
        treecal(&args)
    };
    assert_error(&export(&[]), &["l_hand", "--add-tool-links"], "export");
    let run = export(&["--add-tool-links"]);
    assert_success(&run, "export --add-tool-links");
    assert_eq!(read(&exported), calibrated);
}
