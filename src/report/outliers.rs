//! The outliers of a calibration (robust estimation): the `"outliers"` list of `report.json`
//! and its table in `report.md`.

use crate::calibration::CalibrationRun;
use crate::calibration::{DataSet, RobustLoss};
use crate::tree::KinematicTree;
use serde::Serialize;
use std::fmt::Write;

/// One measurement named as an outlier.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutlierRow {
    /// The row's `id` (the CSV's id column, else its 1-based data row number).
    pub id: String,
    /// `identification` (left out of the fit) or `validation` (marked, still counted in every
    /// validation figure).
    pub set: DataSet,
    /// The tool link observed.
    pub tool: String,
    /// Position residual at the calibrated model (mm).
    pub residual_mm: f64,
    /// Orientation residual at the calibrated model (deg); `None` for a position.
    pub residual_deg: Option<f64>,
    /// Residual norm in robust standard deviations.
    pub standardized: f64,
    /// The loss's weight (below 0.5: the row was left out).
    pub weight: f64,
}

/// How the robust estimation ran (`report.json` `"robust"`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobustSummary {
    /// `huber`, `cauchy` or `off`.
    pub loss: RobustLoss,
    /// Robust scale of the standardized residuals (1 = noise as assumed).
    pub scale: f64,
    /// Calibrations after the first one.
    pub rounds: usize,
    /// Whether the weights settled.
    pub converged: bool,
    /// Identification measurements with a weight below 1.
    pub down_weighted: usize,
}

/// The robust summary of a run.
pub fn robust_summary(run: &CalibrationRun) -> RobustSummary {
    let robust = &run.robust;
    RobustSummary {
        loss: robust.loss,
        scale: robust.scale,
        rounds: robust.rounds,
        converged: robust.converged,
        down_weighted: robust.weights.iter().filter(|&&w| w < 1.0).count(),
    }
}

/// The outliers of `run` with their row ids: `ids[0]` for the identification data, `ids[1]`
/// for the validation data, in the order the run got them (a missing id shows as `#index`).
pub fn outlier_rows(
    run: &CalibrationRun,
    tree: &KinematicTree,
    ids: [&[String]; 2],
) -> Vec<OutlierRow> {
    run.outliers
        .iter()
        .map(|o| {
            let ids = match o.set {
                DataSet::Identification => ids[0],
                DataSet::Validation => ids[1],
            };
            let tool = run.report.model.tools().get(o.tool).map_or_else(
                || format!("tool {}", o.tool),
                |t| tree.link(t.link).name.clone(),
            );
            OutlierRow {
                id: ids
                    .get(o.index)
                    .cloned()
                    .unwrap_or_else(|| format!("#{}", o.index + 1)),
                set: o.set,
                tool,
                residual_mm: o.residual.position * 1e3,
                residual_deg: o.residual.rotation.map(f64::to_degrees),
                standardized: o.standardized,
                weight: o.weight,
            }
        })
        .collect()
}

/// What the robust estimation did, in words: the rows it down-weighted and the calibrations
/// it ran after the plain least-squares one (0, 1 or n of each, no empty clause).
fn robust_sentence(robust: &RobustSummary) -> String {
    let down = match robust.down_weighted {
        0 => "no identification measurement down-weighted".to_owned(),
        1 => "1 identification measurement down-weighted".to_owned(),
        n => format!("{n} identification measurements down-weighted"),
    };
    let rounds = match robust.rounds {
        0 => "the plain least-squares calibration is the result (no reweighted one ran)".to_owned(),
        1 => "1 more calibration after the plain least-squares one".to_owned(),
        n => format!("{n} more calibrations after the plain least-squares one"),
    };
    let settled = if robust.converged {
        ""
    } else {
        " (the weights had not settled)"
    };
    format!("{down}; {rounds}{settled}")
}

/// The `## Outliers` section of `report.md` (empty when the loss is off and nothing to say);
/// `down_weighted`: the identification rows the fit kept with a weight below 1, as
/// `(id, weight, position residual after calibration in mm)`.
pub fn outliers_markdown(
    robust: &RobustSummary,
    rows: &[OutlierRow],
    down_weighted: &[(String, f64, f64)],
) -> String {
    let mut out = String::new();
    if robust.loss == RobustLoss::Off {
        let _ = writeln!(
            out,
            "Robust estimation is off (`robust` off): every measurement has weight 1.\n"
        );
        return out;
    }
    let _ = writeln!(out, "## Outliers (robust {} loss)\n", robust.loss);
    let _ = writeln!(
        out,
        "Robust scale of the residuals: {:.3} of the assumed noise; {}.\n",
        robust.scale,
        robust_sentence(robust)
    );
    if !down_weighted.is_empty() {
        let _ = writeln!(
            out,
            "Down-weighted but kept in the fit (identification rows with a robust weight below 1):\n"
        );
        let _ = writeln!(out, "| id | weight | position after (mm) |");
        let _ = writeln!(out, "|---|---|---|");
        for (id, weight, error) in down_weighted {
            let _ = writeln!(out, "| {id} | {weight:.4} | {error:.4} |");
        }
        out.push('\n');
    }
    if rows.is_empty() {
        let _ = writeln!(out, "No measurement is an outlier.\n");
        return out;
    }
    let _ = writeln!(
        out,
        "Outliers: identification rows were left out of the fit; validation rows are marked and still counted in every validation figure:\n"
    );
    let _ = writeln!(
        out,
        "| id | set | tool | position (mm) | orientation (deg) | robust σ | weight |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for row in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.4} | {} | {:.1} | {:.4} |",
            row.id,
            match row.set {
                DataSet::Identification => "identification",
                DataSet::Validation => "validation",
            },
            row.tool,
            row.residual_mm,
            row.residual_deg
                .map_or_else(|| "—".to_owned(), |d| format!("{d:.5}")),
            row.standardized,
            row.weight
        );
    }
    out.push('\n');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn summary(down_weighted: usize, rounds: usize, converged: bool) -> RobustSummary {
        RobustSummary {
            loss: RobustLoss::Huber,
            scale: 1.0,
            rounds,
            converged,
            down_weighted,
        }
    }

    /// "0 calibration(s) after the first" is said for 0, 1 and n, without empty clauses.
    #[test]
    fn the_robust_line_counts_in_words() {
        let line = |s: &RobustSummary| outliers_markdown(s, &[], &[]);
        let clean = line(&summary(0, 0, true));
        assert!(
            clean.contains("1.000 of the assumed noise; no identification measurement down-weighted; the plain least-squares calibration is the result (no reweighted one ran).\n"),
            "{clean}"
        );
        let one = line(&summary(1, 1, true));
        assert!(
            one.contains("; 1 identification measurement down-weighted; 1 more calibration after the plain least-squares one.\n"),
            "{one}"
        );
        let many = line(&summary(3, 4, false));
        assert!(
            many.contains("; 3 identification measurements down-weighted; 4 more calibrations after the plain least-squares one (the weights had not settled).\n"),
            "{many}"
        );
        for text in [clean, one, many] {
            assert!(!text.contains("(s)") && !text.contains(" 0 "), "{text}");
        }
    }
}
