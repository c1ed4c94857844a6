//! `treecal verify` on the real TIAGo data (read in place from `../shared/data/tiago_qualisys/`):
//! the figures of a calibration verified on another session equal `calibrate --validation` on
//! the same rows (one code path) and Pinocchio's recomputation; `--max-error` decides the exit
//! code; the frame refit, the strata and the errors.

use crate::common::cli::{assert_success, path_str, treecal};
use crate::common::repo;
use crate::oracle::oracle_available;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use treecal::workflow::{
    calibrate, CalibrateConfig, MeasurementSource, RobotSource, VerifyConfig, VerifyFrame,
};

/// The TIAGo mocap data, read in place: `$TREECAL_SHARED_DIR/data/tiago_qualisys`, else
/// `../shared/data/tiago_qualisys` next to the checkout, else `/work/shared/…`.
pub(crate) fn tiago() -> PathBuf {
    let relative = "data/tiago_qualisys";
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Some(dir) = std::env::var_os("TREECAL_SHARED_DIR") {
        candidates.push(PathBuf::from(dir).join(relative));
    }
    candidates.push(repo().join("../shared").join(relative));
    candidates.push(PathBuf::from("/work/shared").join(relative));
    candidates
        .into_iter()
        .find(|c| c.join("urdf/tiago_48_schunk.urdf").is_file())
        .expect("the TIAGo data of ../shared/data/tiago_qualisys were not found; set TREECAL_SHARED_DIR")
}

pub(crate) fn session(name: &str, kind: &str) -> PathBuf {
    tiago().join(format!("data/qualisys_{name}_{kind}.csv"))
}

pub(crate) const OTHER_SESSIONS: [&str; 3] = ["2021-11-26", "2021-11-30-1403", "2021-11-30-1504"];

/// Calibrates on session 2021-11-30 (`kind`: three, pos1) validated on `validation`, written
/// to `out`.
pub(crate) fn calibrate_tiago(kind: &str, validation: &Path, out: &Path) -> serde_json::Value {
    let config = CalibrateConfig {
        robot: RobotSource::File(tiago().join("urdf/tiago_48_schunk.urdf")),
        measurements: MeasurementSource::Csv(session("2021-11-30", kind)),
        validation: Some(MeasurementSource::Csv(validation.to_owned())),
        ..CalibrateConfig::default()
    };
    let calibration = calibrate(&config).expect("calibrate");
    assert!(calibration.usable(), "{:?}", calibration.verdict);
    calibration.write(out).expect("write");
    calibration.report()
}

/// The Robonaut example calibrated with its stiffness file into a temporary folder: the folder
/// (kept alive), the output folder, the measurements and the stiffness file.
fn calibrated_with_stiffness() -> (tempfile::TempDir, PathBuf, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let stiffness = repo().join("robots/robonaut/stiffness.yaml");
    let example = repo().join("robots/robonaut/example/measurements.csv");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&example),
        "--stiffness",
        path_str(&stiffness),
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate with --stiffness");
    (dir, out, example, stiffness)
}

/// calibrate's per-row validation position errors (after), by row id.
fn calibrate_rows(report: &serde_json::Value) -> HashMap<String, f64> {
    let mut rows = HashMap::new();
    for arm in report["validation"].as_array().unwrap() {
        for row in arm["rows"].as_array().unwrap() {
            rows.insert(
                row["id"].as_str().unwrap().to_owned(),
                row["position_mm"]["after"].as_f64().unwrap(),
            );
        }
    }
    rows
}

fn verify_config(out: &Path, fresh: &Path, frame: VerifyFrame) -> VerifyConfig {
    VerifyConfig {
        calibration: Some(out.to_owned()),
        measurements: MeasurementSource::Csv(fresh.to_owned()),
        frame,
        ..VerifyConfig::default()
    }
}

#[test]
fn verify_on_each_other_session_equals_calibrate_validation() {
    let dir = tempfile::tempdir().unwrap();
    for name in OTHER_SESSIONS {
        let fresh = session(name, "three");
        let out = dir.path().join(name);
        let report = calibrate_tiago("three", &fresh, &out);
        let verification =
            treecal::workflow::verify(&verify_config(&out, &fresh, VerifyFrame::Registration))
                .expect("verify");
        let v = &verification.report;
        assert_eq!(v.context.refitted_parameters, 0);
        // The artifact figures: the same function on the same files, to the bit.
        let alone = &report["artifact"]["urdf_alone"]["errors"];
        for key in ["rms_position_mm", "max_position_mm", "mean_position_mm"] {
            let expected = alone[key].as_f64().unwrap();
            let got = serde_json::to_value(v.summary).unwrap()[key]
                .as_f64()
                .unwrap();
            assert!(
                (got - expected).abs() <= 1e-9,
                "{name} {key}: {got} vs {expected}"
            );
        }
        // Every row against calibrate's per-row validation errors (the in-memory model).
        let expected = calibrate_rows(&report);
        assert_eq!(expected.len(), v.rows.len(), "{name}: rows");
        for row in &v.rows {
            let e = expected[&row.id];
            assert!(
                (row.position_mm - e).abs() <= 1e-9,
                "{name} {}: {} vs {e}",
                row.id,
                row.position_mm
            );
        }
        // The strata: the same rows in the same strata, the same figures.
        let strata = serde_json::to_value(v.strata.as_ref().unwrap()).unwrap();
        let calibrate_strata = &report["validation_strata"];
        for (a, b) in strata["strata"]
            .as_array()
            .unwrap()
            .iter()
            .zip(calibrate_strata["strata"].as_array().unwrap())
        {
            assert_eq!(a["observations"], b["observations"], "{name}: {a} vs {b}");
            if let (Some(x), Some(y)) =
                (a["rms_position_mm"].as_f64(), b["rms_position_mm"].as_f64())
            {
                assert!((x - y).abs() <= 1e-9, "{name}: {a} vs {b}");
            }
        }
        assert_eq!(strata["worst"]["id"], calibrate_strata["worst"]["id"]);
    }
}

/// Runs tests/oracle/verify_points.py; per-row errors by id, and the RMS.
fn pinocchio_errors(
    urdf: &Path,
    link: &str,
    csv: &Path,
    extra: &[&str],
) -> (HashMap<String, f64>, f64) {
    let output = Command::new("python3")
        .arg(repo().join("tests/oracle/verify_points.py"))
        .args([path_str(urdf), link, path_str(csv)])
        .args(extra)
        .output()
        .expect("python3");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let mut rows = HashMap::new();
    let mut rms = f64::NAN;
    for line in String::from_utf8(output.stdout).unwrap().lines() {
        let (id, value) = line.split_once(' ').unwrap();
        let value: f64 = value.parse().unwrap();
        if id == "rms" {
            rms = value;
        } else {
            rows.insert(id.to_owned(), value);
        }
    }
    (rows, rms)
}

#[test]
fn verify_equals_an_independent_pinocchio_recomputation() {
    if !oracle_available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let fresh = session("2021-11-26", "pos1");
    let out = dir.path().join("cal");
    calibrate_tiago("pos1", &session("2021-11-30-1403", "pos1"), &out);
    let urdf = out.join("calibrated.urdf");
    let text = std::fs::read_to_string(&urdf).unwrap();
    let link = if text.contains("\"wrist_ft_tool_link_marker\"") {
        "wrist_ft_tool_link_marker"
    } else {
        "wrist_ft_tool_link"
    };
    let registration = out.join("registration.yaml");
    for (frame, extra) in [
        (
            VerifyFrame::Registration,
            vec!["--registration", path_str(&registration)],
        ),
        (
            VerifyFrame::Fit,
            vec!["--registration", path_str(&registration), "--fit-frame"],
        ),
    ] {
        let v = treecal::workflow::verify(&verify_config(&out, &fresh, frame)).unwrap();
        let (rows, rms) = pinocchio_errors(&urdf, link, &fresh, &extra);
        // The frame fit converges to the same least-squares minimum from both sides.
        let tolerance = if frame == VerifyFrame::Fit {
            1e-6
        } else {
            1e-9
        };
        for row in &v.report.rows {
            let p = rows[&row.id];
            assert!(
                (row.position_mm - p).abs() <= tolerance,
                "{frame:?} {}: {} vs pinocchio {p}",
                row.id,
                row.position_mm
            );
        }
        let got = v.report.summary.rms_position_mm;
        assert!(
            (got - rms).abs() <= tolerance,
            "{frame:?}: RMS {got} vs pinocchio {rms}"
        );
    }
}

#[test]
fn max_error_decides_the_exit_code() {
    let dir = tempfile::tempdir().unwrap();
    let fresh = session("2021-11-26", "three");
    let out = dir.path().join("cal");
    calibrate_tiago("three", &fresh, &out);
    let run = |max: &str, folder: &str| {
        let target = dir.path().join(folder);
        treecal(&[
            "verify",
            "--calibration",
            path_str(&out),
            "--measurements",
            path_str(&fresh),
            "--max-error",
            max,
            "--out",
            path_str(&target),
        ])
    };
    let failed = run("2", "v2");
    assert_eq!(failed.code, Some(1), "{failed}");
    assert!(failed.stderr.contains("verdict: failed"), "{failed}");
    assert!(
        dir.path().join("v2/report.md").is_file(),
        "the report is written before failing"
    );
    let passed = run("10", "v10");
    assert_success(&passed, "verify --max-error 10");
    assert!(passed.stdout.contains("verdict: passed"), "{passed}");
    for file in [
        "report.md",
        "report.html",
        "report.json",
        "errors.svg",
        "provenance.yaml",
    ] {
        assert!(dir.path().join("v10").join(file).is_file(), "{file}");
    }
    let html = std::fs::read_to_string(dir.path().join("v2/report.html")).unwrap();
    assert!(
        html.contains("failed") && html.contains("<svg"),
        "the page shows the verdict and the plot"
    );
    // The command line's files say its flag, not the library's setting name.
    let report = std::fs::read_to_string(dir.path().join("v2/report.md")).unwrap();
    assert!(
        report.contains("--max-error 2 mm") && !report.contains("`max_error`"),
        "{report}"
    );
    assert!(html.contains("<code>--max-error</code>") && !html.contains("<code>max_error</code>"));
}

#[test]
fn the_frame_refit_says_six_parameters_per_session_and_fits_better() {
    let dir = tempfile::tempdir().unwrap();
    let fresh = session("2021-11-26", "three");
    let out = dir.path().join("cal");
    calibrate_tiago("three", &session("2021-11-30-1403", "three"), &out);
    let fixed =
        treecal::workflow::verify(&verify_config(&out, &fresh, VerifyFrame::Registration)).unwrap();
    let fit = treecal::workflow::verify(&verify_config(&out, &fresh, VerifyFrame::Fit)).unwrap();
    assert_eq!(fit.report.context.refitted_parameters, 6);
    assert_eq!(fit.report.context.sessions.len(), 1);
    assert!(fit.markdown.contains("6 parameter(s)"), "{}", fit.markdown);
    // Same tracker frame in every session: the refit moves it little and cannot do worse.
    assert!(fit.report.summary.rms_position_mm <= fixed.report.summary.rms_position_mm + 1e-9);
    assert!(
        fit.report.context.sessions[0].moved_mm < 5.0,
        "{:?}",
        fit.report.context.sessions
    );
}

#[test]
fn verify_without_a_calibration_or_with_a_wrong_one_names_what_to_give() {
    let fresh = session("2021-11-26", "three");
    let run = treecal(&[
        "verify",
        "--measurements",
        path_str(&fresh),
        "--out",
        "/nonexistent/x",
    ]);
    crate::common::cli::assert_error(&run, &["--calibration", "--robot"], "no robot");
    let dir = tempfile::tempdir().unwrap();
    let run = treecal(&[
        "verify",
        "--calibration",
        path_str(dir.path()),
        "--measurements",
        path_str(&fresh),
    ]);
    crate::common::cli::assert_error(&run, &["calibrated.urdf", "--robot"], "empty folder");
    let run = treecal(&[
        "verify",
        "--robot",
        path_str(&tiago().join("urdf/tiago_48_schunk.urdf")),
        "--measurements",
        path_str(&fresh),
        "--frame",
        "registration",
        "--out",
        path_str(&dir.path().join("v")),
    ]);
    crate::common::cli::assert_error(&run, &["--frame base", "--registration"], "no registration");
}

/// A calibration compensated with the user's own stiffness file (which stays outside the
/// output folder): verify without `--stiffness` scores the URDF rigid and says loudly that the
/// calibration validated the URDF with that file, naming both figures; with the file, no such
/// warning, and the figure is the compensated one (no false alarm).
#[test]
fn verify_warns_when_the_validated_compensation_is_missing() {
    let (dir, out, example, stiffness) = calibrated_with_stiffness();
    let verified = dir.path().join("verify");
    let verify = |extra: &[&str]| {
        let mut args = vec!["verify", "--calibration", path_str(&out)];
        args.extend(["--measurements", path_str(&example)]);
        args.extend(["--out", path_str(&verified)]);
        args.extend_from_slice(extra);
        treecal(&args)
    };
    let rigid = verify(&[]);
    assert_success(&rigid, "verify without --stiffness");
    for text in [
        "warning: the calibration was validated as calibrated.urdf + ",
        "stiffness.yaml (",
        "scores the URDF rigid, like calibrated.urdf alone (",
        "give --stiffness",
    ] {
        assert!(rigid.stderr.contains(text), "{text}: {rigid}");
    }
    let compensated = verify(&["--stiffness", path_str(&stiffness)]);
    assert_success(&compensated, "verify with --stiffness");
    assert!(
        !compensated.stderr.contains("validated as"),
        "{compensated}"
    );
}

/// A bumped target among the fresh rows (every target 0.3 m off on one row): the robust refit
/// leaves it out of the session's frame, so the other rows score as without it; the verdict
/// judges the others and names the row to re-measure; every figure still counts it. The clean
/// session flags nothing (no false alarm).
#[test]
fn a_blunder_in_the_fresh_rows_neither_drags_the_frame_nor_decides_the_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let clean = session("2021-11-26", "three");
    let out = dir.path().join("cal");
    calibrate_tiago("three", &session("2021-11-30-1403", "three"), &out);
    let text = std::fs::read_to_string(&clean).unwrap();
    let header = text.lines().position(|l| l.starts_with("id,")).unwrap();
    let columns: Vec<&str> = text.lines().nth(header).unwrap().split(',').collect();
    let bumped_line = header + 10;
    let mut bumped_id = String::new();
    let lines: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, line)| {
            if i != bumped_line {
                return line.to_owned();
            }
            let fields: Vec<String> = line
                .split(',')
                .zip(&columns)
                .map(|(value, column)| match *column {
                    "ax" | "bx" | "cx" => format!("{}", value.parse::<f64>().unwrap() + 0.3),
                    _ => value.to_owned(),
                })
                .collect();
            bumped_id = fields[0].clone();
            fields.join(",")
        })
        .collect();
    let bumped = dir.path().join("bumped.csv");
    std::fs::write(&bumped, lines.join("\n") + "\n").unwrap();
    let verify = |fresh: &Path| {
        let config = VerifyConfig {
            max_error_mm: Some(10.0),
            ..verify_config(&out, fresh, VerifyFrame::Fit)
        };
        treecal::workflow::verify(&config).expect("verify")
    };
    let reference = verify(&clean);
    assert!(
        reference.report.verdict.set_aside.is_none(),
        "no false alarm"
    );
    assert!(reference.report.rows.iter().all(|r| !r.outlier));
    let blundered = verify(&bumped);
    let v = &blundered.report;
    let aside = v
        .verdict
        .set_aside
        .as_ref()
        .expect("the bumped row set aside");
    assert_eq!(aside.ids, vec![bumped_id.clone()]);
    assert!(v.verdict.passed, "{}", v.verdict.sentence());
    assert!(v.verdict.rms_position_mm > 30.0, "every row counts");
    assert!(v.verdict.sentence().contains(&bumped_id));
    // The frame is not dragged: the other rows score as in the clean session.
    let clean_rows: HashMap<&str, f64> = reference
        .report
        .rows
        .iter()
        .map(|r| (r.id.as_str(), r.position_mm))
        .collect();
    for row in v.rows.iter().filter(|r| r.id != bumped_id) {
        let e = clean_rows[row.id.as_str()];
        assert!(
            (row.position_mm - e).abs() < 0.3,
            "{}: {} vs {e}",
            row.id,
            row.position_mm
        );
    }
    let json: serde_json::Value = serde_json::from_slice(
        &blundered
            .files
            .iter()
            .find(|(n, _)| n == "report.json")
            .unwrap()
            .1,
    )
    .unwrap();
    let marked: Vec<&str> = json["rows"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["outlier"] == true)
        .map(|r| r["id"].as_str().unwrap())
        .collect();
    assert_eq!(marked, vec![bumped_id.as_str()]);
}

/// report.md names where the error is: with rows of two tools and two sessions, one tool
/// drifted, the by-tool and by-session tables give each its RMS (red team: the overall RMS
/// of a dual-arm verify mixed a drifted arm with a good one and said neither).
#[test]
fn the_verify_report_splits_the_error_by_tool_and_by_session() {
    use treecal::report::{VerifyContext, VerifyReport, VerifyRow};
    let row = |i: usize, tool: &str, session: &str, mm: f64| VerifyRow {
        id: format!("r{i}"),
        index: i,
        tool: tool.into(),
        session: Some(session.into()),
        position_mm: mm,
        orientation_deg: Some(0.1),
        stratum: None,
        outlier: false,
    };
    let mut rows = Vec::new();
    for i in 0..8 {
        let session = if i % 2 == 0 { "day1" } else { "day2" };
        rows.push(row(2 * i, "left_tool", session, 3.0));
        rows.push(row(2 * i + 1, "right_tool", session, 1.0));
    }
    let context = VerifyContext {
        robot: "r".into(),
        files: "calibrated.urdf".into(),
        measurements: "fresh.csv".into(),
        frame: "fit".into(),
        refitted_parameters: 12,
        sessions: Vec::new(),
        strata_judged: false,
    };
    let markdown = VerifyReport::new(context, rows, Some(2.0)).markdown();
    assert!(
        markdown.contains("| tool | rows | RMS (mm) |"),
        "{markdown}"
    );
    assert!(
        markdown.contains("| left_tool | 8 | 3.0000 | 3.0000 | 0.1000 |"),
        "{markdown}"
    );
    assert!(
        markdown.contains("| right_tool | 8 | 1.0000 |"),
        "{markdown}"
    );
    let rms = (5.0f64).sqrt();
    assert!(
        markdown.contains(&format!("| day1 | 8 | {rms:.4} |")),
        "{markdown}"
    );
}

/// provenance.yaml lists every file calibrate wrote with its SHA-256 (what `sha256sum`
/// prints); verify on the folder says nothing of it while the files are as written, and warns
/// (stderr and report.md, naming the file) once calibrated.urdf was edited by hand.
#[test]
fn verify_notices_a_calibrated_urdf_edited_after_the_calibration() {
    let (dir, out, example, stiffness) = calibrated_with_stiffness();
    let provenance = std::fs::read_to_string(out.join("provenance.yaml")).unwrap();
    let urdf = out.join("calibrated.urdf");
    let sha = treecal::io::sha256_hex(&std::fs::read(&urdf).unwrap());
    assert!(
        provenance.contains(&format!(
            "- name: calibrated.urdf\n  bytes: {}\n  sha256: {sha}\n",
            std::fs::metadata(&urdf).unwrap().len()
        )),
        "{provenance}"
    );
    assert!(
        !provenance.contains("name: provenance.yaml"),
        "{provenance}"
    );
    let verified = dir.path().join("verify");
    let verify = || {
        treecal(&[
            "verify",
            "--calibration",
            path_str(&out),
            "--measurements",
            path_str(&example),
            "--stiffness",
            path_str(&stiffness),
            "--out",
            path_str(&verified),
        ])
    };
    let clean = verify();
    assert_success(&clean, "verify as written");
    assert!(!clean.stderr.contains("is not the file"), "{clean}");
    // A hand edit: one joint origin moved by a millimetre.
    let text = std::fs::read_to_string(&urdf).unwrap();
    let at = text.find("<origin xyz=\"").unwrap() + "<origin xyz=\"".len();
    std::fs::write(&urdf, format!("{}0.001{}", &text[..at], &text[at + 1..])).unwrap();
    let edited = verify();
    assert_success(&edited, "verify after an edit");
    let report = std::fs::read_to_string(verified.join("report.md")).unwrap();
    for text in [&edited.stderr, &report] {
        assert!(
            text.contains("calibrated.urdf is not the file `calibrate` wrote")
                && text.contains("edited or replaced after the calibration"),
            "{text}"
        );
    }
}
