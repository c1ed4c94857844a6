//! Tables of a simulation in the layout of the paper's Table 3.

use crate::measurement::Observation;
use crate::sim::{ArmErrors, TrialReport};
use crate::sim::{ArmSummary, SimulationSummary};
use serde::Serialize;
use std::fmt::Write;

/// The `schema_version` of `results.json` (its layout is documented in docs/file-formats.md).
/// Version 3 writes every enum value in snake_case, as report.json does
/// (`trials[].rigid_run.stages[].termination` was `CostConverged` in version 2).
pub const RESULTS_SCHEMA: &str = "treecal.results/3";

/// `results.json`: every number of a simulation.
#[derive(Debug, Clone, Serialize)]
pub struct SimulationResults<'a> {
    /// [`RESULTS_SCHEMA`].
    pub schema_version: &'static str,
    /// Robot name.
    pub robot: &'a str,
    /// The master seed.
    pub seed: u64,
    /// Mean ± standard deviation over the trials.
    pub summary: &'a SimulationSummary,
    /// Every trial, in trial order.
    pub trials: &'a [TrialReport],
}

/// The `results.json` contents of a simulation of `robot` with master seed `seed`.
pub fn simulation_results<'a>(
    robot: &'a str,
    seed: u64,
    trials: &'a [TrialReport],
    summary: &'a SimulationSummary,
) -> SimulationResults<'a> {
    SimulationResults {
        schema_version: RESULTS_SCHEMA,
        robot,
        seed,
        summary,
        trials,
    }
}

fn trial_table(out: &mut String, title: &str, arms: &[ArmErrors], orientation: bool) {
    let _ = writeln!(out, "### {title}\n");
    let _ = writeln!(
        out,
        "| arm | error | before max | before mean | rigid max | rigid mean | compensated max | compensated mean | removed (rigid) | removed (compensated) |"
    );
    let _ = writeln!(
        out,
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
    );
    for arm in arms {
        let _ = writeln!(
            out,
            "| {} | position (mm) | {:.3} | {:.3} | {:.3} | {:.3} | {:.4} | {:.4} | {:.2} % | {:.3} % |",
            arm.arm,
            arm.before.max_position_mm,
            arm.before.mean_position_mm,
            arm.rigid.max_position_mm,
            arm.rigid.mean_position_mm,
            arm.compensated.max_position_mm,
            arm.compensated.mean_position_mm,
            arm.position_removed_percent[0],
            arm.position_removed_percent[1]
        );
        if !orientation {
            continue;
        }
        let _ = writeln!(
            out,
            "| {} | orientation (deg) | {:.4} | {:.4} | {:.4} | {:.4} | {:.5} | {:.5} | {:.2} % | {:.3} % |",
            arm.arm,
            arm.before.max_orientation_deg,
            arm.before.mean_orientation_deg,
            arm.rigid.max_orientation_deg,
            arm.rigid.mean_orientation_deg,
            arm.compensated.max_orientation_deg,
            arm.compensated.mean_orientation_deg,
            arm.orientation_removed_percent[0],
            arm.orientation_removed_percent[1]
        );
    }
    out.push('\n');
}

fn summary_table(out: &mut String, title: &str, arms: &[ArmSummary], orientation: bool) {
    let _ = writeln!(out, "### {title} (mean ± standard deviation over trials)\n");
    let _ = writeln!(
        out,
        "| arm | error | before mean | rigid mean | compensated mean | removed (rigid) | removed (compensated) |"
    );
    let _ = writeln!(out, "| --- | --- | ---: | ---: | ---: | ---: | ---: |");
    for arm in arms {
        let _ = writeln!(
            out,
            "| {} | position (mm) | {:.3} ± {:.3} | {:.3} ± {:.3} | {:.4} ± {:.4} | {:.2} ± {:.2} % | {:.3} ± {:.3} % |",
            arm.arm,
            arm.before_position_mm.mean,
            arm.before_position_mm.std,
            arm.after_position_mm[0].mean,
            arm.after_position_mm[0].std,
            arm.after_position_mm[1].mean,
            arm.after_position_mm[1].std,
            arm.position_removed_percent[0].mean,
            arm.position_removed_percent[0].std,
            arm.position_removed_percent[1].mean,
            arm.position_removed_percent[1].std
        );
        if !orientation {
            continue;
        }
        let _ = writeln!(
            out,
            "| {} | orientation (deg) | {:.4} ± {:.4} | {:.4} ± {:.4} | {:.5} ± {:.5} | {:.2} ± {:.2} % | {:.3} ± {:.3} % |",
            arm.arm,
            arm.before_orientation_deg.mean,
            arm.before_orientation_deg.std,
            arm.after_orientation_deg[0].mean,
            arm.after_orientation_deg[0].std,
            arm.after_orientation_deg[1].mean,
            arm.after_orientation_deg[1].std,
            arm.orientation_removed_percent[0].mean,
            arm.orientation_removed_percent[0].std,
            arm.orientation_removed_percent[1].mean,
            arm.orientation_removed_percent[1].std
        );
    }
    out.push('\n');
}

/// The Markdown summary: per-arm tables of the first trial (paper Table 3 layout: maximum and
/// mean error before and after, without and with flexibility compensation) and, for more than
/// one trial, mean ± standard deviation over trials.
pub fn simulation_markdown(
    header: &str,
    trials: &[TrialReport],
    summary: &SimulationSummary,
) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "# treecal simulate\n\n{header}\n");
    let _ = writeln!(
        out,
        "Errors are against the true (deflected, noise-free) tool poses. \"rigid\": calibrated ignoring flexibility, predicted rigidly; \"compensated\": calibrated and predicted with the flexibility model. \"removed\": share of the mean error removed.\n"
    );
    // Position-only measurements (one target) cannot see the tool orientation, which is kept at
    // its nominal value: its error is not the calibration's to remove, so it is not shown.
    let orientation = !trials.first().is_some_and(|t| {
        !t.measurements.is_empty()
            && t.measurements
                .iter()
                .all(|m| matches!(m.observation, Observation::Position(_)))
    });
    if !orientation {
        let _ = writeln!(
            out,
            "Position-only measurements (one target per tool): the tool orientation cannot be observed and is kept at its nominal value, so orientation errors are not shown.\n"
        );
    }
    if let Some(first) = trials.first() {
        let _ = writeln!(out, "## Trial 1 (seed {})\n", first.seed);
        trial_table(
            &mut out,
            "Identification configurations",
            &first.identification,
            orientation,
        );
        trial_table(
            &mut out,
            "Validation configurations",
            &first.validation,
            orientation,
        );
        let _ = writeln!(
            out,
            "Measurement noise alone predicts an RMS validation position error of {:.4} mm.\n",
            first.noise_floor_position_mm
        );
        blunder_line(
            &mut out,
            &[first.blunders.counts(0), first.blunders.counts(1)],
        );
    }
    if trials.len() > 1 {
        let _ = writeln!(out, "## All {} trials\n", summary.trials);
        summary_table(
            &mut out,
            "Identification configurations",
            &summary.identification,
            orientation,
        );
        summary_table(
            &mut out,
            "Validation configurations",
            &summary.validation,
            orientation,
        );
        let _ = writeln!(
            out,
            "Noise floor (RMS validation position error predicted from the noise): {:.4} ± {:.4} mm.\n",
            summary.noise_floor_position_mm.mean, summary.noise_floor_position_mm.std
        );
        blunder_line(&mut out, &summary.blunders);
    }
    stiffness_line(&mut out, trials);
    out
}

/// What the stiffness identification made of the trials (nothing without it).
fn stiffness_line(out: &mut String, trials: &[TrialReport]) {
    let estimates: Vec<_> = trials.iter().filter_map(|t| t.stiffness.as_ref()).collect();
    let Some(total) = estimates.first().map(|e| e.len()) else {
        return;
    };
    let identified: Vec<usize> = estimates
        .iter()
        .map(|e| e.iter().filter(|c| c.identified).count())
        .collect();
    let below: Vec<usize> = estimates
        .iter()
        .map(|e| e.iter().filter(|c| c.fitted_below_zero.is_some()).count())
        .collect();
    let _ = writeln!(
        out,
        "Stiffness identification: {}–{} of {total} compliance scales identified per trial; {} fitted at or below zero and held at the prior (in {} of {} trials).\n",
        identified.iter().min().unwrap_or(&0),
        identified.iter().max().unwrap_or(&0),
        below.iter().sum::<usize>(),
        below.iter().filter(|&&b| b > 0).count(),
        estimates.len()
    );
}

/// What robust estimation made of the injected blunders (nothing when there were none and
/// nothing was named).
fn blunder_line(out: &mut String, counts: &[[usize; 3]; 2]) {
    if counts.iter().flatten().all(|&c| c == 0) {
        return;
    }
    let [rigid, compensated] = counts;
    let _ = writeln!(
        out,
        "Blunders named / missed / clean measurements named as outliers: {} / {} / {} (rigid), {} / {} / {} (compensated).\n",
        rigid[0], rigid[1], rigid[2], compensated[0], compensated[1], compensated[2]
    );
}
