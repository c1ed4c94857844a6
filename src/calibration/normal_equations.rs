//! Streamed normal equations: `JᵀWJ`, `JᵀWr` and `½‖r‖²` accumulated configuration by
//! configuration instead of stacking the whole Jacobian (issue 14).
//!
//! The measurements are cut into chunks of about [`CHUNK_ROWS`] rows, always between
//! configurations (so that the tools of one configuration share one evaluation, as in the
//! stacked form). Each chunk is linearised on its own (`solver::linearise` on the sub-slice, a
//! few hundred rows that stay in cache), and its products are added to the totals. Chunks are
//! evaluated in parallel, [`WINDOW`] at a time, and their products added in chunk order: the
//! chunking depends on the data only, so the sums — and every result — are the same on any
//! number of threads. Memory is `O(p²)` plus one chunk per thread, not `O(N·p)`.
//!
//! Near rank deficiency the solver needs the singular vectors of the column-scaled Jacobian
//! to a precision that squaring into `JᵀJ` loses. For that the triangle `R` of `J = Q·R` is
//! streamed too (a sequential TSQR: each chunk's `R` is stacked under the running one and
//! re-factorised), on request only: `RᵀR = JᵀJ`, and `R·S⁻¹` is the triangle of the scaled
//! Jacobian `J·S⁻¹`, so the QR + SVD decision is the one the stacked form made.
//! See `docs/identification.md` and `docs/performance.md`.

use super::linearise::linearise_into;
use super::observation::Nuisance;
use super::options::IdentificationOptions;
use super::predictor::Predictor;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::measurement::Measurement;
use nalgebra::{DMatrix, DMatrixView, DVector, Vector6};
use rayon::prelude::*;
use std::ops::Range;

mod memo;
pub(crate) use memo::ProductsMemo;

/// Rows per chunk (at least; a chunk ends at the next change of configuration). 192 rows of
/// 64 columns are 96 KiB: a chunk's Jacobian stays in the core's L2 cache.
pub(super) const CHUNK_ROWS: usize = 192;

/// Chunks evaluated in parallel before their products are added (in chunk order).
pub(super) const WINDOW: usize = 16;

/// What to accumulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Products {
    /// The cost only (a trial step).
    Cost,
    /// Cost, `JᵀWJ` and `JᵀWr`.
    Normal,
    /// Also the triangle `R` of the weighted Jacobian (rank-deficient problems).
    NormalAndFactor,
}

/// The products of the weighted Jacobian `J` (free columns, rows divided by their σ) and the
/// weighted residual `r` over all measurements.
#[derive(Debug, Clone)]
pub(super) struct NormalEquations {
    /// `JᵀJ` (p × p; 0 × 0 for [`Products::Cost`]).
    pub normal: DMatrix<f64>,
    /// `Jᵀr`.
    pub gradient: DVector<f64>,
    /// `½‖r‖²`.
    pub cost: f64,
    /// The upper triangle `R` of `J = Q·R` (p × p, zero rows appended when `J` has fewer
    /// rows), for [`Products::NormalAndFactor`].
    pub factor: Option<DMatrix<f64>>,
}

impl NormalEquations {
    fn zeros(columns: usize, products: Products) -> Self {
        let size = if products == Products::Cost {
            0
        } else {
            columns
        };
        Self {
            normal: DMatrix::zeros(size, size),
            gradient: DVector::zeros(size),
            cost: 0.0,
            factor: (products == Products::NormalAndFactor).then(|| DMatrix::zeros(0, columns)),
        }
    }

    /// Adds one chunk's products (TSQR step for the factor).
    fn add(&mut self, part: NormalEquations) {
        self.cost += part.cost;
        self.normal += part.normal;
        self.gradient += part.gradient;
        if let (Some(total), Some(next)) = (self.factor.as_mut(), part.factor) {
            *total = stacked_triangle(total, &next);
        }
    }
}

/// `target += AᵀA` through nalgebra's `gemm` on a transposed view of `A` (no copy), which
/// hands the product to the `matrixmultiply` kernel (blocked, vectorised, stride-aware);
/// `tr_mul` takes one dot product per element instead (8× slower on a 192 × 64 chunk, see
/// `docs/performance.md`). Small matrices take `tr_mul`: nalgebra 0.35 sends products with a
/// side of 5 or less to its own loops, which assume contiguous columns and must not see the
/// strided view.
pub(crate) fn add_gram(target: &mut DMatrix<f64>, a: &DMatrix<f64>) {
    const SMALL: usize = 16;
    let (rows, columns) = a.shape();
    if rows <= SMALL || columns <= SMALL {
        *target += a.tr_mul(a);
        return;
    }
    let transposed = DMatrixView::from_slice_with_strides(a.as_slice(), columns, rows, rows, 1);
    target.gemm(1.0, &transposed, a, 1.0);
}

/// `target += JᵀJ` for the weighted Jacobian `J` of `measurements`, one tool at a time over
/// only the columns that tool's rows touch: on a branched robot a tool's rows are zero in the
/// other branches' columns (on Robonaut each tool touches 38 or 34 of the 64), so the products
/// cost about a third of the dense `JᵀJ`. Columns are dropped only where every row of the
/// tool is exactly zero, which adds nothing to the sums, so any predictor's Jacobian is
/// handled; the sums are the dense product's in another order (equal to round-off).
pub(crate) fn add_grouped_gram(
    target: &mut DMatrix<f64>,
    jacobian: &DMatrix<f64>,
    measurements: &[Measurement],
) {
    // The row ranges of each tool, in order of first appearance.
    let mut groups: Vec<(usize, Vec<Range<usize>>, usize)> = Vec::new();
    let mut row = 0;
    for m in measurements {
        let rows = row..row + m.observation.rows();
        row = rows.end;
        match groups.iter_mut().find(|(tool, _, _)| *tool == m.tool) {
            Some((_, ranges, count)) => {
                *count += rows.len();
                ranges.push(rows);
            }
            None => groups.push((m.tool, vec![rows.clone()], rows.len())),
        }
    }
    let height = jacobian.nrows();
    let data = jacobian.as_slice();
    let column = |c: usize| &data[c * height..(c + 1) * height];
    for (_, ranges, count) in &groups {
        let columns: Vec<usize> = (0..jacobian.ncols())
            .filter(|&c| {
                let values = column(c);
                ranges
                    .iter()
                    .any(|r| values[r.clone()].iter().any(|v| *v != 0.0))
            })
            .collect();
        if *count == height && columns.len() == jacobian.ncols() {
            add_gram(target, jacobian);
            continue;
        }
        let mut packed = DMatrix::zeros(*count, columns.len());
        for (to, &from) in packed
            .as_mut_slice()
            .chunks_exact_mut((*count).max(1))
            .zip(&columns)
        {
            let mut start = 0;
            for r in ranges {
                to[start..start + r.len()].copy_from_slice(&column(from)[r.clone()]);
                start += r.len();
            }
        }
        let mut gram = DMatrix::zeros(columns.len(), columns.len());
        add_gram(&mut gram, &packed);
        for (j, &to_j) in columns.iter().enumerate() {
            for (i, &to_i) in columns.iter().enumerate() {
                target[(to_i, to_j)] += gram[(i, j)];
            }
        }
    }
}

/// The triangle of `[top; bottom]` (at most `columns` rows).
fn stacked_triangle(top: &DMatrix<f64>, bottom: &DMatrix<f64>) -> DMatrix<f64> {
    let columns = top.ncols();
    let mut stacked = DMatrix::zeros(top.nrows() + bottom.nrows(), columns);
    stacked.rows_mut(0, top.nrows()).copy_from(top);
    stacked
        .rows_mut(top.nrows(), bottom.nrows())
        .copy_from(bottom);
    triangle(stacked)
}

/// `R` of `A = Q·R`: min(rows, columns) × columns.
fn triangle(a: DMatrix<f64>) -> DMatrix<f64> {
    if a.nrows() == 0 {
        return a;
    }
    a.qr().r()
}

/// Consecutive measurement ranges of at least [`CHUNK_ROWS`] rows, cut only where the
/// configuration changes.
pub(super) fn chunks(measurements: &[Measurement]) -> Vec<Range<usize>> {
    let mut ranges = Vec::new();
    let (mut start, mut rows) = (0, 0);
    for (index, m) in measurements.iter().enumerate() {
        if rows >= CHUNK_ROWS && m.q != measurements[index - 1].q {
            ranges.push(start..index);
            (start, rows) = (index, 0);
        }
        rows += m.observation.rows();
    }
    if start < measurements.len() {
        ranges.push(start..measurements.len());
    }
    ranges
}

/// Everything [`accumulate`] needs besides the model.
#[derive(Clone, Copy)]
pub(super) struct Problem<'a> {
    /// The measurements, in the caller's order.
    pub measurements: &'a [Measurement],
    /// One flexibility offset per measurement, if any.
    pub offsets: Option<&'a [Vector6<f64>]>,
    /// How the model predicts the tool poses.
    pub predictor: &'a dyn Predictor,
    /// Indices of the free parameters (the columns of `J`).
    pub free: &'a [usize],
    /// Row weights (σ's).
    pub options: &'a IdentificationOptions,
    /// The prior's rows over the free parameters, if any.
    pub prior: Option<&'a super::prior::PriorRows>,
    /// The last products over these measurements, to be updated where only some robust
    /// weights changed ([`ProductsMemo`]).
    pub memo: Option<&'a ProductsMemo<'a>>,
}

std::thread_local! {
    /// The storage of this thread's last chunk Jacobian, for its next chunk
    /// ([`linearise_into`]).
    static SPARE_JACOBIAN: std::cell::Cell<Vec<f64>> = const { std::cell::Cell::new(Vec::new()) };
}

/// The products of one chunk.
fn chunk_products(
    model: &McpcModel,
    nuisance: &Nuisance,
    problem: &Problem<'_>,
    range: Range<usize>,
    products: Products,
) -> Result<NormalEquations> {
    // The chunk's rows are its measurements', so its observation weights (robust estimation)
    // are theirs too: linearise indexes the weights by position in the slice it gets.
    let sliced;
    let options = if problem.options.observation_weights.is_empty() {
        problem.options
    } else {
        sliced = problem.options.for_range(range.clone());
        &sliced
    };
    let lin = linearise_into(
        model,
        nuisance,
        &problem.measurements[range.clone()],
        problem.offsets.map(|o| &o[range.clone()]),
        problem.predictor,
        problem.free,
        options,
        products != Products::Cost,
        match products {
            Products::Cost => Vec::new(),
            _ => SPARE_JACOBIAN.take(),
        },
    )?;
    let cost = 0.5 * lin.residual.norm_squared();
    if products == Products::Cost {
        return Ok(NormalEquations {
            cost,
            ..NormalEquations::zeros(problem.free.len(), products)
        });
    }
    // As many columns as the linearisation has (the free parameters, and any a caller adds).
    let columns = lin.jacobian.ncols();
    let mut normal = DMatrix::zeros(columns, columns);
    add_grouped_gram(
        &mut normal,
        &lin.jacobian,
        &problem.measurements[range.clone()],
    );
    let gradient = lin.jacobian.tr_mul(&lin.residual);
    let factor = match products {
        Products::NormalAndFactor => Some(triangle(lin.jacobian)),
        _ => {
            SPARE_JACOBIAN.set(lin.jacobian.data.into());
            None
        }
    };
    Ok(NormalEquations {
        normal,
        gradient,
        cost,
        factor,
    })
}

/// `JᵀWJ`, `JᵀWr`, `½‖r‖²` (and `R` on request) of `problem` at `model`, streamed over
/// chunks in parallel and added in a fixed order (deterministic on any number of threads).
#[cfg(test)]
pub(super) fn accumulate(
    model: &McpcModel,
    problem: &Problem<'_>,
    products: Products,
) -> Result<NormalEquations> {
    accumulate_with(model, Nuisance::none(), problem, products)
}

/// [`accumulate`] at nuisance values `nuisance` (the free columns past the model's parameters
/// are its values).
pub(super) fn accumulate_with(
    model: &McpcModel,
    nuisance: &Nuisance,
    problem: &Problem<'_>,
    products: Products,
) -> Result<NormalEquations> {
    let updated = problem
        .memo
        .and_then(|memo| memo.updated(model, nuisance, problem, products));
    let mut total = match updated {
        Some(products) => products?,
        None => streamed(model, nuisance, problem, products)?,
    };
    if let Some(memo) = problem.memo {
        memo.record(model, nuisance, problem, &total);
    }
    if let Some(prior) = problem.prior {
        add_prior(&mut total, model, nuisance, problem.free, prior);
    }
    let columns = total.gradient.len().max(problem.free.len());
    if let Some(factor) = total.factor.as_mut() {
        if factor.nrows() < columns {
            *factor = factor.clone().resize_vertically(columns, 0.0);
        }
    }
    Ok(total)
}

/// The products of every chunk of `problem`, added in chunk order (no prior).
fn streamed(
    model: &McpcModel,
    nuisance: &Nuisance,
    problem: &Problem<'_>,
    products: Products,
) -> Result<NormalEquations> {
    let mut total: Option<NormalEquations> = None;
    for window in chunks(problem.measurements).chunks(WINDOW) {
        let parts: Vec<Result<NormalEquations>> = window
            .par_iter()
            .map(|range| chunk_products(model, nuisance, problem, range.clone(), products))
            .collect();
        for part in parts {
            let part = part?;
            match total.as_mut() {
                Some(total) => total.add(part),
                None => total = Some(part),
            }
        }
    }
    Ok(total.unwrap_or_else(|| NormalEquations::zeros(problem.free.len(), products)))
}

/// Adds the prior rows `√w·(θ₀ − θ)` (Jacobian `√w` on their own column) to the products.
fn add_prior(
    total: &mut NormalEquations,
    model: &McpcModel,
    nuisance: &Nuisance,
    free: &[usize],
    prior: &super::prior::PriorRows,
) {
    let mut values = model.parameters();
    values.extend(nuisance.values());
    let with_normal = total.normal.nrows() == free.len() && !free.is_empty();
    let mut rows = Vec::new();
    for (k, &p) in free.iter().enumerate() {
        let weight = prior.weights[k];
        if weight <= 0.0 {
            continue;
        }
        let Some(&value) = values.get(p) else {
            continue;
        };
        let difference = prior.centers[k] - value;
        total.cost += 0.5 * weight * difference * difference;
        if with_normal {
            total.normal[(k, k)] += weight;
            total.gradient[k] += weight * difference;
        }
        rows.push((k, weight.sqrt()));
    }
    if let Some(factor) = total.factor.as_mut() {
        let mut extra = DMatrix::zeros(rows.len(), free.len());
        for (row, (k, value)) in rows.into_iter().enumerate() {
            extra[(row, k)] = value;
        }
        *factor = stacked_triangle(factor, &extra);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::linearise::{linearise, Linearisation};
    use crate::calibration::predictor::Rigid;
    use crate::calibration::test_problems::{problem, robonaut};

    fn relative(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (a - b).amax() / b.amax()
    }

    #[test]
    fn streamed_products_equal_the_stacked_ones() {
        let robot = robonaut();
        let model = &robot.0;
        let options = IdentificationOptions::default();
        let free: Vec<usize> = (0..model.parameter_count()).step_by(2).collect();
        for (configurations, poses) in [(3, true), (700, true), (300, false)] {
            let measurements = problem(&robot, configurations, poses);
            let problem = Problem {
                measurements: &measurements,
                offsets: None,
                predictor: &Rigid,
                free: &free,
                options: &options,
                prior: None,
                memo: None,
            };
            let (stacked, streamed) =
                streamed_and_stacked(model, &problem, Products::NormalAndFactor);
            let normal = stacked.jacobian.tr_mul(&stacked.jacobian);
            let cost_only = accumulate(model, &problem, Products::Cost).expect("cost");
            assert_eq!(cost_only.cost, streamed.cost);
            // RᵀR = JᵀJ, and R has J's singular values (to round-off).
            let factor = streamed.factor.expect("factor");
            assert_eq!(factor.shape(), (free.len(), free.len()));
            assert!(relative(&factor.tr_mul(&factor), &normal) < 1e-12);
            let ours = factor.singular_values();
            let reference = stacked.jacobian.singular_values();
            for (a, b) in ours.iter().zip(reference.iter()) {
                assert!((a - b).abs() < 1e-10 * reference[0], "{a} vs {b}");
            }
        }
    }

    /// Robust weights (some 0) follow their measurements into every chunk: the streamed
    /// products equal the stacked ones over several chunks.
    #[test]
    fn observation_weights_follow_the_measurements_into_every_chunk() {
        let robot = robonaut();
        let model = &robot.0;
        let measurements = problem(&robot, 120, true);
        assert!(chunks(&measurements).len() > 2);
        let options = IdentificationOptions {
            observation_weights: (0..measurements.len())
                .map(|i| [1.0, 0.0, 0.25, 1.0, 0.7][i % 5])
                .collect(),
            ..Default::default()
        };
        let free: Vec<usize> = (0..model.parameter_count()).collect();
        let problem = Problem {
            measurements: &measurements,
            offsets: None,
            predictor: &Rigid,
            free: &free,
            options: &options,
            prior: None,
            memo: None,
        };
        streamed_and_stacked(model, &problem, Products::Normal);
    }

    /// The streamed products of `problem` and the stacked linearisation, after checking that
    /// they agree on JᵀJ, Jᵀr and the cost (to 1e-12 relative).
    fn streamed_and_stacked(
        model: &McpcModel,
        problem: &Problem<'_>,
        products: Products,
    ) -> (Linearisation, NormalEquations) {
        let stacked = linearise(
            model,
            Nuisance::none(),
            problem.measurements,
            None,
            &Rigid,
            problem.free,
            problem.options,
            true,
        )
        .expect("linearise");
        let normal = stacked.jacobian.tr_mul(&stacked.jacobian);
        let streamed = accumulate(model, problem, products).expect("accumulate");
        assert!(relative(&streamed.normal, &normal) < 1e-12);
        let gradient = stacked.jacobian.tr_mul(&stacked.residual);
        assert!((&streamed.gradient - &gradient).amax() < 1e-12 * gradient.amax());
        let cost = 0.5 * stacked.residual.norm_squared();
        assert!((streamed.cost - cost).abs() < 1e-12 * cost);
        (stacked, streamed)
    }

    #[test]
    fn chunks_cover_everything_and_cut_between_configurations() {
        let measurements = problem(&robonaut(), 250, true);
        let ranges = chunks(&measurements);
        assert!(ranges.len() > 2);
        assert_eq!(ranges[0].start, 0);
        assert_eq!(ranges.last().map(|r| r.end), Some(measurements.len()));
        for pair in ranges.windows(2) {
            assert_eq!(pair[0].end, pair[1].start);
            let (before, after) = (&measurements[pair[0].end - 1], &measurements[pair[1].start]);
            assert_ne!(before.q, after.q);
        }
        assert!(chunks(&[]).is_empty());
    }

    #[test]
    fn sums_do_not_depend_on_the_thread_count() {
        let robot = robonaut();
        let model = &robot.0;
        let options = IdentificationOptions::default();
        let free: Vec<usize> = (0..model.parameter_count()).collect();
        let measurements = problem(&robot, 400, true);
        let problem = Problem {
            measurements: &measurements,
            offsets: None,
            predictor: &Rigid,
            free: &free,
            options: &options,
            prior: None,
            memo: None,
        };
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool")
                .install(|| accumulate(model, &problem, Products::NormalAndFactor))
                .expect("accumulate")
        };
        let (one, three) = (on(1), on(3));
        assert_eq!(one.normal, three.normal);
        assert_eq!(one.gradient, three.gradient);
        assert_eq!(one.cost, three.cost);
        assert_eq!(one.factor, three.factor);
    }
}
