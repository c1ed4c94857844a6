//! The checks of a finished calibration: each looks at one aspect of a [`CalibrationRun`] and
//! returns a [`Finding`] when there is something to say. [`assess`] runs them all; the
//! measurement-frame and unit checks run earlier, where the data are read and the frame is
//! chosen. Thresholds and their reasons: `docs/calibration.md`, "What treecal checks and
//! infers".

use super::outcome::CalibrationRun;
use super::plan::StageReport;
use super::solver::Termination;
use super::verdict::Finding;
use crate::tree::KinematicTree;

/// Fewer equations than this many per unknown parameter is a warning: the residuals then
/// understate the noise by more than √(1 − 1/1.5) ≈ 0.58 (the fit follows the noise nearly as
/// much as it averages it), and σ̂ rests on fewer degrees of freedom than there are unknowns.
pub const REDUNDANCY_WARNING: f64 = 1.5;

/// σ̂ (residuals over the assumed noise) above this is a warning: the noise is larger than
/// `--position-sigma` / `--rotation-sigma` say, or the model misses something.
pub const SIGMA_WARNING: f64 = 10.0;

/// σ̂ above this is a failure: no instrument is that far off its stated noise; the residuals
/// come from a mistake (units, swapped columns, the wrong robot or frame).
pub const SIGMA_FAILED: f64 = 100.0;

/// A condition number of the column-scaled Jacobian above this is a warning: the worst
/// determined parameter combination is a thousand times weaker than the best.
pub const CONDITION_WARNING: f64 = 1e3;

/// The validation error over the error the identification predicts for it (noise plus the
/// parameter uncertainty) above this is a warning.
pub const VALIDATION_WARNING: f64 = 3.0;

/// The same ratio above this is a failure.
pub const VALIDATION_FAILED: f64 = 30.0;

/// A harmonic amplitude `√(a² + b²)` or a backlash (rad) above this is a warning: larger than
/// the error of any encoder or gear train a robot is sold with (≈ 3°).
pub const JOINT_ERROR_WARNING: f64 = 0.05;

/// The same above this is a failure (≈ 17°): no joint is that far off; the fit traded the term
/// against the geometry (over a narrow joint range `cos q` is nearly the zero offset) and the
/// joint-angle errors file would move the robot wherever the data did not reach.
pub const JOINT_ERROR_FAILED: f64 = 0.3;

/// Every check of a finished calibration, in order: the position-only and reference-gauge
/// notes; per stage
/// redundancy, σ̂, rank, conditioning (these two not after a failed σ̂) and convergence; then
/// the validation checks.
pub fn assess(run: &CalibrationRun, tree: &KinematicTree) -> Vec<Finding> {
    let mut findings: Vec<Finding> = position_only(run).into_iter().collect();
    findings.extend(run.repeatability.as_ref().and_then(|r| r.not_held_out()));
    findings.extend(
        super::gauge::gauge_summary(&run.report.model, tree)
            .map(|text| Finding::note("reference-gauge", text)),
    );
    for stage in &run.report.stages {
        let scale = residual_scale(stage);
        // Residuals of a mistake (units, swapped tools) wreck the linearisation too: rank and
        // conditioning at such a "solution" say nothing more.
        let mistaken = scale
            .as_ref()
            .is_some_and(|f| f.status == super::verdict::Status::Failed);
        findings.extend(redundancy(stage));
        findings.extend(scale);
        if !mistaken {
            findings.extend(rank(run, stage, tree));
            findings.extend(conditioning(stage));
        }
        findings.extend(convergence(stage));
    }
    findings.extend(joint_errors_plausible(run, tree));
    findings.extend(validation_improves(run));
    findings.extend(validation_matches_prediction(run));
    findings
}

/// A note naming the tools whose orientation position-only data cannot see (kept at their
/// starting values, `identifiable: no`).
pub fn position_only(run: &CalibrationRun) -> Option<Finding> {
    let mut tools: Vec<&str> = Vec::new();
    for stage in run.report.stages.iter().filter(|s| s.locked_tools == 0) {
        for &p in &stage.kept {
            if let Some(parameter) = run.parameters.get(p) {
                if !tools.contains(&parameter.owner.as_str()) {
                    tools.push(&parameter.owner);
                }
            }
        }
    }
    (!tools.is_empty()).then(|| {
        Finding::note(
            "position-only",
            format!(
                "position-only observations: the orientation of {} cannot be observed from measured points; it was kept at its starting (nominal) value and is marked identifiable: no; orientation errors are not reported",
                tools.join(", ")
            ),
        )
    })
}

/// Fewer equations than unknowns fails (no redundancy: σ̂ and the uncertainties are undefined
/// and the fit passes through the noise); fewer than [`REDUNDANCY_WARNING`] per unknown warns.
pub fn redundancy(stage: &StageReport) -> Option<Finding> {
    let id = &stage.identification;
    let unknowns = id.free.len();
    if unknowns == 0 {
        return None;
    }
    let advice = format!(
        "measure more configurations: at least {} equations ({REDUNDANCY_WARNING}× the unknowns)",
        (REDUNDANCY_WARNING * unknowns as f64).ceil()
    );
    if id.rows <= unknowns {
        Some(Finding::failed(
            "too-few-equations",
            format!(
                "stage '{}': {} equations from {} observations for {unknowns} unknown parameters: the data cannot determine them (no redundancy; σ̂ and the uncertainties are undefined); {advice}",
                stage.name, id.rows, stage.measurements
            ),
        ))
    } else if (id.rows as f64) < REDUNDANCY_WARNING * unknowns as f64 {
        Some(Finding::warning(
            "little-redundancy",
            format!(
                "stage '{}': only {} equations for {unknowns} unknown parameters: the fit follows the noise and σ̂ rests on {} degrees of freedom; {advice}",
                stage.name,
                id.rows,
                id.rows - id.rank
            ),
        ))
    } else {
        None
    }
}

/// Parameter combinations the data cannot determine, beyond what the observation type
/// explains (position-only tool orientation is not freed at all, so it is not counted here).
pub fn rank(run: &CalibrationRun, stage: &StageReport, tree: &KinematicTree) -> Option<Finding> {
    let id = &stage.identification;
    let missing = id.free.len().saturating_sub(id.rank);
    // Without redundancy the rank deficiency is a consequence; `redundancy` says it.
    if missing == 0 || id.rows <= id.free.len() {
        return None;
    }
    let limit = stage.full_model_parameters();
    let example = id.unidentifiable.first().map(|combination| {
        combination
            .terms
            .iter()
            .take(4)
            .map(|(p, w)| {
                let name = if *p < limit {
                    run.report.model.parameter_name(tree, *p)
                } else {
                    format!("locked-arm tool parameter {}", p - limit)
                };
                format!("{name} ({w:+.2})")
            })
            .collect::<Vec<_>>()
            .join(" with ")
    });
    Some(Finding::warning(
        "rank-deficient",
        format!(
            "stage '{}': rank {} of {}: {missing} parameter combination(s) cannot be determined from these configurations and were kept at their starting values (e.g. {}); add configurations that move these joints apart (see report.md)",
            stage.name,
            id.rank,
            id.free.len(),
            example.unwrap_or_default()
        ),
    ))
}

/// σ̂ far above 1: residuals much larger than the assumed noise.
pub fn residual_scale(stage: &StageReport) -> Option<Finding> {
    let id = &stage.identification;
    if id.rows <= id.free.len() {
        return None;
    }
    let scale = id.residual_scale;
    let residuals = format!(
        "RMS residual {} mm, {} deg",
        readable(id.residual_rms_position * 1e3),
        readable(id.residual_rms_rotation.to_degrees())
    );
    if !scale.is_finite() || scale > SIGMA_FAILED {
        Some(Finding::failed(
            "sigma-ratio",
            format!(
                "stage '{}': σ̂ = {scale:.4e}: the residuals ({residuals}) are far larger than any measurement noise; typical causes: lengths in mm read as m (`length_unit`), angles in degrees read as radians (`angle_unit`), swapped or mislabelled tool columns, the wrong robot or measurement frame, a robot measured from a link other than its URDF root (a sole on the floor, a mobile base: name it with `reference_link`), large deflections left uncompensated (`stiffness`)",
                stage.name
            ),
        ))
    } else if scale > SIGMA_WARNING {
        Some(Finding::warning(
            "sigma-ratio",
            format!(
                "stage '{}': σ̂ = {scale:.1}: the residuals ({residuals}) are {scale:.0}× the assumed noise: the model leaves about {} mm RMS unexplained (the residual beyond the declared noise, in quadrature). That is model error — compare richer models with `cv` or let `model` auto choose (flexibility: `stiffness`; backlash, joint-angle errors, a wrong tool) — or a noise larger than `position_sigma` / `rotation_sigma` say; either way the accuracy to trust is the validation RMS in mm (report.md), whatever σ is declared; the standard deviations are scaled by σ̂",
                stage.name,
                readable(unexplained_mm(id.residual_rms_position, scale)),
            ),
        ))
    } else {
        None
    }
}

/// The part of an RMS position residual (m) the declared noise does not explain, in
/// quadrature (mm): `rms·√(1 − 1/σ̂²)` (the noise alone would leave `rms/σ̂`).
pub fn unexplained_mm(rms_position: f64, scale: f64) -> f64 {
    if scale <= 1.0 {
        return 0.0;
    }
    rms_position * 1e3 * (1.0 - 1.0 / (scale * scale)).sqrt()
}

/// Four decimals, or scientific notation for values a mistake makes huge.
fn readable(value: f64) -> String {
    if value.abs() < 1e5 {
        format!("{value:.4}")
    } else {
        format!("{value:.3e}")
    }
}

/// An ill-conditioned identification: some combination is determined far worse than the rest.
pub fn conditioning(stage: &StageReport) -> Option<Finding> {
    let id = &stage.identification;
    if id.rank == 0 || id.rows <= id.free.len() || id.condition_number <= CONDITION_WARNING {
        return None;
    }
    Some(Finding::warning(
        "ill-conditioned",
        format!(
            "stage '{}': condition number {:.3e} (above {CONDITION_WARNING:.0e}): the weakest parameter combination is determined {:.0}× worse than the best; spread the configurations over the joint ranges (`treecal check`, `treecal plan`) and look at the standard deviations",
            stage.name, id.condition_number, id.condition_number
        ),
    ))
}

/// The iteration limit was reached before the solver converged.
pub fn convergence(stage: &StageReport) -> Option<Finding> {
    (stage.identification.termination == Termination::MaxIterations).then(|| {
        Finding::warning(
            "not-converged",
            format!(
                "stage '{}': the solver stopped at its iteration limit ({} iterations) before converging",
                stage.name, stage.identification.iterations
            ),
        )
    })
}

/// Identified joint-angle errors (harmonics, backlash) too large for any real joint: a warning
/// above [`JOINT_ERROR_WARNING`], a failure above [`JOINT_ERROR_FAILED`], naming each joint with
/// its size (and standard deviation when identified).
pub fn joint_errors_plausible(run: &CalibrationRun, tree: &KinematicTree) -> Option<Finding> {
    let model = &run.report.model;
    let std_dev_of = |name: String| {
        run.parameters
            .iter()
            .find(|p| p.name == name)
            .and_then(|p| p.std_dev)
    };
    // (size, joint, description) of every term over the warning threshold.
    let mut large: Vec<(f64, &str, String)> = Vec::new();
    for (frame, f) in model.frames().iter().enumerate() {
        let [_, sine, cosine, backlash] = model.joint_error_values(frame);
        let joint = tree.joint(f.joint).name.as_str();
        if sine.is_some() || cosine.is_some() {
            let (a, b) = (sine.unwrap_or(0.0), cosine.unwrap_or(0.0));
            let amplitude = a.hypot(b);
            if amplitude > JOINT_ERROR_WARNING {
                let sd = |kind: &str| {
                    std_dev_of(format!("{joint} {kind}"))
                        .map_or(String::new(), |s| format!(" ± {:.2}", s.to_degrees()))
                };
                large.push((
                    amplitude,
                    joint,
                    format!(
                        "{joint} harmonic amplitude {:.2}° (sine {:.2}°{}, cosine {:.2}°{})",
                        amplitude.to_degrees(),
                        a.to_degrees(),
                        sd("sine"),
                        b.to_degrees(),
                        sd("cosine")
                    ),
                ));
            }
        }
        if let Some(h) = backlash.filter(|h| h.abs() > JOINT_ERROR_WARNING) {
            large.push((
                h.abs(),
                joint,
                format!("{joint} backlash {:.2}°", h.to_degrees()),
            ));
        }
    }
    let worst = large.iter().map(|(size, ..)| *size).fold(0.0, f64::max);
    if large.is_empty() {
        return None;
    }
    let text = format!(
        "identified joint-angle errors larger than any encoder or gear has ({} of {} joints over {:.1}°): {}. The fit traded them against the geometry (over a narrow joint range a harmonic looks like the zero offset, a backlash like it when the gravity torque keeps one sign), so joint_errors.yaml moves the joints wherever the data did not reach; use `prior`, leave `joint_errors` out, or freeze these terms (`freeze` '{first} sine', '{first} cosine', '{first} backlash')",
        large.len(),
        model.frames().len(),
        JOINT_ERROR_WARNING.to_degrees(),
        large
            .iter()
            .map(|(.., text)| text.as_str())
            .collect::<Vec<_>>()
            .join("; "),
        first = large[0].1
    );
    Some(if worst > JOINT_ERROR_FAILED {
        Finding::failed("joint-errors-implausible", text)
    } else {
        Finding::warning("joint-errors-implausible", text)
    })
}

/// The stiffness fit put some compliance scales at or below zero (held at the prior since).
pub fn stiffness_below_zero(report: &super::StiffnessReport) -> Option<Finding> {
    let held = &report.held_below_zero;
    (!held.is_empty()).then(|| {
        Finding::warning(
            "stiffness-below-zero",
            format!(
                "the stiffness fit put {} compliance scale(s) at or below zero, which no robot has, and holds them at the prior: {}. The data ask for a negative compliance there, so something the fit holds fixed is off (a compliance kept at the prior nearby, the stiffness file's structure, or the geometry); measure at a second payload (payload_kg) or give a wider `stiffness_prior`, and trust these compliances less",
                held.len(),
                held.join("; ")
            ),
        )
    })
}

/// RMS over the position errors (mm) after calibration of every arm of a data set.
fn rms_after(arms: &[super::outcome::ArmResiduals]) -> Option<f64> {
    let values: Vec<f64> = arms.iter().flat_map(|a| a.position_mm[1].clone()).collect();
    crate::math::root_mean_square(&values)
}

/// The RMS position error the validation data should show: the measurement noise (the RMS
/// identification residual) and the parameter uncertainty (the covariance prediction) added in
/// quadrature (mm).
fn expected_validation_rms(run: &CalibrationRun) -> Option<f64> {
    let noise = rms_after(&run.identification)?;
    let predicted = run.predicted_validation_rms_mm?;
    Some((noise * noise + predicted * predicted).sqrt()).filter(|e| e.is_finite() && *e > 0.0)
}

/// The validation rows the validation checks judge, per arm: RMS position error before and
/// after (mm) over them.
struct JudgedArm<'a> {
    arm: &'a str,
    before: f64,
    after: f64,
}

/// The validation rows the checks judge. Every row counts in the report's figures; a gross
/// blunder (a bumped target, a mistyped joint value) would decide these checks alone — one
/// 600 mm row makes any calibration "no better than the nominal robot" — so the checks judge
/// the rows without the gross blunders ([`validation_set_aside`]) and say so (`set_aside`
/// counts the rows they left out).
struct JudgedValidation<'a> {
    arms: Vec<JudgedArm<'a>>,
    after_rms: Option<f64>,
    set_aside: usize,
}

/// Per validation row (in validation order): whether the validation checks set it aside — a
/// gross blunder ([`super::gross_rows`]: flagged as an outlier by the robust loss and at least
/// [`super::GROSS_FACTOR`] times the RMS of the rows not flagged). Every row still counts in the
/// reported figures; only the pass/fail comparisons skip these.
pub fn validation_set_aside(run: &CalibrationRun) -> Vec<bool> {
    let rows: usize = run.validation.iter().map(|a| a.position_mm[1].len()).sum();
    let flagged =
        super::robust::outlier_mask(&run.outliers, super::robust::DataSet::Validation, rows);
    let mut errors = vec![0.0; rows];
    for arm in &run.validation {
        for (&row, &error) in arm.rows.iter().zip(&arm.position_mm[1]) {
            if row < rows {
                errors[row] = error;
            }
        }
    }
    super::gross_rows(&errors, &flagged)
}

fn judged_validation(run: &CalibrationRun) -> JudgedValidation<'_> {
    let flagged = validation_set_aside(run);
    let set_aside = flagged.iter().filter(|&&f| f).count();
    let keep = |row: usize| !flagged.get(row).copied().unwrap_or(false);
    let rms = |values: Vec<f64>| crate::math::root_mean_square(&values);
    let mut all_after = Vec::new();
    let arms = run
        .validation
        .iter()
        .filter_map(|arm| {
            let kept = |k: usize| -> Vec<f64> {
                arm.rows
                    .iter()
                    .zip(&arm.position_mm[k])
                    .filter(|(&row, _)| keep(row))
                    .map(|(_, &v)| v)
                    .collect()
            };
            let after = kept(1);
            all_after.extend_from_slice(&after);
            Some(JudgedArm {
                arm: &arm.arm,
                before: rms(kept(0))?,
                after: rms(after)?,
            })
        })
        .collect();
    JudgedValidation {
        arms,
        after_rms: rms(all_after),
        set_aside,
    }
}

impl JudgedValidation<'_> {
    /// How the rows were chosen, for a finding's message (empty when every row is judged).
    fn rows_judged(&self) -> String {
        if self.set_aside == 0 {
            String::new()
        } else {
            format!(
                " (judged without the {} gross blunder(s) among the validation rows flagged as outliers, each at least {}× the RMS of the others, named in the outliers warning; they count in every figure of the report)",
                self.set_aside,
                super::GROSS_FACTOR
            )
        }
    }
}

/// On the validation data the calibrated model must beat the registered nominal one (RMS
/// position error over every row but the gross blunders, [`validation_set_aside`]), unless the nominal model is
/// already within the noise.
pub fn validation_improves(run: &CalibrationRun) -> Option<Finding> {
    let expected = expected_validation_rms(run);
    let judged = judged_validation(run);
    let worse: Vec<String> = judged
        .arms
        .iter()
        .filter(|arm| arm.after >= arm.before)
        // A nominal model already at the noise floor cannot be improved measurably.
        .filter(|arm| expected.is_none_or(|e| arm.before > 2.0 * e))
        .map(|arm| {
            format!(
                "{} (RMS position error {:.4} mm before, {:.4} mm after)",
                arm.arm, arm.before, arm.after
            )
        })
        .collect();
    (!worse.is_empty()).then(|| {
        Finding::failed(
            "validation-worse",
            format!(
                "on the validation data the calibrated model is no better than the nominal one: {}{}; the calibration does not describe the robot (swapped tools or columns, units, or validation data from another set-up)",
                worse.join("; "),
                judged.rows_judged()
            ),
        )
    })
}

/// The validation error (over every row but the gross blunders, [`validation_set_aside`]) against what the
/// identification predicts for it.
pub fn validation_matches_prediction(run: &CalibrationRun) -> Option<Finding> {
    let expected = expected_validation_rms(run)?;
    let judged = judged_validation(run);
    let actual = judged.after_rms?;
    let ratio = actual / expected;
    let message = format!(
        "the RMS validation position error {actual:.4} mm{} is {ratio:.1}× what the identification predicts ({expected:.4} mm: its residuals and the parameter uncertainty); the model fits the identification data but does not carry over (too few or too similar configurations, or validation data taken differently)",
        judged.rows_judged()
    );
    if ratio > VALIDATION_FAILED {
        Some(Finding::failed("validation-prediction", message))
    } else if ratio > VALIDATION_WARNING {
        Some(Finding::warning("validation-prediction", message))
    } else {
        None
    }
}
