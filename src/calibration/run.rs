//! A calibration from measured data, end to end: hold-out, initial guess, the plan, parameter
//! uncertainties and the errors before and after, per arm (`treecal calibrate`).

pub use super::frame::MeasurementFrame;
use super::frame::{check_length_scale, choose_measurement_frame, ChosenFrame};
pub use super::hold_out::{hold_out, hold_out_indices};
use super::observation::kind_of;
use super::options::IdentificationOptions;
pub use super::outcome::{
    ArmResiduals, CalibrationRun, ErrorSummary, FrameRefinement, ParameterEstimate,
};
use super::plan::{calibrate, CalibrationReport, Compensation, Plan};
use super::predictor::Deflected;
use super::robust::{self, DataSet, Outlier, RobustLoss, RobustReport};
use super::sessions::{
    calibrate_sessions, finish_sessions, session_findings, validation_in_training_frames,
    SessionCalibration, Sessions,
};
use super::verdict::Finding;
use crate::error::{Error, Result};
use crate::kinematics::{FlexibilityModel, McpcModel, ParameterOwner};
use crate::math::Pose;
use crate::measurement::Measurement;
use crate::tree::{Branches, KinematicTree};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// What a calibration is run on and how.
#[derive(Debug, Clone, Copy)]
pub struct CalibrationInput<'a> {
    /// The robot.
    pub tree: &'a KinematicTree,
    /// Its coupled branch and arms.
    pub branches: &'a Branches,
    /// The nominal MCPC model of `branches`.
    pub nominal: &'a McpcModel,
    /// The flexibility model, for exact compensation; `None` calibrates a rigid robot.
    pub flexibility: Option<&'a FlexibilityModel>,
    /// The stages.
    pub plan: &'a Plan,
    /// Row weights, tolerances.
    pub options: &'a IdentificationOptions,
    /// Where the measurements are: fitted, the root frame, a known registration, or `Auto`
    /// (see [`MeasurementFrame`]); the tool frames are always fitted.
    pub measurement_frame: MeasurementFrame,
}

/// Calibrates from `measurements` and evaluates the result on them and on `validation`.
pub fn run_calibration(
    input: &CalibrationInput<'_>,
    measurements: &[Measurement],
    validation: &[Measurement],
) -> Result<CalibrationRun> {
    check_length_scale(input.nominal, measurements)?;
    // The measurement frame is the first session's; the others are fitted with the geometry.
    let (guess, frame, frame_finding) = choose_measurement_frame(
        input.nominal,
        &Sessions::of(measurements).first_session(measurements),
        input.measurement_frame,
    )?;
    let fitted_frame = frame.chosen == ChosenFrame::Fitted;
    let compensation = match input.flexibility {
        Some(flexibility) => Compensation::Exact(Deflected {
            tree: input.tree,
            flexibility,
        }),
        None => Compensation::None,
    };
    let mut guess = guess;
    let SessionCalibration {
        mut report,
        mut robust,
        measurements: in_first_frame,
        sessions,
    } = calibrate_sessions(
        input.branches,
        &guess.model,
        measurements,
        compensation,
        input.plan,
        input.options,
    )?;
    let (given_measurements, given_validation) = (measurements, validation);
    // From here on every row is in the first session's frame (validation: the training frame).
    let measurements = &in_first_frame[..];
    let validation = &validation_in_training_frames(validation, Some(&sessions))[..];
    let mut frame_refinement = None;
    if let (true, Some(flexibility)) = (fitted_frame, input.flexibility) {
        // The frame is refined with the robust weights found, the outliers left out.
        let weighted = IdentificationOptions {
            observation_weights: robust.fit_weights(),
            ..input.options.clone()
        };
        let weighted_input = CalibrationInput {
            options: &weighted,
            ..*input
        };
        let refined =
            refine_measurement_frame(&weighted_input, flexibility, measurements, &report)?;
        guess.world_from_base = refined.report.model.world_from_base();
        report = refined.report;
        frame_refinement = Some(refined.summary);
        robust.residuals = robust::residuals(
            &report.model,
            measurements,
            compensation,
            None,
            input.options,
        )?;
    }
    let outliers = name_outliers(
        input,
        &report,
        &robust,
        compensation,
        measurements,
        validation,
    )?;
    // The fair "before": the nominal robot registered like the calibrated one (frame when
    // fitted, tools), on the rows the fit used with the fit's weights.
    let baseline = super::baseline::registered_nominal(
        &guess.model,
        measurements,
        &robust.fit_weights(),
        fitted_frame,
        input.options,
    )?;
    let validation_strata = super::validation::strata(&report.model, measurements, validation);
    // The identification rows the fit kept, with their indices in the data given (for the
    // reports' row ids); every validation row counts (its outliers are only marked).
    let (measurement_rows, measurements): (Vec<usize>, Vec<Measurement>) = measurements
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            !outliers
                .iter()
                .any(|o| o.set == DataSet::Identification && o.index == *i)
        })
        .map(|(i, m)| (i, m.clone()))
        .unzip();
    let validation_rows: Vec<usize> = (0..validation.len()).collect();
    let measurements = &measurements[..];
    let parameters = estimates(input, &guess.model, &report);
    let predict = |model: &McpcModel, q: &[f64], payload: Option<f64>| -> Result<Vec<Pose>> {
        match input.flexibility {
            Some(flexibility) => flexibility
                .for_payload(payload)?
                .deflected_tool_poses(input.tree, model, q),
            None => Ok(model.tool_poses(q)),
        }
    };
    let residuals = |data: &[Measurement], rows: &[usize]| -> Result<Vec<ArmResiduals>> {
        arm_residuals(
            input,
            data,
            rows,
            &|q, _| Ok(baseline.tool_poses(q)),
            &|q, payload| predict(&report.model, q, payload),
        )
    };
    let identification = residuals(measurements, &measurement_rows)?;
    let validation_residuals = if validation.is_empty() {
        Vec::new()
    } else {
        residuals(validation, &validation_rows)?
    };
    let predicted_validation_sd_mm = predicted_spread(&report, validation);
    let predicted_validation_rms_mm = (!predicted_validation_sd_mm.is_empty())
        .then(|| {
            (predicted_validation_sd_mm
                .iter()
                .map(|s| s * s)
                .sum::<f64>()
                / predicted_validation_sd_mm.len() as f64)
                .sqrt()
        })
        .filter(|rms| rms.is_finite());
    let sessions = finish_sessions(
        sessions,
        &report.model,
        given_measurements,
        given_validation,
        compensation,
        input.options,
    )?;
    let mut findings = vec![frame_finding];
    findings.extend(sessions.iter().flat_map(session_findings));
    findings.extend(report.notes.iter().cloned());
    findings.extend(outlier_finding(
        &robust,
        &outliers,
        measurements.len(),
        validation.len(),
    ));
    let mut run = CalibrationRun {
        guess,
        frame,
        frame_refinement,
        report,
        parameters,
        identification,
        validation: validation_residuals,
        predicted_validation_rms_mm,
        predicted_validation_sd_mm,
        findings,
        robust,
        outliers,
        baseline,
        validation_strata,
        sessions,
    };
    let found = super::checks::assess(&run, input.tree);
    run.findings.extend(found);
    // Residuals far above the noise: look for a root cause in the joint columns.
    let suspicious = run.report.stages.iter().any(|s| {
        let scale = s.identification.residual_scale;
        !scale.is_finite() || scale > super::checks::SIGMA_WARNING
    });
    if suspicious {
        let frame = run.report.model.world_from_base();
        if let Some(cause) = super::columns::diagnose_columns(
            input.tree,
            input.nominal,
            measurements,
            fitted_frame,
            &frame,
            input.options,
        )? {
            run.findings.insert(1, cause);
        }
    }
    super::columns::mark_consequences(&mut run.findings);
    Ok(run)
}

/// The outliers of the identification data (the robust fit's) and of the validation data
/// (judged by the same loss at the larger of the identification data's robust scale and
/// their own): none when the loss is off. Validation data are never fitted: a validation outlier
/// is named and marked, and still counted in every validation figure.
fn name_outliers(
    input: &CalibrationInput<'_>,
    report: &CalibrationReport,
    robust: &RobustReport,
    compensation: Compensation<'_>,
    measurements: &[Measurement],
    validation: &[Measurement],
) -> Result<Vec<Outlier>> {
    if robust.loss == RobustLoss::Off {
        return Ok(Vec::new());
    }
    let mut outliers = robust.name_outliers(
        DataSet::Identification,
        measurements,
        &robust.residuals,
        &robust.weights,
        robust.scale,
    );
    let residuals =
        robust::residuals(&report.model, validation, compensation, None, input.options)?;
    // A validation row is an outlier only if it stands out from the other validation rows as
    // well as from the fit's noise: validation data that are all off (another robot, a moved
    // tracker) are the validation checks' business, not blunders.
    let scale = robust
        .scale
        .max(robust::robust_scale(&residuals, validation));
    let weights = robust::weights_of(robust.loss, &residuals, validation, scale);
    outliers.extend(robust.name_outliers(
        DataSet::Validation,
        validation,
        &residuals,
        &weights,
        scale,
    ));
    Ok(outliers)
}

/// The warning that names the outliers: identification rows left out of the fit, validation
/// rows marked but kept in every figure; `kept_identification` counts the identification rows
/// the fit still uses, `validation` all validation rows.
fn outlier_finding(
    robust: &RobustReport,
    outliers: &[Outlier],
    kept_identification: usize,
    validation: usize,
) -> Option<Finding> {
    if outliers.is_empty() {
        return None;
    }
    let count = |set: DataSet| outliers.iter().filter(|o| o.set == set).count();
    let (identification, flagged) = (count(DataSet::Identification), count(DataSet::Validation));
    Some(Finding::warning(
        "outliers",
        format!(
            "{identification} of {} identification and {flagged} of {validation} validation measurements are outliers by the robust {} loss (residuals beyond {:.0}–{:.0} robust σ, robust σ = {:.3} of the assumed noise): the identification ones were left out of the fit, the validation ones are marked and still counted in every validation figure; see \"outliers\" in report.json, check those rows (a bumped target, a wrong row), or compare with --robust off",
            identification + kept_identification,
            robust.loss,
            robust.loss.outlier_norm(3),
            robust.loss.outlier_norm(6),
            robust.scale,
        ),
    ))
}

/// The covariance of all parameters (full-model order, rad and m), assembled from the stages:
/// each stage's `σ̂²·(JᵀWJ)⁺` over the parameters it freed (a coupled stage's torso frames are
/// the first parameters of its reduced model; its locked tools are dropped). Later stages
/// overwrite earlier ones; stages are independent, so cross-stage covariances are zero.
pub fn assembled_covariance(report: &CalibrationReport) -> DMatrix<f64> {
    let n = report.model.parameter_count();
    let mut covariance = DMatrix::zeros(n, n);
    for stage in &report.stages {
        let id = &stage.identification;
        let Some(c) = &id.covariance else { continue };
        let limit = stage.full_model_parameters();
        let kept: Vec<(usize, usize)> = id
            .free
            .iter()
            .enumerate()
            .filter(|(_, &p)| p < limit && p < n)
            .map(|(k, &p)| (k, p))
            .collect();
        for &(a, p) in &kept {
            for &(b, q) in &kept {
                covariance[(p, q)] = c[(a, b)];
            }
        }
    }
    covariance
}

/// Table 2 rows: nominal is the URDF's value (the measurement frame does not enter the
/// parameters), start the closed-form initial guess `start`, standard deviations and identifiability from the stage that freed each one.
fn estimates(
    input: &CalibrationInput<'_>,
    start: &McpcModel,
    report: &CalibrationReport,
) -> Vec<ParameterEstimate> {
    let (nominal, start) = (input.nominal.parameters(), start.parameters());
    let calibrated = report.model.parameters();
    let layout = report.model.parameter_layout();
    let mut spread: Vec<(Option<f64>, bool)> = vec![(None, true); calibrated.len()];
    for stage in &report.stages {
        let id = &stage.identification;
        let limit = stage.full_model_parameters();
        for (k, &p) in id.free.iter().enumerate() {
            if p < limit && p < spread.len() {
                let sd = id.standard_deviations[k];
                spread[p] = (sd.is_finite().then_some(sd), id.identifiable[k]);
            }
        }
        // Kept at their starting values: the observations cannot see them.
        let count = spread.len();
        for &p in stage.kept.iter().filter(|&&p| p < limit && p < count) {
            spread[p] = (None, false);
        }
    }
    layout
        .iter()
        .enumerate()
        .map(|(i, (owner, kind))| {
            let owner_name = match owner {
                ParameterOwner::Frame(f) => input
                    .tree
                    .joint(report.model.frames()[*f].joint)
                    .name
                    .clone(),
                ParameterOwner::Tool(t) => {
                    input.tree.link(report.model.tools()[*t].link).name.clone()
                }
                ParameterOwner::Measurement => "measurement_frame".into(),
            };
            ParameterEstimate {
                name: report.model.parameter_name(input.tree, i),
                owner: owner_name,
                kind: kind.name().into(),
                unit: if kind.is_angle() { "rad" } else { "m" }.into(),
                nominal: nominal[i],
                start: start[i],
                calibrated: calibrated[i],
                change: calibrated[i] - nominal[i],
                std_dev: spread[i].0,
                identifiable: spread[i].1,
            }
        })
        .collect()
}

/// Tool poses at a configuration with a row's payload (kg at every tool, `None`: the model's).
type PredictAt<'a> = dyn Fn(&[f64], Option<f64>) -> Result<Vec<Pose>> + 'a;

/// `rows[i]`: the index of `data[i]` in the data set the run was given.
fn arm_residuals(
    input: &CalibrationInput<'_>,
    data: &[Measurement],
    rows: &[usize],
    before: &PredictAt<'_>,
    after: &PredictAt<'_>,
) -> Result<Vec<ArmResiduals>> {
    let tools = input.nominal.tools().len();
    let mut position = vec![[Vec::new(), Vec::new()]; tools];
    let mut orientation = vec![[Vec::new(), Vec::new()]; tools];
    let mut indices = vec![Vec::new(); tools];
    let mut cache: super::predictor::Cached<'_, [Vec<Pose>; 2]> = None;
    for (i, m) in data.iter().enumerate() {
        if let Some(list) = indices.get_mut(m.tool) {
            list.push(rows.get(i).copied().unwrap_or(i));
        }
        let key = (m.q.as_slice(), m.payload);
        if cache.as_ref().is_none_or(|(k, _)| *k != key) {
            cache = Some((key, [before(&m.q, m.payload)?, after(&m.q, m.payload)?]));
        }
        let Some((_, predictions)) = &cache else {
            continue;
        };
        for (k, predicted) in predictions.iter().enumerate() {
            let pose = predicted.get(m.tool).ok_or_else(|| Error::InvalidData {
                origin: "measurements".into(),
                message: format!("tool {} does not exist", m.tool),
            })?;
            let kind = kind_of(&m.observation);
            if let Some(measured) = kind.measured_point() {
                position[m.tool][k].push((measured - pose.translation.vector).norm() * 1e3);
            }
            if let Some(measured) = kind.measured_frame() {
                orientation[m.tool][k]
                    .push(measured.rotation.angle_to(&pose.rotation).to_degrees());
            }
        }
    }
    Ok((0..tools)
        .filter(|&tool| !position[tool][0].is_empty())
        .map(|tool| {
            let before = ErrorSummary::of(&position[tool][0], &orientation[tool][0]);
            let after = ErrorSummary::of(&position[tool][1], &orientation[tool][1]);
            let link = input.nominal.tools()[tool].link;
            ArmResiduals {
                arm: input.branches.arm_name(link),
                tool: input.tree.link(link).name.clone(),
                rows: indices[tool].clone(),
                observations: position[tool][0].len(),
                before,
                after,
                position_removed_percent: removed_percent(
                    before.rms_position_mm,
                    after.rms_position_mm,
                ),
                orientation_removed_percent: before
                    .rms_orientation_deg
                    .zip(after.rms_orientation_deg)
                    .map(|(b, a)| removed_percent(b, a)),
                position_mm: position[tool].clone(),
                orientation_deg: orientation[tool].clone(),
            }
        })
        .collect())
}

/// Per validation observation, `√trace(J_p·C·J_pᵀ)` with `C` the assembled parameter
/// covariance ([`assembled_covariance`]) (mm): the spread of the predicted position that the
/// identification noise leaves.
fn predicted_spread(report: &CalibrationReport, validation: &[Measurement]) -> Vec<f64> {
    // A stage without redundancy has no covariance: nothing can be predicted (not zero).
    let undetermined = report
        .stages
        .iter()
        .any(|s| s.identification.covariance.is_none());
    if validation.is_empty() || undetermined {
        return Vec::new();
    }
    let covariance = assembled_covariance(report);
    let model = &report.model;
    validation
        .iter()
        .map(|m| {
            let jacobian = model.tool_jacobian(m.tool, &m.q).jacobian;
            let position = jacobian.rows(0, 3);
            (position * &covariance * position.transpose())
                .trace()
                .max(0.0)
                .sqrt()
                * 1e3
        })
        .collect()
}

struct Refined {
    report: CalibrationReport,
    summary: FrameRefinement,
}

/// Rigid kinematics cannot tell the measurement frame from the MCPC parameters (the model is
/// complete: any frame error is absorbed by them), but the deflections can: gravity and the
/// lever arms of the loads are fixed in space, and the absorbed parametrisation places joints
/// and masses differently. A frame fitted to the nominal model (off by the geometric errors)
/// therefore leaves a systematic error of the order of deflection × relative geometric error.
/// This refines the six frame parameters by variable projection: Gauss–Newton on the weighted
/// residual *after* calibrating the parameters at each trial frame, with forward-difference
/// derivatives (each a warm-started calibration) and a Gaussian prior centred on the closed-form
/// frame ([`FRAME_PRIOR_LENGTH`], [`FRAME_PRIOR_ANGLE`]) for the directions the data leave free.
fn refine_measurement_frame(
    input: &CalibrationInput<'_>,
    flexibility: &FlexibilityModel,
    measurements: &[Measurement],
    start: &CalibrationReport,
) -> Result<Refined> {
    let predictor = Deflected {
        tree: input.tree,
        flexibility,
    };
    let residual_of = |report: &CalibrationReport| {
        super::linearise::weighted_residual(&report.model, measurements, &predictor, input.options)
    };
    let calibrate_at = |from: &McpcModel, frame: &Pose| -> Result<CalibrationReport> {
        let mut model = from.clone();
        model.set_world_from_base(frame);
        calibrate(
            input.branches,
            &model,
            measurements,
            Compensation::Exact(predictor),
            input.plan,
            input.options,
        )
    };
    // Frame perturbation: world_from_base ← exp(δ)·world_from_base, δ = (translation, rotation)
    // in the measurement frame.
    let moved = |frame: &Pose, delta: &[f64]| -> Pose {
        let rotation = nalgebra::UnitQuaternion::from_scaled_axis(nalgebra::Vector3::new(
            delta[3], delta[4], delta[5],
        ));
        // Turned about the frame's own origin, not the measurement origin.
        let origin =
            frame.translation.vector + nalgebra::Vector3::new(delta[0], delta[1], delta[2]);
        Pose::from_parts(origin.into(), rotation * frame.rotation)
    };
    const STEP: f64 = 1e-4;
    const MAX_ITERATIONS: usize = 10;
    let initial_frame = start.model.world_from_base();
    // The correction from the closed-form frame as (translation, rotation vector).
    let correction_of = |frame: &Pose| -> DVector<f64> {
        let t = frame.translation.vector - initial_frame.translation.vector;
        let r = (frame.rotation * initial_frame.rotation.inverse()).scaled_axis();
        DVector::from_column_slice(&[t.x, t.y, t.z, r.x, r.y, r.z])
    };
    let prior: DVector<f64> = DVector::from_column_slice(&[
        1.0 / FRAME_PRIOR_LENGTH,
        1.0 / FRAME_PRIOR_LENGTH,
        1.0 / FRAME_PRIOR_LENGTH,
        1.0 / FRAME_PRIOR_ANGLE,
        1.0 / FRAME_PRIOR_ANGLE,
        1.0 / FRAME_PRIOR_ANGLE,
    ]);
    let total_cost = |residual: &DVector<f64>, frame: &Pose| -> f64 {
        0.5 * residual.norm_squared()
            + 0.5 * correction_of(frame).component_mul(&prior).norm_squared()
    };
    let mut current = start.clone();
    let mut residual = residual_of(&current)?;
    let initial_cost = 0.5 * residual.norm_squared();
    let mut iterations = 0;
    let mut determined = 0;
    let mut damping = 0.0;
    while iterations < MAX_ITERATIONS {
        let frame = current.model.world_from_base();
        // The six columns are independent calibrations: run them on all cores.
        let columns: Vec<DVector<f64>> = (0..6)
            .into_par_iter()
            .map(|k| -> Result<DVector<f64>> {
                let mut delta = [0.0; 6];
                delta[k] = STEP;
                let shifted = calibrate_at(&current.model, &moved(&frame, &delta))?;
                Ok((residual_of(&shifted)? - &residual) / STEP)
            })
            .collect::<Result<_>>()?;
        let jacobian = DMatrix::from_columns(&columns);
        crate::limits::ensure_finite(
            jacobian.iter().chain(residual.iter()),
            "measurement frame refinement: the Jacobian",
        )?;
        let singular_values = jacobian.clone().svd(false, false).singular_values;
        let largest = singular_values.max();
        // Directions the data determine better than the prior does.
        determined = singular_values
            .iter()
            .filter(|&&s| s > 1.0 / FRAME_PRIOR_LENGTH.max(FRAME_PRIOR_ANGLE) && s > 1e-6 * largest)
            .count();
        let cost = total_cost(&residual, &frame);
        let weights = prior.component_mul(&prior);
        let normal = jacobian.tr_mul(&jacobian) + DMatrix::from_diagonal(&weights);
        let gradient = jacobian.tr_mul(&residual) + correction_of(&frame).component_mul(&weights);
        let mut accepted = false;
        let mut converged = false;
        for _ in 0..10 {
            let damped = &normal + DMatrix::identity(6, 6) * damping;
            let Some(cholesky) = damped.cholesky() else {
                break;
            };
            let step = -cholesky.solve(&gradient);
            let trial_frame = moved(&frame, step.as_slice());
            let trial = calibrate_at(&current.model, &trial_frame)?;
            let trial_residual = residual_of(&trial)?;
            let trial_cost = total_cost(&trial_residual, &trial_frame);
            if trial_cost < cost {
                current = trial;
                residual = trial_residual;
                damping *= 0.1;
                accepted = true;
                iterations += 1;
                // Past the noise floor the cost creeps along the valley the data leave
                // free; a relative decrease of 1e-5 is far below what noise tells apart.
                converged = step.norm() < 1e-9 || cost - trial_cost <= 1e-5 * cost;
                break;
            }
            damping = if damping == 0.0 {
                1e-6 * normal.diagonal().max()
            } else {
                damping * 10.0
            };
        }
        if !accepted || converged {
            break;
        }
    }
    Ok(finish(
        current,
        residual,
        initial_cost,
        iterations,
        determined,
        &initial_frame,
    ))
}

/// How far (m) the refined measurement frame is expected to be from the closed-form fit: the
/// scale of a Gaussian prior that keeps the directions the deflections hardly see (such as a
/// turn about the vertical) where the closed form put them.
pub const FRAME_PRIOR_LENGTH: f64 = 0.01;

/// The same for rotations (rad).
pub const FRAME_PRIOR_ANGLE: f64 = 0.01;

fn finish(
    report: CalibrationReport,
    residual: DVector<f64>,
    initial_cost: f64,
    iterations: usize,
    determined: usize,
    initial_frame: &Pose,
) -> Refined {
    let frame = report.model.world_from_base();
    let change = frame * initial_frame.inverse();
    Refined {
        summary: FrameRefinement {
            iterations,
            cost: [initial_cost, 0.5 * residual.norm_squared()],
            correction: [
                change.rotation.angle(),
                (frame.translation.vector - initial_frame.translation.vector).norm(),
            ],
            determined,
        },
        report,
    }
}

/// The percentage of `before` that `after` removed (0 when there was nothing to remove).
pub fn removed_percent(before: f64, after: f64) -> f64 {
    if before > 0.0 {
        100.0 * (1.0 - after / before)
    } else {
        0.0
    }
}
