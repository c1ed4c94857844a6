//! The validation figures of a calibration by stratum: rows that repeat an identification
//! posture, new postures inside the identification joint ranges, postures outside them, all
//! rows together, and the worst row (`report.json` `"validation_strata"`, report.md).

use super::arm::ArmReport;
use crate::calibration::Stratum;
use serde::Serialize;
use std::fmt::Write;

/// The position error of one group of validation rows, after calibration.
#[derive(Debug, Clone, Serialize)]
pub struct StratumFigures {
    /// `repeat`, `inside`, `outside`, or `all`.
    pub stratum: String,
    /// In words.
    pub description: String,
    /// Rows in the group (every row counts, outliers included).
    pub observations: usize,
    /// RMS position error (mm); `None` for an empty group.
    pub rms_position_mm: Option<f64>,
    /// Largest position error (mm); `None` for an empty group.
    pub max_position_mm: Option<f64>,
}

/// The validation row with the largest position error after calibration.
#[derive(Debug, Clone, Serialize)]
pub struct WorstRow {
    /// The row's id.
    pub id: String,
    /// Its index in the validation data (for renaming).
    #[serde(skip)]
    pub index: usize,
    /// The tool observed.
    pub tool: String,
    /// Its stratum.
    pub stratum: Option<Stratum>,
    /// Its position error after calibration (mm).
    pub position_mm: f64,
    /// Whether the robust loss names it an outlier.
    pub outlier: bool,
}

/// The validation figures by stratum and the worst row.
#[derive(Debug, Clone, Serialize)]
pub struct ValidationStrata {
    /// `all`, then `repeat`, `inside`, `outside`.
    pub strata: Vec<StratumFigures>,
    /// The worst row.
    pub worst: Option<WorstRow>,
    /// With rows the robust loss flagged as outliers (they count in `strata`): the rows not
    /// flagged, apart (`stratum` `unflagged`); absent when no row, or every row, is flagged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub without_flagged: Option<StratumFigures>,
}

fn figures(stratum: &str, description: &str, errors: &[f64]) -> StratumFigures {
    let n = errors.len();
    StratumFigures {
        stratum: stratum.to_owned(),
        description: description.to_owned(),
        observations: n,
        rms_position_mm: crate::math::root_mean_square(errors),
        max_position_mm: (n > 0).then(|| errors.iter().copied().fold(0.0, f64::max)),
    }
}

/// A row as the figures see it: its stratum, position error (mm) and whether it is an outlier.
type Scored = (Option<Stratum>, f64, bool);

/// One validation row as the strata see it.
#[derive(Debug, Clone)]
pub struct StrataRow {
    /// The row's id.
    pub id: String,
    /// Its index in the validation data.
    pub index: usize,
    /// The tool observed.
    pub tool: String,
    /// Its stratum.
    pub stratum: Option<Stratum>,
    /// Its position error (mm).
    pub position_mm: f64,
    /// Whether the robust loss names it an outlier.
    pub outlier: bool,
}

impl ValidationStrata {
    /// The strata of the validation `arms` (every row carries its stratum); `None` without
    /// validation rows.
    pub fn of(arms: &[ArmReport]) -> Option<Self> {
        // No row is copied (at 10⁶ configurations 4·10⁵ ids and tool names, twice a run).
        let rows: Vec<(&ArmReport, &super::arm::RowErrors)> = arms
            .iter()
            .flat_map(|a| a.rows.iter().map(move |r| (a, r)))
            .collect();
        let scored: Vec<Scored> = rows
            .iter()
            .map(|(_, r)| (r.stratum, r.position_mm.after, r.outlier))
            .collect();
        Self::of_scored(&scored, |i| {
            let (arm, row) = rows[i];
            WorstRow {
                id: row.id.clone(),
                index: row.index,
                tool: arm.tool.clone(),
                stratum: row.stratum,
                position_mm: row.position_mm.after,
                outlier: row.outlier,
            }
        })
    }

    /// The strata of any scored rows (`calibrate`'s validation, `treecal verify`); `None`
    /// without rows.
    pub fn of_rows(rows: &[StrataRow]) -> Option<Self> {
        let scored: Vec<Scored> = rows
            .iter()
            .map(|r| (r.stratum, r.position_mm, r.outlier))
            .collect();
        Self::of_scored(&scored, |i| {
            let row = &rows[i];
            WorstRow {
                id: row.id.clone(),
                index: row.index,
                tool: row.tool.clone(),
                stratum: row.stratum,
                position_mm: row.position_mm,
                outlier: row.outlier,
            }
        })
    }

    /// The figures of rows scored as `(stratum, position error (mm), outlier)`, the worst
    /// one described by `worst(its index)`.
    fn of_scored(scored: &[Scored], worst: impl FnOnce(usize) -> WorstRow) -> Option<Self> {
        if scored.is_empty() {
            return None;
        }
        let errors = |keep: &dyn Fn(Option<Stratum>) -> bool| -> Vec<f64> {
            scored
                .iter()
                .filter(|(s, _, _)| keep(*s))
                .map(|(_, e, _)| *e)
                .collect()
        };
        let mut strata = vec![figures("all", "every validation row", &errors(&|_| true))];
        for stratum in [Stratum::Repeat, Stratum::Inside, Stratum::Outside] {
            strata.push(figures(
                stratum.as_str(),
                stratum.describe(),
                &errors(&|s| s == Some(stratum)),
            ));
        }
        let worst = scored
            .iter()
            .enumerate()
            .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
            .map(|(i, _)| worst(i));
        let unflagged: Vec<f64> = scored
            .iter()
            .filter(|(_, _, outlier)| !outlier)
            .map(|(_, e, _)| *e)
            .collect();
        let without_flagged = (!unflagged.is_empty() && unflagged.len() < scored.len())
            .then(|| figures("unflagged", "rows not flagged as outliers", &unflagged));
        Some(Self {
            strata,
            worst,
            without_flagged,
        })
    }

    /// The markdown paragraph and table.
    pub fn markdown(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "### Validation by stratum (every row counted, position after calibration)\n"
        );
        let _ = writeln!(out, "| rows | n | RMS (mm) | max (mm) |");
        let _ = writeln!(out, "|---|---|---|---|");
        let mm = |v: Option<f64>| v.map_or_else(|| "—".to_owned(), |v| format!("{v:.4}"));
        for s in self.strata.iter().chain(&self.without_flagged) {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} |",
                s.description,
                s.observations,
                mm(s.rms_position_mm),
                mm(s.max_position_mm)
            );
        }
        out.push('\n');
        if let Some(w) = &self.worst {
            let _ = writeln!(
                out,
                "Worst validation row: {} ({}, {}{}): {:.4} mm.\n",
                w.id,
                w.tool,
                w.stratum.map_or("—", Stratum::describe),
                if w.outlier {
                    ", marked as an outlier"
                } else {
                    ""
                },
                w.position_mm
            );
        }
        out
    }
}
