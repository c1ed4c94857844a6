//! Which robot parameters a contact calibration fits (`calibrate --contacts`): the full joint
//! frames (default), only the joint zero offsets (`--model offsets`), or fewer by name
//! (`--freeze`, `--free`); the written calibrated.urdf carries what was fitted (read back, the
//! calibrated robot registered alone predicts the held-out contacts as the calibration did);
//! the model flags a contact calibration does not use are errors, not silently ignored.

use crate::common::cli::{assert_error, assert_success, path_str, treecal};
use std::path::Path;

/// The built-in robot's simulated flush contacts (noise-free, the truth off in every joint
/// frame), written as a lab's files into `dir`.
fn simulate(dir: &Path) {
    let run = treecal(&[
        "simulate",
        "--observation",
        "flush",
        "--trials",
        "1",
        "--poses",
        "40",
        "--out",
        path_str(dir),
    ]);
    assert_success(&run, "simulate --observation flush");
}

/// `calibrate --contacts` on the files in `sim` with `robot` (the built-in robot when `None`)
/// and `extra` flags: the run and report.json.
fn calibrate(
    sim: &Path,
    robot: Option<&Path>,
    out: &Path,
    extra: &[&str],
) -> (crate::common::cli::Run, serde_json::Value) {
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
    let report = std::fs::read_to_string(out.join("report.json"))
        .map(|t| serde_json::from_str(&t).unwrap())
        .unwrap_or(serde_json::Value::Null);
    (run, report)
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
        let (run, report) = calibrate(&sim, None, &out, &extra);
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
        let (_, reread) = calibrate(&sim, Some(&urdf), &again, &extra);
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
    let (run, _) = calibrate(&sim, None, &out, &["--model", "auto"]);
    assert_error(
        &run,
        &["--model", "cross-validation", "offsets or geometry"],
        "auto",
    );
    // Flags of the tracker calibration's model choice: refused by the command line (usage
    // errors, exit code 2), naming the flag.
    for extra in [
        vec!["--identify-stiffness"],
        vec!["--joint-errors", "harmonics"],
        vec!["--cv", "5"],
        vec!["--prior"],
    ] {
        let (run, _) = calibrate(&sim, None, &out, &extra);
        assert_eq!(run.code, Some(2), "{extra:?}\n{run}");
        assert!(
            run.stderr.contains("cannot be used with") && run.stderr.contains(extra[0]),
            "{extra:?}\n{run}"
        );
    }
    let (run, _) = calibrate(&sim, None, &out, &["--freeze", "no_such_joint*"]);
    assert_error(
        &run,
        &["--freeze", "'no_such_joint*'", "matches no parameter"],
        "freeze",
    );
    assert!(!out.exists(), "nothing written on an error");
}
