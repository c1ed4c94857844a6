//! `treecal compare` on calibrations of the real TIAGo data: a folder against itself moves
//! nothing; two sessions' calibrations list what moved beyond 3σ and the displacement.

use crate::common::cli::{assert_success, path_str, treecal};
use crate::verify::{calibrate_tiago, session};
use treecal::workflow::{compare, CompareConfig};

#[test]
fn a_folder_compared_with_itself_lists_none() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    calibrate_tiago("three", &session("2021-11-26", "three"), &a);
    let comparison = compare(&CompareConfig {
        a: a.clone(),
        b: a.clone(),
        k: 3.0,
    })
    .unwrap();
    let r = &comparison.report;
    assert!(r.moved.is_empty(), "{:?}", r.moved);
    assert!(r.parameters_judged > 10, "{}", r.parameters_judged);
    let d = r.displacement.as_ref().unwrap();
    assert!(d.max_deployed_mm < 1e-9 && d.max_aligned_mm < 1e-6, "{d:?}");
    assert_eq!(r.validation[0], r.validation[1]);
}

#[test]
fn two_sessions_calibrations_list_moved_parameters_and_the_displacement() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, out) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("cmp"),
    );
    calibrate_tiago("three", &session("2021-11-26", "three"), &a);
    // B: calibrated on 2021-11-26, validated on 2021-11-30.
    let config = treecal::workflow::CalibrateConfig {
        robot: treecal::workflow::RobotSource::File(
            crate::verify::tiago().join("urdf/tiago_48_schunk.urdf"),
        ),
        measurements: treecal::workflow::MeasurementSource::Csv(session("2021-11-26", "three")),
        validation: Some(treecal::workflow::MeasurementSource::Csv(session(
            "2021-11-30",
            "three",
        ))),
        ..Default::default()
    };
    treecal::workflow::calibrate(&config)
        .unwrap()
        .write(&b)
        .unwrap();
    let run = treecal(&[
        "compare",
        path_str(&a),
        path_str(&b),
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "compare");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let moved = report["moved"].as_array().unwrap();
    for m in moved {
        assert!(m["sigmas"].as_f64().unwrap() > 3.0, "{m}");
    }
    let d = &report["displacement"];
    assert!(d["configurations"].as_u64().unwrap() > 60, "{d}");
    assert!(d["rms_aligned_mm"].as_f64().unwrap() > 0.0, "{d}");
    assert!(
        run.stdout.contains("Parameters moved beyond 3 combined σ"),
        "{run}"
    );
    for file in [
        "report.md",
        "report.html",
        "report.json",
        "displacement.svg",
        "provenance.yaml",
    ] {
        assert!(out.join(file).is_file(), "{file}");
    }
    eprintln!(
        "compare A/B: {} parameters moved beyond 3σ; displacement {d}",
        moved.len()
    );
}

/// report.md judges drift by the tools, not by parameter σ's: parameters listed as moved while
/// the aligned tools stay within the two calibrations' combined noise prediction are read as
/// no drift; tools beyond twice it are a drift (red team: two calibrations of one unchanged
/// simulated SDA10F listed 5 parameters at 4–17σ, and nothing said the tools had not moved).
#[test]
fn compare_judges_drift_by_the_tools_against_the_predicted_noise() {
    use treecal::report::{
        CompareReport, Displacement, DisplacementRow, MovedParameter, ValidationFigures,
        COMPARE_SCHEMA,
    };
    let figures = |folder: &str| ValidationFigures {
        folder: folder.into(),
        verdict: "ok".into(),
        urdf_alone_rms_mm: Some(1.0),
        urdf_alone_max_mm: Some(2.0),
        registered_nominal_rms_mm: Some(12.0),
        repeat_rms_mm: None,
        inside_rms_mm: Some(1.0),
        outside_rms_mm: None,
        predicted_rms_mm: Some(0.3),
    };
    let report = |aligned_mm: f64| CompareReport {
        schema_version: COMPARE_SCHEMA,
        robot: "r".into(),
        k: 3.0,
        parameters_judged: 72,
        moved: vec![MovedParameter {
            name: "torso y".into(),
            unit: "m".into(),
            a: 0.0,
            b: 1e-3,
            b_calibrated: 1e-3,
            change: 1e-3,
            combined_std_dev: 1e-4,
            sigmas: 10.0,
        }],
        frame_change: None,
        displacement: Some(Displacement::of(vec![DisplacementRow {
            tool: "left".into(),
            deployed_mm: 5.0,
            aligned_mm,
        }])),
        validation: [figures("a"), figures("b")],
        provenance: "provenance.yaml".into(),
    };
    // Combined prediction √(0.3² + 0.3²) = 0.424 mm; the limit twice that, 0.849 mm.
    let same = report(0.5).markdown();
    assert!(same.contains("did not move beyond the noise"), "{same}");
    assert!(same.contains("0.424 mm RMS combined"), "{same}");
    let drifted = report(1.75).markdown();
    assert!(
        drifted.contains("**The tools moved:** 1.750 mm"),
        "{drifted}"
    );
}
