//! Iterative identification (paper eq. (26)–(29)), made robust: the Levenberg–Marquardt loop
//! of one stage and what it found.
//!
//! Each iteration linearises the weighted residuals `r = W·(measured ⊖ predicted − D_f)`
//! (`linearise`, through the observation seam) around the current parameters, scales the
//! Jacobian's columns to unit norm (so millimetres and radians are comparable), and takes the
//! minimum-norm Gauss–Newton step through the SVD (`linear_algebra`), keeping only singular
//! values above `rank_tolerance · σ_max`: combinations of parameters the data cannot determine
//! are reported and left where they started (at their nominal values). When the Gauss–Newton
//! step does not reduce the cost, the step is damped (Levenberg–Marquardt) until it does. Not
//! converging is an outcome in the report, not an error. See `docs/identification.md`.
//!
//! The predictors, the options, the linearisation and the linear algebra live in files of
//! their own (`predictor`, `options`, `linearise`, `linear_algebra`); they are re-exported
//! here under their former paths.

use super::linear_algebra::{
    eigen_decomposition, floored_scales, qr_svd, scale_columns, well_conditioned, WELL_CONDITIONED,
};
use super::linearise::{residual_rms, rows_of};
use super::normal_equations::{accumulate_with, NormalEquations, Problem, Products};
use super::observation::{kind_of, Nuisance};
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::measurement::Measurement;
use nalgebra::{DMatrix, DVector, Vector6};

pub use super::linearise::{weighted_jacobian, weighted_residual};
pub use super::options::IdentificationOptions;
pub use super::predictor::{
    Deflected, DeflectedWithDerivative, Predictor, Rigid, CORRECTION_RADIUS,
};

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
    /// The nuisance parameters at the solution (empty unless [`identify_with_nuisance`]).
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

/// Identifies the `free` parameters of `model` from `measurements`.
///
/// `offsets`, if given, holds one predicted flexibility error per measurement (eq. (26): the
/// residual is `measured ⊖ predicted − D_f`); `predictor` is how the model predicts the tool
/// poses (rigid FK, or a deflected FK). Errors only for inputs that make no sense (a tool
/// index out of range, a configuration of the wrong size, non-finite values, too few rows).
pub fn identify(
    model: &McpcModel,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<IdentificationReport> {
    identify_with_nuisance(
        model,
        Nuisance::none(),
        measurements,
        offsets,
        predictor,
        free,
        options,
    )
}

/// [`identify`] with nuisance parameters of the measurement kinds (contacts' planes,
/// contact points, bar lengths): the solver's parameter vector is the model's parameters
/// followed by `nuisance`'s values, and `free` indexes it (free or fixed like the model's
/// parameters). The report's `parameters` are the model's, its `nuisance` the fitted values.
pub fn identify_with_nuisance(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<IdentificationReport> {
    validate(model, nuisance, measurements, offsets, free, options)?;
    let prior_rows = if nuisance.is_empty() {
        prior_rows(model, measurements, offsets, predictor, free, options)?
    } else {
        // A prior that follows the residual scale refits without it: not with nuisance.
        options
            .prior
            .as_ref()
            .map(|prior| prior.rows(free, 1.0))
            .filter(|rows| rows.count() > 0)
    };
    // JᵀWJ and JᵀWr streamed over the configurations (`normal_equations`), with the triangle
    // R of J too once a problem has proved rank-deficient.
    let problem = Problem {
        measurements,
        offsets,
        predictor,
        free,
        options,
        prior: prior_rows.as_ref(),
    };
    let descent = descend(model, nuisance, &problem)?;
    summarise(descent, &problem)
}

/// Where the Levenberg–Marquardt iteration ended.
struct Descent {
    /// The model at the solution.
    model: McpcModel,
    /// The nuisance parameters at the solution.
    nuisance: Nuisance,
    /// Its parameters.
    parameters: Vec<f64>,
    /// Cost before the first and after each accepted iteration.
    costs: Vec<f64>,
    /// Accepted iterations.
    iterations: usize,
    /// Why it stopped.
    termination: Termination,
    /// The analysis of the linearisation at the solution, when the loop ended with a valid one.
    analysis: Option<Analysis>,
    /// The latest products.
    lin: NormalEquations,
}

/// The damped Gauss–Newton iteration from `model` (eq. (27)–(29)): minimum-norm steps over
/// the retained singular directions, damped (Levenberg–Marquardt) until the cost decreases.
fn descend(model: &McpcModel, nuisance: &Nuisance, problem: &Problem<'_>) -> Result<Descent> {
    let (free, options) = (problem.free, problem.options);
    let mut current = model.clone();
    let mut current_nuisance = nuisance.clone();
    let mut parameters = current.parameters();
    parameters.extend(nuisance.values());
    let mut lin = accumulate_with(&current, &current_nuisance, problem, Products::Normal)?;
    let mut cost = lin.cost;
    let mut costs = vec![cost];
    let mut damping = 0.0;
    let mut iterations = 0;
    let mut termination = Termination::MaxIterations;
    // The analysis of the linearisation at `current` once the loop ends, if still valid.
    let mut final_analysis: Option<Analysis> = None;

    while iterations < options.max_iterations {
        // An SVD of a non-finite matrix never ends: stop with an error instead. The normal
        // matrix's diagonal holds the squared column norms, so it is finite exactly when the
        // weighted Jacobian is and no square overflows (e.g. a tiny sigma); the cost likewise.
        crate::limits::ensure_finite(
            lin.normal
                .iter()
                .chain(lin.gradient.iter())
                .chain(std::iter::once(&lin.cost)),
            "identification: the weighted Jacobian and residual",
        )?;
        let analysis = analyse(&mut lin, options.rank_tolerance, || {
            accumulate_with(
                &current,
                &current_nuisance,
                problem,
                Products::NormalAndFactor,
            )
        })?;
        // Converged when the full Gauss–Newton step is negligible against the parameters.
        let scaled_parameters = free
            .iter()
            .zip(analysis.scales.iter())
            .map(|(&p, s)| (parameters[p] * s).powi(2))
            .sum::<f64>()
            .sqrt();
        // The undamped step, also the first trial below (one Cholesky factorisation, not two).
        let full_step = damped_step(&analysis, options.rank_tolerance, 0.0);
        if full_step.norm() <= options.step_tolerance * (1.0 + scaled_parameters) {
            termination = Termination::StepConverged;
            final_analysis = Some(analysis);
            break;
        }
        let Some(((candidate, candidate_nuisance), trial, trial_cost)) = first_decrease(
            (&current, &current_nuisance),
            &parameters,
            problem,
            &analysis,
            &full_step,
            cost,
            &mut damping,
        )?
        else {
            termination = Termination::NoDecrease;
            final_analysis = Some(analysis);
            break;
        };
        let previous = cost;
        current = candidate;
        current_nuisance = candidate_nuisance;
        parameters = trial;
        cost = trial_cost;
        costs.push(cost);
        iterations += 1;
        damping *= 0.1;
        if previous - cost <= options.cost_tolerance * previous {
            // The last step was negligible: the analysis before it describes the solution
            // (rank, singular values) as well as a new one would, at half the cost.
            termination = Termination::CostConverged;
            final_analysis = Some(analysis);
            break;
        }
        let products = if lin.factor.is_some() {
            Products::NormalAndFactor
        } else {
            Products::Normal
        };
        lin = accumulate_with(&current, &current_nuisance, problem, products)?;
    }
    parameters.truncate(current.parameter_count());
    Ok(Descent {
        model: current,
        nuisance: current_nuisance,
        parameters,
        costs,
        iterations,
        termination,
        analysis: final_analysis,
        lin,
    })
}

/// The minimum-norm (damped) Gauss–Newton step in scaled units over the retained singular
/// directions: `Σ vᵢ (vᵢᵀ g) / (σᵢ² + λ)`, with `g = J_sᵀ r`; by Cholesky of `N + λI` when the
/// scaled normal matrix is well conditioned (the same step).
fn damped_step(analysis: &Analysis, rank_tolerance: f64, damping: f64) -> DVector<f64> {
    let columns = analysis.scales.len();
    if let Some(normal) = &analysis.normal {
        let damped = normal + DMatrix::identity(columns, columns) * damping;
        if let Some(cholesky) = damped.cholesky() {
            return cholesky.solve(&analysis.gradient);
        }
    }
    let sigma_max = analysis.singular_values.iter().copied().fold(0.0, f64::max);
    let threshold = rank_tolerance * sigma_max;
    let mut step = DVector::zeros(columns);
    for (i, &sigma) in analysis.singular_values.iter().enumerate() {
        if sigma > threshold {
            let v = analysis.v_t.row(i).transpose();
            let along = v.dot(&analysis.gradient) / (sigma * sigma + damping);
            step += v * along;
        }
    }
    step
}

/// The first of up to 40 ever more damped steps from `current` that lowers the cost below
/// `cost`: the model there, its parameters and its cost; `None` when none does. `damping` is
/// left where the accepted step was taken (or where the attempts gave up).
#[allow(clippy::type_complexity)]
fn first_decrease(
    (current, nuisance): (&McpcModel, &Nuisance),
    parameters: &[f64],
    problem: &Problem<'_>,
    analysis: &Analysis,
    full_step: &DVector<f64>,
    cost: f64,
    damping: &mut f64,
) -> Result<Option<((McpcModel, Nuisance), Vec<f64>, f64)>> {
    let count = current.parameter_count();
    let sigma_max = analysis.singular_values.iter().copied().fold(0.0, f64::max);
    for _attempt in 0..40 {
        let step_scaled = if *damping == 0.0 {
            full_step.clone()
        } else {
            damped_step(analysis, problem.options.rank_tolerance, *damping)
        };
        let step: DVector<f64> = step_scaled.component_div(&analysis.scales);
        let mut trial = parameters.to_vec();
        for (k, &p) in problem.free.iter().enumerate() {
            trial[p] += step[k];
        }
        let mut candidate = current.clone();
        candidate.set_parameters(&trial[..count])?;
        let mut candidate_nuisance = nuisance.clone();
        candidate_nuisance.set_values(&trial[count..])?;
        let trial_cost =
            accumulate_with(&candidate, &candidate_nuisance, problem, Products::Cost)?.cost;
        if trial_cost < cost {
            return Ok(Some(((candidate, candidate_nuisance), trial, trial_cost)));
        }
        *damping = if *damping == 0.0 {
            1e-6 * sigma_max * sigma_max
        } else {
            *damping * 10.0
        };
    }
    Ok(None)
}

/// The report at the solution: rank, singular values, unidentifiable combinations, residual
/// RMS, the a-posteriori scale σ̂ and the covariance on the identifiable subspace.
fn summarise(descent: Descent, problem: &Problem<'_>) -> Result<IdentificationReport> {
    let (free, options, measurements) = (problem.free, problem.options, problem.measurements);
    let Descent {
        model: current,
        nuisance,
        parameters,
        costs,
        iterations,
        termination,
        analysis,
        mut lin,
    } = descent;
    let cost = costs.last().copied().unwrap_or(lin.cost);
    // Identifiability at the solution.
    let analysis = match analysis {
        Some(analysis) => analysis,
        None => analyse(&mut lin, options.rank_tolerance, || {
            accumulate_with(&current, &nuisance, problem, Products::NormalAndFactor)
        })?,
    };
    let mut order: Vec<usize> = (0..analysis.singular_values.len()).collect();
    order.sort_by(|&a, &b| analysis.singular_values[b].total_cmp(&analysis.singular_values[a]));
    let singular_values: Vec<f64> = order.iter().map(|&i| analysis.singular_values[i]).collect();
    let sigma_max = singular_values.first().copied().unwrap_or(0.0);
    let threshold = options.rank_tolerance * sigma_max;
    let rank = singular_values.iter().filter(|&&s| s > threshold).count();
    let condition_number = match singular_values.get(rank.saturating_sub(1)) {
        Some(&smallest) if rank > 0 && smallest > 0.0 => sigma_max / smallest,
        _ => f64::INFINITY,
    };
    // Null-space directions: the rows of Vᵀ for the small singular values.
    let unidentifiable = order[rank..]
        .iter()
        .map(|&i| {
            combination(
                &analysis
                    .v_t
                    .row(i)
                    .transpose()
                    .component_div(&analysis.scales),
                free,
            )
        })
        .collect();
    let (residual_rms_position, residual_rms_rotation) = residual_rms(
        &current,
        &nuisance,
        measurements,
        problem.offsets,
        problem.predictor,
        options,
    )?;
    // A-posteriori scale of the assumed σ's.
    // Rows of measurements left out (weight 0, robust estimation) carry no information.
    let rows = rows_of(measurements)
        - measurements
            .iter()
            .zip(&options.observation_weights)
            .filter(|(_, &w)| w == 0.0)
            .map(|(m, _)| m.observation.rows())
            .sum::<usize>()
        + problem.prior.map_or(0, |p| p.count());
    let residual_scale = if rows > rank {
        (2.0 * cost / (rows - rank) as f64).sqrt()
    } else {
        f64::NAN
    };
    let unscaled_inverse = unscaled_inverse(&analysis, &order[..rank]);
    let covariance = residual_scale
        .is_finite()
        .then(|| &unscaled_inverse * residual_scale.powi(2));
    let standard_deviations = (0..free.len())
        .map(|k| residual_scale * unscaled_inverse[(k, k)].max(0.0).sqrt())
        .collect();
    let identifiable = (0..free.len())
        .map(|k| {
            let null: f64 = order[rank..]
                .iter()
                .map(|&i| analysis.v_t[(i, k)].powi(2))
                .sum();
            null.sqrt() < IDENTIFIABLE_NULL_WEIGHT
        })
        .collect();
    Ok(IdentificationReport {
        covariance,
        residual_scale,
        standard_deviations,
        identifiable,
        parameters,
        nuisance,
        free: free.to_vec(),
        iterations,
        costs,
        termination,
        rows,
        rank,
        singular_values,
        condition_number,
        unidentifiable,
        residual_rms_position,
        residual_rms_rotation,
    })
}

/// `(JᵀWJ)⁺` in parameter units on the identifiable subspace (the retained directions
/// `retained`, indices into the analysis's singular values): the covariance over σ̂².
/// `C = σ̂²·S⁻¹·N⁺·S⁻¹` with `N⁺ = V_r·Σ_r⁻²·V_rᵀ`, or `N⁻¹` by Cholesky when well
/// conditioned: Σ over retained directions of `(v_k / s_k)² / σᵢ²`.
fn unscaled_inverse(analysis: &Analysis, retained: &[usize]) -> DMatrix<f64> {
    let columns = analysis.scales.len();
    match analysis.normal.as_ref().and_then(|n| n.clone().cholesky()) {
        Some(cholesky) => {
            let inverse = cholesky.inverse();
            DMatrix::from_fn(columns, columns, |a, b| {
                inverse[(a, b)] / (analysis.scales[a] * analysis.scales[b])
            })
        }
        None => {
            // W = S⁻¹·V_r·Σ_r⁻¹, N⁺ in parameter units = W·Wᵀ.
            let mut w = DMatrix::zeros(columns, retained.len());
            for (column, &i) in retained.iter().enumerate() {
                for k in 0..columns {
                    w[(k, column)] =
                        analysis.v_t[(i, k)] / analysis.scales[k] / analysis.singular_values[i];
                }
            }
            &w * w.transpose()
        }
    }
}

/// The prior's rows over `free`, if the options have a prior; with `follow_residual_scale`,
/// weighted by the residual scale σ̂ (when above 1) of the same fit without the prior, so that
/// the prior weighs against the data as if the declared noise were right.
fn prior_rows(
    model: &McpcModel,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<Option<super::prior::PriorRows>> {
    let Some(prior) = &options.prior else {
        return Ok(None);
    };
    let rows = prior.rows(free, 1.0);
    if rows.count() == 0 {
        return Ok(None);
    }
    let scale = if prior.follow_residual_scale {
        let plain = IdentificationOptions {
            prior: None,
            ..options.clone()
        };
        let report = identify(model, measurements, offsets, predictor, free, &plain)?;
        let scale = report.residual_scale;
        if scale.is_finite() {
            scale.max(1.0)
        } else {
            1.0
        }
    } else {
        1.0
    };
    Ok(Some(prior.rows(free, scale)))
}

/// The column-scaled Jacobian's singular values and right singular vectors, and the scaled
/// gradient `g = J_sᵀ·r`.
struct Analysis {
    scales: DVector<f64>,
    singular_values: DVector<f64>,
    v_t: DMatrix<f64>,
    gradient: DVector<f64>,
    /// The scaled normal matrix `J_sᵀJ_s` when it is well conditioned (then `v_t` is empty and
    /// steps and covariance come from its Cholesky factor).
    normal: Option<DMatrix<f64>>,
}

/// Column scaling, then the SVD of the small triangle `R` of `J_s = Q·R` (same singular values
/// and `V` as `J_s`, at a fraction of the cost). With fewer rows than columns, zero rows
/// complete the matrix so that `V` spans the whole null space. All from the streamed normal
/// equations; `with_factor` recomputes them with `R` when `lin` lacks it and it is needed.
fn analyse(
    lin: &mut NormalEquations,
    rank_tolerance: f64,
    with_factor: impl FnOnce() -> Result<NormalEquations>,
) -> Result<Analysis> {
    let scales = floored_scales(lin.normal.diagonal().iter().map(|d| d.max(0.0).sqrt()));
    let gradient = lin.gradient.component_div(&scales);
    // Fast path: the singular values from the eigenvalues of the normal matrix alone, and the
    // steps and the covariance by Cholesky, when it is well conditioned (see
    // `singular_decomposition`); no singular vectors are needed then (nothing is
    // unidentifiable).
    let normal = DMatrix::from_fn(scales.len(), scales.len(), |a, b| {
        lin.normal[(a, b)] / (scales[a] * scales[b])
    });
    let eigenvalues = normal.symmetric_eigenvalues();
    let largest = eigenvalues.max();
    // Full rank with a margin, also for a caller's coarser rank tolerance.
    let ratio = WELL_CONDITIONED.max(100.0 * rank_tolerance * rank_tolerance);
    if largest > 0.0 && eigenvalues.min() > ratio * largest {
        return Ok(Analysis {
            scales,
            singular_values: eigenvalues.map(f64::sqrt),
            v_t: DMatrix::zeros(0, 0),
            gradient,
            normal: Some(normal),
        });
    }
    // Singular vectors are needed: from the same normal matrix while squaring still resolves
    // the spectrum (a caller's coarse rank tolerance), else from QR + SVD.
    let (singular_values, v_t) = if well_conditioned(&eigenvalues) {
        eigen_decomposition(normal)
    } else {
        if lin.factor.is_none() {
            *lin = with_factor()?;
        }
        let factor = lin.factor.as_ref().ok_or_else(|| Error::InvalidData {
            origin: "identification".into(),
            message: "no triangular factor".into(),
        })?;
        // R·S⁻¹ is the triangle of the scaled Jacobian J·S⁻¹.
        qr_svd(scale_columns(factor, &scales))
    };
    Ok(Analysis {
        scales,
        singular_values,
        v_t,
        gradient,
        normal: None,
    })
}

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

fn validate(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<()> {
    let bad = |message: String| Error::InvalidData {
        origin: "identification".into(),
        message,
    };
    if measurements.is_empty() {
        return Err(bad("no measurements".into()));
    }
    if !options.noise().is_valid() {
        return Err(bad(
            "position_sigma and rotation_sigma must be positive".into()
        ));
    }
    let count = model.parameter_count() + nuisance.len();
    if let Some(&p) = free.iter().find(|&&p| p >= count) {
        return Err(bad(format!(
            "free parameter {p} does not exist (the model and its nuisance have {count})"
        )));
    }
    let observation_weights = &options.observation_weights;
    if !observation_weights.is_empty() && observation_weights.len() != measurements.len() {
        return Err(bad(format!(
            "{} observation weights for {} measurements",
            observation_weights.len(),
            measurements.len()
        )));
    }
    if let Some(w) = observation_weights
        .iter()
        .find(|w| !(w.is_finite() && **w >= 0.0))
    {
        return Err(bad(format!(
            "observation weight {w} is not a non-negative number"
        )));
    }
    if let Some(offsets) = offsets {
        if offsets.len() != measurements.len() {
            return Err(bad(format!(
                "{} flexibility offsets for {} measurements",
                offsets.len(),
                measurements.len()
            )));
        }
    }
    for (index, m) in measurements.iter().enumerate() {
        let second = match &m.observation {
            crate::measurement::Observation::Contact(contact) => contact.second_tool(),
            _ => None,
        };
        if let Some(tool) = second.filter(|&t| t >= model.tools().len()) {
            return Err(bad(format!(
                "measurement {index} names a second tool {tool} of {}",
                model.tools().len()
            )));
        }
        if m.tool >= model.tools().len() {
            return Err(bad(format!(
                "measurement {index} names tool {} of {}",
                m.tool,
                model.tools().len()
            )));
        }
        let finite = m.q.iter().all(|v| v.is_finite()) && kind_of(&m.observation).is_finite();
        if !finite {
            return Err(bad(format!("measurement {index} has a non-finite value")));
        }
    }
    Ok(())
}
