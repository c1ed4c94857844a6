//! The fair "before" of a calibration: the nominal robot with the same freedom as the
//! calibrated one has outside its geometry — the measurement frame (when it is fitted) and the
//! tool frames — fitted by least squares to the same rows with the same weights. The
//! closed-form start (`initial_guess`) places frame and tools one after the other and can leave
//! the nominal robot several times worse than a registration would: a baseline that flatters
//! the calibration.

use super::coarse_to_fine::CoarseToFine;
use super::observation::{kind_of, Nuisance, RobotState, Tools};
use super::options::IdentificationOptions;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::Pose;
use crate::measurement::Measurement;
use nalgebra::{DMatrix, DVector, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// Levenberg–Marquardt iterations at most.
const MAX_ITERATIONS: usize = 100;

/// Central-difference step of the numerical Jacobian (m, rad).
const STEP: f64 = 1e-6;

/// `start` with its tool frames (and, when `fit_frame`, its measurement frame) fitted by
/// weighted least squares to `measurements`: position rows over `position_sigma`, rotation
/// rows over `rotation_sigma`, measurement `i` weighted by `weights[i]` (empty: all 1). The
/// joint frames keep their nominal values.
pub fn registered_nominal(
    start: &McpcModel,
    measurements: &[Measurement],
    weights: &[f64],
    fit_frame: bool,
    options: &IdentificationOptions,
) -> Result<McpcModel> {
    let tools: Vec<usize> = (0..start.tools().len())
        .filter(|&t| measurements.iter().any(|m| m.tool == t))
        .flat_map(|t| {
            let offset = start.tool_parameter_offset(t);
            offset..offset + 6
        })
        .collect();
    let frame_count = if fit_frame { 6 } else { 0 };
    let unknowns = frame_count + tools.len();
    if unknowns == 0 || measurements.is_empty() {
        return Ok(start.clone());
    }
    let base = start.parameters();
    let frame = start.world_from_base();
    let model_at = |x: &DVector<f64>| -> Result<McpcModel> {
        let mut model = start.clone();
        if fit_frame {
            model.set_world_from_base(&moved(&frame, &x.as_slice()[..6]));
        }
        let mut parameters = base.clone();
        for (k, &p) in tools.iter().enumerate() {
            parameters[p] += x[frame_count + k];
        }
        model.set_parameters(&parameters)?;
        Ok(model)
    };
    // Many rows: the registration's few unknowns are fitted to the evenly spread subsample of
    // whole configurations the identification starts on (`CoarseToFine`), with their weights,
    // and the Jacobian's tool poses move the centre's (one forward kinematics per configuration
    // instead of one per shifted model). Every row is still scored with the result.
    let subsample = CoarseToFine::DEFAULT
        .subsample(measurements)
        .map(|selected| {
            let rows: Vec<Measurement> =
                selected.iter().map(|&i| measurements[i].clone()).collect();
            let weights: Vec<f64> = if weights.is_empty() {
                Vec::new()
            } else {
                selected
                    .iter()
                    .map(|&i| weights.get(i).copied().unwrap_or(1.0))
                    .collect()
            };
            (rows, weights)
        });
    let rows = match &subsample {
        Some((rows, weights)) => Rows {
            measurements: rows,
            weights,
            options,
            centre_poses: true,
        },
        None => Rows {
            measurements,
            weights,
            options,
            centre_poses: false,
        },
    };
    model_at(&levenberg_marquardt(
        DVector::zeros(unknowns),
        &model_at,
        &rows,
    )?)
}

/// The rows a registration is fitted to, their weights (empty: all 1) and σ's.
struct Rows<'a> {
    measurements: &'a [Measurement],
    weights: &'a [f64],
    options: &'a IdentificationOptions,
    /// Whether the Jacobian moves the centre's tool poses ([`centre_jacobian`]) rather than
    /// computing every shifted model's.
    centre_poses: bool,
}

impl Rows<'_> {
    /// The weighted squared residual of every row at `model`, summed block by block in order
    /// (the blocks in parallel: the same sum on any number of threads).
    fn cost(&self, model: &McpcModel) -> f64 {
        let blocks: Vec<(&[Measurement], &[f64])> =
            chunks(self.measurements, self.weights).collect();
        let parts: Vec<f64> = blocks
            .par_iter()
            .map(|(rows, w)| weighted_residual(model, rows, w, self.options).norm_squared())
            .collect();
        parts.into_iter().sum()
    }
}

/// Levenberg–Marquardt from `x` over `rows`, until a step no longer lowers the cost.
fn levenberg_marquardt(
    mut x: DVector<f64>,
    model_at: &dyn Fn(&DVector<f64>) -> Result<McpcModel>,
    rows: &Rows<'_>,
) -> Result<DVector<f64>> {
    let unknowns = x.len();
    let mut cost = rows.cost(&model_at(&x)?);
    let mut damping = 1e-3;
    for _ in 0..MAX_ITERATIONS {
        let (normal, gradient) = normal_equations(&x, unknowns, model_at, rows)?;
        let mut improved = false;
        for _ in 0..12 {
            let scale = normal.diagonal().map(|d| d.max(1e-12));
            let damped = &normal + DMatrix::from_diagonal(&(scale * damping));
            // Position-only tools leave combinations free: the minimum-norm step.
            let svd = damped.svd(true, true);
            let Ok(step) = svd.solve(&(-&gradient), 1e-12 * normal.diagonal().max()) else {
                break;
            };
            let trial = &x + &step;
            let trial_cost = rows.cost(&model_at(&trial)?);
            if trial_cost < cost {
                let decrease = cost - trial_cost;
                x = trial;
                improved = decrease > 1e-12 * cost.max(1e-300);
                cost = trial_cost;
                damping = (damping * 0.3).max(1e-12);
                break;
            }
            damping *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Ok(x)
}

/// Measurements per block of the normal equations: the Jacobian is never held for all rows
/// (10⁵ configurations would keep ~60 MB), only for one block at a time.
const CHUNK: usize = 2048;

/// `measurements` with their weights in blocks of [`CHUNK`] (weights empty: all 1).
fn chunks<'a>(
    measurements: &'a [Measurement],
    weights: &'a [f64],
) -> impl Iterator<Item = (&'a [Measurement], &'a [f64])> {
    measurements
        .chunks(CHUNK)
        .enumerate()
        .map(move |(c, rows)| {
            let from = (c * CHUNK).min(weights.len());
            let to = (from + rows.len()).min(weights.len());
            (rows, &weights[from..to])
        })
}

/// JᵀJ and Jᵀr of the weighted residual at `x`, the Jacobian by central differences,
/// accumulated block by block over the rows (the blocks in parallel, added in order: the same
/// sums on any number of threads).
fn normal_equations(
    x: &DVector<f64>,
    unknowns: usize,
    model_at: &dyn Fn(&DVector<f64>) -> Result<McpcModel>,
    rows: &Rows<'_>,
) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let centre = model_at(x)?;
    let mut shifted = Vec::with_capacity(unknowns);
    for k in 0..unknowns {
        let (mut plus, mut minus) = (x.clone(), x.clone());
        plus[k] += STEP;
        minus[k] -= STEP;
        shifted.push((model_at(&plus)?, model_at(&minus)?));
    }
    let (options, centre_poses) = (rows.options, rows.centre_poses);
    let block = |(rows, w): &(&[Measurement], &[f64])| -> Result<(DMatrix<f64>, DVector<f64>)> {
        let residual = weighted_residual(&centre, rows, w, options);
        let jacobian = if centre_poses {
            centre_jacobian(&centre, &shifted, rows, w, options)
        } else {
            let mut jacobian = DMatrix::zeros(residual.len(), unknowns);
            for (k, (plus, minus)) in shifted.iter().enumerate() {
                let column = (weighted_residual(plus, rows, w, options)
                    - weighted_residual(minus, rows, w, options))
                    / (2.0 * STEP);
                jacobian.set_column(k, &column);
            }
            jacobian
        };
        crate::limits::ensure_finite(jacobian.iter(), "the nominal robot's registration")?;
        Ok((jacobian.tr_mul(&jacobian), jacobian.tr_mul(&residual)))
    };
    let blocks: Vec<(&[Measurement], &[f64])> = chunks(rows.measurements, rows.weights).collect();
    let parts: Vec<Result<(DMatrix<f64>, DVector<f64>)>> = blocks.par_iter().map(block).collect();
    let mut normal = DMatrix::zeros(unknowns, unknowns);
    let mut gradient = DVector::zeros(unknowns);
    for part in parts {
        let (block_normal, block_gradient) = part?;
        normal += block_normal;
        gradient += block_gradient;
    }
    Ok((normal, gradient))
}

/// How a shifted model's tool poses follow from the centre's: `left · pose · right[tool]`
/// (the measurement frame moves on the left, a tool's constant transform on the right).
struct PoseShift {
    left: Pose,
    right: Vec<Pose>,
}

impl PoseShift {
    fn between(centre: &McpcModel, shifted: &McpcModel) -> PoseShift {
        let right = centre
            .tools()
            .iter()
            .zip(shifted.tools())
            .map(|(c, s)| c.constant_transform().inverse() * s.constant_transform())
            .collect();
        PoseShift {
            left: shifted.world_from_base() * centre.world_from_base().inverse(),
            right,
        }
    }
}

/// The central-difference Jacobian of [`weighted_residual`] with every shifted model's tool
/// pose moved from the centre's ([`PoseShift`]): one forward kinematics per configuration.
/// The same rows as the centre's residual.
fn centre_jacobian(
    centre: &McpcModel,
    shifted: &[(McpcModel, McpcModel)],
    measurements: &[Measurement],
    weights: &[f64],
    options: &IdentificationOptions,
) -> DMatrix<f64> {
    let shifts: Vec<(PoseShift, PoseShift)> = shifted
        .iter()
        .map(|(plus, minus)| {
            (
                PoseShift::between(centre, plus),
                PoseShift::between(centre, minus),
            )
        })
        .collect();
    let noise = options.noise();
    let mut columns: Vec<Vec<f64>> = vec![Vec::with_capacity(measurements.len() * 6); shifts.len()];
    let mut cached: Option<(&[f64], Vec<Pose>)> = None;
    let (mut error, mut plus_error, mut minus_error) = (Vec::new(), Vec::new(), Vec::new());
    let mut moved = Vec::new();
    for (i, m) in measurements.iter().enumerate() {
        if cached.as_ref().is_none_or(|(q, _)| *q != m.q.as_slice()) {
            cached = Some((m.q.as_slice(), centre.tool_poses(&m.q)));
        }
        let poses = cached.as_ref().map_or(&[][..], |(_, p)| p.as_slice());
        if m.tool >= poses.len() {
            continue;
        }
        let w = weights.get(i).copied().unwrap_or(1.0).max(0.0).sqrt();
        let kind = kind_of(&m.observation);
        error.resize(kind.rows(), 0.0);
        if kind.residual(&state(centre, m, poses), &mut error).is_err() {
            continue;
        }
        plus_error.resize(kind.rows(), 0.0);
        minus_error.resize(kind.rows(), 0.0);
        for (k, ((plus, minus), (plus_shift, minus_shift))) in
            shifted.iter().zip(&shifts).enumerate()
        {
            moved.clear();
            moved.extend_from_slice(poses);
            moved[m.tool] = plus_shift.left * poses[m.tool] * plus_shift.right[m.tool];
            let plus_ok = kind
                .residual(&state(plus, m, &moved), &mut plus_error)
                .is_ok();
            moved[m.tool] = minus_shift.left * poses[m.tool] * minus_shift.right[m.tool];
            let minus_ok = kind
                .residual(&state(minus, m, &moved), &mut minus_error)
                .is_ok();
            for ((p, n), row_kind) in plus_error.iter().zip(&minus_error).zip(kind.row_kinds()) {
                let value = match plus_ok && minus_ok {
                    true => w * (p - n) / noise.sigma(*row_kind) / (2.0 * STEP),
                    false => 0.0,
                };
                columns[k].push(value);
            }
        }
    }
    let rows = columns.first().map_or(0, Vec::len);
    DMatrix::from_fn(rows, columns.len(), |r, c| columns[c][r])
}

/// The robot state of measurement `m` with the tool poses `poses`.
fn state<'a>(model: &'a McpcModel, m: &'a Measurement, poses: &'a [Pose]) -> RobotState<'a> {
    RobotState {
        model,
        q: &m.q,
        tool: m.tool,
        tools: Tools::Poses(poses),
        offset: None,
        nuisance: Nuisance::none(),
    }
}

/// `frame` moved by `delta` = (translation, rotation vector) in the measurement frame, turned
/// about its own origin.
fn moved(frame: &Pose, delta: &[f64]) -> Pose {
    let rotation = UnitQuaternion::from_scaled_axis(Vector3::new(delta[3], delta[4], delta[5]));
    let origin = frame.translation.vector + Vector3::new(delta[0], delta[1], delta[2]);
    Pose::from_parts(origin.into(), rotation * frame.rotation)
}

/// The residual rows of every measurement at `model` (rigid), over the σ's and weighted.
fn weighted_residual(
    model: &McpcModel,
    measurements: &[Measurement],
    weights: &[f64],
    options: &IdentificationOptions,
) -> DVector<f64> {
    let mut rows = Vec::with_capacity(measurements.len() * 6);
    let mut cached: Option<(&[f64], Vec<Pose>)> = None;
    let noise = options.noise();
    let mut error = Vec::new();
    for (i, m) in measurements.iter().enumerate() {
        if cached.as_ref().is_none_or(|(q, _)| *q != m.q.as_slice()) {
            cached = Some((m.q.as_slice(), model.tool_poses(&m.q)));
        }
        if cached.as_ref().is_none_or(|(_, p)| m.tool >= p.len()) {
            continue;
        }
        let w = weights.get(i).copied().unwrap_or(1.0).max(0.0).sqrt();
        let kind = kind_of(&m.observation);
        let at = RobotState {
            model,
            q: &m.q,
            tool: m.tool,
            tools: Tools::Poses(cached.as_ref().map_or(&[][..], |(_, p)| p.as_slice())),
            offset: None,
            nuisance: Nuisance::none(),
        };
        error.resize(kind.rows(), 0.0);
        if kind.residual(&at, &mut error).is_err() {
            continue;
        }
        for (e, row_kind) in error.iter().zip(kind.row_kinds()) {
            rows.push(w * e / noise.sigma(*row_kind));
        }
    }
    DVector::from_vec(rows)
}
