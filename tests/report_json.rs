//! The JSON reports (`report.json`, `results.json`, `check` and `inspect --format json`) are
//! labelled: a `schema_version` at the top, objects keyed by meaning instead of arrays whose
//! meaning depends on position, and per-row results named by the CSV's ids.

use crate::common::cli::{assert_success, path_str, treecal};
use crate::common::robot;
use serde_json::Value;
use std::collections::BTreeSet;
use treecal::report::{CHECK_SCHEMA, REPORT_SCHEMA, RESULTS_SCHEMA};

/// The documented values of a stage's `termination` (report.json and results.json).
const TERMINATIONS: [&str; 4] = [
    "step_converged",
    "cost_converged",
    "no_decrease",
    "max_iterations",
];

/// Keys under which a list of numbers is a list of like values, not a tuple: URDF's own
/// `xyz`/`rpy` vectors, a spectrum, per-configuration errors (in objects keyed `before`,
/// `after`, `rigid`, `compensated`), measurement indices.
const NUMBER_LISTS: [&str; 8] = [
    "xyz",
    "rpy",
    "singular_values",
    "before",
    "after",
    "rigid",
    "compensated",
    "injected",
];

/// Every place in `value` that holds a positional array: an array of arrays, of mixed kinds, or
/// of numbers under a key not in [`NUMBER_LISTS`]. Paths like `trials/0/stages`.
fn positional_arrays(value: &Value, key: &str, path: &str, found: &mut Vec<String>) {
    match value {
        Value::Object(map) => {
            for (k, v) in map {
                positional_arrays(v, k, &format!("{path}/{k}"), found);
            }
        }
        Value::Array(items) => {
            let kinds: BTreeSet<&str> = items
                .iter()
                .map(|v| match v {
                    Value::Null | Value::Number(_) => "number",
                    Value::String(_) => "string",
                    Value::Object(_) => "object",
                    Value::Array(_) => "array",
                    Value::Bool(_) => "bool",
                })
                .collect();
            let tuple = kinds.len() > 1
                || kinds.contains("array")
                || kinds.contains("bool")
                || (kinds.contains("number") && !NUMBER_LISTS.contains(&key));
            if tuple {
                found.push(format!("{path}: {kinds:?}"));
            }
            for (i, v) in items.iter().enumerate() {
                positional_arrays(v, key, &format!("{path}/{i}"), found);
            }
        }
        _ => {}
    }
}

#[track_caller]
fn assert_labelled(value: &Value, what: &str) {
    let mut found = Vec::new();
    positional_arrays(value, "", "", &mut found);
    assert!(found.is_empty(), "{what}: positional arrays at {found:#?}");
}

/// The check itself can fail: tuples, pairs and nested arrays are found.
#[test]
fn the_positional_array_check_finds_tuples() {
    let bad = serde_json::json!({
        "removed": [99.0, 99.9],
        "stages": [["torso", 5]],
        "fine": {"before": [1.0, 2.0], "names": ["a", "b"]},
        "terms": [{"parameter": "x", "weight": 0.7}],
    });
    let mut found = Vec::new();
    positional_arrays(&bad, "", "", &mut found);
    assert_eq!(found.len(), 3, "{found:?}");
    assert!(found[0].starts_with("/removed"), "{found:?}");
    assert!(found[1].starts_with("/stages:"), "{found:?}");
    assert!(found[2].starts_with("/stages/0:"), "{found:?}");
}

/// The example's `(id, tool)` per data row, in file order.
fn csv_rows(path: &std::path::Path) -> Vec<(String, String)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (id, tool) = (column("id"), column("tool"));
    lines
        .map(|line| {
            let cells: Vec<&str> = line.split(',').collect();
            (cells[id].to_string(), cells[tool].to_string())
        })
        .collect()
}

/// The top-level keys of pretty-printed JSON, in file order.
fn top_level_keys(text: &str) -> Vec<String> {
    text.lines()
        .filter_map(|line| line.strip_prefix("  \""))
        .filter_map(|rest| rest.split_once("\":"))
        .map(|(key, _)| key.to_string())
        .collect()
}

fn f64_of(value: &Value) -> f64 {
    value
        .as_f64()
        .unwrap_or_else(|| panic!("{value} is not a number"))
}

#[test]
fn report_json_is_labelled_and_names_every_row_by_its_csv_id() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let csv = robot("robonaut/example/measurements.csv");
    let stiffness = robot("robonaut/stiffness.yaml");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--stiffness",
        path_str(&stiffness),
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate the example");
    let text = std::fs::read_to_string(out.join("report.json")).unwrap();
    // Verdict first, then the schema version.
    assert!(text.starts_with("{\n  \"verdict\": {"), "{}", &text[..80]);
    let report: Value = serde_json::from_str(&text).unwrap();
    let keys = top_level_keys(&text);
    assert_eq!(
        keys[..3],
        ["verdict", "schema_version", "context"],
        "{keys:?}"
    );
    assert_eq!(report["schema_version"], REPORT_SCHEMA);
    assert_labelled(&report, "report.json");
    assert!(f64_of(&report["context"]["sigma"]["position_m"]) > 0.0);
    assert!(f64_of(&report["context"]["sigma"]["rotation_rad"]) > 0.0);
    assert!(
        f64_of(&report["initial_guess_rms_m"]["before"])
            >= f64_of(&report["initial_guess_rms_m"]["after"])
    );

    // Every identification and validation row, by id, is a row of the CSV with the arm's
    // tool; together with the outliers they are the CSV's rows, each once.
    let rows = csv_rows(&csv);
    let mut seen: Vec<(String, String)> = Vec::new();
    for set in ["identification", "validation"] {
        let arms = report[set].as_array().unwrap();
        assert_eq!(arms.len(), 2, "{set}");
        for arm in arms {
            let tool = arm["tool"].as_str().unwrap();
            let arm_rows = arm["rows"].as_array().unwrap();
            assert_eq!(arm_rows.len() as u64, arm["observations"].as_u64().unwrap());
            let mut after = Vec::new();
            for row in arm_rows {
                let id = row["id"].as_str().unwrap().to_string();
                assert!(
                    rows.contains(&(id.clone(), tool.to_string())),
                    "{set}: row {id} of {tool} is not in the CSV"
                );
                seen.push((id, tool.to_string()));
                after.push(f64_of(&row["position_mm"]["after"]));
                assert!(f64_of(&row["orientation_deg"]["before"]) >= 0.0);
                if set == "validation" {
                    assert!(f64_of(&row["predicted_sd_mm"]) > 0.0, "{row}");
                } else {
                    assert!(row.get("predicted_sd_mm").is_none(), "{row}");
                }
            }
            // The rows' errors are the ones the arm's statistics summarise.
            let mean = after.iter().sum::<f64>() / after.len() as f64;
            let reported = f64_of(&arm["after"]["mean_position_mm"]);
            assert!(
                (mean - reported).abs() < 1e-9 * reported.max(1.0),
                "{mean} vs {reported}"
            );
        }
    }
    for outlier in report["outliers"].as_array().unwrap() {
        let row = (
            outlier["id"].as_str().unwrap().to_string(),
            outlier["tool"].as_str().unwrap().to_string(),
        );
        seen.push(row);
    }
    let mut expected = rows.clone();
    expected.sort();
    seen.sort();
    assert_eq!(seen, expected, "the rows reported are not the CSV's");
    // The predicted spreads give the predicted RMS.
    let spreads: Vec<f64> = report["validation"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|arm| arm["rows"].as_array().unwrap().iter())
        .map(|row| f64_of(&row["predicted_sd_mm"]))
        .collect();
    let rms = (spreads.iter().map(|s| s * s).sum::<f64>() / spreads.len() as f64).sqrt();
    let predicted = f64_of(&report["predicted_validation_rms_mm"]);
    assert!((rms - predicted).abs() < 1e-9, "{rms} vs {predicted}");

    // The plots name the configurations by the same ids.
    let svg = std::fs::read_to_string(out.join("left_arm_validation_position.svg")).unwrap();
    let first = report["validation"][0]["rows"][0]["id"].as_str().unwrap();
    assert!(
        svg.contains(&format!(">\n{first}\n</text>")),
        "id {first} is not a tick label"
    );
    assert!(svg.contains("measurement id"));
}

#[test]
fn results_json_is_labelled() {
    let dir = tempfile::tempdir().unwrap();
    let run = treecal(&[
        "simulate",
        "--outliers",
        "0.05",
        "--out",
        path_str(dir.path()),
    ]);
    assert_success(&run, "simulate");
    let text = std::fs::read_to_string(dir.path().join("results.json")).unwrap();
    // At the top level; the key order is stable, whether a struct's or sorted.
    let keys = top_level_keys(&text);
    assert!(keys.iter().any(|k| k == "schema_version"), "{keys:?}");
    let results: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(results["schema_version"], RESULTS_SCHEMA);
    assert_labelled(&results, "results.json");
    let trial = &results["trials"][0];
    for arm in trial["validation"].as_array().unwrap() {
        let removed = &arm["position_removed_percent"];
        assert!(
            f64_of(&removed["compensated"]) > f64_of(&removed["rigid"]),
            "{arm}"
        );
        let count = arm["position_mm"]["before"].as_array().unwrap().len();
        for key in ["rigid", "compensated"] {
            assert_eq!(arm["position_mm"][key].as_array().unwrap().len(), count);
        }
    }
    // Version 3: the termination in snake_case, as report.json writes it (version 2 wrote
    // `CostConverged`).
    assert_eq!(RESULTS_SCHEMA, "treecal.results/3");
    for run in ["rigid_run", "compensated_run"] {
        for stage in trial[run]["stages"].as_array().unwrap() {
            assert!(
                stage["name"].is_string() && stage["rank"].as_u64() <= stage["parameters"].as_u64()
            );
            let termination = stage["termination"].as_str().unwrap();
            assert!(
                TERMINATIONS.contains(&termination),
                "termination {termination} is not a documented value"
            );
        }
    }
    let summary = &results["summary"];
    for arm in summary["validation"].as_array().unwrap() {
        assert!(f64_of(&arm["after_position_mm"]["compensated"]["mean"]) >= 0.0);
    }
    // 5 % blunders: the counts are labelled per calibration.
    let blunders = &summary["blunders"]["compensated"];
    let injected = trial["blunders"]["injected"].as_array().unwrap().len() as u64;
    assert!(injected > 0);
    assert_eq!(
        blunders["named"].as_u64().unwrap() + blunders["missed"].as_u64().unwrap(),
        injected,
        "{blunders}"
    );
    assert!(trial["blunders"]["named"]["rigid"].is_array());
}

#[test]
fn check_and_inspect_json_carry_a_schema_version_and_labels() {
    let run = treecal(&[
        "check",
        "--targets",
        "1",
        "--identify-stiffness",
        "--format",
        "json",
    ]);
    assert_success(&run, "check --format json");
    assert!(run.stdout.starts_with("{\n  \"schema_version\": "), "{run}");
    let check: Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(check["schema_version"], CHECK_SCHEMA);
    assert_labelled(&check, "check");
    // Positions only: the tool orientations cannot be identified, named term by term.
    let analysis = &check["stages"][1]["analysis"];
    let term = &analysis["unidentifiable"][0]["terms"][0];
    assert!(
        term["parameter"].is_string() && term["weight"].is_number(),
        "{term}"
    );
    let parameter = &check["compliance"]["parameters"][0];
    assert!(parameter["name"].is_string() && parameter["identified"].is_boolean());

    let inspect = treecal(&["inspect", "--format", "json"]);
    assert_success(&inspect, "inspect --format json");
    let value: Value = serde_json::from_str(&inspect.stdout).unwrap();
    assert_eq!(value["schema_version"], treecal::report::INSPECT_SCHEMA);
}

/// With `--identify-stiffness` the stiffness block comes last and the order stays (it was
/// merged through a sorted map before, which put the verdict last).
#[test]
fn report_json_with_stiffness_keeps_its_key_order() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let csv = robot("robonaut/example/measurements.csv");
    let stiffness = robot("robonaut/stiffness.yaml");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--stiffness",
        path_str(&stiffness),
        "--identify-stiffness",
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate --identify-stiffness");
    let text = std::fs::read_to_string(out.join("report.json")).unwrap();
    let keys = top_level_keys(&text);
    assert_eq!(keys[..2], ["verdict", "schema_version"], "{keys:?}");
    assert_eq!(
        keys.last().map(String::as_str),
        Some("stiffness"),
        "{keys:?}"
    );
    let report: Value = serde_json::from_str(&text).unwrap();
    assert_labelled(&report, "report.json with stiffness");
    let block = &report["stiffness"];
    assert!(f64_of(&block["cost"]["after"]) <= f64_of(&block["cost"]["before"]));
    assert!(block["identified"]["identified"].as_u64() <= block["identified"]["total"].as_u64());
    assert!(f64_of(&block["group_scales"]["joint"]["scale"]) > 0.0);
    // The example data: nothing fitted below zero, so no such warning and null per parameter.
    assert_eq!(block["held_below_zero"], serde_json::json!([]), "{block}");
    assert!(block["parameters"][0]["fitted_below_zero"].is_null());
    assert_eq!(report["verdict"]["status"], "ok", "{}", report["verdict"]);
}

/// `folder`'s report.json rewritten as `treecal.report/2` wrote it: that schema version and the
/// stages' `termination` in the Rust spelling (`CostConverged`), the one value version 3 renamed.
fn as_version_2(folder: &std::path::Path) {
    let path = folder.join("report.json");
    let mut report: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    report["schema_version"] = "treecal.report/2".into();
    for stage in report["stages"].as_array_mut().unwrap() {
        let old = match stage["termination"].as_str().unwrap() {
            "step_converged" => "StepConverged",
            "cost_converged" => "CostConverged",
            "no_decrease" => "NoDecrease",
            "max_iterations" => "MaxIterations",
            other => panic!("termination {other} is not a documented value"),
        };
        stage["termination"] = old.into();
    }
    std::fs::write(&path, serde_json::to_string_pretty(&report).unwrap()).unwrap();
}

/// report.json version 3 writes every enum value in snake_case; `verify` and `compare` still
/// read a version-2 report (the old spelling) to the same results, and refuse a newer version
/// naming the ones they read.
#[test]
fn verify_and_compare_read_a_version_2_report_and_refuse_a_newer_one() {
    use treecal::workflow::{compare, verify, CompareConfig, MeasurementSource, VerifyConfig};
    let dir = tempfile::tempdir().unwrap();
    let (new, old) = (dir.path().join("new"), dir.path().join("old"));
    let csv = robot("robonaut/example/measurements.csv");
    for out in [&new, &old] {
        treecal::workflow::calibrate(&treecal::workflow::CalibrateConfig {
            measurements: MeasurementSource::Csv(csv.clone()),
            stiffness: Some(treecal::workflow::StiffnessSource::File(robot(
                "robonaut/stiffness.yaml",
            ))),
            ..Default::default()
        })
        .unwrap()
        .write(out)
        .unwrap();
    }
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(new.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["schema_version"], REPORT_SCHEMA);
    for stage in report["stages"].as_array().unwrap() {
        let termination = stage["termination"].as_str().unwrap();
        assert!(TERMINATIONS.contains(&termination), "{termination}");
    }
    as_version_2(&old);

    let comparison = compare(&CompareConfig {
        a: new.clone(),
        b: old.clone(),
        k: 3.0,
    })
    .unwrap();
    assert!(
        comparison.report.moved.is_empty(),
        "{:?}",
        comparison.report.moved
    );
    let [a, b] = &comparison.report.validation;
    assert_eq!(
        (a.verdict.as_str(), a.inside_rms_mm),
        (b.verdict.as_str(), b.inside_rms_mm)
    );

    let verify_with = |folder: &std::path::Path| {
        let verification = verify(&VerifyConfig {
            calibration: Some(folder.to_owned()),
            measurements: MeasurementSource::Csv(csv.clone()),
            ..VerifyConfig::default()
        })
        .unwrap();
        assert!(verification.report.context.strata_judged, "{folder:?}");
        serde_json::to_value(&verification.report.rows).unwrap()
    };
    assert_eq!(verify_with(&new), verify_with(&old));

    let path = old.join("report.json");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("treecal.report/2", "treecal.report/9");
    std::fs::write(&path, text).unwrap();
    let error = compare(&CompareConfig {
        a: new,
        b: old,
        k: 3.0,
    })
    .unwrap_err()
    .to_string();
    assert!(
        error.contains("report.json") && error.contains("treecal.report/1 to /3"),
        "{error}"
    );
}
