//! The rules that choose and name arms, shared by the branch detection and the automatic
//! arm search: which rule decided, the common ancestor of two links, left and right from names.

use super::{KinematicTree, LinkId};
use std::fmt;

/// The rule that made a decision, so the user can see why and override it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DecisionRule {
    /// The user named the tool links.
    GivenTools,
    /// Automatic: leaf chains whose names say arm/hand/palm/tool/… (or do not say
    /// leg/head/finger/…) were preferred.
    ArmNames,
    /// Automatic: of the candidate chains, the two that diverge furthest from the root,
    /// then the longest.
    Structure,
    /// Left and right from names containing `left`/`right` or starting with `l_`/`r_`.
    SideNames,
    /// Left and right from the sign of the tip's y in the root frame at the zero configuration.
    SideY,
    /// Left and right could not be told apart; the first tool given is called left.
    GivenOrder,
    /// One arm, or more than two: arms are named after their tools.
    NoSides,
}

impl fmt::Display for DecisionRule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DecisionRule::GivenTools => "tool links given by the user",
            DecisionRule::ArmNames => {
                "automatic: chains named like arms (arm/hand/palm/wrist/gripper/tool…), never like legs, heads, fingers or wheels"
            }
            DecisionRule::Structure => {
                "automatic: the two chains that diverge furthest from the root, then the longest"
            }
            DecisionRule::SideNames => "names containing left/right or starting with l_/r_",
            DecisionRule::SideY => {
                "sign of the tip's y in the root frame at the zero configuration (+y is left)"
            }
            DecisionRule::GivenOrder => {
                "left and right could not be told apart; the first tool given is called left"
            }
            DecisionRule::NoSides => "not a two-arm robot: arms are named after their tools",
        })
    }
}

/// The deepest link that is an ancestor of (or equal to) both `a` and `b`.
pub(super) fn common_ancestor(tree: &KinematicTree, a: LinkId, b: LinkId) -> LinkId {
    let mut current = a;
    while !tree.is_ancestor(current, b) {
        match tree.link(current).parent_joint {
            Some(j) => current = tree.joint(j).parent,
            None => return tree.root(),
        }
    }
    current
}

/// Left or right.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Side {
    Left,
    Right,
}

/// Left/right from a name: contains `left`/`right`, or has a token starting `l_`/`r_`.
pub(super) fn side_from_name(name: &str) -> Option<Side> {
    let lower = name.to_lowercase();
    let token_prefix = |p: &str| {
        lower.match_indices(p).any(|(i, _)| {
            i == 0 || matches!(lower.as_bytes()[i - 1], b'/' | b'_' | b'-' | b'.' | b':')
        })
    };
    let left = lower.contains("left") || token_prefix("l_");
    let right = lower.contains("right") || token_prefix("r_");
    match (left, right) {
        (true, false) => Some(Side::Left),
        (false, true) => Some(Side::Right),
        _ => None,
    }
}

/// The side a tool link's name points to.
pub(super) fn side_from_tip(tree: &KinematicTree, tip: LinkId) -> Option<Side> {
    side_from_name(&tree.link(tip).name)
}
