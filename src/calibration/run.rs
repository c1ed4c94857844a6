//! A calibration from measured data, end to end: hold-out, initial guess, the plan, parameter
//! uncertainties and the errors before and after, per arm (`treecal calibrate`).

use super::coarse_to_fine::CoarseToFine;
use super::frame::{check_length_scale, choose_measurement_frame, ChosenFrame};
pub use super::hold_out::{hold_out, hold_out_indices};
use super::initial_guess::InitialGuess;
use super::observation::kind_of;
use super::options::IdentificationOptions;
pub use super::outcome::{
    ArmResiduals, CalibrationRun, ErrorSummary, FrameRefinement, ParameterEstimate,
};
use super::plan::{CalibrationReport, Compensation};
use super::predictor::Deflected;
use super::robust::{self, DataSet, Outlier, RobustLoss, RobustReport};
use super::sessions::{
    calibrate_sessions, labelled, session_findings, validation_in_training_frames,
    SessionCalibration, Sessions, SessionsReport,
};
use super::verdict::Finding;
use crate::error::{Error, Result};
use crate::kinematics::{FlexibilityModel, McpcModel, ParameterOwner};
use crate::math::{root_mean_square, Pose};
use crate::measurement::Measurement;
use nalgebra::DMatrix;
use std::borrow::Cow;

mod frame_refinement;
mod input;
mod spread;
use frame_refinement::refine_measurement_frame;
pub use frame_refinement::{FRAME_PRIOR_ANGLE, FRAME_PRIOR_LENGTH};
pub use input::CalibrationInput;
use spread::predicted_spread;

/// Calibrates from `measurements` and evaluates the result on them and on `validation`.
pub fn run_calibration(
    input: &CalibrationInput<'_>,
    measurements: &[Measurement],
    validation: &[Measurement],
) -> Result<CalibrationRun> {
    check_length_scale(input.nominal, &closed_form_rows(measurements))?;
    // The measurement frame is the first session's; the others are fitted with the geometry.
    let (mut guess, frame, frame_finding) = choose_measurement_frame(
        input.nominal,
        &closed_form_rows(&Sessions::of(measurements).first_session(measurements)),
        input.measurement_frame,
    )?;
    let fitted_frame = frame.chosen == ChosenFrame::Fitted;
    let compensation = compensation_of(input);
    let SessionCalibration {
        mut report,
        mut robust,
        measurements: in_first_frame,
        mut sessions,
    } = calibrate_sessions(
        input.branches,
        &guess.model,
        measurements,
        compensation,
        input.plan,
        input.options,
    )?;
    let (given_measurements, given_validation) = (measurements, validation);
    // From here on every row is in the first session's frame.
    let measurements = in_first_frame.as_deref().unwrap_or(measurements);
    let frame_refinement = match (fitted_frame, input.flexibility) {
        (true, Some(flexibility)) => Some(refine_frame(
            input,
            (flexibility, compensation),
            measurements,
            &mut guess,
            &mut report,
            &mut robust,
        )?),
        _ => None,
    };
    // Validation in the training frame; a new session measured in another frame re-registered.
    sessions.validation = new_session_frames(
        &report.model,
        (given_measurements, given_validation),
        compensation,
        &sessions,
        input.options,
    )?;
    let validation = &in_training_frames(given_validation, &sessions)[..];
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
    let (validation_strata, repeatability) =
        super::repeatability::strata_and_repeatability(&report.model, measurements, validation);
    // Every validation row counts (its outliers are only marked).
    let measurement_rows = kept_rows(measurements.len(), &outliers);
    let parameters = estimates(input, &guess.model, &report);
    let baseline_validation = &nominal_validation(
        &baseline,
        (given_measurements, given_validation, validation),
        &sessions,
        input.options,
    )?[..];
    let (identification, validation_residuals) = before_and_after(
        input,
        &baseline,
        &report,
        (measurements, &measurement_rows),
        [baseline_validation, validation],
    )?;
    let predicted_validation_sd_mm = predicted_spread(&report, validation);
    // The sessions' report when any row names a session (its validation figures above).
    let sessions = labelled(given_measurements, given_validation).then_some(sessions);
    let findings = first_findings(
        frame_finding,
        &sessions,
        &report,
        (&robust, &outliers),
        measurement_rows.len(),
        validation.len(),
    );
    let mut run = CalibrationRun {
        guess,
        frame,
        frame_refinement,
        report,
        parameters,
        identification,
        validation: validation_residuals,
        predicted_validation_rms_mm: root_mean_square(&predicted_validation_sd_mm)
            .filter(|rms| rms.is_finite()),
        predicted_validation_sd_mm,
        findings,
        robust,
        outliers,
        baseline,
        validation_strata,
        repeatability,
        sessions,
    };
    let kept = (measurements, &measurement_rows[..]);
    assess(input, &mut run, kept, fitted_frame)?;
    Ok(run)
}

/// The rows the closed-form steps (the length-scale check, the measurement frame's choice and
/// the initial guess) read: all of `rows`, or above the coarse-to-fine threshold the
/// identification's evenly spread subsample of whole configurations ([`CoarseToFine`]): the
/// closed-form fits are averages that a subsample of 20,000 configurations fixes as well, and
/// the iteration from them reaches the same optimum (`docs/performance.md`, round eleven).
fn closed_form_rows(rows: &[Measurement]) -> Cow<'_, [Measurement]> {
    match CoarseToFine::DEFAULT.subsample(rows) {
        Some(selected) => Cow::Owned(selected.iter().map(|&i| rows[i].clone()).collect()),
        None => Cow::Borrowed(rows),
    }
}

/// How the run predicts deflections: exactly with a flexibility model, not at all without.
fn compensation_of<'a>(input: &CalibrationInput<'a>) -> Compensation<'a> {
    match input.flexibility {
        Some(flexibility) => Compensation::Exact(Deflected {
            tree: input.tree,
            flexibility,
        }),
        None => Compensation::None,
    }
}

/// The validation rows in the training frames; with one session and no new session measured
/// in another frame, the rows as given.
fn in_training_frames<'m>(
    validation: &'m [Measurement],
    sessions: &SessionsReport,
) -> Cow<'m, [Measurement]> {
    if sessions.frames.len() < 2 && !sessions.validation.iter().any(|v| v.moved()) {
        Cow::Borrowed(validation)
    } else {
        Cow::Owned(validation_in_training_frames(validation, Some(sessions)))
    }
}

/// The validation rows the nominal robot's "before" is scored on: the calibrated model's
/// `placed` rows (in the training frames), but when a new session was measured in another
/// frame (judged at the calibrated model), the given rows placed with the nominal robot's own
/// re-registration of it.
fn nominal_validation<'m>(
    baseline: &McpcModel,
    (training, validation, placed): (&[Measurement], &[Measurement], &'m [Measurement]),
    sessions: &SessionsReport,
    options: &IdentificationOptions,
) -> Result<Cow<'m, [Measurement]>> {
    if !sessions.validation.iter().any(|v| v.moved()) {
        return Ok(Cow::Borrowed(placed));
    }
    let frames = new_session_frames(
        baseline,
        (training, validation),
        Compensation::None,
        sessions,
        options,
    )?;
    let mut nominal = sessions.clone();
    for (session, own) in nominal.validation.iter_mut().zip(frames) {
        session.session_from_first = own.session_from_first;
    }
    Ok(Cow::Owned(validation_in_training_frames(
        validation,
        Some(&nominal),
    )))
}

/// The validation sessions' figures at `model` (empty when no row of either set names a
/// session): what tells a new session measured in another frame
/// ([`super::sessions::SessionValidation::moved`]) and its re-registered frame.
fn new_session_frames(
    model: &McpcModel,
    (training, validation): (&[Measurement], &[Measurement]),
    compensation: Compensation<'_>,
    sessions: &SessionsReport,
    options: &IdentificationOptions,
) -> Result<Vec<super::sessions::SessionValidation>> {
    if !labelled(training, validation) || validation.is_empty() {
        return Ok(Vec::new());
    }
    super::sessions::validate_sessions(model, validation, compensation, sessions, options)
}

/// The indices of the identification rows the fit kept (of `count`), in order (for the
/// reports' row ids).
fn kept_rows(count: usize, outliers: &[Outlier]) -> Vec<usize> {
    let flagged = super::robust::outlier_mask(outliers, DataSet::Identification, count);
    (0..count).filter(|&i| !flagged[i]).collect()
}

/// The findings of the calibration itself, in order: the measurement frame's, the sessions',
/// the plan's notes and the outliers' (`kept_identification` and `validation` as in
/// [`outlier_finding`]).
fn first_findings(
    frame_finding: Finding,
    sessions: &Option<SessionsReport>,
    report: &CalibrationReport,
    (robust, outliers): (&RobustReport, &[Outlier]),
    kept_identification: usize,
    validation: usize,
) -> Vec<Finding> {
    let mut findings = vec![frame_finding];
    findings.extend(sessions.iter().flat_map(session_findings));
    findings.extend(report.notes.iter().cloned());
    findings.extend(outlier_finding(
        robust,
        outliers,
        kept_identification,
        validation,
    ));
    findings
}

/// The measurement frame refined ([`refine_measurement_frame`]) with the robust weights
/// found, the outliers left out; `guess`, `report` and the robust residuals follow it.
fn refine_frame(
    input: &CalibrationInput<'_>,
    (flexibility, compensation): (&FlexibilityModel, Compensation<'_>),
    measurements: &[Measurement],
    guess: &mut InitialGuess,
    report: &mut CalibrationReport,
    robust: &mut RobustReport,
) -> Result<FrameRefinement> {
    let weighted = IdentificationOptions {
        observation_weights: robust.fit_weights(),
        ..input.options.clone()
    };
    let weighted_input = CalibrationInput {
        options: &weighted,
        ..*input
    };
    let refined = refine_measurement_frame(&weighted_input, flexibility, measurements, report)?;
    guess.world_from_base = refined.report.model.world_from_base();
    *report = refined.report;
    robust.residuals = robust::residuals(
        &report.model,
        measurements,
        compensation,
        None,
        input.options,
    )?;
    Ok(refined.summary)
}

/// The per-arm errors before (the registered nominal `baseline`) and after (the calibrated
/// model) on the identification rows the fit kept (with their indices in the data given) and on
/// every validation row.
fn before_and_after(
    input: &CalibrationInput<'_>,
    baseline: &McpcModel,
    report: &CalibrationReport,
    (measurements, measurement_rows): (&[Measurement], &[usize]),
    validation: [&[Measurement]; 2],
) -> Result<(Vec<ArmResiduals>, Vec<ArmResiduals>)> {
    let validation_rows: Vec<usize> = (0..validation[1].len()).collect();
    let predict = |model: &McpcModel, q: &[f64], payload: Option<f64>| -> Result<Vec<Pose>> {
        match input.flexibility {
            Some(flexibility) => flexibility
                .for_payload(payload)?
                .deflected_tool_poses(input.tree, model, q),
            None => Ok(model.tool_poses(q)),
        }
    };
    let residuals = |data: [&[Measurement]; 2], rows: &[usize]| -> Result<Vec<ArmResiduals>> {
        arm_residuals(
            input,
            data,
            rows,
            &|q, _| Ok(baseline.tool_poses(q)),
            &|q, payload| predict(&report.model, q, payload),
        )
    };
    let identification = residuals([measurements; 2], measurement_rows)?;
    let validation_residuals = if validation[1].is_empty() {
        Vec::new()
    } else {
        residuals(validation, &validation_rows)?
    };
    Ok((identification, validation_residuals))
}

/// Adds the checks' findings to `run`, and, when the residuals are far above the noise, a root
/// cause found in the joint columns.
fn assess(
    input: &CalibrationInput<'_>,
    run: &mut CalibrationRun,
    (measurements, rows): (&[Measurement], &[usize]),
    fitted_frame: bool,
) -> Result<()> {
    if let Some(shifted) = run.repeatability.as_ref().filter(|r| r.shifted) {
        run.findings
            .push(Finding::note("repeatability-shift", shifted.describe()));
    }
    let found = super::checks::assess(run, input.tree);
    run.findings.extend(found);
    // Residuals far above the noise: look for a root cause in the joint columns.
    let suspicious = run.report.stages.iter().any(|s| {
        let scale = s.identification.residual_scale;
        !scale.is_finite() || scale > super::checks::SIGMA_WARNING
    });
    if suspicious && input.diagnose_columns {
        let frame = run.report.model.world_from_base();
        let kept: Vec<Measurement> = rows.iter().map(|&i| measurements[i].clone()).collect();
        if let Some(cause) = super::columns::diagnose_columns(
            input.tree,
            input.nominal,
            &kept,
            fitted_frame,
            &frame,
            input.options,
        )? {
            run.findings.insert(1, cause);
        }
    }
    super::columns::mark_consequences(&mut run.findings);
    Ok(())
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
            "{identification} of {} identification and {flagged} of {validation} validation measurements are outliers by the robust {} loss (residuals beyond {:.0}–{:.0} robust σ, robust σ = {:.3} of the assumed noise): the identification ones were left out of the fit, the validation ones are marked and still counted in every validation figure; see \"outliers\" in report.json, check those rows (a bumped target, a wrong row), or compare with `robust` off",
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
type PredictAt<'a> = dyn Fn(&[f64], Option<f64>) -> Result<Vec<Pose>> + Sync + 'a;

/// One row (its index, its tool) and its position (mm) and orientation (deg) errors before
/// and after.
type RowErrors = ([usize; 2], [Option<f64>; 2], [Option<f64>; 2]);

/// The before/after residuals of the rows `rows` of `data` (indices in the data set the run
/// was given), per tool: before against `data[0]`, after against `data[1]` (the same rows,
/// each model's moved validation sessions placed by its own re-registration).
fn arm_residuals(
    input: &CalibrationInput<'_>,
    data: [&[Measurement]; 2],
    rows: &[usize],
    before: &PredictAt<'_>,
    after: &PredictAt<'_>,
) -> Result<Vec<ArmResiduals>> {
    let tools = input.nominal.tools().len();
    let mut position = vec![[Vec::new(), Vec::new()]; tools];
    let mut orientation = vec![[Vec::new(), Vec::new()]; tools];
    let mut indices = vec![Vec::new(); tools];
    // Each row's errors in parallel, gathered in row order (the same lists on any number of
    // threads).
    let part = |range: std::ops::Range<usize>| -> Result<Vec<RowErrors>> {
        let mut cache: super::predictor::Cached<'_, [Vec<Pose>; 2]> = None;
        let mut errors = Vec::with_capacity(range.len());
        for &row in &rows[range] {
            let m = &data[1][row];
            let key = (m.q.as_slice(), m.payload);
            if cache.as_ref().is_none_or(|(k, _)| *k != key) {
                cache = Some((key, [before(&m.q, m.payload)?, after(&m.q, m.payload)?]));
            }
            let Some((_, predictions)) = &cache else {
                continue;
            };
            let mut found: RowErrors = ([row, m.tool], [None; 2], [None; 2]);
            for (k, predicted) in predictions.iter().enumerate() {
                let pose = predicted.get(m.tool).ok_or_else(|| Error::InvalidData {
                    origin: "measurements".into(),
                    message: format!("tool {} does not exist", m.tool),
                })?;
                let kind = kind_of(&data[k][row].observation);
                found.1[k] = kind
                    .measured_point()
                    .map(|measured| (measured - pose.translation.vector).norm() * 1e3);
                found.2[k] = kind
                    .measured_frame()
                    .map(|measured| measured.rotation.angle_to(&pose.rotation).to_degrees());
            }
            errors.push(found);
        }
        Ok(errors)
    };
    super::linearise::map_rows_in_order(rows.len(), part, |([row, tool], positions, angles)| {
        if let Some(list) = indices.get_mut(tool) {
            list.push(row);
        }
        for k in 0..2 {
            position[tool][k].extend(positions[k]);
            orientation[tool][k].extend(angles[k]);
        }
    })?;
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

/// The percentage of `before` that `after` removed (0 when there was nothing to remove).
pub fn removed_percent(before: f64, after: f64) -> f64 {
    if before > 0.0 {
        100.0 * (1.0 - after / before)
    } else {
        0.0
    }
}
