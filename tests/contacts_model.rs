//! Which robot parameters a contact calibration fits (`calibrate --contacts`): the full joint
//! frames (default), only the joint zero offsets (`--model offsets`), or fewer by name
//! (`--freeze`, `--free`); the written calibrated.urdf carries what was fitted (read back, the
//! calibrated robot registered alone predicts the held-out contacts as the calibration did);
//! the model flags a contact calibration does not use are errors, not silently ignored; the
//! data choose the model by cross-validation (`--model auto`, or by default when the residuals
//! are over twice the declared σ's).

use crate::common::cli::{assert_error, assert_success, calibrate_contacts, path_str, treecal};
use std::path::Path;

/// The built-in robot's simulated flush contacts (noise-free, the truth off in every joint
/// frame), written as a lab's files into `dir`.
fn simulate(dir: &Path) {
    simulate_with(dir, "0");
}

/// As [`simulate`], with encoder noise σ `encoder` (rad) on the recorded configurations.
fn simulate_with(dir: &Path, encoder: &str) {
    let run = treecal(&[
        "simulate",
        "--observation",
        "flush",
        "--trials",
        "1",
        "--poses",
        "40",
        "--encoder-noise",
        encoder,
        "--out",
        path_str(dir),
    ]);
    assert_success(&run, "simulate --observation flush");
}

/// Held-out height RMS (mm) of `which` ("before", "after") with the training planes.
fn height(report: &serde_json::Value, which: &str) -> f64 {
    report["held_out"]["training_plane"][which]["height_mm"]["rms"]
        .as_f64()
        .unwrap_or_else(|| panic!("{report}"))
}

/// The unknowns the fit had (joint-frame parameters and nuisance).
fn unknowns(run: &crate::common::cli::Run) -> usize {
    let line = run
        .stdout
        .lines()
        .find(|l| l.contains(" unknowns (joint frames and nuisance)"))
        .unwrap_or_else(|| panic!("{}", run.stdout));
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "unknowns").unwrap();
    words[at - 1].parse().unwrap()
}

#[test]
fn offsets_geometry_and_frozen_parameters_are_fitted_and_exported_as_fitted() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    simulate(&sim);
    let mut fitted = Vec::new();
    for (name, extra) in [
        ("geometry", vec![]),
        ("offsets", vec!["--model", "offsets"]),
        ("frozen", vec!["--freeze", "left_*"]),
    ] {
        let out = dir.path().join(name);
        let (run, report) = calibrate_contacts(&sim, None, &out, &extra);
        assert_success(&run, name);
        let count = unknowns(&run);
        let (before, after) = (height(&report, "before"), height(&report, "after"));
        assert!(after < before, "{name}: {before} -> {after} mm");
        // The run itself reads its calibrated.urdf back and scores it.
        let as_written = report["written"]["height_mm"]["rms"]
            .as_f64()
            .unwrap_or_else(|| panic!("{report}"));
        assert!(
            (as_written - after).abs() < 1e-6 + 1e-6 * after,
            "{name}: {as_written} {after}"
        );
        assert!(!run.stderr.contains("as written predicts"), "{run}");
        // The written URDF, registered alone (only the planes fitted), predicts the held-out
        // contacts as the calibration did.
        let again = dir.path().join(format!("{name}-again"));
        let urdf = out.join("calibrated.urdf");
        // (Its own calibration may not gain further: only its "before" is read.)
        let (_, reread) = calibrate_contacts(&sim, Some(&urdf), &again, &extra);
        let written = height(&reread, "before");
        assert!(
            (written - after).abs() < 1e-4 + 1e-4 * after,
            "{name}: calibrated {after} mm, calibrated.urdf registered {written} mm"
        );
        fitted.push((count, after));
    }
    let [(geometry, exact), (offsets, partial), (frozen, _)] = fitted[..] else {
        unreachable!()
    };
    // Noise-free: the full geometry recovers the truth; offsets alone cannot (the truth is
    // off in every frame parameter) but still gain; freezing the left arm fits fewer.
    assert!(exact < 1e-3, "geometry {exact} mm");
    assert!(partial > 0.1, "offsets {partial} mm");
    assert!(offsets < geometry && frozen < geometry, "{fitted:?}");
}

#[test]
fn model_flags_a_contact_calibration_does_not_use_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    simulate(&sim);
    let out = dir.path().join("out");
    // Flags of the tracker calibration's model choice: refused by the command line (usage
    // errors, exit code 2), naming the flag.
    for extra in [
        vec!["--identify-stiffness"],
        vec!["--joint-errors", "harmonics"],
        vec!["--significant", "2"],
    ] {
        let (run, _) = calibrate_contacts(&sim, None, &out, &extra);
        assert_eq!(run.code, Some(2), "{extra:?}\n{run}");
        assert!(
            run.stderr.contains("cannot be used with") && run.stderr.contains(extra[0]),
            "{extra:?}\n{run}"
        );
    }
    let (run, _) = calibrate_contacts(&sim, None, &out, &["--freeze", "no_such_joint*"]);
    assert_error(
        &run,
        &["--freeze", "'no_such_joint*'", "matches no parameter"],
        "freeze",
    );
    assert!(!out.exists(), "nothing written on an error");
}

/// The chosen model's name and the cross-validation's candidates (empty when none ran).
fn model_of(report: &serde_json::Value) -> (String, Vec<String>) {
    let name = report["model"]["name"]
        .as_str()
        .unwrap_or_else(|| panic!("{report}"))
        .to_owned();
    let rows = report["model_choice"]["rows"]
        .as_array()
        .map(|rows| {
            rows.iter()
                .map(|r| r["model"].as_str().unwrap().to_owned())
                .collect()
        })
        .unwrap_or_default();
    (name, rows)
}

#[test]
fn the_data_choose_the_contact_model_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    simulate(&sim);
    // Noise-free, the truth off in every joint frame parameter: the full geometry is exact
    // and significantly better than the prior's reference.
    let (run, report) =
        calibrate_contacts(&sim, None, &dir.path().join("auto"), &["--model", "auto"]);
    assert_success(&run, "auto");
    let (name, rows) = model_of(&report);
    assert_eq!(name, "geometry", "{run}");
    assert_eq!(rows, ["offsets", "geometry", "geometry+prior"], "{report}");
    assert!(
        run.stderr.contains("model choice (contacts): 'geometry'"),
        "{run}"
    );
    assert!(height(&report, "after") < 1e-3, "{report}");
    let table = std::fs::read_to_string(dir.path().join("auto/report.md")).unwrap();
    assert!(
        table.contains("## Model choice (cross-validation)"),
        "{table}"
    );
    assert!(table.contains("| geometry **(chosen)** |"), "{table}");
    // Residuals at the declared noise (here none): the default fits the full geometry without
    // a cross-validation, and says nothing about a model choice.
    let (run, report) = calibrate_contacts(&sim, None, &dir.path().join("default"), &[]);
    assert_success(&run, "default");
    assert_eq!(model_of(&report), ("geometry".to_owned(), Vec::new()));
    assert!(!run.stderr.contains("model choice"), "{run}");
    // A model asked for is kept; --cv adds the table; --prior holds the geometry near nominal.
    let (run, report) = calibrate_contacts(
        &sim,
        None,
        &dir.path().join("prior"),
        &["--model", "geometry", "--prior", "--cv", "3"],
    );
    assert_success(&run, "prior");
    let (name, rows) = model_of(&report);
    assert_eq!(
        (name.as_str(), rows.len()),
        ("geometry+prior", 3),
        "{report}"
    );
    assert_eq!(report["model_choice"]["folds"], 3, "{report}");
    let biased = height(&report, "after");
    assert!(
        biased > 1e-2,
        "the prior holds the truth's 5 mm back: {biased} mm"
    );
}

#[test]
fn residuals_over_the_declared_noise_let_the_data_choose() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    simulate_with(&sim, "1e-3");
    // The setup declares σ's far below what the encoder noise leaves.
    let setup = sim.join("contact-setup.yaml");
    let text = std::fs::read_to_string(&setup).unwrap();
    let tight = text
        .replace("height: 0.001", "height: 0.0001")
        .replace("tilt: 0.01", "tilt: 0.0001");
    assert_ne!(text, tight, "{text}");
    std::fs::write(&setup, tight).unwrap();
    let (run, report) = calibrate_contacts(&sim, None, &dir.path().join("out"), &[]);
    assert_success(&run, "default");
    assert!(
        run.stderr.contains("the geometry fit leaves residuals")
            && run.stderr.contains("chosen by cross-validation"),
        "{run}"
    );
    let (name, rows) = model_of(&report);
    assert_eq!(rows.len(), 3, "{report}");
    let chosen = report["model_choice"]["chosen"].as_u64().unwrap() as usize;
    // One plane and encoder noise: the cross-validation's geometry shrinks the robot (held-out
    // contacts on the same plane cannot see it), so the prior holds the scale and says so
    // (docs/contacts.md, "The length scale").
    assert_eq!(rows[chosen], "geometry", "{report}");
    assert_eq!(name, "geometry+prior", "{report}");
    assert!(run.stderr.contains("its nominal size"), "{run}");
    let ratio = report["size_ratio"].as_f64().unwrap();
    assert!((ratio - 1.0).abs() < 0.15, "{ratio}");
}
