//! docs/tutorial.md, as written: every command line of its `sh` blocks runs with `bash` in a
//! scratch folder holding a copy of `robots/` (and `../shared` pointing at the shared robots),
//! `treecal` being the built binary and the `cargo run … --example tutorial_robot --` prefix
//! the built example; then the figures the tutorial states are checked.

use crate::common::repo;
use serde_json::Value;
use std::path::{Path, PathBuf};

const EXAMPLE_PREFIX: &str = "cargo run --release --locked --example tutorial_robot --";

/// The command lines of the tutorial's `sh` blocks, with their line numbers.
fn commands(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut in_sh = false;
    for (index, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if let Some(info) = trimmed.strip_prefix("```") {
            in_sh = !in_sh && info.trim() == "sh";
            continue;
        }
        if in_sh && !trimmed.is_empty() && !trimmed.starts_with('#') {
            out.push((index + 1, trimmed.to_owned()));
        }
    }
    out
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

/// The built example, or `None` (a loud skip; a failure with `TREECAL_REQUIRE_TOOLS=1`):
/// `cargo test` builds the examples, `cargo test --test tests` does not.
fn example_binary(treecal: &Path) -> Option<PathBuf> {
    let path = treecal.parent()?.join("examples/tutorial_robot");
    if path.is_file() {
        return Some(path);
    }
    let problem = format!(
        "{} is not built (cargo build --example tutorial_robot)",
        path.display()
    );
    if std::env::var("TREECAL_REQUIRE_TOOLS").is_ok_and(|v| v == "1") {
        panic!("TREECAL_REQUIRE_TOOLS=1 but {problem}");
    }
    eprintln!("\n!!! SKIPPED: tests/tutorial.rs: {problem}\n");
    None
}

fn report(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path.join("report.json")).unwrap()).unwrap()
}

/// RMS of the validation rows' position errors, before or after.
fn validation_rms(report: &Value, which: &str) -> f64 {
    let errors: Vec<f64> = report["validation"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|arm| arm["rows"].as_array().unwrap().iter())
        .map(|row| row["position_mm"][which].as_f64().unwrap())
        .collect();
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt()
}

#[test]
fn tutorial_commands_run_as_written_and_give_what_it_says() {
    let treecal = PathBuf::from(env!("CARGO_BIN_EXE_treecal"));
    let Some(example) = example_binary(&treecal) else {
        return;
    };
    let shared = std::env::var_os("TREECAL_SHARED_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("../shared"));
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("repo");
    copy_dir(&repo().join("robots"), &root.join("robots"));
    std::os::unix::fs::symlink(shared.canonicalize().unwrap(), dir.path().join("shared")).unwrap();
    let path = format!(
        "{}:{}",
        treecal.parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let text = std::fs::read_to_string(repo().join("docs/tutorial.md")).unwrap();
    let commands = commands(&text);
    assert!(commands.len() >= 15, "{commands:?}");
    for (line, command) in &commands {
        let command = command.replace(EXAMPLE_PREFIX, &example.display().to_string());
        let run = std::process::Command::new("bash")
            .args(["-euo", "pipefail", "-c", &command])
            .current_dir(&root)
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "docs/tutorial.md:{line}: `{command}` failed:\n{}\n{}",
            String::from_utf8_lossy(&run.stdout),
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let out = root.join("tutorial/robonaut");
    let calibration = report(&out.join("calibration"));
    assert_eq!(
        calibration["verdict"]["status"], "ok",
        "{}",
        calibration["verdict"]
    );
    let (before, after) = (
        validation_rms(&calibration, "before"),
        validation_rms(&calibration, "after"),
    );
    assert!(
        before > 1.0 && after < 0.1,
        "held out: {before} mm → {after} mm"
    );
    for file in ["report.html", "calibration_overlay.yaml", "calibrated.urdf"] {
        assert!(out.join("calibration").join(file).is_file(), "{file}");
    }
    assert!(!out.join("calibration/joint_offsets.yaml").exists());
    assert!(out.join("offsets/joint_offsets.yaml").is_file());
    // The deployed URDF, as written, on a new session: at the noise level.
    let revalidation = report(&out.join("revalidation"));
    assert_eq!(
        revalidation["verdict"]["status"], "ok",
        "{}",
        revalidation["verdict"]
    );
    let deployed = revalidation["artifact"]["urdf_alone"]["errors"]["rms_position_mm"]
        .as_f64()
        .unwrap();
    assert!(
        deployed < 0.1,
        "the deployed robot on new data: {deployed} mm"
    );
    assert!(validation_rms(&revalidation, "before") > 1.0);
    let nao = report(&root.join("tutorial/nao/calibration"));
    assert_ne!(nao["verdict"]["status"], "failed", "{}", nao["verdict"]);
}
