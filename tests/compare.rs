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
