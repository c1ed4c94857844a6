//! The MCPC model (paper section 2.2, eq. (1)–(4)) of the selected branches of a tree.
//!
//! Every movable joint on a branch gets a frame Σᵢ on its axis (z along the axis, origin at
//! the foot of the perpendicular from the previous frame's origin) and the transform
//!
//! ```text
//! prev_from_frame = Q(θ_prev) · Rz(φ) · Rx(α) · Ry(β) · Trans(x, y, 0)      (eq. (1))
//! prev_from_tool  = Q(θ_last) · Rz(φ) · Rx(α) · Ry(β) · Rz(γ) · Trans(x, y, z)   (eq. (2))
//! ```
//!
//! where `Q` is the previous joint's motion (rotation about, or translation along, its z).
//! `φ` is a constant, not a parameter: the zero-offset choice that keeps every nominal |β|
//! at or below 60° so the model never sits on the MCPC singularity β = ±90° (where α and the
//! rotation about the new axis become the same motion and the identification Jacobian loses
//! rank). Prismatic joints keep only (α, β): their origin is placed at the previous frame's
//! origin, since the position of a translation axis has no effect. See `docs/mcpc.md`.

use crate::error::{Error, Result};
use crate::math::{
    pose, rot_x, rot_y, rot_z, wrap_angle, xyz_angles_from_rotation, Pose, Rotation, Transform,
    Vec3,
};
use crate::tree::{Actuation, Branches, JointId, JointKind, KinematicTree, LinkId};
use std::f64::consts::FRAC_PI_2;

mod from_tree;
mod parameters;

/// |β| above this (60°) triggers the re-parametrisation by φ = 90°, after which |β| < 30°.
///
/// Any |β| up to 60° keeps cos β ≥ 0.5, far from the singularity; 60° rather than 45° because
/// 45° axes are common in real robots and a nominal value exactly at the threshold would make
/// the choice hinge on rounding.
pub const SINGULARITY_THRESHOLD: f64 = std::f64::consts::FRAC_PI_3;

/// `Rz(φ)·Rx(α)·Ry(β)·Trans(x, y, 0)`: a joint frame in the previous moved frame (eq. (1)).
pub fn frame_transform(phi: f64, alpha: f64, beta: f64, x: f64, y: f64) -> Pose {
    pose(
        Vec3::new(0.0, 0.0, 0.0),
        rot_z(phi) * rot_x(alpha) * rot_y(beta),
    ) * pose(Vec3::new(x, y, 0.0), Rotation::identity())
}

/// `Rz(φ)·Rx(α)·Ry(β)·Rz(γ)·Trans(x, y, z)`: a tool frame in the last moved frame (eq. (2)).
pub fn tool_transform(phi: f64, alpha: f64, beta: f64, gamma: f64, x: f64, y: f64, z: f64) -> Pose {
    pose(
        Vec3::new(0.0, 0.0, 0.0),
        rot_z(phi) * rot_x(alpha) * rot_y(beta) * rot_z(gamma),
    ) * pose(Vec3::new(x, y, z), Rotation::identity())
}

/// Whether an MCPC frame's joint rotates or translates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameKind {
    /// Revolute or continuous: parameters (α, β, x, y).
    Revolute,
    /// Prismatic: parameters (α, β).
    Prismatic,
}

impl FrameKind {
    /// Number of MCPC parameters of such a frame.
    pub fn parameter_count(self) -> usize {
        match self {
            FrameKind::Revolute => 4,
            FrameKind::Prismatic => 2,
        }
    }
}

/// One joint frame Σᵢ of the MCPC model.
#[derive(Debug, Clone, PartialEq)]
pub struct McpcFrame {
    /// The tree joint this frame belongs to.
    pub joint: JointId,
    /// Revolute or prismatic.
    pub kind: FrameKind,
    /// The previous MCPC frame (`None`: the base, i.e. the root link frame).
    pub parent: Option<usize>,
    /// How the joint value follows the configuration vector.
    pub actuation: Actuation,
    /// Constant rotation about the previous joint axis (rad), the zero-offset choice.
    pub phi: f64,
    /// Rotation about the previous X (rad).
    pub alpha: f64,
    /// Rotation about the new Y (rad).
    pub beta: f64,
    /// Offset along the new X (m); 0 for prismatic frames.
    pub x: f64,
    /// Offset along the new Y (m); 0 for prismatic frames.
    pub y: f64,
    /// The URDF child link's frame in the moved frame Σᵢ·Q(θᵢ) (constant).
    pub frame_from_link: Pose,
    /// Whether φ includes the 90° turn that moves this frame off the β = ±90° singularity
    /// (otherwise φ only undoes an earlier turn, or is 0).
    pub reparametrised: bool,
    /// This frame's rotation about its z relative to the reference frame later rows are
    /// expressed in (the plain MCPC frame, or for a re-parametrised row the frame whose x is
    /// the previous joint axis projected normal to this one; see `docs/mcpc.md`) (rad); the next
    /// row's φ undoes it (0 unless `reparametrised`).
    pub twist: f64,
}

impl McpcFrame {
    /// `prev_from_frame` without the previous joint's motion: Rz(φ)·Rx(α)·Ry(β)·Trans(x, y, 0).
    pub fn constant_transform(&self) -> Pose {
        frame_transform(self.phi, self.alpha, self.beta, self.x, self.y)
    }

    /// The joint's motion Q(θ): rotation about z or translation along z.
    pub fn motion(&self, value: f64) -> Pose {
        match self.kind {
            FrameKind::Revolute => pose(Vec3::zeros(), rot_z(value)),
            FrameKind::Prismatic => pose(Vec3::new(0.0, 0.0, value), Rotation::identity()),
        }
    }
}

/// A tool frame of the MCPC model (eq. (2)): six parameters after the last joint frame.
#[derive(Debug, Clone, PartialEq)]
pub struct McpcTool {
    /// The tool link.
    pub link: LinkId,
    /// The last MCPC frame of the tool's chain (`None`: the tool is rigid on the base).
    pub parent: Option<usize>,
    /// Constant rotation about the last joint axis (rad).
    pub phi: f64,
    /// Rotation about X (rad).
    pub alpha: f64,
    /// Rotation about Y (rad).
    pub beta: f64,
    /// Rotation about Z (rad).
    pub gamma: f64,
    /// Offset along the tool X (m).
    pub x: f64,
    /// Offset along the tool Y (m).
    pub y: f64,
    /// Offset along the tool Z (m).
    pub z: f64,
    /// Whether φ includes the 90° turn away from the β = ±90° singularity.
    pub reparametrised: bool,
}

impl McpcTool {
    /// The tool whose frame sits at `last_from_tool` in the last moved frame `P = Σ_n·Q(θ_n)`
    /// (the base if `parent` is `None`). `twist` is the last frame's rotation about its z
    /// relative to its reference frame ([`McpcFrame::twist`]); φ undoes it, plus 90° where
    /// the tool would otherwise sit near the X-Y-Z angle singularity |β| = 90°.
    pub fn from_relative_pose(
        link: LinkId,
        parent: Option<usize>,
        twist: f64,
        last_from_tool: &Pose,
    ) -> Self {
        let rotation = rot_z(twist) * last_from_tool.rotation;
        let [a, b, c] = xyz_angles_from_rotation(&rotation);
        let reparametrised = b.abs() > SINGULARITY_THRESHOLD;
        let (phi, [alpha, beta, gamma]) = if reparametrised {
            (
                -twist + FRAC_PI_2,
                xyz_angles_from_rotation(&(rot_z(-FRAC_PI_2) * rotation)),
            )
        } else {
            (-twist, [a, b, c])
        };
        let offset = last_from_tool.rotation.inverse() * last_from_tool.translation.vector;
        McpcTool {
            link,
            parent,
            phi: wrap_angle(phi),
            alpha,
            beta,
            gamma,
            x: offset.x,
            y: offset.y,
            z: offset.z,
            reparametrised,
        }
    }

    /// Rz(φ)·Rx(α)·Ry(β)·Rz(γ)·Trans(x, y, z).
    pub fn constant_transform(&self) -> Pose {
        tool_transform(
            self.phi, self.alpha, self.beta, self.gamma, self.x, self.y, self.z,
        )
    }
}

/// The MCPC model of a tree's selected branches: frames (parents first) and tools.
#[derive(Debug, Clone, PartialEq)]
pub struct McpcModel {
    frames: Vec<McpcFrame>,
    tools: Vec<McpcTool>,
    /// `constant_transform` of every frame, cached for forward kinematics.
    frame_constants: Vec<Transform>,
    /// `constant_transform` of every tool.
    tool_constants: Vec<Transform>,
    /// For each tool, the frames from the base to it, base side first.
    tool_chains: Vec<Vec<usize>>,
    /// Index of each frame's first parameter in the flat vector.
    frame_offsets: Vec<usize>,
    /// Index of each tool's first parameter in the flat vector.
    tool_offsets: Vec<usize>,
    /// Rotation axes of α and β of each frame, in the previous moved frame (for the Jacobian).
    frame_axes: Vec<[Vec3; 2]>,
    /// Rotation axes of α, β and γ of each tool, in the last moved frame.
    tool_axes: Vec<[Vec3; 3]>,
    /// Where the base (root link) frame is in the measurement (world) frame; identity unless set.
    world_from_base: Transform,
    /// Joint-angle errors (`joint_errors`), after the tools in the flat vector.
    pub(crate) joint_errors: super::model_extras::JointErrors,
    /// The measurement frame as parameters, last in the flat vector.
    pub(crate) frame_parameters: Option<super::model_extras::FrameParameters>,
    /// The link fixed in the world, when it is not the root (`kinematics::reference`).
    pub(crate) reference: Option<super::model_extras::ReferenceChain>,
}

/// Which parameter of a frame or tool.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ParameterKind {
    /// α (rad).
    Alpha,
    /// β (rad).
    Beta,
    /// γ (rad, tools only).
    Gamma,
    /// x (m).
    X,
    /// y (m).
    Y,
    /// z (m, tools only).
    Z,
    /// Joint zero offset δ (rad; `docs/identification.md`, joint-angle errors).
    Offset,
    /// Coefficient `a` of the joint-angle error `a·sin q` (rad).
    Sine,
    /// Coefficient `b` of the joint-angle error `b·cos q` (rad).
    Cosine,
    /// Backlash: half the dead band, signed by the gravity torque (rad).
    Backlash,
}

impl ParameterKind {
    /// Whether the parameter is an angle (else a length).
    pub fn is_angle(self) -> bool {
        !matches!(self, ParameterKind::X | ParameterKind::Y | ParameterKind::Z)
    }

    /// Short name: alpha, beta, gamma, x, y, z.
    pub fn name(self) -> &'static str {
        match self {
            ParameterKind::Alpha => "alpha",
            ParameterKind::Beta => "beta",
            ParameterKind::Gamma => "gamma",
            ParameterKind::X => "x",
            ParameterKind::Y => "y",
            ParameterKind::Z => "z",
            ParameterKind::Offset => "offset",
            ParameterKind::Sine => "sine",
            ParameterKind::Cosine => "cosine",
            ParameterKind::Backlash => "backlash",
        }
    }
}

/// Where a parameter of the flat vector lives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParameterOwner {
    /// A joint frame, by index in [`McpcModel::frames`].
    Frame(usize),
    /// A tool, by index in [`McpcModel::tools`].
    Tool(usize),
    /// The measurement frame ([`McpcModel::with_frame_parameters`]): α, β, γ, x, y, z.
    Measurement,
}

const REVOLUTE_PARAMETERS: [ParameterKind; 4] = [
    ParameterKind::Alpha,
    ParameterKind::Beta,
    ParameterKind::X,
    ParameterKind::Y,
];
const PRISMATIC_PARAMETERS: [ParameterKind; 2] = [ParameterKind::Alpha, ParameterKind::Beta];
const TOOL_PARAMETERS: [ParameterKind; 6] = [
    ParameterKind::Alpha,
    ParameterKind::Beta,
    ParameterKind::Gamma,
    ParameterKind::X,
    ParameterKind::Y,
    ParameterKind::Z,
];

impl McpcModel {
    /// Builds a model from frames (parents first) and tools; checks the references.
    pub fn new(frames: Vec<McpcFrame>, tools: Vec<McpcTool>) -> Result<Self> {
        for (index, frame) in frames.iter().enumerate() {
            if frame.parent.is_some_and(|p| p >= index) {
                return Err(Error::InvalidTable {
                    origin: "MCPC model".into(),
                    message: format!("frame {index} names a parent that does not come before it"),
                });
            }
        }
        if tools
            .iter()
            .any(|t| t.parent.is_some_and(|p| p >= frames.len()))
        {
            return Err(Error::InvalidTable {
                origin: "MCPC model".into(),
                message: "a tool names a frame that does not exist".into(),
            });
        }
        let tool_chains = tools
            .iter()
            .map(|tool| {
                let mut chain = Vec::new();
                let mut current = tool.parent;
                while let Some(f) = current {
                    chain.push(f);
                    current = frames[f].parent;
                }
                chain.reverse();
                chain
            })
            .collect();
        let mut frame_offsets = Vec::with_capacity(frames.len());
        let mut offset = 0;
        for frame in &frames {
            frame_offsets.push(offset);
            offset += frame.kind.parameter_count();
        }
        let tool_offsets = (0..tools.len()).map(|t| offset + 6 * t).collect();
        let mut model = Self {
            frame_constants: Vec::new(),
            tool_constants: Vec::new(),
            frame_axes: Vec::new(),
            tool_axes: Vec::new(),
            frames,
            tools,
            tool_chains,
            frame_offsets,
            tool_offsets,
            world_from_base: Transform::identity(),
            joint_errors: Default::default(),
            frame_parameters: None,
            reference: None,
        };
        model.refresh();
        Ok(model)
    }

    fn refresh(&mut self) {
        self.frame_axes.clear();
        self.frame_constants.clear();
        for index in 0..self.frames.len() {
            let (axes, constant) = Self::frame_caches(&self.frames[index]);
            self.frame_axes.push(axes);
            self.frame_constants.push(constant);
        }
        self.tool_axes.clear();
        self.tool_constants.clear();
        for index in 0..self.tools.len() {
            let (axes, constant) = Self::tool_caches(&self.tools[index]);
            self.tool_axes.push(axes);
            self.tool_constants.push(constant);
        }
    }

    /// Rotation axes of α and β (d/dα rotates about Rz(φ)·x, d/dβ about Rz(φ)·Rx(α)·y) and
    /// the constant transform of a frame.
    fn frame_caches(f: &McpcFrame) -> ([Vec3; 2], Transform) {
        let turn = rot_z(f.phi);
        (
            [turn * Vec3::x(), turn * rot_x(f.alpha) * Vec3::y()],
            Transform::from_pose(&f.constant_transform()),
        )
    }

    /// Rotation axes of α, β and γ (about Rz(φ)·x, Rz(φ)·Rx(α)·y, Rz(φ)·Rx(α)·Ry(β)·z) and
    /// the constant transform of a tool.
    fn tool_caches(t: &McpcTool) -> ([Vec3; 3], Transform) {
        let turn = rot_z(t.phi);
        let tilt = turn * rot_x(t.alpha);
        (
            [
                turn * Vec3::x(),
                tilt * Vec3::y(),
                tilt * rot_y(t.beta) * Vec3::z(),
            ],
            Transform::from_pose(&t.constant_transform()),
        )
    }

    /// The joint frames, parents first.
    pub fn frames(&self) -> &[McpcFrame] {
        &self.frames
    }

    /// The tools.
    pub fn tools(&self) -> &[McpcTool] {
        &self.tools
    }

    /// The frames from the base to tool `tool`, base side first.
    pub fn tool_chain(&self, tool: usize) -> &[usize] {
        &self.tool_chains[tool]
    }

    /// The index of the frame of tree joint `joint`, if it is in the model.
    pub fn frame_of_joint(&self, joint: JointId) -> Option<usize> {
        self.frames.iter().position(|f| f.joint == joint)
    }

    /// The index of the tool at link `link`, if it is in the model.
    pub fn tool_of_link(&self, link: LinkId) -> Option<usize> {
        self.tools.iter().position(|t| t.link == link)
    }

    /// The joint value of frame `frame` at configuration `q`, with the joint-angle errors of
    /// the model if it has any (`kinematics::joint_errors`).
    #[inline]
    pub fn joint_value(&self, frame: usize, q: &[f64]) -> f64 {
        let raw = self.raw_joint_value(frame, q);
        if self.joint_errors.is_active() {
            raw + self.joint_error(frame, raw, q)
        } else {
            raw
        }
    }

    /// The joint value of frame `frame` at configuration `q` as commanded (no joint errors).
    #[inline]
    pub fn raw_joint_value(&self, frame: usize, q: &[f64]) -> f64 {
        match self.frames[frame].actuation {
            Actuation::Independent(dof) => q[dof.0],
            Actuation::Mimic {
                master,
                multiplier,
                offset,
            } => multiplier * q[master.0] + offset,
            Actuation::None => 0.0,
        }
    }

    /// The pose of the base (root link) frame in the measurement frame: a constant, not a
    /// parameter (the MCPC parameters are complete, so small errors in it are absorbed by the
    /// first frames' parameters). Forward kinematics and Jacobians are in this frame.
    pub fn world_from_base(&self) -> Pose {
        self.world_from_base.to_pose()
    }

    /// Sets [`Self::world_from_base`].
    pub fn set_world_from_base(&mut self, world_from_base: &Pose) {
        self.world_from_base = Transform::from_pose(world_from_base);
        if let Some(parameters) = self.frame_parameters.as_mut() {
            // The parameters are relative to the frame set here.
            parameters.reference = self.world_from_base;
            parameters.values = [0.0; 6];
        }
    }

    /// Moves the measurement frame to `world_from_base` through its parameters (relative to
    /// the frame they were created at, unlike [`Self::set_world_from_base`], which restarts
    /// them at zero); without frame parameters, sets the constant frame.
    pub fn set_measurement_frame(&mut self, world_from_base: &Pose) {
        let Some(parameters) = self.frame_parameters.as_mut() else {
            self.set_world_from_base(world_from_base);
            return;
        };
        let target = Transform::from_pose(world_from_base);
        let relative = target.rotation * parameters.reference.rotation.transpose();
        // relative = Rx(a)·Ry(b)·Rz(c): b = asin(r02), a = atan2(−r12, r22), c = atan2(−r01, r00).
        let b = relative[(0, 2)].clamp(-1.0, 1.0).asin();
        let a = (-relative[(1, 2)]).atan2(relative[(2, 2)]);
        let c = (-relative[(0, 1)]).atan2(relative[(0, 0)]);
        let t = target.translation - parameters.reference.translation;
        parameters.values = [a, b, c, t.x, t.y, t.z];
        self.world_from_base = parameters.effective();
    }

    /// [`Self::world_from_base`] in the fast form.
    pub(crate) fn world_from_base_transform(&self) -> &Transform {
        &self.world_from_base
    }

    /// Index of frame `frame`'s first parameter in the flat parameter vector.
    pub fn frame_parameter_offset(&self, frame: usize) -> usize {
        self.frame_offsets[frame]
    }

    /// Index of tool `tool`'s first parameter in the flat parameter vector.
    pub fn tool_parameter_offset(&self, tool: usize) -> usize {
        self.tool_offsets[tool]
    }

    /// Axes of α and β of frame `frame`, in the previous moved frame.
    pub(crate) fn frame_axes(&self, frame: usize) -> &[Vec3; 2] {
        &self.frame_axes[frame]
    }

    /// Axes of α, β and γ of tool `tool`, in the last moved frame.
    pub(crate) fn tool_axes(&self, tool: usize) -> &[Vec3; 3] {
        &self.tool_axes[tool]
    }

    /// Cached `Rz(φ)Rx(α)Ry(β)Trans(x, y, 0)` of frame `frame`.
    #[inline]
    pub fn frame_constant(&self, frame: usize) -> &Transform {
        &self.frame_constants[frame]
    }

    /// Cached `Rz(φ)Rx(α)Ry(β)Rz(γ)Trans(x, y, z)` of tool `tool`.
    #[inline]
    pub fn tool_constant(&self, tool: usize) -> &Transform {
        &self.tool_constants[tool]
    }
}
