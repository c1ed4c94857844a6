//! The paper's section 5.2 simulation: a true robot with random parameter errors and gravity
//! deflections, measured by a noisy laser tracker, calibrated without and with flexibility
//! compensation, and judged on the identification and on separate validation configurations.

use super::blunders::inject_blunders;
use super::collision::CollisionChecker;
use super::noise::{observe, NoiseModel, Targets};
use super::planning::{plan_poses, PlanningOptions, PlanningStage};
use super::sampling::{sample_configurations, SamplingOptions};
use super::truth::{true_model, with_joint_errors, ErrorRanges, JointErrorRanges};
use crate::calibration::{
    calibrate_robust, CalibrationReport, Compensation, Deflected, IdentificationOptions,
    ParameterSet, Plan, RobustLoss, RobustReport,
};
use crate::calibration::{calibrate_with_stiffness, Fitted, StiffnessOptions};
use crate::error::Result;
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::math::Pose;
use crate::measurement::Measurement;
use crate::measurement::TARGET_SPACING;
use crate::tree::{Branches, KinematicTree};
use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

use super::trial_report::truth_joint_errors;
pub use super::trial_report::{
    ArmErrors, BlunderReport, ErrorStats, RunSummary, StageSummary, TrialReport, TruthJointError,
};

/// Settings of one simulated calibration.
#[derive(Debug, Clone)]
pub struct SimulationOptions {
    /// Configurations measured for the arms (the paper uses 20).
    pub poses: usize,
    /// Configurations measured for the torso with the arms locked (staged plan).
    pub torso_poses: usize,
    /// How many locked arm configurations the torso configurations use.
    pub locks: usize,
    /// Separate configurations the results are validated on.
    pub validation_poses: usize,
    /// Parameter errors of the true robot.
    pub errors: ErrorRanges,
    /// Joint-angle errors of the true robot beyond its geometry (harmonics, backlash); the
    /// calibrations do not model them.
    pub joint_errors: JointErrorRanges,
    /// Tracker noise.
    pub noise: NoiseModel,
    /// Targets per tool.
    pub targets: Targets,
    /// The calibration plan.
    pub plan: Plan,
    /// The master seed; trial `k` uses a seed derived from it.
    pub seed: u64,
    /// `None`: identification configurations drawn at random. `Some`: planned in every trial
    /// with the nominal model (its `candidates`, `criterion` and `workspace` are used; poses,
    /// stage, targets, locks, seed and σ follow this simulation).
    pub planning: Option<PlanningOptions>,
    /// `Some`: identify the compliances jointly with the geometry in the compensated
    /// calibration, from the model's flexibility as the prior.
    pub identify_stiffness: Option<StiffnessOptions>,
    /// The robust loss of both calibrations.
    pub robust: RobustLoss,
    /// Fraction of the measurements turned into blunders ([`inject_blunders`]).
    pub outliers: f64,
    /// How far a blunder moves its target (m).
    pub outlier_size: f64,
    /// Payloads (kg at every tool) the identification configurations are measured at, in
    /// turn (the rows split evenly, each row carrying its payload); empty: the stiffness
    /// file's payloads.
    pub payloads: Vec<f64>,
}

impl Default for SimulationOptions {
    fn default() -> Self {
        Self {
            poses: 20,
            torso_poses: 10,
            locks: 2,
            validation_poses: 20,
            errors: ErrorRanges::default(),
            joint_errors: JointErrorRanges::default(),
            noise: NoiseModel::at901(),
            targets: Targets::Three,
            plan: Plan::staged(),
            seed: 0,
            planning: None,
            identify_stiffness: None,
            robust: RobustLoss::default(),
            outliers: 0.0,
            outlier_size: 0.05,
            payloads: Vec::new(),
        }
    }
}

/// Everything a trial needs that does not change between trials.
pub struct Setup<'a> {
    /// The robot.
    pub tree: &'a KinematicTree,
    /// Its branches.
    pub branches: &'a Branches,
    /// The nominal MCPC model.
    pub nominal: &'a McpcModel,
    /// The truth's flexibility.
    pub truth_flexibility: &'a FlexibilityModel,
    /// The flexibility the compensating calibration assumes.
    pub model_flexibility: &'a FlexibilityModel,
    /// Self-collision checks for sampling (none: every configuration within limits).
    pub checker: Option<&'a CollisionChecker>,
}

/// The seed of trial `trial`, independent of how trials are spread over threads.
pub fn trial_seed(master: u64, trial: usize) -> u64 {
    // SplitMix64 of (master, trial): well-mixed, version-stable.
    let mut z = master ^ (trial as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Runs trial `trial` of a simulation.
pub fn run_trial(
    setup: &Setup<'_>,
    options: &SimulationOptions,
    trial: usize,
) -> Result<TrialReport> {
    let seed = trial_seed(options.seed, trial);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let tree = setup.tree;
    let truth = true_model(setup.nominal, &options.errors, &mut rng)?;
    let truth = with_joint_errors(&truth, tree, &options.joint_errors, &mut rng)?;
    let sampling = SamplingOptions::default();

    let identification_options = identification_options(&options.noise, options.targets);
    let (torso_configurations, arm_configurations) = match &options.planning {
        None => random_configurations(setup, options, &mut rng)?,
        Some(planning) => {
            planned_configurations(setup, options, planning, &identification_options, &mut rng)?
        }
    };
    let validation = sample_configurations(
        tree,
        setup.checker,
        options.validation_poses,
        &mut rng,
        &sampling,
        &[],
    )?;

    // Measure the deflected truth.
    let mut measurements = Vec::new();
    let mut measured = 0;
    let mut measure =
        |configurations: &[Vec<f64>], stage: &str, rng: &mut ChaCha8Rng| -> Result<()> {
            for q in configurations {
                // The payloads in turn, so that every stage sees each of them.
                let payload = (!options.payloads.is_empty())
                    .then(|| options.payloads[measured % options.payloads.len()]);
                measured += 1;
                let poses = setup
                    .truth_flexibility
                    .for_payload(payload)?
                    .deflected_tool_poses(tree, &truth, q)?;
                for (tool, pose) in poses.iter().enumerate() {
                    measurements.push(Measurement {
                        payload,
                        tool,
                        q: q.clone(),
                        observation: observe(pose, options.targets, &options.noise, rng),
                        stage: Some(stage.into()),
                        session: None,
                    });
                }
            }
            Ok(())
        };
    measure(&torso_configurations, "torso", &mut rng)?;
    measure(&arm_configurations, "arms", &mut rng)?;
    let injected = inject_blunders(
        &mut measurements,
        options.outliers,
        options.outlier_size,
        seed,
    );
    finish_trial(
        setup,
        options,
        seed,
        &truth,
        measurements,
        &identification_options,
        &arm_configurations,
        &validation,
    )
    .map(|report| TrialReport {
        blunders: BlunderReport {
            injected,
            ..report.blunders
        },
        ..report
    })
}

/// Configurations of the torso stage, then of the arms stage.
type StageConfigurations = (Vec<Vec<f64>>, Vec<Vec<f64>>);

/// Torso configurations (the arms locked at a few random configurations) and arm
/// configurations, drawn at random.
fn random_configurations(
    setup: &Setup<'_>,
    options: &SimulationOptions,
    rng: &mut ChaCha8Rng,
) -> Result<StageConfigurations> {
    let tree = setup.tree;
    let sampling = SamplingOptions::default();
    // Torso configurations: arms locked at a few random configurations, the torso moving.
    let torso_dofs = setup.branches.coupled.dofs(tree);
    let locks = sample_configurations(
        tree,
        setup.checker,
        options.locks.max(1),
        rng,
        &sampling,
        &[],
    )?;
    let mut torso_configurations = Vec::with_capacity(options.torso_poses);
    for index in 0..options.torso_poses {
        let lock = &locks[index % locks.len()];
        let fixed: Vec<(usize, f64)> = (0..tree.dof_count())
            .filter(|d| !torso_dofs.contains(d))
            .map(|d| (d, lock[d]))
            .collect();
        torso_configurations.extend(sample_configurations(
            tree,
            setup.checker,
            1,
            rng,
            &sampling,
            &fixed,
        )?);
    }
    let arm_configurations =
        sample_configurations(tree, setup.checker, options.poses, rng, &sampling, &[])?;
    Ok((torso_configurations, arm_configurations))
}

/// Torso and arm configurations planned with the nominal model (sim/planning.rs): the torso set
/// for the torso stage with the arms locked, the arm set for the arms stage of a staged plan or
/// for all parameters otherwise.
fn planned_configurations(
    setup: &Setup<'_>,
    options: &SimulationOptions,
    planning: &PlanningOptions,
    identification: &IdentificationOptions,
    rng: &mut ChaCha8Rng,
) -> Result<StageConfigurations> {
    let staged = options
        .plan
        .stages
        .iter()
        .any(|s| s.parameters == ParameterSet::Coupled);
    let plan = |stage: PlanningStage, poses: usize, seed: u64| -> Result<Vec<Vec<f64>>> {
        if poses == 0 {
            return Ok(Vec::new());
        }
        let planning = PlanningOptions {
            poses,
            candidates: planning.candidates,
            stage,
            targets: options.targets,
            locks: options.locks.max(1),
            position_sigma: identification.position_sigma,
            rotation_sigma: identification.rotation_sigma,
            seed,
            ..planning.clone()
        };
        let report = plan_poses(
            setup.tree,
            setup.branches,
            setup.nominal,
            setup.checker,
            &planning,
            &|_| {},
        )?;
        Ok(report.poses.into_iter().map(|p| p.q).collect())
    };
    let torso = plan(PlanningStage::Torso, options.torso_poses, rng.random())?;
    let arms_stage = if staged {
        PlanningStage::Arms
    } else {
        PlanningStage::All
    };
    let arms = plan(arms_stage, options.poses, rng.random())?;
    Ok((torso, arms))
}

/// Calibrates from the measurements and judges the results.
#[allow(clippy::too_many_arguments)]
fn finish_trial(
    setup: &Setup<'_>,
    options: &SimulationOptions,
    seed: u64,
    truth: &McpcModel,
    measurements: Vec<Measurement>,
    identification_options: &IdentificationOptions,
    arm_configurations: &[Vec<f64>],
    validation: &[Vec<f64>],
) -> Result<TrialReport> {
    let tree = setup.tree;
    let identification_options = IdentificationOptions {
        robust: options.robust,
        ..identification_options.clone()
    };
    let (rigid, rigid_robust) = calibrate_robust(
        setup.branches,
        setup.nominal,
        &measurements,
        Compensation::None,
        &options.plan,
        &identification_options,
    )?;
    let compensated_with = |flexibility: Option<&FlexibilityModel>| {
        let compensation = match flexibility {
            Some(flexibility) => Compensation::Exact(Deflected { tree, flexibility }),
            None => Compensation::None,
        };
        calibrate_robust(
            setup.branches,
            setup.nominal,
            &measurements,
            compensation,
            &options.plan,
            &identification_options,
        )
    };
    // With stiffness identification, the errors are those of the calibration again with the
    // identified flexibility (`calibrate_with_stiffness`, as `calibrate` does).
    let (compensated, compensated_robust, identified) = match &options.identify_stiffness {
        Some(stiffness) => {
            let sequence = calibrate_with_stiffness(
                tree,
                setup.model_flexibility,
                Some(setup.model_flexibility),
                &identification_options,
                stiffness,
                compensated_with,
                |(report, robust): &(CalibrationReport, RobustReport)| Fitted {
                    model: report.model.clone(),
                    measurements: measurements.clone(),
                    outliers: robust.outliers(),
                },
            )?;
            let (first, first_robust) = sequence.first;
            let (again, _) = sequence.again;
            (first, first_robust, Some((again.model, sequence.stiffness)))
        }
        None => {
            let (first, first_robust) = compensated_with(Some(setup.model_flexibility))?;
            (first, first_robust, None)
        }
    };
    let blunders = BlunderReport {
        injected: Vec::new(),
        named: [rigid_robust.outliers(), compensated_robust.outliers()],
    };
    let (compensated_model, compensated_flexibility) = match &identified {
        Some((model, report)) => (model, &report.flexibility),
        None => (&compensated.model, setup.model_flexibility),
    };
    let errors = |configurations: &[Vec<f64>]| -> Result<Vec<ArmErrors>> {
        arm_errors(
            setup,
            truth,
            &rigid.model,
            (compensated_model, compensated_flexibility),
            configurations,
        )
    };
    let noise_floor_position_mm = noise_floor(
        compensated_model,
        &measurements,
        &identification_options,
        &options.noise,
        validation,
    );
    Ok(TrialReport {
        seed,
        identification: errors(arm_configurations)?,
        validation: errors(validation)?,
        noise_floor_position_mm,
        rigid_run: summary(&rigid),
        compensated_run: summary(&compensated),
        stiffness: identified.map(|(_, r)| r.estimates),
        blunders,
        truth_joint_errors: truth_joint_errors(tree, truth),
        measurements,
        notes: compensated
            .notes
            .iter()
            .map(|n| n.message.clone())
            .collect(),
    })
}

/// Row weights that match the tracker: σ at a typical distance for positions, and the
/// orientation noise of a three-target frame (`√2·σ / spacing`).
fn identification_options(noise: &NoiseModel, targets: Targets) -> IdentificationOptions {
    let mut options = IdentificationOptions::default();
    if !noise.is_none() {
        // σ at the base, about where the tools are.
        let sigma = noise.sigma(&crate::math::Vec3::zeros());
        options.position_sigma = sigma;
        options.rotation_sigma = match targets {
            Targets::Three => std::f64::consts::SQRT_2 * sigma / TARGET_SPACING,
            Targets::One => options.rotation_sigma,
        };
    }
    options
}

fn summary(report: &CalibrationReport) -> RunSummary {
    RunSummary {
        cycles: report.cycles,
        stages: report
            .stages
            .iter()
            .map(|s| StageSummary {
                name: s.name.clone(),
                iterations: s.identification.iterations,
                termination: s.identification.termination,
                rank: s.identification.rank,
                parameters: s.identification.free.len(),
            })
            .collect(),
    }
}

fn arm_errors(
    setup: &Setup<'_>,
    truth: &McpcModel,
    rigid: &McpcModel,
    (compensated, flexibility): (&McpcModel, &FlexibilityModel),
    configurations: &[Vec<f64>],
) -> Result<Vec<ArmErrors>> {
    let tools = setup.nominal.tools().len();
    let mut position = vec![[Vec::new(), Vec::new(), Vec::new()]; tools];
    let mut orientation = vec![[Vec::new(), Vec::new(), Vec::new()]; tools];
    for q in configurations {
        let actual = setup
            .truth_flexibility
            .deflected_tool_poses(setup.tree, truth, q)?;
        let predictions: [Vec<Pose>; 3] = [
            setup.nominal.tool_poses(q),
            rigid.tool_poses(q),
            flexibility.deflected_tool_poses(setup.tree, compensated, q)?,
        ];
        for tool in 0..tools {
            for (k, predicted) in predictions.iter().enumerate() {
                let d = actual[tool].translation.vector - predicted[tool].translation.vector;
                position[tool][k].push(d.norm() * 1e3);
                orientation[tool][k].push(
                    actual[tool]
                        .rotation
                        .angle_to(&predicted[tool].rotation)
                        .to_degrees(),
                );
            }
        }
    }
    Ok((0..tools)
        .map(|tool| {
            let stats: Vec<ErrorStats> = (0..3)
                .map(|k| ErrorStats::of(&position[tool][k], &orientation[tool][k]))
                .collect();
            let removed = crate::calibration::removed_percent;
            let arm = setup.branches.arm_name(setup.nominal.tools()[tool].link);
            ArmErrors {
                arm,
                before: stats[0],
                rigid: stats[1],
                compensated: stats[2],
                position_removed_percent: [
                    removed(stats[0].mean_position_mm, stats[1].mean_position_mm),
                    removed(stats[0].mean_position_mm, stats[2].mean_position_mm),
                ],
                orientation_removed_percent: [
                    removed(stats[0].mean_orientation_deg, stats[1].mean_orientation_deg),
                    removed(stats[0].mean_orientation_deg, stats[2].mean_orientation_deg),
                ],
                position_mm: position[tool].clone(),
                orientation_deg: orientation[tool].clone(),
            }
        })
        .collect())
}

/// RMS position error at the validation poses that the measurement noise alone causes:
/// the parameter covariance σ²·(JᵀWJ)⁺ of the identification data, propagated through the
/// validation Jacobians (mm).
fn noise_floor(
    model: &McpcModel,
    measurements: &[Measurement],
    options: &IdentificationOptions,
    noise: &NoiseModel,
    validation: &[Vec<f64>],
) -> f64 {
    if noise.is_none() || validation.is_empty() {
        return 0.0;
    }
    let n = model.parameter_count();
    let mut information = DMatrix::<f64>::zeros(n, n);
    for m in measurements {
        let jacobian = &model.tool_jacobian(m.tool, &m.q).jacobian;
        for row in 0..m.observation.rows() {
            let sigma = if row < 3 {
                options.position_sigma
            } else {
                options.rotation_sigma
            };
            // In place (`information += rᵀ·r` allocated an n × n matrix per row): the same
            // products summed in the same order, so the same bits.
            let r = jacobian.row(row).transpose() / sigma;
            information.ger(1.0, &r, &r, 1.0);
        }
    }
    let tolerance = 1e-12 * information.norm();
    let covariance = match information.pseudo_inverse(tolerance) {
        Ok(c) => c,
        Err(_) => return f64::NAN,
    };
    let mut sum = 0.0;
    let mut count = 0.0;
    // `position_variance` skips the zero columns, which is exact only for finite entries.
    let finite = covariance.iter().all(|v| v.is_finite());
    for q in validation {
        for tool in model.tool_jacobians(q) {
            sum += if finite {
                position_variance(&tool.jacobian, &covariance)
            } else {
                let position = tool.jacobian.rows(0, 3);
                (position * &covariance * position.transpose()).trace()
            };
            count += 1.0;
        }
    }
    (sum / count).sqrt() * 1e3
}

/// `tr(P·C·Pᵀ)` for the position rows `P` (the first three) of `jacobian` and a finite
/// `covariance`: nalgebra's `(P * C * Pᵀ).trace()` bit for bit whenever it is not zero, at a
/// fraction of the cost. That product sums each entry term by term in index order (`gemv`
/// column by column for three rows), and so does this, over the columns where `P`'s row is
/// not zero: a zero term `0·c` (`c` finite) added to a sum changes at most the sign of a zero
/// sum, which the next non-zero term or the trace's non-zero total absorbs. Only the
/// diagonal of the 3 × 3 product is formed.
fn position_variance(jacobian: &DMatrix<f64>, covariance: &DMatrix<f64>) -> f64 {
    let n = covariance.nrows();
    let mut row_times_covariance = vec![0.0; n];
    let mut trace = 0.0;
    for i in 0..3 {
        let row: Vec<(usize, f64)> = (0..jacobian.ncols())
            .map(|k| (k, jacobian[(i, k)]))
            .filter(|&(_, p)| p != 0.0)
            .collect();
        // (P·C)[i, j] = Σ_k P[i, k]·C[k, j], k ascending; C's column j is contiguous.
        for (j, out) in row_times_covariance.iter_mut().enumerate() {
            let column = &covariance.as_slice()[j * n..(j + 1) * n];
            *out = row.iter().fold(0.0, |s, &(k, p)| s + p * column[k]);
        }
        // (P·C·Pᵀ)[i, i] = Σ_j (P·C)[i, j]·P[i, j], j ascending.
        let diagonal = row
            .iter()
            .fold(0.0, |s, &(j, p)| s + row_times_covariance[j] * p);
        trace += diagonal;
    }
    trace
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `position_variance` is nalgebra's `(P·C·Pᵀ).trace()` bit for bit, on seeded random
    /// Jacobians with zero columns (parameters off the tool's chain) and symmetric
    /// covariances.
    #[test]
    fn position_variance_is_the_products_trace_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(15);
        for n in [1, 7, 30, 64] {
            for _ in 0..20 {
                let mut jacobian = DMatrix::from_fn(6, n, |_, _| rng.random_range(-2.0..2.0));
                for k in 0..n {
                    if rng.random_range(0.0..1.0) < 0.5 {
                        jacobian.column_mut(k).fill(0.0);
                    }
                }
                jacobian[(0, 0)] = 1.5;
                let a = DMatrix::from_fn(n + 3, n, |_, _| rng.random_range(-1.0..1.0));
                let covariance = a.transpose() * &a;
                let position = jacobian.rows(0, 3);
                let expected = (position * &covariance * position.transpose()).trace();
                assert_eq!(
                    position_variance(&jacobian, &covariance).to_bits(),
                    expected.to_bits(),
                    "n = {n}"
                );
            }
        }
    }
}
