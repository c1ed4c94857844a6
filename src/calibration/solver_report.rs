//! What one identification found: why it stopped, its rank and covariance, and the parameter
//! combinations the data cannot determine (the report of the loop in `solver`).

use super::observation::Nuisance;
use crate::kinematics::McpcModel;
use nalgebra::{DMatrix, DVector};

/// Why the iteration stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// The step became negligible.
    StepConverged,
    /// The cost stopped decreasing measurably.
    CostConverged,
    /// No damped step lowered the cost: a (local) minimum at the noise floor.
    NoDecrease,
    /// The iteration limit was reached first.
    MaxIterations,
}

/// A direction in parameter space the data cannot determine: `(parameter index, weight)`,
/// largest weights first, normalised to unit length in parameter units (rad, m).
#[derive(Debug, Clone, PartialEq)]
pub struct Combination {
    /// Parameter indices (into the model's flat vector) and their weights.
    pub terms: Vec<(usize, f64)>,
}

impl Combination {
    /// The combination in words, e.g. `left_tool alpha (+0.71) with left_tool gamma (−0.71)`.
    pub fn describe(&self, model: &McpcModel, tree: &crate::tree::KinematicTree) -> String {
        self.terms
            .iter()
            .map(|(p, w)| format!("{} ({w:+.2})", model.parameter_name(tree, *p)))
            .collect::<Vec<_>>()
            .join(" with ")
    }

    /// [`Self::describe`] for a fit with nuisance parameters: indices past the model's
    /// parameters are named by `nuisance` (e.g. `plane day1 height (+0.71)`).
    pub fn describe_with(
        &self,
        model: &McpcModel,
        tree: &crate::tree::KinematicTree,
        nuisance: &Nuisance,
    ) -> String {
        let count = model.parameter_count();
        self.terms
            .iter()
            .map(|(p, w)| {
                let name = match p.checked_sub(count) {
                    Some(k) => nuisance
                        .value_name(k)
                        .unwrap_or_else(|| format!("nuisance {k}")),
                    None => model.parameter_name(tree, *p),
                };
                format!("{name} ({w:+.2})")
            })
            .collect::<Vec<_>>()
            .join(" with ")
    }
}

/// What the identification did and found.
#[derive(Debug, Clone)]
pub struct IdentificationReport {
    /// The identified parameters (whole vector; parameters not free are unchanged).
    pub parameters: Vec<f64>,
    /// The nuisance parameters at the solution (empty unless [`identify_with_nuisance`](super::identify_with_nuisance)).
    pub nuisance: Nuisance,
    /// Indices of the parameters that were free (flat: the model's parameters, then the
    /// nuisance values).
    pub free: Vec<usize>,
    /// Accepted iterations.
    pub iterations: usize,
    /// Cost ½‖r‖² (weighted) before the first and after each accepted iteration.
    pub costs: Vec<f64>,
    /// Why it stopped.
    pub termination: Termination,
    /// Rows (equations) of the stacked residual: 6 per pose, 3 per position observation.
    pub rows: usize,
    /// Numerical rank of the scaled Jacobian at the solution.
    pub rank: usize,
    /// Scaled singular values at the solution, largest first.
    pub singular_values: Vec<f64>,
    /// σ_max / σ_min over the retained singular values.
    pub condition_number: f64,
    /// Parameter combinations the data cannot determine (kept at their starting values).
    pub unidentifiable: Vec<Combination>,
    /// RMS of the position residuals at the solution (m).
    pub residual_rms_position: f64,
    /// RMS of the rotation residuals at the solution (rad), over pose observations.
    pub residual_rms_rotation: f64,
    /// `σ̂ = √(2·cost / (rows − rank))`: how large the weighted residuals are against the
    /// assumed σ's (1 when the noise is as assumed and the model explains the data; NaN with
    /// no redundancy).
    pub residual_scale: f64,
    /// Standard deviation of each free parameter (rad or m, same order as `free`):
    /// `σ̂·√diag((JᵀWJ)⁺)` over the identifiable subspace. For a parameter that is part of an
    /// unidentifiable combination this is the spread of its identifiable part only.
    pub standard_deviations: Vec<f64>,
    /// `σ̂²·(JᵀWJ)⁺` over the free parameters (rad, m; same order as `free`), on the
    /// identifiable subspace; `None` without redundancy.
    pub covariance: Option<DMatrix<f64>>,
    /// Whether each free parameter is determined by the data on its own (it has no weight,
    /// beyond [`IDENTIFIABLE_NULL_WEIGHT`] in scaled units, in any unidentifiable combination).
    pub identifiable: Vec<bool>,
}

/// A parameter whose unit vector (column-scaled) has more than this weight in the null space
/// is reported as not identifiable.
pub const IDENTIFIABLE_NULL_WEIGHT: f64 = 1e-3;

/// The null-space `direction` over the `free` parameters as a [`Combination`]: unit length,
/// terms below a tenth of the largest weight left out, largest first.
pub(crate) fn combination(direction: &DVector<f64>, free: &[usize]) -> Combination {
    let norm = direction.norm().max(f64::MIN_POSITIVE);
    let largest = direction.amax() / norm;
    let mut terms: Vec<(usize, f64)> = direction
        .iter()
        .enumerate()
        .map(|(k, w)| (free[k], w / norm))
        .filter(|(_, w)| w.abs() >= 0.1 * largest)
        .collect();
    terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    Combination { terms }
}
