//! The clock offset between a joint log and a tracker log, from the motion itself: the lag
//! that best correlates the joint side's speed (the tool speed the joint values imply) with
//! the tracker's target speed. A coarse search over every lag that overlaps the logs enough,
//! then a fine one around the best, refined below the sample period by a parabola through
//! the three best correlations. Speed magnitudes do not depend on the unknown tracker frame.

use super::median_period;

/// Limits of the offset search and of its trust.
#[derive(Debug, Clone, PartialEq)]
pub struct ClockOptions {
    /// Smallest overlap of the logs at a candidate lag, as a fraction of the shorter log.
    pub min_overlap: f64,
    /// A second correlation peak at least this fraction of the best: the offset is ambiguous
    /// and refused.
    pub ambiguous_ratio: f64,
    /// A second peak at least this fraction of the best: the offset is doubtful (a warning).
    pub doubtful_ratio: f64,
    /// A best correlation below this: the logs do not show the same motion; refused.
    pub min_correlation: f64,
    /// A best correlation below this: doubtful.
    pub good_correlation: f64,
    /// Fewest separate motions the overlap must show.
    pub min_motions: usize,
    /// Most points of the coarse search's grid (the fine grid is the shorter sample period).
    pub coarse_points: usize,
}

impl Default for ClockOptions {
    fn default() -> Self {
        Self {
            min_overlap: 0.5,
            ambiguous_ratio: 0.9,
            doubtful_ratio: 0.75,
            min_correlation: 0.5,
            good_correlation: 0.8,
            min_motions: 3,
            coarse_points: 4096,
        }
    }
}

/// Whether an estimated offset can be used.
#[derive(Debug, Clone, PartialEq)]
pub enum ClockVerdict {
    /// One clear correlation peak.
    Confident,
    /// Usable, but look at it (the reason).
    Doubtful(String),
    /// Not usable (the reason): give the offset instead.
    Refused(String),
}

/// An estimated clock offset: joint-log time = tracker time + `offset`.
#[derive(Debug, Clone, PartialEq)]
pub struct ClockEstimate {
    /// Seconds to add to tracker times to get joint-log times.
    pub offset: f64,
    /// The correlation of the two speed signals at `offset` (1: identical shapes).
    pub correlation: f64,
    /// The best other offset outside the main peak and its correlation.
    pub runner_up: Option<(f64, f64)>,
    /// The fine search's step (s): the shorter median sample period.
    pub step: f64,
    /// Separate motions seen in the overlap at `offset`.
    pub motions: usize,
    /// Whether to use it.
    pub verdict: ClockVerdict,
    /// Whether the signals were rotation speeds (a rigid body's, against the tool link's the
    /// joint log implies: equal wherever the body sits on the tool) rather than point speeds.
    pub from_rotation: bool,
}

/// Estimates the offset from the joint side's speed (`joint_times`, `joint_speeds`) and the
/// tracker's (`tracker_times`, `tracker_speeds`); non-finite speeds are skipped.
pub fn estimate_clock_offset(
    joint_times: &[f64],
    joint_speeds: &[f64],
    tracker_times: &[f64],
    tracker_speeds: &[f64],
    options: &ClockOptions,
) -> ClockEstimate {
    let refused = |reason: String| ClockEstimate {
        offset: 0.0,
        correlation: 0.0,
        runner_up: None,
        step: 0.0,
        motions: 0,
        verdict: ClockVerdict::Refused(reason),
        from_rotation: false,
    };
    let (ja, jv) = finite(joint_times, joint_speeds);
    let (ta, tv) = finite(tracker_times, tracker_speeds);
    if ja.len() < 3 || ta.len() < 3 {
        return refused("too few samples to estimate the clock offset".into());
    }
    let step = fine_step(&ja, &ta);
    let a = resample(&ja, &jv, step);
    let b = resample(&ta, &tv, step);
    let factor = a
        .len()
        .max(b.len())
        .div_ceil(options.coarse_points.max(1))
        .max(1);
    let (ac, bc) = (block_means(&a, factor), block_means(&b, factor));
    let min_overlap =
        ((options.min_overlap * ac.len().min(bc.len()) as f64).ceil() as usize).max(2);
    let coarse: Vec<(isize, f64)> = (-(bc.len() as isize)..=ac.len() as isize)
        .filter_map(|k| correlation(&ac, &bc, k, min_overlap).map(|c| (k, c)))
        .collect();
    let Some(best) = (0..coarse.len()).max_by(|&i, &j| coarse[i].1.total_cmp(&coarse[j].1)) else {
        return refused(
            "the logs do not overlap in time by half the shorter one at any offset".into(),
        );
    };
    let runner_up = runner_up(&coarse, best);
    let (lag, correlation_at) = refine(&a, &b, coarse[best].0, factor);
    let offset = ja[0] - ta[0] + lag * step;
    let motions = count_motions(&ac, &bc, coarse[best].0);
    let c1 = correlation_at;
    let runner = runner_up.map(|i| {
        (
            ja[0] - ta[0] + (coarse[i].0 * factor as isize) as f64 * step,
            coarse[i].1,
        )
    });
    let ratio = runner.map_or(0.0, |(_, c2)| {
        c2.max(0.0) / coarse[best].1.max(f64::MIN_POSITIVE)
    });
    let verdict = verdict(c1, ratio, runner, motions, options);
    ClockEstimate {
        offset,
        correlation: c1,
        runner_up: runner,
        step,
        motions,
        verdict,
        from_rotation: false,
    }
}

/// The verdict on a peak of correlation `c1` whose runner-up is `ratio` of it.
fn verdict(
    c1: f64,
    ratio: f64,
    runner: Option<(f64, f64)>,
    motions: usize,
    options: &ClockOptions,
) -> ClockVerdict {
    let second = runner.map_or(String::new(), |(o, c)| {
        format!(" (the next best offset, {o:+.3} s, correlates {c:.3})")
    });
    if motions < options.min_motions {
        ClockVerdict::Refused(format!(
            "too little motion to estimate the clock offset: {motions} separate motions in the overlap, at least {} needed",
            options.min_motions
        ))
    } else if c1 < options.min_correlation {
        ClockVerdict::Refused(format!(
            "the logs' speeds correlate at most {c1:.3} (below {}): they may not record the same motion",
            options.min_correlation
        ))
    } else if ratio >= options.ambiguous_ratio {
        ClockVerdict::Refused(format!(
            "the clock offset is ambiguous: two offsets correlate almost equally{second}; repetitive motion (equal moves and pauses) causes this"
        ))
    } else if ratio >= options.doubtful_ratio {
        ClockVerdict::Doubtful(format!("a second offset correlates nearly as well{second}"))
    } else if c1 < options.good_correlation {
        ClockVerdict::Doubtful(format!(
            "the logs' speeds correlate only {c1:.3} at the best offset{second}"
        ))
    } else {
        ClockVerdict::Confident
    }
}

/// The samples whose value is finite.
fn finite(times: &[f64], values: &[f64]) -> (Vec<f64>, Vec<f64>) {
    times
        .iter()
        .zip(values)
        .filter(|(t, v)| t.is_finite() && v.is_finite())
        .map(|(t, v)| (*t, *v))
        .unzip()
}

/// The shorter median sample period, coarsened so that no grid exceeds 2²² points.
fn fine_step(a: &[f64], b: &[f64]) -> f64 {
    const MOST_POINTS: f64 = (1u32 << 22) as f64;
    let span = (a[a.len() - 1] - a[0]).max(b[b.len() - 1] - b[0]);
    let period = median_period(a).min(median_period(b));
    let floor = span / MOST_POINTS;
    if period > floor {
        period
    } else {
        floor.max(f64::MIN_POSITIVE)
    }
}

/// `values` at `times` interpolated linearly onto `times[0] + k·step`.
fn resample(times: &[f64], values: &[f64], step: f64) -> Vec<f64> {
    let span = times[times.len() - 1] - times[0];
    let count = (span / step).floor() as usize + 1;
    let mut out = Vec::with_capacity(count);
    let mut j = 0;
    for k in 0..count {
        let t = times[0] + k as f64 * step;
        while j + 2 < times.len() && times[j + 1] < t {
            j += 1;
        }
        let (t0, t1) = (times[j], times[j + 1]);
        let w = if t1 > t0 {
            ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push(values[j] + w * (values[j + 1] - values[j]));
    }
    out
}

/// Means of consecutive blocks of `factor` values (the last block may be shorter).
fn block_means(values: &[f64], factor: usize) -> Vec<f64> {
    values
        .chunks(factor)
        .map(|c| c.iter().sum::<f64>() / c.len() as f64)
        .collect()
}

/// The Pearson correlation of `a[i]` with `b[i - lag]` over their overlap, if it has at
/// least `min_overlap` points; 0 where either side is constant.
fn correlation(a: &[f64], b: &[f64], lag: isize, min_overlap: usize) -> Option<f64> {
    let start = lag.max(0) as usize;
    let end = (a.len() as isize).min(b.len() as isize + lag);
    if end <= start as isize || ((end as usize) - start) < min_overlap {
        return None;
    }
    let end = end as usize;
    let n = (end - start) as f64;
    let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for i in start..end {
        let (x, y) = (a[i], b[(i as isize - lag) as usize]);
        sa += x;
        sb += y;
        saa += x * x;
        sbb += y * y;
        sab += x * y;
    }
    let va = saa - sa * sa / n;
    let vb = sbb - sb * sb / n;
    let cov = sab - sa * sb / n;
    Some(if va > 0.0 && vb > 0.0 {
        cov / (va * vb).sqrt()
    } else {
        0.0
    })
}

/// The best lag outside the main peak: where the correlation first falls below half the
/// best on either side of `best`.
fn runner_up(curve: &[(isize, f64)], best: usize) -> Option<usize> {
    let half = 0.5 * curve[best].1;
    let mut lo = best;
    while lo > 0 && curve[lo - 1].1 > half && curve[lo - 1].0 == curve[lo].0 - 1 {
        lo -= 1;
    }
    let mut hi = best;
    while hi + 1 < curve.len() && curve[hi + 1].1 > half && curve[hi + 1].0 == curve[hi].0 + 1 {
        hi += 1;
    }
    (0..curve.len())
        .filter(|&i| i < lo || i > hi)
        .max_by(|&i, &j| curve[i].1.total_cmp(&curve[j].1))
}

/// The fine lag (in fine steps, fractional) and its correlation around the coarse lag: a
/// search that halves its step from the coarse one (about 2·log2(factor) evaluations, so a
/// long kHz log stays fast), then a parabola through the best and its two neighbours.
fn refine(a: &[f64], b: &[f64], coarse_lag: isize, factor: usize) -> (f64, f64) {
    let mut known: std::collections::HashMap<isize, f64> = std::collections::HashMap::new();
    let mut at = |k: isize| {
        *known
            .entry(k)
            .or_insert_with(|| correlation(a, b, k, 2).unwrap_or(f64::NEG_INFINITY))
    };
    let mut lag = coarse_lag * factor as isize;
    let mut step = factor as isize;
    loop {
        step = (step + 1) / 2;
        let best = [lag - step, lag, lag + step]
            .into_iter()
            .max_by(|&i, &j| at(i).total_cmp(&at(j)))
            .unwrap_or(lag);
        lag = best;
        // At the finest step, climb until both neighbours are no better.
        if step == 1 && at(lag - 1) <= at(lag) && at(lag + 1) <= at(lag) {
            break;
        }
    }
    let (cm, c0, cp) = (at(lag - 1), at(lag), at(lag + 1));
    let denominator = cm - 2.0 * c0 + cp;
    if !(cm.is_finite() && cp.is_finite()) || denominator >= 0.0 {
        return (lag as f64, c0);
    }
    let shift = (0.5 * (cm - cp) / denominator).clamp(-0.5, 0.5);
    (lag as f64 + shift, c0 - 0.25 * (cm - cp) * shift)
}

/// Separate motions of the joint side in the overlap at `lag` (coarse grid): runs above a
/// quarter of its 95th-percentile speed, ended below a tenth (hysteresis against noise).
fn count_motions(a: &[f64], b: &[f64], lag: isize) -> usize {
    let start = lag.max(0) as usize;
    let end = ((a.len() as isize).min(b.len() as isize + lag).max(0) as usize).max(start);
    let overlap = &a[start..end];
    if overlap.is_empty() {
        return 0;
    }
    let mut sorted = overlap.to_vec();
    sorted.sort_by(f64::total_cmp);
    let high = sorted[(sorted.len() - 1) * 95 / 100];
    if high <= 0.0 {
        return 0;
    }
    let (on, off) = (0.25 * high, 0.1 * high);
    let mut moving = false;
    let mut motions = 0;
    for &v in overlap {
        if !moving && v > on {
            moving = true;
            motions += 1;
        } else if moving && v < off {
            moving = false;
        }
    }
    motions
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Speed bumps of random widths at random times, sampled at `rate` from `start`.
    fn bumps(
        events: &[(f64, f64)],
        rate: f64,
        start: f64,
        end: f64,
        shift: f64,
    ) -> (Vec<f64>, Vec<f64>) {
        let times: Vec<f64> = (0..((end - start) * rate) as usize)
            .map(|k| start + k as f64 / rate)
            .collect();
        let speeds = times
            .iter()
            .map(|&t| {
                events
                    .iter()
                    .map(|&(at, width)| {
                        let u = (t + shift - at) / width;
                        if (0.0..1.0).contains(&u) {
                            (std::f64::consts::PI * u).sin()
                        } else {
                            0.0
                        }
                    })
                    .sum()
            })
            .collect();
        (times, speeds)
    }

    #[test]
    fn a_shift_is_found_below_the_sample_period() {
        let events = [
            (3.0, 1.2),
            (7.5, 2.0),
            (11.0, 0.8),
            (16.2, 1.7),
            (21.0, 1.1),
        ];
        let (ja, jv) = bumps(&events, 100.0, 0.0, 25.0, 0.0);
        // Tracker time = true time - 3.217: its samples at t see the motion at t + 3.217.
        let (ta, tv) = bumps(&events, 120.0, -3.0, 20.0, 3.217);
        let e = estimate_clock_offset(&ja, &jv, &ta, &tv, &ClockOptions::default());
        assert_eq!(e.verdict, ClockVerdict::Confident, "{e:?}");
        assert!((e.offset - 3.217).abs() < 1e-3, "{e:?}");
        assert_eq!(e.motions, 5);
    }

    #[test]
    fn periodic_motion_and_stillness_are_refused() {
        let events: Vec<(f64, f64)> = (0..8).map(|k| (1.0 + 3.0 * k as f64, 1.5)).collect();
        let (ja, jv) = bumps(&events, 100.0, 0.0, 25.0, 0.0);
        let (ta, tv) = bumps(&events, 100.0, 0.0, 25.0, 1.0);
        let e = estimate_clock_offset(&ja, &jv, &ta, &tv, &ClockOptions::default());
        assert!(
            matches!(&e.verdict, ClockVerdict::Refused(why) if why.contains("ambiguous")),
            "{e:?}"
        );
        let still = vec![0.0; ja.len()];
        let e = estimate_clock_offset(&ja, &still, &ja, &still, &ClockOptions::default());
        assert!(matches!(&e.verdict, ClockVerdict::Refused(_)), "{e:?}");
        let e = estimate_clock_offset(&[0.0], &[1.0], &ta, &tv, &ClockOptions::default());
        assert!(
            matches!(&e.verdict, ClockVerdict::Refused(why) if why.contains("too few")),
            "{e:?}"
        );
    }

    #[test]
    fn a_noisy_match_is_doubtful_but_found() {
        let events = [
            (3.0, 1.2),
            (7.5, 2.0),
            (11.0, 0.8),
            (16.2, 1.7),
            (21.0, 1.1),
        ];
        let (ja, jv) = bumps(&events, 100.0, 0.0, 25.0, 0.0);
        let (ta, mut tv) = bumps(&events, 120.0, -3.0, 20.0, 3.217);
        // Deterministic uniform noise of standard deviation 0.33 (the bumps' is about 0.3).
        let mut state = 12345u64;
        for v in &mut tv {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *v += ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 1.15;
        }
        let e = estimate_clock_offset(&ja, &jv, &ta, &tv, &ClockOptions::default());
        assert!(
            matches!(&e.verdict, ClockVerdict::Doubtful(why) if why.contains("correlate only")),
            "{e:?}"
        );
        assert!((e.offset - 3.217).abs() < 1.0 / 120.0, "{e:?}");
    }
}
