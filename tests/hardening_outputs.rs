//! Issue 21, the command and output half: a reader that closes the pipe, collision meshes that
//! cannot be used, outputs that would replace an input, output folders left by killed or
//! concurrent runs, outputs checked before computing, and silently accepted inputs (mimic
//! chains, unused stage labels, repeated joint names).

use crate::common::cli::*;
use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn example() -> String {
    path_str(&robot("robonaut/example/measurements.csv")).to_owned()
}

// ---------------------------------------------------------------------------------------------
// broken pipe

/// Runs `treecal args…` with standard output a pipe whose reader is already gone (as for
/// `treecal inspect | head -1` once `head` has exited).
#[cfg(unix)]
fn treecal_into_closed_pipe(args: &[&str]) -> (Option<i32>, String) {
    let (reader, writer) = rustix::pipe::pipe().unwrap();
    drop(reader);
    let output = Command::new(env!("CARGO_BIN_EXE_treecal"))
        .args(args)
        .current_dir(repo())
        .stdin(Stdio::null())
        .stdout(Stdio::from(writer))
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[cfg(unix)]
#[test]
fn a_closed_pipe_ends_every_printing_command_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let joints = write(
        dir.path(),
        "q.csv",
        "left_joint1,left_joint2\n0.1,0.2\n0.3,0.4\n",
    );
    let out = dir.path().join("out");
    let poses = dir.path().join("poses.csv");
    let example = example();
    let stiffness = path_str(&robot("robonaut/stiffness.yaml")).to_owned();
    let runs: Vec<Vec<&str>> = vec![
        vec!["inspect"],
        vec!["inspect", "--format", "json"],
        vec!["to-mcpc"],
        vec!["fk", "--tip", "left_tool", "--joints", path_str(&joints)],
        vec!["check", "--measurements", &example],
        vec![
            "calibrate",
            "--measurements",
            &example,
            "--stiffness",
            &stiffness,
            "-o",
            path_str(&out),
        ],
        vec![
            "plan",
            "--poses",
            "2",
            "--candidates",
            "40",
            "-o",
            path_str(&poses),
        ],
        vec![
            "simulate",
            "--poses",
            "8",
            "--torso-poses",
            "8",
            "--validation-poses",
            "4",
            "-o",
            path_str(&out),
        ],
    ];
    for args in runs {
        let (code, stderr) = treecal_into_closed_pipe(&args);
        assert!(
            !stderr.contains("panicked") && !stderr.contains("Broken pipe"),
            "{args:?}: {stderr}"
        );
        assert_eq!(code, Some(0), "{args:?}: exit code\n{stderr}");
    }
    // Any other failure to print is still an error (a full disk behind a redirection).
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full");
    if let Ok(full) = full {
        let output = Command::new(env!("CARGO_BIN_EXE_treecal"))
            .arg("inspect")
            .stdout(Stdio::from(full))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.starts_with("treecal: error: standard output:"),
            "{stderr}"
        );
    }
    // simulate states its collision check in summary.md's header.
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(
        summary.contains("self-collision check: meshes ("),
        "{summary}"
    );
}

// ---------------------------------------------------------------------------------------------
// collision meshes that cannot be used

/// The humanoid with a `package://` collision mesh that is not installed on its left upper arm.
fn humanoid_with_missing_mesh(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(robot("humanoid/humanoid.urdf")).unwrap();
    let marker = "</robot>";
    let link = r#"  <link name="mesh_probe"><collision><geometry><mesh filename="package://not_installed/meshes/probe.stl"/></geometry></collision></link>
  <joint name="mesh_probe_joint" type="fixed"><parent link="r_foot"/><child link="mesh_probe"/></joint>
"#;
    let text = text.replacen(marker, &format!("{link}{marker}"), 1);
    write(dir, "humanoid_mesh.urdf", &text)
}

fn plan_args<'a>(robot: &'a str, out: &'a str, check: Option<&'a str>) -> Vec<&'a str> {
    let mut args = vec![
        "plan",
        "--robot",
        robot,
        "--poses",
        "2",
        "--candidates",
        "40",
        "-o",
        out,
    ];
    if let Some(check) = check {
        args.extend(["--collision-check", check]);
    }
    args
}

#[test]
fn a_missing_collision_mesh_stops_plan_unless_the_check_is_weakened_explicitly() {
    let dir = tempfile::tempdir().unwrap();
    let robot_path = humanoid_with_missing_mesh(dir.path());
    let robot = path_str(&robot_path);
    let out = dir.path().join("poses.csv");
    let run = treecal(&plan_args(robot, path_str(&out), None));
    assert_error(
        &run,
        &[
            "package://not_installed/meshes/probe.stl",
            "--package-path",
            "--collision-check primitives-only",
        ],
        "plan with a missing mesh",
    );
    assert!(!out.exists(), "nothing written");

    for (check, header) in [
        (
            "primitives-only",
            "# self-collision check: primitives-only (",
        ),
        (
            "off",
            "# self-collision check: off (configurations NOT checked",
        ),
    ] {
        let run = treecal(&plan_args(robot, path_str(&out), Some(check)));
        assert_success(&run, check);
        let csv = std::fs::read_to_string(&out).unwrap();
        assert!(csv.starts_with(header), "{check}: {csv}");
        assert!(run.stdout.contains("self-collision check:"), "{run}");
        assert!(run.stderr.contains("--collision-check"), "{check}: {run}");
        // The pose file is still a pose file.
        let check_run = treecal(&["check", "--robot", robot, "--poses", path_str(&out)]);
        assert_success(&check_run, "check of the planned poses");
    }
}

#[test]
fn a_robot_whose_shapes_all_load_plans_with_the_full_check_stated() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("poses.csv");
    let humanoid = robot("humanoid/humanoid.urdf");
    let run = treecal(&plan_args(path_str(&humanoid), path_str(&out), None));
    assert_success(
        &run,
        "plan on the humanoid (primitives only, nothing missing)",
    );
    let csv = std::fs::read_to_string(&out).unwrap();
    assert!(csv.starts_with("# self-collision check: meshes ("), "{csv}");
    assert!(
        !run.stderr.contains("collision") && !run.stderr.contains("mesh"),
        "no false alarm: {run}"
    );
}

#[test]
fn an_unreadable_mesh_is_named_without_an_unformatted_placeholder() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "probe.xyz", "not a mesh at all");
    let text = std::fs::read_to_string(robot("humanoid/humanoid.urdf")).unwrap();
    let text = text.replacen(
        "</robot>",
        r#"<link name="mesh_probe"><collision><geometry><mesh filename="probe.xyz"/></geometry></collision></link>
<joint name="mesh_probe_joint" type="fixed"><parent link="r_foot"/><child link="mesh_probe"/></joint>
</robot>"#,
        1,
    );
    let urdf = write(dir.path(), "robot.urdf", &text);
    let out = dir.path().join("poses.csv");
    let run = treecal(&plan_args(path_str(&urdf), path_str(&out), None));
    assert_error(
        &run,
        &["probe.xyz", "unreadable"],
        "plan with a non-mesh file",
    );
    assert!(!run.stderr.contains("{path"), "{run}");
}

#[test]
fn a_missing_collision_mesh_stops_simulate_too() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(robot("robonaut/robonaut.urdf")).unwrap();
    let text = text.replacen(
        "</robot>",
        r#"<link name="mesh_probe"><collision><geometry><mesh filename="missing/probe.dae"/></geometry></collision></link>
<joint name="mesh_probe_joint" type="fixed"><parent link="base_link"/><child link="mesh_probe"/></joint>
</robot>"#,
        1,
    );
    let urdf = write(dir.path(), "robonaut_mesh.urdf", &text);
    let stiffness = robot("robonaut/stiffness.yaml");
    let out = dir.path().join("sim");
    let run = treecal(&[
        "simulate",
        "--robot",
        path_str(&urdf),
        "--stiffness",
        path_str(&stiffness),
        "-o",
        path_str(&out),
    ]);
    assert_error(
        &run,
        &["missing/probe.dae", "--collision-check"],
        "simulate with a missing mesh",
    );
}

// ---------------------------------------------------------------------------------------------
// outputs that would replace or delete an input

#[test]
fn calibrate_refuses_an_output_folder_holding_any_input() {
    let example_text = std::fs::read_to_string(robot("robonaut/example/measurements.csv")).unwrap();
    let stiffness = std::fs::read_to_string(robot("robonaut/stiffness.yaml")).unwrap();
    let registration = "units: {length: mm, angle: deg}\nxyz: [0, 0, 0]\nrpy: [0, 0, 0]\n";
    for (name, flag, text) in [
        // Under an output's name: it used to be overwritten (registration) or deleted.
        ("params.yaml", "--measurement-frame", registration),
        ("stiffness.yaml", "--stiffness", stiffness.as_str()),
        ("measurements.csv", "--measurements", example_text.as_str()),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let input = write(&out, name, text);
        let mut args = vec!["calibrate", "-o", path_str(&out)];
        let example_path = example();
        if flag != "--measurements" {
            args.extend(["--measurements", &example_path]);
        }
        args.extend([flag, path_str(&input)]);
        let run = treecal(&args);
        assert_error(
            &run,
            &["the output folder holds the input file", name],
            &format!("{flag} inside --out"),
        );
        assert_eq!(
            std::fs::read_to_string(&input).unwrap(),
            text,
            "{name} kept"
        );
    }
}

#[test]
fn file_outputs_refuse_their_inputs_and_folders() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = write(
        dir.path(),
        "robot.urdf",
        &std::fs::read_to_string(robot("humanoid/humanoid.urdf")).unwrap(),
    );
    let before = std::fs::read_to_string(&urdf).unwrap();
    for args in [
        vec!["to-mcpc", "--robot", path_str(&urdf), "-o", path_str(&urdf)],
        vec![
            "plan",
            "--robot",
            path_str(&urdf),
            "--poses",
            "2",
            "-o",
            path_str(&urdf),
        ],
    ] {
        let run = treecal(&args);
        assert_error(
            &run,
            &["the output is the input file"],
            &format!("{args:?}"),
        );
    }
    assert_eq!(std::fs::read_to_string(&urdf).unwrap(), before);
}

// ---------------------------------------------------------------------------------------------
// outputs checked before computing

#[test]
fn unwritable_outputs_are_refused_before_computing() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "a_file", "x");
    let under_file = file.join("poses.csv");
    let example = example();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["plan", "--poses", "2", "-o", "."], "is a folder"),
        (
            vec!["plan", "--poses", "2", "-o", path_str(&under_file)],
            "is a file, not a folder",
        ),
        (vec!["to-mcpc", "-o", "."], "is a folder"),
        (
            vec!["from-mcpc", "robots/robonaut/table1.yaml", "-o", ".."],
            "is a folder",
        ),
        (
            vec!["calibrate", "--measurements", &example, "-o", "."],
            "names no folder",
        ),
        (
            vec![
                "calibrate",
                "--measurements",
                &example,
                "-o",
                path_str(&file),
            ],
            "is a file",
        ),
        (vec!["simulate", "-o", path_str(&file)], "is a file"),
    ];
    for (args, needle) in cases {
        let started = std::time::Instant::now();
        let run = treecal_in(Some(dir.path()), &args);
        assert_error(&run, &[needle], &format!("{args:?}"));
        assert!(
            !run.stderr.contains("wrote"),
            "{args:?}: refused before computing\n{run}"
        );
        assert!(
            started.elapsed().as_secs() < 30,
            "{args:?}: took {:?}",
            started.elapsed()
        );
    }
}

// ---------------------------------------------------------------------------------------------
// output folders of killed and concurrent runs

#[test]
fn a_second_run_on_a_locked_output_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let lock = treecal::io::lock_output(dir.path(), "out").unwrap();
    let out = dir.path().join("out");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        &example(),
        "-o",
        path_str(&out),
    ]);
    assert_error(
        &run,
        &["another treecal run", ".out.lock"],
        "calibrate while another run writes --out",
    );
    drop(lock);
    assert!(!dir.path().join(".out.lock").exists());
}

#[test]
fn leftovers_of_killed_runs_are_recovered_or_removed() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // Killed between the two renames of the fallback swap: no `out`, its previous folder.
    let previous = dir.path().join(".out.old-999999999");
    std::fs::create_dir(&previous).unwrap();
    write(&previous, "report.md", "old");
    // Killed while writing.
    std::fs::create_dir(dir.path().join(".out.new-999999998")).unwrap();
    treecal::io::check_output_folder(&out, &|_| true).unwrap();
    treecal::io::replace_folder(&out, &[("report.md".into(), b"new".to_vec())]).unwrap();
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["out"]);
    assert_eq!(
        std::fs::read_to_string(out.join("report.md")).unwrap(),
        "new"
    );
}

// ---------------------------------------------------------------------------------------------
// silent acceptance

/// A chain of `count` revolute joints, each after the first mimicking the one before with
/// `multiplier`.
fn mimic_chain(count: usize, multiplier: &str) -> String {
    let mut joints = String::new();
    let mut links = String::from(r#"<link name="l0"/>"#);
    for i in 1..=count {
        links.push_str(&format!(r#"<link name="l{i}"/>"#));
        let mimic = if i > 1 {
            format!(r#"<mimic joint="j{}" multiplier="{multiplier}"/>"#, i - 1)
        } else {
            String::new()
        };
        joints.push_str(&format!(
            r#"<joint name="j{i}" type="revolute"><parent link="l{}"/><child link="l{i}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>{mimic}</joint>"#,
            i - 1
        ));
    }
    format!(r#"<robot name="chain">{links}{joints}</robot>"#)
}

#[test]
fn an_overflowing_mimic_chain_is_an_error_naming_the_joints() {
    // 1e5^79 overflows to infinity: `fk` printed NaN poses with exit 0.
    let error = treecal::parse_urdf(&mimic_chain(80, "1e5"), "chain.urdf")
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("<mimic> chain") && error.contains("j1") && error.contains("multiplier"),
        "{error}"
    );
    // A short chain composes to a sane factor (no false alarm), and moves as composed.
    let tree = treecal::parse_urdf(&mimic_chain(4, "2"), "chain.urdf")
        .unwrap()
        .tree;
    assert_eq!(tree.dof_count(), 1);
    let last = tree.link_id("l4").unwrap();
    let pose = tree.link_pose(last, &[0.1]).unwrap();
    // Rotations about z add up: 0.1 (1 + 2 + 4 + 8).
    let angle = pose.rotation.angle();
    assert!((angle - 1.5).abs() < 1e-12, "{angle}");
}

#[test]
fn rows_whose_stage_no_stage_uses_are_named_and_an_error_when_strict() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(robot("robonaut/example/measurements.csv")).unwrap();
    let mut relabelled = 0;
    let lines: Vec<String> = text
        .lines()
        .map(|line| {
            if relabelled < 2 && line.contains(",arms,") {
                relabelled += 1;
                line.replacen(",arms,", ",arm,", 1)
            } else {
                line.to_owned()
            }
        })
        .collect();
    let csv = write(dir.path(), "m.csv", &(lines.join("\n") + "\n"));
    // `check` analyses the stages of the same plan: it names them too.
    let run = treecal(&["check", "--measurements", path_str(&csv)]);
    assert_success(&run, "check");
    assert!(
        run.stderr.contains("2 rows labelled 'arm'") && run.stderr.contains("used by no stage"),
        "{run}"
    );
    let out = dir.path().join("out");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&csv),
        "-o",
        path_str(&out),
    ]);
    assert!(
        run.stderr.contains("2 rows labelled 'arm'") && run.stderr.contains("did you mean 'arms'"),
        "{run}"
    );
    let strict = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--strict",
        "-o",
        path_str(&out),
    ]);
    assert_error(&strict, &["labelled 'arm'", "used by no stage"], "--strict");
    // The example as shipped: every row is used.
    let good = treecal(&[
        "calibrate",
        "--measurements",
        &example(),
        "-o",
        path_str(&out),
    ]);
    assert!(!good.stderr.contains("used by no stage"), "{good}");
}

#[test]
fn fk_refuses_a_joint_named_twice() {
    let config = treecal::workflow::FkConfig {
        tip: "left_tool".into(),
        joint_names: vec!["left_joint1".into(), "left_joint1 ".into()],
        joints: vec![vec![0.1, 0.2]],
        ..Default::default()
    };
    let error = treecal::workflow::fk(&config).unwrap_err().to_string();
    assert!(error.contains("'left_joint1' is named twice"), "{error}");
}
