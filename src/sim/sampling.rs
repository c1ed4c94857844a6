//! Random configurations within joint limits, optionally free of self-collision.
//!
//! Each sample draws every free joint variable uniformly between its limits (shrunk by
//! [`SamplingOptions::limits_margin`]) in configuration-vector order, so the same seed gives the
//! same configurations on every machine (`ChaCha8Rng` is version-stable).

use super::collision::CollisionChecker;
use crate::error::{Error, Result};
use crate::tree::{JointKind, KinematicTree, LinkId};
use rand::rngs::ChaCha8Rng;
use rand::RngExt;
use std::f64::consts::PI;

/// Settings of [`sample_configurations`].
#[derive(Debug, Clone)]
pub struct SamplingOptions {
    /// Draws allowed per returned configuration before giving up (rejected ones included).
    pub max_attempts_per_sample: usize,
    /// Distance kept from each joint limit (rad or m); unbounded joints are drawn in [−π, π).
    pub limits_margin: f64,
}

impl Default for SamplingOptions {
    fn default() -> Self {
        Self {
            max_attempts_per_sample: 1000,
            limits_margin: 0.0,
        }
    }
}

/// How one joint variable is drawn.
#[derive(Debug, Clone, Copy)]
enum Draw {
    /// Held at this value (given as fixed, or a joint whose limits leave a single value).
    Constant(f64),
    /// Uniform in `[lower, upper)`.
    Uniform(f64, f64),
}

/// `count` configurations (one value per independent joint each) drawn uniformly within the
/// joint limits, with the `fixed` joint variables (configuration index, value) held at their
/// values, and, with a `checker`, none in self-collision.
///
/// Unbounded revolute and continuous joints are drawn in [−π, π); an unbounded prismatic joint
/// that is not fixed is an error, as are fixed values outside their joint's limits. Fails with
/// a message naming the colliding links when `max_attempts_per_sample` draws in a row collide.
pub fn sample_configurations(
    tree: &KinematicTree,
    checker: Option<&CollisionChecker>,
    count: usize,
    rng: &mut ChaCha8Rng,
    options: &SamplingOptions,
    fixed: &[(usize, f64)],
) -> Result<Vec<Vec<f64>>> {
    let draws = draws(tree, options, fixed)?;
    if let Some(checker) = checker {
        if checker.link_count() != tree.links().len() {
            return Err(Error::InvalidData {
                origin: "sampling".into(),
                message: format!(
                    "the collision checker was built for a robot with {} links, not for '{}' \
                     with {}",
                    checker.link_count(),
                    tree.name(),
                    tree.links().len()
                ),
            });
        }
    }
    // Capped so that an absurd count fails on time, not on one huge allocation up front.
    let mut samples = Vec::with_capacity(count.min(1 << 16));
    let mut q = vec![0.0; draws.len()];
    for sample in 0..count {
        let mut found = false;
        for _ in 0..options.max_attempts_per_sample {
            for (value, draw) in q.iter_mut().zip(&draws) {
                *value = match *draw {
                    Draw::Constant(v) => v,
                    Draw::Uniform(lower, upper) => rng.random_range(lower..upper),
                };
            }
            let free = match checker {
                Some(checker) => !checker.in_collision(&tree.link_poses(&q)?),
                None => true,
            };
            if free {
                found = true;
                break;
            }
        }
        if !found {
            return Err(no_free_configuration(
                tree,
                checker,
                &draws,
                &q,
                !fixed.is_empty(),
                (sample + 1, count),
                options.max_attempts_per_sample,
            ));
        }
        samples.push(q.clone());
    }
    Ok(samples)
}

/// How each joint variable is drawn, after checking the options, the limits and `fixed`.
fn draws(
    tree: &KinematicTree,
    options: &SamplingOptions,
    fixed: &[(usize, f64)],
) -> Result<Vec<Draw>> {
    let bad_option = |message: String| Error::InvalidData {
        origin: "sampling options".into(),
        message,
    };
    if options.max_attempts_per_sample == 0 {
        return Err(bad_option(
            "max_attempts_per_sample must be at least 1".into(),
        ));
    }
    let margin = options.limits_margin;
    if !(margin.is_finite() && margin >= 0.0) {
        return Err(bad_option(format!(
            "limits_margin must be a finite value of 0 or more (rad or m), not {margin}"
        )));
    }
    let mut held: Vec<Option<f64>> = vec![None; tree.dof_count()];
    for &(dof, value) in fixed {
        let name = |dof: usize| tree.joint(tree.dofs()[dof]).name.clone();
        if dof >= held.len() {
            return Err(bad_option(format!(
                "fixed joint index {dof} is out of range: the robot has {} independent joints",
                held.len()
            )));
        }
        if !value.is_finite() {
            return Err(bad_option(format!(
                "joint '{}' is fixed at {value}; give a finite value",
                name(dof)
            )));
        }
        if held[dof].is_some() {
            return Err(bad_option(format!("joint '{}' is fixed twice", name(dof))));
        }
        held[dof] = Some(value);
    }
    let limits = tree.dof_limits();
    let mut draws = Vec::with_capacity(held.len());
    for ((&joint_id, limit), held) in tree.dofs().iter().zip(&limits).zip(held) {
        let joint = tree.joint(joint_id);
        // An infinite bound is no bound (the importer has already refused NaN and lower > upper).
        let bounds = limit
            .filter(|l| l.lower.is_finite() && l.upper.is_finite() && l.lower <= l.upper)
            .map(|l| (l.lower, l.upper));
        if let Some(value) = held {
            // Rounding slack, so that a value read back from a file at the limit still passes.
            let slack = 1e-9;
            if let Some((lower, upper)) = bounds {
                if value < lower - slack || value > upper + slack {
                    return Err(bad_option(format!(
                        "joint '{}' is fixed at {value}, outside its limits [{lower}, {upper}]",
                        joint.name
                    )));
                }
            }
            draws.push(Draw::Constant(value));
            continue;
        }
        let (lower, upper) = match bounds {
            // A joint that cannot move stays where it is, whatever the margin.
            Some((lower, upper)) if lower == upper => {
                draws.push(Draw::Constant(lower));
                continue;
            }
            Some((lower, upper)) => (lower + margin, upper - margin),
            None if joint.kind == JointKind::Prismatic => {
                return Err(Error::InvalidRobot {
                    origin: tree.name().to_owned(),
                    message: format!(
                        "prismatic joint '{}' has no limits, so there is no range to sample; \
                         give it <limit lower=\"…\" upper=\"…\"/> in the URDF or fix its value",
                        joint.name
                    ),
                });
            }
            None => (-PI, PI),
        };
        if lower >= upper {
            return Err(bad_option(format!(
                "limits_margin {margin} leaves nothing to sample of joint '{}' (limits [{}, {}])",
                joint.name,
                lower - margin,
                upper + margin
            )));
        }
        if !(upper - lower).is_finite() {
            return Err(Error::InvalidRobot {
                origin: tree.name().to_owned(),
                message: format!(
                    "joint '{}' has limits [{lower}, {upper}], too far apart to sample",
                    joint.name
                ),
            });
        }
        draws.push(Draw::Uniform(lower, upper));
    }
    Ok(draws)
}

/// The error when no collision-free configuration was found, naming the colliding links at
/// the zero configuration (fixed joints at their values) and at the last draw.
fn no_free_configuration(
    tree: &KinematicTree,
    checker: Option<&CollisionChecker>,
    draws: &[Draw],
    last: &[f64],
    any_fixed: bool,
    (sample, count): (usize, usize),
    attempts: usize,
) -> Error {
    let names = |pairs: Vec<(LinkId, LinkId)>| -> String {
        pairs
            .iter()
            .map(|&(a, b)| format!("{}–{}", tree.link(a).name, tree.link(b).name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let colliding = |q: &[f64]| -> String {
        match (checker, tree.link_poses(q)) {
            (Some(checker), Ok(poses)) => names(checker.colliding_pairs(&poses)),
            _ => String::new(),
        }
    };
    let zero: Vec<f64> = draws
        .iter()
        .map(|d| match *d {
            Draw::Constant(v) => v,
            Draw::Uniform(..) => 0.0,
        })
        .collect();
    let at_zero = match colliding(&zero) {
        pairs if pairs.is_empty() => "none".to_owned(),
        pairs => pairs,
    };
    Error::InvalidRobot {
        origin: tree.name().to_owned(),
        message: format!(
            "could not find a self-collision-free configuration in {} attempts (sample {} of \
             {count}); the robot may be in collision at every configuration (pairs colliding \
             at the zero configuration{}: {at_zero}; at the last attempt: {})",
            attempts,
            sample,
            if any_fixed {
                " with the fixed joints"
            } else {
                ""
            },
            colliding(last),
        ),
    }
}
