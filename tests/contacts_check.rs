//! `treecal check --contacts C.csv --contact-setup S.yaml` (issue 29): what a lab's contacts
//! leave undetermined, in the contact calibration report's words, with check's exit codes.

use crate::common::cli::{assert_error, assert_success, path_str, treecal};

#[test]
fn check_names_what_contacts_leave_undetermined() {
    let dir = tempfile::tempdir().unwrap();
    for (observation, words) in [
        ("touch,bar", "see the two hands relative to each other only"),
        ("flush", "alias exactly"),
    ] {
        let sim = dir.path().join(observation.replace(',', "-"));
        let run = treecal(&[
            "simulate",
            "--observation",
            observation,
            "--poses",
            "30",
            "--trials",
            "1",
            "--out",
            path_str(&sim),
        ]);
        assert_success(&run, observation);
        let contacts = path_str(&sim.join("contacts.csv")).to_owned();
        let setup = path_str(&sim.join("contact-setup.yaml")).to_owned();
        let args = ["check", "--contacts", &contacts, "--contact-setup", &setup];
        let run = treecal(&args);
        assert_success(&run, observation);
        assert!(run.stdout.contains(words), "{observation}: {}", run.stdout);
        assert!(
            run.stdout.contains("unknowns are not determined"),
            "{}",
            run.stdout
        );
        let run = treecal(&[&args[..], &["--format", "json"]].concat());
        assert_success(&run, observation);
        let json: serde_json::Value = serde_json::from_str(&run.stdout).expect("json");
        let (rank, unknowns) = (json["rank"].as_u64(), json["unknowns"].as_u64());
        assert!(rank.unwrap() < unknowns.unwrap(), "{json}");
        assert!(!json["unidentifiable"].as_array().unwrap().is_empty());
    }
    // A missing file is an error (exit 1) naming it.
    let run = treecal(&[
        "check",
        "--contacts",
        "nowhere.csv",
        "--contact-setup",
        "nowhere.yaml",
    ]);
    assert_error(&run, &["nowhere"], "missing contacts");
}

/// A misspelt link in the setup file (red team): the error named the link alone ("unknown
/// link 'right_tol'"), not the file nor the tool it belongs to; it now names both, with the
/// hint, for `check` and `calibrate` alike, and a misspelt `reference_link` likewise.
#[test]
fn a_misspelt_setup_link_names_the_setup_file_and_the_tool() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    let run = treecal(&[
        "simulate",
        "--observation",
        "touch",
        "--poses",
        "10",
        "--torso-poses",
        "0",
        "--trials",
        "1",
        "--out",
        path_str(&sim),
    ]);
    assert_success(&run, "simulate touch");
    let text = std::fs::read_to_string(sim.join("contact-setup.yaml")).unwrap();
    let contacts = path_str(&sim.join("contacts.csv")).to_owned();
    for (from, to, needles) in [
        (
            "link: right_tool",
            "link: right_tol",
            ["bad.yaml", "tool 'right_tool'", "did you mean 'right_tool'"],
        ),
        (
            "tools:",
            "reference_link: base_lnk\ntools:",
            ["bad.yaml", "reference_link", "did you mean 'base_link'"],
        ),
    ] {
        assert!(text.contains(from), "{text}");
        let bad = dir.path().join("bad.yaml");
        std::fs::write(&bad, text.replacen(from, to, 1)).unwrap();
        let setup = path_str(&bad).to_owned();
        let out = path_str(&dir.path().join("out")).to_owned();
        for args in [
            vec!["check", "--contacts", &contacts, "--contact-setup", &setup],
            vec![
                "calibrate",
                "--contacts",
                &contacts,
                "--contact-setup",
                &setup,
                "-o",
                &out,
            ],
        ] {
            assert_error(&treecal(&args), &needles, to);
        }
    }
}
