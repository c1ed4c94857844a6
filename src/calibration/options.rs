//! The settings of one identification ([`IdentificationOptions`]): iteration limits and
//! tolerances, the noise model, robust and prior settings, frozen parameters.

use super::loss::RobustLoss;
use super::observation::Noise;
use super::prior::Prior;

/// Settings of the identification.
#[derive(Debug, Clone)]
pub struct IdentificationOptions {
    /// Iteration limit.
    pub max_iterations: usize,
    /// Expected position error of a measurement (m): position rows are divided by it.
    pub position_sigma: f64,
    /// Expected rotation error of a measurement (rad): rotation rows are divided by it.
    pub rotation_sigma: f64,
    /// Expected error of a contact's height above its plane (m).
    pub height_sigma: f64,
    /// Expected error of a contact face's tilt against its plane (rad).
    pub tilt_sigma: f64,
    /// Expected error of a coordinate of a touch's gap (m).
    pub gap_sigma: f64,
    /// Expected error of a distance between two contact points (m).
    pub length_sigma: f64,
    /// Singular values below this times the largest are treated as zero (unidentifiable).
    pub rank_tolerance: f64,
    /// Stop when the scaled step is below this (relative to the scaled parameters + 1).
    pub step_tolerance: f64,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_tolerance: f64,
    /// Per-measurement weights (robust estimation, `super::robust`): measurement `i`'s rows
    /// are multiplied by `√weights[i]`, so its share of the cost is `weights[i]·½‖r_i‖²`.
    /// Empty: every weight is 1 (the plain least-squares problem, bit for bit).
    pub observation_weights: Vec<f64>,
    /// How [`super::run::run_calibration`] and [`super::robust::calibrate_robust`] weight
    /// measurements by their residuals (default Huber); [`identify`](super::solver::identify) itself only applies
    /// `observation_weights`.
    pub robust: RobustLoss,
    /// Parameters (flat indices into the full model) that a plan never frees: the model
    /// level's and `--freeze`'s ([`super::plan::calibrate`]); [`identify`](super::solver::identify) frees what it is told.
    pub frozen: Vec<usize>,
    /// A Gaussian prior on the parameters (rows in the normal equations; `None`: no prior).
    pub prior: Option<Prior>,
    /// The model given is already near the solution (a robust refit from the previous fit's):
    /// a problem large enough for the coarse-to-fine start (`docs/identification.md`) skips
    /// its coarse stage and iterates on every row from there. Smaller problems ignore it.
    pub warm_start: bool,
}

impl IdentificationOptions {
    /// The noise model: σ per row kind.
    pub fn noise(&self) -> Noise {
        Noise {
            position: self.position_sigma,
            rotation: self.rotation_sigma,
            height: self.height_sigma,
            tilt: self.tilt_sigma,
            gap: self.gap_sigma,
            length: self.length_sigma,
        }
    }

    /// The same options for the measurements at `selected` (a stage's subset): the
    /// observation weights follow the measurements.
    pub fn for_measurements(&self, selected: &[usize]) -> Self {
        let mut options = self.clone();
        if !self.observation_weights.is_empty() {
            options.observation_weights = selected
                .iter()
                .map(|&i| self.observation_weights.get(i).copied().unwrap_or(1.0))
                .collect();
        }
        options
    }

    /// The same options for the contiguous measurements `range` (a chunk of the normal
    /// equations): as [`Self::for_measurements`], but the weights are copied for the range
    /// only — never the whole weight vector per chunk, which made large problems quadratic.
    pub fn for_range(&self, range: std::ops::Range<usize>) -> Self {
        let Self {
            max_iterations,
            position_sigma,
            rotation_sigma,
            height_sigma,
            tilt_sigma,
            gap_sigma,
            length_sigma,
            rank_tolerance,
            step_tolerance,
            cost_tolerance,
            observation_weights,
            robust,
            frozen,
            prior,
            warm_start,
        } = self;
        Self {
            max_iterations: *max_iterations,
            position_sigma: *position_sigma,
            rotation_sigma: *rotation_sigma,
            height_sigma: *height_sigma,
            tilt_sigma: *tilt_sigma,
            gap_sigma: *gap_sigma,
            length_sigma: *length_sigma,
            rank_tolerance: *rank_tolerance,
            step_tolerance: *step_tolerance,
            cost_tolerance: *cost_tolerance,
            observation_weights: if observation_weights.is_empty() {
                Vec::new()
            } else {
                range
                    .map(|i| observation_weights.get(i).copied().unwrap_or(1.0))
                    .collect()
            },
            robust: *robust,
            frozen: frozen.clone(),
            prior: prior.clone(),
            warm_start: *warm_start,
        }
    }
}

impl Default for IdentificationOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            position_sigma: 1e-4,
            rotation_sigma: 1e-4,
            height_sigma: super::observation::DEFAULT_CONTACT_SIGMAS[0],
            tilt_sigma: super::observation::DEFAULT_CONTACT_SIGMAS[1],
            gap_sigma: super::observation::DEFAULT_CONTACT_SIGMAS[2],
            length_sigma: super::observation::DEFAULT_CONTACT_SIGMAS[3],
            rank_tolerance: 1e-8,
            step_tolerance: 1e-12,
            cost_tolerance: 1e-8,
            observation_weights: Vec::new(),
            robust: RobustLoss::default(),
            frozen: Vec::new(),
            prior: None,
            warm_start: false,
        }
    }
}
