//! Identification: simulated round trips, rank-deficient data, position-only data.

use crate::common::*;
use rand::RngExt;
use treecal::calibration::{identify, IdentificationOptions, Rigid, Termination};
use treecal::kinematics::McpcModel;
use treecal::measurement::{Measurement, Observation};
use treecal::tree::{detect_branches, KinematicTree};

/// Paper section 5.2: ±0.05 rad on angles.
pub const ANGLE_ERROR: f64 = 0.05;
/// Paper section 5.2: ±5 cm on lengths.
pub const LENGTH_ERROR: f64 = 0.05;

/// The paper's section 5.2 errors: every angle parameter off by up to ±0.05 rad, every length
/// by up to ±5 cm.
pub fn perturbed(model: &McpcModel, seed: u64) -> McpcModel {
    let mut rng = rng(seed);
    let layout = model.parameter_layout();
    let values: Vec<f64> = model
        .parameters()
        .iter()
        .zip(&layout)
        .map(|(v, (_, kind))| {
            let range = if kind.is_angle() {
                ANGLE_ERROR
            } else {
                LENGTH_ERROR
            };
            v + rng.random_range(-range..range)
        })
        .collect();
    let mut truth = model.clone();
    truth.set_parameters(&values).unwrap();
    truth
}

/// Full-pose measurements of every tool at `count` random configurations, noise-free.
pub fn measure(
    tree: &KinematicTree,
    truth: &McpcModel,
    count: usize,
    seed: u64,
    position_only: bool,
) -> Vec<Measurement> {
    let mut rng = rng(seed);
    let mut measurements = Vec::new();
    for _ in 0..count {
        let q = random_configuration(tree, &mut rng);
        for (tool, pose) in truth.tool_poses(&q).into_iter().enumerate() {
            let observation = if position_only {
                Observation::Position(pose.translation.vector)
            } else {
                Observation::Pose(pose)
            };
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation,
                stage: None,
                session: None,
            });
        }
    }
    measurements
}

fn all(model: &McpcModel) -> Vec<usize> {
    (0..model.parameter_count()).collect()
}

#[test]
fn noise_free_round_trip_recovers_every_parameter() {
    let (tree, nominal) = robonaut_model();
    for seed in 0..5 {
        let truth = perturbed(&nominal, seed);
        let measurements = measure(&tree, &truth, 20, 100 + seed, false);
        let report = identify(
            &nominal,
            &measurements,
            None,
            &Rigid,
            &all(&nominal),
            &IdentificationOptions::default(),
        )
        .unwrap();
        assert_eq!(report.rank, 64, "seed {seed}: {:?}", report.singular_values);
        assert!(report.unidentifiable.is_empty());
        assert!(
            report.iterations <= 6,
            "seed {seed}: {} iterations, costs {:?}",
            report.iterations,
            report.costs
        );
        for (index, (got, want)) in report.parameters.iter().zip(truth.parameters()).enumerate() {
            assert!(
                (got - want).abs() < 1e-8,
                "seed {seed}: parameter {index}: {got} vs {want}"
            );
        }
        assert!(report.residual_rms_position < 1e-9 && report.residual_rms_rotation < 1e-9);
        eprintln!(
            "seed {seed}: {} iterations, {:?}, condition {:.3e}",
            report.iterations, report.termination, report.condition_number
        );
    }
}

/// Too few configurations: the rank is reported below the parameter count, the missing
/// combinations are listed, and the parameters off the identifiable subspace stay nominal.
#[test]
fn too_few_configurations_report_unidentifiable_combinations() {
    let (tree, nominal) = robonaut_model();
    let truth = perturbed(&nominal, 1);
    let measurements = measure(&tree, &truth, 4, 7, false); // 8 poses · 6 rows = 48 < 64
    let report = identify(
        &nominal,
        &measurements,
        None,
        &Rigid,
        &all(&nominal),
        &IdentificationOptions::default(),
    )
    .unwrap();
    assert!(report.rank <= 48, "rank {}", report.rank);
    assert_eq!(report.unidentifiable.len(), 64 - report.rank);
    // The data are still fitted exactly: the model explains what was measured.
    assert!(
        report.residual_rms_position < 1e-8,
        "{}",
        report.residual_rms_position
    );
    assert!(report.parameters.iter().all(|p| p.is_finite()));
}

/// A single target per tool: the tool's orientation parameters cannot all be determined; the
/// rank analysis says so (three combinations per tool) and the fit is still exact.
#[test]
fn position_only_data_lose_the_tool_orientation() {
    let (tree, nominal) = robonaut_model();
    let truth = perturbed(&nominal, 2);
    let measurements = measure(&tree, &truth, 40, 8, true);
    let report = identify(
        &nominal,
        &measurements,
        None,
        &Rigid,
        &all(&nominal),
        &IdentificationOptions::default(),
    )
    .unwrap();
    eprintln!(
        "position only: {:?} after {} iterations, costs {:?}, rank {}",
        report.termination, report.iterations, report.costs, report.rank
    );
    assert_eq!(
        report.rank,
        64 - 6,
        "singular values {:?}",
        report.singular_values
    );
    assert_eq!(report.unidentifiable.len(), 6);
    let tool_start = nominal.tool_parameter_offset(0);
    for combination in &report.unidentifiable {
        let words = combination.describe(&nominal, &tree);
        assert!(words.contains("_tool "), "{words}");
        // Every missing direction involves tool parameters.
        assert!(
            combination.terms.iter().any(|(p, _)| *p >= tool_start),
            "{combination:?}"
        );
    }
    assert!(
        report.residual_rms_position < 1e-9,
        "{}",
        report.residual_rms_position
    );
    // Tool points are predicted exactly at new configurations.
    let mut identified = nominal.clone();
    identified.set_parameters(&report.parameters).unwrap();
    let mut rng = rng(99);
    for _ in 0..10 {
        let q = random_configuration(&tree, &mut rng);
        for (a, b) in identified.tool_poses(&q).iter().zip(truth.tool_poses(&q)) {
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-8);
        }
    }
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let (tree, nominal) = robonaut_model();
    let mut measurements = measure(&tree, &nominal, 2, 1, false);
    let options = IdentificationOptions::default();
    assert!(identify(&nominal, &[], None, &Rigid, &all(&nominal), &options).is_err());
    assert!(identify(&nominal, &measurements, None, &Rigid, &[999], &options).is_err());
    measurements[0].tool = 7;
    assert!(identify(
        &nominal,
        &measurements,
        None,
        &Rigid,
        &all(&nominal),
        &options
    )
    .is_err());
    measurements[0].tool = 0;
    measurements[0].q[0] = f64::NAN;
    let message = identify(
        &nominal,
        &measurements,
        None,
        &Rigid,
        &all(&nominal),
        &options,
    )
    .unwrap_err()
    .to_string();
    assert!(message.contains("non-finite"), "{message}");
}

/// Starting at the truth, nothing moves and the outcome says why it stopped.
#[test]
fn starting_at_the_solution_terminates_immediately() {
    let (tree, nominal) = robonaut_model();
    let measurements = measure(&tree, &nominal, 20, 3, false);
    let report = identify(
        &nominal,
        &measurements,
        None,
        &Rigid,
        &all(&nominal),
        &IdentificationOptions::default(),
    )
    .unwrap();
    assert!(report.iterations <= 1);
    assert_ne!(report.termination, Termination::MaxIterations);
}

/// Stage-1 configurations: the torso joints random, every other joint at one of `locks`
/// random lock configurations (drawn first), in turn.
fn torso_configurations(
    tree: &KinematicTree,
    count: usize,
    locks: usize,
    rng: &mut rand::rngs::ChaCha8Rng,
) -> Vec<Vec<f64>> {
    let torso_dofs = detect_branches(tree, None).unwrap().coupled.dofs(tree);
    let locked: Vec<Vec<f64>> = (0..locks)
        .map(|_| random_configuration(tree, rng))
        .collect();
    (0..count)
        .map(|index| {
            let mut q = locked[index % locks].clone();
            let free = random_configuration(tree, rng);
            for &d in &torso_dofs {
                q[d] = free[d];
            }
            q
        })
        .collect()
}

/// Stage-1 data: the torso moves, each arm stays locked at one of `locks` configurations.
fn torso_measurements(
    tree: &KinematicTree,
    truth: &McpcModel,
    count: usize,
    locks: usize,
    seed: u64,
) -> Vec<Measurement> {
    let mut measurements = Vec::new();
    for q in torso_configurations(tree, count, locks, &mut rng(seed)) {
        for (tool, pose) in truth.tool_poses(&q).into_iter().enumerate() {
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: Observation::Pose(pose),
                stage: Some("torso".into()),
                session: None,
            });
        }
    }
    measurements
}

/// The paper's staging (torso with arms locked, then the arms) and the simultaneous plan give
/// the same parameters on noise-free data: the truth.
#[test]
fn staged_and_simultaneous_plans_agree() {
    use treecal::calibration::{calibrate, Compensation, Plan};
    let (tree, nominal) = robonaut_model();
    let branches = detect_branches(&tree, None).unwrap();
    let truth = perturbed(&nominal, 4);
    let mut measurements = torso_measurements(&tree, &truth, 12, 2, 40);
    for mut m in measure(&tree, &truth, 20, 41, false) {
        m.stage = Some("arms".into());
        measurements.push(m);
    }
    let options = IdentificationOptions::default();
    let staged = calibrate(
        &branches,
        &nominal,
        &measurements,
        Compensation::None,
        &Plan::staged(),
        &options,
    )
    .unwrap();
    let simultaneous = calibrate(
        &branches,
        &nominal,
        &measurements,
        Compensation::None,
        &Plan::simultaneous(),
        &options,
    )
    .unwrap();
    assert_eq!(staged.stages.len(), 2);
    assert!(staged.notes.is_empty(), "{:?}", staged.notes);
    assert_eq!(staged.stages[0].locked_tools, 4, "two locks × two arms");
    let torso = &staged.stages[0].identification;
    assert_eq!(
        torso.rank,
        8 + 4 * 6,
        "torso + locked tools: {:?}",
        torso.singular_values
    );
    for stage in &staged.stages {
        assert!(
            stage.identification.iterations <= 6,
            "{}: {}",
            stage.name,
            stage.identification.iterations
        );
    }
    let want = truth.parameters();
    for (index, ((a, b), w)) in staged
        .model
        .parameters()
        .iter()
        .zip(simultaneous.model.parameters())
        .zip(&want)
        .enumerate()
    {
        assert!((a - w).abs() < 1e-8, "staged parameter {index}: {a} vs {w}");
        assert!(
            (b - w).abs() < 1e-8,
            "simultaneous parameter {index}: {b} vs {w}"
        );
    }
}

#[test]
fn a_stage_without_its_measurements_is_an_error() {
    use treecal::calibration::{calibrate, Compensation, Plan};
    let (tree, nominal) = robonaut_model();
    let branches = detect_branches(&tree, None).unwrap();
    let measurements = measure(&tree, &nominal, 5, 1, false);
    let message = calibrate(
        &branches,
        &nominal,
        &measurements,
        Compensation::None,
        &Plan::staged(),
        &IdentificationOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        message.contains("stage 'torso'") && message.contains("labelled 'torso'"),
        "{message}"
    );
}

/// A tracker far from the base and three-target tool frames hundreds of millimetres and tens
/// of degrees from the URDF tool links: the closed-form initial guess brings the solver close
/// enough to converge to the truth.
#[test]
fn initial_guess_recovers_a_distant_measurement_frame_and_tool_frames() {
    use treecal::calibration::initial_guess;
    use treecal::kinematics::McpcTool;
    use treecal::math::{pose, rotation_from_rpy, Vec3};
    let (tree, nominal) = robonaut_model();
    let perturbed_model = perturbed(&nominal, 6);
    // Tool frames like the paper's Table 2 tool rows (three-target frames).
    let offsets = [
        pose(
            Vec3::new(-0.0756, -0.0702, 0.2559),
            rotation_from_rpy(0.3, -0.5, 0.7),
        ),
        pose(
            Vec3::new(-0.2803, -0.1098, 0.1647),
            rotation_from_rpy(-0.87, 0.72, 0.69),
        ),
    ];
    let tools: Vec<McpcTool> = perturbed_model
        .tools()
        .iter()
        .zip(&offsets)
        .map(|(t, offset)| {
            let twist = t.parent.map_or(0.0, |f| perturbed_model.frames()[f].twist);
            McpcTool::from_relative_pose(
                t.link,
                t.parent,
                twist,
                &(t.constant_transform() * offset),
            )
        })
        .collect();
    let mut truth = McpcModel::new(perturbed_model.frames().to_vec(), tools).unwrap();
    let world_from_base = pose(Vec3::new(2.5, -1.2, 0.4), rotation_from_rpy(0.1, -0.2, 2.4));
    truth.set_world_from_base(&world_from_base);
    let measurements = measure(&tree, &truth, 20, 60, false);

    let without = identify(
        &nominal,
        &measurements,
        None,
        &Rigid,
        &all(&nominal),
        &IdentificationOptions::default(),
    )
    .unwrap();
    eprintln!(
        "without the initial guess: {:?} after {} iterations, position rms {:.3e} m",
        without.termination, without.iterations, without.residual_rms_position
    );
    let guess = initial_guess(&nominal, &measurements, 3).unwrap();
    assert!(
        guess.rms_before > 1.0,
        "the raw model is metres off: {}",
        guess.rms_before
    );
    // After the guess, what is left is about the size of the geometric errors themselves
    // (±5 cm, ±0.05 rad): compare with the nominal model against the same truth seen from the
    // base with the URDF tool frames.
    let geometric: f64 = {
        let plain_truth = perturbed(&nominal, 6);
        let mut rng = rng(60);
        let mut sum = 0.0;
        let mut count = 0.0;
        for _ in 0..20 {
            let q = random_configuration(&tree, &mut rng);
            for (a, b) in nominal
                .tool_poses(&q)
                .iter()
                .zip(plain_truth.tool_poses(&q))
            {
                sum += (a.translation.vector - b.translation.vector).norm_squared();
                count += 1.0;
            }
        }
        (sum / count).sqrt()
    };
    assert!(
        guess.rms_after < 1.5 * geometric,
        "the guess leaves {} m, the geometric errors alone {} m",
        guess.rms_after,
        geometric
    );
    let report = identify(
        &guess.model,
        &measurements,
        None,
        &Rigid,
        &all(&nominal),
        &IdentificationOptions::default(),
    )
    .unwrap();
    assert_eq!(report.rank, 64);
    let mut identified = guess.model.clone();
    identified.set_parameters(&report.parameters).unwrap();
    let mut rng = rng(61);
    for _ in 0..20 {
        let q = random_configuration(&tree, &mut rng);
        for (a, b) in identified.tool_poses(&q).iter().zip(truth.tool_poses(&q)) {
            assert_pose_eq(a, &b, 1e-8, "validation pose");
        }
    }
    eprintln!(
        "initial guess: {:.3} m → {:.4} m (geometric errors alone: {geometric:.4} m); then {} iterations",
        guess.rms_before, guess.rms_after, report.iterations
    );
}

#[test]
fn rigid_fit_needs_three_points_off_a_line() {
    use treecal::calibration::fit_rigid_transform;
    use treecal::math::Vec3;
    let line = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(2.0, 0.0, 0.0),
    ];
    assert!(fit_rigid_transform(&line, &line).is_none());
    assert!(fit_rigid_transform(&line[..2], &line[..2]).is_none());
}

// ---------------------------------------------------------------------------------------------
// Flexibility in the truth and in the model (paper section 3 and eq. (26))

fn robonaut_flexibility(
    tree: &KinematicTree,
    model: &McpcModel,
) -> treecal::kinematics::FlexibilityModel {
    let stiffness =
        treecal::io::read_stiffness(&robot("robonaut/stiffness.yaml"), tree, model).unwrap();
    treecal::kinematics::FlexibilityModel::new(tree, model, &stiffness).unwrap()
}

/// Measurements of the deflected truth (joint and link compliance, 20 kg payloads).
fn measure_deflected(
    tree: &KinematicTree,
    truth: &McpcModel,
    flexibility: &treecal::kinematics::FlexibilityModel,
    configurations: &[Vec<f64>],
    stage: Option<&str>,
) -> Vec<Measurement> {
    let mut measurements = Vec::new();
    for q in configurations {
        for (tool, pose) in flexibility
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
                stage: stage.map(String::from),
                session: None,
            });
        }
    }
    measurements
}

/// With the deflections in the truth and the exact compensation in the model, every parameter
/// is recovered to 1e-8, staged and simultaneous alike; ignoring flexibility cannot.
#[test]
fn noise_free_round_trip_with_flexibility() {
    use treecal::calibration::{calibrate, Compensation, Deflected, Plan};
    let (tree, nominal) = robonaut_model();
    let branches = detect_branches(&tree, None).unwrap();
    let flexibility = robonaut_flexibility(&tree, &nominal);
    let source = Deflected {
        tree: &tree,
        flexibility: &flexibility,
    };
    let truth = perturbed(&nominal, 8);
    let mut draw = rng(80);
    let arms: Vec<Vec<f64>> = (0..20)
        .map(|_| random_configuration(&tree, &mut draw))
        .collect();
    let torso = torso_configurations(&tree, 12, 2, &mut draw);
    let mut measurements = measure_deflected(&tree, &truth, &flexibility, &torso, Some("torso"));
    measurements.extend(measure_deflected(
        &tree,
        &truth,
        &flexibility,
        &arms,
        Some("arms"),
    ));
    let options = IdentificationOptions::default();
    let want = truth.parameters();
    for plan in [Plan::simultaneous(), Plan::staged()] {
        let report = calibrate(
            &branches,
            &nominal,
            &measurements,
            Compensation::Exact(source),
            &plan,
            &options,
        )
        .unwrap();
        eprintln!("{}: {} cycle(s)", plan.stages[0].name, report.cycles);
        for stage in &report.stages {
            eprintln!(
                "  {}: {:?} after {} iterations",
                stage.name, stage.identification.termination, stage.identification.iterations
            );
            assert!(
                stage.identification.iterations <= 6,
                "{}: {} iterations",
                stage.name,
                stage.identification.iterations
            );
        }
        for (index, (got, w)) in report.model.parameters().iter().zip(&want).enumerate() {
            assert!(
                (got - w).abs() < 1e-8,
                "{:?}: parameter {index}: {got} vs {w}",
                plan.stages[0].name
            );
        }
    }
    // The paper's linear subtraction (eq. (26)) gets close, ignoring flexibility does not.
    let error_of = |compensation| {
        let report = calibrate(
            &branches,
            &nominal,
            &measurements,
            compensation,
            &Plan::simultaneous(),
            &options,
        )
        .unwrap();
        let mut rng = rng(81);
        let mut worst: f64 = 0.0;
        for _ in 0..20 {
            let q = random_configuration(&tree, &mut rng);
            let expected = flexibility.deflected_tool_poses(&tree, &truth, &q).unwrap();
            let predicted = flexibility
                .deflected_tool_poses(&tree, &report.model, &q)
                .unwrap();
            for (a, b) in expected.iter().zip(&predicted) {
                worst = worst.max((a.translation.vector - b.translation.vector).norm());
            }
        }
        worst
    };
    let linear = error_of(Compensation::Linear(source));
    let none = error_of(Compensation::None);
    eprintln!("validation position error: linear eq. (26) {linear:.3e} m, without compensation {none:.3e} m");
    assert!(linear < 0.5 * none, "linear {linear} vs none {none}");
}

/// A robot with no movable torso joint (Robonaut with its torso joints made fixed): the staged
/// plan skips its torso stage and says so (an `empty-torso` note that counts the unused torso
/// rows, passed on to the calibration's findings), and its result is exactly that of the arms
/// stage alone. (Robonaut with its torso gets no note: `staged_and_simultaneous_plans_agree`.)
#[test]
fn staged_plan_on_an_empty_torso_skips_the_torso_stage() {
    use treecal::calibration::{calibrate, Compensation, ParameterSet, Plan, Stage};
    let mut text = std::fs::read_to_string(robot("robonaut/robonaut.urdf")).unwrap();
    for joint in ["torso_joint1", "torso_joint2"] {
        let revolute = format!("<joint name=\"{joint}\" type=\"revolute\">");
        assert!(text.contains(&revolute));
        text = text.replace(
            &revolute,
            &format!("<joint name=\"{joint}\" type=\"fixed\">"),
        );
    }
    let tree = treecal::parse_urdf(&text, "no torso").unwrap().tree;
    let branches = detect_branches(&tree, None).unwrap();
    assert!(branches.coupled.dofs(&tree).is_empty());
    let nominal = McpcModel::from_tree(&tree, &branches).unwrap();
    let truth = perturbed(&nominal, 5);
    let mut measurements = torso_measurements(&tree, &truth, 6, 2, 42);
    let torso_rows = measurements.len();
    for mut m in measure(&tree, &truth, 20, 43, false) {
        m.stage = Some("arms".into());
        measurements.push(m);
    }
    let options = IdentificationOptions::default();
    let run = |plan: &Plan| {
        calibrate(
            &branches,
            &nominal,
            &measurements,
            Compensation::None,
            plan,
            &options,
        )
        .unwrap()
    };
    let staged = run(&Plan::staged());
    let arms_only = run(&Plan {
        stages: vec![Stage {
            name: "arms".into(),
            parameters: ParameterSet::Arms,
            measurements: Some("arms".into()),
        }],
    });
    assert_eq!(staged.stages.len(), 1);
    assert_eq!(staged.stages[0].name, "arms");
    assert_eq!(staged.model.parameters(), arms_only.model.parameters());
    assert_eq!(staged.notes.len(), 1, "{:?}", staged.notes);
    let note = &staged.notes[0];
    assert_eq!(note.code, "empty-torso");
    assert_eq!(note.status, treecal::calibration::Status::Ok);
    assert!(
        note.message.contains("torso stage 'torso' is skipped")
            && note
                .message
                .contains(&format!("its {torso_rows} measurements are not used")),
        "{}",
        note.message
    );
    assert!(arms_only.notes.is_empty());
    // Without torso rows at all the staged plan runs too (before, the torso stage demanded them).
    let arms_rows: Vec<_> = measurements[torso_rows..].to_vec();
    let staged = calibrate(
        &branches,
        &nominal,
        &arms_rows,
        Compensation::None,
        &Plan::staged(),
        &options,
    )
    .unwrap();
    assert_eq!(staged.model.parameters(), arms_only.model.parameters());
    assert!(!staged.notes[0].message.contains("not used"));
}
