//! `treecal::workflow::{simulate, check, plan}` and the command-line grammar of `simulate`,
//! `check` and `plan` (issue 15): one library call per job, the CLI a shell over it.

use crate::common::cli::*;
use std::path::Path;
use treecal::workflow::PlanSource;
use treecal::workflow::{check, CheckConfig};
use treecal::workflow::{plan, PlanConfig};
use treecal::workflow::{simulate, SimulateConfig};

/// The number after `needle` in `text` (up to the next `,` `;` or space).
fn number_after<'a>(text: &'a str, needle: &str) -> Vec<&'a str> {
    text.match_indices(needle)
        .map(|(at, _)| {
            let rest = &text[at + needle.len()..];
            let end = rest
                .find(|c: char| c == ',' || c == ';' || c.is_whitespace())
                .unwrap_or(rest.len());
            &rest[..end]
        })
        .collect()
}

/// A small planned pose file: `plan` with `extra` flags, its stdout.
fn plan_file(out: &Path, extra: &[&str]) -> Run {
    let mut args = vec![
        "plan",
        "--poses",
        "8",
        "--candidates",
        "150",
        "--seed",
        "2",
        "-o",
        path_str(out),
    ];
    args.extend_from_slice(extra);
    let run = treecal(&args);
    assert_success(&run, "plan");
    run
}

#[test]
fn workflow_simulate_gives_the_cli_results_json() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim");
    let run = treecal(&[
        "simulate",
        "--poses",
        "8",
        "--torso-poses",
        "6",
        "--validation-poses",
        "5",
        "--trials",
        "2",
        "--seed",
        "7",
        "-o",
        path_str(&out),
    ]);
    assert_success(&run, "simulate");
    let config = SimulateConfig {
        poses: 8,
        torso_poses: 6,
        validation_poses: 5,
        trials: 2,
        seed: 7,
        ..SimulateConfig::default()
    };
    let outcome = simulate(&config).unwrap();
    let written = std::fs::read(out.join("results.json")).unwrap();
    let (_, bytes) = outcome
        .files
        .iter()
        .find(|(name, _)| name == "results.json")
        .unwrap();
    assert_eq!(&written, bytes, "results.json differs from the library's");
    assert_eq!(run.stdout, outcome.markdown);
    // (Bytes, not parsed values: serde_json's parser may round the last bit.)
    assert_eq!(
        String::from_utf8(written).unwrap(),
        treecal::io::to_json_rows(&outcome.results).unwrap()
    );
    assert_eq!(outcome.reports.len(), 2);
    // A different seed, different numbers (the comparison above can fail).
    let other = simulate(&SimulateConfig { seed: 8, ..config }).unwrap();
    assert_ne!(other.results, outcome.results);
}

/// Before: `plan` printed the pool-scaled planning criterion (0.2176) and `check` 0.1507 for
/// the same file. Now both print check's analysis.
#[test]
fn plan_and_check_print_the_same_o1_for_the_planned_file() {
    let dir = tempfile::tempdir().unwrap();
    for (name, extra, stages) in [
        ("all.csv", &[][..], &["all"][..]),
        (
            "staged.csv",
            &["--stage", "staged", "--torso-poses", "6"][..],
            &["torso", "arms"][..],
        ),
    ] {
        let out = dir.path().join(name);
        let planned = plan_file(&out, extra);
        let plan_o1 = number_after(&planned.stdout, "planned ");
        assert_eq!(plan_o1.len(), stages.len(), "{planned}");
        let checked = treecal(&["check", "--pose-file", path_str(&out)]);
        assert_success(&checked, "check --pose-file");
        let check_o1 = number_after(&checked.stdout, "  O1 ");
        assert_eq!(plan_o1, check_o1, "plan:\n{planned}\ncheck:\n{checked}");
        for stage in stages {
            assert!(
                checked.stdout.contains(&format!("stage {stage}:")),
                "{checked}"
            );
        }
    }
    // The library agrees with itself: plan's reported O1 is check's on the written rows.
    let planned = plan(&PlanConfig {
        poses: 8,
        candidates: 150,
        seed: 2,
        ..PlanConfig::default()
    })
    .unwrap();
    let out = dir.path().join("library.csv");
    planned.write(&out).unwrap();
    let checked = check(&CheckConfig {
        pose_file: Some(out),
        ..CheckConfig::default()
    })
    .unwrap();
    let analysis = checked.report.stages[0].analysis.as_ref().unwrap();
    assert_eq!(
        planned.sets[0].planned.indices.o1.to_bits(),
        analysis.indices.o1.to_bits()
    );
    assert_eq!(checked.report.plan, "simultaneous");
}

/// `check --poses 20` said "20: No such file"; now it says that check takes a file.
#[test]
fn check_pose_file_and_the_old_poses_spelling() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.csv");
    plan_file(&out, &[]);
    let new = treecal(&["check", "--pose-file", path_str(&out)]);
    assert_success(&new, "check --pose-file");
    let old = treecal(&["check", "--poses", path_str(&out)]);
    assert_success(&old, "check --poses FILE");
    assert_eq!(new.stdout, old.stdout);
    let count = treecal(&["check", "--poses", "20"]);
    assert_eq!(count.code, Some(2), "{count}");
    for needle in [
        "takes a pose file, not a count",
        "--pose-file",
        "plan --poses 20",
    ] {
        assert!(count.stderr.contains(needle), "{needle}\n{count}");
    }
    let both = treecal(&[
        "check",
        "--pose-file",
        path_str(&out),
        "--poses",
        path_str(&out),
    ]);
    assert_eq!(both.code, Some(2), "{both}");
}

/// check's rotation σ defaulted to 1e-4 rad, calibrate's to 1e-3; now every command says
/// 1e-4 m and 1e-3 rad, from the library's constants.
#[test]
fn sigma_defaults_agree_across_commands() {
    use treecal::calibration::{DEFAULT_POSITION_SIGMA, DEFAULT_ROTATION_SIGMA};
    assert_eq!(DEFAULT_POSITION_SIGMA, 1e-4);
    assert_eq!(DEFAULT_ROTATION_SIGMA, 1e-3);
    for command in ["check", "plan", "calibrate"] {
        let help = treecal(&[command, "--help"]);
        assert_success(&help, command);
        let flat = help.stdout.split_whitespace().collect::<Vec<_>>().join(" ");
        for (flag, default) in [
            ("--position-sigma", "[default: 0.0001]"),
            ("--rotation-sigma", "[default: 0.001]"),
        ] {
            let at = flat
                .find(flag)
                .unwrap_or_else(|| panic!("{command}: {flag}"));
            let next = flat[at..].find("[default:").unwrap() + at;
            assert!(
                flat[next..].starts_with(default),
                "{command} {flag}: {flat}"
            );
        }
    }
    // The default is used: the same report as with the flags spelled out, another with 1e-4.
    let plain = check(&CheckConfig::default()).unwrap();
    let explicit = check(&CheckConfig {
        rotation_sigma: 1e-3,
        position_sigma: 1e-4,
        ..CheckConfig::default()
    })
    .unwrap();
    assert_eq!(plain.text, explicit.text);
    let old = check(&CheckConfig {
        rotation_sigma: 1e-4,
        ..CheckConfig::default()
    })
    .unwrap();
    assert_ne!(plain.text, old.text);
}

/// `simulate --candidates 5` said "planned from 5 candidates" and planned from 20; now it is
/// an error, and an accepted count is the count said.
#[test]
fn simulate_candidates_are_the_candidates_said() {
    let dir = tempfile::tempdir().unwrap();
    let out = path_str(dir.path());
    let few = treecal(&[
        "simulate",
        "--poses-from",
        "planned",
        "--candidates",
        "5",
        "-o",
        out,
    ]);
    assert_error(
        &few,
        &["--candidates", "5 candidates cannot give --poses 20"],
        "too few candidates",
    );
    let torso = treecal(&[
        "simulate",
        "--poses-from",
        "planned",
        "--candidates",
        "8",
        "--poses",
        "8",
        "--torso-poses",
        "9",
        "-o",
        out,
    ]);
    assert_error(&torso, &["cannot give --torso-poses 9"], "torso poses");
    // Random poses do not use candidates: no error.
    let config = SimulateConfig {
        candidates: 5,
        poses: 6,
        torso_poses: 4,
        validation_poses: 3,
        ..SimulateConfig::default()
    };
    assert!(simulate(&config).is_ok());
    let planned = SimulateConfig {
        poses_from: treecal::workflow::PosesFrom::Planned,
        candidates: 6,
        ..config
    };
    let outcome = simulate(&planned).unwrap();
    assert!(outcome.markdown.contains("(planned from 6 candidates)"));
}

/// `--plan`, `--criterion`, `--poses-from`: value enums whose errors list the choices and
/// suggest the near one.
#[test]
fn value_enums_list_choices_and_suggest() {
    for (args, choices, near) in [
        (
            &["check", "--plan", "stagged"][..],
            "staged, simultaneous",
            "'staged'",
        ),
        (
            &["simulate", "--plan", "simultanous"][..],
            "staged, simultaneous",
            "'simultaneous'",
        ),
        (
            &["simulate", "--poses-from", "planed"][..],
            "random, planned",
            "'planned'",
        ),
        (
            &["plan", "--poses", "5", "--criterion", "0l", "-o", "x.csv"][..],
            "o1, d, o3",
            "",
        ),
        (
            &["plan", "--poses", "5", "--stage", "stagd", "-o", "x.csv"][..],
            "all, arms, torso, staged",
            "'staged'",
        ),
    ] {
        let run = treecal(args);
        assert_eq!(run.code, Some(2), "{run}");
        assert!(
            run.stderr
                .contains(&format!("[possible values: {choices}]")),
            "{run}"
        );
        assert!(run.stderr.contains(near), "{run}");
    }
}

/// `check --plan` is staged when the rows are labelled, else simultaneous (as calibrate);
/// `--plan-file` analyses a plan file's stages.
#[test]
fn check_plan_auto_and_plan_file() {
    let dir = tempfile::tempdir().unwrap();
    let unlabelled = dir.path().join("all.csv");
    plan_file(&unlabelled, &[]);
    let auto = check(&CheckConfig {
        pose_file: Some(unlabelled.clone()),
        ..CheckConfig::default()
    })
    .unwrap();
    assert_eq!(auto.report.plan, "simultaneous");
    let staged = check(&CheckConfig {
        pose_file: Some(unlabelled.clone()),
        plan: PlanSource::Staged,
        ..CheckConfig::default()
    })
    .unwrap();
    assert_eq!(staged.report.plan, "staged");
    assert!(staged.report.stages[0].skipped.is_some());
    // The default random set is labelled: staged.
    let default = check(&CheckConfig::default()).unwrap();
    assert_eq!(default.report.plan, "staged");

    let file = dir.path().join("plan.yaml");
    std::fs::write(
        &file,
        "stages:\n  - name: everything\n    parameters: all\n",
    )
    .unwrap();
    let run = treecal(&[
        "check",
        "--pose-file",
        path_str(&unlabelled),
        "--plan-file",
        path_str(&file),
    ]);
    assert_success(&run, "check --plan-file");
    assert!(run.stdout.contains("stage everything:"), "{run}");
    let simultaneous = treecal(&["check", "--pose-file", path_str(&unlabelled)]);
    assert_eq!(
        number_after(&run.stdout, "  O1 "),
        number_after(&simultaneous.stdout, "  O1 ")
    );
    let both = treecal(&["check", "--plan", "staged", "--plan-file", path_str(&file)]);
    assert_eq!(both.code, Some(2), "{both}");
}

/// `-o/--out` everywhere: a folder for simulate, a file for plan; plan's `--output` still works.
#[test]
fn out_is_the_output_flag_of_simulate_and_plan() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("sim");
    let short = [
        "simulate",
        "--poses",
        "6",
        "--torso-poses",
        "4",
        "--validation-poses",
        "3",
    ];
    let run = treecal(&[&short[..], &["-o", path_str(&folder)]].concat());
    assert_success(&run, "simulate -o");
    assert!(folder.join("results.json").is_file());
    for flag in ["-o", "--out", "--output"] {
        let file = dir.path().join(format!("plan{flag}.csv"));
        let run = treecal(&[
            "plan",
            "--poses",
            "4",
            "--candidates",
            "40",
            flag,
            path_str(&file),
        ]);
        assert_success(&run, flag);
        assert!(file.is_file(), "{flag}");
    }
}

/// Not on a terminal (the tests' stderr is a pipe), progress is a plain line at the end (and
/// at most one per 5 s before).
#[test]
fn progress_is_printed_as_lines_when_not_on_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let run = treecal(&[
        "simulate",
        "--poses",
        "6",
        "--torso-poses",
        "4",
        "--validation-poses",
        "3",
        "--trials",
        "3",
        "-o",
        path_str(dir.path()),
    ]);
    assert_success(&run, "simulate --trials 3");
    let lines: Vec<&str> = run
        .stderr
        .lines()
        .filter(|l| l.starts_with("treecal: simulate: "))
        .collect();
    assert!(
        lines
            .last()
            .unwrap()
            .starts_with("treecal: simulate: 3/3 trials ("),
        "{run}"
    );
    assert!(lines.last().unwrap().ends_with(" s)"), "{run}");
    let planned = plan_file(
        &dir.path().join("p.csv"),
        &["--stage", "staged", "--torso-poses", "4"],
    );
    for stage in ["torso", "arms"] {
        let line = format!("treecal: plan: {stage}: 150/150 candidates (");
        assert!(planned.stderr.contains(&line), "{planned}");
    }
}
