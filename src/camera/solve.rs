//! The iteration of a camera calibration ([`calibrate_camera`]): column scaling, the SVD of
//! the scaled Jacobian with a rank decision, minimum-norm Gauss–Newton steps damped
//! (Levenberg–Marquardt) until the cost drops, and the covariance and unidentifiable
//! directions at the solution.

use super::fit::{CameraFitOptions, CameraFitReport, CameraProblem, Linearisation, State};
use super::unknown::Unknown;
use crate::calibration::Termination;
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use nalgebra::{DMatrix, DVector};

/// A parameter whose unit vector (column-scaled) has more than this weight in the null space
/// is reported as not identifiable (as in the tracker identification).
const NULL_WEIGHT: f64 = 1e-3;

/// The SVD of the column-scaled Jacobian.
struct Analysis {
    scales: DVector<f64>,
    singular_values: DVector<f64>,
    v_t: DMatrix<f64>,
    gradient: DVector<f64>,
    rank: usize,
}

impl Analysis {
    fn of(lin: &Linearisation, rank_tolerance: f64) -> Self {
        let columns = lin.jacobian.ncols();
        let norms: Vec<f64> = lin.jacobian.column_iter().map(|c| c.norm()).collect();
        let floor = norms.iter().copied().fold(0.0, f64::max) * 1e-6;
        let scales = DVector::from_iterator(
            columns,
            norms.iter().map(|&n| {
                if n > floor {
                    n
                } else if floor > 0.0 {
                    floor
                } else {
                    1.0
                }
            }),
        );
        let mut scaled = lin.jacobian.clone();
        for (mut column, s) in scaled.column_iter_mut().zip(scales.iter()) {
            column /= *s;
        }
        let gradient = scaled.tr_mul(&lin.residual);
        // The SVD of the small triangle R of J_s = Q·R has J_s's singular values and V.
        let square = if scaled.nrows() >= columns {
            scaled.qr().r()
        } else {
            scaled.resize_vertically(columns, 0.0)
        };
        let svd = square.svd(false, true);
        let v_t = svd
            .v_t
            .unwrap_or_else(|| DMatrix::identity(columns, columns));
        let singular_values = svd.singular_values;
        let largest = singular_values.iter().copied().fold(0.0, f64::max);
        let rank = singular_values
            .iter()
            .filter(|&&s| s > rank_tolerance * largest)
            .count();
        Self {
            scales,
            singular_values,
            v_t,
            gradient,
            rank,
        }
    }

    fn threshold(&self, rank_tolerance: f64) -> f64 {
        rank_tolerance * self.singular_values.iter().copied().fold(0.0, f64::max)
    }

    /// The damped minimum-norm step in unknown units: `S⁻¹·Σ vᵢ (vᵢᵀg)/(σᵢ² + λ)` over the
    /// retained directions.
    fn step(&self, damping: f64, rank_tolerance: f64) -> DVector<f64> {
        let threshold = self.threshold(rank_tolerance);
        let mut step = DVector::zeros(self.scales.len());
        for (i, &sigma) in self.singular_values.iter().enumerate() {
            if sigma > threshold {
                let v = self.v_t.row(i).transpose();
                step += &v * (v.dot(&self.gradient) / (sigma * sigma + damping));
            }
        }
        step
    }
}

/// Fits `problem`'s unknowns starting from `model` (the rig's augmented model) and the rig's
/// intrinsics. Not converging is an outcome in the report; errors only for inputs that make
/// no sense or a non-finite Jacobian.
pub fn calibrate_camera(
    model: &McpcModel,
    problem: &CameraProblem<'_>,
    options: &CameraFitOptions,
) -> Result<CameraFitReport> {
    problem.validate(model)?;
    if !(options.pixel_sigma > 0.0 && options.position_sigma > 0.0 && options.rotation_sigma > 0.0)
    {
        return Err(invalid(
            "the pixel, position and rotation σ must be positive",
        ));
    }
    let mut state = State {
        model: model.clone(),
        intrinsics: problem.rig.cameras.iter().map(|c| c.intrinsics).collect(),
        nuisance: problem.contacts.nuisance.clone(),
    };
    let (kept, rejected) = problem.kept_points(&state);
    let cost_of = |lin: &Linearisation| 0.5 * lin.residual.norm_squared();
    let mut lin = problem
        .linearise(&state, &kept, options, true)
        .ok_or_else(|| invalid("a detected point has no pixel at the start"))?;
    let mut cost = cost_of(&lin);
    let mut costs = vec![cost];
    let (mut damping, mut iterations) = (0.0, 0);
    let mut termination = Termination::MaxIterations;
    let tolerance = options.rank_tolerance;
    let analysis = loop {
        crate::limits::ensure_finite(
            lin.jacobian.iter().chain(lin.residual.iter()),
            "camera calibration: the weighted Jacobian and residual",
        )?;
        let analysis = Analysis::of(&lin, tolerance);
        if iterations >= options.max_iterations {
            break analysis;
        }
        let full = analysis.step(0.0, tolerance);
        let size = state_size(problem, &state, &analysis.scales);
        if full.norm() <= options.step_tolerance * (1.0 + size) {
            termination = Termination::StepConverged;
            break analysis;
        }
        let largest = analysis.singular_values.iter().copied().fold(0.0, f64::max);
        let mut accepted = None;
        for _attempt in 0..40 {
            let scaled = if damping == 0.0 {
                full.clone()
            } else {
                analysis.step(damping, tolerance)
            };
            let trial = problem.moved(&state, &scaled.component_div(&analysis.scales))?;
            let trial_cost = problem
                .linearise(&trial, &kept, options, false)
                .map_or(f64::INFINITY, |l| cost_of(&l));
            if trial_cost < cost {
                accepted = Some((trial, trial_cost));
                damping *= 0.1;
                break;
            }
            damping = if damping == 0.0 {
                1e-6 * largest * largest
            } else {
                damping * 10.0
            };
        }
        let Some((trial, trial_cost)) = accepted else {
            termination = Termination::NoDecrease;
            break analysis;
        };
        let previous = cost;
        state = trial;
        cost = trial_cost;
        costs.push(cost);
        iterations += 1;
        lin = problem
            .linearise(&state, &kept, options, true)
            .ok_or_else(|| invalid("a detected point lost its pixel"))?;
        if previous - cost <= options.cost_tolerance * previous {
            termination = Termination::CostConverged;
            crate::limits::ensure_finite(lin.jacobian.iter(), "camera calibration")?;
            break Analysis::of(&lin, tolerance);
        }
    };
    let mut report = statistics(
        problem,
        state,
        &analysis,
        &lin,
        costs,
        iterations,
        termination,
        rejected,
    )?;
    report.residual_rms_pixel *= options.pixel_sigma;
    Ok(report)
}

/// ‖S·x‖ of the model parameters and intrinsics being fitted (the step test's scale).
fn state_size(problem: &CameraProblem<'_>, state: &State, scales: &DVector<f64>) -> f64 {
    let parameters = state.model.parameters();
    let nuisance = state.nuisance.values();
    problem
        .unknowns
        .iter()
        .zip(scales.iter())
        .map(|(u, s)| {
            let value = match *u {
                Unknown::Parameter(p) => parameters[p],
                Unknown::Intrinsic { camera, index } => state.intrinsics[camera].to_vector()[index],
                Unknown::Nuisance(k) => nuisance.get(k).copied().unwrap_or(0.0),
            };
            (value * s).powi(2)
        })
        .sum::<f64>()
        .sqrt()
}

/// The report at the solution: σ̂, covariance, identifiability.
#[allow(clippy::too_many_arguments)]
fn statistics(
    problem: &CameraProblem<'_>,
    state: State,
    analysis: &Analysis,
    lin: &Linearisation,
    costs: Vec<f64>,
    iterations: usize,
    termination: Termination,
    rejected: Vec<super::fit::RejectedPoint>,
) -> Result<CameraFitReport> {
    let n = problem.unknowns.len();
    let rows = lin.residual.len();
    let rank = analysis.rank;
    let cost = 0.5 * lin.residual.norm_squared();
    let residual_scale = if rows > rank {
        (2.0 * cost / (rows - rank) as f64).sqrt()
    } else {
        f64::NAN
    };
    let mut order: Vec<usize> = (0..analysis.singular_values.len()).collect();
    order.sort_by(|&a, &b| analysis.singular_values[b].total_cmp(&analysis.singular_values[a]));
    // W = S⁻¹·V_r·Σ_r⁻¹; (JᵀWJ)⁺ = W·Wᵀ.
    let mut w = DMatrix::zeros(n, rank);
    for (column, &i) in order[..rank].iter().enumerate() {
        for k in 0..n {
            w[(k, column)] =
                analysis.v_t[(i, k)] / analysis.scales[k] / analysis.singular_values[i];
        }
    }
    let covariance = residual_scale
        .is_finite()
        .then(|| &w * w.transpose() * residual_scale.powi(2));
    let identifiable = (0..n)
        .map(|k| {
            order[rank..]
                .iter()
                .map(|&i| analysis.v_t[(i, k)].powi(2))
                .sum::<f64>()
                .sqrt()
                < NULL_WEIGHT
        })
        .collect();
    let unidentifiable = order[rank..]
        .iter()
        .map(|&i| {
            let direction = analysis
                .v_t
                .row(i)
                .transpose()
                .component_div(&analysis.scales);
            let norm = direction.norm().max(f64::MIN_POSITIVE);
            let largest = direction.amax() / norm;
            let mut terms: Vec<(usize, f64)> = direction
                .iter()
                .enumerate()
                .map(|(k, v)| (k, v / norm))
                .filter(|(_, v)| v.abs() >= 0.1 * largest)
                .collect();
            terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            terms
        })
        .collect();
    let pixel_rows = rows
        - problem
            .tracker
            .iter()
            .map(|m| m.observation.rows())
            .sum::<usize>()
        - problem.contacts.row_count();
    let options_sigma = pixel_sigma_of(lin, pixel_rows);
    let kinds = super::fit::kind_scales(problem, &lin.residual, rank);
    Ok(CameraFitReport {
        nuisance: state.nuisance,
        model: state.model,
        intrinsics: state.intrinsics,
        unknowns: problem.unknowns.clone(),
        iterations,
        costs,
        termination,
        rows,
        rank,
        residual_scale,
        residual_rms_pixel: options_sigma,
        covariance,
        identifiable,
        unidentifiable,
        rejected,
        kinds,
    })
}

/// RMS of the first `pixel_rows` weighted residuals (in units of the pixel σ).
fn pixel_sigma_of(lin: &Linearisation, pixel_rows: usize) -> f64 {
    if pixel_rows == 0 {
        return 0.0;
    }
    (lin.residual.rows(0, pixel_rows).norm_squared() / pixel_rows as f64).sqrt()
}

fn invalid(message: &str) -> Error {
    Error::InvalidData {
        origin: "camera calibration".into(),
        message: message.into(),
    }
}
