//! The deployable outputs of `calibrate` (issue 23): `calibration_overlay.yaml` reproduces
//! `calibrated.urdf` when applied to the nominal URDF (by treecal, and by the real `xacro` from
//! PyPI when it is installed: required with `TREECAL_REQUIRE_TOOLS=1`), and
//! `joint_offsets.yaml` carries an offsets-only calibration.

use crate::common::cli::*;
use crate::common::*;
use std::path::{Path, PathBuf};
use treecal::io::parse_overlay;
use treecal::tree::{JointKind, KinematicTree};
use treecal::urdf::{apply_overlay, JointOverlay};
use treecal::{load_urdf, parse_urdf};

/// The built-in Robonaut with a finger link below each tool link: the tool links have
/// children, so the export adds `<tool>_marker` links (docs/export.md).
fn robonaut_with_fingers(dir: &Path) -> PathBuf {
    let mut text = read(&robot("robonaut/robonaut.urdf"));
    let mut fingers = String::new();
    for side in ["left", "right"] {
        fingers.push_str(&format!(
            "  <link name=\"{side}_finger\"/>\n  <joint name=\"{side}_finger_joint\" type=\"fixed\">\n    <parent link=\"{side}_tool\"/>\n    <child link=\"{side}_finger\"/>\n    <origin xyz=\"0 0 0.05\" rpy=\"0 0 0\"/>\n  </joint>\n"
        ));
    }
    text = text.replace("</robot>", &format!("{fingers}</robot>"));
    let path = dir.join("robonaut_fingers.urdf");
    std::fs::write(&path, text).unwrap();
    path
}

/// Runs the README example calibration (with `extra` flags; `fingers`: on
/// [`robonaut_with_fingers`]) into a fresh folder.
pub fn calibrate_example(extra: &[&str]) -> (tempfile::TempDir, PathBuf) {
    calibrate_example_on(false, extra)
}

fn calibrate_example_on(fingers: bool, extra: &[&str]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let robot_path = robonaut_with_fingers(dir.path());
    let out = dir.path().join("out");
    let csv = robot("robonaut/example/measurements.csv");
    let stiffness = robot("robonaut/stiffness.yaml");
    let mut args = vec![
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--stiffness",
        path_str(&stiffness),
        "--out",
        path_str(&out),
    ];
    if fingers {
        args.extend_from_slice(&["--robot", path_str(&robot_path)]);
    }
    args.extend_from_slice(extra);
    let run = treecal(&args);
    assert_success(&run, "calibrate the README example");
    (dir, out)
}

/// The largest distance (m) and angle (rad) between the poses of the links both trees have,
/// over `configurations` seeded random configurations.
fn largest_link_gap(a: &KinematicTree, b: &KinematicTree, configurations: usize) -> (f64, f64) {
    let mut rng = rng(23);
    let (mut distance, mut angle) = (0.0f64, 0.0f64);
    for _ in 0..configurations {
        let q = random_configuration(a, &mut rng);
        let poses_a = a.link_poses(&q).unwrap();
        let poses_b = b.link_poses(&q).unwrap();
        for (index, link) in a.links().iter().enumerate() {
            let other = b.link_id(&link.name).unwrap();
            let (d, r) = pose_difference(&poses_a[index], &poses_b[other.0]);
            distance = distance.max(d);
            angle = angle.max(r);
        }
    }
    (distance, angle)
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn readme_example_overlay_applied_to_the_nominal_urdf_is_calibrated_urdf() {
    let (_dir, out) = calibrate_example(&[]);
    let overlay_text = read(&out.join("calibration_overlay.yaml"));
    let overlay = parse_overlay(&overlay_text, "calibration_overlay.yaml").unwrap();
    assert!(overlay.joints.len() >= 10, "{overlay_text}");
    assert!(overlay_text.contains("xacro.load_yaml"), "{overlay_text}");
    let nominal_path = robot("robonaut/robonaut.urdf");
    let nominal = read(&nominal_path);
    let applied = apply_overlay(&nominal, "robonaut.urdf", &overlay).unwrap();
    let calibrated = read(&out.join("calibrated.urdf"));
    // The same edits with the same numbers: the very same file.
    assert_eq!(applied, calibrated);
    let a = parse_urdf(&applied, "applied").unwrap().tree;
    let b = load_urdf(&out.join("calibrated.urdf")).unwrap().tree;
    let (distance, angle) = largest_link_gap(&b, &a, 20);
    assert!(
        distance <= 1e-9 && angle <= 1e-9,
        "{distance} m, {angle} rad"
    );
    // And it moved something: the nominal robot is far from it.
    let n = load_urdf(&nominal_path).unwrap().tree;
    let (distance, _) = largest_link_gap(&b, &n, 5);
    assert!(distance > 1e-3, "{distance}");

    // A geometry calibration: no offsets file, and the report says why.
    assert!(!out.join("joint_offsets.yaml").exists());
    let report = read(&out.join("report.md"));
    assert!(
        report.contains("no `joint_offsets.yaml`: the calibration changes"),
        "{report}"
    );
    assert!(report.contains("calibration_overlay.yaml"), "{report}");
    // The command line's reports say its flags, not the library's setting names (the Python
    // binding's say keywords); provenance.yaml hashes the files as written.
    assert!(
        report.contains("(calibrate with --model offsets for an offsets-only result)")
            && !report.contains("`model`"),
        "{report}"
    );
    let html = read(&out.join("report.html"));
    assert!(
        html.contains("<code>--model</code> offsets")
            && html.contains("give <code>--validation</code> to use your own")
            && !html.contains("<code>model</code>")
            && !html.contains("`validation`"),
        "report.html names the library's setting"
    );
    // Root frame (not fitted): no gap where "measurement frame and" would go.
    assert!(
        report.contains("registered like the calibrated one: its tool frames fitted"),
        "{report}"
    );
    let provenance = read(&out.join("provenance.yaml"));
    let line = format!("sha256: {}", treecal::io::sha256_hex(report.as_bytes()));
    assert!(provenance.contains(&line), "{provenance}");
}

#[test]
fn overlay_round_trips_through_its_yaml_and_refuses_a_calibrated_urdf() {
    let (dir, out) = calibrate_example_on(true, &[]);
    let text = read(&out.join("calibration_overlay.yaml"));
    let overlay = parse_overlay(&text, "overlay").unwrap();
    let again = treecal::io::overlay_to_yaml(&overlay, "");
    let reread: JointOverlay = parse_overlay(&again, "again").unwrap();
    assert_eq!(overlay, reread);
    // Applied twice, the added links would be declared twice: refused with a message.
    assert_eq!(overlay.added_links.len(), 2, "{text}");
    let nominal = read(&dir.path().join("robonaut_fingers.urdf"));
    let applied = apply_overlay(&nominal, "robonaut_fingers.urdf", &overlay).unwrap();
    let calibrated = read(&out.join("calibrated.urdf"));
    assert_eq!(applied, calibrated);
    {
        let error = apply_overlay(&calibrated, "calibrated.urdf", &overlay).unwrap_err();
        assert!(error.to_string().contains("nominal URDF"), "{error}");
    }
    // A wrong robot is named.
    let other = read(&robot("humanoid/humanoid.urdf"));
    let error = apply_overlay(&other, "humanoid.urdf", &overlay).unwrap_err();
    assert!(error.to_string().contains("does not have"), "{error}");
}

/// The `offset` of every joint in joint_offsets.yaml (`  "name": {offset: v, unit: u, ...}`).
fn offsets_of(text: &str) -> Vec<(String, f64)> {
    text.lines()
        .filter_map(|line| {
            let line = line.strip_prefix("  \"")?;
            let (name, rest) = line.split_once("\": {offset: ")?;
            let value = rest.split(',').next()?.parse().ok()?;
            Some((name.to_owned(), value))
        })
        .collect()
}

/// Measurements of the nominal Robonaut whose encoders read `q − offset` (positions of both
/// tools in the root frame, m and rad): a robot that offsets alone calibrate.
fn offset_measurements(dir: &Path, offsets: &[(&str, f64)]) -> PathBuf {
    let tree = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let names: Vec<String> = tree
        .dofs()
        .iter()
        .map(|&j| tree.joint(j).name.clone())
        .collect();
    let mut text = format!("id,tool,{},x,y,z\n", names.join(","));
    let mut rng = rng(11);
    for row in 0..40 {
        let q: Vec<f64> = random_configuration(&tree, &mut rng)
            .iter()
            .map(|v| 0.8 * v)
            .collect();
        let mut reported = q.clone();
        for (joint, offset) in offsets {
            reported[tree.dof_of(tree.joint_id(joint).unwrap()).unwrap().0] -= offset;
        }
        for tool in ["left_tool", "right_tool"] {
            let p = tree
                .link_pose(tree.link_id(tool).unwrap(), &q)
                .unwrap()
                .translation
                .vector;
            let values: Vec<String> = reported.iter().map(|v| v.to_string()).collect();
            text += &format!(
                "{row}{tool},{tool},{},{},{},{}\n",
                values.join(","),
                p.x,
                p.y,
                p.z
            );
        }
    }
    let path = dir.join("offsets.csv");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn offsets_model_writes_joint_offsets_that_move_the_nominal_urdf_like_the_calibrated_one() {
    let dir = tempfile::tempdir().unwrap();
    let truth = [
        ("torso_joint2", 0.004),
        ("left_joint2", -0.006),
        ("right_joint3", 0.003),
    ];
    let csv = offset_measurements(dir.path(), &truth);
    let out = dir.path().join("out");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--model",
        "offsets",
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate --model offsets");
    let text = read(&out.join("joint_offsets.yaml"));
    assert!(
        text.contains("convention: q_urdf = q_reported + offset"),
        "{text}"
    );
    let offsets = offsets_of(&text);
    assert!(offsets.len() >= 10, "{text}");
    // The offsets found are the true ones (noise-free data).
    for (joint, value) in &truth {
        let found = offsets.iter().find(|(j, _)| j == joint).unwrap().1;
        assert!(
            (found - value).abs() < 1e-6,
            "{joint}: {found} against {value}"
        );
    }
    let nominal = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let calibrated = load_urdf(&out.join("calibrated.urdf")).unwrap().tree;
    let mut rng = rng(7);
    let mut largest = 0.0f64;
    for _ in 0..20 {
        let q = random_configuration(&calibrated, &mut rng);
        let mut shifted = q.clone();
        for (joint, offset) in &offsets {
            let id = nominal.joint_id(joint).unwrap();
            shifted[nominal.dof_of(id).unwrap().0] += offset;
        }
        let a = calibrated.link_poses(&q).unwrap();
        let b = nominal.link_poses(&shifted).unwrap();
        // The links the joints move (the tool frames, measured markers, are in the overlay).
        for joint in nominal
            .joints()
            .iter()
            .filter(|j| j.kind != JointKind::Fixed)
        {
            let child = calibrated.link_id(&nominal.link(joint.child).name).unwrap();
            let (d, r) = pose_difference(&a[child.0], &b[joint.child.0]);
            largest = largest.max(d).max(r);
        }
    }
    assert!(largest <= 1e-9, "{largest}");
    let report = read(&out.join("report.md"));
    assert!(report.contains("`joint_offsets.yaml`:"), "{report}");
}

const XACRO_PACKAGE: &str = "xacro (PyPI: python3 -m pip install xacro==2.1.1)";

/// The `xacro` command, or `None` (a loud skip) when it is missing and not required.
fn xacro() -> Option<PathBuf> {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|p| p.join("xacro"))
            .find(|p| p.is_file())
    });
    if found.is_none() {
        if std::env::var("TREECAL_REQUIRE_TOOLS").is_ok_and(|v| v == "1") {
            panic!("TREECAL_REQUIRE_TOOLS=1 but xacro is missing: {XACRO_PACKAGE}");
        }
        eprintln!("\n!!! SKIPPED: the xacro check of tests/deploy.rs: {XACRO_PACKAGE}\n");
    }
    found
}

/// The nominal URDF as a xacro that reads every overlay joint's origin and axis, and adds the
/// overlay's links, with the lines docs/export.md gives.
fn xacro_of(nominal: &str, overlay: &JointOverlay) -> String {
    let mut text = nominal.replacen(
        "<robot name=\"robonaut\">",
        "<robot name=\"robonaut\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n  <xacro:property name=\"calibration\" value=\"${xacro.load_yaml('calibration_overlay.yaml')}\"/>",
        1,
    );
    assert!(
        text.contains("xmlns:xacro"),
        "the test expects <robot name=\"robonaut\">"
    );
    for joint in &overlay.joints {
        let start = text
            .find(&format!("<joint name=\"{}\"", joint.joint))
            .unwrap();
        let end = start + text[start..].find("</joint>").unwrap();
        let element = &text[start..end];
        let origin_start = element.find("<origin").unwrap();
        let origin_end = origin_start + element[origin_start..].find("/>").unwrap() + 2;
        // docs/export.md's lines: a property `j` for the joint's entry, then its values.
        let tag_end = element.find('>').unwrap() + 1;
        let j = "j";
        let mut replaced = format!(
            "{}\n    <xacro:property name=\"j\" value=\"${{calibration['joints']['{}']}}\"/>{}<origin xyz=\"${{{j}['x']}} ${{{j}['y']}} ${{{j}['z']}}\" rpy=\"${{{j}['roll']}} ${{{j}['pitch']}} ${{{j}['yaw']}}\"/>{}",
            &element[..tag_end],
            joint.joint,
            &element[tag_end..origin_start],
            &element[origin_end..]
        );
        if joint.axis.is_some() {
            let axis_start = replaced.find("<axis").unwrap();
            let axis_end = axis_start + replaced[axis_start..].find("/>").unwrap() + 2;
            replaced.replace_range(
                axis_start..axis_end,
                &format!(
                    "<axis xyz=\"${{{j}['axis'][0]}} ${{{j}['axis'][1]}} ${{{j}['axis'][2]}}\"/>"
                ),
            );
        }
        text.replace_range(start..end, &replaced);
    }
    let mut added = String::new();
    for link in &overlay.added_links {
        let m = format!("calibration['added_links']['{}']", link.link);
        added.push_str(&format!(
            "  <link name=\"{name}\"/>\n  <joint name=\"${{{m}['joint']}}\" type=\"fixed\">\n    <parent link=\"${{{m}['parent']}}\"/>\n    <child link=\"{name}\"/>\n    <origin xyz=\"${{{m}['x']}} ${{{m}['y']}} ${{{m}['z']}}\" rpy=\"${{{m}['roll']}} ${{{m}['pitch']}} ${{{m}['yaw']}}\"/>\n  </joint>\n",
            name = link.link
        ));
    }
    text.replace("</robot>", &format!("{added}</robot>"))
}

#[test]
fn real_xacro_loading_the_overlay_gives_calibrated_urdf_to_a_nanometre() {
    let Some(xacro) = xacro() else { return };
    let (dir, out) = calibrate_example_on(true, &[]);
    let overlay = parse_overlay(&read(&out.join("calibration_overlay.yaml")), "overlay").unwrap();
    let source = dir.path().join("robot.urdf.xacro");
    std::fs::copy(
        out.join("calibration_overlay.yaml"),
        dir.path().join("calibration_overlay.yaml"),
    )
    .unwrap();
    assert_eq!(overlay.added_links.len(), 2);
    let nominal = read(&dir.path().join("robonaut_fingers.urdf"));
    std::fs::write(&source, xacro_of(&nominal, &overlay)).unwrap();
    let expanded = dir.path().join("expanded.urdf");
    let run = std::process::Command::new(&xacro)
        .arg(&source)
        .arg("-o")
        .arg(&expanded)
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "xacro failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let a = load_urdf(&expanded).unwrap().tree;
    let b = load_urdf(&out.join("calibrated.urdf")).unwrap().tree;
    assert_eq!(a.links().len(), b.links().len());
    let (distance, angle) = largest_link_gap(&b, &a, 20);
    assert!(
        distance <= 1e-9 && angle <= 1e-9,
        "{distance} m, {angle} rad"
    );
}
