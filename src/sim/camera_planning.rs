//! Planning camera configurations (`plan --camera`, docs/camera.md section 7): choose K of N
//! collision-free configurations in which the cameras see at least one target
//! ([`super::camera_visibility`]), so that the pixel Jacobian of the chosen set is as
//! informative as possible.
//!
//! Each candidate's block is the stacked pixel Jacobian of every target it shows over the
//! fit's unknowns (`Rig::unknowns`: robot parameters, estimated camera and target poses and
//! intrinsics), rows divided by the pixel σ, columns scaled by their RMS norm over the whole
//! candidate pool (so that criteria of different sets compare). Its information `A_cᵀA_c` is
//! kept (an image has more rows than there are unknowns). The choice is a greedy pick on
//! `log det(εI + Σ A_cᵀA_c)` followed by exchanges (the best swap of a chosen and a free
//! candidate, while it raises `log det`). Sets are scored by the observability criterion on the
//! singular values of the directions the whole pool determines, with `m` = configurations.

use super::camera_visibility::Sight;
use super::collision::CollisionChecker;
use super::sampling::{sample_configurations, SamplingOptions};
use crate::calibration::{criterion_value, Criterion};
use crate::camera::{linearise_view, Unknown, View};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

/// The ridge on the information matrix while choosing (columns scaled to unit RMS norm per
/// candidate).
const RIDGE: f64 = 1e-6;

/// Draws per wanted candidate before giving up.
const MAX_DRAWS_PER_CANDIDATE: usize = 200;

/// Exchange passes at most.
const MAX_EXCHANGES: usize = 50;

/// Settings of [`plan_camera_poses`].
#[derive(Debug, Clone)]
pub struct CameraPlanningOptions {
    /// Configurations to choose.
    pub poses: usize,
    /// Candidates (configurations showing a target) to choose from.
    pub candidates: usize,
    /// The criterion the sets are scored by.
    pub criterion: Criterion,
    /// Pixel noise σ (px): rows are divided by it.
    pub pixel_sigma: f64,
    /// Seed of the candidate draws and of the random comparison set.
    pub seed: u64,
}

/// What [`plan_camera_poses`] chose.
#[derive(Debug, Clone)]
pub struct CameraPlanReport {
    /// The chosen configurations, with the views each shows.
    pub poses: Vec<(Vec<f64>, Vec<View>)>,
    /// The random comparison set (as many candidates, drawn from the same pool).
    pub random_poses: Vec<(Vec<f64>, Vec<View>)>,
    /// The criterion.
    pub criterion: Criterion,
    /// Its value for the chosen set.
    pub planned_value: f64,
    /// Its value for the random set.
    pub random_value: f64,
    /// Candidates in the pool.
    pub candidates: usize,
    /// Collision-free configurations drawn.
    pub draws: usize,
    /// Of those, configurations in which no target is seen.
    pub hidden: usize,
    /// The unknowns and the number the whole pool determines.
    pub unknowns: usize,
    /// Directions the pool determines (the criterion's singular values).
    pub pool_rank: usize,
    /// Exchanges made after the greedy pick.
    pub exchanges: usize,
}

/// Chooses `options.poses` configurations ([`CameraPlanReport`]).
pub fn plan_camera_poses(
    sight: &Sight<'_>,
    checker: Option<&CollisionChecker>,
    options: &CameraPlanningOptions,
    progress: &dyn Fn(usize),
) -> Result<CameraPlanReport> {
    if options.poses == 0
        || options.candidates < options.poses
        || !options.pixel_sigma.is_finite()
        || options.pixel_sigma <= 0.0
    {
        return Err(Error::InvalidData {
            origin: "camera pose planning".into(),
            message: format!(
                "{} poses from {} candidates with pixel σ {}: ask for at least one pose, at \
                 least as many candidates, and a positive pixel σ",
                options.poses, options.candidates, options.pixel_sigma
            ),
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let (pool, draws, hidden) = candidate_pool(sight, checker, options, &mut rng, progress)?;
    let unknowns = sight.rig.unknowns(sight.model, true);
    let mut informations: Vec<DMatrix<f64>> = pool
        .par_iter()
        .map(|(q, views)| information(sight, &unknowns, q, views, options.pixel_sigma))
        .collect();
    scale_columns(&mut informations);
    let n = unknowns.len();
    let pool_values =
        eigen_descending(&informations.iter().fold(DMatrix::zeros(n, n), |a, m| a + m));
    let largest = pool_values.first().copied().unwrap_or(0.0);
    let pool_rank = pool_values.iter().filter(|&&v| v > 1e-12 * largest).count();
    let (chosen, exchanges) = choose(&informations, options.poses);
    let score = |set: &[usize]| {
        let sum = set
            .iter()
            .fold(DMatrix::zeros(n, n), |a, &c| a + &informations[c]);
        let values: Vec<f64> = eigen_descending(&sum)[..pool_rank]
            .iter()
            .map(|v| v.max(0.0).sqrt())
            .collect();
        criterion_value(options.criterion, &values, set.len())
    };
    let mut order: Vec<usize> = (0..pool.len()).collect();
    for i in 0..options.poses {
        let j = rng.random_range(i..order.len());
        order.swap(i, j);
    }
    let mut random = order[..options.poses].to_vec();
    random.sort_unstable();
    let take = |set: &[usize]| set.iter().map(|&c| pool[c].clone()).collect();
    Ok(CameraPlanReport {
        planned_value: score(&chosen),
        random_value: score(&random),
        poses: take(&chosen),
        random_poses: take(&random),
        criterion: options.criterion,
        candidates: pool.len(),
        draws,
        hidden,
        unknowns: n,
        pool_rank,
        exchanges,
    })
}

/// Collision-free configurations showing at least one target: the pool, the draws, and the
/// draws that showed nothing.
#[allow(clippy::type_complexity)]
fn candidate_pool(
    sight: &Sight<'_>,
    checker: Option<&CollisionChecker>,
    options: &CameraPlanningOptions,
    rng: &mut ChaCha8Rng,
    progress: &dyn Fn(usize),
) -> Result<(Vec<(Vec<f64>, Vec<View>)>, usize, usize)> {
    let mut pool = Vec::with_capacity(options.candidates);
    let (mut draws, mut hidden) = (0, 0);
    let max_draws = options.candidates.saturating_mul(MAX_DRAWS_PER_CANDIDATE);
    while pool.len() < options.candidates && draws < max_draws {
        let batch = sample_configurations(
            sight.tree,
            checker,
            256,
            rng,
            &SamplingOptions::default(),
            &[],
        )?;
        let seen: Vec<Vec<View>> = batch
            .par_iter()
            .map(|q| sight.visible_views(q))
            .collect::<Result<_>>()?;
        for (q, views) in batch.into_iter().zip(seen) {
            draws += 1;
            if views.is_empty() {
                hidden += 1;
            } else if pool.len() < options.candidates {
                pool.push((q, views));
            }
        }
        progress(pool.len());
    }
    if pool.len() < options.poses {
        return Err(Error::InvalidData {
            origin: "camera pose planning".into(),
            message: format!(
                "only {} of {draws} collision-free configurations show a camera a whole target \
                 (in the image, facing it, not hidden by the robot), fewer than the {} poses \
                 asked for; check the camera's pose in the camera file, or use smaller boards",
                pool.len(),
                options.poses
            ),
        });
    }
    Ok((pool, draws, hidden))
}

/// `A_cᵀA_c` of one candidate: its views' pixel Jacobian over `unknowns`, rows / σ.
fn information(
    sight: &Sight<'_>,
    unknowns: &[Unknown],
    q: &[f64],
    views: &[View],
    pixel_sigma: f64,
) -> DMatrix<f64> {
    let tools = sight.model.tool_jacobians(q);
    let rows: usize = views.iter().map(|v| 2 * v.points.len()).sum();
    let mut a = DMatrix::zeros(rows, unknowns.len());
    let mut row = 0;
    for view in views {
        let intrinsics = &sight.rig.cameras[view.camera].intrinsics;
        let prediction = linearise_view(sight.rig, view, &tools, intrinsics);
        for r in 0..2 * view.points.len() {
            for (column, unknown) in unknowns.iter().enumerate() {
                a[(row, column)] = match *unknown {
                    Unknown::Parameter(p) => prediction.wrt_model[(r, p)],
                    Unknown::Intrinsic { camera, index } if camera == view.camera => {
                        prediction.wrt_intrinsics[(r, index)]
                    }
                    Unknown::Intrinsic { .. } | Unknown::Nuisance(_) => 0.0,
                } / pixel_sigma;
            }
            row += 1;
        }
    }
    a.tr_mul(&a)
}

/// Scales column `j` of every `A_c` by the RMS of its norms over the pool: `M_c ← S⁻¹ M_c S⁻¹`.
fn scale_columns(informations: &mut [DMatrix<f64>]) {
    let Some(first) = informations.first() else {
        return;
    };
    let n = first.nrows();
    let count = informations.len() as f64;
    let scales: Vec<f64> = (0..n)
        .map(|j| {
            let rms = (informations.iter().map(|m| m[(j, j)]).sum::<f64>() / count).sqrt();
            if rms > 0.0 {
                rms
            } else {
                1.0
            }
        })
        .collect();
    for m in informations.iter_mut() {
        for i in 0..n {
            for j in 0..n {
                m[(i, j)] /= scales[i] * scales[j];
            }
        }
    }
}

/// Eigenvalues of a symmetric matrix, largest first.
fn eigen_descending(m: &DMatrix<f64>) -> Vec<f64> {
    let mut values: Vec<f64> = m.clone().symmetric_eigenvalues().iter().copied().collect();
    values.sort_by(|a, b| b.total_cmp(a));
    values
}

/// `log det(εI + M)`, −∞ when not positive definite.
fn log_det(m: &DMatrix<f64>) -> f64 {
    let mut with_ridge = m.clone();
    for i in 0..m.nrows() {
        with_ridge[(i, i)] += RIDGE;
    }
    match with_ridge.cholesky() {
        Some(c) => 2.0 * c.l_dirty().diagonal().iter().map(|d| d.ln()).sum::<f64>(),
        None => f64::NEG_INFINITY,
    }
}

/// The greedy pick and the exchanges on `log det`: the chosen indices (sorted) and the
/// exchanges made.
fn choose(informations: &[DMatrix<f64>], k: usize) -> (Vec<usize>, usize) {
    let n = informations.first().map_or(0, |m| m.nrows());
    let mut chosen: Vec<usize> = Vec::with_capacity(k);
    let mut sum = DMatrix::zeros(n, n);
    let free = |chosen: &[usize]| -> Vec<usize> {
        (0..informations.len())
            .filter(|c| !chosen.contains(c))
            .collect()
    };
    for _ in 0..k {
        let best = best_of(&free(&chosen), |c| log_det(&(&sum + &informations[c])));
        let Some((c, _)) = best else { break };
        sum += &informations[c];
        chosen.push(c);
    }
    let mut exchanges = 0;
    let mut current = log_det(&sum);
    while exchanges < MAX_EXCHANGES {
        let candidates = free(&chosen);
        let swaps: Vec<(usize, usize)> = (0..chosen.len())
            .flat_map(|i| candidates.iter().map(move |&c| (i, c)))
            .collect();
        let best = swaps
            .par_iter()
            .map(|&(i, c)| {
                let value = log_det(&(&sum - &informations[chosen[i]] + &informations[c]));
                (value, i, c)
            })
            .reduce(
                || (f64::NEG_INFINITY, usize::MAX, usize::MAX),
                |a, b| {
                    if b.0 > a.0 || (b.0 == a.0 && (b.1, b.2) < (a.1, a.2)) {
                        b
                    } else {
                        a
                    }
                },
            );
        if best.0.is_nan() || best.0 <= current + 1e-9 * current.abs().max(1.0) {
            break;
        }
        sum = sum - &informations[chosen[best.1]] + &informations[best.2];
        chosen[best.1] = best.2;
        current = best.0;
        exchanges += 1;
    }
    chosen.sort_unstable();
    (chosen, exchanges)
}

/// The index with the largest score (the first on ties), evaluated in parallel.
fn best_of(indices: &[usize], score: impl Fn(usize) -> f64 + Sync) -> Option<(usize, f64)> {
    indices
        .par_iter()
        .map(|&c| (c, score(c)))
        .reduce_with(|a, b| {
            if b.1 > a.1 || (b.1 == a.1 && b.0 < a.0) {
                b
            } else {
                a
            }
        })
}
