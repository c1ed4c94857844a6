//! Robust estimation: blunders (a bumped target, a wrong row) found, named and kept out of the
//! result, by iteratively reweighted least squares (IRLS) around a calibration plan.
//!
//! Every measurement (one row of the CSV: one tool observed at one configuration) gets one
//! weight from its whole standardized residual norm `‖W·r_i‖` (position rows over
//! `position_sigma`, rotation rows over `rotation_sigma`): a bumped target spoils all of a row's
//! coordinates, and with three targets a bumped B or C target moves only the rotation. The
//! norms are divided by a robust scale (the median of the norms about zero, made consistent
//! for χ with 3 or 6 degrees of freedom: a median absolute deviation), and the loss turns the
//! standardized norm `u` into a weight. After the weights settle, measurements whose weight
//! fell below [`OUTLIER_WEIGHT`] are outliers: named, and left out of one last fit. See
//! `docs/identification.md`, "Robust estimation".

use super::coarse_to_fine::CoarseToFine;
use super::normal_equations::ProductsMemo;
use super::observation::{
    kind_of, norms_by_row_kind, standardized_norm, Nuisance, RobotState, Tools,
};
use super::options::IdentificationOptions;
use super::plan::{
    calibrate, calibrate_reusing, linear_offsets, CalibrationReport, Compensation, Plan,
};
use super::predictor::{Cached, Predictor};
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::Pose;
use crate::measurement::Measurement;
use crate::tree::Branches;
use nalgebra::Vector6;
use serde::Serialize;

pub use super::loss::{
    robust_scale, threshold, weights_of, Residual, RobustLoss, OUTLIER_WEIGHT, SCALE_FLOOR,
};

/// Reweighting rounds at most (each a calibration).
pub const MAX_ROUNDS: usize = 30;

/// The weights have settled when none changes by more than this in a round.
pub const WEIGHT_TOLERANCE: f64 = 1e-4;

/// What the robust estimation did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobustReport {
    /// The loss.
    pub loss: RobustLoss,
    /// The robust scale of the standardized residuals (1 = the noise is as assumed).
    pub scale: f64,
    /// Calibrations run after the first, unweighted one (reweighting rounds, plus the final
    /// fit without the outliers).
    pub rounds: usize,
    /// Whether the weights settled within [`MAX_ROUNDS`].
    pub converged: bool,
    /// Per measurement: the loss's weight at the solution.
    pub weights: Vec<f64>,
    /// Per measurement: the residual at the solution.
    pub residuals: Vec<Residual>,
}

impl RobustReport {
    /// Indices of the measurements whose weight is below [`OUTLIER_WEIGHT`].
    pub fn outliers(&self) -> Vec<usize> {
        (0..self.weights.len())
            .filter(|&i| self.weights[i] < OUTLIER_WEIGHT)
            .collect()
    }

    /// The weights the final fit used: the loss's, with the outliers at 0; empty (every
    /// weight 1) when no weight was reduced.
    pub fn fit_weights(&self) -> Vec<f64> {
        if self.weights.iter().all(|&w| w == 1.0) {
            return Vec::new();
        }
        self.weights
            .iter()
            .map(|&w| if w < OUTLIER_WEIGHT { 0.0 } else { w })
            .collect()
    }

    /// The measurements of `data` (the identification data, or validation data weighted by
    /// [`weights_of`]) whose weight is below [`OUTLIER_WEIGHT`]; `scale` is the robust scale
    /// the weights were computed at.
    pub fn name_outliers(
        &self,
        set: DataSet,
        data: &[Measurement],
        residuals: &[Residual],
        weights: &[f64],
        scale: f64,
    ) -> Vec<Outlier> {
        (0..data.len().min(residuals.len()).min(weights.len()))
            .filter(|&i| weights[i] < OUTLIER_WEIGHT)
            .map(|i| Outlier {
                set,
                index: i,
                tool: data[i].tool,
                residual: residuals[i],
                standardized: residuals[i].norm / scale,
                weight: weights[i],
            })
            .collect()
    }
}

/// Which data a measurement belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DataSet {
    /// The identification data (the fit).
    Identification,
    /// The validation data (judged, never fitted).
    Validation,
}

/// A measurement named as an outlier.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Outlier {
    /// Identification or validation data.
    pub set: DataSet,
    /// Index into that data (file order).
    pub index: usize,
    /// The tool observed (index into the model's tools).
    pub tool: usize,
    /// Its residual at the calibrated model.
    pub residual: Residual,
    /// Its residual norm in robust scales (`‖W·r‖ / scale`).
    pub standardized: f64,
    /// Its weight under the loss (the final fit left it out).
    pub weight: f64,
}

/// Per row of data set `set` (`count` rows): whether `outliers` name it. Linear: a mask, not
/// a search of the outliers per row.
pub(crate) fn outlier_mask(outliers: &[Outlier], set: DataSet, count: usize) -> Vec<bool> {
    let mut flagged = vec![false; count];
    for outlier in outliers {
        if outlier.set == set && outlier.index < count {
            flagged[outlier.index] = true;
        }
    }
    flagged
}

/// Runs `plan` robustly with the loss `options.robust`: a plain least-squares calibration,
/// then calibrations reweighted by the loss until the weights settle, then one without the
/// outliers (if any). Clean data end after the first calibration with every weight 1: the
/// result is the least-squares one.
pub fn calibrate_robust(
    branches: &Branches,
    model: &McpcModel,
    measurements: &[Measurement],
    compensation: Compensation<'_>,
    plan: &Plan,
    options: &IdentificationOptions,
) -> Result<(CalibrationReport, RobustReport)> {
    calibrate_robust_with(
        (branches, model, plan),
        measurements,
        compensation,
        options,
        CoarseToFine::DEFAULT,
    )
}

/// [`calibrate_robust`] with the thresholds of a large problem given (tests lower them).
fn calibrate_robust_with(
    (branches, model, plan): (&Branches, &McpcModel, &Plan),
    measurements: &[Measurement],
    compensation: Compensation<'_>,
    options: &IdentificationOptions,
    thresholds: CoarseToFine,
) -> Result<(CalibrationReport, RobustReport)> {
    let loss = options.robust;
    // A large problem (above the coarse-to-fine threshold) with a loss: the first fit is the
    // evenly spread subsample's alone (its residuals over every row set the first weights as
    // well as the full fit's would: they differ by far less than the noise), and every fit
    // after it starts from the previous one (`warm_start`: no coarse stage again).
    let subsample = match loss {
        RobustLoss::Off => None,
        _ => thresholds.subsample(measurements),
    };
    // A large problem's fit starts from the previous one; any other from `model`. Started at
    // the previous solution, a refit's first products are the previous fit's last ones
    // updated where the weights changed (`memo`), not a pass over every row.
    let memo = ProductsMemo::new(measurements);
    let run = |previous: &McpcModel, weights: Vec<f64>| {
        let start = if subsample.is_some() { previous } else { model };
        let options = IdentificationOptions {
            observation_weights: weights,
            warm_start: subsample.is_some(),
            ..options.clone()
        };
        calibrate_reusing(
            (branches, start, plan),
            measurements,
            compensation,
            &options,
            Some(&memo),
        )
    };
    let offsets = linear_offsets(compensation, model, measurements)?;
    let residuals_at = |model: &McpcModel| {
        residuals(
            model,
            measurements,
            compensation,
            offsets.as_deref(),
            options,
        )
    };
    let mut report = match &subsample {
        Some(selected) => {
            let rows: Vec<Measurement> =
                selected.iter().map(|&i| measurements[i].clone()).collect();
            calibrate(branches, model, &rows, compensation, plan, options)?
        }
        None => run(model, Vec::new())?,
    };
    // Whether `report` is the subsample's fit, which never ends the loop.
    let mut coarse = subsample.is_some();
    let mut residuals = residuals_at(&report.model)?;
    let mut weights = vec![1.0; measurements.len()];
    let (mut rounds, mut converged, mut scale) = (0, true, robust_scale(&residuals, measurements));
    if loss != RobustLoss::Off {
        loop {
            let next = weights_of(loss, &residuals, measurements, scale);
            let change = next
                .iter()
                .zip(&weights)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            weights = next;
            if change <= WEIGHT_TOLERANCE && !coarse {
                break;
            }
            if rounds == MAX_ROUNDS {
                converged = false;
                break;
            }
            rounds += 1;
            report = run(&report.model, weights.clone())?;
            coarse = false;
            residuals = residuals_at(&report.model)?;
            scale = robust_scale(&residuals, measurements);
        }
    }
    let mut robust = RobustReport {
        loss,
        scale,
        rounds,
        converged,
        weights,
        residuals,
    };
    if !robust.outliers().is_empty() {
        // The outliers' bounded pull (Huber: k robust σ each) is a bias the data do not need:
        // the last fit leaves them out, which also keeps them out of σ̂ and the covariance.
        report = run(&report.model, robust.fit_weights())?;
        robust.residuals = residuals_at(&report.model)?;
        robust.rounds += 1;
    }
    Ok((report, robust))
}

/// The residual of every measurement at `model`, predicted as `compensation` predicts
/// (rigidly, rigidly minus the linear deflections `offsets`, or deflected).
pub fn residuals(
    model: &McpcModel,
    measurements: &[Measurement],
    compensation: Compensation<'_>,
    offsets: Option<&[Vector6<f64>]>,
    options: &IdentificationOptions,
) -> Result<Vec<Residual>> {
    let noise = options.noise();
    // Rows in parallel, kept in row order (`map_rows_in_order`).
    let part = |range: std::ops::Range<usize>| -> Result<Vec<Residual>> {
        let mut cached: Cached<'_, Vec<Pose>> = None;
        let mut out = Vec::with_capacity(range.len());
        let mut error = Vec::new();
        for index in range {
            let m = &measurements[index];
            let key = (m.q.as_slice(), m.payload);
            if cached.as_ref().is_none_or(|(k, _)| *k != key) {
                let poses = match compensation {
                    Compensation::Exact(source) => source.predict_at(model, &m.q, m.payload)?,
                    Compensation::None | Compensation::Linear(_) => model.tool_poses(&m.q),
                };
                cached = Some((key, poses));
            }
            let Some((_, predicted)) = cached.as_ref().filter(|(_, p)| m.tool < p.len()) else {
                continue;
            };
            let kind = kind_of(&m.observation);
            let state = RobotState {
                model,
                q: &m.q,
                tool: m.tool,
                tools: Tools::Poses(predicted),
                offset: offsets.and_then(|o| o.get(index)),
                nuisance: Nuisance::none(),
            };
            error.resize(kind.rows(), 0.0);
            kind.residual(&state, &mut error)?;
            let norms = norms_by_row_kind(kind, &error);
            let (position, rotation) = (norms[0], norms[1]);
            out.push(Residual {
                position: position.unwrap_or(0.0),
                rotation,
                norm: standardized_norm(kind, &error, &noise),
            });
        }
        Ok(out)
    };
    let mut out = Vec::with_capacity(measurements.len());
    super::linearise::map_rows_in_order(measurements.len(), part, |r| out.push(r))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::loss::chi_median;
    use crate::measurement::Observation;

    /// A large problem's robust fit (the subsample's fit first, every refit from the previous
    /// one) ends where the plain sequence of fits from the start ends, on clean data and with
    /// blunders: the same outliers, the parameters within a hundredth of their standard
    /// deviation.
    #[test]
    fn a_large_problem_starts_on_the_subsample_and_ends_at_the_same_fit() {
        use crate::calibration::coarse_to_fine::CoarseToFine;
        use crate::calibration::test_problems::{problem, robonaut_with_branches, with_noise};

        let (robot, branches) = robonaut_with_branches();
        let clean = with_noise(problem(&robot, 800, true), [2e-4, 2e-3]);
        let mut blunders = clean.clone();
        for i in [17, 555, 1201] {
            if let Observation::Pose(pose) = &mut blunders[i].observation {
                pose.translation.vector.x += 0.02;
            }
        }
        let options = IdentificationOptions {
            position_sigma: 2e-4,
            rotation_sigma: 2e-3,
            ..Default::default()
        };
        for (measurements, outliers) in [(&clean, vec![]), (&blunders, vec![17, 555, 1201])] {
            let run = |thresholds: CoarseToFine| {
                calibrate_robust_with(
                    (&branches, &robot.0, &Plan::simultaneous()),
                    measurements,
                    Compensation::None,
                    &options,
                    thresholds,
                )
                .expect("robust calibration")
            };
            let (plain, plain_robust) = run(CoarseToFine {
                above_rows: usize::MAX,
                coarse_rows: 0,
            });
            let (staged, staged_robust) = run(CoarseToFine {
                above_rows: 1000,
                coarse_rows: 400,
            });
            assert_eq!(plain_robust.outliers(), outliers);
            assert_eq!(staged_robust.outliers(), outliers);
            // The subsample's fit came first, then at least one over every row.
            assert!(staged_robust.rounds >= 1, "rounds {}", staged_robust.rounds);
            let (a, b) = (plain.model.parameters(), staged.model.parameters());
            let report = &plain.stages[0].identification;
            for (k, &p) in report.free.iter().enumerate() {
                let sd = report.standard_deviations[k];
                let difference = (a[p] - b[p]).abs();
                assert!(
                    difference <= 1e-2 * sd + 1e-12,
                    "parameter {p}: {difference} vs σ {sd}"
                );
            }
        }
    }

    #[test]
    fn huber_keeps_clean_norms_and_caps_large_ones() {
        let k = threshold(6);
        assert_eq!(RobustLoss::Huber.weight(k, 6), 1.0);
        assert_eq!(RobustLoss::Huber.weight(0.5 * k, 6), 1.0);
        assert!((RobustLoss::Huber.weight(10.0 * k, 6) - 0.1).abs() < 1e-12);
        assert!((RobustLoss::Cauchy.weight(k, 6) - 0.5).abs() < 1e-12);
        assert_eq!(RobustLoss::Off.weight(1e9, 3), 1.0);
        for loss in [RobustLoss::Huber, RobustLoss::Cauchy] {
            for rows in [3, 6] {
                let u = loss.outlier_norm(rows);
                assert!((loss.weight(u, rows) - OUTLIER_WEIGHT).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn the_scale_is_the_consistent_median_and_floored() {
        let measurement = |rows: usize| Measurement {
            payload: None,
            tool: 0,
            q: Vec::new(),
            observation: if rows == 3 {
                Observation::Position(crate::math::Vec3::zeros())
            } else {
                Observation::Pose(Pose::identity())
            },
            stage: None,
            session: None,
        };
        let residual = |norm: f64| Residual {
            position: 0.0,
            rotation: None,
            norm,
        };
        let data = [measurement(6), measurement(6), measurement(3)];
        // Normalised: 1, 2, 1000 → median 2.
        let norms = [chi_median(6), 2.0 * chi_median(6), 1000.0 * chi_median(3)];
        let residuals: Vec<Residual> = norms.iter().map(|&n| residual(n)).collect();
        assert!((robust_scale(&residuals, &data) - 2.0).abs() < 1e-12);
        let tiny: Vec<Residual> = norms.iter().map(|&n| residual(n * 1e-9)).collect();
        assert_eq!(robust_scale(&tiny, &data), SCALE_FLOOR);
    }
}
