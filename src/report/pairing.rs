//! The pairing report `treecal pair` writes beside its CSV (Markdown): the logs, the clock
//! offset and how sure it is, every plateau kept or rejected and why, and the thresholds.

use crate::pairing::{ClockEstimate, ClockVerdict, Plateau, PlateauOptions, PlateauStatus};

/// Everything the report shows.
#[derive(Debug, Clone)]
pub struct PairingReport<'a> {
    /// The tool link measured.
    pub tool: &'a str,
    /// The joint log, its samples and median sample period (s).
    pub joint_log: (&'a str, usize, f64),
    /// The tracker log, its samples and median sample period (s).
    pub tracker_log: (&'a str, usize, f64),
    /// Tracker rows left out (target not seen) and joint samples left out (a watched joint
    /// missing).
    pub dropped: (usize, usize),
    /// The offset used (s): joint-log time = tracker time + offset.
    pub offset: f64,
    /// The estimate, when the offset was not given.
    pub estimate: Option<&'a ClockEstimate>,
    /// The joint log's first time: the report's times count from it.
    pub time_zero: f64,
    /// Plateaus in time order with the id of each kept one.
    pub plateaus: &'a [(Option<String>, Plateau)],
    /// Brief still moments passed over.
    pub brief: usize,
    /// Whether each watched joint is prismatic (its spread is shown in mm, not deg).
    pub prismatic: &'a [bool],
    /// The thresholds used.
    pub options: &'a PlateauOptions,
}

const DEGREE: f64 = 180.0 / std::f64::consts::PI;

/// The report as Markdown.
pub fn pairing_markdown(report: &PairingReport) -> String {
    let mut out = String::from("# Pairing report (treecal pair)\n\n");
    let (joints, joint_samples, joint_period) = report.joint_log;
    let (tracker, tracker_samples, tracker_period) = report.tracker_log;
    out += &format!("- tool: `{}`\n", report.tool);
    out += &format!(
        "- joint log: `{joints}`: {joint_samples} samples, median period {:.2} ms ({} left out: a watched joint missing)\n",
        joint_period * 1e3,
        report.dropped.1
    );
    out += &format!(
        "- tracker log: `{tracker}`: {tracker_samples} samples, median period {:.2} ms ({} rows left out: target not seen)\n",
        tracker_period * 1e3,
        report.dropped.0
    );
    out += &format!(
        "- times below count from the joint log's first sample ({} s)\n\n",
        report.time_zero
    );
    out += &clock_section(report);
    out += &plateau_section(report);
    out += &thresholds(report.options);
    out
}

fn clock_section(report: &PairingReport) -> String {
    let mut out = String::from("## Clock offset\n\n");
    out += &format!(
        "offset: **{:+.4} s** (joint-log time = tracker time + offset)\n\n",
        report.offset
    );
    let Some(e) = report.estimate else {
        return out + "given with `clock_offset`: not estimated.\n\n";
    };
    let confidence = match &e.verdict {
        ClockVerdict::Confident => "high: one clear correlation peak".to_string(),
        ClockVerdict::Doubtful(why) => format!("LOW: {why}"),
        ClockVerdict::Refused(why) => format!("REFUSED: {why}"),
    };
    let signals = if e.from_rotation {
        "the tool link's rotation speed the joint log implies correlates {:.4} with the rigid body's rotation speed (the same wherever the body sits on the tool)"
    } else {
        "the tool speed the joint log implies correlates {:.4} with the tracker's target speed"
    };
    out += &format!(
        "estimated from the motion: {} at this offset (search step {:.2} ms, refined below it); {} separate motions.\n\n",
        signals.replace("{:.4}", &format!("{:.4}", e.correlation)),
        e.step * 1e3,
        e.motions
    );
    if let Some((offset, correlation)) = e.runner_up {
        out += &format!("next best offset outside the main peak: {offset:+.3} s, correlation {correlation:.4}.\n\n");
    }
    out + &format!("confidence: {confidence}\n\n")
}

fn plateau_section(report: &PairingReport) -> String {
    let kept = report
        .plateaus
        .iter()
        .filter(|(id, _)| id.is_some())
        .count();
    let mut out = format!(
        "## Plateaus\n\n{kept} kept (one measurement row each), {} rejected; {} brief still moments (shorter than a quarter of the minimum duration) not listed.\n\n",
        report.plateaus.len() - kept,
        report.brief
    );
    out += "| id | start (s) | duration (s) | joint samples | tracker samples | marker std (mm) | rotation std (deg) | joint std (deg or mm, largest) | result |\n";
    out += "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n";
    for (id, p) in report.plateaus {
        let optional =
            |v: Option<f64>, scale: f64| v.map_or("-".to_string(), |v| format!("{:.4}", v * scale));
        let joint_std = p
            .joint_std
            .iter()
            .zip(report.prismatic.iter().chain(std::iter::repeat(&false)))
            .map(|(s, &prismatic)| s * if prismatic { 1e3 } else { DEGREE })
            .fold(0.0, f64::max);
        let result = match &p.status {
            PlateauStatus::Kept => "kept".to_string(),
            PlateauStatus::Rejected(why) => format!("rejected: {why}"),
        };
        out += &format!(
            "| {} | {:.3} | {:.3} | {} | {} | {} | {} | {:.5} | {} |\n",
            id.as_deref().unwrap_or("-"),
            p.start - report.time_zero,
            p.end - p.start,
            p.joint_samples,
            p.tracker_samples,
            optional(p.position_spread, 1e3),
            optional(p.rotation_spread, DEGREE),
            joint_std,
            result
        );
    }
    out + "\n"
}

fn thresholds(o: &PlateauOptions) -> String {
    format!(
        "## Thresholds\n\n\
         | still joint speed | still marker speed | speed window | minimum plateau | trimmed at each end | max marker std | max rotation std | max joint std | longest gap |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n\
         | {:.3} deg/s ({:.3} mm/s prismatic) | {:.3} mm/s | {:.3} s | {:.3} s | {:.3} s | {:.3} mm | {:.3} deg | {:.4} deg ({:.4} mm prismatic) | {:.3} s |\n",
        o.joint_speed * DEGREE,
        o.prismatic_speed * 1e3,
        o.marker_speed * 1e3,
        o.window,
        o.min_duration,
        o.margin,
        o.max_marker_spread * 1e3,
        o.max_rotation_spread * DEGREE,
        o.max_joint_spread * DEGREE,
        o.max_prismatic_spread * 1e3,
        o.max_gap
    )
}
