//! Speeds of sampled signals, robust to tracker noise and uneven sampling.

/// How the change of a multi-dimensional sample is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpeedNorm {
    /// The Euclidean norm (a position: m/s).
    Euclidean,
    /// The largest component (joint values: the fastest joint's rad/s or m/s).
    Max,
}

/// The speed at every sample over a window of `window` seconds centred on it: the change
/// between the mean of the samples in the half window before it and the mean of those in the
/// half window after it (both including the sample), divided by the distance between the two
/// mean times. Averaging divides white noise by about √(samples per half window), so a still
/// target reads near zero even at sub-millimetre noise. A sample with no neighbour within the
/// window on either side (isolated by dropped samples) has an unknown speed: infinity.
/// `times` increase; every sample has the same length. Linear in the number of samples.
pub fn windowed_speeds<S: AsRef<[f64]>>(
    times: &[f64],
    samples: &[S],
    window: f64,
    norm: SpeedNorm,
) -> Vec<f64> {
    let count = times.len().min(samples.len());
    let dimension = samples.first().map_or(0, |s| s.as_ref().len());
    // prefix[k] = sums over samples 0..k (values, then time last).
    let mut prefix = vec![vec![0.0; dimension + 1]; count + 1];
    for k in 0..count {
        let values = samples[k].as_ref();
        let mut next = prefix[k].clone();
        for (d, sum) in next.iter_mut().take(dimension).enumerate() {
            *sum += values.get(d).copied().unwrap_or(0.0);
        }
        next[dimension] += times[k];
        prefix[k + 1] = next;
    }
    let mean =
        |from: usize, to: usize, d: usize| (prefix[to][d] - prefix[from][d]) / (to - from) as f64;
    let half = 0.5 * window;
    let (mut lo, mut hi) = (0, 0);
    let mut speeds = Vec::with_capacity(count);
    for i in 0..count {
        while times[lo] < times[i] - half {
            lo += 1;
        }
        hi = hi.max(i);
        while hi + 1 < count && times[hi + 1] <= times[i] + half {
            hi += 1;
        }
        // Left: lo..=i, right: i..=hi.
        let span = mean(i, hi + 1, dimension) - mean(lo, i + 1, dimension);
        if span <= 0.0 {
            speeds.push(f64::INFINITY);
            continue;
        }
        let change = (0..dimension).map(|d| (mean(i, hi + 1, d) - mean(lo, i + 1, d)).abs());
        let size = match norm {
            SpeedNorm::Euclidean => change.map(|c| c * c).sum::<f64>().sqrt(),
            SpeedNorm::Max => change.fold(0.0, f64::max),
        };
        speeds.push(size / span);
    }
    speeds
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_has_its_slope_and_a_constant_none() {
        let times: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
        let ramp: Vec<[f64; 2]> = times.iter().map(|t| [0.3 * t, -0.1 * t]).collect();
        let speeds = windowed_speeds(&times, &ramp, 0.2, SpeedNorm::Euclidean);
        for s in &speeds {
            assert!((s - (0.1f64.hypot(0.3))).abs() < 1e-9, "{s}");
        }
        let max = windowed_speeds(&times, &ramp, 0.2, SpeedNorm::Max);
        assert!(max.iter().all(|s| (s - 0.3).abs() < 1e-9));
        let still: Vec<[f64; 1]> = times.iter().map(|_| [2.0]).collect();
        assert!(windowed_speeds(&times, &still, 0.2, SpeedNorm::Max)
            .iter()
            .all(|s| *s == 0.0));
    }

    #[test]
    fn an_isolated_sample_has_an_unknown_speed() {
        let times = [0.0, 0.01, 5.0, 10.0, 10.01];
        let values = [[0.0]; 5];
        let speeds = windowed_speeds(&times, &values, 0.2, SpeedNorm::Max);
        assert_eq!(speeds[2], f64::INFINITY);
        assert_eq!(speeds[0], 0.0);
        assert_eq!(speeds[4], 0.0);
    }
}
