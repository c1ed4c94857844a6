//! Coarse-to-fine identification of many configurations: the iteration first converges on an
//! evenly spread subsample of whole configurations, then goes on over every row from there
//! until the usual convergence test holds on all of them. The answer is the full-data optimum
//! (to the solver's tolerance); most iterations are paid on the subsample. Below
//! [`COARSE_ABOVE_ROWS`] rows nothing changes. See `docs/identification.md`.

use crate::measurement::Measurement;
use rayon::prelude::*;

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
            .into_par_iter()
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

    /// Above a (lowered) threshold the result is the plain full-data optimum to the solver's
    /// tolerance: parameters within a thousandth of their standard deviation, the same cost.
    #[test]
    fn coarse_to_fine_reaches_the_full_data_optimum() {
        use crate::calibration::observation::Nuisance;
        use crate::calibration::solver::{identify_coarse_to_fine, IdentificationOptions, Rigid};
        use crate::calibration::test_problems::{problem, robonaut, with_noise};
        use crate::kinematics::McpcModel;

        let robot = robonaut();
        let model = &robot.0;
        let measurements = with_noise(problem(&robot, 1500, true), [2e-4, 2e-3]);
        // Robust weights, some rows left out: the subsample takes its rows' weights.
        let options = IdentificationOptions {
            observation_weights: (0..measurements.len())
                .map(|i| [1.0, 1.0, 0.6, 1.0, 0.0, 1.0, 0.9][i % 7])
                .collect(),
            ..Default::default()
        };
        let free: Vec<usize> = (0..model.parameter_count()).collect();
        let run_from =
            |model: &McpcModel, thresholds: CoarseToFine, options: &IdentificationOptions| {
                identify_coarse_to_fine(
                    (model, Nuisance::none()),
                    (&measurements, None),
                    &Rigid,
                    &free,
                    options,
                    thresholds,
                    None,
                )
                .expect("identification")
            };
        let run = |thresholds: CoarseToFine| {
            identify_coarse_to_fine(
                (model, Nuisance::none()),
                (&measurements, None),
                &Rigid,
                &free,
                &options,
                thresholds,
                None,
            )
            .expect("identification")
        };
        let plain = run(CoarseToFine {
            above_rows: usize::MAX,
            coarse_rows: 0,
        });
        let thresholds = CoarseToFine {
            above_rows: 1000,
            coarse_rows: 500,
        };
        assert!(thresholds.subsample(&measurements).is_some());
        let staged = run(thresholds);
        assert_eq!(staged.rank, plain.rank);
        let (a, b) = (plain.costs.last().unwrap(), staged.costs.last().unwrap());
        assert!((a - b).abs() <= 1e-8 * a, "cost {a} vs {b}");
        for (k, &p) in free.iter().enumerate() {
            let sd = plain.standard_deviations[k];
            let difference = (plain.parameters[p] - staged.parameters[p]).abs();
            assert!(
                difference <= 1e-3 * sd + 1e-12,
                "parameter {p}: {difference} vs σ {sd}"
            );
        }
        // Started at the solution (a robust refit's warm start), a large problem iterates on
        // every row at once and stops at the first linearisation: its step is negligible.
        let mut solved = model.clone();
        solved
            .set_parameters(&plain.parameters)
            .expect("parameters");
        let warm_options = IdentificationOptions {
            warm_start: true,
            ..options.clone()
        };
        let warm = run_from(&solved, thresholds, &warm_options);
        assert_eq!(warm.iterations, 0);
        assert_eq!(warm.costs.len(), 1);
        for (k, &p) in free.iter().enumerate() {
            let sd = plain.standard_deviations[k];
            let difference = (plain.parameters[p] - warm.parameters[p]).abs();
            assert!(difference <= 1e-3 * sd + 1e-12);
        }
        // From the start, a warm start is not taken for granted: the descent goes on.
        let cold = run_from(model, thresholds, &warm_options);
        assert!(cold.iterations >= 2);
        let difference = (cold.costs.last().unwrap() - a).abs();
        assert!(
            difference <= 1e-8 * a,
            "cost {a} vs {}",
            cold.costs.last().unwrap()
        );
    }
}
