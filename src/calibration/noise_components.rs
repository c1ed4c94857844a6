//! The noise model from the data: one variance component per row kind (position, rotation),
//! estimated from a fit's residuals with the degrees of freedom split by each kind's share of
//! the hat matrix (Helmert / Förstner), so the σ ratio between the kinds is the data's rather
//! than the declared guess. See `docs/identification.md`, "Noise model from the data".

use super::linear_algebra::floored_scales;
use super::linearise::weighted_jacobian;
use super::observation::{kind_of, Nuisance, RowKind};
use super::options::IdentificationOptions;
use super::predictor::Predictor;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::measurement::Measurement;
use nalgebra::{DMatrix, SymmetricEigen};
use serde::Serialize;

/// Reweighting rounds at most (each a calibration).
pub const MAX_NOISE_ROUNDS: usize = 6;

/// The rounds stop when the estimated σ ratio of two kinds changes by less than this
/// (relative).
pub const NOISE_RATIO_TOLERANCE: f64 = 0.01;

/// Eigenvalues of the scaled normal matrix below this times the largest are a null direction
/// (the solver's rank tolerance 1e-8, squared).
const EIGEN_TOLERANCE: f64 = 1e-16;

/// One row kind's variance component at a fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseComponent {
    /// The row kind (`position`, `rotation`).
    #[serde(serialize_with = "kind_name")]
    pub kind: RowKind,
    /// Rows of this kind in the fit (measurements left out not counted).
    pub rows: usize,
    /// Its redundancy: rows minus its share of the hat matrix (`Σ hᵢᵢ` over its rows) minus
    /// its share of the session frame blocks.
    pub redundancy: f64,
    /// The σ the fit assumed for it (m or rad).
    pub assumed_sigma: f64,
    /// `σ̂_g = √(Σ rᵢ² / redundancy)` of its weighted rows: its residuals against the assumed σ.
    pub scale: f64,
}

impl NoiseComponent {
    /// The σ the residuals say (m or rad): the assumed one times the scale.
    pub fn estimated_sigma(&self) -> f64 {
        self.assumed_sigma * self.scale
    }
}

fn kind_name<S: serde::Serializer>(kind: &RowKind, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(kind.name())
}

/// The variance components of the position and rotation rows of a fit at `model` (the
/// measurements in the model's measurement frame; `options` with the fit's robust weights and
/// prior; `free` the parameters the fit moved; `block_rows`: per extra fitted block of six
/// parameters, such as a later session's frame, the indices of the measurements it moves).
/// Empty unless both kinds have rows: with one kind there is no ratio to estimate.
pub fn variance_components(
    model: &McpcModel,
    measurements: &[Measurement],
    predictor: &dyn Predictor,
    free: &[usize],
    options: &IdentificationOptions,
    block_rows: &[Vec<usize>],
) -> Result<Vec<NoiseComponent>> {
    const KINDS: [RowKind; 2] = [RowKind::Position, RowKind::Rotation];
    let used = |i: usize| options.observation_weights.get(i).is_none_or(|w| *w > 0.0);
    // Per measurement, its first row and its rows' kinds.
    let mut starts = Vec::with_capacity(measurements.len());
    let mut row = 0;
    for m in measurements {
        starts.push(row);
        row += m.observation.rows();
    }
    let count = |kind: RowKind, i: usize| {
        kind_of(&measurements[i].observation)
            .row_kinds()
            .iter()
            .filter(|k| **k == kind)
            .count()
    };
    let rows: Vec<usize> = KINDS
        .iter()
        .map(|&kind| {
            (0..measurements.len())
                .filter(|&i| used(i))
                .map(|i| count(kind, i))
                .sum()
        })
        .collect();
    if rows.contains(&0) || free.is_empty() {
        return Ok(Vec::new());
    }
    let (jacobian, residual) = weighted_jacobian(
        model,
        Nuisance::none(),
        measurements,
        predictor,
        free,
        options,
    )?;
    let leverage = leverages(&jacobian, free, options);
    let mut components = Vec::new();
    for (k, &kind) in KINDS.iter().enumerate() {
        let (mut squares, mut hat) = (0.0, 0.0);
        for (i, m) in measurements.iter().enumerate().filter(|(i, _)| used(*i)) {
            for (j, row_kind) in kind_of(&m.observation).row_kinds().iter().enumerate() {
                if *row_kind == kind {
                    squares += residual[starts[i] + j].powi(2);
                    hat += leverage[starts[i] + j];
                }
            }
        }
        // A block's six parameters are shared by the kinds in proportion to its rows.
        let blocks: f64 = block_rows
            .iter()
            .map(|members| {
                let of = |kind: RowKind| -> usize {
                    members
                        .iter()
                        .filter(|&&i| used(i))
                        .map(|&i| count(kind, i))
                        .sum()
                };
                let all: usize = KINDS.iter().map(|&kind| of(kind)).sum();
                6.0 * of(kind) as f64 / all.max(1) as f64
            })
            .sum();
        let redundancy = rows[k] as f64 - hat - blocks;
        components.push(NoiseComponent {
            kind,
            rows: rows[k],
            redundancy,
            assumed_sigma: options.noise().sigma(kind),
            scale: if redundancy > 0.0 {
                (squares / redundancy).sqrt()
            } else {
                f64::NAN
            },
        });
    }
    Ok(components)
}

/// The diagonal of the hat matrix `J·(JᵀJ + Λ)⁺·Jᵀ` (`Λ` the prior's rows), column-scaled and
/// truncated at the null directions like the solver's step.
fn leverages(jacobian: &DMatrix<f64>, free: &[usize], options: &IdentificationOptions) -> Vec<f64> {
    let prior = options.prior.as_ref().map(|p| p.rows(free, 1.0).weights);
    let mut normal = jacobian.transpose() * jacobian;
    if let Some(weights) = &prior {
        for (c, w) in weights.iter().enumerate() {
            normal[(c, c)] += w;
        }
    }
    let scales = floored_scales((0..free.len()).map(|c| normal[(c, c)].max(0.0).sqrt()));
    let scaled = DMatrix::from_fn(free.len(), free.len(), |r, c| {
        normal[(r, c)] / (scales[r] * scales[c])
    });
    let eigen = SymmetricEigen::new(scaled);
    let largest = eigen.eigenvalues.iter().copied().fold(0.0, f64::max);
    // M = J·S⁻¹·V·Σ⁻¹ over the retained directions: leverage hᵢ = ‖Mᵢ‖².
    let mut basis = Vec::new();
    for (e, &value) in eigen.eigenvalues.iter().enumerate() {
        if value > EIGEN_TOLERANCE * largest && value > 0.0 {
            let v = eigen.eigenvectors.column(e);
            basis.push(DMatrix::from_fn(free.len(), 1, |r, _| {
                v[r] / (scales[r] * value.sqrt())
            }));
        }
    }
    if basis.is_empty() {
        return vec![0.0; jacobian.nrows()];
    }
    let columns: Vec<_> = basis.iter().map(|b| b.column(0).into_owned()).collect();
    let projection = DMatrix::from_columns(&columns);
    let m = jacobian * projection;
    m.row_iter().map(|r| r.norm_squared()).collect()
}

/// The rotation σ that makes the two kinds' scales equal, the position σ kept (so a prior, which
/// weighs against the declared position noise, keeps its strength): `σ_rot · σ̂_rot / σ̂_pos`.
/// `None` when the components do not say (one kind, no redundancy).
pub fn balanced_rotation_sigma(components: &[NoiseComponent]) -> Option<f64> {
    let of = |kind| components.iter().find(|c| c.kind == kind);
    let (position, rotation) = (of(RowKind::Position)?, of(RowKind::Rotation)?);
    let ratio = rotation.scale / position.scale;
    (ratio.is_finite() && ratio > 0.0).then_some(rotation.assumed_sigma * ratio)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leverages_of_a_full_rank_problem_sum_to_its_columns() {
        let j = DMatrix::from_fn(12, 3, |r, c| {
            ((r * 7 + c * 3) % 5) as f64 - 2.0 + 0.1 * c as f64
        });
        let h = leverages(&j, &[0, 1, 2], &IdentificationOptions::default());
        let total: f64 = h.iter().sum();
        assert!((total - 3.0).abs() < 1e-9, "{total}");
        assert!(h.iter().all(|v| (-1e-12..=1.0 + 1e-12).contains(v)));
    }
}
