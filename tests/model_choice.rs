//! The model the data support, with simulated truth: each level recovers its own truth
//! (offsets with the measurement frame, harmonics and backlash on the full geometry), the
//! prior pulls what the data cannot see to nominal with the right covariance, the grouped
//! folds never split a posture, and the cross-validation prefers the level the data were
//! simulated with.

use crate::common::cli::*;
use crate::common::*;
use rand::RngExt;
use treecal::calibration::{
    calibrate, CalibrationInput, Compensation, IdentificationOptions, MeasurementFrame, Plan, Prior,
};
use treecal::kinematics::{GravitySigns, JointErrorTerms, McpcModel};
use treecal::measurement::{Measurement, Observation};
use treecal::tree::{detect_branches, KinematicTree};
use treecal::workflow::{candidates, cross_validate, CrossValidationInput};
use treecal::workflow::{
    fit_noise, glob_match, grouped_folds, posture_groups, prepare, ModelLevel, ModelSpec,
    ParameterPatterns, SIGNIFICANT_T,
};

fn humanoid() -> (KinematicTree, treecal::Branches, McpcModel) {
    let tree = treecal::load_urdf(&robot("humanoid/humanoid.urdf"))
        .unwrap()
        .tree;
    let branches = detect_branches(&tree, None).unwrap();
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    (tree, branches, model)
}

/// Full-pose measurements of every tool of `truth` at `count` random configurations, with
/// Gaussian position noise `noise` (m) and `noise` rad of rotation noise.
fn measure(
    tree: &KinematicTree,
    truth: &McpcModel,
    count: usize,
    noise: f64,
    seed: u64,
) -> Vec<Measurement> {
    measure_with_noise(tree, truth, count, [noise, noise], seed)
}

/// [`measure`] with position noise `noise[0]` (m) and rotation noise `noise[1]` (rad), each
/// coordinate uniform with that standard deviation.
fn measure_with_noise(
    tree: &KinematicTree,
    truth: &McpcModel,
    count: usize,
    noise: [f64; 2],
    seed: u64,
) -> Vec<Measurement> {
    let mut rng = rng(seed);
    let mut data = Vec::new();
    for _ in 0..count {
        let q = random_configuration(tree, &mut rng);
        for (tool, pose) in truth.tool_poses(&q).into_iter().enumerate() {
            let mut jitter = |sigma: f64| rng.random_range(-1.0..1.0) * sigma * 3f64.sqrt();
            let shift =
                nalgebra::Vector3::new(jitter(noise[0]), jitter(noise[0]), jitter(noise[0]));
            let turn = nalgebra::Vector3::new(jitter(noise[1]), jitter(noise[1]), jitter(noise[1]));
            let noisy = treecal::math::Pose::from_parts(
                (pose.translation.vector + shift).into(),
                nalgebra::UnitQuaternion::from_scaled_axis(turn) * pose.rotation,
            );
            data.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: Observation::Pose(noisy),
                stage: None,
                session: None,
            });
        }
    }
    data
}

/// A copy of `model` with every free parameter moved by up to `size` (rad or m).
fn perturbed(model: &McpcModel, size: f64, seed: u64) -> McpcModel {
    let mut rng = rng(seed);
    let values: Vec<f64> = model
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-size..size))
        .collect();
    let mut truth = model.clone();
    truth.set_parameters(&values).unwrap();
    truth
}

fn spec(level: ModelLevel, harmonics: bool, backlash: bool) -> ModelSpec {
    ModelSpec {
        level,
        harmonics,
        backlash,
        ..ModelSpec::default()
    }
}

#[test]
fn offsets_level_recovers_joint_offsets_and_the_measurement_frame() {
    let (tree, branches, nominal) = humanoid();
    let prepared = prepare(
        &spec(ModelLevel::Offsets, false, false),
        &tree,
        &nominal,
        &IdentificationOptions::default(),
        &ParameterPatterns::default(),
    )
    .unwrap();
    // Truth: offsets, tools and the frame moved; the MCPC frames nominal.
    let mut truth = perturbed(&prepared.nominal, 0.02, 1);
    let mut values = truth.parameters();
    for &p in &prepared.options.frozen {
        values[p] = prepared.nominal.parameters()[p];
    }
    truth.set_parameters(&values).unwrap();
    let data = measure(&tree, &truth, 25, 0.0, 2);
    let report = calibrate(
        &branches,
        &prepared.nominal,
        &data,
        Compensation::None,
        &Plan::simultaneous(),
        &prepared.options,
    )
    .unwrap();
    check_recovery(&tree, &report, &truth, 1e-8);
}

/// Every parameter the data determine is the truth's, and at new configurations the tools
/// are where the truth puts them (the last joint's offset, for one, is also a turn of the
/// tool: the combination is determined, not each part).
fn check_recovery(
    tree: &KinematicTree,
    report: &treecal::calibration::CalibrationReport,
    truth: &McpcModel,
    tolerance: f64,
) {
    let found = report.model.parameters();
    let identification = &report.stages[0].identification;
    let mut checked = 0;
    for (k, &p) in identification.free.iter().enumerate() {
        if identification.identifiable[k] {
            checked += 1;
            let (a, b) = (found[p], truth.parameters()[p]);
            assert!(
                (a - b).abs() < tolerance,
                "{}: {a} vs {b}",
                truth.parameter_name(tree, p)
            );
        }
    }
    assert!(checked > identification.free.len() / 2);
    for m in measure(tree, truth, 5, 0.0, 99) {
        let Observation::Pose(pose) = m.observation else {
            unreachable!()
        };
        assert_pose_eq(
            &report.model.tool_pose(m.tool, &m.q),
            &pose,
            tolerance,
            "validation",
        );
    }
}

#[test]
fn harmonics_and_backlash_are_recovered_with_the_geometry() {
    let (tree, branches, nominal) = humanoid();
    let gravity = GravitySigns::new(&tree, &nominal).unwrap();
    let terms = JointErrorTerms {
        offsets: false,
        harmonics: true,
        backlash: true,
    };
    let model = nominal.with_joint_errors(terms, Some(gravity)).unwrap();
    let truth = perturbed(&model, 0.01, 3);
    let data = measure(&tree, &truth, 60, 0.0, 4);
    let report = calibrate(
        &branches,
        &model,
        &data,
        Compensation::None,
        &Plan::simultaneous(),
        &IdentificationOptions::default(),
    )
    .unwrap();
    let names: Vec<String> = (0..model.parameter_count())
        .map(|i| model.parameter_name(&tree, i))
        .collect();
    let checked = names
        .iter()
        .filter(|n| n.ends_with("backlash") || n.ends_with("sine"))
        .count();
    assert!(checked >= 2 * model.frames().len() - 2, "{names:?}");
    check_recovery(&tree, &report, &truth, 1e-7);
    // Backlash is seen (not every joint: a vertical axis carries no gravity torque).
    let identification = &report.stages[0].identification;
    let seen = identification
        .free
        .iter()
        .zip(&identification.identifiable)
        .filter(|(&p, &ok)| ok && names[p].ends_with("backlash"))
        .count();
    assert!(
        seen >= model.frames().len() / 2,
        "{seen} backlash terms determined"
    );
}

#[test]
fn the_prior_keeps_unseen_parameters_nominal_and_enters_the_covariance() {
    let (tree, branches, nominal) = humanoid();
    // Positions only at few configurations: rank-deficient without the prior.
    let truth = perturbed(&nominal, 0.003, 5);
    let data: Vec<Measurement> = measure(&tree, &truth, 6, 0.0, 6)
        .into_iter()
        .map(|m| Measurement {
            observation: match m.observation {
                Observation::Pose(p) => Observation::Position(p.translation.vector),
                other => other,
            },
            ..m
        })
        .collect();
    let mut prior = Prior::default_for(&nominal, &nominal.parameters());
    // A prior on the tools too, so that every parameter has one.
    prior.sigma = prior.sigma.iter().map(|s| s.min(0.01)).collect();
    let options = IdentificationOptions {
        prior: Some(prior.clone()),
        ..Default::default()
    };
    let free: Vec<usize> = (0..nominal.parameter_count()).collect();
    let with = treecal::calibration::identify(
        &nominal,
        &data,
        None,
        &treecal::calibration::Rigid,
        &free,
        &options,
    )
    .unwrap();
    assert_eq!(
        with.rank,
        free.len(),
        "the prior makes every parameter determined"
    );
    // The covariance is σ̂²·(JᵀWJ + Λ)⁻¹ at the solution, Λ = diag(1/σ_prior²).
    let mut solved = nominal.clone();
    solved.set_parameters(&with.parameters).unwrap();
    let weights = [1.0 / options.position_sigma, 1.0 / options.rotation_sigma];
    let rows: usize = data.iter().map(|m| m.observation.rows()).sum();
    let mut jacobian = nalgebra::DMatrix::zeros(rows, free.len());
    let mut row = 0;
    for m in &data {
        let tool = solved.tool_jacobian(m.tool, &m.q);
        for k in 0..m.observation.rows() {
            for c in 0..free.len() {
                jacobian[(row + k, c)] = tool.jacobian[(k, c)] * weights[k / 3];
            }
        }
        row += m.observation.rows();
    }
    let mut normal = jacobian.tr_mul(&jacobian);
    for (c, s) in prior.sigma.iter().enumerate() {
        normal[(c, c)] += 1.0 / (s * s);
    }
    let expected = normal.try_inverse().unwrap() * with.residual_scale.powi(2);
    let covariance = with.covariance.clone().unwrap();
    let largest = expected.amax();
    assert!(
        (&covariance - &expected).amax() < 1e-6 * largest,
        "covariance differs by {}",
        (&covariance - &expected).amax()
    );
    // Without the prior the minimum-norm step leaves unseen combinations at nominal too, but
    // the prior also pulls the seen-but-weak ones: every parameter stays within a few prior
    // σ of nominal, and the tool points are still fitted.
    for (i, (a, b)) in with.parameters.iter().zip(nominal.parameters()).enumerate() {
        assert!(
            (a - b).abs() < 5.0 * prior.sigma[i],
            "{}: moved {} (σ {})",
            nominal.parameter_name(&tree, i),
            a - b,
            prior.sigma[i]
        );
    }
    assert!(with.residual_rms_position < 5e-3);
    let _ = branches;
}

#[test]
fn a_grouped_fold_never_splits_a_posture() {
    let (tree, _, nominal) = humanoid();
    let mut data = measure(&tree, &nominal, 12, 0.0, 7);
    // The same postures measured again a little off (another session), in another order.
    let again: Vec<Measurement> = data
        .iter()
        .rev()
        .map(|m| Measurement {
            q: m.q.iter().map(|v| v + 0.002).collect(),
            ..m.clone()
        })
        .collect();
    data.extend(again);
    let groups = posture_groups(&data);
    assert_eq!(groups.len(), 12);
    let folds = grouped_folds(&data, 5, 3);
    let mut seen = vec![0; data.len()];
    for fold in &folds {
        for &i in fold {
            seen[i] += 1;
        }
        for group in &groups {
            let inside = group.iter().filter(|i| fold.contains(i)).count();
            assert!(
                inside == 0 || inside == group.len(),
                "fold splits {group:?}"
            );
        }
    }
    assert!(seen.iter().all(|&n| n == 1));
}

#[test]
fn freeze_and_free_patterns_follow_the_parameter_names() {
    assert!(glob_match("arm_7_joint *", "arm_7_joint alpha"));
    assert!(!glob_match("arm_7_joint *", "arm_6_joint alpha"));
    assert!(glob_match("*_joint ?", "left_joint x"));
    let (tree, _, nominal) = humanoid();
    let name = nominal.parameter_name(&tree, 0);
    let joint = name.split(' ').next().unwrap().to_string();
    let patterns = ParameterPatterns {
        freeze: vec![format!("{joint} *")],
        free: vec![format!("{joint} x")],
    };
    let prepared = prepare(
        &ModelSpec::default(),
        &tree,
        &nominal,
        &IdentificationOptions::default(),
        &patterns,
    )
    .unwrap();
    let frozen: Vec<String> = prepared
        .options
        .frozen
        .iter()
        .map(|&i| nominal.parameter_name(&tree, i))
        .collect();
    assert_eq!(frozen.len(), 3, "{frozen:?}");
    assert!(!frozen.contains(&format!("{joint} x")));
    let wrong = ParameterPatterns {
        freeze: vec!["no_such_joint *".into()],
        free: Vec::new(),
    };
    let error = prepare(
        &ModelSpec::default(),
        &tree,
        &nominal,
        &IdentificationOptions::default(),
        &wrong,
    )
    .unwrap_err()
    .to_string();
    assert!(error.contains("matches no parameter"), "{error}");
}

/// Data simulated with harmonic joint errors: the cross-validation prefers a candidate with
/// harmonics; data simulated with the plain geometry: one without.
#[test]
fn cross_validation_chooses_the_level_the_data_were_simulated_with() {
    let (tree, branches, nominal) = humanoid();
    let options = IdentificationOptions {
        position_sigma: 1e-4,
        rotation_sigma: 1e-4,
        ..Default::default()
    };
    let plan = Plan::simultaneous();
    let patterns = ParameterPatterns::default();
    let input = CrossValidationInput {
        calibration: CalibrationInput {
            tree: &tree,
            branches: &branches,
            nominal: &nominal,
            flexibility: None,
            plan: &plan,
            options: &options,
            measurement_frame: MeasurementFrame::Base,
            diagnose_columns: true,
        },
        patterns: &patterns,
        joint_steps: 0,
        stiffness: None,
    };
    let list = vec![
        spec(ModelLevel::Offsets, false, false),
        spec(ModelLevel::Geometry, false, false),
        spec(ModelLevel::Geometry, true, false),
    ];
    assert!(candidates(&tree, &nominal, false, false).len() >= list.len());
    let harmonic = nominal
        .with_joint_errors(
            JointErrorTerms {
                harmonics: true,
                ..Default::default()
            },
            None,
        )
        .unwrap();
    let mut rng = rng(11);
    let mut values = harmonic.parameters();
    let geometry = nominal.parameter_count();
    for v in values.iter_mut().take(geometry) {
        *v += rng.random_range(-0.005..0.005);
    }
    for v in values.iter_mut().skip(geometry) {
        *v += rng.random_range(-0.01..0.01);
    }
    let mut truth = harmonic.clone();
    truth.set_parameters(&values).unwrap();
    let data = measure(&tree, &truth, 40, 5e-5, 12);
    let cv = cross_validate(&input, &list, &data, 4, 1, 1).unwrap();
    assert_eq!(cv.chosen, Some(2), "{cv:#?}");
    let mut plain = nominal.clone();
    plain.set_parameters(&values[..geometry]).unwrap();
    let data = measure(&tree, &plain, 40, 5e-5, 13);
    let cv = cross_validate(&input, &list, &data, 4, 1, 1).unwrap();
    let chosen = cv.chosen.unwrap();
    assert_eq!(cv.rows[chosen].spec.level, ModelLevel::Geometry, "{cv:#?}");
    assert!(
        !cv.rows[chosen].spec.harmonics || {
            // Harmonics may tie on data without them; they must not be clearly better.
            let rms = |i: usize| cv.rows[i].rms_mm.unwrap();
            rms(2) > 0.9 * rms(1)
        }
    );
    assert!(cv.rows[0].rms_mm.unwrap() > 2.0 * cv.rows[1].rms_mm.unwrap());
}

/// The choice on simulated truth, for several data and fold seeds: the full geometry (the
/// paper's model) is the reference, listed first or last; offsets-only truth keeps it or takes
/// `offsets` only when significantly lower (both fit that truth); full geometric truth keeps the
/// geometry. Each row's difference to the reference comes with its standard error.
#[test]
fn the_paper_model_stays_unless_significantly_beaten_for_several_seeds() {
    let (tree, branches, nominal) = humanoid();
    let options = IdentificationOptions::default();
    let plan = Plan::simultaneous();
    let patterns = ParameterPatterns::default();
    let input = CrossValidationInput {
        calibration: CalibrationInput {
            tree: &tree,
            branches: &branches,
            nominal: &nominal,
            flexibility: None,
            plan: &plan,
            options: &options,
            measurement_frame: MeasurementFrame::Base,
            diagnose_columns: true,
        },
        patterns: &patterns,
        joint_steps: 0,
        stiffness: None,
    };
    let list = vec![
        spec(ModelLevel::Geometry, false, false),
        spec(ModelLevel::Offsets, false, false),
    ];
    let reversed = vec![list[1], list[0]];
    let offsets = prepare(&list[1], &tree, &nominal, &options, &patterns).unwrap();
    for seed in [1u64, 2, 3] {
        let mut truth = perturbed(&offsets.nominal, 0.02, 100 + seed);
        let mut values = truth.parameters();
        for &p in &offsets.options.frozen {
            values[p] = offsets.nominal.parameters()[p];
        }
        truth.set_parameters(&values).unwrap();
        let data = measure(&tree, &truth, 30, 5e-5, 200 + seed);
        let cv = cross_validate(&input, &list, &data, 4, 2, seed).unwrap();
        assert_eq!(cv.best, Some(0), "the geometry is the reference: {cv:#?}");
        assert_eq!(cv.seeds, vec![seed, seed + 1]);
        if cv.chosen == Some(1) {
            let row = &cv.rows[1];
            let t = -row.difference_mm.unwrap() / row.difference_se_mm.unwrap();
            assert!(
                t >= SIGNIFICANT_T,
                "offsets taken without significance: {cv:#?}"
            );
        } else {
            assert_eq!(cv.chosen, Some(0), "offsets truth, seed {seed}: {cv:#?}");
        }
        for (i, row) in cv.rows.iter().enumerate() {
            assert_eq!(row.difference_se_mm.is_none(), i == 0, "{cv:#?}");
        }
        let geometry = perturbed(&nominal, 0.005, 300 + seed);
        let data = measure(&tree, &geometry, 30, 5e-5, 400 + seed);
        for (list, reference) in [(&list, 0), (&reversed, 1)] {
            let cv = cross_validate(&input, list, &data, 4, 2, seed).unwrap();
            assert_eq!(
                cv.chosen,
                Some(reference),
                "geometric truth, seed {seed}: {cv:#?}"
            );
            let g = cv.rows[reference].choice_rms_mm.unwrap();
            let o = cv.rows[1 - reference].choice_rms_mm.unwrap();
            assert!(o > 10.0 * g, "{cv:#?}");
            assert!(cv.reason.contains("is the reference"), "{}", cv.reason);
            assert!(
                cv.rows[1 - reference].difference_mm.unwrap() > 0.0,
                "{cv:#?}"
            );
        }
    }
}

/// The forward steps offer one joint's harmonics or backlash at a time: on the 7-DoF arm with
/// backlash on arm_4 only, the cross-validation's first step is `backlash(arm_4_joint)`; on
/// the same geometry without it, no joint term.
#[test]
fn forward_steps_choose_backlash_on_the_joint_that_has_it() {
    let tree = treecal::load_urdf(&repo().join("tests/data/second_robot_arm.urdf"))
        .unwrap()
        .tree;
    let tool = tree.link_id("arm_tool_link").unwrap();
    let branches = detect_branches(&tree, Some(&[tool])).unwrap();
    let nominal = McpcModel::from_tree(&tree, &branches).unwrap();
    let (options, plan, patterns) = (
        IdentificationOptions::default(),
        Plan::simultaneous(),
        ParameterPatterns::default(),
    );
    let input = CrossValidationInput {
        calibration: CalibrationInput {
            tree: &tree,
            branches: &branches,
            nominal: &nominal,
            flexibility: None,
            plan: &plan,
            options: &options,
            measurement_frame: MeasurementFrame::Base,
            diagnose_columns: true,
        },
        patterns: &patterns,
        joint_steps: 2,
        stiffness: None,
    };
    let list = vec![spec(ModelLevel::Geometry, false, false)];
    let rigid = perturbed(&nominal, 0.002, 51);
    let gravity = GravitySigns::new(&tree, &rigid).unwrap();
    let terms = JointErrorTerms {
        backlash: true,
        ..Default::default()
    };
    let mut truth = rigid.with_joint_errors(terms, Some(gravity)).unwrap();
    let names: Vec<String> = (0..truth.parameter_count())
        .map(|i| truth.parameter_name(&tree, i))
        .collect();
    let mut values = truth.parameters();
    let i = names
        .iter()
        .position(|n| n == "arm_4_joint backlash")
        .unwrap();
    values[i] = 0.004;
    truth.set_parameters(&values).unwrap();
    let data = measure(&tree, &truth, 40, 3e-5, 52);
    let cv = cross_validate(&input, &list, &data, 4, 1, 3).unwrap();
    // The first step is arm_4's backlash: the lowest of the one-joint extensions (a second
    // step may add another joint's term on noise: seed 3 adds arm_2's backlash).
    let chosen = &cv.rows[cv.chosen.unwrap()];
    assert!(chosen.model.contains("arm_4_joint"), "{cv:#?}");
    let single = |r: &&treecal::workflow::CvRow| r.model.matches("arm_").count() == 1;
    let first = cv
        .rows
        .iter()
        .filter(single)
        .min_by(|a, b| {
            a.choice_rms_mm
                .unwrap()
                .total_cmp(&b.choice_rms_mm.unwrap())
        })
        .unwrap();
    assert_eq!(first.model, "geometry+backlash(arm_4_joint)", "{cv:#?}");
    assert!(cv.rows[0].choice_rms_mm.unwrap() > 3.0 * first.choice_rms_mm.unwrap());
    let data = measure(&tree, &rigid, 40, 3e-5, 52);
    let cv = cross_validate(&input, &list, &data, 4, 1, 3).unwrap();
    assert_eq!(cv.rows[cv.chosen.unwrap()].model, "geometry", "{cv:#?}");
}

/// `--joint-errors harmonics` writes joint_errors.yaml and says the URDF lacks it; a pattern
/// that matches no parameter is an error naming it.
#[test]
fn calibrate_writes_joint_errors_and_refuses_unknown_patterns() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let csv = robot("robonaut/example/measurements.csv");
    let run = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--joint-errors",
        "harmonics",
        "--stiffness",
        path_str(&robot("robonaut/stiffness.yaml")),
        "--freeze",
        "* cosine",
        "--out",
        path_str(&out),
    ]);
    assert_success(&run, "calibrate --joint-errors harmonics");
    assert!(run.stderr.contains("joint_errors.yaml"), "{}", run.stderr);
    let yaml = std::fs::read_to_string(out.join("joint_errors.yaml")).unwrap();
    assert!(yaml.contains("sine:") && yaml.contains("cosine:"), "{yaml}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["model"]["name"], "geometry+harmonics+compensated");
    let frozen = report["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["name"].as_str().unwrap().ends_with("cosine"))
        .all(|p| p["change"].as_f64() == Some(0.0));
    assert!(frozen, "a frozen cosine term moved");
    let wrong = treecal(&[
        "calibrate",
        "--measurements",
        path_str(&csv),
        "--freeze",
        "no_such_joint *",
        "--out",
        path_str(&dir.path().join("wrong")),
    ]);
    assert_error(
        &wrong,
        &["no_such_joint *", "matches no parameter"],
        "bad pattern",
    );
}

/// The default model (`adaptive`): data at the declared noise keep the full geometry; the same
/// data with a noise declared 30× too small (σ̂ ≈ 30: what model error looks like) are
/// calibrated with the cross-validation's choice, which a note explains; a model asked for by
/// flags is kept.
#[test]
fn the_default_model_follows_cross_validation_only_under_model_error() {
    let (tree, _, nominal) = humanoid();
    let truth = perturbed(&nominal, 0.002, 31);
    let data = measure(&tree, &truth, 24, 5e-5, 32);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("measurements.csv");
    let text = treecal::io::measurements_to_csv(&tree, &nominal, &data).unwrap();
    std::fs::write(&path, text).unwrap();
    let config = |sigma: f64, prior: bool| treecal::workflow::CalibrateConfig {
        robot: treecal::workflow::RobotSource::File(robot("humanoid/humanoid.urdf")),
        measurements: treecal::workflow::MeasurementSource::Csv(path.clone()),
        measurement_frame: treecal::workflow::MeasurementFrameChoice::Base,
        position_sigma: sigma,
        rotation_sigma: sigma,
        prior,
        cv: Some(2),
        ..Default::default()
    };
    let explained = |result: &treecal::workflow::Calibration| {
        result
            .notes
            .iter()
            .any(|n| n.text.contains("model error") && n.text.contains("cross-validation"))
    };
    let clean = treecal::workflow::calibrate(&config(5e-5, false)).unwrap();
    assert_eq!(clean.report()["model"]["name"], "geometry");
    assert!(!explained(&clean));
    let error = treecal::workflow::calibrate(&config(5e-5 / 30.0, false)).unwrap();
    let error_report = error.report();
    let choice = &error_report["model_choice"];
    let chosen = choice["chosen"].as_u64().unwrap() as usize;
    assert_eq!(
        error_report["model"]["name"],
        choice["rows"][chosen]["model"]
    );
    assert!(explained(&error), "{:#?}", error.notes);
    let asked = treecal::workflow::calibrate(&config(5e-5 / 30.0, true)).unwrap();
    assert_eq!(asked.report()["model"]["name"], "geometry+prior");
    assert!(!explained(&asked));
}

/// The noise model from the data: with rotation noise ten times smaller than the declared
/// ratio says, the variance components find the true ratio (within 20 %) and the refit weighs
/// the rotation rows by it; with the declared ratio right, the estimate stays at it. The
/// degrees of freedom of the two kinds add up to the rows less the rank.
#[test]
fn variance_components_recover_the_noise_ratio() {
    let (tree, branches, nominal) = humanoid();
    let truth = perturbed(&nominal, 0.005, 21);
    let plan = Plan::simultaneous();
    let declared = IdentificationOptions {
        position_sigma: 1e-4,
        rotation_sigma: 1e-3,
        ..Default::default()
    };
    let input = CalibrationInput {
        tree: &tree,
        branches: &branches,
        nominal: &nominal,
        flexibility: None,
        plan: &plan,
        options: &declared,
        measurement_frame: MeasurementFrame::Base,
        diagnose_columns: true,
    };
    for (true_rotation, seed) in [(1e-4, 22), (1e-3, 23)] {
        let data = measure_with_noise(&tree, &truth, 40, [1e-4, true_rotation], seed);
        let (run, options, noise) = fit_noise(&input, &data, &[]).unwrap();
        let noise = noise.expect("poses have two row kinds");
        let ratio = noise.rotation_sigma / true_rotation;
        assert!((0.8..1.25).contains(&ratio), "{noise:#?}");
        assert_eq!(options.rotation_sigma, noise.rotation_sigma);
        assert!(noise.converged && noise.rounds <= 3, "{noise:#?}");
        let identification = &run.report.stages[0].identification;
        let dof: f64 = noise.last.iter().map(|c| c.redundancy).sum();
        let expected = (identification.rows - identification.rank) as f64;
        assert!((dof - expected).abs() < 1e-6, "{dof} vs {expected}");
        // Settled: both kinds' residuals at the same multiple of their σ.
        let [a, b] = [noise.last[0].scale, noise.last[1].scale];
        assert!((a / b - 1.0).abs() < 0.05, "{a} vs {b}");
        if true_rotation == 1e-3 {
            assert!((noise.ratio_change() - 1.0).abs() < 0.2, "{noise:#?}");
        } else {
            // Declared 10× too large: the first fit's estimate says so (within 50 %: the
            // wrong weights let the rotation rows absorb more), the refits settle it.
            let first = noise.first[1].estimated_sigma() / noise.first[0].estimated_sigma();
            assert!((0.5..1.5).contains(&first), "{noise:#?}");
        }
    }
}
