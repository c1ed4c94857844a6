//! The kinematic tree: links and joints in topological order, with parent indices.
//!
//! This is the robot as the URDF describes it, with nothing about calibration in it. Links are
//! stored root first and every link after the root has exactly one parent joint, so
//! `joints[j]` always connects an earlier link to a later one and one forward sweep computes
//! every link pose ([`KinematicTree::link_poses`]).

mod arm_rules;
mod arm_search;
mod branches;
mod geometry;
mod limbs;

pub use branches::{
    detect_branches, detect_branches_from, Branch, BranchRole, Branches, DecisionRule,
};
pub use geometry::{Inertial, LinkGeometry, Shape};
pub use limbs::{limbs, Limb};

use crate::error::{Error, Result};
use crate::math::{pose, rot_axis, Pose, Vec3};
use nalgebra::Unit;

/// Index of a link in [`KinematicTree::links`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct LinkId(pub usize);

/// Index of a joint in [`KinematicTree::joints`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct JointId(pub usize);

/// Index of an independent joint variable in a configuration vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct DofId(pub usize);

/// What a joint lets move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// No motion; the joint is a constant transform.
    Fixed,
    /// Rotation about the axis, with limits.
    Revolute,
    /// Rotation about the axis, without limits.
    Continuous,
    /// Translation along the axis.
    Prismatic,
}

impl JointKind {
    /// Whether the joint has a joint variable.
    pub fn is_movable(self) -> bool {
        !matches!(self, JointKind::Fixed)
    }

    /// Whether the joint rotates (revolute or continuous).
    pub fn is_rotational(self) -> bool {
        matches!(self, JointKind::Revolute | JointKind::Continuous)
    }

    /// The URDF spelling.
    pub fn urdf_name(self) -> &'static str {
        match self {
            JointKind::Fixed => "fixed",
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
        }
    }
}

/// Where a movable joint's value comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Actuation {
    /// A fixed joint: no value.
    None,
    /// An independent joint variable.
    Independent(DofId),
    /// A mimic joint: `value = multiplier · q[master] + offset` (chains of mimics are resolved
    /// to the independent joint at their end).
    Mimic {
        /// The independent variable the joint follows.
        master: DofId,
        /// Factor on the master's value.
        multiplier: f64,
        /// Added after scaling (rad or m).
        offset: f64,
    },
}

impl Actuation {
    /// The independent joint variable that drives the joint (its own, or a mimic's master);
    /// `None` for a fixed joint.
    pub fn driver(&self) -> Option<DofId> {
        match *self {
            Actuation::Independent(dof) | Actuation::Mimic { master: dof, .. } => Some(dof),
            Actuation::None => None,
        }
    }
}

/// Joint position limits (rad or m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
}

/// A link: a rigid body with its own frame.
#[derive(Debug, Clone)]
pub struct Link {
    /// The URDF name.
    pub name: String,
    /// The joint that carries this link; `None` for the root.
    pub parent_joint: Option<JointId>,
    /// The joints that hang off this link, in file order.
    pub child_joints: Vec<JointId>,
    /// Mass properties, if the URDF gives them.
    pub inertial: Option<Inertial>,
    /// Collision and visual shapes (kept for self-collision checks; never needed for kinematics).
    pub geometry: LinkGeometry,
}

/// A joint: a constant placement followed by a motion about or along a unit axis.
#[derive(Debug, Clone)]
pub struct Joint {
    /// The URDF name.
    pub name: String,
    /// The joint type.
    pub kind: JointKind,
    /// The link the joint is attached to.
    pub parent: LinkId,
    /// The link the joint moves.
    pub child: LinkId,
    /// The URDF `<origin>`: pose of the joint frame in the parent link frame.
    pub parent_from_joint: Pose,
    /// The motion axis in the joint frame, normalised (meaningless for fixed joints).
    pub axis: Unit<Vec3>,
    /// Position limits, if bounded (revolute and prismatic joints).
    pub limits: Option<Limits>,
    /// Where the joint's value comes from.
    pub actuation: Actuation,
}

impl Joint {
    /// The pose of the child link frame in the parent link frame for joint value `value`.
    pub fn parent_from_child(&self, value: f64) -> Pose {
        match self.kind {
            JointKind::Fixed => self.parent_from_joint,
            JointKind::Revolute | JointKind::Continuous => {
                self.parent_from_joint * pose(Vec3::zeros(), rot_axis(&self.axis, value))
            }
            JointKind::Prismatic => {
                self.parent_from_joint * pose(self.axis.into_inner() * value, Default::default())
            }
        }
    }
}

/// A robot's kinematic tree, root first.
#[derive(Debug, Clone)]
pub struct KinematicTree {
    name: String,
    links: Vec<Link>,
    joints: Vec<Joint>,
    dofs: Vec<JointId>,
}

impl KinematicTree {
    /// Builds a tree from links in topological order and joints whose parents come first.
    ///
    /// Used by the URDF importer, which has already checked names, cycles and roots; this
    /// re-checks the ordering invariants so that no later sweep can index out of order.
    pub(crate) fn from_parts(
        name: String,
        links: Vec<Link>,
        joints: Vec<Joint>,
        dofs: Vec<JointId>,
    ) -> Result<Self> {
        for (index, joint) in joints.iter().enumerate() {
            let ordered = joint.parent.0 < joint.child.0
                && joint.child.0 < links.len()
                && links[joint.child.0].parent_joint == Some(JointId(index));
            if !ordered {
                return Err(Error::InvalidRobot {
                    origin: name,
                    message: format!("joint '{}' is not in topological order", joint.name),
                });
            }
        }
        Ok(Self {
            name,
            links,
            joints,
            dofs,
        })
    }

    /// Adds link `name` on a fixed joint `<name>_joint` at the origin of link `parent` (a
    /// marker point measured on that link, whose offset is then calibrated as a tool); the
    /// ordering invariants hold because the new link and joint come last.
    pub fn add_marker_link(&mut self, name: &str, parent: LinkId) -> Result<LinkId> {
        let joint_name = format!("{name}_joint");
        if self.link_id(name).is_ok() || self.joint_id(&joint_name).is_ok() {
            return Err(Error::InvalidRobot {
                origin: self.name.clone(),
                message: format!(
                    "a link '{name}' or joint '{joint_name}' exists already; name the measured point differently"
                ),
            });
        }
        let link = LinkId(self.links.len());
        let joint = JointId(self.joints.len());
        self.links[parent.0].child_joints.push(joint);
        self.links.push(Link {
            name: name.to_owned(),
            parent_joint: Some(joint),
            child_joints: Vec::new(),
            inertial: None,
            geometry: LinkGeometry::default(),
        });
        self.joints.push(Joint {
            name: joint_name,
            kind: JointKind::Fixed,
            parent,
            child: link,
            parent_from_joint: Pose::identity(),
            axis: Vec3::z_axis(),
            limits: None,
            actuation: Actuation::None,
        });
        Ok(link)
    }

    /// The robot's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// All links, root first, parents before children.
    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// All joints, in the order of the links they carry.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// The root link.
    pub fn root(&self) -> LinkId {
        LinkId(0)
    }

    /// The link with this id.
    pub fn link(&self, id: LinkId) -> &Link {
        &self.links[id.0]
    }

    /// The joint with this id.
    pub fn joint(&self, id: JointId) -> &Joint {
        &self.joints[id.0]
    }

    /// The independent joints, in configuration-vector order (topological order).
    pub fn dofs(&self) -> &[JointId] {
        &self.dofs
    }

    /// Number of independent joint variables.
    pub fn dof_count(&self) -> usize {
        self.dofs.len()
    }

    /// Looks a link up by name.
    pub fn link_id(&self, name: &str) -> Result<LinkId> {
        self.links
            .iter()
            .position(|l| l.name == name)
            .map(LinkId)
            .ok_or_else(|| Error::UnknownLink {
                name: name.to_owned(),
                hint: crate::error::did_you_mean(name, self.links.iter().map(|l| l.name.as_str())),
            })
    }

    /// Looks a joint up by name.
    pub fn joint_id(&self, name: &str) -> Result<JointId> {
        self.joints
            .iter()
            .position(|j| j.name == name)
            .map(JointId)
            .ok_or_else(|| Error::UnknownJoint {
                name: name.to_owned(),
                hint: crate::error::did_you_mean(name, self.joints.iter().map(|j| j.name.as_str())),
            })
    }

    /// The configuration-vector index of an independent joint, `None` for fixed and mimic joints.
    pub fn dof_of(&self, joint: JointId) -> Option<DofId> {
        match self.joints[joint.0].actuation {
            Actuation::Independent(dof) => Some(dof),
            _ => None,
        }
    }

    /// Checks that `q` has one value per independent joint.
    pub fn check_configuration(&self, q: &[f64]) -> Result<()> {
        if q.len() == self.dofs.len() {
            Ok(())
        } else {
            Err(Error::ConfigurationSize {
                expected: self.dofs.len(),
                got: q.len(),
            })
        }
    }

    /// The value of one joint at configuration `q` (0 for fixed joints; mimic joints follow
    /// their master). `q` must have [`Self::dof_count`] entries.
    pub fn joint_value(&self, joint: JointId, q: &[f64]) -> f64 {
        match self.joints[joint.0].actuation {
            Actuation::None => 0.0,
            Actuation::Independent(dof) => q[dof.0],
            Actuation::Mimic {
                master,
                multiplier,
                offset,
            } => multiplier * q[master.0] + offset,
        }
    }

    /// Pose of every link in the root frame at configuration `q`, straight from the URDF
    /// description (no MCPC): the reference forward kinematics.
    pub fn link_poses(&self, q: &[f64]) -> Result<Vec<Pose>> {
        self.check_configuration(q)?;
        let mut root_from_link = Vec::with_capacity(self.links.len());
        root_from_link.push(Pose::identity());
        for (index, joint) in self.joints.iter().enumerate() {
            let value = self.joint_value(JointId(index), q);
            let pose = root_from_link[joint.parent.0] * joint.parent_from_child(value);
            root_from_link.push(pose);
        }
        Ok(root_from_link)
    }

    /// Pose of one link in the root frame at configuration `q`, walking only its ancestors.
    pub fn link_pose(&self, link: LinkId, q: &[f64]) -> Result<Pose> {
        self.check_configuration(q)?;
        let mut root_from_link = Pose::identity();
        for joint in self.path_from_root(link) {
            let value = self.joint_value(joint, q);
            root_from_link *= self.joints[joint.0].parent_from_child(value);
        }
        Ok(root_from_link)
    }

    /// The joints (fixed included) from the root down to `link`, root side first.
    pub fn path_from_root(&self, link: LinkId) -> Vec<JointId> {
        let mut path = Vec::new();
        let mut current = link;
        while let Some(joint) = self.links[current.0].parent_joint {
            path.push(joint);
            current = self.joints[joint.0].parent;
        }
        path.reverse();
        path
    }

    /// The joints (fixed included) on the path from link `from` to link `to`, in the order
    /// the path crosses them: first up from `from` towards the root (joints traversed against
    /// their URDF direction), then down to `to`.
    pub fn path_between(&self, from: LinkId, to: LinkId) -> Vec<JointId> {
        let up = self.path_from_root(from);
        let down = self.path_from_root(to);
        let shared = up.iter().zip(&down).take_while(|(a, b)| a == b).count();
        let mut path: Vec<JointId> = up[shared..].iter().rev().copied().collect();
        path.extend_from_slice(&down[shared..]);
        path
    }

    /// Whether `ancestor` lies on the path from the root to `link` (a link is its own ancestor).
    pub fn is_ancestor(&self, ancestor: LinkId, link: LinkId) -> bool {
        let mut current = link;
        loop {
            if current == ancestor {
                return true;
            }
            match self.links[current.0].parent_joint {
                Some(joint) => current = self.joints[joint.0].parent,
                None => return false,
            }
        }
    }

    /// The all-zero configuration.
    pub fn zero_configuration(&self) -> Vec<f64> {
        vec![0.0; self.dofs.len()]
    }

    /// The limits of each independent joint, `None` where unbounded.
    pub fn dof_limits(&self) -> Vec<Option<Limits>> {
        self.dofs.iter().map(|j| self.joints[j.0].limits).collect()
    }
}
