//! The report of `treecal calibrate`: a serialisable summary for JSON (`report.json`) and the
//! parameter file (`params.yaml`). Its rows per arm are in `arm`, its markdown and plots in
//! `calibrate_markdown`.

pub use super::arm::ArmReport;
use super::artifact::ArtifactReport;
use super::outliers::{robust_summary, OutlierRow, RobustSummary};
use super::stiffness::StiffnessSummary;
use super::strata::ValidationStrata;
use crate::calibration::DataSet;
use crate::calibration::{CalibrationRun, ParameterEstimate, Termination, Verdict};
use crate::math::{rpy_from_rotation, Pose};
use rayon::prelude::*;
use serde::Serialize;

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
/// Version 3 writes every enum value in snake_case (`stages[].termination` was `CostConverged`
/// in version 2); readers accept versions 1 to 3 ([`REPORT_SCHEMA_VERSIONS`]).
pub const REPORT_SCHEMA: &str = "treecal.report/3";

/// The `report.json` layouts `verify` and `compare` read: every version up to
/// [`REPORT_SCHEMA`] (version 1 has no `schema_version`).
pub const REPORT_SCHEMA_VERSIONS: std::ops::RangeInclusive<u32> = 1..=3;

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
    /// Why it stopped (JSON: `step_converged`, `cost_converged`, `no_decrease`,
    /// `max_iterations`).
    pub termination: Termination,
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
    /// Validation rows at repeated identification postures against the identification rows
    /// there, without a model: the floor under their held-out error.
    pub repeatability: Option<crate::calibration::Repeatability>,
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
            // In parallel: 2·10⁶ ids at 10⁶ configurations.
            for arm in arms.iter_mut() {
                arm.rows.par_iter_mut().for_each(|row| {
                    if let Some(id) = ids.get(row.index) {
                        row.id.clone_from(id);
                    }
                });
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
                termination: id.termination,
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
        repeatability: run.repeatability.clone(),
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

/// The held-out headline: RMS position error over every validation row, the rows, the
/// registered nominal robot's RMS, and the rows the robust loss flagged (marked, counted).
pub(super) struct Headline {
    pub rms: f64,
    pub observations: usize,
    pub before_rms: f64,
    /// With flagged rows: how many, and the RMS after and before over the other rows (mm).
    pub without_flagged: Option<(usize, f64, f64)>,
}

impl Headline {
    /// ", K of them flagged as outliers (marked and counted; without them A mm, before B mm)",
    /// or nothing.
    pub fn flagged_text(&self) -> String {
        self.without_flagged
            .map_or(String::new(), |(count, after, before)| {
                format!(
                    "; {count} of them flagged as outliers, marked and counted (without them: {after:.3} mm, before {before:.3} mm)"
                )
            })
    }
}

pub(super) fn held_out_headline(summary: &CalibrationSummary) -> Option<Headline> {
    let all = summary.validation_strata.as_ref()?.strata.first()?;
    let rms = all.rms_position_mm?;
    let rows = || summary.validation.iter().flat_map(|a| a.rows.iter());
    let root_mean_square = |values: Vec<f64>| crate::math::root_mean_square(&values).unwrap_or(0.0);
    let before_rms = root_mean_square(rows().map(|r| r.position_mm.before).collect());
    let flagged = rows().filter(|r| r.outlier).count();
    let without_flagged = (flagged > 0 && flagged < all.observations).then(|| {
        let kept = || rows().filter(|r| !r.outlier);
        (
            flagged,
            root_mean_square(kept().map(|r| r.position_mm.after).collect()),
            root_mean_square(kept().map(|r| r.position_mm.before).collect()),
        )
    });
    Some(Headline {
        rms,
        observations: all.observations,
        before_rms,
        without_flagged,
    })
}
