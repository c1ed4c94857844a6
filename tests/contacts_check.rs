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
