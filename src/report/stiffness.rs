//! The stiffness identification in reports: a markdown table of the compliance parameters
//! (`calibrate --identify-stiffness`, `simulate`) and of what a pose set can determine of them
//! (`check --identify-stiffness`).

use crate::calibration::{ComplianceEstimate, ComplianceIdentifiability, StiffnessReport};
use serde::Serialize;
use std::fmt::Write;

/// The stiffness identification as report.json and params.yaml carry it.
#[derive(Debug, Clone, Serialize)]
pub struct StiffnessSummary {
    /// Relative standard deviation of the prior (the stiffness file).
    pub prior_sigma: f64,
    /// Weighted cost ½‖r‖² before and after the joint fit (JSON: `before`, `after`).
    #[serde(serialize_with = "crate::serde_labels::before_after")]
    pub cost: [f64; 2],
    /// Iterations of the joint fit.
    pub iterations: usize,
    /// Why the joint fit stopped.
    pub termination: crate::calibration::Termination,
    /// Identified compliance parameters / all (JSON: `identified`, `total`).
    #[serde(serialize_with = "identified_json")]
    pub identified: [usize; 2],
    /// `σ̂` of the joint fit.
    pub residual_scale: f64,
    /// Every compliance parameter.
    pub parameters: Vec<ComplianceEstimate>,
    /// Combinations the data cannot determine (kept at the prior), in words.
    pub unidentifiable: Vec<String>,
    /// Scales the joint fit put at or below zero (held at the prior), in words.
    pub held_below_zero: Vec<String>,
    /// Common scale of all joint compliances and of all link compliances, with its standard
    /// deviation (`None`: not identified, 1) (JSON: `joint` and `link`, each with `scale` and
    /// `std_dev`).
    #[serde(serialize_with = "group_scales_json")]
    pub group_scales: [(f64, Option<f64>); 2],
}

fn identified_json<S: serde::Serializer>(
    identified: &[usize; 2],
    serializer: S,
) -> std::result::Result<S::Ok, S::Error> {
    crate::serde_labels::labelled(identified, ["identified", "total"], serializer)
}

fn group_scales_json<S: serde::Serializer>(
    scales: &[(f64, Option<f64>); 2],
    serializer: S,
) -> std::result::Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Scale {
        scale: f64,
        std_dev: Option<f64>,
    }
    let groups = scales.map(|(scale, std_dev)| Scale { scale, std_dev });
    crate::serde_labels::labelled(&groups, ["joint", "link"], serializer)
}

impl StiffnessSummary {
    /// The summary of `report`, identified with prior uncertainty `prior_sigma`.
    pub fn new(report: &StiffnessReport, prior_sigma: f64) -> Self {
        Self {
            prior_sigma,
            cost: report.cost,
            iterations: report.iterations,
            termination: report.termination,
            identified: [
                report.estimates.iter().filter(|e| e.identified).count(),
                report.estimates.len(),
            ],
            residual_scale: report.residual_scale,
            parameters: report.estimates.clone(),
            unidentifiable: report.unidentifiable.clone(),
            held_below_zero: report.held_below_zero.clone(),
            group_scales: report.group_scales,
        }
    }
}

/// "## Stiffness identification" with one row per compliance parameter.
pub fn stiffness_markdown(summary: &StiffnessSummary) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "\n## Stiffness identification\n");
    let _ = writeln!(
        out,
        "Prior: the stiffness file, ±{:.0} % (relative). Identified {} of {} compliance parameters jointly with the geometry (cost {:.4} → {:.4}, {} iterations, {:?}, σ̂ = {:.3}); the others are kept at the prior. Scale = identified compliance / prior compliance.\n",
        summary.prior_sigma * 100.0,
        summary.identified[0],
        summary.identified[1],
        summary.cost[0],
        summary.cost[1],
        summary.iterations,
        summary.termination,
        summary.residual_scale
    );
    for (what, (scale, sd)) in ["joint", "link"].iter().zip(summary.group_scales) {
        let _ = writeln!(
            out,
            "Common scale of all {what} compliances: {scale:.4}{}.",
            sd.map_or(" (not identified)".to_owned(), |sd| format!(" ± {sd:.4}"))
        );
    }
    let _ = writeln!(
        out,
        "\nEach compliance's scale is its own times its group's: \"identified\" means on its own; the others follow the common scale.\n"
    );
    let _ = writeln!(
        out,
        "| parameter | unit | prior | identified | std dev | scale | ± | data alone ± | identified |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|");
    for e in &summary.parameters {
        let sd = |v: Option<f64>| v.map_or("—".to_owned(), |v| format!("{v:.4}"));
        let _ = writeln!(
            out,
            "| {} | {} | {:.5e} | {:.5e} | {} | {:.4} | {} | {} | {} |",
            e.name,
            e.unit,
            e.prior_stiffness,
            e.stiffness,
            e.stiffness_std_dev()
                .map_or("—".to_owned(), |v| format!("{v:.3e}")),
            e.scale,
            sd(e.scale_std_dev),
            relative(e.data_std_dev),
            match (e.identified, e.fitted_below_zero) {
                (true, _) => "yes".to_owned(),
                (false, Some(value)) => format!("no (fitted at {value:.3}; prior)"),
                (false, None) => "no (prior)".to_owned(),
            }
        );
    }
    combinations(&mut out, &summary.unidentifiable);
    if !summary.held_below_zero.is_empty() {
        let _ = writeln!(
            out,
            "\nFitted at or below zero (not physical), held at the prior, the fit redone without them:\n"
        );
        for h in &summary.held_below_zero {
            let _ = writeln!(out, "- {h}");
        }
    }
    out
}

/// "## Compliance identifiability": what the pose set determines of each compliance.
pub fn compliance_identifiability_markdown(
    analysis: &ComplianceIdentifiability,
    prior_sigma: f64,
) -> String {
    let mut out = String::new();
    let determined = analysis.parameters.iter().filter(|p| p.2).count();
    let _ = writeln!(out, "\n## Compliance identifiability\n");
    let _ = writeln!(
        out,
        "With the geometric parameters free, these configurations determine {determined} of {} compliance parameters (the individual ones, then the common scales of all joints and all links) to ±{:.1} % or better (a third of the prior's ±{:.0} %). \"±\": standard deviation of the compliance scale at the assumed σ's.\n",
        analysis.parameters.len(),
        prior_sigma * 100.0 * crate::calibration::DETERMINED,
        prior_sigma * 100.0
    );
    let _ = writeln!(out, "| parameter | ± | determined |");
    let _ = writeln!(out, "|---|---|---|");
    for (name, sd, chosen) in &analysis.parameters {
        let _ = writeln!(
            out,
            "| {name} | {} | {} |",
            relative(*sd),
            if *chosen { "yes" } else { "no" }
        );
    }
    combinations(&mut out, &analysis.unidentifiable);
    out
}

fn relative(value: f64) -> String {
    if value.is_finite() {
        format!("{:.3} %", value * 100.0)
    } else {
        "not at all".into()
    }
}

fn combinations(out: &mut String, list: &[String]) {
    if list.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "\nNot separable from each other or from the geometry (kept at the prior):\n"
    );
    for c in list {
        let _ = writeln!(out, "- {c}");
    }
}
