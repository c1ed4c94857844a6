//! The stacked, weighted residual and its Jacobian over the free parameters, through the
//! observation seam (`calibration::observation`): what the solver and the streamed normal
//! equations linearise.

use super::observation::{kind_of, squares_by_row_kind, Nuisance, RobotState, Tools};
use super::options::IdentificationOptions;
use super::predictor::{Cached, Predictor};
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::Pose;
use crate::measurement::Measurement;
use nalgebra::{DMatrix, DVector, Vector6};
use rayon::prelude::*;
use std::ops::Range;

/// The stacked, weighted residual and its Jacobian over the free parameters.
pub(super) struct Linearisation {
    pub(super) residual: DVector<f64>,
    pub(super) jacobian: DMatrix<f64>,
}

pub(super) fn rows_of(measurements: &[Measurement]) -> usize {
    measurements.iter().map(|m| m.observation.rows()).sum()
}

/// The weighted residual of every measurement (each row over its σ, [`Noise`](super::observation::Noise)) under
/// `predictor` at `model`: the vector whose half squared norm [`identify`](super::solver::identify) minimises.
pub fn weighted_residual(
    model: &McpcModel,
    measurements: &[Measurement],
    predictor: &dyn Predictor,
    options: &IdentificationOptions,
) -> Result<DVector<f64>> {
    Ok(linearise(
        model,
        Nuisance::none(),
        measurements,
        None,
        predictor,
        &[],
        options,
        false,
    )?
    .residual)
}

/// The weighted Jacobian `W·J` over the `free` parameters (flat indices: the model's, then
/// `nuisance`'s values) and the weighted residual at `model` and `nuisance`: what the solver
/// linearises, for analyses outside it (simulation's observable subspace, tests).
pub fn weighted_jacobian(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let lin = linearise(
        model,
        nuisance,
        measurements,
        None,
        predictor,
        free,
        options,
        true,
    )?;
    Ok((lin.jacobian, lin.residual))
}

/// The stacked residual `W·r` and, `with_jacobian`, its Jacobian `W·J` over the `free`
/// parameters, through the observation seam: each measurement's kind gives its unweighted
/// residual and Jacobian rows from the robot state the predictor evaluated (once per
/// configuration and payload, shared by the rows measured there), and each row is multiplied
/// by `√w_i / σ` of its row kind.
#[allow(clippy::too_many_arguments)]
pub(super) fn linearise(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
    with_jacobian: bool,
) -> Result<Linearisation> {
    linearise_into(
        model,
        nuisance,
        measurements,
        offsets,
        predictor,
        free,
        options,
        with_jacobian,
        Vec::new(),
    )
}

/// [`linearise`], the Jacobian written into `spare` (the storage of an earlier one, reused
/// without zeroing: every entry is written below), so that the chunks of a pass on one
/// thread do not each allocate and zero their Jacobian.
#[allow(clippy::too_many_arguments)]
pub(super) fn linearise_into(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
    with_jacobian: bool,
    mut spare: Vec<f64>,
) -> Result<Linearisation> {
    let rows = rows_of(measurements);
    let mut residual = DVector::zeros(rows);
    let height = if with_jacobian { rows } else { 0 };
    // Each measurement's block below writes its rows of every column: the stale values
    // `spare` keeps are all overwritten.
    spare.resize(height * free.len(), 0.0);
    let mut jacobian = DMatrix::from_vec(height, free.len(), spare);
    let noise = options.noise();
    let mut row = 0;
    // Measurements of several tools at one configuration share one evaluation.
    // Keyed by configuration and payload.
    let (mut jacobians, mut jacobians_at) = (Vec::new(), None);
    let mut cached_poses: Cached<'_, Vec<Pose>> = None;
    let (mut block, mut weights) = (DMatrix::zeros(0, 0), Vec::new());
    for (index, m) in measurements.iter().enumerate() {
        let kind = kind_of(&m.observation);
        let count = kind.rows();
        let key = (m.q.as_slice(), m.payload);
        let tools = if with_jacobian {
            if jacobians_at != Some(key) {
                predictor.jacobians_for_into(model, &m.q, m.payload, free, &mut jacobians)?;
                jacobians_at = Some(key);
            }
            Tools::Jacobians(&jacobians)
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
            nuisance,
        };
        // Multiplying by exactly 1.0 keeps unweighted problems bit for bit as before.
        let observation = options
            .observation_weights
            .get(index)
            .map_or(1.0, |w| w.sqrt());
        let weight = |row_kind| (1.0 / noise.sigma(row_kind)) * observation;
        if with_jacobian {
            // Written and weighted in a small block (in cache), then copied once into the
            // tall matrix, whose rows are a column's length apart.
            if block.shape() != (count, free.len()) {
                block = DMatrix::zeros(count, free.len());
            } else {
                block.as_mut_slice().fill(0.0);
            }
            kind.jacobian(
                &state,
                free,
                &mut block.view_mut((0, 0), (count, free.len())),
            )?;
            weights.clear();
            weights.extend(kind.row_kinds().iter().map(|&k| weight(k)));
            let tall = jacobian.as_mut_slice();
            for (column, from) in block.as_slice().chunks_exact(count).enumerate() {
                let to = &mut tall[column * rows + row..][..count];
                for ((to, from), weight) in to.iter_mut().zip(from).zip(&weights) {
                    *to = from * weight;
                }
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

/// RMS of the position residuals (m) and of the rotation residuals (rad, over kinds with
/// rotation rows) at `model`, over the measurements not left out. The rows' squares are
/// computed in parallel ([`map_rows_in_order`]) and summed in row order: the same sums on any
/// number of threads, and as a sequential loop's.
pub(super) fn residual_rms(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    offsets: Option<&[Vector6<f64>]>,
    predictor: &dyn Predictor,
    options: &IdentificationOptions,
) -> Result<(f64, f64)> {
    let (mut position, mut rotation, mut poses, mut count) = (0.0, 0.0, 0usize, 0usize);
    let part = |range: Range<usize>| -> Result<Vec<[Option<f64>; 2]>> {
        let mut error = Vec::new();
        let mut squares = Vec::with_capacity(range.len());
        // Measurements of several tools at one configuration share one prediction (as in
        // `linearise`).
        let mut cached: Cached<'_, Vec<Pose>> = None;
        for index in range {
            // Measurements left out (weight 0, robust estimation) are not part of the fit.
            if options.observation_weights.get(index) == Some(&0.0) {
                continue;
            }
            let m = &measurements[index];
            let key = (m.q.as_slice(), m.payload);
            if cached.as_ref().is_none_or(|(k, _)| *k != key) {
                cached = Some((key, predictor.predict_at(model, &m.q, m.payload)?));
            }
            let predicted = cached.as_ref().map_or(&[][..], |(_, p)| p.as_slice());
            let kind = kind_of(&m.observation);
            let state = RobotState {
                model,
                q: &m.q,
                tool: m.tool,
                tools: Tools::Poses(predicted),
                offset: offsets.map(|o| &o[index]),
                nuisance,
            };
            error.resize(kind.rows(), 0.0);
            kind.residual(&state, &mut error)?;
            let by_kind = squares_by_row_kind(kind, &error);
            // Position and rotation rows (`RowKind::ALL`'s first two).
            squares.push([by_kind[0], by_kind[1]]);
        }
        Ok(squares)
    };
    map_rows_in_order(
        measurements.len(),
        part,
        |[position_squares, rotation_squares]| {
            count += 1;
            position += position_squares.unwrap_or(0.0);
            if let Some(squares) = rotation_squares {
                rotation += squares;
                poses += 1;
            }
        },
    )?;
    let n = count.max(1) as f64;
    let rotation_rms = if poses > 0 {
        (rotation / poses as f64).sqrt()
    } else {
        0.0
    };
    Ok(((position / n).sqrt(), rotation_rms))
}

/// Rows per part of [`map_rows_in_order`]: fixed, so that the parts do not depend on the
/// number of threads.
const MAP_PART_ROWS: usize = 4096;

/// Parts of [`map_rows_in_order`] mapped in parallel before they are folded (bounds what is
/// held at once).
const MAP_WINDOW: usize = 16;

/// `map` over consecutive parts of the rows `0..rows` (fixed boundaries) on rayon's workers, a
/// window of parts at a time; `fold` then takes every part's values in row order on the
/// calling thread, so that what it sums is summed as by a sequential loop. The first error
/// in row order is returned (a part stops at its first).
pub(crate) fn map_rows_in_order<T: Send>(
    rows: usize,
    map: impl Fn(Range<usize>) -> Result<Vec<T>> + Sync,
    mut fold: impl FnMut(T),
) -> Result<()> {
    let parts: Vec<Range<usize>> = (0..rows)
        .step_by(MAP_PART_ROWS)
        .map(|start| start..(start + MAP_PART_ROWS).min(rows))
        .collect();
    for window in parts.chunks(MAP_WINDOW) {
        let mapped: Vec<Result<Vec<T>>> = window.par_iter().map(|r| map(r.clone())).collect();
        for part in mapped {
            part?.into_iter().for_each(&mut fold);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    /// A reused Jacobian's stale values (NaN here, and longer or shorter than needed) are all
    /// overwritten: the same matrix as a fresh one, bit for bit, for poses and positions.
    #[test]
    fn a_reused_jacobian_is_a_fresh_one() {
        use crate::calibration::predictor::Rigid;
        use crate::calibration::test_problems::{problem, robonaut};
        let robot = robonaut();
        let model = &robot.0;
        let options = IdentificationOptions::default();
        let free: Vec<usize> = (0..model.parameter_count()).step_by(3).collect();
        for poses in [true, false] {
            let measurements = problem(&robot, 40, poses);
            let fresh = linearise(
                model,
                Nuisance::none(),
                &measurements,
                None,
                &Rigid,
                &free,
                &options,
                true,
            )
            .expect("fresh");
            let size = fresh.jacobian.len();
            for spare_len in [size / 2, size, 2 * size] {
                let reused = linearise_into(
                    model,
                    Nuisance::none(),
                    &measurements,
                    None,
                    &Rigid,
                    &free,
                    &options,
                    true,
                    vec![f64::NAN; spare_len],
                )
                .expect("reused");
                assert_eq!(reused.jacobian, fresh.jacobian);
                assert_eq!(reused.residual, fresh.residual);
            }
        }
    }

    /// Over several windows of parts: every row once, in order, on any number of threads; a
    /// failure gives the error of the earliest failing row, even when a later part (in an
    /// earlier window) fails too.
    #[test]
    fn rows_are_folded_in_order_and_the_first_error_wins() {
        let rows = MAP_PART_ROWS * MAP_WINDOW * 2 + 17;
        let mut seen = Vec::new();
        map_rows_in_order(rows, |range| Ok(range.collect()), |row| seen.push(row))
            .expect("nothing fails");
        assert_eq!(seen, (0..rows).collect::<Vec<usize>>());
        let failing = [MAP_PART_ROWS * MAP_WINDOW + 5, MAP_PART_ROWS * 3 + 1];
        let mut folded = 0;
        let result = map_rows_in_order(
            rows,
            |range| {
                range
                    .map(|row| match failing.contains(&row) {
                        true => Err(Error::InvalidData {
                            origin: row.to_string(),
                            message: "fails".into(),
                        }),
                        false => Ok(row),
                    })
                    .collect()
            },
            |_| folded += 1,
        );
        match result {
            Err(Error::InvalidData { origin, .. }) => {
                assert_eq!(origin, failing[1].to_string())
            }
            other => panic!("expected the earlier row's error, got {other:?}"),
        }
        // The parts before the failing one were folded, none after it.
        assert_eq!(folded, MAP_PART_ROWS * 3);
    }
}
