//! Iterative identification (paper eq. (26)–(29)), made robust.
//!
//! Each iteration linearises the weighted residuals `r = W·(pose_error(measured, predicted) − D_f)`
//! around the current parameters, scales the Jacobian's columns to unit norm (so millimetres
//! and radians are comparable), and takes the minimum-norm Gauss–Newton step through the SVD,
//! keeping only singular values above `rank_tolerance · σ_max`: combinations of parameters the
//! data cannot determine are reported and left where they started (at their nominal values).
//! When the Gauss–Newton step does not reduce the cost, the step is damped
//! (Levenberg–Marquardt) until it does. Not converging is an outcome in the report, not an
//! error. See `docs/identification.md`.

use super::normal_equations::{accumulate, NormalEquations, Problem, Products};
use super::observation::{kind_of, squares_by_row_kind, Noise, Nuisance, RobotState, Tools};
use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, ToolJacobian};
use crate::math::{pose_error, Pose};
use crate::measurement::Measurement;
use nalgebra::{DMatrix, DVector, Vector6};

/// How far (rad, m) the parameters may move before a Jacobian correction of
/// [`DeflectedWithDerivative`] is recomputed.
pub const CORRECTION_RADIUS: f64 = 1e-2;

/// How the model predicts the observed tool poses at a configuration. `Sync`: configurations
/// are evaluated in parallel (`calibration::normal_equations`).
pub trait Predictor: Sync {
    /// Poses of all tools (in `model.tools()` order) at configuration `q`.
    fn predict(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<Pose>>;

    /// Poses and identification Jacobians of all tools at `q`; by default the rigid ones.
    fn jacobians(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<ToolJacobian>> {
        Ok(model.tool_jacobians(q))
    }

    /// [`Self::predict`] for a row measured with `payload` kg at every tool (`None`: the
    /// predictor's own loads). Rigid predictions ignore it.
    fn predict_at(&self, model: &McpcModel, q: &[f64], payload: Option<f64>) -> Result<Vec<Pose>> {
        let _ = payload;
        self.predict(model, q)
    }

    /// [`Self::jacobians`] for a row measured with `payload` kg at every tool.
    fn jacobians_at(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
    ) -> Result<Vec<ToolJacobian>> {
        let _ = payload;
        self.jacobians(model, q)
    }
}

/// The rigid MCPC forward kinematics.
#[derive(Debug, Clone, Copy, Default)]
pub struct Rigid;

impl Predictor for Rigid {
    fn predict(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<Pose>> {
        Ok(model.tool_poses(q))
    }
}

/// The MCPC forward kinematics with the flexibility model's deflections inserted into the
/// chain, re-evaluated at the current parameters: exact flexibility compensation.
#[derive(Debug, Clone, Copy)]
pub struct Deflected<'a> {
    /// The tree the flexibility model was built for.
    pub tree: &'a crate::tree::KinematicTree,
    /// The flexibility model (built for the same MCPC model structure).
    pub flexibility: &'a crate::kinematics::FlexibilityModel,
}

impl Predictor for Deflected<'_> {
    fn predict(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<Pose>> {
        self.predict_at(model, q, None)
    }

    /// The Jacobian on the deflected chain: parameter changes move the bent robot, but how the
    /// deflections themselves change with the parameters (through the lever arms of the loads)
    /// is left out. [`DeflectedWithDerivative`] adds it.
    fn jacobians(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<ToolJacobian>> {
        self.jacobians_at(model, q, None)
    }

    fn predict_at(&self, model: &McpcModel, q: &[f64], payload: Option<f64>) -> Result<Vec<Pose>> {
        self.flexibility
            .for_payload(payload)?
            .deflected_tool_poses(self.tree, model, q)
    }

    fn jacobians_at(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
    ) -> Result<Vec<ToolJacobian>> {
        let flexibility = self.flexibility.for_payload(payload)?;
        Ok(model.jacobians_on(&flexibility.deflected_chain(self.tree, model, q)?))
    }
}

impl Deflected<'_> {
    /// The deflection of every tool at `q` with `payload` kg at every tool (`None`: the
    /// model's own loads): `deflected ⊖ rigid` (exact, not the linear map).
    pub fn offsets(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
    ) -> Result<Vec<Vector6<f64>>> {
        let deflected = self.predict_at(model, q, payload)?;
        Ok(deflected
            .iter()
            .zip(model.tool_poses(q))
            .map(|(d, r)| pose_error(d, &r))
            .collect())
    }
}

/// Exact flexibility compensation with a Jacobian that includes how the deflections change
/// with the parameters. At 5000 N·m/rad and 20 kg the deflections are centimetres and
/// degrees, and a 5 cm error in a lever arm changes them by a good fraction, so the Jacobian
/// on the deflected chain alone ([`Deflected`]) makes the iteration converge only linearly.
/// The missing part — the exact derivative of the deflected poses (forward differences) minus
/// the deflected-chain Jacobian — is computed per configuration once the iterates settle and
/// reused while the parameters stay within [`CORRECTION_RADIUS`] of where it was computed (its
/// own change is second order): two or three times per calibration.
#[derive(Debug)]
pub struct DeflectedWithDerivative<'a> {
    source: Deflected<'a>,
    /// Per configuration (keyed by the bits of `q`: O(1) lookup): where the correction was
    /// computed and the correction.
    cache: std::sync::Mutex<std::collections::HashMap<CorrectionKey, Correction>>,
}

/// Where a row is evaluated: its configuration and payload (rows of several tools measured
/// there share one evaluation).
pub(crate) type RowKey<'a> = (&'a [f64], Option<f64>);

/// The latest evaluation and where it was made.
pub(crate) type Cached<'a, T> = Option<(RowKey<'a>, T)>;

/// The cache key of a correction: the bits of the configuration and of the payload.
type CorrectionKey = (Vec<u64>, Option<u64>);

/// A cached Jacobian correction: parameters where it was computed, parameters of the latest
/// request, and `J_exact − J_chain` per tool.
type Correction = (Vec<f64>, Vec<f64>, Vec<DMatrix<f64>>);

/// The cache key of a configuration: its exact bits (`+ 0.0`: −0 and +0 are one key, as
/// under `==`).
fn configuration_key(q: &[f64]) -> Vec<u64> {
    q.iter().map(|v| (v + 0.0).to_bits()).collect()
}

impl<'a> DeflectedWithDerivative<'a> {
    /// Wraps a deflected predictor.
    pub fn new(source: Deflected<'a>) -> Self {
        Self {
            source,
            cache: std::sync::Mutex::new(std::collections::HashMap::new()),
        }
    }

    /// `J_exact − J_chain` at `q`, from the cache or computed now.
    ///
    /// A correction is reused while the parameters stay within [`CORRECTION_RADIUS`] of where
    /// it was computed. Beyond that it is recomputed only once the iterates settle (the last
    /// request was within the radius too): while they still travel, a stale correction steers
    /// as well and costs nothing, and the final one is always within the radius of the
    /// solution, which keeps the solution's bias from a stale Jacobian negligible.
    fn correction(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
        chain: &[ToolJacobian],
    ) -> Result<Vec<DMatrix<f64>>> {
        let parameters = model.parameters();
        let close = |at: &[f64]| {
            at.iter()
                .zip(&parameters)
                .all(|(a, b)| (a - b).abs() <= CORRECTION_RADIUS)
        };
        let key = (configuration_key(q), payload.map(f64::to_bits));
        {
            let mut cache = self
                .cache
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner());
            if let Some((at, latest, found)) = cache.get_mut(&key) {
                let settled = close(latest);
                latest.clone_from(&parameters);
                if close(at) || !settled {
                    return Ok(found.clone());
                }
            } else {
                // First request: far from the solution, the deflected-chain Jacobian alone
                // steers well enough; the correction waits until the iterates settle.
                let zero: Vec<DMatrix<f64>> =
                    chain.iter().map(|c| c.jacobian.map(|_| 0.0)).collect();
                cache.insert(
                    key,
                    (
                        vec![f64::INFINITY; parameters.len()],
                        parameters,
                        zero.clone(),
                    ),
                );
                return Ok(zero);
            }
        }
        let step = 1e-7;
        let base = self.source.predict_at(model, q, payload)?;
        let mut correction: Vec<DMatrix<f64>> = chain.iter().map(|c| -c.jacobian.clone()).collect();
        let mut shifted = model.clone();
        for (index, &value) in parameters.iter().enumerate() {
            shifted.set_parameter(index, value + step)?;
            for (tool, pose) in self
                .source
                .predict_at(&shifted, q, payload)?
                .iter()
                .enumerate()
            {
                let column = pose_error(pose, &base[tool]) / step;
                let mut target = correction[tool].column_mut(index);
                target += column;
            }
            shifted.set_parameter(index, value)?;
        }
        let mut cache = self
            .cache
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        cache.insert(key, (parameters.clone(), parameters, correction.clone()));
        Ok(correction)
    }
}

impl Predictor for DeflectedWithDerivative<'_> {
    fn predict(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<Pose>> {
        self.source.predict(model, q)
    }

    /// The deflected-chain Jacobian plus the (frozen) effect of the deflections' own change.
    fn jacobians(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<ToolJacobian>> {
        self.jacobians_at(model, q, None)
    }

    fn predict_at(&self, model: &McpcModel, q: &[f64], payload: Option<f64>) -> Result<Vec<Pose>> {
        self.source.predict_at(model, q, payload)
    }

    fn jacobians_at(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
    ) -> Result<Vec<ToolJacobian>> {
        let chain = self.source.jacobians_at(model, q, payload)?;
        let correction = self.correction(model, q, payload, &chain)?;
        Ok(chain
            .into_iter()
            .zip(correction)
            .map(|(tool, extra)| ToolJacobian {
                pose: tool.pose,
                jacobian: tool.jacobian + extra,
            })
            .collect())
    }
}

/// Settings of the identification.
#[derive(Debug, Clone)]
pub struct IdentificationOptions {
    /// Iteration limit.
    pub max_iterations: usize,
    /// Expected position error of a measurement (m): position rows are divided by it.
    pub position_sigma: f64,
    /// Expected rotation error of a measurement (rad): rotation rows are divided by it.
    pub rotation_sigma: f64,
    /// Singular values below this times the largest are treated as zero (unidentifiable).
    pub rank_tolerance: f64,
    /// Stop when the scaled step is below this (relative to the scaled parameters + 1).
    pub step_tolerance: f64,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_tolerance: f64,
    /// Per-measurement weights (robust estimation, [`super::robust`]): measurement `i`'s rows
    /// are multiplied by `√weights[i]`, so its share of the cost is `weights[i]·½‖r_i‖²`.
    /// Empty: every weight is 1 (the plain least-squares problem, bit for bit).
    pub observation_weights: Vec<f64>,
    /// How [`super::run::run_calibration`] and [`super::robust::calibrate_robust`] weight
    /// measurements by their residuals (default Huber); [`identify`] itself only applies
    /// `observation_weights`.
    pub robust: super::robust::RobustLoss,
    /// Parameters (flat indices into the full model) that a plan never frees: the model
    /// level's and `--freeze`'s ([`super::plan::calibrate`]); [`identify`] frees what it is told.
    pub frozen: Vec<usize>,
    /// A Gaussian prior on the parameters (rows in the normal equations; `None`: no prior).
    pub prior: Option<super::prior::Prior>,
}

impl IdentificationOptions {
    /// The noise model: σ per row kind.
    pub fn noise(&self) -> Noise {
        Noise {
            position: self.position_sigma,
            rotation: self.rotation_sigma,
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
}

impl Default for IdentificationOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            position_sigma: 1e-4,
            rotation_sigma: 1e-4,
            rank_tolerance: 1e-8,
            step_tolerance: 1e-12,
            cost_tolerance: 1e-8,
            observation_weights: Vec::new(),
            robust: super::robust::RobustLoss::default(),
            frozen: Vec::new(),
            prior: None,
        }
    }
}

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
}

/// What the identification did and found.
#[derive(Debug, Clone)]
pub struct IdentificationReport {
    /// The identified parameters (whole vector; parameters not free are unchanged).
    pub parameters: Vec<f64>,
    /// Indices of the parameters that were free.
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

/// The stacked, weighted residual and its Jacobian over the free parameters.
pub(super) struct Linearisation {
    pub(super) residual: DVector<f64>,
    pub(super) jacobian: DMatrix<f64>,
}

fn rows_of(measurements: &[Measurement]) -> usize {
    measurements.iter().map(|m| m.observation.rows()).sum()
}

/// The weighted residual of every measurement (each row over its σ, [`Noise`]) under
/// `predictor` at `model`: the vector whose half squared norm [`identify`] minimises.
pub fn weighted_residual(
    model: &McpcModel,
    measurements: &[Measurement],
    predictor: &dyn Predictor,
    options: &IdentificationOptions,
) -> Result<DVector<f64>> {
    Ok(linearise(model, measurements, None, predictor, &[], options, false)?.residual)
}

/// The stacked residual `W·r` and, `with_jacobian`, its Jacobian `W·J` over the `free`
/// parameters, through the observation seam: each measurement's kind gives its unweighted
/// residual and Jacobian rows from the robot state the predictor evaluated (once per
/// configuration and payload, shared by the rows measured there), and each row is multiplied
/// by `√w_i / σ` of its row kind.
pub(super) fn linearise(
    model: &McpcModel,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
    with_jacobian: bool,
) -> Result<Linearisation> {
    let rows = rows_of(measurements);
    let mut residual = DVector::zeros(rows);
    let mut jacobian = DMatrix::zeros(if with_jacobian { rows } else { 0 }, free.len());
    let noise = options.noise();
    let mut row = 0;
    // Measurements of several tools at one configuration share one evaluation.
    // Keyed by configuration and payload.
    let mut cached: Cached<'_, Vec<ToolJacobian>> = None;
    let mut cached_poses: Cached<'_, Vec<Pose>> = None;
    for (index, m) in measurements.iter().enumerate() {
        let kind = kind_of(&m.observation);
        let count = kind.rows();
        let key = (m.q.as_slice(), m.payload);
        let tools = if with_jacobian {
            if cached.as_ref().is_none_or(|(k, _)| *k != key) {
                cached = Some((key, predictor.jacobians_at(model, &m.q, m.payload)?));
            }
            Tools::Jacobians(cached.as_ref().map_or(&[][..], |(_, j)| j.as_slice()))
        } else {
            if cached_poses.as_ref().is_none_or(|(k, _)| *k != key) {
                cached_poses = Some((key, predictor.predict_at(model, &m.q, m.payload)?));
            }
            Tools::Poses(cached_poses.as_ref().map_or(&[][..], |(_, p)| p.as_slice()))
        };
        let state = RobotState {
            model,
            q: &m.q,
            tool: m.tool,
            tools,
            offset: offsets.map(|o| &o[index]),
            nuisance: Nuisance::none(),
        };
        // Multiplying by exactly 1.0 keeps unweighted problems bit for bit as before.
        let observation = options
            .observation_weights
            .get(index)
            .map_or(1.0, |w| w.sqrt());
        let weight = |row_kind| (1.0 / noise.sigma(row_kind)) * observation;
        if with_jacobian {
            let mut block = jacobian.view_mut((row, 0), (count, free.len()));
            kind.jacobian(&state, free, &mut block)?;
            for (k, &row_kind) in kind.row_kinds().iter().enumerate() {
                block.row_mut(k).scale_mut(weight(row_kind));
            }
        }
        kind.residual(&state, &mut residual.as_mut_slice()[row..row + count])?;
        for (k, &row_kind) in kind.row_kinds().iter().enumerate() {
            residual[row + k] *= weight(row_kind);
        }
        row += count;
    }
    Ok(Linearisation { residual, jacobian })
}

fn residual_rms(
    model: &McpcModel,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    options: &IdentificationOptions,
) -> Result<(f64, f64)> {
    let (mut position, mut rotation, mut poses, mut count) = (0.0, 0.0, 0usize, 0usize);
    let mut error = Vec::new();
    for (index, m) in measurements.iter().enumerate() {
        // Measurements left out (weight 0, robust estimation) are not part of the fit.
        if options.observation_weights.get(index) == Some(&0.0) {
            continue;
        }
        count += 1;
        let predicted = predictor.predict_at(model, &m.q, m.payload)?;
        let kind = kind_of(&m.observation);
        let state = RobotState {
            model,
            q: &m.q,
            tool: m.tool,
            tools: Tools::Poses(&predicted),
            offset: offsets.map(|o| &o[index]),
            nuisance: Nuisance::none(),
        };
        error.resize(kind.rows(), 0.0);
        kind.residual(&state, &mut error)?;
        let [position_squares, rotation_squares] = squares_by_row_kind(kind, &error);
        position += position_squares.unwrap_or(0.0);
        if let Some(squares) = rotation_squares {
            rotation += squares;
            poses += 1;
        }
    }
    let n = count.max(1) as f64;
    let rotation_rms = if poses > 0 {
        (rotation / poses as f64).sqrt()
    } else {
        0.0
    };
    Ok(((position / n).sqrt(), rotation_rms))
}

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
    validate(model, measurements, offsets, free, options)?;
    let prior_rows = prior_rows(model, measurements, offsets, predictor, free, options)?;
    let mut current = model.clone();
    let mut parameters = current.parameters();
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
    let mut lin = accumulate(&current, &problem, Products::Normal)?;
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
            accumulate(&current, &problem, Products::NormalAndFactor)
        })?;
        let sigma_max = analysis.singular_values.iter().copied().fold(0.0, f64::max);
        let threshold = options.rank_tolerance * sigma_max;
        // Minimum-norm (damped) Gauss–Newton step in scaled units over the retained singular
        // directions: Σ vᵢ (vᵢᵀ g) / (σᵢ² + λ), with g = J_sᵀ r.
        let step_for = |damping: f64| -> DVector<f64> {
            if let Some(normal) = &analysis.normal {
                // Well conditioned: (N + λI)⁻¹·g is the same step, by Cholesky.
                let damped = normal + DMatrix::identity(free.len(), free.len()) * damping;
                if let Some(cholesky) = damped.cholesky() {
                    return cholesky.solve(&analysis.gradient);
                }
            }
            let mut step = DVector::zeros(free.len());
            for (i, &sigma) in analysis.singular_values.iter().enumerate() {
                if sigma > threshold {
                    let v = analysis.v_t.row(i).transpose();
                    let along = v.dot(&analysis.gradient) / (sigma * sigma + damping);
                    step += v * along;
                }
            }
            step
        };
        // Converged when the full Gauss–Newton step is negligible against the parameters.
        let scaled_parameters = free
            .iter()
            .zip(analysis.scales.iter())
            .map(|(&p, s)| (parameters[p] * s).powi(2))
            .sum::<f64>()
            .sqrt();
        // The undamped step, also the first trial below (one Cholesky factorisation, not two).
        let full_step = step_for(0.0);
        if full_step.norm() <= options.step_tolerance * (1.0 + scaled_parameters) {
            termination = Termination::StepConverged;
            final_analysis = Some(analysis);
            break;
        }

        let mut accepted = false;
        for _attempt in 0..40 {
            let step_scaled = if damping == 0.0 {
                full_step.clone()
            } else {
                step_for(damping)
            };
            let step: DVector<f64> = step_scaled.component_div(&analysis.scales);
            let mut trial = parameters.clone();
            for (k, &p) in free.iter().enumerate() {
                trial[p] += step[k];
            }
            let mut candidate = current.clone();
            candidate.set_parameters(&trial)?;
            let trial_cost = accumulate(&candidate, &problem, Products::Cost)?.cost;
            if trial_cost < cost {
                let previous = cost;
                current = candidate;
                parameters = trial;
                cost = trial_cost;
                costs.push(cost);
                iterations += 1;
                damping *= 0.1;
                accepted = true;
                if previous - cost <= options.cost_tolerance * previous {
                    termination = Termination::CostConverged;
                }
                break;
            }
            damping = if damping == 0.0 {
                1e-6 * sigma_max * sigma_max
            } else {
                damping * 10.0
            };
        }
        if !accepted {
            termination = Termination::NoDecrease;
            final_analysis = Some(analysis);
            break;
        }
        if termination == Termination::CostConverged {
            // The last step was negligible: the analysis before it describes the solution
            // (rank, singular values) as well as a new one would, at half the cost.
            final_analysis = Some(analysis);
            break;
        }
        let products = if lin.factor.is_some() {
            Products::NormalAndFactor
        } else {
            Products::Normal
        };
        lin = accumulate(&current, &problem, products)?;
        if termination != Termination::MaxIterations {
            break;
        }
    }

    // Identifiability at the solution.
    let analysis = match final_analysis {
        Some(analysis) => analysis,
        None => analyse(&mut lin, options.rank_tolerance, || {
            accumulate(&current, &problem, Products::NormalAndFactor)
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
    let (residual_rms_position, residual_rms_rotation) =
        residual_rms(&current, measurements, offsets, predictor, options)?;
    // A-posteriori scale of the assumed σ's, and the covariance σ̂²·(JᵀWJ)⁺ on the
    // identifiable subspace, back in parameter units: Σ over retained directions of
    // (v_k / s_k)² / σᵢ².
    // Rows of measurements left out (weight 0, robust estimation) carry no information.
    let rows = rows_of(measurements)
        - measurements
            .iter()
            .zip(&options.observation_weights)
            .filter(|(_, &w)| w == 0.0)
            .map(|(m, _)| m.observation.rows())
            .sum::<usize>()
        + prior_rows.as_ref().map_or(0, |p| p.count());
    let residual_scale = if rows > rank {
        (2.0 * cost / (rows - rank) as f64).sqrt()
    } else {
        f64::NAN
    };
    // C = σ̂²·S⁻¹·N⁺·S⁻¹ with N⁺ = V_r·Σ_r⁻²·V_rᵀ, or N⁻¹ by Cholesky when well conditioned.
    let unscaled_inverse = match analysis.normal.as_ref().and_then(|n| n.clone().cholesky()) {
        Some(cholesky) => {
            let inverse = cholesky.inverse();
            DMatrix::from_fn(free.len(), free.len(), |a, b| {
                inverse[(a, b)] / (analysis.scales[a] * analysis.scales[b])
            })
        }
        None => {
            // W = S⁻¹·V_r·Σ_r⁻¹, N⁺ in parameter units = W·Wᵀ.
            let mut w = DMatrix::zeros(free.len(), rank);
            for (column, &i) in order[..rank].iter().enumerate() {
                for k in 0..free.len() {
                    w[(k, column)] =
                        analysis.v_t[(i, k)] / analysis.scales[k] / analysis.singular_values[i];
                }
            }
            &w * w.transpose()
        }
    };
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

/// Smallest eigenvalue ratio of the scaled normal matrix for which squaring the Jacobian
/// loses nothing near the rank tolerance (σ ratio 1e-5): eigenvalues then come out to ~1e-6
/// relative.
const WELL_CONDITIONED: f64 = 1e-10;

/// Singular values (unsorted) and `Vᵀ` of a column-scaled Jacobian: from the normal matrix
/// when it is well conditioned, else through the SVD of the small triangle `R` of
/// `J_s = Q·R`. Shared with `calibration::identifiability`.
pub(crate) fn singular_decomposition(scaled: DMatrix<f64>) -> (DVector<f64>, DMatrix<f64>) {
    // Fast path: the eigen-decomposition of the scaled normal matrix gives σ² and V in a third
    // of the time of QR + SVD, and exactly enough when the matrix is well conditioned (σ²
    // ratios above 1e-10 are resolved to ~1e-6 relative, far from the rank tolerance). Near
    // rank deficiency, where squaring would lose the small singular values, QR + SVD decide.
    let normal = normal_matrix(&scaled);
    if well_conditioned(&normal.symmetric_eigenvalues()) {
        eigen_decomposition(normal)
    } else {
        qr_svd(scaled)
    }
}

/// Whether the eigenvalues of a normal matrix are all above [`WELL_CONDITIONED`] of the
/// largest.
fn well_conditioned(eigenvalues: &DVector<f64>) -> bool {
    let largest = eigenvalues.max();
    largest > 0.0 && eigenvalues.min() > WELL_CONDITIONED * largest
}

/// `σ = √λ` and `Vᵀ` from the eigen-decomposition of the normal matrix `JᵀJ`.
fn eigen_decomposition(normal: DMatrix<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let eigen = normal.symmetric_eigen();
    (
        eigen.eigenvalues.map(|l| l.max(0.0).sqrt()),
        eigen.eigenvectors.transpose(),
    )
}

/// Singular values and `Vᵀ` through the SVD of the triangle `R` of `J = Q·R` (same σ and `V`);
/// with fewer rows than columns, zero rows complete the matrix so that there is one singular
/// value per column and `V` spans the whole null space.
fn qr_svd(scaled: DMatrix<f64>) -> (DVector<f64>, DMatrix<f64>) {
    let columns = scaled.ncols();
    let square = if scaled.nrows() >= columns {
        scaled.qr().r()
    } else {
        scaled.resize_vertically(columns, 0.0)
    };
    let svd = square.svd(false, true);
    let v_t = svd
        .v_t
        .unwrap_or_else(|| DMatrix::identity(columns, columns));
    (svd.singular_values, v_t)
}

/// `AᵀA`. A dense product beat both a row-sparse and a block-sparse accumulation that skip the
/// zeros outside each tool's chain (measured: 100 configurations 12.1 → 7.1 ms per
/// calibration); the blocked kernel ([`super::normal_equations::add_gram`]) beats `tr_mul`.
fn normal_matrix(a: &DMatrix<f64>) -> DMatrix<f64> {
    let mut normal = DMatrix::zeros(a.ncols(), a.ncols());
    super::normal_equations::add_gram(&mut normal, a);
    normal
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

/// Column norms, floored at 1e-6 of the largest: a column that is zero but for rounding (a
/// rotation about an axis through the tool point, say) must stay negligible after scaling,
/// not be blown up into a unit column of noise.
pub(crate) fn column_scales(jacobian: &DMatrix<f64>) -> DVector<f64> {
    floored_scales(jacobian.column_iter().map(|c| c.norm()))
}

/// [`column_scales`] from the column norms.
fn floored_scales(norms: impl Iterator<Item = f64>) -> DVector<f64> {
    let norms: Vec<f64> = norms.collect();
    let floor = norms.iter().copied().fold(0.0, f64::max) * 1e-6;
    DVector::from_iterator(
        norms.len(),
        norms.into_iter().map(|n| {
            if n > floor {
                n
            } else if floor > 0.0 {
                floor
            } else {
                1.0
            }
        }),
    )
}

pub(crate) fn scale_columns(jacobian: &DMatrix<f64>, scales: &DVector<f64>) -> DMatrix<f64> {
    let mut scaled = jacobian.clone();
    for (mut column, s) in scaled.column_iter_mut().zip(scales.iter()) {
        column /= *s;
    }
    scaled
}

fn validate(
    model: &McpcModel,
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
    let count = model.parameter_count();
    if let Some(&p) = free.iter().find(|&&p| p >= count) {
        return Err(bad(format!(
            "free parameter {p} does not exist (the model has {count})"
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
