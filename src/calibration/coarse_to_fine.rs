//! Coarse-to-fine identification of many configurations: the iteration first converges on an
//! evenly spread subsample of whole configurations, then goes on over every row from there
//! until the usual convergence test holds on all of them. The answer is the full-data optimum
//! (to the solver's tolerance); most iterations are paid on the subsample. Below
//! [`COARSE_ABOVE_ROWS`] rows nothing changes. See `docs/identification.md`.

use crate::measurement::Measurement;

/// Measurement rows above which an identification starts on a subsample.
pub(crate) const COARSE_ABOVE_ROWS: usize = 60_000;

/// About how many rows the subsample holds (2·10⁴ configurations of a two-tool robot).
pub(crate) const COARSE_ROWS: usize = 40_000;

/// When a problem is large enough to start on a subsample, and how large the subsample is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct CoarseToFine {
    /// Rows above which the coarse stage runs.
    pub above_rows: usize,
    /// About how many rows the coarse stage uses.
    pub coarse_rows: usize,
}

impl CoarseToFine {
    /// The thresholds every identification uses.
    pub(crate) const DEFAULT: CoarseToFine = CoarseToFine {
        above_rows: COARSE_ABOVE_ROWS,
        coarse_rows: COARSE_ROWS,
    };

    /// The indices (ascending) of the subsample of `measurements`, or `None` when they are not
    /// above the threshold. Whole configurations (consecutive rows at the same joint values,
    /// one per tool) are kept or left together, every k-th of them: the subsample sees every
    /// tool and the whole workspace, as the full data do.
    pub(crate) fn subsample(&self, measurements: &[Measurement]) -> Option<Vec<usize>> {
        if measurements.len() <= self.above_rows || self.coarse_rows == 0 {
            return None;
        }
        let starts: Vec<usize> = (0..measurements.len())
            .filter(|&i| i == 0 || measurements[i].q != measurements[i - 1].q)
            .collect();
        let every = measurements.len().div_ceil(self.coarse_rows);
        if every < 2 {
            return None;
        }
        let mut selected = Vec::with_capacity(measurements.len() / every + 8);
        for (group, &start) in starts.iter().enumerate() {
            if group % every != 0 {
                continue;
            }
            let end = starts.get(group + 1).copied().unwrap_or(measurements.len());
            selected.extend(start..end);
        }
        Some(selected)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Observation;
    use nalgebra::Vector3;

    fn rows(configurations: usize, tools: usize) -> Vec<Measurement> {
        (0..configurations)
            .flat_map(|c| {
                (0..tools).map(move |tool| Measurement {
                    payload: None,
                    tool,
                    q: vec![c as f64, 0.5],
                    observation: Observation::Position(Vector3::zeros()),
                    stage: None,
                    session: None,
                })
            })
            .collect()
    }

    #[test]
    fn the_subsample_keeps_whole_configurations_evenly_spread() {
        let thresholds = CoarseToFine {
            above_rows: 100,
            coarse_rows: 50,
        };
        let data = rows(200, 2);
        let selected = thresholds.subsample(&data).expect("above the threshold");
        // 400 rows, every 8th configuration: 25 configurations of 2 rows.
        assert_eq!(selected.len(), 50);
        for pair in selected.chunks(2) {
            assert_eq!(data[pair[0]].q, data[pair[1]].q);
            assert_eq!((data[pair[0]].tool, data[pair[1]].tool), (0, 1));
        }
        let first: Vec<f64> = selected.iter().step_by(2).map(|&i| data[i].q[0]).collect();
        assert_eq!(first, (0..25).map(|c| (c * 8) as f64).collect::<Vec<_>>());
        assert!(selected.windows(2).all(|w| w[0] < w[1]));
        // At or below the threshold: no subsample.
        assert_eq!(thresholds.subsample(&rows(50, 2)), None);
        assert_eq!(CoarseToFine::DEFAULT.subsample(&data), None);
    }
}
