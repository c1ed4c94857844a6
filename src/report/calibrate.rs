//! The report of `treecal calibrate`: the paper's Table 2 (calibrated parameters) and Table 3
//! (errors before and after, per arm) layouts in markdown, a serialisable summary for JSON, the
//! parameter file (`params.yaml`) and the per-configuration error plots (Fig. 9–12 style).

use super::artifact::ArtifactReport;
use super::outliers::{outliers_markdown, robust_summary, OutlierRow, RobustSummary};
use super::plot::arm_error_plots_by_id;
use super::stiffness::StiffnessSummary;
use super::strata::ValidationStrata;
use crate::calibration::DataSet;
use crate::calibration::Stratum;
use crate::calibration::{
    ArmResiduals, CalibrationRun, ErrorSummary, IdentificationOptions, ParameterEstimate, Status,
    Verdict,
};
use crate::error::Result;
use crate::math::{rpy_from_rotation, Pose};
use serde::Serialize;
use std::fmt::Write;

/// What the report says about where the data came from.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationContext {
    /// Robot name.
    pub robot: String,
    /// The measurement file.
    pub measurements: String,
    /// Where the validation data came from (a file, or the held-out fifth).
    pub validation: String,
    /// Plan name (`staged`, `simultaneous` or a file).
    pub plan: String,
    /// Whether flexibility was compensated (a stiffness file was given).
    pub compensation: String,
    /// Assumed noise: position σ (m) and rotation σ (rad) (JSON: `position_m`,
    /// `rotation_rad`).
    #[serde(serialize_with = "sigma_json")]
    pub sigma: [f64; 2],
    /// How the measurement frame was found (fitted, or the root frame).
    pub measurement_frame: String,
}

fn sigma_json<S: serde::Serializer>(
    sigma: &[f64; 2],
    serializer: S,
) -> std::result::Result<S::Ok, S::Error> {
    crate::serde_labels::labelled(sigma, ["position_m", "rotation_rad"], serializer)
}

/// The `schema_version` of `report.json` (its layout is documented in docs/file-formats.md).
pub const REPORT_SCHEMA: &str = "treecal.report/2";

/// One stage's solver outcome.
#[derive(Debug, Clone, Serialize)]
pub struct StageOutcome {
    /// Stage name.
    pub name: String,
    /// Measurements used.
    pub measurements: usize,
    /// Equations (rows: 6 per pose, 3 per position observation).
    pub rows: usize,
    /// Accepted iterations (of the last plan cycle).
    pub iterations: usize,
    /// Why it stopped.
    pub termination: String,
    /// Final weighted cost ½‖r‖².
    pub cost: f64,
    /// Numerical rank / free parameters.
    pub rank: usize,
    /// Free parameters (including locked-arm tools of a coupled stage).
    pub parameters: usize,
    /// Condition number of the column-scaled Jacobian.
    pub condition_number: f64,
    /// RMS position residual (mm).
    pub residual_rms_position_mm: f64,
    /// RMS rotation residual (deg).
    pub residual_rms_rotation_deg: f64,
    /// σ̂: residuals against the assumed noise (1 = as expected).
    pub residual_scale: f64,
    /// The parameter combinations the stage's data cannot determine, in words.
    pub unidentifiable: Vec<String>,
}

/// The machine-readable report (`report.json`).
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationSummary {
    /// `ok`, `warning` or `failed`, and every finding of the checks (notes included).
    pub verdict: Verdict,
    /// [`REPORT_SCHEMA`].
    pub schema_version: &'static str,
    /// Inputs.
    pub context: CalibrationContext,
    /// The fitted measurement frame: `xyz` (m) and `rpy` (rad) of the robot base in it.
    pub measurement_frame: FrameValues,
    /// RMS position distance before / after the closed-form initial guess (m; JSON:
    /// `before`, `after`).
    #[serde(serialize_with = "crate::serde_labels::before_after")]
    pub initial_guess_rms_m: [f64; 2],
    /// How the measurement frame was refined jointly with the parameters, if it was.
    pub frame_refinement: Option<crate::calibration::FrameRefinement>,
    /// Plan repetitions.
    pub cycles: usize,
    /// Per stage.
    pub stages: Vec<StageOutcome>,
    /// Every parameter.
    pub parameters: Vec<ParameterEstimate>,
    /// Errors on the identification data, per arm, with every row's errors.
    pub identification: Vec<ArmReport>,
    /// Errors on the validation data, per arm, with every row's errors (every row counts;
    /// outliers are marked).
    pub validation: Vec<ArmReport>,
    /// The validation position error by stratum (repeat, inside, outside the identification
    /// ranges) and the worst row (renamed by [`CalibrationSummary::name_rows`]).
    pub validation_strata: Option<ValidationStrata>,
    /// RMS validation position error the parameter covariance predicts (mm).
    pub predicted_validation_rms_mm: Option<f64>,
    /// The predicted position error standard deviation per validation observation (mm), in
    /// the order of the validation rows kept; in JSON each validation row carries its own
    /// (`predicted_sd_mm`).
    #[serde(skip)]
    pub predicted_validation_sd_mm: Vec<f64>,
    /// Joints whose URDF origin (or axis) the export changed.
    pub changed_joints: Vec<String>,
    /// How the robust estimation ran.
    pub robust: RobustSummary,
    /// The measurements named as outliers (left out of the fit or the statistics); filled by
    /// the caller with [`super::outliers::outlier_rows`], which needs the rows' ids.
    pub outliers: Vec<OutlierRow>,
    /// The outputs validated as written: the URDF alone, with its compensation file, and
    /// the registration (filled by the workflow).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub artifact: Option<ArtifactReport>,
    /// The stiffness identification (`--identify-stiffness`), if it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<StiffnessSummary>,
    /// The measurement sessions, when the data name any (`session` column).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sessions: Option<super::sessions::SessionsSummary>,
}

/// The errors of one arm's tool on one data set (identification or validation).
#[derive(Debug, Clone, Serialize)]
pub struct ArmReport {
    /// The arm (branch name).
    pub arm: String,
    /// The arm's tool link (the CSV's `tool`).
    pub tool: String,
    /// Observations of this tool in the set (identification: the outliers left out of the fit
    /// are left out; validation: every row).
    pub observations: usize,
    /// Before calibration: the nominal robot registered like the calibrated one (measurement
    /// frame when fitted, tool frames: least squares on the identification rows), rigid.
    pub before: ErrorSummary,
    /// After calibration.
    pub after: ErrorSummary,
    /// % of the RMS position error removed.
    pub position_removed_percent: f64,
    /// % of the RMS orientation error removed (`null` for position-only data).
    pub orientation_removed_percent: Option<f64>,
    /// Every observation, in file order.
    pub rows: Vec<RowErrors>,
}

/// The errors at one measurement row, named by its id.
#[derive(Debug, Clone, Serialize)]
pub struct RowErrors {
    /// The row's `id` (the CSV's id column, else its 1-based data row number); `#n` (the
    /// n-th row of the set) until [`CalibrationSummary::name_rows`] names it.
    pub id: String,
    /// The row's index in its data set (identification or validation, outliers included).
    #[serde(skip)]
    pub index: usize,
    /// Position error (mm) before and after calibration.
    pub position_mm: BeforeAfter,
    /// Orientation error (deg) before and after calibration; absent for positions.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation_deg: Option<BeforeAfter>,
    /// Validation rows: the position error standard deviation the parameter covariance
    /// predicts here (mm); absent elsewhere or when no covariance was available.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_sd_mm: Option<f64>,
    /// Validation rows: whether the posture repeats an identification posture, is new inside
    /// the identification joint ranges, or lies outside them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stratum: Option<Stratum>,
    /// Whether the robust loss names the row an outlier (a validation outlier is still
    /// counted in every figure).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub outlier: bool,
    /// The robust weight of an identification row the fit down-weighted (below 1); absent at
    /// weight 1 and for validation rows.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub weight: Option<f64>,
}

/// What marks a row besides its errors: stratum, outlier, robust weight.
#[derive(Debug, Clone, Copy, Default)]
struct RowMarks {
    stratum: Option<Stratum>,
    outlier: bool,
    weight: Option<f64>,
}

/// A quantity before and after calibration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BeforeAfter {
    /// Before calibration.
    pub before: f64,
    /// After calibration.
    pub after: f64,
}

impl ArmReport {
    /// The report of `arm`; `predicted[i]`: the predicted spread at the set's `i`-th kept row
    /// (empty for none).
    fn of(
        arm: &ArmResiduals,
        kept: &[usize],
        predicted: &[f64],
        marks: &dyn Fn(usize) -> RowMarks,
    ) -> Self {
        let rows = arm
            .rows
            .iter()
            .enumerate()
            .map(|(k, &index)| {
                let pair = |values: &[Vec<f64>; 2]| {
                    Some(BeforeAfter {
                        before: *values[0].get(k)?,
                        after: *values[1].get(k)?,
                    })
                };
                let mark = marks(index);
                RowErrors {
                    stratum: mark.stratum,
                    outlier: mark.outlier,
                    weight: mark.weight,
                    id: format!("#{}", index + 1),
                    index,
                    position_mm: pair(&arm.position_mm).unwrap_or(BeforeAfter {
                        before: f64::NAN,
                        after: f64::NAN,
                    }),
                    orientation_deg: pair(&arm.orientation_deg),
                    predicted_sd_mm: kept
                        .binary_search(&index)
                        .ok()
                        .and_then(|j| predicted.get(j).copied()),
                }
            })
            .collect();
        Self {
            arm: arm.arm.clone(),
            tool: arm.tool.clone(),
            observations: arm.observations,
            before: arm.before,
            after: arm.after,
            position_removed_percent: arm.position_removed_percent,
            orientation_removed_percent: arm.orientation_removed_percent,
            rows,
        }
    }

    /// The reports of `arms`, one data set; `predicted`: the spread per kept row of the set,
    /// in file order (empty for none).
    fn of_set(run: &CalibrationRun, set: DataSet) -> Vec<Self> {
        let (arms, predicted): (&[ArmResiduals], &[f64]) = match set {
            DataSet::Identification => (&run.identification, &[]),
            DataSet::Validation => (&run.validation, &run.predicted_validation_sd_mm),
        };
        let mut kept: Vec<usize> = arms.iter().flat_map(|a| a.rows.iter().copied()).collect();
        kept.sort_unstable();
        let marks = |index: usize| RowMarks {
            stratum: match set {
                DataSet::Validation => run.validation_strata.get(index).copied(),
                DataSet::Identification => None,
            },
            outlier: run
                .outliers
                .iter()
                .any(|o| o.set == set && o.index == index),
            weight: match set {
                DataSet::Identification => {
                    run.robust.weights.get(index).copied().filter(|&w| w < 1.0)
                }
                DataSet::Validation => None,
            },
        };
        arms.iter()
            .map(|arm| Self::of(arm, &kept, predicted, &marks))
            .collect()
    }
}

impl CalibrationSummary {
    /// The identification rows the fit kept with a robust weight below 1: `(id, weight,
    /// position error after calibration in mm)`, in file order.
    pub fn down_weighted(&self) -> Vec<(String, f64, f64)> {
        self.identification
            .iter()
            .flat_map(|a| a.rows.iter())
            .filter_map(|r| r.weight.map(|w| (r.id.clone(), w, r.position_mm.after)))
            .collect()
    }

    /// Names every row by its id: `ids[0]` for the identification data, `ids[1]` for the
    /// validation data, in the order the run got them (a missing id stays `#n`).
    pub fn name_rows(&mut self, ids: [&[String]; 2]) {
        for (arms, ids) in [
            (&mut self.identification, ids[0]),
            (&mut self.validation, ids[1]),
        ] {
            for row in arms.iter_mut().flat_map(|a| a.rows.iter_mut()) {
                if let Some(id) = ids.get(row.index) {
                    row.id.clone_from(id);
                }
            }
        }
        self.validation_strata = ValidationStrata::of(&self.validation);
    }
}

/// A frame as URDF writes it.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FrameValues {
    /// Translation (m).
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw (rad).
    pub rpy: [f64; 3],
}

impl FrameValues {
    fn of(pose: &Pose) -> Self {
        let t = pose.translation.vector;
        Self {
            xyz: [t.x, t.y, t.z],
            rpy: rpy_from_rotation(&pose.rotation),
        }
    }
}

/// Collects the summary of a calibration run; `names` describes each stage's unidentifiable
/// combinations (the caller knows the stage models).
pub fn calibration_summary(
    context: CalibrationContext,
    run: &CalibrationRun,
    unidentifiable: Vec<Vec<String>>,
    changed_joints: Vec<String>,
) -> CalibrationSummary {
    let stages = run
        .report
        .stages
        .iter()
        .zip(
            unidentifiable
                .into_iter()
                .chain(std::iter::repeat(Vec::new())),
        )
        .map(|(stage, names)| {
            let id = &stage.identification;
            StageOutcome {
                name: stage.name.clone(),
                measurements: stage.measurements,
                rows: id.rows,
                iterations: id.iterations,
                termination: format!("{:?}", id.termination),
                cost: id.costs.last().copied().unwrap_or(f64::NAN),
                rank: id.rank,
                parameters: id.free.len(),
                condition_number: id.condition_number,
                residual_rms_position_mm: id.residual_rms_position * 1e3,
                residual_rms_rotation_deg: id.residual_rms_rotation.to_degrees(),
                residual_scale: id.residual_scale,
                unidentifiable: names,
            }
        })
        .collect();
    let validation = ArmReport::of_set(run, DataSet::Validation);
    CalibrationSummary {
        verdict: Verdict::from_findings(run.findings.clone()),
        schema_version: REPORT_SCHEMA,
        context,
        measurement_frame: FrameValues::of(&run.guess.world_from_base),
        initial_guess_rms_m: [run.guess.rms_before, run.guess.rms_after],
        frame_refinement: run.frame_refinement.clone(),
        cycles: run.report.cycles,
        stages,
        parameters: run.parameters.clone(),
        identification: ArmReport::of_set(run, DataSet::Identification),
        validation_strata: ValidationStrata::of(&validation),
        validation,
        predicted_validation_rms_mm: run.predicted_validation_rms_mm,
        predicted_validation_sd_mm: run.predicted_validation_sd_mm.clone(),
        changed_joints,
        robust: robust_summary(run),
        // The caller knows the rows' ids and the tool names: see `outlier_rows`.
        outliers: Vec::new(),
        artifact: None,
        stiffness: None,
        sessions: run.sessions.as_ref().map(super::sessions::sessions_summary),
    }
}

/// `params.yaml`: the parameters with their units, and the measurement frame; `treecal export`
/// reads the `name` and `calibrated` of every entry.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterFile<'a> {
    /// Robot name.
    pub robot: &'a str,
    /// Units of the values.
    pub units: &'a str,
    /// The fitted measurement frame (not part of the URDF).
    pub measurement_frame: FrameValues,
    /// Every MCPC parameter.
    pub parameters: &'a [ParameterEstimate],
}

/// The `params.yaml` contents of a run.
pub fn parameter_file<'a>(robot: &'a str, run: &'a CalibrationRun) -> ParameterFile<'a> {
    ParameterFile {
        robot,
        units: "SI: rad for alpha, beta, gamma; m for x, y, z (report.md shows deg and mm)",
        measurement_frame: FrameValues::of(&run.guess.world_from_base),
        parameters: &run.parameters,
    }
}

fn display(p: &ParameterEstimate, value: f64) -> f64 {
    if p.unit == "rad" {
        value.to_degrees()
    } else {
        value * 1e3
    }
}

fn number(value: Option<f64>, digits: usize) -> String {
    match value {
        Some(v) if v.is_finite() => format!("{v:.digits$}"),
        _ => "—".into(),
    }
}

/// The markdown report (`report.md`).
pub fn calibration_markdown(
    summary: &CalibrationSummary,
    options: &IdentificationOptions,
) -> String {
    let mut out = String::new();
    let c = &summary.context;
    let _ = writeln!(out, "# Calibration of '{}'\n", c.robot);
    verdict_markdown(&mut out, &summary.verdict);
    headline_markdown(&mut out, summary);
    let _ = writeln!(
        out,
        "Measurements: {}. Validation: {}. Plan: {} ({} cycle(s)). Flexibility: {}. Assumed noise: σ = {:.4} mm, {:.4} mrad.\n",
        c.measurements,
        c.validation,
        c.plan,
        summary.cycles,
        c.compensation,
        options.position_sigma * 1e3,
        options.rotation_sigma * 1e3,
    );
    let f = &summary.measurement_frame;
    let _ = writeln!(
        out,
        "Measurement frame ({}): robot base at xyz = ({:.4}, {:.4}, {:.4}) m, rpy = ({:.4}, {:.4}, {:.4}) deg; RMS position distance of the nominal model {:.2} mm before the initial fit, {:.2} mm after.\n",
        c.measurement_frame,
        f.xyz[0],
        f.xyz[1],
        f.xyz[2],
        f.rpy[0].to_degrees(),
        f.rpy[1].to_degrees(),
        f.rpy[2].to_degrees(),
        summary.initial_guess_rms_m[0] * 1e3,
        summary.initial_guess_rms_m[1] * 1e3,
    );

    if let Some(r) = &summary.frame_refinement {
        let _ = writeln!(
            out,
            "The measurement frame was then refined with the parameters through the deflections ({} iteration(s), {} of 6 directions determined; moved by {:.4} deg and {:.3} mm; cost {:.4e} → {:.4e}).\n",
            r.iterations,
            r.determined,
            r.correction[0].to_degrees(),
            r.correction[1] * 1e3,
            r.cost[0],
            r.cost[1]
        );
    }

    // Table 3 layout.
    let _ = writeln!(
        out,
        "\"Before\" is the nominal robot (the URDF's geometry) registered like the calibrated one: its {} tool frames fitted by least squares to the identification rows with the fit's weights (rigid). \"After\" is the calibrated model{}. Every validation row counts; RMS is the headline figure.\n",
        if c.measurement_frame.starts_with("fitted") {
            "measurement frame and"
        } else {
            ""
        },
        if c.compensation.starts_with("compensated") {
            " with its predicted deflections"
        } else {
            ""
        }
    );
    for (title, arms) in [
        ("measurement configurations", &summary.identification),
        ("validation configurations", &summary.validation),
    ] {
        if arms.is_empty() {
            continue;
        }
        let _ = writeln!(out, "## Errors on the {title} (paper Table 3 layout)\n");
        let _ = writeln!(
            out,
            "| arm | n | | before RMS | before max | before mean | after RMS | after max | after mean | RMS removed |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
        for arm in arms {
            let _ = writeln!(
                out,
                "| {} | {} | position (mm) | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.2} % |",
                arm.arm,
                arm.observations,
                arm.before.rms_position_mm,
                arm.before.max_position_mm,
                arm.before.mean_position_mm,
                arm.after.rms_position_mm,
                arm.after.max_position_mm,
                arm.after.mean_position_mm,
                arm.position_removed_percent
            );
            if arm.before.mean_orientation_deg.is_some() {
                let _ = writeln!(
                    out,
                    "| {} | {} | orientation (deg) | {} | {} | {} | {} | {} | {} | {} % |",
                    arm.arm,
                    arm.observations,
                    number(arm.before.rms_orientation_deg, 5),
                    number(arm.before.max_orientation_deg, 5),
                    number(arm.before.mean_orientation_deg, 5),
                    number(arm.after.rms_orientation_deg, 5),
                    number(arm.after.max_orientation_deg, 5),
                    number(arm.after.mean_orientation_deg, 5),
                    number(arm.orientation_removed_percent, 2),
                );
            }
        }
        out.push('\n');
    }
    if let Some(strata) = &summary.validation_strata {
        out.push_str(&strata.markdown());
    }
    if let Some(rms) = summary.predicted_validation_rms_mm {
        let mut spread = summary.predicted_validation_sd_mm.clone();
        spread.sort_by(f64::total_cmp);
        let at = |f: f64| spread[((spread.len() - 1) as f64 * f).round() as usize];
        let _ = writeln!(
            out,
            "The parameter covariance predicts the position error the measurement noise alone leaves at the validation configurations: RMS {rms:.4} mm; per observation a standard deviation of {:.4} mm (median), {:.4} mm (95th percentile), {:.4} mm (largest). The model error adds to it.\n",
            at(0.5),
            at(0.95),
            at(1.0)
        );
    }

    if let Some(artifact) = &summary.artifact {
        out.push_str(&artifact.markdown());
    }
    out.push_str(&outliers_markdown(
        &summary.robust,
        &summary.outliers,
        &summary.down_weighted(),
    ));

    // Solver outcome.
    let _ = writeln!(out, "## Solver, per stage\n");
    let _ = writeln!(
        out,
        "| stage | measurements | equations | iterations | termination | cost | rank | condition | residual RMS | σ̂ |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
    for s in &summary.stages {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.4e} | {}/{} | {:.3e} | {:.4} mm, {:.5} deg | {:.3} |",
            s.name,
            s.measurements,
            s.rows,
            s.iterations,
            s.termination,
            s.cost,
            s.rank,
            s.parameters,
            s.condition_number,
            s.residual_rms_position_mm,
            s.residual_rms_rotation_deg,
            s.residual_scale
        );
    }
    out.push('\n');
    let _ = writeln!(
        out,
        "σ̂ is the residual against the assumed noise (√(2·cost/(rows − rank)); 1 means the residuals are as large as the noise alone explains; much larger means model error or underestimated noise).\n"
    );
    for s in &summary.stages {
        if !s.unidentifiable.is_empty() {
            let _ = writeln!(
                out,
                "Stage '{}': {} combination(s) the data cannot determine (kept at their starting values):\n",
                s.name,
                s.unidentifiable.len()
            );
            for name in &s.unidentifiable {
                let _ = writeln!(out, "- {name}");
            }
            out.push('\n');
        }
    }

    // Table 2 layout.
    let _ = writeln!(
        out,
        "## Calibrated parameters (paper Table 2 layout; deg and mm)\n"
    );
    let _ = writeln!(
        out,
        "| frame | parameter | nominal | calibrated | change | std. dev. | identifiable |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for p in &summary.parameters {
        let _ = writeln!(
            out,
            "| {} | {} ({}) | {:.4} | {:.4} | {:+.4} | {} | {} |",
            p.owner,
            p.kind,
            if p.unit == "rad" { "deg" } else { "mm" },
            display(p, p.nominal),
            display(p, p.calibrated),
            display(p, p.change),
            number(p.std_dev.map(|s| display(p, s)), 4),
            if p.identifiable { "yes" } else { "no" }
        );
    }
    out.push('\n');
    starts_markdown(&mut out, &summary.parameters);
    if !summary.changed_joints.is_empty() {
        let _ = writeln!(
            out,
            "calibrated.urdf: the origins (and, where needed, axes) of {} joint(s) changed: {}.",
            summary.changed_joints.len(),
            summary.changed_joints.join(", ")
        );
    }
    out
}

/// The held-out accuracy in mm, whatever σ was declared: every validation row, the
/// registered nominal robot, and what the written URDF gives alone.
/// The held-out headline: the RMS position error over every validation row (mm), the row
/// count, and the registered nominal robot's RMS over the same rows (mm); `None` without
/// validation figures.
pub(super) fn held_out_headline(summary: &CalibrationSummary) -> Option<(f64, usize, f64)> {
    let all = summary.validation_strata.as_ref()?.strata.first()?;
    let rms = all.rms_position_mm?;
    let before: Vec<f64> = summary
        .validation
        .iter()
        .flat_map(|a| a.rows.iter().map(|r| r.position_mm.before))
        .collect();
    let before_rms =
        (before.iter().map(|v| v * v).sum::<f64>() / before.len().max(1) as f64).sqrt();
    Some((rms, all.observations, before_rms))
}

fn headline_markdown(out: &mut String, summary: &CalibrationSummary) {
    let Some((rms, observations, before_rms)) = held_out_headline(summary) else {
        return;
    };
    let _ = write!(
        out,
        "**Held-out accuracy:** RMS position error {rms:.3} mm over all {} validation rows (before: {before_rms:.3} mm, the registered nominal robot)",
        observations
    );
    if let Some(alone) = summary
        .artifact
        .as_ref()
        .and_then(|a| a.urdf_alone.as_ref())
    {
        let _ = write!(
            out,
            "; {} as written: {:.3} mm",
            alone.files, alone.errors.rms_position_mm
        );
    }
    out.push_str(".\n\n");
}

/// The parameters whose fit started away from the URDF value (the closed-form fit of the
/// measured frames), listed apart from Table 2's nominal column.
fn starts_markdown(out: &mut String, parameters: &[ParameterEstimate]) {
    let moved: Vec<String> = parameters
        .iter()
        .filter(|p| (p.start - p.nominal).abs() > 1e-9)
        .map(|p| {
            let unit = if p.unit == "rad" { "deg" } else { "mm" };
            format!("{} {} {:.4} {unit}", p.owner, p.kind, display(p, p.start))
        })
        .collect();
    if !moved.is_empty() {
        let _ = writeln!(
            out,
            "Closed-form start (initial guess of the measured frames, not the URDF; the nominal column is the URDF's value): {}.\n",
            moved.join(", ")
        );
    }
}

/// The verdict and its reasons, as the report's first section.
fn verdict_markdown(out: &mut String, verdict: &Verdict) {
    let meaning = match verdict.status {
        Status::Ok => "the result can be used",
        Status::Warning => "the result can be used, but read the warnings",
        Status::Failed => "the result must not be used; calibrated.urdf was not written",
    };
    let _ = writeln!(out, "**Verdict: {}** ({meaning}).\n", verdict.status);
    for reason in &verdict.reasons {
        let label = match reason.status {
            Status::Ok => "note",
            Status::Warning => "warning",
            Status::Failed => "failed",
        };
        let _ = writeln!(out, "- {label} ({}): {}", reason.code, reason.message);
    }
    if !verdict.reasons.is_empty() {
        out.push('\n');
    }
}

/// The per-configuration error plots of one data set: `(file stem, SVG)` per arm and quantity,
/// stems `<arm>_<set>_<quantity>`, the x axis labelled by the rows' ids.
pub fn calibration_plots(arms: &[ArmReport], set: &str) -> Result<Vec<(String, String)>> {
    let mut plots = Vec::new();
    for arm in arms {
        // Outliers stay in the plots, marked `*`.
        let ids: Vec<String> = arm
            .rows
            .iter()
            .map(|r| {
                if r.outlier {
                    format!("{}*", r.id)
                } else {
                    r.id.clone()
                }
            })
            .collect();
        let marked = arm.rows.iter().any(|r| r.outlier);
        let column = |f: &dyn Fn(&RowErrors) -> Option<f64>| -> Vec<f64> {
            arm.rows.iter().filter_map(f).collect()
        };
        let position = [
            column(&|r| Some(r.position_mm.before)),
            column(&|r| Some(r.position_mm.after)),
        ];
        let orientation = [
            column(&|r| r.orientation_deg.map(|o| o.before)),
            column(&|r| r.orientation_deg.map(|o| o.after)),
        ];
        // Rows observing a position only (a mixed file) have no orientation error: the
        // orientation plot is labelled by the rows that have one.
        let oriented: Vec<String> = ids
            .iter()
            .zip(&arm.rows)
            .filter(|(_, r)| r.orientation_deg.is_some())
            .map(|(id, _)| id.clone())
            .collect();
        let title = format!(
            "on the {set} configurations{}",
            if marked {
                " (* outlier, still counted)"
            } else {
                ""
            }
        );
        let labels = ["before calibration", "after calibration"];
        let stem = format!("{}_{set}", arm.arm);
        let none = [Vec::new(), Vec::new()];
        plots.extend(arm_error_plots_by_id(
            &arm.arm, &stem, &title, &labels, &ids, &position, &none,
        )?);
        plots.extend(arm_error_plots_by_id(
            &arm.arm,
            &stem,
            &title,
            &labels,
            &oriented,
            &none,
            &orientation,
        )?);
    }
    Ok(plots)
}
