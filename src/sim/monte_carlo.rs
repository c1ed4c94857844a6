//! Many simulated calibrations with new true robots: mean ± standard deviation of the results,
//! on all cores, with results that do not depend on the core count (each trial has its own
//! seed and the results are collected in trial order).

use super::experiment::{run_trial, ArmErrors, Setup, SimulationOptions, TrialReport};
use crate::error::Result;
use rayon::prelude::*;
use serde::Serialize;

/// Mean and standard deviation (sample, n − 1) of a quantity over trials.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// Standard deviation (0 for one trial).
    pub std: f64,
}

impl Spread {
    fn of(values: &[f64]) -> Self {
        let n = values.len().max(1) as f64;
        let mean = values.iter().sum::<f64>() / n;
        let std = if values.len() > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Self { mean, std }
    }
}

/// One arm on one set of configurations, over all trials.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArmSummary {
    /// The arm.
    pub arm: String,
    /// Mean position error before calibration (mm).
    pub before_position_mm: Spread,
    /// Mean orientation error before calibration (deg).
    pub before_orientation_deg: Spread,
    /// Mean position error after calibration without / with compensation (mm; JSON: `rigid`,
    /// `compensated`).
    #[serde(serialize_with = "crate::serde_labels::rigid_compensated")]
    pub after_position_mm: [Spread; 2],
    /// Mean orientation error after calibration without / with compensation (deg; JSON:
    /// `rigid`, `compensated`).
    #[serde(serialize_with = "crate::serde_labels::rigid_compensated")]
    pub after_orientation_deg: [Spread; 2],
    /// % of the mean position error removed without / with compensation (JSON: `rigid`,
    /// `compensated`).
    #[serde(serialize_with = "crate::serde_labels::rigid_compensated")]
    pub position_removed_percent: [Spread; 2],
    /// % of the mean orientation error removed without / with compensation (JSON: `rigid`,
    /// `compensated`).
    #[serde(serialize_with = "crate::serde_labels::rigid_compensated")]
    pub orientation_removed_percent: [Spread; 2],
}

/// The summary of a simulation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimulationSummary {
    /// Trials run.
    pub trials: usize,
    /// Per arm, on the identification configurations.
    pub identification: Vec<ArmSummary>,
    /// Per arm, on the validation configurations.
    pub validation: Vec<ArmSummary>,
    /// RMS validation position error the noise alone predicts (mm), over trials.
    pub noise_floor_position_mm: Spread,
    /// Over all trials, without / with compensation: blunders named, blunders missed, clean
    /// measurements named as outliers (JSON: `rigid` and `compensated`, each with `named`,
    /// `missed` and `clean_named`).
    #[serde(serialize_with = "blunders_json")]
    pub blunders: [[usize; 3]; 2],
}

fn blunders_json<S: serde::Serializer>(
    blunders: &[[usize; 3]; 2],
    serializer: S,
) -> std::result::Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Counts {
        named: usize,
        missed: usize,
        clean_named: usize,
    }
    let [rigid, compensated] = blunders.map(|[named, missed, clean_named]| Counts {
        named,
        missed,
        clean_named,
    });
    crate::serde_labels::rigid_compensated(&[rigid, compensated], serializer)
}

/// Runs `trials` trials on all cores; `progress` is called once per finished trial.
pub fn run_trials(
    setup: &Setup<'_>,
    options: &SimulationOptions,
    trials: usize,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<TrialReport>> {
    (0..trials)
        .into_par_iter()
        .map(|trial| {
            let report = run_trial(setup, options, trial);
            progress();
            report
        })
        .collect()
}

fn summarise_arms(
    reports: &[TrialReport],
    set: impl Fn(&TrialReport) -> &[ArmErrors],
) -> Vec<ArmSummary> {
    let Some(first) = reports.first() else {
        return Vec::new();
    };
    (0..set(first).len())
        .map(|arm| {
            let values = |f: &dyn Fn(&ArmErrors) -> f64| -> Spread {
                Spread::of(&reports.iter().map(|r| f(&set(r)[arm])).collect::<Vec<_>>())
            };
            ArmSummary {
                arm: set(first)[arm].arm.clone(),
                before_position_mm: values(&|a| a.before.mean_position_mm),
                before_orientation_deg: values(&|a| a.before.mean_orientation_deg),
                after_position_mm: [
                    values(&|a| a.rigid.mean_position_mm),
                    values(&|a| a.compensated.mean_position_mm),
                ],
                after_orientation_deg: [
                    values(&|a| a.rigid.mean_orientation_deg),
                    values(&|a| a.compensated.mean_orientation_deg),
                ],
                position_removed_percent: [
                    values(&|a| a.position_removed_percent[0]),
                    values(&|a| a.position_removed_percent[1]),
                ],
                orientation_removed_percent: [
                    values(&|a| a.orientation_removed_percent[0]),
                    values(&|a| a.orientation_removed_percent[1]),
                ],
            }
        })
        .collect()
}

/// Mean ± standard deviation over the trials.
pub fn summarise(reports: &[TrialReport]) -> SimulationSummary {
    SimulationSummary {
        trials: reports.len(),
        identification: summarise_arms(reports, |r| &r.identification),
        validation: summarise_arms(reports, |r| &r.validation),
        noise_floor_position_mm: Spread::of(
            &reports
                .iter()
                .map(|r| r.noise_floor_position_mm)
                .collect::<Vec<_>>(),
        ),
        blunders: [0, 1].map(|run| {
            reports.iter().fold([0; 3], |total, r| {
                let counts = r.blunders.counts(run);
                [0, 1, 2].map(|k| total[k] + counts[k])
            })
        }),
    }
}
