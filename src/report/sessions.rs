//! The measurement sessions of a calibration in report.json (`"sessions"`) and report.md
//! ("## Sessions"): every training session with its rows and its frame relative to the first,
//! and every validation session's held-out RMS in the training frame and re-registered.

use crate::calibration::{session_label, SessionsReport};
use crate::math::Pose;
use serde::Serialize;
use std::fmt::Write as _;

/// The sessions block of report.json.
#[derive(Debug, Clone, Serialize)]
pub struct SessionsSummary {
    /// Parameters of each session's frame after the first (6).
    pub parameters_per_session: usize,
    /// Alternations of calibration and frame fits.
    pub rounds: usize,
    /// Whether the frames settled.
    pub converged: bool,
    /// Training sessions, the first (the reference frame) first.
    pub training: Vec<SessionRow>,
    /// Validation sessions.
    pub validation: Vec<ValidationSessionRow>,
}

/// A training session.
#[derive(Debug, Clone, Serialize)]
pub struct SessionRow {
    /// Its name (`null`: rows without a session label).
    pub name: Option<String>,
    /// Its rows.
    pub rows: usize,
    /// Its frame in the first session's frame (`xyz` m, `rpy` rad): measured ≈ frame ·
    /// predicted.
    pub session_from_first: FrameXyzRpy,
    /// Translation of that frame (mm).
    pub offset_mm: f64,
    /// Rotation angle of that frame (deg).
    pub offset_deg: f64,
    /// Directions of the frame its rows determine (of 6).
    pub determined: usize,
    /// How far the frame moves the session's own measured points (RMS, mm).
    pub rows_moved_mm: f64,
}

/// A validation session's figures.
#[derive(Debug, Clone, Serialize)]
pub struct ValidationSessionRow {
    /// Its name.
    pub name: Option<String>,
    /// Its validation rows (all counted).
    pub rows: usize,
    /// `training` (a training session: its fitted frame), `new` (the first session's frame)
    /// or `moved` (new, measured in another frame: its rows count re-registered).
    pub training_frame: &'static str,
    /// RMS position error in the training frame (mm).
    pub training_frame_rms_mm: f64,
    /// RMS position error with the session's frame refitted, geometry fixed (mm).
    pub reregistered_rms_mm: f64,
    /// Parameters refitted for the re-registration.
    pub refitted_parameters: usize,
    /// The re-registered frame in the first session's frame.
    pub reregistered_frame: FrameXyzRpy,
    /// Its translation (mm) and rotation angle (deg).
    pub reregistered_offset_mm: f64,
    /// Its rotation angle (deg).
    pub reregistered_offset_deg: f64,
}

/// A frame as `xyz` (m) and `rpy` (rad).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FrameXyzRpy {
    /// Translation (m).
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw (rad).
    pub rpy: [f64; 3],
}

impl FrameXyzRpy {
    fn of(pose: &Pose) -> Self {
        let t = pose.translation.vector;
        Self {
            xyz: [t.x, t.y, t.z],
            rpy: crate::math::rpy_from_rotation(&pose.rotation),
        }
    }
}

/// The report.json block of `report`.
pub fn sessions_summary(report: &SessionsReport) -> SessionsSummary {
    SessionsSummary {
        parameters_per_session: crate::calibration::FRAME_BLOCK_PARAMETERS,
        rounds: report.rounds,
        converged: report.converged,
        training: report
            .frames
            .iter()
            .map(|f| SessionRow {
                name: f.name.clone(),
                rows: f.rows,
                session_from_first: FrameXyzRpy::of(&f.session_from_first),
                offset_mm: f.session_from_first.translation.vector.norm() * 1e3,
                offset_deg: f.session_from_first.rotation.angle().to_degrees(),
                determined: f.determined,
                rows_moved_mm: f.displacement * 1e3,
            })
            .collect(),
        validation: report
            .validation
            .iter()
            .map(|v| ValidationSessionRow {
                name: v.name.clone(),
                rows: v.rows,
                training_frame: if v.seen_in_training {
                    "training"
                } else if v.moved() {
                    "moved"
                } else {
                    "new"
                },
                training_frame_rms_mm: v.training_frame_rms * 1e3,
                reregistered_rms_mm: v.reregistered_rms * 1e3,
                refitted_parameters: v.refitted_parameters,
                reregistered_frame: FrameXyzRpy::of(&v.session_from_first),
                reregistered_offset_mm: v.session_from_first.translation.vector.norm() * 1e3,
                reregistered_offset_deg: v.session_from_first.rotation.angle().to_degrees(),
            })
            .collect(),
    }
}

/// "## Sessions": the training sessions' frames and the validation sessions' two figures.
pub fn sessions_markdown(summary: &SessionsSummary) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "\n## Sessions\n");
    let _ = writeln!(
        out,
        "One measurement frame per session: the first session's is the measurement frame above; \
         every other session's frame ({} parameters) is fitted jointly with the geometry \
         ({} round(s){}).\n",
        summary.parameters_per_session,
        summary.rounds,
        if summary.converged {
            ""
        } else {
            ", not settled"
        }
    );
    let _ = writeln!(
        out,
        "| training session | rows | frame from the first (mm) | (deg) | its rows moved (mm RMS) | directions determined |"
    );
    let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|");
    for s in &summary.training {
        let _ = writeln!(
            out,
            "| {} | {} | {:.2} | {:.3} | {:.2} | {}/6 |",
            session_label(&s.name),
            s.rows,
            s.offset_mm,
            s.offset_deg,
            s.rows_moved_mm,
            s.determined
        );
    }
    if summary.validation.is_empty() {
        return out;
    }
    let _ = writeln!(
        out,
        "\nValidation by session, every row counted. *Training frame*: a session seen in training \
         uses its fitted frame, a new one the first session's. *Re-registered*: the session's \
         frame refitted to its own validation rows ({} parameters, geometry fixed), which removes \
         what a moved tracker adds. The headline validation figures use the training frame, but \
         for a new session measured in another frame (more than 3× the error re-registered, \
         training frame *moved*): its rows count re-registered.\n",
        summary
            .validation
            .first()
            .map_or(6, |v| v.refitted_parameters)
    );
    let _ = writeln!(
        out,
        "| validation session | rows | training frame | RMS, training frame (mm) | RMS, re-registered (mm) | re-registered frame from the first (mm, deg) |"
    );
    let _ = writeln!(out, "|---|---:|---|---:|---:|---:|");
    for v in &summary.validation {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.3} | {:.3} | {:.2}, {:.3} |",
            session_label(&v.name),
            v.rows,
            match v.training_frame {
                "training" => "its own (seen in training)",
                "moved" =>
                    "the first session's (new; measured in another frame: counted re-registered)",
                _ => "the first session's (new)",
            },
            v.training_frame_rms_mm,
            v.reregistered_rms_mm,
            v.reregistered_offset_mm,
            v.reregistered_offset_deg
        );
    }
    pooled_validation_row(&mut out, summary);
    out
}

/// With several validation sessions, the figures over every validation row: the training
/// frame (the headline) and each session re-registered (its parameters counted).
fn pooled_validation_row(out: &mut String, summary: &SessionsSummary) {
    if summary.validation.len() < 2 {
        return;
    }
    let rows: usize = summary.validation.iter().map(|v| v.rows).sum();
    let pooled = |rms: fn(&ValidationSessionRow) -> f64| {
        let sum: f64 = summary
            .validation
            .iter()
            .map(|v| v.rows as f64 * rms(v).powi(2))
            .sum();
        (sum / rows.max(1) as f64).sqrt()
    };
    let refitted: usize = summary
        .validation
        .iter()
        .map(|v| v.refitted_parameters)
        .sum();
    let _ = writeln!(
        out,
        "| every validation row | {rows} | as above | {:.3} | {:.3} ({refitted} parameters refitted on validation rows) | |",
        pooled(|v| v.training_frame_rms_mm),
        pooled(|v| v.reregistered_rms_mm),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn session(name: &str, rows: usize, training: f64, reregistered: f64) -> ValidationSessionRow {
        ValidationSessionRow {
            name: Some(name.into()),
            rows,
            training_frame: "new",
            training_frame_rms_mm: training,
            reregistered_rms_mm: reregistered,
            refitted_parameters: 6,
            reregistered_frame: FrameXyzRpy {
                xyz: [0.0; 3],
                rpy: [0.0; 3],
            },
            reregistered_offset_mm: 0.0,
            reregistered_offset_deg: 0.0,
        }
    }

    #[test]
    fn the_pooled_row_weighs_each_session_by_its_rows() {
        let mut summary = SessionsSummary {
            parameters_per_session: 6,
            rounds: 1,
            converged: true,
            training: Vec::new(),
            validation: vec![session("a", 10, 3.0, 2.0)],
        };
        let mut out = String::new();
        pooled_validation_row(&mut out, &summary);
        assert!(out.is_empty(), "one session needs no pooled row: {out}");
        summary.validation.push(session("b", 30, 1.0, 1.0));
        pooled_validation_row(&mut out, &summary);
        // √((10·9 + 30·1)/40) = √3, √((10·4 + 30·1)/40) = √1.75.
        let expected = format!(
            "| every validation row | 40 | as above | {:.3} | {:.3} (12 parameters refitted on validation rows) | |",
            3f64.sqrt(),
            1.75f64.sqrt()
        );
        assert_eq!(out.trim_end(), expected);
    }
}
