//! The joint ranges contact configurations are drawn in (issue 29: "a standing robot with
//! `--reference-link` at a sole"). A lab's humanoid touching a table stands on its sole in
//! its balance controller's posture: the support leg moves a little to shift the pelvis, it
//! does not swing through its whole range. And a joint no frame of the model moves (the other
//! leg, a head, the fingers) changes nothing the contacts see, so it rests.
//!
//! - A joint no frame of the model moves rests at zero (clamped into its limits).
//! - A joint of the support leg (the model's frames from the root to the reference link) moves
//!   within [`STANCE_ANGLE`] (revolute) or [`STANCE_LENGTH`] (prismatic) of that rest value,
//!   inside its limits.
//! - Every other joint moves within its limits (unbounded ones within ±π).

use crate::kinematics::McpcModel;
use crate::tree::KinematicTree;

/// How far a support-leg joint moves from its rest value (rad): 0.4 rad ≈ 23°, a standing
/// robot shifting its pelvis and bending its knee to reach. (At 0.15–0.25 rad the leg's
/// parameters are so weakly excited that Atlas's encoder-noise trials on `l_foot` leave the
/// linear regime: error / covariance up to 1.45–1.56.)
pub const STANCE_ANGLE: f64 = 0.4;

/// How far a prismatic support-leg joint moves from its rest value (m).
pub const STANCE_LENGTH: f64 = 0.02;

/// Each joint variable's range (unbounded: [−π, π]).
pub(super) fn limits_of(tree: &KinematicTree) -> Vec<(f64, f64)> {
    tree.dof_limits()
        .iter()
        .map(|l| {
            l.map_or((-std::f64::consts::PI, std::f64::consts::PI), |l| {
                (l.lower, l.upper)
            })
        })
        .collect()
}

/// The value a joint rests at: zero, clamped into its range.
fn rest_value((lower, upper): (f64, f64)) -> f64 {
    0.0f64.clamp(lower, upper.max(lower))
}

/// The joint variables no frame of `model` moves, each with its rest value.
fn resting_joints(tree: &KinematicTree, model: &McpcModel) -> Vec<(usize, f64)> {
    let used = driven(tree, model.frames().iter().map(|f| &f.actuation));
    limits_of(tree)
        .into_iter()
        .enumerate()
        .filter(|(dof, _)| !used[*dof])
        .map(|(dof, range)| (dof, rest_value(range)))
        .collect()
}

/// Which joint variables `actuations` drive (one flag per variable of `tree`).
fn driven<'a>(
    tree: &KinematicTree,
    actuations: impl Iterator<Item = &'a crate::tree::Actuation>,
) -> Vec<bool> {
    let mut used = vec![false; tree.dof_count()];
    for dof in actuations.filter_map(|a| a.driver()) {
        if let Some(u) = used.get_mut(dof.0) {
            *u = true;
        }
    }
    used
}

/// The ranges contact configurations of `model` are drawn and projected in (see the module
/// documentation); without a reference link, every joint the model moves keeps its limits.
pub fn contact_limits(tree: &KinematicTree, model: &McpcModel) -> Vec<(f64, f64)> {
    let mut limits = limits_of(tree);
    for (dof, value) in resting_joints(tree, model) {
        limits[dof] = (value, value);
    }
    let frames = model.frames();
    for &f in model.reference_chain() {
        let Some(frame) = frames.get(f) else { continue };
        let Some(dof) = frame.actuation.driver() else {
            continue;
        };
        let Some(range) = limits.get_mut(dof.0) else {
            continue;
        };
        let half = if tree.joint(frame.joint).kind.is_rotational() {
            STANCE_ANGLE
        } else {
            STANCE_LENGTH
        };
        let rest = rest_value(*range);
        *range = (range.0.max(rest - half), range.1.min(rest + half));
    }
    limits
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workflow::RobotSource;

    #[test]
    fn a_standing_robot_holds_its_support_leg_and_rests_what_the_model_does_not_move() {
        let mut notes = Vec::new();
        let free = RobotSource::BuiltIn
            .nominal(None, None, &mut notes)
            .unwrap();
        let tree = &free.import.tree;
        let full = limits_of(tree);
        // Without a reference link, every joint the model moves keeps its limits.
        let resting = resting_joints(tree, &free.model);
        for (dof, (range, limit)) in contact_limits(tree, &free.model)
            .iter()
            .zip(&full)
            .enumerate()
        {
            if resting.iter().any(|(d, _)| *d == dof) {
                assert_eq!(range.0, range.1);
            } else {
                assert_eq!(range, limit);
            }
        }
        // The right arm measured from the left arm's third link: the left arm's joints (the
        // "support leg") move within the stance.
        let tools = ["right_tool".to_owned()];
        let standing = RobotSource::BuiltIn
            .nominal(Some(&tools), Some("left_link3"), &mut notes)
            .unwrap();
        let held = contact_limits(tree, &standing.model);
        let chain = standing.model.reference_chain();
        assert!(!chain.is_empty());
        let mut narrowed = 0;
        for &f in chain {
            let Some(dof) = standing.model.frames()[f].actuation.driver() else {
                continue;
            };
            let (lo, hi) = held[dof.0];
            assert!(hi - lo <= 2.0 * STANCE_ANGLE + 1e-12, "{lo} {hi}");
            assert!(lo >= full[dof.0].0 && hi <= full[dof.0].1 && lo <= 0.0 && hi >= 0.0);
            narrowed += usize::from(hi - lo < full[dof.0].1 - full[dof.0].0);
        }
        assert!(narrowed > 0);
    }
}
