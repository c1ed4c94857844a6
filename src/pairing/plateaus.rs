//! Static plateaus: the intervals where the joints and the tracked target are both still for
//! long enough, averaged into one configuration and one observation each, with their spread.
//! Runs of still samples are cut at dropped samples longer than `max_gap`, and trimmed by
//! `margin` at both ends, so that no sample taken while moving is averaged.

use super::average::measure;
use super::speed::{windowed_speeds, SpeedNorm};
use super::{JointSeries, TrackerSeries};

/// Thresholds of stillness and of an acceptable plateau (SI units).
#[derive(Debug, Clone, PartialEq)]
pub struct PlateauOptions {
    /// Width of the speed window (s), see [`windowed_speeds`].
    pub window: f64,
    /// Fastest still rotational joint (rad/s).
    pub joint_speed: f64,
    /// Fastest still prismatic joint (m/s).
    pub prismatic_speed: f64,
    /// Fastest still target (m/s).
    pub marker_speed: f64,
    /// Shortest plateau (s), after trimming.
    pub min_duration: f64,
    /// Trimmed from both ends of every still run (s).
    pub margin: f64,
    /// Largest RMS distance of the target's samples from their mean (m).
    pub max_marker_spread: f64,
    /// Largest RMS angle of the rigid body's samples from their mean (rad).
    pub max_rotation_spread: f64,
    /// Largest standard deviation of a rotational joint (rad).
    pub max_joint_spread: f64,
    /// Largest standard deviation of a prismatic joint (m).
    pub max_prismatic_spread: f64,
    /// A longer time without samples (s) ends a still run.
    pub max_gap: f64,
    /// Fewest samples of each log in a plateau.
    pub min_samples: usize,
}

impl Default for PlateauOptions {
    fn default() -> Self {
        let degree = std::f64::consts::PI / 180.0;
        Self {
            window: 0.2,
            joint_speed: 0.5 * degree,
            prismatic_speed: 0.5e-3,
            marker_speed: 2e-3,
            min_duration: 1.0,
            margin: 0.1,
            max_marker_spread: 0.5e-3,
            max_rotation_spread: 0.2 * degree,
            max_joint_spread: 0.05 * degree,
            max_prismatic_spread: 0.05e-3,
            max_gap: 0.5,
            min_samples: 5,
        }
    }
}

pub use super::plateau::{Plateau, PlateauStatus};

/// Every plateau found, in time order, and how many brief still moments (shorter than a
/// quarter of the minimum duration, e.g. at a reversal of motion) were passed over.
#[derive(Debug, Clone, PartialEq)]
pub struct PlateauSearch {
    /// Kept and rejected plateaus.
    pub plateaus: Vec<Plateau>,
    /// Brief still moments not listed.
    pub brief: usize,
}

/// Finds the plateaus of `joints` and `tracker` (whose times must already be on the joint
/// clock, see [`TrackerSeries::shifted`]).
pub fn find_plateaus(
    joints: &JointSeries,
    tracker: &TrackerSeries,
    options: &PlateauOptions,
) -> PlateauSearch {
    // Prismatic values scaled so that one threshold (the rotational one) applies to both.
    let scales: Vec<f64> = (0..joints.values.first().map_or(0, Vec::len))
        .map(|d| match joints.prismatic.get(d) {
            Some(true) => options.joint_speed / options.prismatic_speed,
            _ => 1.0,
        })
        .collect();
    let scaled: Vec<Vec<f64>> = joints
        .values
        .iter()
        .map(|row| row.iter().zip(&scales).map(|(v, s)| v * s).collect())
        .collect();
    let joint_speeds = windowed_speeds(&joints.times, &scaled, options.window, SpeedNorm::Max);
    let points: Vec<[f64; 3]> = tracker.positions.iter().map(|p| [p.x, p.y, p.z]).collect();
    let marker_speeds = windowed_speeds(
        &tracker.times,
        &points,
        options.window,
        SpeedNorm::Euclidean,
    );
    let joint_runs = still_runs(&joints.times, &joint_speeds, options.joint_speed, options);
    let tracker_runs = still_runs(
        &tracker.times,
        &marker_speeds,
        options.marker_speed,
        options,
    );
    let mut search = PlateauSearch {
        plateaus: Vec::new(),
        brief: 0,
    };
    for &(start, end) in &joint_runs {
        if end - start < 0.25 * options.min_duration {
            search.brief += 1;
            continue;
        }
        search.plateaus.extend(plateaus_in_run(
            (start, end),
            &tracker_runs,
            joints,
            tracker,
            options,
        ));
    }
    search
}

/// Trimmed `(start, end)` runs of consecutive samples with `speed ≤ threshold`, cut where
/// samples are more than `max_gap` apart.
fn still_runs(
    times: &[f64],
    speeds: &[f64],
    threshold: f64,
    options: &PlateauOptions,
) -> Vec<(f64, f64)> {
    let mut runs = Vec::new();
    let mut open: Option<(f64, f64)> = None;
    for (i, (&t, &speed)) in times.iter().zip(speeds).enumerate() {
        let joined = i > 0 && t - times[i - 1] <= options.max_gap;
        let still = speed <= threshold;
        if let (Some(run), true, true) = (open.as_mut(), still, joined) {
            run.1 = t;
            continue;
        }
        runs.extend(open.take());
        open = still.then_some((t, t));
    }
    runs.extend(open);
    runs.into_iter()
        .map(|(s, e)| (s + options.margin, e - options.margin))
        .filter(|(s, e)| e > s)
        .collect()
}

/// The plateau(s) of one still run of the joints: the longest part where the target was
/// still too, or the run rejected with the reason.
fn plateaus_in_run(
    run: (f64, f64),
    tracker_runs: &[(f64, f64)],
    joints: &JointSeries,
    tracker: &TrackerSeries,
    options: &PlateauOptions,
) -> Vec<Plateau> {
    let mut parts: Vec<(f64, f64)> = tracker_runs
        .iter()
        .map(|&(s, e)| (s.max(run.0), e.min(run.1)))
        .filter(|(s, e)| e - s >= options.min_duration)
        .collect();
    parts.sort_by(|a, b| (b.1 - b.0).total_cmp(&(a.1 - a.0)));
    let Some(&longest) = parts.first() else {
        let reason = lonely_run_reason(run, tracker_runs, tracker, options);
        return vec![measure(
            run,
            joints,
            tracker,
            PlateauStatus::Rejected(reason),
        )];
    };
    let mut plateau = measure(longest, joints, tracker, PlateauStatus::Kept);
    plateau.status = check(&plateau, joints, options);
    let mut others: Vec<Plateau> = parts[1..]
        .iter()
        .map(|&part| measure(part, joints, tracker, PlateauStatus::Kept))
        .collect();
    // Still parts at different places: the target (or the tracker) moved, not the robot.
    let jump = others
        .iter()
        .filter_map(|p| Some((p.position? - plateau.position?).norm()))
        .fold(0.0, f64::max);
    if jump > 3.0 * options.max_marker_spread {
        plateau.status = PlateauStatus::Rejected(format!(
            "the target moved {:.3} mm while the joints were still (between still parts of this plateau); was the tracker or the target bumped?",
            jump * 1e3
        ));
    }
    for other in &mut others {
        other.status = PlateauStatus::Rejected(format!(
            "a shorter still part of the joint plateau at {:.3} s (the target moved or was lost in between)",
            longest.0
        ));
    }
    let mut out = vec![plateau];
    out.extend(others);
    out.sort_by(|a, b| a.start.total_cmp(&b.start));
    out
}

/// Why a still run of the joints has no plateau: too short, no tracker samples, or a target
/// that moved (or was still only briefly).
fn lonely_run_reason(
    run: (f64, f64),
    tracker_runs: &[(f64, f64)],
    tracker: &TrackerSeries,
    options: &PlateauOptions,
) -> String {
    let duration = run.1 - run.0;
    if duration < options.min_duration {
        return format!(
            "still for {duration:.2} s; at least {:.2} s needed",
            options.min_duration
        );
    }
    let inside: Vec<f64> = tracker
        .times
        .iter()
        .copied()
        .filter(|t| (run.0..=run.1).contains(t))
        .collect();
    if inside.is_empty() {
        return "no tracker samples while the joints were still (the target was hidden, or the logs do not overlap here)".into();
    }
    // The time the tracker saw the target (gaps longer than max_gap do not count).
    let seen: f64 = inside
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&dt| dt <= options.max_gap)
        .sum();
    let still: f64 = tracker_runs
        .iter()
        .map(|&(s, e)| (e.min(run.1) - s.max(run.0)).max(0.0))
        .sum();
    let mostly_still = still + 2.0 * options.margin >= 0.8 * seen;
    if mostly_still && seen < options.min_duration + 2.0 * options.margin {
        return format!(
            "the tracker saw the target for only {seen:.2} s of the joints' {duration:.2} s (the target was hidden, or the tracker log starts or ends here)"
        );
    }
    if mostly_still {
        return format!(
            "the target was still for {still:.2} s of the joints' {duration:.2} s but in no part for {:.2} s: its speed crossed the threshold in between (tracker noise? raise `still_marker_speed`)",
            options.min_duration
        );
    }
    format!(
        "the target moved (or was lost) while the joints were still: still for {still:.2} s of the joints' {duration:.2} s, in no part for {:.2} s; was the tracker or the target bumped?",
        options.min_duration
    )
}

/// The verdict on a plateau's samples: enough of them, and their spread within bounds.
fn check(p: &Plateau, joints: &JointSeries, options: &PlateauOptions) -> PlateauStatus {
    let degree = 180.0 / std::f64::consts::PI;
    let limit = |i: usize| match joints.prismatic.get(i) {
        Some(true) => options.max_prismatic_spread,
        _ => options.max_joint_spread,
    };
    // The joint furthest beyond its limit.
    let ratio = |i: usize| p.joint_std[i] / limit(i);
    let widest = (0..p.joint_std.len()).max_by(|&i, &j| ratio(i).total_cmp(&ratio(j)));
    let over = widest.is_some_and(|i| ratio(i) > 1.0);
    let reason = if p.joint_samples < options.min_samples || p.tracker_samples < options.min_samples
    {
        format!(
            "{} joint and {} tracker samples; at least {} of each needed (dropped samples?)",
            p.joint_samples, p.tracker_samples, options.min_samples
        )
    } else if p.position_spread.unwrap_or(f64::INFINITY) > options.max_marker_spread {
        format!(
            "the target's samples spread {:.3} mm RMS; at most {:.3} mm allowed",
            p.position_spread.unwrap_or(f64::INFINITY) * 1e3,
            options.max_marker_spread * 1e3
        )
    } else if p.rotation_spread.unwrap_or(0.0) > options.max_rotation_spread {
        format!(
            "the rigid body's orientation spreads {:.3} deg RMS; at most {:.3} deg allowed",
            p.rotation_spread.unwrap_or(0.0) * degree,
            options.max_rotation_spread * degree
        )
    } else if over {
        let index = widest.unwrap_or(0);
        let name = joints.names.get(index).map_or("?", String::as_str);
        let (scale, unit) = match joints.prismatic.get(index) {
            Some(true) => (1e3, "mm"),
            _ => (degree, "deg"),
        };
        format!(
            "joint '{name}' spreads {:.4} {unit} (standard deviation); at most {:.4} {unit} allowed",
            p.joint_std[index] * scale,
            limit(index) * scale
        )
    } else {
        return PlateauStatus::Kept;
    };
    PlateauStatus::Rejected(reason)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// One joint holding 0 until 3 s, moving to 1 rad by 4 s, holding to 8 s; the target
    /// follows at x = value (m), sampled every 10 ms, except a tracker gap over the move.
    fn logs(gap: bool) -> (JointSeries, TrackerSeries) {
        let value = |t: f64| {
            ((t - 3.0).clamp(0.0, 1.0) * std::f64::consts::PI / 2.0)
                .sin()
                .powi(2)
        };
        let times: Vec<f64> = (0..800).map(|k| k as f64 * 0.01).collect();
        let joints = JointSeries {
            names: vec!["j".into()],
            prismatic: vec![false],
            times: times.clone(),
            values: times.iter().map(|&t| vec![value(t)]).collect(),
        };
        let seen: Vec<f64> = times
            .into_iter()
            .filter(|t| !gap || !(2.5..4.5).contains(t))
            .collect();
        let tracker = TrackerSeries {
            positions: seen
                .iter()
                .map(|&t| Vec3::new(value(t), 0.0, 0.0))
                .collect(),
            times: seen,
            orientations: None,
        };
        (joints, tracker)
    }

    #[test]
    fn two_plateaus_with_no_moving_sample() {
        for gap in [false, true] {
            let (joints, tracker) = logs(gap);
            let search = find_plateaus(&joints, &tracker, &PlateauOptions::default());
            let kept: Vec<&Plateau> = search
                .plateaus
                .iter()
                .filter(|p| p.status == PlateauStatus::Kept)
                .collect();
            assert_eq!(kept.len(), 2, "{search:?}");
            assert!(kept[0].end < 3.0 && kept[1].start > 4.0, "{kept:?}");
            assert_eq!(kept[0].joint_mean, [0.0]);
            assert_eq!(kept[1].joint_mean, [1.0]);
            assert_eq!(kept[1].position_spread, Some(0.0));
        }
    }

    #[test]
    fn a_bumped_target_is_rejected_with_its_reason() {
        let (joints, mut tracker) = logs(false);
        for (t, p) in tracker.times.iter().zip(&mut tracker.positions) {
            p.y = if *t > 6.0 { 0.01 } else { 0.0 };
        }
        let search = find_plateaus(&joints, &tracker, &PlateauOptions::default());
        let rejected: Vec<&PlateauStatus> = search
            .plateaus
            .iter()
            .map(|p| &p.status)
            .filter(|s| **s != PlateauStatus::Kept)
            .collect();
        assert!(
            rejected.iter().any(
                |s| matches!(s, PlateauStatus::Rejected(why) if why.contains("moved 10.000 mm"))
            ),
            "{search:?}"
        );
        assert_eq!(
            search
                .plateaus
                .iter()
                .filter(|p| p.status == PlateauStatus::Kept)
                .count(),
            1
        );
    }
}
