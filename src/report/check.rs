//! `treecal check`: the identifiability of a pose set, per calibration stage.

use crate::calibration::{
    ComplianceIdentifiability, IdentifiabilityReport, NamedCombination, ObservationKind,
};
use serde::Serialize;
use std::fmt::Write;

/// The `schema_version` of `check --format json` / `yaml` (docs/file-formats.md).
pub const CHECK_SCHEMA: &str = "treecal.check/2";

/// Everything `check` shows; serialises to YAML/JSON, renders to text.
#[derive(Debug, Clone, Serialize)]
pub struct CheckReport {
    /// [`CHECK_SCHEMA`].
    pub schema_version: &'static str,
    /// Robot name.
    pub robot: String,
    /// Where the configurations came from (a file, or the default random set).
    pub poses: String,
    /// What is measured per tool.
    pub observation: ObservationKind,
    /// `staged` or `simultaneous`.
    pub plan: String,
    /// One entry per stage of the plan.
    pub stages: Vec<StageCheck>,
    /// Whether every analysed stage is well conditioned.
    pub well_conditioned: bool,
    /// What the poses determine of the compliances (`--identify-stiffness`), if asked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compliance: Option<ComplianceIdentifiability>,
}

/// The analysis of one stage.
#[derive(Debug, Clone, Serialize)]
pub struct StageCheck {
    /// Stage name (`torso`, `arms`, `all`).
    pub name: String,
    /// Why the stage was not analysed, if it was not.
    pub skipped: Option<String>,
    /// The analysis.
    pub analysis: Option<IdentifiabilityReport>,
    /// One-line verdict.
    pub verdict: String,
}

impl StageCheck {
    /// A stage analysed.
    pub fn analysed(name: &str, analysis: IdentifiabilityReport) -> Self {
        Self {
            name: name.into(),
            skipped: None,
            verdict: analysis.verdict(),
            analysis: Some(analysis),
        }
    }

    /// A stage not analysed, and why.
    pub fn skipped(name: &str, reason: String) -> Self {
        Self {
            name: name.into(),
            verdict: format!("not analysed: {reason}"),
            skipped: Some(reason),
            analysis: None,
        }
    }
}

impl CheckReport {
    /// Builds the report; `well_conditioned` from the analysed stages.
    pub fn new(
        robot: String,
        poses: String,
        observation: ObservationKind,
        plan: String,
        stages: Vec<StageCheck>,
    ) -> Self {
        let well_conditioned = stages
            .iter()
            .filter_map(|s| s.analysis.as_ref())
            .all(IdentifiabilityReport::is_well_conditioned)
            && stages.iter().any(|s| s.analysis.is_some());
        Self {
            schema_version: CHECK_SCHEMA,
            robot,
            poses,
            observation,
            plan,
            stages,
            well_conditioned,
            compliance: None,
        }
    }

    /// Human-readable text.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let observation = match self.observation {
            ObservationKind::Pose => "full tool poses (3 targets)",
            ObservationKind::Position => "tool positions (1 target)",
        };
        let _ = writeln!(out, "robot: {}", self.robot);
        let _ = writeln!(out, "poses: {}", self.poses);
        let _ = writeln!(out, "measured: {observation}; plan: {}", self.plan);
        for stage in &self.stages {
            let _ = writeln!(out, "\nstage {}:", stage.name);
            if let Some(analysis) = &stage.analysis {
                stage_text(&mut out, analysis);
                for warning in analysis.warnings() {
                    let _ = writeln!(out, "  warning: {warning}");
                }
            }
            let _ = writeln!(out, "  verdict: {}", stage.verdict);
        }
        let overall = if self.well_conditioned {
            "well conditioned"
        } else {
            "poorly conditioned (see the stages above)"
        };
        let _ = writeln!(out, "\nverdict: {overall}");
        out
    }
}

fn stage_text(out: &mut String, a: &IdentifiabilityReport) {
    let count = a.parameter_count();
    let locked = if a.locked_tools > 0 {
        format!(" (including {} rigid locked-arm tools)", a.locked_tools)
    } else {
        String::new()
    };
    let plural = |n: usize, word: &str| format!("{n} {word}{}", if n == 1 { "" } else { "s" });
    let _ = writeln!(
        out,
        "  {}, {}, {}, {count} parameters{locked}",
        plural(a.configurations, "configuration"),
        plural(a.observations, "observation"),
        plural(a.rows, "row")
    );
    let values = &a.singular_values;
    let smallest: Vec<String> = values
        .iter()
        .rev()
        .take(5)
        .map(|s| format!("{s:.3e}"))
        .collect();
    let _ = writeln!(
        out,
        "  scaled singular values: largest {:.3e}, median {:.3e}, smallest {}",
        values.first().copied().unwrap_or(0.0),
        values.get(values.len() / 2).copied().unwrap_or(0.0),
        smallest.join(", ")
    );
    let _ = writeln!(
        out,
        "  rank {} of {count}; condition number {:.3e} (over the identifiable subspace)",
        a.rank, a.condition_number
    );
    let indices = |label: &str, i: &crate::calibration::ObservabilityIndices| {
        format!(
            "  {label}O1 {:.3e}  O2 {:.3e}  O3 {:.3e}  O4 {:.3e}  O5 {:.3e}",
            i.o1, i.o2, i.o3, i.o4, i.o5
        )
    };
    let _ = writeln!(out, "{}", indices("", &a.indices));
    if a.rank < count {
        let _ = writeln!(
            out,
            "{}",
            indices("identifiable subspace: ", &a.identifiable_indices)
        );
    }
    list(
        out,
        "cannot be identified (a change along these leaves every measured tool in place)",
        &a.unidentifiable,
    );
    list(
        out,
        &format!(
            "poorly determined (singular value below 1/{} of the largest)",
            a.condition_limit
        ),
        &a.poorly_determined,
    );
}

/// At most this many combinations are listed in text (all are in YAML/JSON).
const LISTED: usize = 12;

fn list(out: &mut String, title: &str, combinations: &[NamedCombination]) {
    if combinations.is_empty() {
        return;
    }
    let _ = writeln!(out, "  {title}:");
    for combination in combinations.iter().take(LISTED) {
        let _ = writeln!(out, "    - {}", combination.description);
    }
    if combinations.len() > LISTED {
        let _ = writeln!(
            out,
            "    … and {} more (see `format` yaml)",
            combinations.len() - LISTED
        );
    }
}
