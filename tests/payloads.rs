//! Payloads as data: the measurement CSV's `payload_kg` column, predictions at a row's own
//! payload, and simulated identification data drawn at several payloads.

use crate::common::{random_configuration, rng, robot, simulated_robonaut};
use treecal::calibration::weighted_residual;
use treecal::calibration::{
    analyse_compliance, Deflected, DeflectedWithDerivative, IdentificationOptions, Predictor,
    Rigid, StiffnessOptions,
};
use treecal::io::{measurements_to_csv, parse_measurements, MeasurementReadOptions};
use treecal::kinematics::FlexibilityModel;
use treecal::math::pose_error;
use treecal::measurement::{Measurement, Observation};
use treecal::sim::{run_trial, SimulationOptions};
use treecal::tree::KinematicTree;
use treecal::McpcModel;

fn robonaut() -> (KinematicTree, McpcModel, FlexibilityModel) {
    let (tree, model) = crate::common::robonaut_model();
    let stiffness =
        treecal::io::read_stiffness(&robot("robonaut/stiffness.yaml"), &tree, &model).unwrap();
    let flexibility = FlexibilityModel::new(&tree, &model, &stiffness).unwrap();
    (tree, model, flexibility)
}

/// Every tool at `q` as the flexibility model loaded with `payload` sees it, the rows carrying
/// that payload.
fn observed(
    tree: &KinematicTree,
    model: &McpcModel,
    flexibility: &FlexibilityModel,
    q: &[f64],
    payload: Option<f64>,
) -> Vec<Measurement> {
    flexibility
        .for_payload(payload)
        .unwrap()
        .deflected_tool_poses(tree, model, q)
        .unwrap()
        .into_iter()
        .enumerate()
        .map(|(tool, pose)| Measurement {
            tool,
            q: q.to_vec(),
            observation: Observation::Pose(pose),
            stage: None,
            session: None,
            payload,
        })
        .collect()
}

/// The writer emits `payload_kg` only when a row has a payload; the reader reads it back (an
/// empty cell is the stiffness file's payload), and refuses a negative mass, naming line and
/// column.
#[test]
fn the_payload_column_round_trips_and_bad_masses_are_named() {
    let (tree, model, flexibility) = robonaut();
    let mut random = rng(3);
    let payloads = [Some(0.0), Some(12.5), None, Some(20.0)];
    let measurements: Vec<Measurement> = payloads
        .iter()
        .flat_map(|&p| {
            let q = random_configuration(&tree, &mut random);
            observed(&tree, &model, &flexibility, &q, p)
        })
        .collect();
    let text = measurements_to_csv(&tree, &model, &measurements).unwrap();
    assert!(
        text.lines().next().unwrap().ends_with(",payload_kg"),
        "{text}"
    );
    let options = MeasurementReadOptions::default();
    let read = parse_measurements(&text, "loaded.csv", &tree, &model, &options).unwrap();
    let back: Vec<Option<f64>> = read.measurements.iter().map(|m| m.payload).collect();
    let written: Vec<Option<f64>> = measurements.iter().map(|m| m.payload).collect();
    assert_eq!(back, written);

    // No payloads: no column, and rows read without one carry none.
    let plain = without_payloads(&measurements);
    let text_plain = measurements_to_csv(&tree, &model, &plain).unwrap();
    assert!(!text_plain.contains("payload_kg"));
    let read = parse_measurements(&text_plain, "plain.csv", &tree, &model, &options).unwrap();
    assert!(read.measurements.iter().all(|m| m.payload.is_none()));

    let bad = text.replacen(",12.5\n", ",-3\n", 1);
    assert_ne!(bad, text);
    let message = parse_measurements(&bad, "loaded.csv", &tree, &model, &options)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("loaded.csv:")
            && message.contains(":payload_kg")
            && message.contains("kg"),
        "{message}"
    );
}

/// A row's prediction is the flexibility model's at the row's payload (to 1e-12), for the
/// exact and the derivative-corrected predictors; the rigid one ignores it; the residual of
/// rows observed at their payload is zero, and the payload matters (an unloaded row predicted
/// with the file's 20 kg is off by more than a millimetre).
#[test]
fn predictions_use_the_rows_payload() {
    let (tree, model, flexibility) = robonaut();
    let mut random = rng(9);
    let exact = Deflected {
        tree: &tree,
        flexibility: &flexibility,
    };
    let corrected = DeflectedWithDerivative::new(exact);
    for payload in [0.0, 7.5, 20.0] {
        let q = random_configuration(&tree, &mut random);
        let expected = flexibility
            .with_payload_at_every_tool(payload)
            .unwrap()
            .deflected_tool_poses(&tree, &model, &q)
            .unwrap();
        for predictor in [&exact as &dyn Predictor, &corrected] {
            let predicted = predictor.predict_at(&model, &q, Some(payload)).unwrap();
            let chain = predictor.jacobians_at(&model, &q, Some(payload)).unwrap();
            for tool in 0..expected.len() {
                let off = pose_error(&predicted[tool], &expected[tool]).amax();
                let chain_off = pose_error(&chain[tool].pose, &expected[tool]).amax();
                assert!(off <= 1e-12 && chain_off <= 1e-12, "{payload} kg: {off:e}");
            }
        }
        let rigid = Rigid.predict_at(&model, &q, Some(payload)).unwrap();
        assert_eq!(rigid, model.tool_poses(&q));

        let rows = observed(&tree, &model, &flexibility, &q, Some(payload));
        let options = IdentificationOptions::default();
        let residual = weighted_residual(&model, &rows, &exact, &options).unwrap();
        assert!(residual.amax() <= 1e-9, "residual {:e}", residual.amax());
        if payload == 0.0 {
            let unloaded = without_payloads(&rows);
            let none = exact.offsets(&model, &q, None).unwrap();
            let loaded = exact.offsets(&model, &q, Some(payload)).unwrap();
            let gap = (none[0] - loaded[0]).fixed_rows::<3>(0).norm();
            assert!(
                gap > 1e-3,
                "the file's 20 kg moves the tool by {gap} m only"
            );
            let residual = weighted_residual(&model, &unloaded, &exact, &options).unwrap();
            assert!(residual.amax() > 1.0, "the payload changed nothing");
        }
    }
}

/// The compliance analysis reads the rows' own payloads: the same as the payloads given as a
/// list, and different from the rows without them.
#[test]
fn the_compliance_analysis_takes_the_rows_payloads() {
    let (tree, model, flexibility) = robonaut();
    let mut random = rng(4);
    let mut rows = Vec::new();
    let mut list = Vec::new();
    for k in 0..24 {
        let payload = [0.0, 20.0][k % 2];
        let q = random_configuration(&tree, &mut random);
        for m in observed(&tree, &model, &flexibility, &q, Some(payload)) {
            rows.push(m);
            list.push(payload);
        }
    }
    let options = IdentificationOptions::default();
    let free: Vec<usize> = (0..model.parameter_count()).collect();
    let analyse = |rows: &[Measurement], list: Option<&[f64]>| {
        analyse_compliance(
            &tree,
            &model,
            &flexibility,
            rows,
            list,
            &free,
            &options,
            StiffnessOptions::default().prior_sigma,
        )
        .unwrap()
    };
    let from_rows = analyse(&rows, None);
    let from_list = analyse(&rows, Some(&list));
    let unloaded = without_payloads(&rows);
    let from_file = analyse(&unloaded, None);
    let spread = |a: &treecal::calibration::ComplianceIdentifiability| -> Vec<f64> {
        a.parameters.iter().map(|p| p.1).collect()
    };
    assert_eq!(spread(&from_rows), spread(&from_list));
    assert_ne!(spread(&from_rows), spread(&from_file));
}

/// `simulate --payloads 0,20`: the identification configurations alternate between the two
/// payloads (every row carries its own, and the CSV writes them), and with the second payload
/// the identification determines more compliances than with self-weight alone.
#[test]
fn simulated_data_at_two_payloads_determine_more_than_at_one() {
    let robot = simulated_robonaut();
    let setup = robot.setup();
    let trial = |payloads: Vec<f64>| {
        let options = SimulationOptions {
            poses: 20,
            torso_poses: 10,
            validation_poses: 4,
            seed: 21,
            identify_stiffness: Some(StiffnessOptions::default()),
            payloads,
            ..SimulationOptions::default()
        };
        run_trial(&setup, &options, 0).unwrap()
    };
    let (one, two) = (trial(vec![0.0]), trial(vec![0.0, 20.0]));
    let loads: Vec<Option<f64>> = two.measurements.iter().map(|m| m.payload).collect();
    let at = |p: f64| loads.iter().filter(|&&l| l == Some(p)).count();
    assert_eq!(at(0.0) + at(20.0), loads.len());
    assert_eq!(at(0.0), at(20.0), "rows not split evenly");
    let text = measurements_to_csv(&robot.tree, &robot.nominal, &two.measurements).unwrap();
    assert!(text.contains("payload_kg"));
    let identified = |r: &treecal::sim::TrialReport| {
        r.stiffness
            .as_ref()
            .unwrap()
            .iter()
            .filter(|e| e.identified)
            .count()
    };
    eprintln!(
        "identified: 0 kg {}, 0 and 20 kg {}",
        identified(&one),
        identified(&two)
    );
    assert!(identified(&two) > identified(&one));
}

/// What identifies what (docs/flexibility.md, section 12): the same 40 configurations with
/// their rows at one payload, split evenly between two, and between three (as
/// `simulate --payloads` draws them), and self-weight alone. Prints the table of the doc.
/// Splitting the rows between payloads never loses a compliance that one payload determines
/// less well than the split does, and a payload beyond self-weight determines more.
#[test]
fn what_one_two_and_three_payloads_determine() {
    let (tree, model, flexibility) = robonaut();
    let mut random = rng(7);
    let configurations: Vec<Vec<f64>> = (0..40)
        .map(|_| random_configuration(&tree, &mut random))
        .collect();
    let options = IdentificationOptions::default();
    let free: Vec<usize> = (0..model.parameter_count()).collect();
    let analyse = |payloads: &[f64]| {
        let rows: Vec<Measurement> = configurations
            .iter()
            .enumerate()
            .flat_map(|(k, q)| {
                let payload = payloads[k % payloads.len()];
                observed(&tree, &model, &flexibility, q, Some(payload))
            })
            .collect();
        analyse_compliance(
            &tree,
            &model,
            &flexibility,
            &rows,
            None,
            &free,
            &options,
            0.5,
        )
        .unwrap()
    };
    let cases: [(&str, &[f64]); 5] = [
        ("0 kg", &[0.0]),
        ("20 kg", &[20.0]),
        ("0, 20 kg", &[0.0, 20.0]),
        ("10, 20 kg", &[10.0, 20.0]),
        ("0, 10, 20 kg", &[0.0, 10.0, 20.0]),
    ];
    let results: Vec<_> = cases.iter().map(|(_, p)| analyse(p)).collect();
    let count = |a: &treecal::calibration::ComplianceIdentifiability| {
        a.parameters.iter().filter(|p| p.2).count()
    };
    eprintln!(
        "| parameter | {} |",
        cases.iter().map(|c| c.0).collect::<Vec<_>>().join(" | ")
    );
    for k in 0..results[0].parameters.len() {
        eprintln!(
            "| {} | {} |",
            results[0].parameters[k].0,
            results
                .iter()
                .map(|r| format!(
                    "{:.4}{}",
                    r.parameters[k].1,
                    if r.parameters[k].2 { "*" } else { "" }
                ))
                .collect::<Vec<_>>()
                .join(" | ")
        );
    }
    for ((what, _), r) in cases.iter().zip(&results) {
        eprintln!(
            "{what}: {} of {} determined; not separable: {:?}",
            count(r),
            r.parameters.len(),
            r.unidentifiable
        );
    }
    let counts: Vec<usize> = results.iter().map(count).collect();
    assert!(
        counts[2] > counts[0],
        "a payload beyond self-weight adds nothing: {counts:?}"
    );
    assert!(counts[1] > counts[0], "{counts:?}");
    assert!(
        counts.iter().all(|&c| c < results[0].parameters.len()),
        "{counts:?}"
    );
}

/// The same rows with no payload stated.
fn without_payloads(rows: &[Measurement]) -> Vec<Measurement> {
    rows.iter()
        .map(|m| Measurement {
            payload: None,
            ..m.clone()
        })
        .collect()
}
