//! Branch detection: which movable joints form the coupled branch (torso) and which form
//! each arm, given the tool links or found automatically.
//!
//! The coupled branch is every movable joint on the path from the root to the link where the
//! tool chains diverge (their deepest common ancestor); each arm is the movable joints from
//! there to its tool. Joints on no selected chain (head, legs, fingers) are not part of any
//! branch.

use super::{JointId, KinematicTree, LinkId};
use crate::error::{Error, Result};
use std::fmt;

/// What a branch is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BranchRole {
    /// The coupled branch (torso): shared by every arm.
    Coupled,
    /// The left arm of a two-arm robot.
    Left,
    /// The right arm of a two-arm robot.
    Right,
    /// An arm of a robot with one or more than two named tools.
    Arm,
}

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
            DecisionRule::ArmNames => "automatic: chains whose joint or link names look like arms",
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

/// A set of movable joints calibrated together.
#[derive(Debug, Clone, PartialEq)]
pub struct Branch {
    /// `torso`, `left_arm`, `right_arm`, or the tool link's name.
    pub name: String,
    /// The branch's role.
    pub role: BranchRole,
    /// The link the branch starts from (root for the coupled branch, the divergence link for arms).
    pub start: LinkId,
    /// Movable joints, root side first.
    pub joints: Vec<JointId>,
    /// The tool link at the end of an arm; `None` for the coupled branch.
    pub tool: Option<LinkId>,
}

impl Branch {
    /// The configuration-vector indices of the branch's independent joints (mimic joints,
    /// which follow another joint, have none).
    pub fn dofs(&self, tree: &KinematicTree) -> Vec<usize> {
        self.joints
            .iter()
            .filter_map(|j| tree.dof_of(*j))
            .map(|d| d.0)
            .collect()
    }
}

/// The coupled branch and the arms of a robot.
#[derive(Debug, Clone, PartialEq)]
pub struct Branches {
    /// The movable joints from the root to the divergence link.
    pub coupled: Branch,
    /// One branch per tool: left then right for two-arm robots, otherwise in the tools' order.
    pub arms: Vec<Branch>,
    /// The deepest link shared by every tool chain, where the arms diverge.
    pub divergence: LinkId,
    /// How the tools were chosen.
    pub selection: DecisionRule,
    /// How left and right were told apart.
    pub sides: DecisionRule,
}

impl Branches {
    /// The name of the arm ending at tool link `tool` (`"tool <link index>"` if none does).
    pub fn arm_name(&self, tool: LinkId) -> String {
        self.arms
            .iter()
            .find(|a| a.tool == Some(tool))
            .map(|a| a.name.clone())
            .unwrap_or_else(|| format!("tool {}", tool.0))
    }

    /// The tool links, in arm order.
    pub fn tools(&self) -> Vec<LinkId> {
        self.arms.iter().filter_map(|a| a.tool).collect()
    }

    /// All branches, coupled first.
    pub fn all(&self) -> impl Iterator<Item = &Branch> {
        std::iter::once(&self.coupled).chain(self.arms.iter())
    }
}

/// Finds the coupled branch and the arms. With `tools`, those links end the arms; without,
/// the two arm end links are chosen automatically (see `docs/mcpc.md`).
pub fn detect_branches(tree: &KinematicTree, tools: Option<&[LinkId]>) -> Result<Branches> {
    let (tips, selection) = match tools {
        Some(tools) => (tools.to_vec(), DecisionRule::GivenTools),
        None => automatic_tips(tree)?,
    };
    if tips.is_empty() {
        return Err(Error::Branches("no tool links given".into()));
    }
    for (i, &a) in tips.iter().enumerate() {
        for &b in &tips[i + 1..] {
            if a == b {
                return Err(Error::Branches(format!(
                    "tool link '{}' is named twice",
                    tree.link(a).name
                )));
            }
            let (upper, lower) = if tree.is_ancestor(a, b) {
                (a, b)
            } else {
                (b, a)
            };
            if tree.is_ancestor(upper, lower) {
                return Err(Error::Branches(format!(
                    "tool link '{}' lies on the chain of tool link '{}'; tools must be on different branches",
                    tree.link(upper).name,
                    tree.link(lower).name
                )));
            }
        }
    }

    let divergence = if tips.len() == 1 {
        tree.root()
    } else {
        tips.iter()
            .skip(1)
            .fold(tips[0], |lca, &t| common_ancestor(tree, lca, t))
    };
    let movable_on = |from: LinkId, to: LinkId| -> Vec<JointId> {
        let skip = tree.path_from_root(from).len();
        tree.path_from_root(to)
            .into_iter()
            .skip(skip)
            .filter(|j| tree.joint(*j).kind.is_movable())
            .collect()
    };
    let coupled = Branch {
        name: "torso".into(),
        role: BranchRole::Coupled,
        start: tree.root(),
        joints: movable_on(tree.root(), divergence),
        tool: None,
    };
    let mut arms: Vec<Branch> = tips
        .iter()
        .map(|&tip| Branch {
            name: tree.link(tip).name.clone(),
            role: BranchRole::Arm,
            start: divergence,
            joints: movable_on(divergence, tip),
            tool: Some(tip),
        })
        .collect();

    let sides = if arms.len() == 2 {
        let rule = assign_sides(tree, &mut arms, selection)?;
        arms[0].name = "left_arm".into();
        arms[0].role = BranchRole::Left;
        arms[1].name = "right_arm".into();
        arms[1].role = BranchRole::Right;
        rule
    } else {
        DecisionRule::NoSides
    };
    Ok(Branches {
        coupled,
        arms,
        divergence,
        selection,
        sides,
    })
}

fn common_ancestor(tree: &KinematicTree, a: LinkId, b: LinkId) -> LinkId {
    let mut current = a;
    while !tree.is_ancestor(current, b) {
        match tree.link(current).parent_joint {
            Some(j) => current = tree.joint(j).parent,
            None => return tree.root(),
        }
    }
    current
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    Left,
    Right,
}

/// Left/right from a name: contains `left`/`right`, or has a token starting `l_`/`r_`.
fn side_from_name(name: &str) -> Option<Side> {
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

/// The side the names of an arm point to: the tool link's name, else a majority of the arm's
/// joint and link names.
fn side_of_arm(tree: &KinematicTree, arm: &Branch) -> Option<Side> {
    let tool = arm.tool?;
    if let Some(side) = side_from_name(&tree.link(tool).name) {
        return Some(side);
    }
    let mut score = 0i32;
    for &j in &arm.joints {
        let joint = tree.joint(j);
        for name in [&joint.name, &tree.link(joint.child).name] {
            match side_from_name(name) {
                Some(Side::Left) => score += 1,
                Some(Side::Right) => score -= 1,
                None => {}
            }
        }
    }
    match score.cmp(&0) {
        std::cmp::Ordering::Greater => Some(Side::Left),
        std::cmp::Ordering::Less => Some(Side::Right),
        std::cmp::Ordering::Equal => None,
    }
}

/// Orders two arms left then right and says which rule decided.
fn assign_sides(
    tree: &KinematicTree,
    arms: &mut [Branch],
    selection: DecisionRule,
) -> Result<DecisionRule> {
    let sides = (side_of_arm(tree, &arms[0]), side_of_arm(tree, &arms[1]));
    match sides {
        (Some(Side::Left), Some(Side::Right)) => return Ok(DecisionRule::SideNames),
        (Some(Side::Right), Some(Side::Left)) => {
            arms.swap(0, 1);
            return Ok(DecisionRule::SideNames);
        }
        _ => {}
    }
    let q = tree.zero_configuration();
    let y = |arm: &Branch| -> Result<f64> {
        let tool = arm.tool.unwrap_or(arm.start);
        Ok(tree.link_pose(tool, &q)?.translation.vector.y)
    };
    let (y0, y1) = (y(&arms[0])?, y(&arms[1])?);
    if (y0 - y1).abs() > 1e-9 {
        if y1 > y0 {
            arms.swap(0, 1);
        }
        Ok(DecisionRule::SideY)
    } else if selection == DecisionRule::GivenTools {
        Ok(DecisionRule::GivenOrder)
    } else {
        Err(Error::Branches(format!(
            "cannot tell left from right for tools '{}' and '{}' (neither names nor y decide); name them with --tools LEFT,RIGHT",
            tree.link(arms[0].tool.unwrap_or(arms[0].start)).name,
            tree.link(arms[1].tool.unwrap_or(arms[1].start)).name
        )))
    }
}

/// Words that mark a chain as an arm, and words that mark it as something else.
const ARM_WORDS: &[&str] = &[
    "arm", "hand", "palm", "wrist", "tool", "gripper", "elbow", "shoulder", "tcp", "flange",
];
const NON_ARM_WORDS: &[&str] = &[
    "leg", "foot", "hip", "knee", "ankle", "head", "neck", "finger", "thumb", "camera", "eye",
    "wheel", "toe",
];
/// Words that mark a link as the end-effector link of an arm's last rigid body.
const TIP_WORDS: &[&str] = &[
    "tool",
    "tcp",
    "end_effector",
    "eef",
    "ee_link",
    "palm",
    "hand",
    "gripper",
    "flange",
];

/// A chain ending in a leaf or a hand, as seen by the automatic tool search.
struct Candidate {
    /// The last movable joint of the chain.
    end: JointId,
    /// Its movable joints, root side first, from the last branching point.
    run: Vec<JointId>,
    /// The chosen end link.
    tip: LinkId,
}

fn automatic_tips(tree: &KinematicTree) -> Result<(Vec<LinkId>, DecisionRule)> {
    let joints = tree.joints();
    // The nearest movable joint at or above each link (None: the root's rigid body).
    let mut body_of: Vec<Option<JointId>> = vec![None; tree.links().len()];
    for (index, joint) in joints.iter().enumerate() {
        body_of[joint.child.0] = if joint.kind.is_movable() {
            Some(JointId(index))
        } else {
            body_of[joint.parent.0]
        };
    }
    let movable_parent = |j: JointId| body_of[joints[j.0].parent.0];
    let mut movable_children: Vec<Vec<JointId>> = vec![Vec::new(); joints.len()];
    for (index, joint) in joints.iter().enumerate() {
        if joint.kind.is_movable() {
            if let Some(parent) = movable_parent(JointId(index)) {
                movable_children[parent.0].push(JointId(index));
            }
        }
    }
    // Longest chain of movable joints below each joint (children come after parents).
    let mut depth_below = vec![0usize; joints.len()];
    for index in (0..joints.len()).rev() {
        depth_below[index] = movable_children[index]
            .iter()
            .map(|c| 1 + depth_below[c.0])
            .max()
            .unwrap_or(0);
    }

    let mut candidates: Vec<Candidate> = Vec::new();
    for (index, joint) in joints.iter().enumerate() {
        let end = JointId(index);
        let children = &movable_children[index];
        if !joint.kind.is_movable() || children.len() == 1 {
            continue;
        }
        let mut run = vec![end];
        let mut current = end;
        while let Some(parent) = movable_parent(current) {
            if movable_children[parent.0].len() != 1 {
                break;
            }
            run.push(parent);
            current = parent;
        }
        run.reverse();
        // A hand: a branching whose sub-chains (fingers) are all shorter than the arm itself.
        let is_hand = !children.is_empty() && depth_below[index] < run.len();
        if run.len() < 2 || !(children.is_empty() || is_hand) {
            continue;
        }
        let tip = choose_tip(tree, end, &body_of, children);
        candidates.push(Candidate { end, run, tip });
    }
    // Chains inside a hand (fingers) are not arms.
    let all_ends: Vec<(JointId, bool)> = candidates
        .iter()
        .map(|c| (c.end, !movable_children[c.end.0].is_empty()))
        .collect();
    candidates.retain(|c| {
        !all_ends.iter().any(|&(other, is_hand)| {
            is_hand
                && other != c.end
                && tree.is_ancestor(joints[other.0].child, joints[c.run[0].0].parent)
        })
    });

    let names_of = |c: &Candidate| -> Vec<String> {
        let mut names: Vec<String> = c
            .run
            .iter()
            .flat_map(|j| {
                [
                    joints[j.0].name.to_lowercase(),
                    tree.link(joints[j.0].child).name.to_lowercase(),
                ]
            })
            .collect();
        names.push(tree.link(c.tip).name.to_lowercase());
        names
    };
    let has_word = |c: &Candidate, words: &[&str]| {
        names_of(c)
            .iter()
            .any(|n| words.iter().any(|w| n.contains(w)))
    };
    let arm_like: Vec<usize> = (0..candidates.len())
        .filter(|&i| {
            has_word(&candidates[i], ARM_WORDS) && !has_word(&candidates[i], NON_ARM_WORDS)
        })
        .collect();
    let not_other: Vec<usize> = (0..candidates.len())
        .filter(|&i| !has_word(&candidates[i], NON_ARM_WORDS))
        .collect();
    let (pool, mut rule) = if arm_like.len() >= 2 {
        (arm_like, DecisionRule::ArmNames)
    } else if not_other.len() >= 2 && not_other.len() < candidates.len() {
        (not_other, DecisionRule::ArmNames)
    } else {
        ((0..candidates.len()).collect(), DecisionRule::Structure)
    };
    match pool.len() {
        0 => Err(Error::Branches(
            "no arm-like chain of two or more movable joints found; name the tool links with --tools".into(),
        )),
        1 => Ok((vec![candidates[pool[0]].tip], rule)),
        2 => Ok((pool.iter().map(|&i| candidates[i].tip).collect(), rule)),
        _ => {
            // The arms share the most torso: the pair whose common ancestor has the most movable
            // joints above it; then the longest pair of chains.
            let movable_above = |link: LinkId| {
                tree.path_from_root(link)
                    .iter()
                    .filter(|j| joints[j.0].kind.is_movable())
                    .count()
            };
            let mut best: Option<((usize, usize), (usize, usize))> = None;
            for (a, &i) in pool.iter().enumerate() {
                for &k in &pool[a + 1..] {
                    let lca = common_ancestor(tree, candidates[i].tip, candidates[k].tip);
                    let score = (movable_above(lca), candidates[i].run.len() + candidates[k].run.len());
                    if best.is_none_or(|(s, _)| score > s) {
                        best = Some((score, (i, k)));
                    }
                }
            }
            rule = if rule == DecisionRule::ArmNames { DecisionRule::ArmNames } else { DecisionRule::Structure };
            let (_, (i, k)) = best.ok_or_else(|| Error::Branches("no pair of arms found".into()))?;
            Ok((vec![candidates[i].tip, candidates[k].tip], rule))
        }
    }
}

/// The end link of a chain ending at movable joint `end`: in the rigid body the joint moves,
/// the first link whose name says tool/palm/hand/…; else where that body's own sub-tree ends
/// (the common ancestor of its leaves and of the joints hanging off it).
fn choose_tip(
    tree: &KinematicTree,
    end: JointId,
    body_of: &[Option<JointId>],
    movable_children: &[JointId],
) -> LinkId {
    let body: Vec<LinkId> = (0..tree.links().len())
        .map(LinkId)
        .filter(|l| body_of[l.0] == Some(end))
        .collect();
    if let Some(&named) = body.iter().find(|l| {
        let name = tree.link(**l).name.to_lowercase();
        TIP_WORDS.iter().any(|w| name.contains(w))
    }) {
        return named;
    }
    let mut ends: Vec<LinkId> = body
        .iter()
        .copied()
        .filter(|l| tree.link(*l).child_joints.is_empty())
        .collect();
    ends.extend(movable_children.iter().map(|j| tree.joint(*j).parent));
    let first = tree.joint(end).child;
    match ends.split_first() {
        Some((&head, rest)) => rest
            .iter()
            .fold(head, |lca, &l| common_ancestor(tree, lca, l)),
        None => first,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn side_names() {
        assert!(matches!(side_from_name("left_tool"), Some(Side::Left)));
        assert!(matches!(side_from_name("r2/right_palm"), Some(Side::Right)));
        assert!(matches!(side_from_name("l_hand"), Some(Side::Left)));
        assert!(matches!(side_from_name("arm_r_link"), Some(Side::Right)));
        assert!(side_from_name("pedal_link").is_none());
        assert!(side_from_name("tool").is_none());
    }
}
