//! Contacts and tracker rows in one calibration (issue 29, mixed data): `simulate
//! --observation flush,tracker|touch,tracker` writes the contacts, the setup (its σ's those of
//! the simulated encoder noise) and tracker.csv; `calibrate --contacts … --measurements
//! tracker.csv` fits both, the tracker's frame with the rest, each row kind by its σ.

use crate::common::cli::{assert_error, assert_success, path_str, report_json, treecal};
use std::path::Path;

/// Simulates `observation` on the built-in robot (seeded, encoder noise 1e-4 rad, tracker
/// σ 0.1 mm) into `dir/sim` and returns it.
fn simulate(dir: &Path, observation: &str) -> std::path::PathBuf {
    let sim = dir.join("sim");
    let run = treecal(&[
        "simulate",
        "--observation",
        observation,
        "--encoder-noise",
        "1e-4",
        "--poses",
        "30",
        "--trials",
        "1",
        "--seed",
        "7",
        "--out",
        path_str(&sim),
    ]);
    assert_success(&run, observation);
    for file in ["contacts.csv", "contact-setup.yaml", "tracker.csv"] {
        assert!(sim.join(file).is_file(), "{observation}: {file} missing");
    }
    sim
}

/// `calibrate --contacts … --measurements tracker.csv` of `sim` with `setup`, into `dir/name`.
fn calibrate(dir: &Path, sim: &Path, setup: &Path, name: &str) -> crate::common::cli::Run {
    let out = dir.join(name);
    treecal(&[
        "calibrate",
        "--contacts",
        path_str(&sim.join("contacts.csv")),
        "--contact-setup",
        path_str(setup),
        "--validation",
        path_str(&sim.join("contacts-validation.csv")),
        "--measurements",
        path_str(&sim.join("tracker.csv")),
        "--position-sigma",
        "1e-4",
        "--out",
        path_str(&out),
    ])
}

/// σ̂ of each row kind in report.json's `kinds`.
fn kind_scales(json: &serde_json::Value) -> Vec<(String, f64)> {
    json["kinds"]
        .as_array()
        .expect("kinds")
        .iter()
        .map(|k| {
            (
                k["kind"].as_str().unwrap().to_owned(),
                k["residual_scale"].as_f64().unwrap(),
            )
        })
        .collect()
}

fn assert_scales(json: &serde_json::Value, expected: &[&str]) {
    let scales = kind_scales(json);
    let names: Vec<&str> = scales.iter().map(|(k, _)| k.as_str()).collect();
    assert_eq!(names, expected, "{json}");
    for (kind, scale) in &scales {
        assert!((0.7..=1.4).contains(scale), "{kind}: σ̂ {scale}");
    }
}

/// Flush contacts of the left tool and tracker positions of it: the perturbed robot is
/// recovered in what the contacts see (held-out heights and tilts at the noise's level, from
/// 10 mm and 2° before) and every row kind's σ̂ is 1 when the declared σ's are the simulated.
#[test]
fn flush_contacts_with_tracker_rows_recover_the_robot_and_each_kind_scores_one() {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulate(dir.path(), "flush,tracker");
    let run = calibrate(dir.path(), &sim, &sim.join("contact-setup.yaml"), "cal");
    assert_success(&run, "calibrate flush + tracker");
    let json = report_json(&dir.path().join("cal"));
    assert_eq!(json["usable"], true, "{json}");
    assert_scales(&json, &["tracker position", "height", "tilt"]);
    let held = &json["held_out"]["training_plane"];
    let value = |at: &str, what: &str| held[at][what]["rms"].as_f64().unwrap();
    let (before, after) = (value("before", "height_mm"), value("after", "height_mm"));
    // Encoder noise of 1e-4 rad at ~0.5 m: ~0.05 mm of height per contact.
    assert!(before > 2.0 && after < 0.1, "height {before} -> {after} mm");
    // calibrated.urdf read back, placed in the fitted tracker frame (the planes' frame),
    // predicts the held-out contacts as the calibration did.
    let written = json["written"]["height_mm"]["rms"].as_f64().unwrap();
    assert!(
        (written - after).abs() < 1e-6,
        "written {written} mm, {after} mm"
    );
    assert!(!run.stderr.contains("as written predicts"), "{run}");
    let (before, after) = (value("before", "tilt_deg"), value("after", "tilt_deg"));
    assert!(before > 0.5 && after < 0.02, "tilt {before} -> {after} °");
    // Contact rows only are the training contacts; the tracker's frame is fitted.
    assert_eq!(json["training_contacts"], 40, "{json}");
    assert_eq!(json["tracker"]["fitted"], true, "{json}");
    let report = std::fs::read_to_string(dir.path().join("cal/report.md")).unwrap();
    assert!(report.contains("Rows by kind"), "{report}");
    assert!(!run.stdout.contains("position error"), "{}", run.stdout);
}

/// The two tools touch and both are tracked: a tracked tool's fitted target offset carries
/// its contact point, which its own fitted x, y, z absorb: the fit is consistent (σ̂ ≈ 1 per
/// kind, held-out gaps at the noise's level).
#[test]
fn touching_tools_that_are_also_tracked_fit_consistently() {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulate(dir.path(), "touch,tracker");
    let run = calibrate(dir.path(), &sim, &sim.join("contact-setup.yaml"), "cal");
    assert_success(&run, "calibrate touch + tracker");
    let json = report_json(&dir.path().join("cal"));
    assert_eq!(json["usable"], true, "{json}");
    assert_scales(&json, &["tracker position", "gap"]);
    let held = &json["held_out"]["training_plane"];
    let value = |at: &str| held[at]["gap_mm"]["rms"].as_f64().unwrap();
    assert!(
        value("before") > 10.0 && value("after") < 0.1,
        "gap {} -> {} mm",
        value("before"),
        value("after")
    );
    // Held contact points are carried by the fitted target offsets: named, not silent.
    let setup = std::fs::read_to_string(sim.join("contact-setup.yaml")).unwrap();
    let held_points = dir.path().join("held-points.yaml");
    std::fs::write(&held_points, setup.replace("point: true", "point: false")).unwrap();
    let run = calibrate(dir.path(), &sim, &held_points, "held-points");
    assert!(
        run.stderr.contains("target offset moves the held point"),
        "{}",
        run.stderr
    );
}

/// A held plane cannot sit in a fitted tracker frame (it would stay where the nominal robot
/// put it while the tracker rows pin the robot): an error naming the setting and what to do.
#[test]
fn held_planes_with_a_fitted_tracker_frame_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulate(dir.path(), "flush,tracker");
    let setup = std::fs::read_to_string(sim.join("contact-setup.yaml")).unwrap();
    let held = dir.path().join("held.yaml");
    std::fs::write(&held, setup.replace("plane: true", "plane: false")).unwrap();
    let run = calibrate(dir.path(), &sim, &held, "held");
    assert_error(
        &run,
        &["held.yaml", "free: plane: false", "free the planes"],
        "held plane, fitted tracker frame",
    );
}
