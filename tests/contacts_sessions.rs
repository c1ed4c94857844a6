//! Held-out contacts of a session without training contacts (a new table set-up): the training
//! fit never saw that table, so its plane is fitted to the held-out contacts (the robot held)
//! for both robots; those figures count in the verdict, which says what it judged by — never
//! "better on the held-out contacts" over zero contacts.

use crate::common::cli::{assert_success, calibrate_contacts, path_str, treecal};
use std::path::Path;

/// The built-in robot's noise-free flush contacts on two tables (sessions `day1`, `day2`).
fn simulate(dir: &Path) {
    let run = treecal(&[
        "simulate",
        "--observation",
        "flush",
        "--tables",
        "2",
        "--trials",
        "1",
        "--poses",
        "30",
        "--out",
        path_str(dir),
    ]);
    assert_success(&run, "simulate --observation flush --tables 2");
}

/// The comment and header lines of a contacts CSV, then its rows whose session `keep` accepts.
fn rows_of(text: &str, keep: impl Fn(&str) -> bool) -> String {
    let mut out = String::new();
    let mut header_seen = false;
    for line in text.lines() {
        let data = header_seen && !line.starts_with('#');
        header_seen |= !line.starts_with('#');
        if !data || line.split(',').nth(1).is_some_and(&keep) {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// Calibrates on `day1`'s training contacts, validating on `validation` (a CSV text).
fn calibrate(sim: &Path, validation: &str, out: &Path) -> serde_json::Value {
    let training = std::fs::read_to_string(sim.join("contacts.csv")).unwrap();
    let train = out.with_extension("training.csv");
    let held = out.with_extension("validation.csv");
    std::fs::write(&train, rows_of(&training, |s| s == "day1")).unwrap();
    std::fs::write(&held, validation).unwrap();
    let run = treecal(&[
        "calibrate",
        "--contacts",
        path_str(&train),
        "--contact-setup",
        path_str(&sim.join("contact-setup.yaml")),
        "--validation",
        path_str(&held),
        "--out",
        path_str(out),
    ]);
    assert_success(&run, "calibrate --contacts");
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("**Verdict: usable"), "{report}");
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

fn rms(value: &serde_json::Value) -> f64 {
    value["height_mm"]["rms"].as_f64().unwrap()
}

#[test]
fn a_session_without_training_contacts_is_scored_with_its_plane_fitted_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    simulate(&sim);
    let all_training = std::fs::read_to_string(sim.join("contacts.csv")).unwrap();
    let all_validation = std::fs::read_to_string(sim.join("contacts-validation.csv")).unwrap();
    let day2 = |s: &str| s == "day2";
    let new_only = format!(
        "{}{}",
        rows_of(&all_validation, day2),
        rows_of(&all_training, day2)
            .lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("id,"))
            .map(|l| format!("{l}\n"))
            .collect::<String>()
    );

    // Every held-out contact is on the new table: judged there, with its plane fitted.
    let json = calibrate(&sim, &new_only, &dir.path().join("new"));
    let held = &json["held_out"];
    assert_eq!(held["judged"], "new_sessions", "{held}");
    assert_eq!(held["training_plane"]["after"]["height_mm"]["count"], 0);
    let new = &held["new_sessions_fitted_plane"];
    assert!(new["contacts"].as_u64().unwrap() > 30, "{new}");
    let (before, after) = (rms(&new["before"]), rms(&new["after"]));
    // Noise-free contacts of a robot off in every frame: the calibrated robot is exact on
    // the new table too, the nominal one millimetres off.
    assert!(after < 1e-3 && before > 1.0, "{new}");
    let written = json["written"]["height_mm"]["rms"].as_f64().unwrap();
    assert!((written - after).abs() < 1e-3, "{written} {after}");
    let report = std::fs::read_to_string(dir.path().join("new/report.md")).unwrap();
    assert!(report.contains("sessions without training contacts: each session's plane fitted"));
    assert!(report.contains("| calibrated, new sessions (plane fitted to them) |"));

    // A known table and a new one: both figures, judged on the held-out contacts.
    let mixed = format!(
        "{}{}",
        rows_of(&all_validation, |s| s == "day1"),
        new_only
            .lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("id,"))
            .map(|l| format!("{l}\n"))
            .collect::<String>()
    );
    let json = calibrate(&sim, &mixed, &dir.path().join("mixed"));
    let held = &json["held_out"];
    assert_eq!(held["judged"], "held_out", "{held}");
    assert!(
        held["training_plane"]["after"]["height_mm"]["count"]
            .as_u64()
            .unwrap()
            > 0
    );
    assert!(
        held["new_sessions_fitted_plane"]["contacts"]
            .as_u64()
            .unwrap()
            > 30
    );
}

#[test]
fn held_out_contacts_of_training_sessions_are_judged_with_their_training_planes() {
    // No false alarm: every held-out session was trained on, so nothing is refitted.
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    simulate(&sim);
    let validation = std::fs::read_to_string(sim.join("contacts-validation.csv")).unwrap();
    let json = calibrate(
        &sim,
        &rows_of(&validation, |s| s == "day1"),
        &dir.path().join("known"),
    );
    let held = &json["held_out"];
    assert_eq!(held["judged"], "held_out", "{held}");
    assert_eq!(held["new_sessions_fitted_plane"]["contacts"], 0);
    assert!(rms(&held["training_plane"]["after"]) < 1e-3, "{held}");
    let report = std::fs::read_to_string(dir.path().join("known/report.md")).unwrap();
    assert!(
        report.contains("predicts the held-out contacts better"),
        "{report}"
    );
    assert!(!report.contains("new sessions (plane fitted to them)"));
}

#[test]
fn tools_restrict_a_contact_calibration_to_one_side() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    let run = treecal(&[
        "simulate",
        "--observation",
        "flush",
        "--both-hands",
        "--trials",
        "1",
        "--poses",
        "30",
        "--out",
        path_str(&sim),
    ]);
    assert_success(&run, "simulate --observation flush --both-hands");
    let calibrate =
        |tools: &str, out: &Path| calibrate_contacts(&sim, None, out, &["--tools", tools]);
    let (run, json) = calibrate("left_tool", &dir.path().join("left"));
    assert_success(&run, "calibrate --contacts --tools left_tool");
    assert!(
        run.stderr
            .contains("tools left_tool: the model holds their chains only"),
        "{run}"
    );
    let tools = json["held_out"]["tools"].as_object().unwrap();
    assert_eq!(tools.keys().collect::<Vec<_>>(), ["left_tool"], "{json}");
    let (run, _) = calibrate("no_such_tool", &dir.path().join("bad"));
    assert!(!run.success, "{run}");
    assert!(
        run.stderr
            .contains("'no_such_tool' of --tools is not a tool of the setup"),
        "{run}"
    );
}
