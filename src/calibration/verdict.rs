//! The verdict that ends every calibration: `ok`, `warning` or `failed`, with its reasons.
//!
//! Every check of a calibration (input sanity, measurement frame, rank, σ̂, validation) adds a
//! [`Finding`]; the [`Verdict`] is the worst of them. `failed` means the result must not be
//! used: the CLI exits non-zero and writes no calibrated URDF.

use serde::Serialize;

/// How bad a finding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Nothing to worry about (a finding of this level is a note).
    Ok,
    /// The result is usable, but look at the reason.
    Warning,
    /// The result cannot be trusted.
    Failed,
}

impl Status {
    /// `ok`, `warning` or `failed`.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Warning => "warning",
            Status::Failed => "failed",
        }
    }
}

impl std::fmt::Display for Status {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One check's outcome worth telling the user.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Finding {
    /// `ok` (a note), `warning` or `failed`.
    pub status: Status,
    /// A stable machine-readable name of the check, e.g. `sigma-ratio`, `measurement-frame`.
    pub code: String,
    /// What was found and what to do, in one or two sentences.
    pub message: String,
}

impl Finding {
    /// A note: said, but it does not change the verdict.
    pub fn note(code: &str, message: impl Into<String>) -> Self {
        Self::new(Status::Ok, code, message)
    }

    /// A warning.
    pub fn warning(code: &str, message: impl Into<String>) -> Self {
        Self::new(Status::Warning, code, message)
    }

    /// A failure.
    pub fn failed(code: &str, message: impl Into<String>) -> Self {
        Self::new(Status::Failed, code, message)
    }

    fn new(status: Status, code: &str, message: impl Into<String>) -> Self {
        Self {
            status,
            code: code.to_owned(),
            message: message.into(),
        }
    }
}

/// The code of the findings on the calibrated URDF's export (`workflow::export_notes`, and a
/// failed export).
const EXPORT_CODE: &str = "urdf-export";

/// The verdict of a calibration: the worst status among its findings, and the findings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    /// `ok`, `warning` or `failed`.
    pub status: Status,
    /// Every finding, notes included, in the order the checks ran.
    pub reasons: Vec<Finding>,
}

impl Verdict {
    /// The verdict of `findings`: `ok` when there are none above a note. A failed verdict
    /// writes no calibrated URDF, so the notes on what that URDF holds (code `urdf-export`: a
    /// `<tool>_marker` link added, a tool moved onto its joint's axis) are left out: they would
    /// name links of a file that does not exist.
    pub fn from_findings(mut findings: Vec<Finding>) -> Self {
        let status = findings
            .iter()
            .map(|f| f.status)
            .max()
            .unwrap_or(Status::Ok);
        if status == Status::Failed {
            findings.retain(|f| !(f.code == EXPORT_CODE && f.status == Status::Ok));
        }
        Self {
            status,
            reasons: findings,
        }
    }

    /// Whether the result may be used (`ok` or `warning`).
    pub fn usable(&self) -> bool {
        self.status != Status::Failed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_worst_finding_decides() {
        assert_eq!(Verdict::from_findings(vec![]).status, Status::Ok);
        let verdict = Verdict::from_findings(vec![
            Finding::note("a", "fine"),
            Finding::failed("b", "bad"),
            Finding::warning("c", "hm"),
        ]);
        assert_eq!(verdict.status, Status::Failed);
        assert!(!verdict.usable());
        assert_eq!(verdict.reasons.len(), 3);
        let json = serde_json::to_string(&verdict).unwrap_or_default();
        assert!(json.starts_with(r#"{"status":"failed","reasons":[{"status":"ok","code":"a""#));
    }

    /// A failed verdict writes no URDF: its export notes ("added link 'tool_marker' … use
    /// 'tool_marker'") go, a failed export stays; a usable verdict keeps them.
    #[test]
    fn a_failed_verdict_names_no_link_of_an_unwritten_urdf() {
        let findings = |sigma: Finding| {
            vec![
                Finding::note(EXPORT_CODE, "added link 'hand_marker'"),
                sigma,
                Finding::note("measurement-frame", "fitted"),
            ]
        };
        let failed = Verdict::from_findings(findings(Finding::failed("sigma-ratio", "far")));
        let codes: Vec<&str> = failed.reasons.iter().map(|f| f.code.as_str()).collect();
        assert_eq!(codes, ["sigma-ratio", "measurement-frame"]);
        let usable = Verdict::from_findings(findings(Finding::warning("sigma-ratio", "high")));
        assert_eq!(usable.reasons.len(), 3);
        let export_failed = Verdict::from_findings(vec![Finding::failed(EXPORT_CODE, "cannot")]);
        assert_eq!(export_failed.reasons.len(), 1);
    }
}
