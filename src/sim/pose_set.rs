//! Default pose sets for a staged calibration: torso configurations with the arms locked,
//! and free configurations for the arms (the draws `treecal simulate` makes).

use super::collision::CollisionChecker;
use super::sampling::{sample_configurations, SamplingOptions};
use crate::error::Result;
use crate::tree::{Branches, KinematicTree};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;

/// Configurations for the two stages of the staged plan.
#[derive(Debug, Clone, PartialEq)]
pub struct StagedPoseSet {
    /// Torso configurations: the torso joints random, every other joint at one of the lock
    /// configurations, in turn.
    pub torso: Vec<Vec<f64>>,
    /// Arm configurations: every joint random.
    pub arms: Vec<Vec<f64>>,
}

/// `torso` torso-stage configurations at `locks` random locked arm configurations, and `arms`
/// random configurations, all within the joint limits and (with a `checker`) free of
/// self-collision; the same `seed` gives the same set.
pub fn staged_pose_set(
    tree: &KinematicTree,
    branches: &Branches,
    checker: Option<&CollisionChecker>,
    torso: usize,
    locks: usize,
    arms: usize,
    seed: u64,
) -> Result<StagedPoseSet> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let sampling = SamplingOptions::default();
    let torso_dofs = branches.coupled.dofs(tree);
    let mut torso_configurations = Vec::with_capacity(torso);
    if torso > 0 {
        let lock_configurations =
            sample_configurations(tree, checker, locks.max(1), &mut rng, &sampling, &[])?;
        for index in 0..torso {
            let lock = &lock_configurations[index % lock_configurations.len()];
            let fixed: Vec<(usize, f64)> = (0..tree.dof_count())
                .filter(|d| !torso_dofs.contains(d))
                .map(|d| (d, lock[d]))
                .collect();
            torso_configurations.extend(sample_configurations(
                tree, checker, 1, &mut rng, &sampling, &fixed,
            )?);
        }
    }
    let arms = sample_configurations(tree, checker, arms, &mut rng, &sampling, &[])?;
    Ok(StagedPoseSet {
        torso: torso_configurations,
        arms,
    })
}
