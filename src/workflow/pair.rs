//! `pair`: a joint-state log and a tracker log → the measurement CSV, with a pairing report.
//! The clock offset comes from the motion (or is given), the measurements from the static
//! plateaus (`crate::pairing`). See docs/workflows.md and docs/file-formats.md.

use super::note::Note;
use super::source::RobotSource;
use crate::error::{Error, Result};
use crate::io::{
    paired_measurements_to_csv, read_joint_log, read_tracker_log, write_atomically, JointLog,
    JointLogOptions, MeasurementUnits, PairedRow, TrackerLog, TrackerLogOptions,
};
use crate::limits::{self, Quantity};
use crate::pairing::{
    estimate_clock_offset, find_plateaus, median_period, windowed_speeds, ClockEstimate,
    ClockOptions, ClockVerdict, JointSeries, Plateau, PlateauOptions, PlateauStatus, TrackerSeries,
};
use crate::report::{pairing_markdown, PairingReport};
use crate::tree::{Actuation, JointKind, KinematicTree};
use std::path::{Path, PathBuf};

/// What to pair. `Default` holds the CLI's defaults (with empty paths and tool).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PairConfig {
    /// The robot (its joint names and, for the clock, its forward kinematics).
    pub robot: RobotSource,
    /// The tool link the tracker's target is on.
    pub tool: String,
    /// The joint-state log: CSV or MCAP.
    pub joints: PathBuf,
    /// How to read it.
    pub joint_log: JointLogOptions,
    /// The tracker log (CSV).
    pub tracker: PathBuf,
    /// How to read it.
    pub tracker_log: TrackerLogOptions,
    /// A known clock offset (s; joint-log time = tracker time + offset) instead of the estimate.
    pub clock_offset: Option<f64>,
    /// Limits of the offset estimate.
    pub clock: ClockOptions,
    /// Stillness thresholds.
    pub plateaus: PlateauOptions,
}

/// The paired measurements and the report.
#[derive(Debug, Clone)]
pub struct Pairing {
    /// The measurement CSV (docs/file-formats.md, section 4).
    pub csv: String,
    /// The pairing report (Markdown).
    pub report: String,
    /// The offset used (s): joint-log time = tracker time + offset.
    pub offset: f64,
    /// The estimate, when the offset was not given.
    pub estimate: Option<ClockEstimate>,
    /// Every plateau in time order, with the id of each kept one.
    pub plateaus: Vec<(Option<String>, Plateau)>,
    /// What the user should know, in order.
    pub notes: Vec<Note>,
}

impl Pairing {
    /// Writes the CSV to `csv` and the report to `report` (atomically).
    pub fn write(&self, csv: &Path, report: &Path) -> Result<()> {
        write_atomically(csv, self.csv.as_bytes())?;
        write_atomically(report, self.report.as_bytes())
    }

    /// The rows written.
    pub fn kept(&self) -> usize {
        self.plateaus.iter().filter(|(id, _)| id.is_some()).count()
    }
}

/// The report's path beside a CSV: `M.csv` → `M.pairing.md`.
pub fn report_path(csv: &Path) -> PathBuf {
    csv.with_extension("pairing.md")
}

/// Reads both logs, finds the clock offset and the plateaus, and builds the CSV and report.
pub fn pair(config: &PairConfig) -> Result<Pairing> {
    let robot = config.robot.load()?;
    let mut notes = robot.notes();
    let tree = robot.tree();
    let tool = tree.link_id(config.tool.trim())?;
    let log = read_joint_log(&config.joints, &config.joint_log)?;
    let tracker_log = read_tracker_log(&config.tracker, &config.tracker_log)?;
    let columns = joint_columns(tree, &log, &config.tool, &mut notes)?;
    let (series, all, dropped_joint_samples) = joint_series(tree, &log, &columns)?;
    if dropped_joint_samples > 0 {
        notes.push(Note::warning(format!(
            "{}: {dropped_joint_samples} samples without a value for every joint moving '{}' were left out",
            log.origin, config.tool
        )));
    }
    let tracker = TrackerSeries {
        times: tracker_log.times.clone(),
        positions: tracker_log.positions.clone(),
        orientations: tracker_log.orientations.clone(),
    };
    let (offset, estimate) =
        clock_offset(config, tree, tool, &columns, &series, &tracker, &mut notes)?;
    let search = find_plateaus(&series, &tracker.shifted(offset), &config.plateaus);
    let mut plateaus = Vec::with_capacity(search.plateaus.len());
    let mut rows = Vec::new();
    for plateau in search.plateaus {
        if plateau.status != PlateauStatus::Kept {
            plateaus.push((None, plateau));
            continue;
        }
        let id = format!("{}-{}", config.tool.trim(), rows.len() + 1);
        rows.push(PairedRow {
            id: id.clone(),
            tool: config.tool.trim().to_owned(),
            joints: all.mean_over(plateau.start, plateau.end),
            position: plateau.position.unwrap_or_default(),
            orientation: plateau.orientation,
        });
        plateaus.push((Some(id), plateau));
    }
    let report = PairingReport {
        tool: config.tool.trim(),
        joint_log: (&log.origin, log.times.len(), median_period(&log.times)),
        tracker_log: (
            &tracker_log.origin,
            tracker_log.times.len(),
            median_period(&tracker_log.times),
        ),
        dropped: (tracker_log.dropped.len(), dropped_joint_samples),
        offset,
        estimate: estimate.as_ref(),
        time_zero: log.times[0],
        plateaus: &plateaus,
        brief: search.brief,
        prismatic: &series.prismatic,
        options: &config.plateaus,
    };
    let report = pairing_markdown(&report) + &provenance_markdown(config)?;
    if rows.is_empty() {
        return Err(Error::InvalidData {
            origin: format!("{} and {}", log.origin, tracker_log.origin),
            message: no_plateau_message(&plateaus, search.brief),
        });
    }
    let csv = write_csv(&log, &tracker_log, &columns, &rows, offset)?;
    Ok(Pairing {
        csv,
        report,
        offset,
        estimate,
        plateaus,
        notes,
    })
}

/// Where the pairing came from (the report's last section): treecal's version and commit,
/// and every input file with its size and SHA-256 (what `sha256sum` prints). Nothing of the
/// run's time, so the same logs give the same report.
fn provenance_markdown(config: &PairConfig) -> Result<String> {
    let commit = crate::io::commit_description(crate::io::GIT_COMMIT, crate::io::GIT_DIRTY);
    let mut out = format!(
        "## Provenance\n\ntreecal {} (commit {commit}); robot: {}\n\n| input | bytes | sha256 |\n| --- | ---: | --- |\n",
        env!("CARGO_PKG_VERSION"),
        config
            .robot
            .path()
            .map_or_else(|| "the built-in Robonaut".to_owned(), |p| format!("`{}`", p.display()))
    );
    let inputs = config
        .robot
        .path()
        .into_iter()
        .chain([config.joints.as_path(), config.tracker.as_path()]);
    for path in inputs {
        let file = crate::io::input_file(path)?;
        out += &format!("| `{}` | {} | {} |\n", file.path, file.bytes, file.sha256);
    }
    Ok(out)
}

/// A joint-log column that is an independent joint of the robot.
struct JointColumn {
    /// Its index among the log's names.
    column: usize,
    /// Its configuration index in the tree.
    dof: usize,
    prismatic: bool,
    /// Whether it moves the tool (is watched for stillness).
    moves_tool: bool,
}

/// Why nothing was paired: the first reasons, counted.
fn no_plateau_message(plateaus: &[(Option<String>, Plateau)], brief: usize) -> String {
    let reasons: Vec<String> = plateaus
        .iter()
        .filter_map(|(_, p)| match &p.status {
            PlateauStatus::Rejected(why) => Some(format!("at {:.3} s: {why}", p.start)),
            PlateauStatus::Kept => None,
        })
        .collect();
    let mut message = format!(
        "no plateau where both logs are still for long enough was found ({} rejected, {brief} brief still moments); the thresholds are in docs/workflows.md (pair)",
        reasons.len()
    );
    for reason in reasons.iter().take(3) {
        message.push_str(&format!("; {reason}"));
    }
    if reasons.len() > 3 {
        message.push_str(&format!("; … and {} more", reasons.len() - 3));
    }
    message
}

/// The joint log's columns treecal uses.
struct JointColumns {
    used: Vec<JointColumn>,
}

impl JointColumns {
    fn watched(&self) -> impl Iterator<Item = &JointColumn> {
        self.used.iter().filter(|c| c.moves_tool)
    }
}

/// Maps the log's names onto the robot's independent joints; every joint that moves the
/// tool must be in the log. Other names are notes.
fn joint_columns(
    tree: &KinematicTree,
    log: &JointLog,
    tool: &str,
    notes: &mut Vec<Note>,
) -> Result<JointColumns> {
    let tool_link = tree.link_id(tool.trim())?;
    let moving: Vec<usize> = tree
        .path_from_root(tool_link)
        .into_iter()
        .filter_map(|j| tree.joint(j).actuation.driver().map(|dof| dof.0))
        .collect();
    let mut used = Vec::new();
    let mut unused = Vec::new();
    for (column, name) in log.names.iter().enumerate() {
        let joint = tree.joint_id(name).ok().map(|j| tree.joint(j));
        match joint.map(|j| (&j.actuation, j.kind)) {
            Some((Actuation::Independent(dof), kind)) => used.push(JointColumn {
                column,
                dof: dof.0,
                prismatic: kind == JointKind::Prismatic,
                moves_tool: moving.contains(&dof.0),
            }),
            _ => unused.push(name.as_str()),
        }
    }
    if !unused.is_empty() {
        notes.push(Note::info(format!(
            "{}: {} names that are not independent joints of '{}' are not used: {}",
            log.origin,
            unused.len(),
            tree.name(),
            unused
                .iter()
                .take(8)
                .copied()
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let missing: Vec<String> = moving
        .iter()
        .filter(|dof| !used.iter().any(|c| c.dof == **dof))
        .map(|&dof| tree.joint(tree.dofs()[dof]).name.clone())
        .collect();
    if !missing.is_empty() {
        return Err(Error::InvalidData {
            origin: log.origin.clone(),
            message: format!(
                "no values for {} joints that move '{tool}': {}; the log must name them as the URDF does",
                missing.len(),
                missing.join(", ")
            ),
        });
    }
    Ok(JointColumns { used })
}

/// How long (s) a watched joint's last value stands in for a sample that does not give it.
const HOLD_LAST: f64 = 0.1;

/// Every used joint of every sample, SI, NaN where absent: for averaging over a plateau.
struct AllJoints {
    times: Vec<f64>,
    values: Vec<Vec<f64>>,
}

impl AllJoints {
    /// The mean of every used joint over the samples in `[start, end]`, NaN for none.
    fn mean_over(&self, start: f64, end: f64) -> Vec<f64> {
        let width = self.values.first().map_or(0, Vec::len);
        (0..width)
            .map(|c| {
                let (sum, n) = self
                    .times
                    .iter()
                    .zip(&self.values)
                    .filter(|(t, row)| (start..=end).contains(*t) && !row[c].is_nan())
                    .fold((0.0, 0usize), |(s, n), (_, row)| (s + row[c], n + 1));
                if n == 0 {
                    f64::NAN
                } else {
                    sum / n as f64
                }
            })
            .collect()
    }
}

/// The watched joints' series (samples having all of them), every used joint's values, and
/// how many samples lacked a watched joint. Values are converted to SI and bounded.
fn joint_series(
    tree: &KinematicTree,
    log: &JointLog,
    columns: &JointColumns,
) -> Result<(JointSeries, AllJoints, usize)> {
    let angle = log.angle_unit.in_radians();
    let length = log.joint_length_unit.in_metres();
    let mut series = JointSeries {
        names: columns
            .watched()
            .map(|c| tree.joint(tree.dofs()[c.dof]).name.clone())
            .collect(),
        prismatic: columns.watched().map(|c| c.prismatic).collect(),
        ..JointSeries::default()
    };
    let mut all = AllJoints {
        times: log.times.clone(),
        values: Vec::with_capacity(log.times.len()),
    };
    let mut dropped = 0;
    let mut last: Vec<Option<(f64, f64)>> = vec![None; series.names.len()];
    for (i, raw) in log.values.iter().enumerate() {
        let mut row = Vec::with_capacity(columns.used.len());
        for c in &columns.used {
            let value = raw[c.column] * if c.prismatic { length } else { angle };
            let quantity = if c.prismatic {
                Quantity::Length
            } else {
                Quantity::Angle
            };
            if !value.is_nan() {
                limits::check(value, quantity, || {
                    format!("{}:{}", log.places[i], log.names[c.column])
                })?;
            }
            row.push(value);
        }
        // A watched joint this sample does not give (another publisher's message) holds its
        // last value if that is at most HOLD_LAST seconds old.
        let t = log.times[i];
        let mut watched = Vec::with_capacity(last.len());
        for (k, value) in columns
            .used
            .iter()
            .zip(&row)
            .filter(|(c, _)| c.moves_tool)
            .map(|(_, v)| *v)
            .enumerate()
        {
            if !value.is_nan() {
                last[k] = Some((t, value));
            }
            watched.push(match last[k] {
                Some((at, held)) if value.is_nan() && t - at <= HOLD_LAST => held,
                _ => value,
            });
        }
        if watched.iter().any(|v| v.is_nan()) {
            dropped += 1;
        } else {
            series.times.push(log.times[i]);
            series.values.push(watched);
        }
        all.values.push(row);
    }
    Ok((series, all, dropped))
}

/// The offset to use: the given one, or the estimate (refused → error, doubtful → warning).
fn clock_offset(
    config: &PairConfig,
    tree: &KinematicTree,
    tool: crate::tree::LinkId,
    columns: &JointColumns,
    series: &JointSeries,
    tracker: &TrackerSeries,
    notes: &mut Vec<Note>,
) -> Result<(f64, Option<ClockEstimate>)> {
    if let Some(offset) = config.clock_offset {
        return Ok((offset, None));
    }
    let estimate = match &tracker.orientations {
        // A rigid body turns as the tool link does: its rotation speed does not depend on
        // the tracker frame nor on where the body sits (a point's speed has the lever arm).
        Some(orientations) => {
            let by_rotation = estimate_from(
                config,
                (series, columns, tree.zero_configuration()),
                (&tracker.times, &rotation_samples(orientations)),
                |q| Ok(rotation_entries(&tree.link_pose(tool, q)?.rotation)),
            )?;
            match by_rotation.verdict {
                ClockVerdict::Confident => ClockEstimate {
                    from_rotation: true,
                    ..by_rotation
                },
                _ => by_position(config, tree, tool, columns, series, tracker)?,
            }
        }
        None => by_position(config, tree, tool, columns, series, tracker)?,
    };
    match &estimate.verdict {
        ClockVerdict::Refused(why) => Err(Error::InvalidData {
            origin: format!("{} and {}", config.joints.display(), config.tracker.display()),
            message: format!(
                "{why}; give the offset with `clock_offset` SECONDS (joint-log time = tracker time + offset)"
            ),
        }),
        ClockVerdict::Doubtful(why) => {
            notes.push(Note::warning(format!(
                "clock offset {:+.4} s has low confidence: {why}; check the pairing report, or give it with `clock_offset`",
                estimate.offset
            )));
            Ok((estimate.offset, Some(estimate)))
        }
        ClockVerdict::Confident => Ok((estimate.offset, Some(estimate))),
    }
}

/// The estimate from the speed of the tool point (the joint side) and of the target.
fn by_position(
    config: &PairConfig,
    tree: &KinematicTree,
    tool: crate::tree::LinkId,
    columns: &JointColumns,
    series: &JointSeries,
    tracker: &TrackerSeries,
) -> Result<ClockEstimate> {
    let points: Vec<[f64; 3]> = tracker.positions.iter().map(|p| [p.x, p.y, p.z]).collect();
    let joints = (series, columns, tree.zero_configuration());
    estimate_from(config, joints, (&tracker.times, &points), |q| {
        let p = tree.link_pose(tool, q)?.translation.vector;
        Ok([p.x, p.y, p.z])
    })
}

/// The estimate from the speed of `signal` (of a configuration) along the joint log against
/// the speed of the tracker's samples (times, values); both speeds are Euclidean norms of the
/// change over the plateau window, which a rotation of the tracker frame does not change.
fn estimate_from<const N: usize>(
    config: &PairConfig,
    (series, columns, zero): (&JointSeries, &JointColumns, Vec<f64>),
    (tracker_times, tracker_samples): (&[f64], &[[f64; N]]),
    signal: impl Fn(&[f64]) -> Result<[f64; N]>,
) -> Result<ClockEstimate> {
    let mut q = zero;
    let mut path = Vec::with_capacity(series.times.len());
    for values in &series.values {
        for (c, v) in columns.watched().zip(values) {
            q[c.dof] = *v;
        }
        path.push(signal(&q)?);
    }
    let window = config.plateaus.window;
    let norm = crate::pairing::SpeedNorm::Euclidean;
    let joint_speeds = windowed_speeds(&series.times, &path, window, norm);
    let tracker_speeds = windowed_speeds(tracker_times, tracker_samples, window, norm);
    Ok(estimate_clock_offset(
        &series.times,
        &joint_speeds,
        tracker_times,
        &tracker_speeds,
        &config.clock,
    ))
}

/// A rotation as the nine entries of its matrix: the Frobenius norm of a change of them is
/// the same in any tracker frame and for any body fixed on the tool (R·B, F·R).
fn rotation_entries(rotation: &crate::math::Rotation) -> [f64; 9] {
    let m = rotation.to_rotation_matrix().into_inner();
    std::array::from_fn(|k| m[(k / 3, k % 3)])
}

fn rotation_samples(orientations: &[crate::math::Rotation]) -> Vec<[f64; 9]> {
    orientations.iter().map(rotation_entries).collect()
}

/// The CSV in the logs' units: joints as the joint log, positions as the tracker log.
fn write_csv(
    log: &JointLog,
    tracker: &TrackerLog,
    columns: &JointColumns,
    rows: &[PairedRow],
    offset: f64,
) -> Result<String> {
    let units = MeasurementUnits {
        length: tracker.length_unit,
        angle: log.angle_unit,
        joint_length: log.joint_length_unit,
        rotation: log.angle_unit,
    };
    let names: Vec<String> = columns
        .used
        .iter()
        .map(|c| log.names[c.column].clone())
        .collect();
    let prismatic: Vec<bool> = columns.used.iter().map(|c| c.prismatic).collect();
    let comment = format!(
        "paired by treecal pair from {} and {} (clock offset {offset:+.6} s); see the pairing report",
        log.origin, tracker.origin
    );
    paired_measurements_to_csv(&names, &prismatic, rows, &units, &[comment])
}
