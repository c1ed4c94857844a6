//! Branch detection: which movable joints form the coupled branch (torso) and which form
//! each arm, given the tool links or found automatically.
//!
//! The coupled branch is every movable joint on the path from the root to the link where the
//! tool chains diverge (their deepest common ancestor); each arm is the movable joints from
//! there to its tool. Joints on no selected chain (head, legs, fingers) are not part of any
//! branch.
//!
//! With a reference link other than the root (the link fixed in the world: a sole, a mobile
//! base), the same holds for the tree hung from that link: the coupled branch is the path from
//! the reference to where the tool paths diverge, each tool's branch the path from there, and a
//! path may cross joints against their URDF direction (up a leg). Joints on the root side of
//! both the reference and every tool move nothing relative to the reference and belong to no
//! branch.

pub use super::arm_rules::DecisionRule;
use super::arm_rules::{common_ancestor, side_from_name, Side};
use super::{JointId, KinematicTree, LinkId};
use crate::error::{Error, Result};

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
    /// A leg (names with leg/foot/sole/ankle/knee/hip/toe…).
    Leg,
    /// A head or neck (names with head/neck/gaze/camera/eye).
    Head,
    /// A branch whose names say neither arm, leg nor head.
    Other,
}

impl BranchRole {
    /// The role a tool branch's names point to, `None` if they say nothing: the tool link's
    /// name, then the names of the branch's joints and their links from the tool end.
    pub fn from_names<'a>(names: impl IntoIterator<Item = &'a str>) -> Option<BranchRole> {
        const LEG: &[&str] = &[
            "leg", "foot", "sole", "ankle", "knee", "hip", "toe", "thigh", "tibia", "shin",
        ];
        const HEAD: &[&str] = &["head", "neck", "gaze", "camera", "eye"];
        const ARM: &[&str] = &[
            "arm", "hand", "palm", "wrist", "gripper", "tool", "elbow", "shoulder", "tcp", "flange",
        ];
        names.into_iter().find_map(|name| {
            let lower = name.to_lowercase();
            let has = |words: &[&str]| words.iter().any(|w| lower.contains(w));
            if has(LEG) {
                Some(BranchRole::Leg)
            } else if has(HEAD) {
                Some(BranchRole::Head)
            } else if has(ARM) {
                Some(BranchRole::Arm)
            } else {
                None
            }
        })
    }

    /// The role in words (`coupled`, `left arm`, `leg`, …).
    pub fn label(self) -> &'static str {
        match self {
            BranchRole::Coupled => "coupled",
            BranchRole::Left => "left arm",
            BranchRole::Right => "right arm",
            BranchRole::Arm => "arm",
            BranchRole::Leg => "leg",
            BranchRole::Head => "head",
            BranchRole::Other => "other",
        }
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
    /// The deepest link shared by every tool chain, where the arms diverge (seen from the
    /// reference link).
    pub divergence: LinkId,
    /// The link fixed in the world while measuring (the root unless chosen).
    pub reference: LinkId,
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

    /// The branches with their roles in one line, for a whole-body model (a reference link
    /// other than the root, or a leg, head or other branch); `None` for torso-and-arms robots,
    /// whose outputs stay as they were.
    pub fn roles_summary(&self, tree: &KinematicTree) -> Option<String> {
        let whole_body = self.reference != tree.root()
            || self.arms.iter().any(|a| {
                matches!(
                    a.role,
                    BranchRole::Leg | BranchRole::Head | BranchRole::Other
                )
            });
        if !whole_body {
            return None;
        }
        let list: Vec<String> = self
            .all()
            .map(|b| {
                format!(
                    "{} '{}' ({} joints)",
                    b.role.label(),
                    b.name,
                    b.joints.len()
                )
            })
            .collect();
        Some(format!("branches: {}", list.join(", ")))
    }

    /// What a reference link other than the root makes invisible, in words (`None` for the
    /// root): its own placement, absorbed by the world-fixed measurement frame, and the
    /// movable joints on the root side of both it and every tool, which move nothing relative
    /// to it; and which joints the paths cross against their URDF direction.
    pub fn reference_summary(&self, tree: &KinematicTree) -> Option<String> {
        if self.reference == tree.root() {
            return None;
        }
        let name = &tree.link(self.reference).name;
        let shared = self
            .tools()
            .into_iter()
            .fold(self.reference, |lca, t| common_ancestor(tree, lca, t));
        let names = |joints: &[JointId]| -> String {
            joints
                .iter()
                .filter(|j| tree.joint(**j).kind.is_movable())
                .map(|j| tree.joint(*j).name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let hidden = names(&tree.path_from_root(shared));
        let mut text = format!(
            "reference link '{name}': every measurement is relative to it, so its own placement is absorbed by the world-fixed measurement frame"
        );
        if !hidden.is_empty() {
            text += &format!(
                "; joints {hidden} (on the root side of both it and every measured link) move nothing relative to it and are not calibrated"
            );
        }
        let skip = tree.path_from_root(shared).len();
        let against = names(&tree.path_from_root(self.reference)[skip..]);
        if !against.is_empty() {
            text += &format!(
                "; joints {against} are crossed from '{name}' against their URDF direction (their parameters still place the URDF's joint origins)"
            );
        }
        Some(text)
    }
}

/// Finds the coupled branch and the arms. With `tools`, those links end the arms; without,
/// the two arm end links are chosen automatically (see `docs/mcpc.md`).
pub fn detect_branches(tree: &KinematicTree, tools: Option<&[LinkId]>) -> Result<Branches> {
    detect_branches_from(tree, tools, tree.root())
}

/// [`detect_branches`] for a robot measured with link `reference` fixed in the world: every
/// movable joint on a path between the reference and a tool is in a branch.
pub fn detect_branches_from(
    tree: &KinematicTree,
    tools: Option<&[LinkId]>,
    reference: LinkId,
) -> Result<Branches> {
    let (tips, selection) = match tools {
        Some(tools) => (tools.to_vec(), DecisionRule::GivenTools),
        None => super::arm_search::automatic_tips(tree)?,
    };
    if tips.is_empty() {
        return Err(Error::Branches("no tool links given".into()));
    }
    if let Some(&tip) = tips.iter().find(|&&t| t == reference) {
        return Err(Error::Branches(format!(
            "tool link '{}' is the reference link; a link fixed in the world cannot be measured",
            tree.link(tip).name
        )));
    }
    for (i, &a) in tips.iter().enumerate() {
        for &b in &tips[i + 1..] {
            if a == b {
                return Err(Error::Branches(format!(
                    "tool link '{}' is named twice",
                    tree.link(a).name
                )));
            }
            let meeting = meeting_link(tree, reference, a, b);
            if meeting == a || meeting == b {
                let (upper, lower) = if meeting == a { (a, b) } else { (b, a) };
                return Err(Error::Branches(format!(
                    "tool link '{}' lies on the chain of tool link '{}'; tools must be on different branches",
                    tree.link(upper).name,
                    tree.link(lower).name
                )));
            }
        }
    }

    let divergence = if tips.len() == 1 {
        reference
    } else {
        tips.iter()
            .skip(1)
            .fold(tips[0], |lca, &t| meeting_link(tree, reference, lca, t))
    };
    let movable_on = |from: LinkId, to: LinkId| -> Vec<JointId> {
        tree.path_between(from, to)
            .into_iter()
            .filter(|j| tree.joint(*j).kind.is_movable())
            .collect()
    };
    let coupled = Branch {
        name: if reference == tree.root() {
            "torso".into()
        } else {
            "coupled".into()
        },
        role: BranchRole::Coupled,
        start: reference,
        joints: movable_on(reference, divergence),
        tool: None,
    };
    let mut arms: Vec<Branch> = tips
        .iter()
        .map(|&tip| {
            let joints = movable_on(divergence, tip);
            let role = tool_role(tree, tip, &joints);
            Branch {
                name: tree.link(tip).name.clone(),
                role: role.unwrap_or(BranchRole::Arm),
                start: divergence,
                joints,
                tool: Some(tip),
            }
        })
        .collect();
    let all_arms = arms.iter().all(|a| {
        matches!(
            tool_role(tree, a.tool.unwrap_or(a.start), &a.joints),
            None | Some(BranchRole::Arm)
        )
    });
    for arm in arms
        .iter_mut()
        .filter(|a| !all_arms && a.role == BranchRole::Arm)
    {
        if tool_role(tree, arm.tool.unwrap_or(arm.start), &arm.joints).is_none() {
            arm.role = BranchRole::Other;
        }
    }

    // Two tools of one kind (two arms, two legs) are told left from right.
    let pair = arms.len() == 2 && (all_arms || arms[0].role == arms[1].role);
    let sides = if pair {
        let rule = assign_sides(tree, &mut arms, selection)?;
        if all_arms {
            arms[0].name = "left_arm".into();
            arms[0].role = BranchRole::Left;
            arms[1].name = "right_arm".into();
            arms[1].role = BranchRole::Right;
        } else if arms[0].role == BranchRole::Leg {
            arms[0].name = "left_leg".into();
            arms[1].name = "right_leg".into();
        }
        rule
    } else {
        DecisionRule::NoSides
    };
    Ok(Branches {
        coupled,
        arms,
        divergence,
        reference,
        selection,
        sides,
    })
}

/// The role of the branch ending at `tip` with `joints`, from their names (tool end first).
fn tool_role(tree: &KinematicTree, tip: LinkId, joints: &[JointId]) -> Option<BranchRole> {
    let names =
        std::iter::once(tree.link(tip).name.as_str()).chain(joints.iter().rev().flat_map(|&j| {
            let joint = tree.joint(j);
            [joint.name.as_str(), tree.link(joint.child).name.as_str()]
        }));
    BranchRole::from_names(names)
}

/// Where the paths from `reference` to `a` and to `b` part: the common ancestor of `a` and `b`
/// in the tree hung from `reference` (the deepest of the three pairwise common ancestors).
pub(super) fn meeting_link(
    tree: &KinematicTree,
    reference: LinkId,
    a: LinkId,
    b: LinkId,
) -> LinkId {
    let depth = |link: LinkId| tree.path_from_root(link).len();
    [
        common_ancestor(tree, reference, a),
        common_ancestor(tree, reference, b),
        common_ancestor(tree, a, b),
    ]
    .into_iter()
    .max_by_key(|&l| depth(l))
    .unwrap_or(reference)
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
            "cannot tell left from right for tools '{}' and '{}' (neither names nor y decide); name them with `tools` LEFT,RIGHT",
            tree.link(arms[0].tool.unwrap_or(arms[0].start)).name,
            tree.link(arms[1].tool.unwrap_or(arms[1].start)).name
        )))
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
