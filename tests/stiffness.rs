//! Stiffness identification: the compliance Jacobian against finite differences, noise-free
//! recovery of the identifiable compliances, and what one and two payloads determine.

use crate::common::{random_configuration, rng, robot, robot_model};
use rand::RngExt;
use rand_distr::{Distribution, Normal};
use treecal::calibration::{
    analyse_compliance, identify_stiffness, IdentificationOptions, StiffnessOptions,
};
use treecal::kinematics::{ComplianceBasis, FlexibilityModel, Stiffness};
use treecal::math::pose_error;
use treecal::measurement::{Measurement, Observation};
use treecal::tree::{detect_branches, KinematicTree};
use treecal::McpcModel;

fn robonaut() -> (KinematicTree, McpcModel, FlexibilityModel) {
    let (tree, model) = crate::common::robonaut_model();
    let stiffness =
        treecal::io::read_stiffness(&robot("robonaut/stiffness.yaml"), &tree, &model).unwrap();
    let flexibility = FlexibilityModel::new(&tree, &model, &stiffness).unwrap();
    (tree, model, flexibility)
}

/// The exact derivative of the deflected tool poses with respect to every compliance scale
/// against central differences, at random scales and configurations (Robonaut with its file;
/// the humanoid with the defaults, head and fingers included).
#[test]
fn compliance_jacobian_matches_finite_differences() {
    let (tree, model, flexibility) = robonaut();
    let (humanoid, humanoid_model) = robot_model("humanoid/humanoid.urdf");
    let humanoid_flexibility =
        FlexibilityModel::new(&humanoid, &humanoid_model, &Stiffness::default()).unwrap();
    let mut random = rng(11);
    for (tree, model, flexibility) in [
        (&tree, &model, &flexibility),
        (&humanoid, &humanoid_model, &humanoid_flexibility),
    ] {
        let basis = ComplianceBasis::new(flexibility);
        let count = basis.parameters().len();
        let mut worst: f64 = 0.0;
        let mut largest: f64 = 0.0;
        for _ in 0..4 {
            let q = random_configuration(tree, &mut random);
            let scales: Vec<f64> = (0..count).map(|_| random.random_range(0.5..2.0)).collect();
            let jacobian = basis.jacobian(&scales, tree, model, &q).unwrap();
            let h = 1e-6;
            for k in 0..count {
                let shifted = |delta: f64| {
                    let mut s = scales.clone();
                    s[k] += delta;
                    basis
                        .scaled(&s)
                        .unwrap()
                        .deflected_tool_poses(tree, model, &q)
                        .unwrap()
                };
                let (plus, minus) = (shifted(h), shifted(-h));
                for tool in 0..plus.len() {
                    let numeric = pose_error(&plus[tool], &minus[tool]) / (2.0 * h);
                    let analytic = jacobian.jacobians[tool].column(k);
                    worst = worst.max((numeric - analytic).amax());
                    largest = largest.max(analytic.amax());
                }
            }
        }
        eprintln!(
            "{}: largest column entry {largest:.3e}, worst difference {worst:.3e}",
            tree.name()
        );
        assert!(
            largest > 1e-4,
            "{}: the derivatives are all zero",
            tree.name()
        );
        assert!(
            worst < 1e-8,
            "{}: compliance Jacobian off by {worst:.3e}",
            tree.name()
        );
    }
}

/// Noise-free poses of a deflected truth at `configurations` (every tool), optionally at a
/// payload per configuration.
fn measure(
    tree: &KinematicTree,
    truth: &McpcModel,
    flexibility: &FlexibilityModel,
    configurations: &[(Vec<f64>, f64)],
    with_payloads: bool,
) -> (Vec<Measurement>, Vec<f64>) {
    let mut measurements = Vec::new();
    let mut payloads = Vec::new();
    for (q, payload) in configurations {
        let loaded = if with_payloads {
            flexibility.with_payload_at_every_tool(*payload).unwrap()
        } else {
            flexibility.clone()
        };
        for (tool, pose) in loaded
            .deflected_tool_poses(tree, truth, q)
            .unwrap()
            .into_iter()
            .enumerate()
        {
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: Observation::Pose(pose),
                stage: None,
                session: None,
            });
            payloads.push(*payload);
        }
    }
    (measurements, payloads)
}

/// The identifiable compliances of the truth are the prior's × 1.5 (the model 50 % too stiff;
/// the others as the prior, since nothing can recover them), its geometry off by ±0.02. From
/// the true geometry nudged by 1e-3 and the prior, the identification recovers the geometry
/// and every identifiable compliance to 1e-6 relative; the others stay at the prior (their
/// common scale is identified as 1).
#[test]
fn noise_free_identification_recovers_the_identifiable_compliances() {
    let (tree, nominal, flexibility) = robonaut();
    let prior = flexibility.scaled(1.0 / 1.5).unwrap();
    let mut random = rng(5);
    let mut truth = nominal.clone();
    let values: Vec<f64> = truth
        .parameters()
        .iter()
        .map(|v| v + random.random_range(-0.02..0.02))
        .collect();
    truth.set_parameters(&values).unwrap();
    let configurations: Vec<(Vec<f64>, f64)> = (0..40)
        .map(|_| (random_configuration(&tree, &mut random), 20.0))
        .collect();
    let free: Vec<usize> = (0..nominal.parameter_count()).collect();
    let options = IdentificationOptions::default();
    // Where the fit starts: the true geometry nudged by 1e-3.
    let mut start = truth.clone();
    let nudged: Vec<f64> = values
        .iter()
        .map(|v| v + random.random_range(-1e-3..1e-3))
        .collect();
    start.set_parameters(&nudged).unwrap();
    // Which compliances these configurations determine, decided as the fit decides it: at its
    // start (the observed values do not matter).
    let (probe, _) = measure(&tree, &start, &prior, &configurations, false);
    let analysis =
        analyse_compliance(&tree, &start, &prior, &probe, None, &free, &options, 0.5).unwrap();
    let basis = ComplianceBasis::new(&prior);
    // The individual scales (the analysis lists the two common scales after them).
    let truth_scales: Vec<f64> = analysis
        .parameters
        .iter()
        .take(basis.parameters().len())
        .map(|p| if p.2 { 1.5 } else { 1.0 })
        .collect();
    let truth_flexibility = basis.scaled(&truth_scales).unwrap();
    let (measurements, _) = measure(&tree, &truth, &truth_flexibility, &configurations, false);
    let started = std::time::Instant::now();
    let report = identify_stiffness(
        &tree,
        &start,
        &prior,
        &measurements,
        None,
        &free,
        &options,
        &StiffnessOptions::default(),
    )
    .unwrap();
    let elapsed = started.elapsed();
    // Good data: nothing fitted below zero, no warning.
    assert!(
        report.held_below_zero.is_empty(),
        "{:?}",
        report.held_below_zero
    );
    assert!(treecal::calibration::stiffness_below_zero(&report).is_none());
    let mut held = report.clone();
    held.held_below_zero
        .push("left_joint1 GI_p: fitted at -0.093, below zero; held at the prior".into());
    let finding = treecal::calibration::stiffness_below_zero(&held).unwrap();
    assert_eq!(finding.status, treecal::calibration::Status::Warning);
    assert!(finding
        .message
        .contains("left_joint1 GI_p: fitted at -0.093"));
    let identified = report.estimates.iter().filter(|e| e.identified).count();
    eprintln!(
        "identified {identified} of {}; cost {:?}; {} iterations; {elapsed:?} (test profile)",
        report.estimates.len(),
        report.cost,
        report.iterations,
    );
    assert!(identified >= 10, "only {identified} compliances identified");
    for (e, &scale) in report.estimates.iter().zip(&truth_scales) {
        assert_eq!(
            e.identified,
            scale != 1.0,
            "{}: analysis and fit disagree",
            e.name
        );
        assert!(
            (e.scale - scale).abs() < 1e-6 * scale,
            "{}: scale {} instead of {scale}",
            e.name,
            e.scale
        );
    }
    let geometry = report
        .model
        .parameters()
        .iter()
        .zip(&values)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(geometry < 1e-8, "geometry off by {geometry:.2e}");
}

/// What one payload and two payloads determine (the numbers in docs/flexibility.md, section
/// 12): 40 configurations measured without payload, at 20 kg, and at both. Measuring again at
/// a second payload adds information, so it determines at least as many compliances.
#[test]
fn a_second_payload_separates_compliance_from_geometry() {
    let (tree, nominal, flexibility) = robonaut();
    let mut random = rng(7);
    let configurations: Vec<Vec<f64>> = (0..40)
        .map(|_| random_configuration(&tree, &mut random))
        .collect();
    let at = |payloads: &[f64]| -> Vec<(Vec<f64>, f64)> {
        configurations
            .iter()
            .flat_map(|q| payloads.iter().map(move |&p| (q.clone(), p)))
            .collect()
    };
    let (unloaded, one, two) = (at(&[0.0]), at(&[20.0]), at(&[20.0, 0.0]));
    let options = IdentificationOptions::default();
    let free: Vec<usize> = (0..nominal.parameter_count()).collect();
    let analyse = |set: &[(Vec<f64>, f64)]| {
        let (measurements, payloads) = measure(&tree, &nominal, &flexibility, set, true);
        analyse_compliance(
            &tree,
            &nominal,
            &flexibility,
            &measurements,
            Some(&payloads),
            &free,
            &options,
            0.5,
        )
        .unwrap()
    };
    let (none, single, double) = (analyse(&unloaded), analyse(&one), analyse(&two));
    let count = |a: &treecal::calibration::ComplianceIdentifiability| {
        a.parameters.iter().filter(|p| p.2).count()
    };
    eprintln!("| parameter | 0 kg ± | 20 kg ± | 20 and 0 kg ± |");
    for ((a, b), c) in none
        .parameters
        .iter()
        .zip(&single.parameters)
        .zip(&double.parameters)
    {
        eprintln!("| {} | {:.4} | {:.4} | {:.4} |", a.0, a.1, b.1, c.1);
    }
    eprintln!(
        "determined: self-weight only {}, one payload {}, two payloads {} of {}",
        count(&none),
        count(&single),
        count(&double),
        single.parameters.len()
    );
    for (what, a) in [
        ("0 kg", &none),
        ("20 kg", &single),
        ("20 and 0 kg", &double),
    ] {
        eprintln!("{what}: not separable: {:?}", a.unidentifiable);
    }
    assert!(count(&double) >= count(&single));
    assert!(count(&double) > 0);
}

/// How a trial's true compliances scatter about the stiffness file: every compliance times
/// `base·exp(spread·ξ_g)·exp(spread·ξ_k)`, a common factor per group (all joints, all links)
/// and one per compliance, ξ ~ N(0, 1).
struct TruthDraw {
    spread: f64,
    base: f64,
}

/// One simulated trial (Robonaut, AT901 noise, staged plan, 2 validation configurations) whose
/// true stiffness is drawn by `draw` from `seed`, identified with `prior`; with the true scales.
fn prior_drawn_trial(
    robot: &crate::common::SimulatedRobot,
    seed: u64,
    draw: &TruthDraw,
    prior: StiffnessOptions,
) -> (treecal::sim::TrialReport, Vec<f64>) {
    let model_flexibility = &robot.flexibility;
    let parameters = ComplianceBasis::new(model_flexibility)
        .parameters()
        .to_vec();
    let mut random = rng(seed);
    let normal = Normal::new(0.0, draw.spread).unwrap();
    let common: [f64; 2] = [0, 1].map(|_| normal.sample(&mut random).exp());
    let truth: Vec<f64> = parameters
        .iter()
        .map(|p| {
            let group = common[usize::from(!p.kind.is_joint())];
            draw.base * group * normal.sample(&mut random).exp()
        })
        .collect();
    let truth_flexibility = model_flexibility
        .with_compliance_scales(&parameters, &truth)
        .unwrap();
    let setup = treecal::sim::Setup {
        truth_flexibility: &truth_flexibility,
        model_flexibility,
        ..robot.setup()
    };
    let options = treecal::sim::SimulationOptions {
        validation_poses: 2,
        seed,
        identify_stiffness: Some(prior),
        ..Default::default()
    };
    let mut report = treecal::sim::run_trials(&setup, &options, 1, &|| {}).unwrap();
    (report.remove(0), truth)
}

/// Monte Carlo of the compliances' standard deviations: Robonaut trials whose truth is drawn
/// from the prior the identification assumes (the default relative σ 0.5; see [`TruthDraw`]);
/// AT901 noise, the staged plan. Over the identified compliances of every trial, the deviations
/// of the scale from the truth over their predicted standard deviations (with the consider
/// covariance of the compliances held at the prior) should be about N(0, 1): a median |z| near
/// 0.67 and about 95 % within 2σ. Fails if fewer than 88 % are within 2σ, the median |z|
/// leaves 0.5–0.85, or any |z| exceeds 10 (a scale run away; 20 trials: about 40 s).
///
/// The variables `TREECAL_COVERAGE_TRIALS` (default 20), `TREECAL_COVERAGE_SIGMA` (the prior's
/// σ, default 0.5), `TREECAL_COVERAGE_SPREAD` (the truth's, default the prior's) and
/// `TREECAL_COVERAGE_BASE` (a common factor on top, default 1) set the trials and the truth;
/// numbers for other settings in docs/identification.md.
#[test]
fn identified_compliances_are_within_their_standard_deviations() {
    let robot = crate::common::simulated_robonaut();
    let variable = |name: &str, default: f64| -> f64 {
        std::env::var(name)
            .ok()
            .and_then(|t| t.parse().ok())
            .unwrap_or(default)
    };
    let trials = variable("TREECAL_COVERAGE_TRIALS", 20.0) as usize;
    let prior = StiffnessOptions {
        prior_sigma: variable("TREECAL_COVERAGE_SIGMA", 0.5),
        ..Default::default()
    };
    let truth = TruthDraw {
        spread: variable("TREECAL_COVERAGE_SPREAD", prior.prior_sigma),
        // A common factor on top (1.5: the model 50 % too stiff).
        base: variable("TREECAL_COVERAGE_BASE", 1.0),
    };
    let reports: Vec<_> = (0..trials)
        .map(|trial| prior_drawn_trial(&robot, 2026 + trial as u64, &truth, prior))
        .collect();
    let mut z: Vec<f64> = Vec::new();
    let mut per_parameter: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
    for (report, truth) in &reports {
        let estimates = report.stiffness.as_ref().unwrap();
        assert_eq!(estimates.len(), truth.len());
        for (e, t) in estimates.iter().zip(truth) {
            if let (true, Some(sd)) = (e.identified, e.scale_std_dev) {
                // In the fit's parameterisation: the scale itself.
                let value = (e.scale - t) / sd;
                z.push(value);
                per_parameter.entry(e.name.clone()).or_default().push(value);
            }
        }
    }
    for (name, values) in &per_parameter {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let rms = (values.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        eprintln!("{name}: n {n}, mean z {mean:+.2}, rms z {rms:.2}");
    }
    let below_zero = reports
        .iter()
        .flat_map(|(r, _)| r.stiffness.as_ref().unwrap())
        .filter(|e| e.fitted_below_zero.is_some())
        .count();
    eprintln!("fitted below zero, held at the prior: {below_zero}");
    let mut magnitudes: Vec<f64> = z.iter().map(|v| v.abs()).collect();
    magnitudes.sort_by(f64::total_cmp);
    let median = magnitudes[magnitudes.len() / 2];
    let within = |k: f64| magnitudes.iter().filter(|&&m| m <= k).count() as f64 / z.len() as f64;
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    let wild = magnitudes.iter().filter(|&&m| m > 10.0).count();
    eprintln!("|z| > 10: {wild}");
    eprintln!(
        "{} trials, {} estimates: median |z| {median:.3}, within 1σ {:.3}, within 2σ {:.3}, mean z {mean:+.3}",
        reports.len(),
        z.len(),
        within(1.0),
        within(2.0)
    );
    assert!(z.len() >= 10 * trials, "only {} estimates", z.len());
    assert_eq!(wild, 0, "{wild} scales more than 10σ off");
    assert!(within(2.0) >= 0.88, "only {:.3} within 2σ", within(2.0));
    assert!((0.5..=0.85).contains(&median), "median |z| {median:.3}");
}

/// A compliance scale the joint fit puts at or below zero is not physical: it is held at the
/// prior (its group's scale), named with its fitted value, and the fit redone; every identified
/// scale is positive. Seed 1: left_joint1 GI_p (truth 0.36) fitted at about −0.09, the data
/// reading through the held link compliances, which the truth scatters by ±50 %.
#[test]
fn a_scale_fitted_below_zero_is_held_at_the_prior_and_named() {
    let robot = crate::common::simulated_robonaut();
    let draw = TruthDraw {
        spread: 0.5,
        base: 1.0,
    };
    let (report, _) = prior_drawn_trial(&robot, 1, &draw, StiffnessOptions::default());
    let estimates = report.stiffness.unwrap();
    let below: Vec<_> = estimates
        .iter()
        .filter(|e| e.fitted_below_zero.is_some())
        .collect();
    assert!(!below.is_empty(), "nothing fitted below zero");
    for e in &below {
        assert!(!e.identified, "{} still identified", e.name);
        assert!(e.fitted_below_zero.unwrap() <= 0.0);
        assert!(e.scale > 0.0, "{}: scale {}", e.name, e.scale);
    }
    assert!(below.iter().any(|e| e.name == "left_joint1 GI_p"));
    for e in estimates.iter().filter(|e| e.identified) {
        assert!(e.scale > 0.0, "{}: identified at {}", e.name, e.scale);
    }
}

/// The largest relative difference of the identified compliance scales of two fits.
fn largest_scale_change(
    a: &[treecal::calibration::ComplianceEstimate],
    b: &[treecal::calibration::ComplianceEstimate],
) -> f64 {
    a.iter()
        .zip(b)
        .filter(|(x, _)| x.identified)
        .map(|(x, y)| ((x.scale - y.scale) / y.scale).abs())
        .fold(0.0, f64::max)
}

/// Issue 22's question: `calibrate --identify-stiffness` passed the rows the robust fit named as
/// blunders to the stiffness fit, `simulate` left them out. The stiffness fit is plain least
/// squares, so leaving them out is right: with a 20 mm blunder in one row, the shared sequence
/// (`calibrate_with_stiffness`) identifies the compliance scales of the clean data, while a fit
/// of every row moves them ten times as far.
#[test]
#[ignore = "unfinished (issue 22): the 20 mm blunder is not named an outlier with this set-up; see the h22 report"]
fn the_stiffness_fit_leaves_the_outliers_out() {
    use treecal::calibration::{
        calibrate_robust, calibrate_with_stiffness, CalibrationReport, Compensation, Deflected,
        Fitted, Plan, RobustReport,
    };
    let (tree, nominal, flexibility) = robonaut();
    let branches = detect_branches(&tree, None).unwrap();
    let mut random = rng(11);
    let mut truth = nominal.clone();
    let values: Vec<f64> = truth
        .parameters()
        .iter()
        .map(|v| v + random.random_range(-0.01..0.01))
        .collect();
    truth.set_parameters(&values).unwrap();
    let truth_flexibility = flexibility.scaled(1.3).unwrap();
    let configurations: Vec<(Vec<f64>, f64)> = (0..30)
        .map(|_| (random_configuration(&tree, &mut random), 20.0))
        .collect();
    let (clean, _) = measure(&tree, &truth, &truth_flexibility, &configurations, false);
    let mut blundered = clean.clone();
    if let Observation::Pose(pose) = &mut blundered[7].observation {
        pose.translation.vector.x += 0.02;
    }
    let options = IdentificationOptions::default();
    let stiffness = StiffnessOptions::default();
    let sequence = |data: &[Measurement]| {
        calibrate_with_stiffness(
            &tree,
            &flexibility,
            Some(&flexibility),
            &options,
            &stiffness,
            |flexibility: Option<&FlexibilityModel>| {
                let compensation = match flexibility {
                    Some(flexibility) => Compensation::Exact(Deflected {
                        tree: &tree,
                        flexibility,
                    }),
                    None => Compensation::None,
                };
                calibrate_robust(
                    &branches,
                    &nominal,
                    data,
                    compensation,
                    &Plan::simultaneous(),
                    &options,
                )
            },
            |(report, robust): &(CalibrationReport, RobustReport)| Fitted {
                model: report.model.clone(),
                measurements: data.to_vec(),
                outliers: robust.outliers(),
            },
        )
        .unwrap()
    };
    let on_clean = sequence(&clean);
    let on_blundered = sequence(&blundered);
    assert!(on_blundered.first.1.outliers().contains(&7));
    let kept_out = largest_scale_change(
        &on_blundered.stiffness.estimates,
        &on_clean.stiffness.estimates,
    );
    // The same fit with the blunder kept in (what `calibrate` did).
    let free: Vec<usize> = (0..nominal.parameter_count()).collect();
    let kept_in = identify_stiffness(
        &tree,
        &on_blundered.first.0.model,
        &flexibility,
        &blundered,
        None,
        &free,
        &options,
        &stiffness,
    )
    .unwrap();
    let kept_in = largest_scale_change(&kept_in.estimates, &on_clean.stiffness.estimates);
    eprintln!("largest scale change: outlier left out {kept_out:.2e}, kept in {kept_in:.2e}");
    assert!(kept_out < 1e-3, "{kept_out}");
    assert!(
        kept_in > 10.0 * kept_out.max(1e-4),
        "{kept_in} vs {kept_out}"
    );
}
