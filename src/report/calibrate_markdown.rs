//! The calibrate report in markdown (`report.md`: the paper's Table 2 and Table 3 layouts)
//! and its per-configuration error plots (Fig. 9–12 style).

use super::arm::{ArmReport, RowErrors};
use super::calibrate::{held_out_headline, CalibrationSummary, StageOutcome};
use super::outliers::outliers_markdown;
use super::plot::arm_error_plots_by_id;
use crate::calibration::{
    session_label, IdentificationOptions, ParameterEstimate, Status, Verdict,
};
use crate::error::Result;
use std::borrow::Cow;
use std::fmt::Write;

fn display(p: &ParameterEstimate, value: f64) -> f64 {
    if p.unit == "rad" {
        value.to_degrees()
    } else {
        value * 1e3
    }
}

fn number(value: Option<f64>, digits: usize) -> String {
    match value {
        Some(v) if v.is_finite() => format!("{v:.digits$}"),
        _ => "—".into(),
    }
}

/// The markdown report (`report.md`).
pub fn calibration_markdown(
    summary: &CalibrationSummary,
    options: &IdentificationOptions,
) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "# Calibration of '{}'\n", summary.context.robot);
    verdict_markdown(&mut out, &summary.verdict);
    headline_markdown(&mut out, summary);
    context_markdown(&mut out, summary, options);
    errors_markdown(&mut out, summary);
    if let Some(artifact) = &summary.artifact {
        out.push_str(&artifact.markdown_written(summary.verdict.usable()));
        out.push_str(&session_frames_markdown(summary));
    }
    out.push_str(&outliers_markdown(
        &summary.robust,
        &summary.outliers,
        &summary.down_weighted(),
    ));
    solver_markdown(&mut out, &summary.stages);
    parameters_markdown(&mut out, summary);
    out
}

/// Where the data came from, the assumed noise and the measurement frame.
fn context_markdown(
    out: &mut String,
    summary: &CalibrationSummary,
    options: &IdentificationOptions,
) {
    let c = &summary.context;
    let _ = writeln!(
        out,
        "Measurements: {}. Validation: {}. Plan: {} ({} cycle(s)). Flexibility: {}. Assumed noise: σ = {:.4} mm, {:.4} mrad.\n",
        c.measurements,
        c.validation,
        c.plan,
        summary.cycles,
        c.compensation,
        options.position_sigma * 1e3,
        options.rotation_sigma * 1e3,
    );
    let f = &summary.measurement_frame;
    let _ = writeln!(
        out,
        "Measurement frame ({}): robot base at xyz = ({:.4}, {:.4}, {:.4}) m, rpy = ({:.4}, {:.4}, {:.4}) deg; RMS position distance of the nominal model {:.2} mm before the initial fit, {:.2} mm after.\n",
        c.measurement_frame,
        f.xyz[0],
        f.xyz[1],
        f.xyz[2],
        f.rpy[0].to_degrees(),
        f.rpy[1].to_degrees(),
        f.rpy[2].to_degrees(),
        summary.initial_guess_rms_m[0] * 1e3,
        summary.initial_guess_rms_m[1] * 1e3,
    );

    if let Some(r) = &summary.frame_refinement {
        let _ = writeln!(
            out,
            "The measurement frame was then refined with the parameters through the deflections ({} iteration(s), {} of 6 directions determined; moved by {:.4} deg and {:.3} mm; cost {:.4e} → {:.4e}).\n",
            r.iterations,
            r.determined,
            r.correction[0].to_degrees(),
            r.correction[1] * 1e3,
            r.cost[0],
            r.cost[1]
        );
    }
}

/// The errors before and after, per arm (paper Table 3 layout), by stratum, and as predicted
/// by the covariance.
fn errors_markdown(out: &mut String, summary: &CalibrationSummary) {
    let c = &summary.context;
    // Table 3 layout.
    let _ = writeln!(
        out,
        "\"Before\" is the nominal robot (the URDF's geometry) registered like the calibrated one: its {}tool frames fitted by least squares to the identification rows with the fit's weights (rigid). \"After\" is the calibrated model{}. Every validation row counts; RMS is the headline figure.\n",
        if c.measurement_frame.starts_with("fitted") {
            "measurement frame and "
        } else {
            ""
        },
        if c.compensation.starts_with("compensated") {
            " with its predicted deflections"
        } else {
            ""
        }
    );
    for (title, arms) in [
        ("measurement configurations", &summary.identification),
        ("validation configurations", &summary.validation),
    ] {
        if arms.is_empty() {
            continue;
        }
        let _ = writeln!(out, "## Errors on the {title} (paper Table 3 layout)\n");
        let _ = writeln!(
            out,
            "| arm | n | | before RMS | before max | before mean | after RMS | after max | after mean | RMS removed |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
        for arm in arms {
            let _ = writeln!(
                out,
                "| {} | {} | position (mm) | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.2} % |",
                arm.arm,
                arm.observations,
                arm.before.rms_position_mm,
                arm.before.max_position_mm,
                arm.before.mean_position_mm,
                arm.after.rms_position_mm,
                arm.after.max_position_mm,
                arm.after.mean_position_mm,
                arm.position_removed_percent
            );
            if arm.before.mean_orientation_deg.is_some() {
                let _ = writeln!(
                    out,
                    "| {} | {} | orientation (deg) | {} | {} | {} | {} | {} | {} | {} % |",
                    arm.arm,
                    arm.observations,
                    number(arm.before.rms_orientation_deg, 5),
                    number(arm.before.max_orientation_deg, 5),
                    number(arm.before.mean_orientation_deg, 5),
                    number(arm.after.rms_orientation_deg, 5),
                    number(arm.after.max_orientation_deg, 5),
                    number(arm.after.mean_orientation_deg, 5),
                    number(arm.orientation_removed_percent, 2),
                );
            }
        }
        out.push('\n');
    }
    if let Some(strata) = &summary.validation_strata {
        out.push_str(&strata.markdown());
    }
    if let Some(repeatability) = &summary.repeatability {
        let _ = writeln!(out, "**Repeatability.** {}.\n", repeatability.describe());
    }
    if let Some(rms) = summary.predicted_validation_rms_mm {
        let mut spread = summary.predicted_validation_sd_mm.clone();
        spread.sort_by(f64::total_cmp);
        let at = |f: f64| spread[((spread.len() - 1) as f64 * f).round() as usize];
        let _ = writeln!(
            out,
            "The parameter covariance predicts the position error the measurement noise alone leaves at the validation configurations: RMS {rms:.4} mm; per observation a standard deviation of {:.4} mm (median), {:.4} mm (95th percentile), {:.4} mm (largest). The model error adds to it.\n",
            at(0.5),
            at(0.95),
            at(1.0)
        );
    }
}

/// The solver's outcome per stage and the combinations each stage could not determine.
fn solver_markdown(out: &mut String, stages: &[StageOutcome]) {
    // Solver outcome.
    let _ = writeln!(out, "## Solver, per stage\n");
    let _ = writeln!(
        out,
        "| stage | measurements | equations | iterations | termination | cost | rank | condition | residual RMS | σ̂ |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
    for s in stages {
        let _ = writeln!(
            out,
            // report.md keeps the words it has always shown (`CostConverged`).
            "| {} | {} | {} | {} | {:?} | {:.4e} | {}/{} | {:.3e} | {:.4} mm, {:.5} deg | {:.3} |",
            s.name,
            s.measurements,
            s.rows,
            s.iterations,
            s.termination,
            s.cost,
            s.rank,
            s.parameters,
            s.condition_number,
            s.residual_rms_position_mm,
            s.residual_rms_rotation_deg,
            s.residual_scale
        );
    }
    out.push('\n');
    let _ = writeln!(
        out,
        "σ̂ is the residual against the assumed noise (√(2·cost/(rows − rank)); 1 means the residuals are as large as the noise alone explains; much larger means model error or underestimated noise).\n"
    );
    for s in stages {
        if !s.unidentifiable.is_empty() {
            let _ = writeln!(
                out,
                "Stage '{}': {} combination(s) the data cannot determine (kept at their starting values):\n",
                s.name,
                s.unidentifiable.len()
            );
            for name in &s.unidentifiable {
                let _ = writeln!(out, "- {name}");
            }
            out.push('\n');
        }
    }
}

/// The calibrated parameters (paper Table 2 layout), the closed-form starts and the changed
/// joints.
fn parameters_markdown(out: &mut String, summary: &CalibrationSummary) {
    // Table 2 layout.
    let _ = writeln!(
        out,
        "## Calibrated parameters (paper Table 2 layout; deg and mm)\n"
    );
    let _ = writeln!(
        out,
        "| frame | parameter | nominal | calibrated | change | std. dev. | identifiable |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for p in &summary.parameters {
        let _ = writeln!(
            out,
            "| {} | {} ({}) | {:.4} | {:.4} | {:+.4} | {} | {} |",
            p.owner,
            p.kind,
            if p.unit == "rad" { "deg" } else { "mm" },
            display(p, p.nominal),
            display(p, p.calibrated),
            display(p, p.change),
            number(p.std_dev.map(|s| display(p, s)), 4),
            if p.identifiable { "yes" } else { "no" }
        );
    }
    out.push('\n');
    starts_markdown(out, &summary.parameters);
    if !summary.changed_joints.is_empty() {
        let _ = writeln!(
            out,
            "calibrated.urdf: the origins (and, where needed, axes) of {} joint(s) changed: {}.",
            summary.changed_joints.len(),
            summary.changed_joints.join(", ")
        );
    }
}

fn headline_markdown(out: &mut String, summary: &CalibrationSummary) {
    let Some(headline) = held_out_headline(summary) else {
        return;
    };
    let _ = write!(
        out,
        "**Held-out accuracy:** RMS position error {:.3} mm over all {} validation rows (before: {:.3} mm, the registered nominal robot){}",
        headline.rms,
        headline.observations,
        headline.before_rms,
        headline.flagged_text()
    );
    let written = summary.artifact.as_ref().into_iter().flat_map(|a| {
        [a.urdf_alone.as_ref(), a.with_compensation.as_ref()]
            .into_iter()
            .flatten()
    });
    let as_written = if summary.verdict.usable() {
        "as written"
    } else {
        "(not written: the verdict failed) would give"
    };
    for score in written {
        let _ = write!(
            out,
            "; {} {as_written}: {:.3} mm",
            score.files, score.errors.rms_position_mm
        );
    }
    out.push_str(".\n\n");
}

/// The parameters whose fit started away from the URDF value (the closed-form fit of the
/// measured frames), listed apart from Table 2's nominal column.
fn starts_markdown(out: &mut String, parameters: &[ParameterEstimate]) {
    let moved: Vec<String> = parameters
        .iter()
        .filter(|p| (p.start - p.nominal).abs() > 1e-9)
        .map(|p| {
            let unit = if p.unit == "rad" { "deg" } else { "mm" };
            format!("{} {} {:.4} {unit}", p.owner, p.kind, display(p, p.start))
        })
        .collect();
    if !moved.is_empty() {
        let _ = writeln!(
            out,
            "Closed-form start (initial guess of the measured frames, not the URDF; the nominal column is the URDF's value): {}.\n",
            moved.join(", ")
        );
    }
}

/// The verdict and its reasons, as the report's first section.
fn verdict_markdown(out: &mut String, verdict: &Verdict) {
    let meaning = match verdict.status {
        Status::Ok => "the result can be used",
        Status::Warning => "the result can be used, but read the warnings",
        Status::Failed => "the result must not be used; calibrated.urdf was not written",
    };
    let _ = writeln!(out, "**Verdict: {}** ({meaning}).\n", verdict.status);
    for reason in &verdict.reasons {
        let label = match reason.status {
            Status::Ok => "note",
            Status::Warning => "warning",
            Status::Failed => "failed",
        };
        let _ = writeln!(out, "- {label} ({}): {}", reason.code, reason.message);
    }
    if !verdict.reasons.is_empty() {
        out.push('\n');
    }
}

/// The per-configuration error plots of one data set: `(file stem, SVG)` per arm and quantity,
/// stems `<arm>_<set>_<quantity>`, the x axis labelled by the rows' ids.
pub fn calibration_plots(arms: &[ArmReport], set: &str) -> Result<Vec<(String, String)>> {
    // One arm at a time: in parallel, two arms' labels and columns (at 10⁶ configurations
    // some hundred MB) would add to the peak memory, for half a second.
    let mut plots = Vec::new();
    for arm in arms {
        plots.extend(arm_plots(arm, set)?);
    }
    Ok(plots)
}

/// The position and orientation plots of one arm's rows of data set `set`.
fn arm_plots(arm: &ArmReport, set: &str) -> Result<Vec<(String, String)>> {
    let mut plots = Vec::new();
    // Outliers stay in the plots, marked `*`.
    let ids: Vec<String> = arm
        .rows
        .iter()
        .map(|r| {
            if r.outlier {
                format!("{}*", r.id)
            } else {
                r.id.clone()
            }
        })
        .collect();
    let marked = arm.rows.iter().any(|r| r.outlier);
    let column = |f: &dyn Fn(&RowErrors) -> Option<f64>| -> Vec<f64> {
        arm.rows.iter().filter_map(f).collect()
    };
    let position = [
        column(&|r| Some(r.position_mm.before)),
        column(&|r| Some(r.position_mm.after)),
    ];
    let orientation = [
        column(&|r| r.orientation_deg.map(|o| o.before)),
        column(&|r| r.orientation_deg.map(|o| o.after)),
    ];
    // Rows observing a position only (a mixed file) have no orientation error: the
    // orientation plot is labelled by the rows that have one.
    let oriented: Cow<'_, [String]> = if arm.rows.iter().all(|r| r.orientation_deg.is_some()) {
        Cow::Borrowed(&ids)
    } else {
        ids.iter()
            .zip(&arm.rows)
            .filter(|(_, r)| r.orientation_deg.is_some())
            .map(|(id, _)| id.clone())
            .collect()
    };
    let title = format!(
        "on the {set} configurations{}",
        if marked {
            " (* outlier, still counted)"
        } else {
            ""
        }
    );
    let labels = ["before calibration", "after calibration"];
    let stem = format!("{}_{set}", arm.arm);
    let none = [Vec::new(), Vec::new()];
    plots.extend(arm_error_plots_by_id(
        &arm.arm, &stem, &title, &labels, &ids, &position, &none,
    )?);
    plots.extend(arm_error_plots_by_id(
        &arm.arm,
        &stem,
        &title,
        &labels,
        &oriented,
        &none,
        &orientation,
    )?);
    Ok(plots)
}

/// With several sessions the written registration is the first session's frame: what else
/// scores the other sessions' rows (their frames are in report.json only).
fn session_frames_markdown(summary: &CalibrationSummary) -> String {
    let Some(sessions) = summary.sessions.as_ref().filter(|s| s.training.len() > 1) else {
        return String::new();
    };
    let others: Vec<String> = sessions.training[1..]
        .iter()
        .map(|s| session_label(&s.name))
        .collect();
    format!(
        "registration.yaml is the first session's frame ({}). The rows of {} are scored in \
         their own session's frame: report.json `sessions.training[].session_from_first` \
         (xyz m, rpy rad), applied after it (measured = session_from_first · registration · \
         link pose).\n\n",
        session_label(&sessions.training[0].name),
        others.join(", ")
    )
}
