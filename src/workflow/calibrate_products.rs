//! What [`super::calibrate::calibrate`] produces besides the parameters and notes: the
//! verdict, report.json, report.md, the URDF and the other files. Its own file so that the
//! steps (which carry it) and the outputs (which fill it) both sit above it.

use crate::calibration::Verdict;

/// Everything the outcome holds besides the parameters and notes.
pub(super) struct Outputs {
    pub verdict: Verdict,
    /// report.json's small keys; its rows are in `report_parts` (`report_json`).
    pub report: serde_json::Value,
    pub report_parts: super::report_json::ReportParts,
    pub markdown: String,
    pub urdf: Option<String>,
    pub files: Vec<(String, Vec<u8>)>,
}
