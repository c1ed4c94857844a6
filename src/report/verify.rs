//! The report of `treecal verify` (report.json, report.md, errors.svg): a deployed
//! calibration scored on fresh rows.

use super::plot::{error_plot_svg, ErrorPlot, Series};
use super::strata::{StrataRow, ValidationStrata};
use crate::calibration::ErrorSummary;
use crate::calibration::Stratum;
use crate::error::Result;
use crate::math::{rpy_from_rotation, Pose};
use serde::Serialize;
use std::fmt::Write;

/// report.json's `schema_version` for verify.
pub const VERIFY_SCHEMA: &str = "treecal-verify/1";

/// One fresh row scored.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VerifyRow {
    /// The row's id.
    pub id: String,
    /// Its index among the rows.
    #[serde(skip)]
    pub index: usize,
    /// The tool observed.
    pub tool: String,
    /// Its session, if the file names one.
    pub session: Option<String>,
    /// Position error (mm).
    pub position_mm: f64,
    /// Orientation error (deg), for measured poses.
    pub orientation_deg: Option<f64>,
    /// Where it lies against the calibrated ranges (`None`: no calibration record).
    pub stratum: Option<Stratum>,
    /// Whether it is a gross blunder (a bumped target, a mistyped value: it stands out under
    /// the robust loss and is at least `GROSS_FACTOR` = 10 times the RMS of the other rows):
    /// left out of its session's frame fit and of the verdict; counted in every figure.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub outlier: bool,
}

/// A session's refitted measurement frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VerifySession {
    /// The session (`None`: rows without a session label).
    pub name: Option<String>,
    /// Its rows.
    pub rows: usize,
    /// The refit's correction of the starting frame (the registration, else the root): how
    /// far the tracker moved, translation (mm).
    pub moved_mm: f64,
    /// The same, rotation (deg).
    pub turned_deg: f64,
    /// The correction, xyz (m; JSON `x`, `y`, `z`).
    #[serde(serialize_with = "xyz")]
    pub xyz: [f64; 3],
    /// The correction, roll-pitch-yaw (rad; JSON `roll`, `pitch`, `yaw`).
    #[serde(serialize_with = "rpy")]
    pub rpy: [f64; 3],
    /// How many of the six directions the rows determine.
    pub determined: usize,
}

fn xyz<S: serde::Serializer>(v: &[f64; 3], s: S) -> std::result::Result<S::Ok, S::Error> {
    crate::serde_labels::labelled(v, ["x", "y", "z"], s)
}

fn rpy<S: serde::Serializer>(v: &[f64; 3], s: S) -> std::result::Result<S::Ok, S::Error> {
    crate::serde_labels::labelled(v, ["roll", "pitch", "yaw"], s)
}

impl VerifySession {
    /// A session with its refitted `correction`.
    pub fn new(name: Option<String>, rows: usize, correction: &Pose, determined: usize) -> Self {
        Self {
            name,
            rows,
            moved_mm: correction.translation.vector.norm() * 1e3,
            turned_deg: correction.rotation.angle().to_degrees(),
            xyz: correction.translation.vector.into(),
            rpy: rpy_from_rotation(&correction.rotation),
            determined,
        }
    }
}

/// What was verified and how.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VerifyContext {
    /// The robot's name.
    pub robot: String,
    /// The files used, e.g. `out/calibrated.urdf + out/registration.yaml`.
    pub files: String,
    /// The fresh measurements.
    pub measurements: String,
    /// `fit`, `registration` or `base`.
    pub frame: String,
    /// Parameters refitted: six per session with `fit`, else none.
    pub refitted_parameters: usize,
    /// The refitted sessions (`fit` only).
    pub sessions: Vec<VerifySession>,
    /// Whether the rows were sorted into strata (the calibration's record was found).
    pub strata_judged: bool,
}

/// The verdict against `--max-error`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VerifyVerdict {
    /// The tolerance on the RMS position error over all rows (mm); `None`: none given.
    pub max_error_mm: Option<f64>,
    /// The RMS position error over all rows (mm).
    pub rms_position_mm: f64,
    /// Whether it is within the tolerance (true without one), judged without the rows in
    /// `set_aside`.
    pub passed: bool,
    /// The gross blunders left out of the verdict (ids), with the RMS position error over the
    /// other rows (mm).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub set_aside: Option<SetAside>,
}

/// Rows the verdict leaves out.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetAside {
    /// Their ids.
    pub ids: Vec<String>,
    /// The RMS position error over the other rows (mm): what the verdict judges.
    pub judged_rms_position_mm: f64,
}

impl VerifyVerdict {
    /// In one sentence.
    pub fn sentence(&self) -> String {
        match (self.max_error_mm, &self.set_aside) {
            (Some(max), Some(aside)) => format!(
                "verdict: {} (RMS position error {:.3} mm without the {} gross blunder(s), {} `max_error` {max} mm; every row: {:.3} mm); re-measure the flagged rows: {}",
                if self.passed { "passed" } else { "failed" },
                aside.judged_rms_position_mm,
                aside.ids.len(),
                if self.passed { "within" } else { "above" },
                self.rms_position_mm,
                super::first_few(&aside.ids),
            ),
            (Some(max), None) => format!(
                "verdict: {} (RMS position error {:.3} mm {} `max_error` {max} mm)",
                if self.passed { "passed" } else { "failed" },
                self.rms_position_mm,
                if self.passed { "within" } else { "above" },
            ),
            (None, _) => format!(
                "RMS position error {:.3} mm (no `max_error`: no verdict){}",
                self.rms_position_mm,
                self.set_aside
                    .as_ref()
                    .map_or(String::new(), |aside| format!(
                        "; {} gross blunder(s) ({}), without them {:.3} mm",
                        aside.ids.len(),
                        super::first_few(&aside.ids),
                        aside.judged_rms_position_mm
                    )),
            ),
        }
    }
}

/// report.json of `treecal verify`.
#[derive(Debug, Clone, Serialize)]
pub struct VerifyReport {
    /// [`VERIFY_SCHEMA`].
    pub schema_version: &'static str,
    /// What was verified.
    pub context: VerifyContext,
    /// The verdict.
    pub verdict: VerifyVerdict,
    /// Every row together.
    pub summary: ErrorSummary,
    /// By stratum, with the worst row (`None` without the calibration's record).
    pub strata: Option<ValidationStrata>,
    /// Every row.
    pub rows: Vec<VerifyRow>,
    /// The provenance file of the folder.
    pub provenance: String,
    /// What the reader must know before the figures (a deployed file changed since the
    /// calibration wrote it, values outside the joint limits, …).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

impl VerifyReport {
    /// The report of `rows`, judged against `max_error_mm`.
    pub fn new(context: VerifyContext, rows: Vec<VerifyRow>, max_error_mm: Option<f64>) -> Self {
        let summary = summary_of(&rows);
        let strata = strata_of(&rows);
        let rms = summary.rms_position_mm;
        let set_aside = set_aside(&rows);
        let judged = set_aside
            .as_ref()
            .map_or(rms, |aside| aside.judged_rms_position_mm);
        Self {
            schema_version: VERIFY_SCHEMA,
            context,
            verdict: VerifyVerdict {
                max_error_mm,
                rms_position_mm: rms,
                passed: max_error_mm.is_none_or(|max| judged <= max),
                set_aside,
            },
            summary,
            strata,
            rows,
            provenance: String::new(),
            warnings: Vec::new(),
        }
    }

    /// The worst row: id, tool and position error (mm).
    pub fn worst(&self) -> Option<&VerifyRow> {
        self.rows
            .iter()
            .max_by(|a, b| a.position_mm.total_cmp(&b.position_mm))
    }

    /// report.md.
    pub fn markdown(&self) -> String {
        let c = &self.context;
        let mut out = String::new();
        let _ = writeln!(out, "# Verification of robot '{}'\n", c.robot);
        let _ = writeln!(out, "- Deployed files: {}", c.files);
        let _ = writeln!(
            out,
            "- Fresh measurements: {} ({} rows)",
            c.measurements,
            self.rows.len()
        );
        let _ = writeln!(out, "- Measurement frame: {}", frame_words(c));
        for warning in &self.warnings {
            let _ = writeln!(out, "- warning: {warning}");
        }
        let _ = writeln!(out, "- **{}**\n", self.verdict.sentence());
        let s = &self.summary;
        let _ = writeln!(
            out,
            "| rows | RMS (mm) | max (mm) | mean (mm) | RMS (deg) | max (deg) |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|");
        let deg = |v: Option<f64>| v.map_or_else(|| "—".to_owned(), |v| format!("{v:.4}"));
        let _ = writeln!(
            out,
            "| {} | {:.4} | {:.4} | {:.4} | {} | {} |\n",
            self.rows.len(),
            s.rms_position_mm,
            s.max_position_mm,
            s.mean_position_mm,
            deg(s.rms_orientation_deg),
            deg(s.max_orientation_deg)
        );
        out.push_str(&groups_markdown(&self.rows));
        match &self.strata {
            Some(strata) => out.push_str(&strata.markdown()),
            None => {
                if let Some(w) = self.worst() {
                    let _ = writeln!(
                        out,
                        "Worst row: {} ({}): {:.4} mm.\n",
                        w.id, w.tool, w.position_mm
                    );
                }
                let _ = writeln!(out, "No calibration record (report.json with `identification_postures`): the rows are not sorted into repeat / inside / outside the calibrated ranges.\n");
            }
        }
        for session in &c.sessions {
            let _ = writeln!(
                out,
                "- Session {}: {} rows, frame refitted by {:.3} mm and {:.4}° ({} of 6 directions determined)",
                session.name.as_deref().unwrap_or("(unnamed)"),
                session.rows,
                session.moved_mm,
                session.turned_deg,
                session.determined
            );
        }
        let _ = writeln!(
            out,
            "\nPer-row position error: errors.svg. Provenance: {}.",
            self.provenance
        );
        out
    }

    /// errors.svg: the position error of every row (x axis: the row ids).
    pub fn plot(&self) -> Result<String> {
        error_plot_svg(&ErrorPlot {
            title: format!("{}: position error per row (verify)", self.context.robot),
            y_label: "position error (mm)".into(),
            series: vec![Series {
                label: "deployed calibration".into(),
                values: self.rows.iter().map(|r| r.position_mm).collect(),
            }],
            x_labels: self.rows.iter().map(|r| r.id.clone()).collect(),
        })
    }
}

/// The rows by tool and by session (each only when there are several), so that a drift
/// of one arm, or a session measured badly, shows where it is: the overall RMS mixes a
/// drifted arm with the others.
fn groups_markdown(rows: &[VerifyRow]) -> String {
    let mut out = String::new();
    let by_tool = group_by(rows, |r| Some(r.tool.clone()));
    let by_session = group_by(rows, |r| r.session.clone());
    for (label, groups) in [("tool", by_tool), ("session", by_session)] {
        if groups.len() < 2 {
            continue;
        }
        let _ = writeln!(
            out,
            "| {label} | rows | RMS (mm) | max (mm) | RMS (deg) |\n|---|---|---|---|---|"
        );
        for (name, members) in groups {
            let position: Vec<f64> = members.iter().map(|r| r.position_mm).collect();
            let orientation: Vec<f64> = members.iter().filter_map(|r| r.orientation_deg).collect();
            let summary = ErrorSummary::of(&position, &orientation);
            let _ = writeln!(
                out,
                "| {} | {} | {:.4} | {:.4} | {} |",
                name.as_deref().unwrap_or("(unnamed)"),
                members.len(),
                summary.rms_position_mm,
                summary.max_position_mm,
                summary
                    .rms_orientation_deg
                    .map_or_else(|| "—".to_owned(), |v| format!("{v:.4}"))
            );
        }
        out.push('\n');
    }
    out
}

/// `rows` grouped by `key`, the groups in the order of their first row.
fn group_by(
    rows: &[VerifyRow],
    key: impl Fn(&VerifyRow) -> Option<String>,
) -> Vec<(Option<String>, Vec<&VerifyRow>)> {
    let mut groups: Vec<(Option<String>, Vec<&VerifyRow>)> = Vec::new();
    for row in rows {
        let name = key(row);
        match groups.iter_mut().find(|(n, _)| *n == name) {
            Some((_, members)) => members.push(row),
            None => groups.push((name, vec![row])),
        }
    }
    groups
}

fn frame_words(c: &VerifyContext) -> String {
    match c.frame.as_str() {
        "fit" => format!(
            "refitted to the fresh rows, the geometry fixed: {} parameter(s) ({} per session, {} session(s)); nothing else is fitted",
            c.refitted_parameters,
            crate::calibration::FRAME_BLOCK_PARAMETERS,
            c.sessions.len()
        ),
        "registration" => "the calibration's registration as written (nothing refitted)".into(),
        _ => "the URDF's root link frame (nothing refitted)".into(),
    }
}

/// The rows the verdict leaves out: the gross blunders (fewer than half the rows by
/// construction).
fn set_aside(rows: &[VerifyRow]) -> Option<SetAside> {
    let flagged = rows.iter().filter(|r| r.outlier).count();
    (flagged > 0 && 2 * flagged < rows.len()).then(|| {
        let kept: Vec<f64> = rows
            .iter()
            .filter(|r| !r.outlier)
            .map(|r| r.position_mm)
            .collect();
        SetAside {
            ids: rows
                .iter()
                .filter(|r| r.outlier)
                .map(|r| r.id.clone())
                .collect(),
            judged_rms_position_mm: crate::math::root_mean_square(&kept).unwrap_or(f64::NAN),
        }
    })
}

/// The strata rows of `rows`.
pub(crate) fn strata_rows(rows: &[VerifyRow]) -> Vec<StrataRow> {
    rows.iter()
        .map(|r| StrataRow {
            id: r.id.clone(),
            index: r.index,
            tool: r.tool.clone(),
            stratum: r.stratum,
            position_mm: r.position_mm,
            outlier: r.outlier,
        })
        .collect()
}

/// The summary of `rows` ([`ErrorSummary::of`], as `calibrate`'s artifact figures).
pub(crate) fn summary_of(rows: &[VerifyRow]) -> ErrorSummary {
    let position: Vec<f64> = rows.iter().map(|r| r.position_mm).collect();
    let orientation: Vec<f64> = rows.iter().filter_map(|r| r.orientation_deg).collect();
    ErrorSummary::of(&position, &orientation)
}

/// The strata of `rows` ([`ValidationStrata::of_rows`]); `None` without strata.
pub(crate) fn strata_of(rows: &[VerifyRow]) -> Option<ValidationStrata> {
    rows.iter()
        .any(|r| r.stratum.is_some())
        .then(|| ValidationStrata::of_rows(&strata_rows(rows)))
        .flatten()
}
