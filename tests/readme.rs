//! README's commands, as written: every command line of its ```` ```sh ```` blocks is either run
//! (`treecal …`, and `cargo run --release --locked -- …` as the `treecal …` it builds) against
//! the built binary in a scratch folder holding a copy of `robots/`, or checked (the other
//! `cargo` lines: build, install and test, which must keep Cargo.lock's versions and agree with
//! `.ci/run`), or is a step of an outside tool ([`OUTSIDE_TOOLS`]: `python3 …`, `pip …`,
//! `apt-get …`, …), shown but not run. Any other command fails the test, so that nothing in
//! README goes unchecked by accident.

use crate::common::cli::{assert_success, treecal_in};
use crate::common::repo;
use std::path::Path;

/// The install line README gives; `--locked` keeps Cargo.lock's crate versions.
const INSTALL: &str = "cargo install --locked --path .";
/// README's test command: CI's (`.ci/run`).
const TEST: &str = "cargo test --locked";
/// Outside tools whose install or test steps README shows but this test does not run.
const OUTSIDE_TOOLS: [&str; 8] = [
    "python3", "python", "pip", "pip3", "pytest", "maturin", "apt-get", "sudo",
];
/// `cargo run --release --locked -- ARGS` builds and runs `treecal ARGS`.
const RUN_PREFIX: &str = "cargo run --release --locked -- ";

/// The command lines of README's `sh` blocks, with their line numbers: comments and blank
/// lines dropped, `\` continuations joined.
fn sh_commands(readme: &str) -> Vec<(usize, String)> {
    let mut commands = Vec::new();
    let mut in_sh = false;
    let mut pending: Option<(usize, String)> = None;
    for (index, line) in readme.lines().enumerate() {
        let trimmed = line.trim();
        if let Some(info) = trimmed.strip_prefix("```") {
            in_sh = !in_sh && info.trim() == "sh";
            continue;
        }
        if !in_sh {
            continue;
        }
        // A comment starts at a `#` after whitespace (README's commands have no `#` in them).
        let code = match trimmed.find(" #") {
            Some(at) => trimmed[..at].trim_end(),
            None if trimmed.starts_with('#') => "",
            None => trimmed,
        };
        let (number, mut text) = pending.take().unwrap_or((index + 1, String::new()));
        match code.strip_suffix('\\') {
            Some(head) => {
                text.push_str(head.trim_end());
                text.push(' ');
                pending = Some((number, text));
            }
            None if !code.is_empty() || !text.is_empty() => {
                text.push_str(code);
                commands.push((number, text.trim().to_string()));
            }
            None => {}
        }
    }
    commands
}

/// What README's test does with one command.
#[derive(Debug, PartialEq)]
enum Action {
    /// Run `treecal` with these arguments.
    Run(Vec<String>),
    /// A cargo line checked against `.ci/run`.
    Checked,
    /// An outside tool's install step.
    Shown,
}

fn classify(command: &str) -> Result<Action, String> {
    if command.contains(['"', '\'', '$', '|', '>', '<', ';', '&', '*']) {
        return Err(format!(
            "`{command}`: quoting, variables, pipes and redirections are not run by tests/readme.rs; \
             write plain arguments or extend the test"
        ));
    }
    let words = |text: &str| text.split_whitespace().map(String::from).collect();
    if let Some(arguments) = command.strip_prefix("treecal ") {
        return Ok(Action::Run(words(arguments)));
    }
    if let Some(arguments) = command.strip_prefix(RUN_PREFIX) {
        return Ok(Action::Run(words(arguments)));
    }
    let first = command.split_whitespace().next().unwrap_or("");
    if first == "cargo" {
        // Builds, installs and tests are too slow to run here; they keep Cargo.lock's versions.
        return if command.split_whitespace().any(|w| w == "--locked") {
            Ok(Action::Checked)
        } else {
            Err(format!(
                "`{command}`: without --locked cargo resolves newer crates than Cargo.lock"
            ))
        };
    }
    if OUTSIDE_TOOLS.contains(&first) {
        return Ok(Action::Shown);
    }
    Err(format!(
        "`{command}` is neither a treecal command, a cargo command with --locked, nor an outside \
         tool's step ({OUTSIDE_TOOLS:?})"
    ))
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

fn readme() -> String {
    std::fs::read_to_string(repo().join("README.md")).unwrap()
}

#[test]
fn readme_commands_run_as_written() {
    let readme = readme();
    let commands = sh_commands(&readme);
    let dir = tempfile::tempdir().unwrap();
    copy_dir(&repo().join("robots"), &dir.path().join("robots"));
    let mut ran = 0;
    for (line, command) in &commands {
        let action = classify(command).unwrap_or_else(|e| panic!("README.md:{line}: {e}"));
        if let Action::Run(arguments) = action {
            let arguments: Vec<&str> = arguments.iter().map(String::as_str).collect();
            let run = treecal_in(Some(dir.path()), &arguments);
            assert_success(&run, &format!("README.md:{line}: `{command}`"));
            ran += 1;
        }
    }
    // The quick start: a simulation and a calibration at least.
    assert!(
        ran >= 2,
        "only {ran} treecal command(s) in README's sh blocks: {commands:?}"
    );
    assert!(dir.path().join("out/calibrate/report.json").exists());
    assert!(dir.path().join("out/simulate/results.json").exists());
}

/// The build and test lines are not run here (too slow) but must be in README as written, and
/// agree with CI: README's test command is `.ci/run`'s, and every cargo build in either keeps
/// Cargo.lock's versions.
#[test]
fn readme_build_and_test_commands_match_ci() {
    let readme = readme();
    let commands: Vec<String> = sh_commands(&readme).into_iter().map(|(_, c)| c).collect();
    for expected in [INSTALL, TEST] {
        assert!(
            commands.iter().any(|c| c == expected),
            "README's sh blocks lack `{expected}`: {commands:?}"
        );
    }
    let ci = std::fs::read_to_string(repo().join(".ci/run")).unwrap();
    assert!(
        ci.lines().any(|l| l.trim() == TEST),
        ".ci/run does not run README's test command `{TEST}`"
    );
    for (name, text) in [("README.md", &readme), (".ci/run", &ci)] {
        for (number, line) in text.lines().enumerate() {
            for verb in [
                "cargo install",
                "cargo run",
                "cargo build",
                "cargo test",
                "cargo clippy",
            ] {
                for (at, _) in line.match_indices(verb) {
                    // The cargo command runs to the end of its inline code span or the line.
                    let rest = &line[at..];
                    let end = rest.find('`').unwrap_or(rest.len());
                    let command = &rest[..end];
                    let bare_mention = command == verb && name == "README.md";
                    assert!(
                        command.contains("--locked") || bare_mention,
                        "{name}:{}: `{command}` without --locked",
                        number + 1
                    );
                }
            }
        }
    }
}

/// The parsing itself: comments, continuations and the three kinds of lines; unknown commands
/// and shell syntax are refused.
#[test]
fn readme_command_parsing() {
    let text = "text\n```sh\n# a comment\ntreecal simulate --trials 2   # two\n\
                treecal calibrate \\\n  --measurements m.csv\n```\n```text\ntreecal not-run\n```\n\
                ```sh\ncargo install --locked --path .\npython3 -m pip install ./python\n```\n";
    let commands = sh_commands(text);
    assert_eq!(
        commands,
        vec![
            (4, "treecal simulate --trials 2".to_string()),
            (5, "treecal calibrate --measurements m.csv".to_string()),
            (12, INSTALL.to_string()),
            (13, "python3 -m pip install ./python".to_string()),
        ]
    );
    assert_eq!(
        classify("cargo run --release --locked -- simulate --trials 2"),
        Ok(Action::Run(vec![
            "simulate".into(),
            "--trials".into(),
            "2".into()
        ]))
    );
    assert_eq!(classify(INSTALL), Ok(Action::Checked));
    assert_eq!(
        classify("python3 -m pip install ./python"),
        Ok(Action::Shown)
    );
    assert!(classify("cargo run --release -- simulate").is_err());
    assert!(classify("cargo install --path .").is_err());
    assert_eq!(
        classify("cargo build --release --locked"),
        Ok(Action::Checked)
    );
    assert!(classify("rm -rf out").is_err());
    assert!(classify("treecal simulate > log.txt").is_err());
}
