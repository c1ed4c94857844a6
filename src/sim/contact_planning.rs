//! Planning contact configurations (`plan --contact-setup`, docs/contacts.md "Planning
//! contact configurations"): choose K of N feasible contact configurations so that the
//! contact rows' weighted Jacobian (robot and nuisance columns, as the contact calibration
//! builds it) is as informative as possible.
//!
//! Each candidate is one contact (1 or 3 rows, padded with zero rows to 3: a zero row adds no
//! information). Columns are scaled by their RMS norm over the whole pool (so that criteria of
//! different sets compare) and columns no candidate moves are dropped. The choice is the pose
//! planner's: a greedy pick and DETMAX exchanges on `log det(εI + MᵀM)` (`sim/detmax.rs`).
//! Sets are scored by the criterion on the singular values of the directions the whole pool
//! determines (contacts always leave some directions unobservable), with `m` = rows.

use super::detmax::Design;
use crate::calibration::{criterion_value, Criterion};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand::RngExt;

/// Rows per candidate block (a flush or touch contact; point and distance rows are padded).
const ROWS: usize = 3;

/// The ridge on the information matrix while choosing (columns scaled to unit RMS norm).
const RIDGE: f64 = 1e-6;

/// Relative size below which a singular value of the pool counts as zero.
const RANK_TOLERANCE: f64 = 1e-8;

/// What [`choose_contacts`] chose.
#[derive(Debug, Clone)]
pub struct ContactChoiceReport {
    /// The chosen candidates (sorted).
    pub chosen: Vec<usize>,
    /// The random comparison set of the same size from the same pool (sorted).
    pub random: Vec<usize>,
    /// The criterion.
    pub criterion: Criterion,
    /// Its value for the chosen set.
    pub planned_value: f64,
    /// Its value for the random set.
    pub random_value: f64,
    /// Directions the chosen set determines (of the pool's).
    pub planned_rank: usize,
    /// Directions the random set determines.
    pub random_rank: usize,
    /// Directions the whole pool determines.
    pub pool_rank: usize,
    /// Columns moved by some candidate (unknowns of the pool).
    pub unknowns: usize,
    /// DETMAX exchanges after the greedy pick.
    pub exchanges: usize,
}

/// Chooses `poses` of the candidate blocks (each the weighted Jacobian rows of one contact,
/// at most 3 rows, all with the same columns) maximising `criterion`; `rng` draws the random
/// comparison set.
pub fn choose_contacts(
    blocks: &[DMatrix<f64>],
    poses: usize,
    criterion: Criterion,
    rng: &mut ChaCha8Rng,
) -> Result<ContactChoiceReport> {
    let columns = blocks.first().map_or(0, |b| b.ncols());
    if poses == 0 || blocks.len() < poses || blocks.iter().any(|b| b.nrows() > ROWS) {
        return Err(Error::InvalidData {
            origin: "contact planning".into(),
            message: format!(
                "{poses} contacts asked of {} feasible candidates; ask for at least one and at \
                 most as many as there are candidates",
                blocks.len()
            ),
        });
    }
    crate::limits::ensure_finite(
        blocks.iter().flat_map(|b| b.iter()),
        "contact planning: the candidates' Jacobians",
    )?;
    let scales: Vec<f64> = (0..columns)
        .map(|k| {
            let sum: f64 = blocks.iter().map(|b| b.column(k).norm_squared()).sum();
            (sum / blocks.len() as f64).sqrt()
        })
        .collect();
    let kept: Vec<usize> = (0..columns).filter(|&k| scales[k] > 0.0).collect();
    let mut stacked = DMatrix::zeros(blocks.len() * ROWS, kept.len());
    for (c, block) in blocks.iter().enumerate() {
        for (to, &from) in kept.iter().enumerate() {
            for row in 0..block.nrows() {
                stacked[(c * ROWS + row, to)] = block[(row, from)] / scales[from];
            }
        }
    }
    let rows: Vec<usize> = blocks.iter().map(|b| b.nrows()).collect();
    let mut design = Design::new(stacked, ROWS, RIDGE);
    let all: Vec<usize> = (0..blocks.len()).collect();
    let pool_values = singular_values(&design.information(&all));
    let largest = pool_values.first().copied().unwrap_or(0.0);
    let pool_rank = pool_values
        .iter()
        .filter(|&&s| s > RANK_TOLERANCE * largest)
        .count();
    design.greedy(poses);
    let exchanges = design.detmax(20 * poses + 100);
    let score = |set: &[usize]| {
        let values = singular_values(&design.information(set));
        let rank = values
            .iter()
            .filter(|&&s| s > RANK_TOLERANCE * largest)
            .count();
        let m = set.iter().map(|&c| rows[c]).sum();
        (criterion_value(criterion, &values[..pool_rank], m), rank)
    };
    let chosen = design.chosen();
    let mut order: Vec<usize> = (0..blocks.len()).collect();
    for i in 0..poses {
        let j = rng.random_range(i..order.len());
        order.swap(i, j);
    }
    let mut random = order[..poses].to_vec();
    random.sort_unstable();
    let (planned_value, planned_rank) = score(&chosen);
    let (random_value, random_rank) = score(&random);
    Ok(ContactChoiceReport {
        chosen,
        random,
        criterion,
        planned_value,
        random_value,
        planned_rank,
        random_rank,
        pool_rank,
        unknowns: kept.len(),
        exchanges,
    })
}

/// Singular values (largest first) of a Jacobian from its information matrix `JᵀJ`.
fn singular_values(information: &DMatrix<f64>) -> Vec<f64> {
    let mut values: Vec<f64> = information
        .clone()
        .symmetric_eigenvalues()
        .iter()
        .map(|l| l.max(0.0).sqrt())
        .collect();
    values.sort_by(|a, b| b.total_cmp(a));
    values
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn the_chosen_set_beats_a_random_one_and_padding_adds_nothing() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        // Candidates that mostly move the first column, a few that move the others.
        let blocks: Vec<DMatrix<f64>> = (0..40)
            .map(|c| {
                let rows = if c % 2 == 0 { 1 } else { 3 };
                DMatrix::from_fn(rows, 4, |r, k| {
                    let spread = if c % 7 == 0 { 1.0 } else { 0.01 };
                    if k == 0 {
                        1.0
                    } else {
                        spread * (((c * 13 + r * 5 + k * 3) % 11) as f64 - 5.0)
                    }
                })
            })
            .collect();
        let report = choose_contacts(&blocks, 6, Criterion::O1, &mut rng).unwrap();
        assert_eq!(report.chosen.len(), 6);
        assert_eq!(report.pool_rank, 4);
        assert!(report.planned_value > report.random_value, "{report:?}");
        assert!(report.planned_rank >= report.random_rank);
        assert!(choose_contacts(&blocks, 41, Criterion::O1, &mut rng).is_err());
    }
}
