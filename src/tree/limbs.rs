//! The limbs of a tree with their roles (arm, leg, head, coupled, other), for `inspect`: what
//! a whole-body calibration could measure, independent of which tools are chosen.
//!
//! A limb is a run of movable joints between two places where the movable tree branches (or
//! the root, or the last movable joint of a chain). Its role comes from its joint and link
//! names (tool end first, as for tool branches); a nameless limb that carries others is
//! `coupled` (a torso), any other nameless one `other`. Movable joints beyond an arm, leg or
//! head (fingers, grippers, toes) are counted with it, not listed as limbs of their own.

use super::{BranchRole, JointId, KinematicTree, LinkId};

/// One limb.
#[derive(Debug, Clone, PartialEq)]
pub struct Limb {
    /// The link the limb ends at (where the tree branches again, or its last moving link).
    pub end: LinkId,
    /// The role its names point to.
    pub role: BranchRole,
    /// Its movable joints, root side first.
    pub joints: Vec<JointId>,
    /// Movable joints beyond it that are counted with it (fingers, grippers).
    pub beyond: usize,
}

/// The limbs of `tree`, the root's first, then the limbs they carry.
pub fn limbs(tree: &KinematicTree) -> Vec<Limb> {
    // Movable joints at or below each link.
    let mut below = vec![0usize; tree.links().len()];
    for joint in tree.joints().iter().rev() {
        below[joint.parent.0] += below[joint.child.0] + usize::from(joint.kind.is_movable());
    }
    let moving_children = |link: LinkId| -> Vec<JointId> {
        tree.link(link)
            .child_joints
            .iter()
            .copied()
            .filter(|&j| {
                let joint = tree.joint(j);
                joint.kind.is_movable() || below[joint.child.0] > 0
            })
            .collect()
    };
    let mut limbs = Vec::new();
    // Breadth first: the root's limbs, then those they carry.
    let mut starts = vec![tree.root()];
    let mut next_start = 0;
    while let Some(&start) = starts.get(next_start) {
        next_start += 1;
        for first in moving_children(start) {
            // Follow the single moving child until the tree branches or stops moving.
            let mut joints = Vec::new();
            let mut joint = first;
            let end = loop {
                let j = tree.joint(joint);
                if j.kind.is_movable() {
                    joints.push(joint);
                }
                let next = moving_children(j.child);
                match next.as_slice() {
                    [only] => joint = *only,
                    _ => break j.child,
                }
            };
            if joints.is_empty() {
                starts.push(end);
                continue;
            }
            let names = std::iter::once(tree.link(end).name.as_str()).chain(
                joints.iter().rev().flat_map(|&j| {
                    let joint = tree.joint(j);
                    [joint.name.as_str(), tree.link(joint.child).name.as_str()]
                }),
            );
            let branches_again = !moving_children(end).is_empty();
            let role = match BranchRole::from_names(names) {
                Some(role) => role,
                None if branches_again => BranchRole::Coupled,
                None => BranchRole::Other,
            };
            let limb_like = matches!(role, BranchRole::Arm | BranchRole::Leg | BranchRole::Head);
            let beyond = if limb_like { below[end.0] } else { 0 };
            if branches_again && !limb_like {
                starts.push(end);
            }
            limbs.push(Limb {
                end,
                role,
                joints,
                beyond,
            });
        }
    }
    limbs
}
