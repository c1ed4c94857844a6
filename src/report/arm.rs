//! The errors of one arm's tool on one data set, row by row (the calibrate report's Table 3
//! rows and plots; the validation strata group them).

use crate::calibration::{ArmResiduals, CalibrationRun, DataSet, ErrorSummary, Stratum};
use rayon::prelude::*;
use serde::Serialize;

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
    /// n-th row of the set) until [`CalibrationSummary::name_rows`](super::CalibrationSummary::name_rows) names it.
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
        marks: &(dyn Fn(usize) -> RowMarks + Sync),
    ) -> Self {
        // In parallel, in order (a label per row: 8·10⁵ rows per arm at 10⁶ configurations).
        let rows = arm
            .rows
            .par_iter()
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
                    predicted_sd_mm: (!predicted.is_empty())
                        .then(|| kept.binary_search(&index).ok())
                        .flatten()
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
    pub(super) fn of_set(run: &CalibrationRun, set: DataSet) -> Vec<Self> {
        let (arms, predicted): (&[ArmResiduals], &[f64]) = match set {
            DataSet::Identification => (&run.identification, &[]),
            DataSet::Validation => (&run.validation, &run.predicted_validation_sd_mm),
        };
        let mut kept: Vec<usize> = arms.iter().flat_map(|a| a.rows.iter().copied()).collect();
        kept.sort_unstable();
        let flagged = crate::calibration::outlier_mask(
            &run.outliers,
            set,
            kept.last().map_or(0, |&last| last + 1),
        );
        let marks = |index: usize| RowMarks {
            stratum: match set {
                DataSet::Validation => run.validation_strata.get(index).copied(),
                DataSet::Identification => None,
            },
            outlier: flagged.get(index).copied().unwrap_or(false),
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
