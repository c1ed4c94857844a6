//! Running the `treecal` binary as a user would: exit status, stdout and stderr.

use super::repo;
use std::path::Path;
use std::process::{Command, Stdio};

/// What one run of the binary produced.
pub struct Run {
    pub success: bool,
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
}

impl std::fmt::Display for Run {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "exit code {:?}\n--- stdout ---\n{}\n--- stderr ---\n{}",
            self.code, self.stdout, self.stderr
        )
    }
}

/// Runs `treecal args…` in `dir` (the repository root when `None`).
pub fn treecal_in(dir: Option<&Path>, args: &[&str]) -> Run {
    let root = repo();
    let output = Command::new(env!("CARGO_BIN_EXE_treecal"))
        .args(args)
        .current_dir(dir.unwrap_or(&root))
        .stdin(Stdio::null())
        .output()
        .unwrap_or_else(|e| panic!("cannot run treecal: {e}"));
    Run {
        success: output.status.success(),
        code: output.status.code(),
        stdout: String::from_utf8(output.stdout).expect("stdout is not UTF-8"),
        stderr: String::from_utf8(output.stderr).expect("stderr is not UTF-8"),
    }
}

/// Runs `treecal args…` in the repository root.
pub fn treecal(args: &[&str]) -> Run {
    treecal_in(None, args)
}

#[track_caller]
pub fn assert_success(run: &Run, what: &str) {
    assert!(run.success, "{what}: expected success\n{run}");
}

/// Asserts a clean failure: non-zero exit, one `treecal: error:` line naming `needles`.
#[track_caller]
pub fn assert_error(run: &Run, needles: &[&str], what: &str) {
    assert!(!run.success, "{what}: expected failure\n{run}");
    assert_eq!(run.code, Some(1), "{what}: exit code\n{run}");
    assert!(
        run.stderr.starts_with("treecal: error: "),
        "{what}: stderr should start with 'treecal: error: '\n{run}"
    );
    for needle in needles {
        assert!(
            run.stderr.contains(needle),
            "{what}: stderr should contain {needle:?}\n{run}"
        );
    }
    assert!(!run.stderr.contains("panicked"), "{what}: panic\n{run}");
}

/// A calibration whose verdict failed: exit 1, notes may come first, then `treecal: error:`
/// lines that contain every needle; no panic.
#[track_caller]
pub fn assert_failed_verdict(run: &Run, needles: &[&str], what: &str) {
    assert!(!run.success, "{what}: expected failure\n{run}");
    assert_eq!(run.code, Some(1), "{what}: exit code\n{run}");
    let errors: String = run
        .stderr
        .lines()
        .filter(|line| line.starts_with("treecal: error: "))
        .collect::<Vec<_>>()
        .join("\n");
    assert!(
        !errors.is_empty(),
        "{what}: no 'treecal: error:' line\n{run}"
    );
    for needle in needles {
        assert!(
            errors.contains(needle),
            "{what}: the error lines should contain {needle:?}\n{run}"
        );
    }
    assert!(!run.stderr.contains("panicked"), "{what}: panic\n{run}");
}

pub fn path_str(path: &Path) -> &str {
    path.to_str().expect("temporary path is not UTF-8")
}

/// `dir/report.json` parsed; panics naming the file when it is missing or does not parse.
pub fn report_json(dir: &Path) -> serde_json::Value {
    let path = dir.join("report.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `dir/report.json` parsed, or `Null` when the run wrote none (a refused run).
pub fn report_json_or_null(dir: &Path) -> serde_json::Value {
    if dir.join("report.json").is_file() {
        report_json(dir)
    } else {
        serde_json::Value::Null
    }
}

/// `calibrate --contacts` on the files `simulate --observation …` wrote into `sim` (contacts.csv,
/// contact-setup.yaml, contacts-validation.csv), with `robot` (the built-in robot when `None`)
/// and `extra` flags: the run and report.json.
pub fn calibrate_contacts(
    sim: &Path,
    robot: Option<&Path>,
    out: &Path,
    extra: &[&str],
) -> (Run, serde_json::Value) {
    let files = [
        sim.join("contacts.csv"),
        sim.join("contact-setup.yaml"),
        sim.join("contacts-validation.csv"),
    ];
    let mut args = vec![
        "calibrate",
        "--contacts",
        path_str(&files[0]),
        "--contact-setup",
        path_str(&files[1]),
        "--validation",
        path_str(&files[2]),
        "--out",
        path_str(out),
    ];
    if let Some(robot) = robot {
        args.extend(["--robot", path_str(robot)]);
    }
    args.extend_from_slice(extra);
    let run = treecal(&args);
    let report = report_json_or_null(out);
    (run, report)
}
