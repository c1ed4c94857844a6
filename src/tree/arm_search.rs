//! The automatic search for a robot's arms: which leaf chains end in a hand, gripper or tool,
//! and which are legs, heads, fingers or wheels (see `docs/robots.md`).
//!
//! 1. A gripper's opening joint (a last movable joint named gripper/finger/jaw/claw, not
//!    yaw/pitch/roll/wrist) belongs to the hand, not the arm.
//! 2. A hand is a movable joint below which further chains (fingers) hang that are all shorter
//!    than the chain from the root to that joint and are not named shoulder/elbow; chains
//!    inside a hand are never arms, and the arm's tool is the hand's palm/hand link.
//! 3. A candidate is a chain of two or more movable joints from the last branching point to a
//!    leaf or a hand. Candidates named like legs, heads, fingers, cameras or wheels are never
//!    chosen; of the rest, those named like arms are preferred.
//! 4. Of more than two, the pair named left and right, then diverging furthest from the root
//!    (sharing the most torso), then the longest, wins.

use super::arm_rules::{common_ancestor, DecisionRule};
use super::{JointId, KinematicTree, LinkId};
use crate::error::{Error, Result};

/// Words that mark a chain as an arm.
const ARM_WORDS: &[&str] = &[
    "arm", "hand", "palm", "wrist", "tool", "gripper", "elbow", "shoulder", "tcp", "flange",
];
/// Words that mark a chain as something other than an arm.
const NON_ARM_WORDS: &[&str] = &[
    "leg",
    "foot",
    "hip",
    "knee",
    "ankle",
    "head",
    "neck",
    "finger",
    "thumb",
    "camera",
    "eye",
    "wheel",
    "toe",
    "caster",
    "suspension",
    "xtion",
    "lidar",
    "velodyne",
    "sole",
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
/// For an arm ending in a hand: the words tried first, in this order.
const HAND_TIP_WORDS: &[&str] = &["palm", "hand"];
/// A last joint with one of these words (and none of [`WRIST_WORDS`]) opens a gripper.
const GRIPPER_JOINT_WORDS: &[&str] = &["gripper", "finger", "jaw", "claw"];
const WRIST_WORDS: &[&str] = &["yaw", "pitch", "roll", "wrist"];
/// A chain hanging below a joint with these words is an arm, so that joint is no hand.
const LIMB_WORDS: &[&str] = &["shoulder", "elbow"];

fn has_any(name: &str, words: &[&str]) -> bool {
    let lower = name.to_lowercase();
    words.iter().any(|w| lower.contains(w))
}

/// A chain ending in a leaf or a hand, as seen by the automatic tool search.
struct Candidate {
    /// Its movable joints, root side first, from the last branching point.
    run: Vec<JointId>,
    /// Whether fingers (or a gripper's opening joint) hang below its last joint.
    hand: bool,
    /// The chosen end link.
    tip: LinkId,
}

/// The movable-joint structure the search works on.
struct Skeleton {
    /// The nearest movable joint at or above each link (None: the root's rigid body).
    body_of: Vec<Option<JointId>>,
    /// Movable joints of the arm structure below each joint (gripper openings left out).
    children: Vec<Vec<JointId>>,
    /// The gripper-opening joints below each joint.
    grippers: Vec<Vec<JointId>>,
    /// Whether a joint takes part (movable and not a gripper opening).
    member: Vec<bool>,
    /// Longest chain of member joints below each joint.
    depth_below: Vec<usize>,
    /// Member joints from the root down to each joint, itself included.
    depth_above: Vec<usize>,
}

impl Skeleton {
    fn new(tree: &KinematicTree) -> Self {
        let joints = tree.joints();
        let mut body_of: Vec<Option<JointId>> = vec![None; tree.links().len()];
        for (index, joint) in joints.iter().enumerate() {
            body_of[joint.child.0] = if joint.kind.is_movable() {
                Some(JointId(index))
            } else {
                body_of[joint.parent.0]
            };
        }
        let parent_of = |j: usize| body_of[joints[j].parent.0];
        let mut all_children: Vec<Vec<JointId>> = vec![Vec::new(); joints.len()];
        for (index, joint) in joints.iter().enumerate() {
            if let (true, Some(parent)) = (joint.kind.is_movable(), parent_of(index)) {
                all_children[parent.0].push(JointId(index));
            }
        }
        let mut member: Vec<bool> = joints.iter().map(|j| j.kind.is_movable()).collect();
        let mut grippers: Vec<Vec<JointId>> = vec![Vec::new(); joints.len()];
        for (index, joint) in joints.iter().enumerate() {
            let opening = member[index]
                && all_children[index].is_empty()
                && has_any(&joint.name, GRIPPER_JOINT_WORDS)
                && !has_any(&joint.name, WRIST_WORDS);
            if let (true, Some(parent)) = (opening, parent_of(index)) {
                member[index] = false;
                grippers[parent.0].push(JointId(index));
            }
        }
        let children: Vec<Vec<JointId>> = all_children
            .iter()
            .map(|c| c.iter().copied().filter(|j| member[j.0]).collect())
            .collect();
        // Children come after parents in the tree's joint order.
        let mut depth_below = vec![0usize; joints.len()];
        for index in (0..joints.len()).rev() {
            depth_below[index] = children[index]
                .iter()
                .map(|c| 1 + depth_below[c.0])
                .max()
                .unwrap_or(0);
        }
        let mut depth_above = vec![0usize; joints.len()];
        for index in 0..joints.len() {
            let above = parent_of(index).map_or(0, |p| depth_above[p.0]);
            depth_above[index] = above + usize::from(member[index]);
        }
        Self {
            body_of,
            children,
            grippers,
            member,
            depth_below,
            depth_above,
        }
    }

    fn parent(&self, tree: &KinematicTree, joint: JointId) -> Option<JointId> {
        self.body_of[tree.joint(joint).parent.0]
    }

    /// Whether the chains below `end` are a hand's fingers rather than limbs.
    fn is_hand(&self, tree: &KinematicTree, end: JointId) -> bool {
        let children = &self.children[end.0];
        if children.is_empty() {
            return !self.grippers[end.0].is_empty();
        }
        let limb_below = children.iter().any(|&c| {
            let joint = tree.joint(c);
            has_any(&joint.name, LIMB_WORDS) || has_any(&tree.link(joint.child).name, LIMB_WORDS)
        });
        self.depth_below[end.0] < self.depth_above[end.0] && !limb_below
    }
}

/// Chooses the arms' end links automatically, and says which rule decided.
pub(super) fn automatic_tips(tree: &KinematicTree) -> Result<(Vec<LinkId>, DecisionRule)> {
    let skeleton = Skeleton::new(tree);
    let mut candidates: Vec<Candidate> = Vec::new();
    for index in 0..tree.joints().len() {
        let end = JointId(index);
        let children = &skeleton.children[index];
        if !skeleton.member[index] || children.len() == 1 {
            continue;
        }
        let mut run = vec![end];
        let mut current = end;
        while let Some(parent) = skeleton.parent(tree, current) {
            if skeleton.children[parent.0].len() != 1 {
                break;
            }
            run.push(parent);
            current = parent;
        }
        run.reverse();
        let hand = skeleton.is_hand(tree, end);
        if run.len() < 2 || !(children.is_empty() || hand) {
            continue;
        }
        let tip = choose_tip(tree, &skeleton, end, hand);
        candidates.push(Candidate { run, hand, tip });
    }
    // Chains inside a hand (fingers) are not arms.
    let hands: Vec<LinkId> = candidates
        .iter()
        .filter(|c| c.hand)
        .filter_map(|c| c.run.last())
        .map(|&end| tree.joint(end).child)
        .collect();
    candidates.retain(|c| {
        let start = tree.joint(c.run[0]).parent;
        !hands.iter().any(|&hand| {
            hand != tree.joint(c.run[c.run.len() - 1]).child && tree.is_ancestor(hand, start)
        })
    });
    choose_arms(tree, &candidates)
}

/// The arms among the candidates, by names and structure.
fn choose_arms(
    tree: &KinematicTree,
    candidates: &[Candidate],
) -> Result<(Vec<LinkId>, DecisionRule)> {
    let names_of = |c: &Candidate| -> Vec<String> {
        let mut names: Vec<String> = c
            .run
            .iter()
            .flat_map(|&j| {
                let joint = tree.joint(j);
                [joint.name.clone(), tree.link(joint.child).name.clone()]
            })
            .collect();
        names.push(tree.link(c.tip).name.clone());
        names
    };
    let named = |c: &Candidate, words: &[&str]| names_of(c).iter().any(|n| has_any(n, words));
    let other: Vec<usize> = (0..candidates.len())
        .filter(|&i| named(&candidates[i], NON_ARM_WORDS))
        .collect();
    let arm_like: Vec<usize> = (0..candidates.len())
        .filter(|&i| !other.contains(&i) && named(&candidates[i], ARM_WORDS))
        .collect();
    let neutral: Vec<usize> = (0..candidates.len())
        .filter(|&i| !other.contains(&i) && !arm_like.contains(&i))
        .collect();
    let (pool, rule) = if arm_like.len() >= 2 || (arm_like.len() == 1 && neutral.is_empty()) {
        (arm_like, DecisionRule::ArmNames)
    } else if !arm_like.is_empty() || !other.is_empty() {
        let mut pool = arm_like;
        pool.extend(&neutral);
        (pool, DecisionRule::ArmNames)
    } else {
        (neutral, DecisionRule::Structure)
    };
    let tip = |i: usize| candidates[i].tip;
    match pool.as_slice() {
        [] => {
            let found: Vec<String> = other
                .iter()
                .map(|&i| format!("'{}'", tree.link(tip(i)).name))
                .collect();
            Err(Error::Branches(if found.is_empty() {
                "no chain of two or more movable joints ending in a leaf or a hand; name the tool links with `tools`".into()
            } else {
                format!(
                    "no arm found: the chains ending at {} are named like legs, heads, fingers or wheels; name the tool links with `tools`",
                    found.join(", ")
                )
            }))
        }
        [only] => Ok((vec![tip(*only)], rule)),
        [a, b] => Ok((vec![tip(*a), tip(*b)], rule)),
        _ => {
            let pair = best_pair(tree, candidates, &pool);
            Ok((vec![tip(pair.0), tip(pair.1)], rule))
        }
    }
}

/// Of several arm candidates, the pair named left and right, sharing the most torso (the most
/// movable joints above their common ancestor), then the longest.
fn best_pair(tree: &KinematicTree, candidates: &[Candidate], pool: &[usize]) -> (usize, usize) {
    let movable_above = |link: LinkId| {
        tree.path_from_root(link)
            .iter()
            .filter(|j| tree.joint(**j).kind.is_movable())
            .count()
    };
    let side = |i: usize| super::arm_rules::side_from_tip(tree, candidates[i].tip);
    // (named left and right, movable joints above the divergence, joints in both runs)
    type Score = (bool, usize, usize);
    let mut best: Option<(Score, (usize, usize))> = None;
    for (a, &i) in pool.iter().enumerate() {
        for &k in &pool[a + 1..] {
            let lca = common_ancestor(tree, candidates[i].tip, candidates[k].tip);
            let sides = matches!((side(i), side(k)), (Some(x), Some(y)) if x != y);
            let score = (
                sides,
                movable_above(lca),
                candidates[i].run.len() + candidates[k].run.len(),
            );
            if best.is_none_or(|(s, _)| score > s) {
                best = Some((score, (i, k)));
            }
        }
    }
    best.map_or((pool[0], pool[1]), |(_, pair)| pair)
}

/// The end link of a chain ending at movable joint `end`, in the rigid body that joint moves:
/// for a hand, the first link named palm, then hand; otherwise (or if none is) the first link
/// whose name says tool/palm/hand/…; else where that body's own sub-tree ends (the common
/// ancestor of its leaves and of the joints hanging off it).
fn choose_tip(tree: &KinematicTree, skeleton: &Skeleton, end: JointId, hand: bool) -> LinkId {
    let body: Vec<LinkId> = (0..tree.links().len())
        .map(LinkId)
        .filter(|l| skeleton.body_of[l.0] == Some(end))
        .collect();
    let first_named = |words: &[&str]| {
        words.iter().find_map(|w| {
            body.iter()
                .copied()
                .find(|l| tree.link(*l).name.to_lowercase().contains(w))
        })
    };
    let named = if hand {
        first_named(HAND_TIP_WORDS).or_else(|| {
            body.iter()
                .copied()
                .find(|l| has_any(&tree.link(*l).name, TIP_WORDS))
        })
    } else {
        body.iter()
            .copied()
            .find(|l| has_any(&tree.link(*l).name, TIP_WORDS))
    };
    if let Some(named) = named {
        return named;
    }
    let mut ends: Vec<LinkId> = body
        .iter()
        .copied()
        .filter(|l| tree.link(*l).child_joints.is_empty())
        .collect();
    let hanging = skeleton.children[end.0]
        .iter()
        .chain(&skeleton.grippers[end.0]);
    ends.extend(hanging.map(|j| tree.joint(*j).parent));
    match ends.split_first() {
        Some((&head, rest)) => rest
            .iter()
            .fold(head, |lca, &l| common_ancestor(tree, lca, l)),
        None => tree.joint(end).child,
    }
}
