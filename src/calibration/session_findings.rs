//! The findings about a calibration's measurement sessions: frames that moved, sessions
//! that disagree.

use super::sessions::{session_label, SessionsReport, FRAME_BLOCK_PARAMETERS, MAX_ROUNDS};
use super::verdict::Finding;
use crate::math::Pose;

/// A frame's offset from the first session's, in words: translation (mm) and rotation (deg).
fn offset_words(frame: &Pose) -> String {
    format!(
        "{:.2} mm, {:.3}°",
        frame.translation.vector.norm() * 1e3,
        frame.rotation.angle().to_degrees()
    )
}

/// The findings of a calibration with sessions: a note naming every session with its rows
/// and its frame relative to the first; a warning for a frame its rows cannot determine or
/// an alternation that did not settle; a note with the validation sessions' two figures.
pub fn session_findings(report: &SessionsReport) -> Vec<Finding> {
    let mut findings = Vec::new();
    let listed: Vec<String> = report
        .frames
        .iter()
        .enumerate()
        .map(|(s, f)| {
            if s == 0 {
                format!(
                    "{} {} rows (the reference frame)",
                    session_label(&f.name),
                    f.rows
                )
            } else {
                format!(
                    "{} {} rows (frame {} from the first; its rows moved by {:.2} mm RMS)",
                    session_label(&f.name),
                    f.rows,
                    offset_words(&f.session_from_first),
                    f.displacement * 1e3
                )
            }
        })
        .collect();
    let message = match report.frames.len() {
        // One session: one frame, nothing fitted beside the geometry.
        1 => format!(
            "1 measurement session, in one measurement frame: {}",
            listed.join("; ")
        ),
        sessions => format!(
            "{sessions} measurement sessions, one measurement frame each ({} parameters per \
             session after the first, fitted with the geometry in {} round(s)): {}",
            FRAME_BLOCK_PARAMETERS,
            report.rounds,
            listed.join("; ")
        ),
    };
    findings.push(Finding::note("sessions", message));
    if !report.converged {
        findings.push(Finding::warning(
            "sessions",
            format!(
                "the session frames did not settle within {MAX_ROUNDS} rounds of calibration \
                 and frame fits; the geometry may still carry part of a session's frame"
            ),
        ));
    }
    for f in report
        .frames
        .iter()
        .filter(|f| f.determined < FRAME_BLOCK_PARAMETERS)
    {
        findings.push(Finding::warning(
            "sessions",
            format!(
                "session {} ({} rows) determines only {} of its frame's {} directions; the \
                 others stay at the closed-form start: measure at least three well-spread \
                 positions (or one pose) per session",
                session_label(&f.name),
                f.rows,
                f.determined,
                FRAME_BLOCK_PARAMETERS
            ),
        ));
    }
    if !report.validation.is_empty() {
        let listed: Vec<String> = report
            .validation
            .iter()
            .map(|v| {
                format!(
                    "{} {} rows ({}): training frame {:.2} mm RMS, re-registered ({} frame \
                     parameters refitted, geometry fixed) {:.2} mm",
                    session_label(&v.name),
                    v.rows,
                    if v.seen_in_training {
                        "seen in training: its own fitted frame"
                    } else if v.moved() {
                        "new, measured in another frame: counted re-registered"
                    } else {
                        "new: the first session's frame"
                    },
                    v.training_frame_rms * 1e3,
                    v.refitted_parameters,
                    v.reregistered_rms * 1e3
                )
            })
            .collect();
        findings.push(Finding::note(
            "validation-sessions",
            format!(
                "validation by session (the headline figures use the training frame): {}",
                listed.join("; ")
            ),
        ));
        let moved: Vec<String> = report
            .validation
            .iter()
            .filter(|v| v.moved())
            .map(|v| session_label(&v.name))
            .collect();
        if !moved.is_empty() {
            findings.push(Finding::note(
                "validation-session-moved",
                format!(
                    "validation session{} {} {} not seen in training and measured in another frame (the tracker or the mocap frame moved: its error in the training frame is more than {}× its re-registered error): every validation figure counts {} rows re-registered ({} frame parameters fitted to its own rows with the calibrated geometry fixed, as `treecal verify` scores a new day; slightly optimistic with few rows). If it was not moved, check that session's data",
                    if moved.len() == 1 { "" } else { "s" },
                    moved.join(", "),
                    if moved.len() == 1 { "was" } else { "were" },
                    super::sessions::MOVED_FACTOR,
                    if moved.len() == 1 { "its" } else { "their" },
                    super::sessions::FRAME_BLOCK_PARAMETERS
                ),
            ));
        }
    }
    findings
}
