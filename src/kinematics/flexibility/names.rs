//! Which MCPC body every URDF link belongs to, and what the names in a stiffness file mean.
//!
//! The body of MCPC frame i is everything its joint moves before the next calibrated joint:
//! the joint's child link, the links fixed to it, and links behind joints outside the model
//! (fingers, a head), which move relative to the body but are not calibrated. Links before the
//! first calibrated joint belong to the base, which the flexibility model treats as rigid.

use crate::error::did_you_mean;
use crate::kinematics::McpcModel;
use crate::tree::{JointKind, KinematicTree, LinkId};

/// The body a link belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Membership {
    /// Rigid on the base (before the first calibrated joint).
    Base,
    /// Part of MCPC frame `frame`'s body; `rigid` when only fixed joints lie in between.
    Body {
        /// The MCPC frame whose joint moves the link.
        frame: usize,
        /// Whether the link is fixed to the body (else behind a joint outside the model).
        rigid: bool,
    },
}

/// The robot's names, as the stiffness data may use them.
pub(crate) struct Names<'a> {
    tree: &'a KinematicTree,
    model: &'a McpcModel,
    membership: Vec<Membership>,
}

impl<'a> Names<'a> {
    /// Assigns every link of `tree` to a body of `model`.
    pub(crate) fn new(tree: &'a KinematicTree, model: &'a McpcModel) -> Self {
        let mut membership = vec![Membership::Base; tree.links().len()];
        // Links are in topological order, so a link's parent is assigned before the link.
        for (index, link) in tree.links().iter().enumerate() {
            let Some(joint_id) = link.parent_joint else {
                continue;
            };
            let joint = tree.joint(joint_id);
            membership[index] = match model.frame_of_joint(joint_id) {
                Some(frame) => Membership::Body { frame, rigid: true },
                None => match membership[joint.parent.0] {
                    Membership::Base => Membership::Base,
                    Membership::Body { frame, rigid } => Membership::Body {
                        frame,
                        rigid: rigid && joint.kind == JointKind::Fixed,
                    },
                },
            };
        }
        Self {
            tree,
            model,
            membership,
        }
    }

    /// The body of every link, in link order.
    pub(crate) fn membership(&self) -> &[Membership] {
        &self.membership
    }

    fn frame_joint_names(&self) -> impl Iterator<Item = &'a str> + 'a {
        let tree = self.tree;
        self.model
            .frames()
            .iter()
            .map(move |f| tree.joint(f.joint).name.as_str())
    }

    fn tool_names(&self) -> Vec<&'a str> {
        let tree = self.tree;
        self.model
            .tools()
            .iter()
            .map(|t| tree.link(t.link).name.as_str())
            .collect()
    }

    /// The MCPC frame of a calibrated joint named `name`, or what is wrong.
    pub(crate) fn joint(&self, name: &str) -> Result<usize, String> {
        match self.tree.joint_id(name) {
            Ok(id) => self.model.frame_of_joint(id).ok_or_else(|| {
                format!(
                    "joint '{name}' is not on a calibrated branch, so it has no compliance in the model; remove it"
                )
            }),
            Err(_) => Err(format!(
                "unknown joint '{name}'{}",
                hint_or_list(name, self.frame_joint_names().collect(), "calibrated joints")
            )),
        }
    }

    /// The tool of the tool link named `name`, or what is wrong.
    pub(crate) fn tool(&self, name: &str) -> Result<usize, String> {
        let tools = self.tool_names();
        match self.tree.link_id(name) {
            Ok(id) => self.model.tool_of_link(id).ok_or_else(|| {
                format!(
                    "link '{name}' is not a tool link; payloads go at the tool links ({})",
                    tools.join(", ")
                )
            }),
            Err(_) => Err(format!(
                "unknown link '{name}'{}",
                hint_or_list(name, tools, "payloads go at the tool links")
            )),
        }
    }

    /// The MCPC frame whose body is named by `name`: a link fixed to the body, or the
    /// calibrated joint that moves it.
    pub(crate) fn body(&self, name: &str) -> Result<usize, String> {
        if let Ok(id) = self.tree.link_id(name) {
            return match self.membership[id.0] {
                Membership::Body { frame, rigid: true } => Ok(frame),
                Membership::Body { rigid: false, .. } => Err(format!(
                    "link '{name}' moves with {}, which is not calibrated: only bodies moved by calibrated joints are beams; name the body it hangs from instead",
                    self.moving_joint(id)
                )),
                Membership::Base => Err(format!(
                    "link '{name}' is part of the base, which the model treats as rigid; remove it"
                )),
            };
        }
        if let Ok(id) = self.tree.joint_id(name) {
            return self.model.frame_of_joint(id).ok_or_else(|| {
                format!(
                    "joint '{name}' is not on a calibrated branch, so it moves no beam; remove it"
                )
            });
        }
        let candidates = self
            .tree
            .links()
            .iter()
            .zip(&self.membership)
            .filter(|(_, m)| matches!(m, Membership::Body { rigid: true, .. }))
            .map(|(l, _)| l.name.as_str())
            .chain(self.frame_joint_names())
            .collect();
        Err(format!(
            "unknown link or joint '{name}'{}",
            hint_or_list(
                name,
                candidates,
                "name a link of a calibrated body or the joint that moves it"
            )
        ))
    }

    /// "joint 'x'": the nearest movable joint above `link`.
    fn moving_joint(&self, link: LinkId) -> String {
        self.tree
            .path_from_root(link)
            .iter()
            .rev()
            .map(|&j| self.tree.joint(j))
            .find(|j| j.kind.is_movable())
            .map_or_else(|| "the base".into(), |j| format!("joint '{}'", j.name))
    }
}

/// "; did you mean 'x'?" when a candidate is close, else "; {what}: a, b, c".
fn hint_or_list(name: &str, candidates: Vec<&str>, what: &str) -> String {
    let hint = did_you_mean(name, candidates.iter().copied());
    if hint.is_empty() {
        format!("; {what}: {}", candidates.join(", "))
    } else {
        hint
    }
}
