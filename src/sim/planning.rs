//! Optimal calibration poses: choose K of N collision-free candidate configurations so that
//! the identification Jacobian of the chosen set is as well conditioned as possible (an
//! observability index, Borm & Menq 1991; active calibration, Sun & Hollerbach 2008).
//!
//! Candidates are drawn uniformly within the joint limits; those in self-collision or with a
//! measured tool outside the workspace box are rejected and counted. Each candidate's
//! identification Jacobian block (every measured tool; 6 rows with three targets, 3 with one)
//! is computed once, rows weighted by 1/σ as the solver does, columns scaled by their RMS norm
//! over the *whole candidate pool* (not over the chosen set, so criteria of different sets are
//! comparable). The choice is a greedy pick followed by DETMAX exchanges on `log det`
//! (`sim/detmax.rs`); for O3 a short exchange pass on the smallest singular value follows.
//! See `docs/planning.md`.

use super::collision::CollisionChecker;
use super::detmax::{Design, MAX_ROWS};
use super::noise::Targets;
use super::sampling::{sample_configurations, SamplingOptions};
use crate::calibration::locked_arm_model;
use crate::calibration::ParameterSet;
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::math::Vec3;
use crate::measurement::{Measurement, Observation};
use crate::tree::{Branches, KinematicTree};
use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

pub use crate::calibration::{criterion_value, Criterion};

/// Which calibration stage the poses are planned for (as [`crate::calibration::ParameterSet`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlanningStage {
    /// The torso with the arms locked: torso frames plus one rigid tool per (tool, lock).
    Torso,
    /// The arms' frames and tools, the torso held.
    Arms,
    /// Every parameter at once.
    All,
}

/// Settings of [`plan_poses`].
#[derive(Debug, Clone)]
pub struct PlanningOptions {
    /// Configurations to choose (K).
    pub poses: usize,
    /// Candidate configurations to choose from (N), after rejections.
    pub candidates: usize,
    /// What to maximise.
    pub criterion: Criterion,
    /// Targets per tool: a frame (6 rows per tool) or a position (3 rows).
    pub targets: Targets,
    /// The stage planned for.
    pub stage: PlanningStage,
    /// Box (min corner, max corner; base frame, m) every measured tool origin must lie in.
    pub workspace: Option<(Vec3, Vec3)>,
    /// Locked arm configurations the torso stage uses (candidate i uses lock i mod locks).
    pub locks: usize,
    /// Position noise (m): position rows are divided by it, as in the solver.
    pub position_sigma: f64,
    /// Rotation noise (rad): rotation rows are divided by it.
    pub rotation_sigma: f64,
    /// Seed of the candidate draws and of the random comparison set.
    pub seed: u64,
}

impl Default for PlanningOptions {
    fn default() -> Self {
        // The AT901 tracker at the base: 15 µm, and a three-target frame √2·σ / 0.1 m.
        let sigma = 15e-6;
        Self {
            poses: 20,
            candidates: 5000,
            criterion: Criterion::O1,
            targets: Targets::Three,
            stage: PlanningStage::All,
            workspace: None,
            locks: 2,
            position_sigma: sigma,
            rotation_sigma: std::f64::consts::SQRT_2 * sigma / crate::measurement::TARGET_SPACING,
            seed: 0,
        }
    }
}

/// One chosen configuration and the tools measured there.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedPose {
    /// One value per independent joint (m, rad).
    pub q: Vec<f64>,
    /// Indices of the measured tools in the model's tools.
    pub tools: Vec<usize>,
}

/// What [`plan_poses`] chose and how good it is.
#[derive(Debug, Clone)]
pub struct PlanReport {
    /// The chosen configurations, in candidate order.
    pub poses: Vec<PlannedPose>,
    /// K configurations drawn at random from the same candidates, for comparison.
    pub random_poses: Vec<PlannedPose>,
    /// The criterion maximised.
    pub criterion: Criterion,
    /// Its value for the chosen set.
    pub planned_value: f64,
    /// Its value for the random set.
    pub random_value: f64,
    /// Candidates that passed the checks (N, or fewer if the draws ran out).
    pub candidates: usize,
    /// Draws rejected for self-collision.
    pub rejected_collision: usize,
    /// Draws rejected for a tool outside the workspace box.
    pub rejected_workspace: usize,
    /// Parameters (Jacobian columns) the criterion is computed over: those the stage
    /// identifies that any candidate moves.
    pub parameters: usize,
    /// Improving DETMAX (and O3) exchanges made after the greedy pick.
    pub exchanges: usize,
}

/// Draws tried per requested candidate before settling for fewer.
const MAX_DRAWS_PER_CANDIDATE: usize = 50;

/// The ridge on the information matrix while choosing (columns are scaled to unit RMS norm per
/// candidate, so one candidate adds about 1 per column).
const RIDGE: f64 = 1e-6;

/// Chooses `options.poses` configurations from `options.candidates` collision-free candidates
/// that maximise `options.criterion`; `progress` is called with the number of candidates
/// accepted so far (up to `options.candidates`).
pub fn plan_poses(
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    checker: Option<&CollisionChecker>,
    options: &PlanningOptions,
    progress: &dyn Fn(usize),
) -> Result<PlanReport> {
    check_options(options)?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let tools: Vec<usize> = (0..model.tools().len()).collect();
    let Drawn {
        candidates,
        rejected_collision,
        rejected_workspace,
    } = draw_candidates(tree, branches, model, checker, options, &mut rng, progress)?;

    let (blocks, rows, parameters) = jacobian_blocks(branches, model, &candidates, options)?;
    let mut design = Design::new(blocks, rows, RIDGE);
    design.greedy(options.poses);
    let mut exchanges = design.detmax(20 * options.poses + 100);
    let observations = options.poses * rows;
    let value = |design: &Design, set: &[usize]| -> f64 {
        let values = singular_values(&design.information(set));
        criterion_value(options.criterion, &values, observations)
    };
    if options.criterion == Criterion::O3 {
        exchanges += refine_min_singular_value(&mut design, &value);
    }
    let chosen = design.chosen();
    let planned_value = value(&design, &chosen);

    let random = random_set(&mut rng, candidates.len(), options.poses);
    let random_value = value(&design, &random);
    let pose = |c: &usize| PlannedPose {
        q: candidates[*c].clone(),
        tools: tools.clone(),
    };
    Ok(PlanReport {
        poses: chosen.iter().map(pose).collect(),
        random_poses: random.iter().map(pose).collect(),
        criterion: options.criterion,
        planned_value,
        random_value,
        candidates: candidates.len(),
        rejected_collision,
        rejected_workspace,
        parameters,
        exchanges,
    })
}

/// The candidates a plan chooses from, and how many draws were rejected.
struct Drawn {
    candidates: Vec<Vec<f64>>,
    rejected_collision: usize,
    rejected_workspace: usize,
}

/// Draws `options.candidates` collision-free configurations with their tools in the workspace
/// box (for the torso stage, around `options.locks` locked arm configurations), or fails when
/// fewer than `options.poses` pass.
fn draw_candidates(
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    checker: Option<&CollisionChecker>,
    options: &PlanningOptions,
    rng: &mut ChaCha8Rng,
    progress: &dyn Fn(usize),
) -> Result<Drawn> {
    let torso_dofs = branches.coupled.dofs(tree);
    let locks = match options.stage {
        PlanningStage::Torso => sample_configurations(
            tree,
            checker,
            options.locks,
            rng,
            &SamplingOptions::default(),
            &[],
        )?,
        _ => Vec::new(),
    };
    let fixed_for = |lock: &[f64]| -> Vec<(usize, f64)> {
        (0..tree.dof_count())
            .filter(|d| !torso_dofs.contains(d))
            .map(|d| (d, lock[d]))
            .collect()
    };

    // Candidates: drawn in batches in one sequence, checked in parallel, kept in draw order.
    let tool_links: Vec<_> = model.tools().iter().map(|t| t.link).collect();
    let mut candidates: Vec<Vec<f64>> = Vec::with_capacity(options.candidates.min(1 << 16));
    let (mut rejected_collision, mut rejected_workspace, mut draws) = (0, 0, 0);
    let max_draws = options.candidates.saturating_mul(MAX_DRAWS_PER_CANDIDATE);
    while candidates.len() < options.candidates && draws < max_draws {
        let batch = (options.candidates - candidates.len()).clamp(64, 1024);
        let drawn: Vec<Vec<f64>> = if locks.is_empty() {
            sample_configurations(tree, None, batch, rng, &SamplingOptions::default(), &[])?
        } else {
            let mut drawn = Vec::with_capacity(batch);
            for k in 0..batch {
                let lock = &locks[(draws + k) % locks.len()];
                drawn.extend(sample_configurations(
                    tree,
                    None,
                    1,
                    rng,
                    &SamplingOptions::default(),
                    &fixed_for(lock),
                )?);
            }
            drawn
        };
        draws += drawn.len();
        let verdicts: Vec<Verdict> = drawn
            .par_iter()
            .map(|q| verdict(tree, checker, &tool_links, options.workspace, q))
            .collect::<Result<_>>()?;
        for (q, verdict) in drawn.into_iter().zip(verdicts) {
            match verdict {
                Verdict::Accepted if candidates.len() < options.candidates => candidates.push(q),
                Verdict::Accepted => {}
                Verdict::Collision => rejected_collision += 1,
                Verdict::Workspace => rejected_workspace += 1,
            }
        }
        progress(candidates.len());
    }
    if candidates.len() < options.poses {
        return Err(Error::InvalidData {
            origin: "pose planning".into(),
            message: format!(
                "only {} of {draws} drawn configurations passed the checks ({rejected_collision} \
                 in self-collision, {rejected_workspace} with a tool outside the workspace box), \
                 fewer than the {} poses asked for; widen the workspace box or ask for fewer \
                 poses",
                candidates.len(),
                options.poses
            ),
        });
    }
    Ok(Drawn {
        candidates,
        rejected_collision,
        rejected_workspace,
    })
}

/// The random comparison set: `poses` distinct candidates of `count` (partial Fisher–Yates),
/// sorted.
fn random_set(rng: &mut ChaCha8Rng, count: usize, poses: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..count).collect();
    for i in 0..poses {
        let j = rng.random_range(i..order.len());
        order.swap(i, j);
    }
    let mut random: Vec<usize> = order[..poses].to_vec();
    random.sort_unstable();
    random
}

fn check_options(options: &PlanningOptions) -> Result<()> {
    let bad = |message: String| {
        Err(Error::InvalidData {
            origin: "pose planning".into(),
            message,
        })
    };
    if options.poses == 0 {
        return bad("ask for at least 1 pose".into());
    }
    if options.candidates > crate::limits::MAX_CANDIDATES {
        return bad(format!(
            "{} candidates is more than the limit of {} (each costs a Jacobian block in memory; \
             docs/file-formats.md, \"Limits\")",
            options.candidates,
            crate::limits::MAX_CANDIDATES
        ));
    }
    if options.candidates < options.poses {
        return bad(format!(
            "{} candidates cannot give {} poses; ask for at least as many candidates as poses",
            options.candidates, options.poses
        ));
    }
    if options.stage == PlanningStage::Torso && options.locks == 0 {
        return bad("the torso stage needs at least 1 locked arm configuration".into());
    }
    for (name, sigma) in [
        ("position sigma", options.position_sigma),
        ("rotation sigma", options.rotation_sigma),
    ] {
        if !(sigma.is_finite() && sigma > 0.0) {
            return bad(format!("the {name} must be positive, not {sigma}"));
        }
    }
    if let Some((low, high)) = options.workspace {
        if !(low.iter().chain(high.iter()).all(|v| v.is_finite())
            && low.x < high.x
            && low.y < high.y
            && low.z < high.z)
        {
            return bad(format!(
                "the workspace box [{}, {}, {}]–[{}, {}, {}] is empty or not finite; give the \
                 minimum corner first",
                low.x, low.y, low.z, high.x, high.y, high.z
            ));
        }
    }
    Ok(())
}

/// Why a drawn configuration was kept or not.
enum Verdict {
    Accepted,
    Collision,
    Workspace,
}

fn verdict(
    tree: &KinematicTree,
    checker: Option<&CollisionChecker>,
    tool_links: &[crate::tree::LinkId],
    workspace: Option<(Vec3, Vec3)>,
    q: &[f64],
) -> Result<Verdict> {
    let poses = tree.link_poses(q)?;
    if let Some((low, high)) = workspace {
        let inside = tool_links.iter().all(|link| {
            let p = poses[link.0].translation.vector;
            (0..3).all(|k| p[k] >= low[k] && p[k] <= high[k])
        });
        if !inside {
            return Ok(Verdict::Workspace);
        }
    }
    if checker.is_some_and(|c| c.in_collision(&poses)) {
        return Ok(Verdict::Collision);
    }
    Ok(Verdict::Accepted)
}

/// Every candidate's weighted, pool-scaled Jacobian block stacked (candidate-major), the rows
/// per candidate, and the number of columns kept.
fn jacobian_blocks(
    branches: &Branches,
    model: &McpcModel,
    candidates: &[Vec<f64>],
    options: &PlanningOptions,
) -> Result<(DMatrix<f64>, usize, usize)> {
    let tool_count = model.tools().len();
    let rows_per_tool = match options.targets {
        Targets::Three => 6,
        Targets::One => 3,
    };
    let rows = rows_per_tool * tool_count;
    if rows > MAX_ROWS {
        return Err(Error::InvalidData {
            origin: "pose planning".into(),
            message: format!(
                "{tool_count} tools give {rows} rows per configuration; the planner handles at \
                 most {MAX_ROWS}"
            ),
        });
    }
    let (stage_model, stage_tools, columns) = stage_model(branches, model, candidates, options)?;
    let weights = [1.0 / options.position_sigma, 1.0 / options.rotation_sigma];
    let per_candidate: Vec<DMatrix<f64>> = candidates
        .par_iter()
        .enumerate()
        .map(|(c, q)| {
            let mut block = DMatrix::zeros(rows, columns.len());
            for tool in 0..tool_count {
                let jacobian = stage_model
                    .tool_jacobian(stage_tools[c * tool_count + tool], q)
                    .jacobian;
                for (k, &column) in columns.iter().enumerate() {
                    for row in 0..rows_per_tool {
                        block[(tool * rows_per_tool + row, k)] =
                            jacobian[(row, column)] * weights[row / 3];
                    }
                }
            }
            block
        })
        .collect();
    let (blocks, kept) = pool_scaled(&per_candidate, columns.len(), rows);
    let squares = blocks.norm_squared();
    crate::limits::ensure_finite(
        blocks.iter().chain([&squares]),
        "planning: the candidates' Jacobians",
    )?;
    Ok((blocks, rows, kept))
}

/// The model a planning stage identifies, which of its tools each (candidate, tool) uses, and
/// the columns (parameters) it frees.
fn stage_model(
    branches: &Branches,
    model: &McpcModel,
    candidates: &[Vec<f64>],
    options: &PlanningOptions,
) -> Result<(McpcModel, Vec<usize>, Vec<usize>)> {
    let coupled_frames = crate::calibration::coupled_frames(model, branches);
    // The model the stage identifies, and which of its tools each measurement uses.
    let tool_count = model.tools().len();
    Ok(match options.stage {
        PlanningStage::Torso => {
            let data: Vec<Measurement> = candidates
                .iter()
                .flat_map(|q| {
                    (0..tool_count).map(move |tool| Measurement {
                        payload: None,
                        tool,
                        q: q.clone(),
                        observation: Observation::Position(Vec3::zeros()),
                        stage: None,
                        session: None,
                    })
                })
                .collect();
            let (stage_model, stage_data, _) =
                locked_arm_model(model, &coupled_frames, &data, "torso")?;
            let columns = (0..stage_model.parameter_count()).collect();
            let tools = stage_data.iter().map(|m| m.tool).collect();
            (stage_model, tools, columns)
        }
        PlanningStage::Arms | PlanningStage::All => {
            let set = if options.stage == PlanningStage::All {
                ParameterSet::All
            } else {
                ParameterSet::Arms
            };
            let columns = crate::calibration::stage_parameters(model, &coupled_frames, set);
            let tools = (0..candidates.len()).flat_map(|_| 0..tool_count).collect();
            (model.clone(), tools, columns)
        }
    })
}

/// The candidates' blocks stacked (candidate-major), each column scaled by its RMS norm over
/// the whole pool, columns no candidate moves dropped; and the number of columns kept.
fn pool_scaled(
    per_candidate: &[DMatrix<f64>],
    columns: usize,
    rows: usize,
) -> (DMatrix<f64>, usize) {
    let candidates = per_candidate;
    // Column scale: RMS norm over the whole pool. Columns no candidate moves are dropped.
    let mut norms = vec![0.0; columns];
    for block in per_candidate {
        for (k, norm) in norms.iter_mut().enumerate() {
            *norm += block.column(k).norm_squared();
        }
    }
    let kept: Vec<(usize, f64)> = norms
        .iter()
        .enumerate()
        .filter(|(_, n)| **n > 0.0)
        .map(|(k, n)| (k, (n / candidates.len() as f64).sqrt()))
        .collect();
    let mut blocks = DMatrix::zeros(candidates.len() * rows, kept.len());
    for (c, block) in per_candidate.iter().enumerate() {
        for (to, &(from, scale)) in kept.iter().enumerate() {
            for row in 0..rows {
                blocks[(c * rows + row, to)] = block[(row, from)] / scale;
            }
        }
    }
    (blocks, kept.len())
}

/// Singular values of a Jacobian from its information matrix `JᵀJ` (√ of the eigenvalues,
/// negative rounding clamped to 0).
fn singular_values(information: &DMatrix<f64>) -> Vec<f64> {
    if !information.iter().all(|v| v.is_finite()) {
        // Its eigen-decomposition would never end; NaN ranks below every finite criterion.
        return vec![f64::NAN; information.ncols()];
    }
    information
        .clone()
        .symmetric_eigenvalues()
        .iter()
        .map(|l| l.max(0.0).sqrt())
        .collect()
}

/// O3 is not a determinant, so after DETMAX (which maximises `log det`) swap chosen poses for
/// the few unchosen ones with the largest `log det` gain while that raises the smallest
/// singular value; a handful of passes at most. Returns the swaps made.
fn refine_min_singular_value(
    design: &mut Design,
    value: &dyn Fn(&Design, &[usize]) -> f64,
) -> usize {
    const SHORTLIST: usize = 8;
    const PASSES: usize = 5;
    let mut swaps = 0;
    for _ in 0..PASSES {
        let chosen = design.chosen();
        let current = value(design, &chosen);
        let mut shortlist: Vec<usize> = Vec::new();
        let mut scratch_chosen = chosen.clone();
        // The best additions, one after another without applying them: rank by gain.
        let mut gains: Vec<(usize, f64)> = (0..design.count())
            .filter(|c| !chosen.contains(c))
            .map(|c| (c, design.gain(c)))
            .collect();
        gains.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        shortlist.extend(gains.iter().take(SHORTLIST).map(|g| g.0));
        let mut best: Option<(usize, usize, f64)> = None;
        for (slot, &out) in chosen.iter().enumerate() {
            for &candidate in &shortlist {
                scratch_chosen[slot] = candidate;
                let v = value(design, &scratch_chosen);
                if v > best.map_or(current, |b| b.2) * (1.0 + 1e-12) {
                    best = Some((out, candidate, v));
                }
            }
            scratch_chosen[slot] = out;
        }
        match best {
            Some((out, candidate, _)) => {
                design.apply(candidate, 1.0);
                design.apply(out, -1.0);
                swaps += 1;
            }
            None => break,
        }
    }
    swaps
}
