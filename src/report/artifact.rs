//! What `calibrate` ships, validated as shipped (`report.json` `"artifact"`, report.md): the
//! validation error of the written URDF text re-read alone (with the written registration),
//! and with its compensation file; what the exported root is when the frame was fitted.

use crate::calibration::ErrorSummary;
use serde::Serialize;
use std::fmt::Write;

/// The validation error of one way of using the outputs.
#[derive(Debug, Clone, Serialize)]
pub struct ArtifactScore {
    /// The files used, e.g. `calibrated.urdf + registration.yaml`.
    pub files: String,
    /// Validation observations scored (every row).
    pub observations: usize,
    /// RMS, max and mean position (mm) and orientation (deg) error.
    pub errors: ErrorSummary,
}

/// The exported root frame when the measurement frame was fitted: where it can be against the
/// robot's physical base.
#[derive(Debug, Clone, Serialize)]
pub struct UnobservableBase {
    /// The transform the data cannot see, in words (base link → first joint(s)).
    pub transform: String,
    /// The exported root against the registered nominal robot's root: translation (mm).
    pub translation_mm: f64,
    /// The same, rotation (deg).
    pub rotation_deg: f64,
    /// How far that moves the measured tool positions in the URDF's own root frame over the
    /// identification configurations: smallest and largest (mm; JSON `min`, `max`).
    #[serde(serialize_with = "min_max")]
    pub tool_shift_mm: [f64; 2],
}

fn min_max<S: serde::Serializer>(v: &[f64; 2], s: S) -> std::result::Result<S::Ok, S::Error> {
    crate::serde_labels::labelled(v, ["min", "max"], s)
}

/// The artifact's validation (`report.json` `"artifact"`).
#[derive(Debug, Clone, Serialize)]
pub struct ArtifactReport {
    /// The registration file written (`registration.yaml`) when the frame was fitted.
    pub registration: Option<String>,
    /// The URDF used alone (with the registration when there is one).
    pub urdf_alone: Option<ArtifactScore>,
    /// The URDF with its compensation file (the deflections predicted), when one applies.
    pub with_compensation: Option<ArtifactScore>,
    /// The registered nominal robot on the same rows (the fair "before").
    pub registered_nominal: Option<ArtifactScore>,
    /// How a user applies the outputs, in words.
    pub how_to_use: String,
    /// With a fitted frame: what the data cannot see and what the exported root therefore is.
    pub unobservable_base: Option<UnobservableBase>,
}

impl ArtifactReport {
    /// The report.md section.
    pub fn markdown(&self) -> String {
        self.markdown_written(true)
    }

    /// The report.md section; `written` false when the verdict failed and nothing was written:
    /// the figures are then those of the files the calibration would have written.
    pub fn markdown_written(&self, written: bool) -> String {
        let mut out = String::new();
        if written {
            let _ = writeln!(out, "## What the outputs give (validated as written)\n");
            let _ = writeln!(
                out,
                "Every figure below re-reads the written files and scores them on every validation row.\n"
            );
        } else {
            let _ = writeln!(
                out,
                "## What the outputs would give (not written: the verdict failed)\n"
            );
            let _ = writeln!(
                out,
                "The verdict failed, so calibrated.urdf and the files beside it were not written; every figure below scores the files the calibration would have written on every validation row.\n"
            );
        }
        let _ = writeln!(out, "| used | n | RMS (mm) | max (mm) | mean (mm) |");
        let _ = writeln!(out, "|---|---|---|---|---|");
        for score in [
            &self.urdf_alone,
            &self.with_compensation,
            &self.registered_nominal,
        ]
        .into_iter()
        .flatten()
        {
            let _ = writeln!(
                out,
                "| {} | {} | {:.4} | {:.4} | {:.4} |",
                score.files,
                score.observations,
                score.errors.rms_position_mm,
                score.errors.max_position_mm,
                score.errors.mean_position_mm
            );
        }
        let _ = writeln!(out, "\n{}\n", self.how_to_use);
        if let Some(base) = &self.unobservable_base {
            let _ = writeln!(
                out,
                "The measurement frame was fitted, so {} cannot be seen: the exported root is the fitted frame, {:.3} mm and {:.4} deg from the registered nominal robot's root; tool positions in the URDF's own root frame move by {:.3}–{:.3} mm over the measured configurations. Use the URDF with its registration to reproduce the figures above.\n",
                base.transform,
                base.translation_mm,
                base.rotation_deg,
                base.tool_shift_mm[0],
                base.tool_shift_mm[1]
            );
        }
        out
    }
}
