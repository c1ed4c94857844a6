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
    pub(crate) joint_errors: super::joint_errors::JointErrors,
    /// The measurement frame as parameters, last in the flat vector.
    pub(crate) frame_parameters: Option<super::joint_errors::FrameParameters>,
    /// The link fixed in the world, when it is not the root (`kinematics::reference`).
    pub(crate) reference: Option<super::reference::ReferenceChain>,
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

    /// The MCPC model of `branches` of `tree` at its nominal (URDF) geometry.
    /// At most [`crate::limits::MAX_PARAMETERS`] parameters.
    pub fn from_tree(tree: &KinematicTree, branches: &Branches) -> Result<Self> {
        let model = convert(tree, branches)?;
        crate::limits::check_count(
            model.parameter_count(),
            crate::limits::MAX_PARAMETERS,
            &format!("robot '{}'", tree.name()),
            "MCPC parameters on the selected branches",
        )?;
        Ok(model)
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

    /// Number of MCPC parameters: 4 per revolute frame, 2 per prismatic frame, 6 per tool.
    pub fn parameter_count(&self) -> usize {
        self.frames
            .iter()
            .map(|f| f.kind.parameter_count())
            .sum::<usize>()
            + 6 * self.tools.len()
            + self
                .joint_errors
                .slots
                .iter()
                .flatten()
                .filter(|v| v.is_some())
                .count()
            + if self.frame_parameters.is_some() {
                6
            } else {
                0
            }
    }

    /// What each entry of the flat parameter vector is: frames in order, then tools.
    pub fn parameter_layout(&self) -> Vec<(ParameterOwner, ParameterKind)> {
        let mut layout = Vec::with_capacity(self.parameter_count());
        for (index, frame) in self.frames.iter().enumerate() {
            let kinds: &[ParameterKind] = match frame.kind {
                FrameKind::Revolute => &REVOLUTE_PARAMETERS,
                FrameKind::Prismatic => &PRISMATIC_PARAMETERS,
            };
            layout.extend(kinds.iter().map(|k| (ParameterOwner::Frame(index), *k)));
        }
        for index in 0..self.tools.len() {
            layout.extend(
                TOOL_PARAMETERS
                    .iter()
                    .map(|k| (ParameterOwner::Tool(index), *k)),
            );
        }
        for (index, slot) in self.joint_errors.slots.iter().enumerate() {
            for (value, kind) in slot.iter().zip(super::joint_errors::JOINT_ERROR_KINDS) {
                if value.is_some() {
                    layout.push((ParameterOwner::Frame(index), kind));
                }
            }
        }
        if self.frame_parameters.is_some() {
            layout.extend(
                TOOL_PARAMETERS
                    .iter()
                    .map(|k| (ParameterOwner::Measurement, *k)),
            );
        }
        layout
    }

    /// A readable name of parameter `index`, e.g. `left_joint1 alpha` or `left_tool z`.
    pub fn parameter_name(&self, tree: &KinematicTree, index: usize) -> String {
        match self.parameter_layout().get(index) {
            Some((ParameterOwner::Frame(f), kind)) => {
                format!("{} {}", tree.joint(self.frames[*f].joint).name, kind.name())
            }
            Some((ParameterOwner::Tool(t), kind)) => {
                format!("{} {}", tree.link(self.tools[*t].link).name, kind.name())
            }
            Some((ParameterOwner::Measurement, kind)) => {
                format!("measurement_frame {}", kind.name())
            }
            None => format!("parameter {index}"),
        }
    }

    /// The flat parameter vector (rad, m) in [`Self::parameter_layout`] order.
    pub fn parameters(&self) -> Vec<f64> {
        self.parameter_layout()
            .into_iter()
            .map(|(owner, kind)| self.parameter(owner, kind))
            .collect()
    }

    /// One parameter's value.
    pub fn parameter(&self, owner: ParameterOwner, kind: ParameterKind) -> f64 {
        match owner {
            ParameterOwner::Frame(i) => {
                let f = &self.frames[i];
                match kind {
                    ParameterKind::Alpha => f.alpha,
                    ParameterKind::Beta => f.beta,
                    ParameterKind::X => f.x,
                    ParameterKind::Y => f.y,
                    ParameterKind::Gamma | ParameterKind::Z => 0.0,
                    kind => self
                        .joint_error_values(i)
                        .get(joint_error_slot(kind))
                        .copied()
                        .flatten()
                        .unwrap_or(0.0),
                }
            }
            ParameterOwner::Tool(i) => {
                let t = &self.tools[i];
                match kind {
                    ParameterKind::Alpha => t.alpha,
                    ParameterKind::Beta => t.beta,
                    ParameterKind::Gamma => t.gamma,
                    ParameterKind::X => t.x,
                    ParameterKind::Y => t.y,
                    ParameterKind::Z => t.z,
                    _ => 0.0,
                }
            }
            ParameterOwner::Measurement => self
                .frame_parameters
                .as_ref()
                .map_or(0.0, |f| f.values[frame_slot(kind)]),
        }
    }

    /// Replaces every parameter (same order as [`Self::parameters`]).
    pub fn set_parameters(&mut self, values: &[f64]) -> Result<()> {
        let layout = self.parameter_layout();
        if values.len() != layout.len() {
            return Err(Error::InvalidTable {
                origin: "MCPC parameters".into(),
                message: format!(
                    "{} values given, the model has {} parameters",
                    values.len(),
                    layout.len()
                ),
            });
        }
        if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidTable {
                origin: "MCPC parameters".into(),
                message: format!("parameter {bad} is not finite"),
            });
        }
        for ((owner, kind), value) in layout.into_iter().zip(values) {
            *self.slot(owner, kind) = *value;
        }
        self.refresh();
        self.refresh_world();
        Ok(())
    }

    /// Replaces parameter `index` alone, refreshing only its frame or tool: the cheap way to
    /// perturb one parameter (finite differences).
    pub fn set_parameter(&mut self, index: usize, value: f64) -> Result<()> {
        let Some(&(owner, kind)) = self.parameter_layout().get(index) else {
            return Err(Error::InvalidTable {
                origin: "MCPC parameters".into(),
                message: format!(
                    "parameter {index} does not exist; the model has {} parameters",
                    self.parameter_count()
                ),
            });
        };
        if !value.is_finite() {
            return Err(Error::InvalidTable {
                origin: "MCPC parameters".into(),
                message: format!("parameter {index} is not finite"),
            });
        }
        *self.slot(owner, kind) = value;
        match owner {
            ParameterOwner::Frame(i) => {
                let (axes, constant) = Self::frame_caches(&self.frames[i]);
                self.frame_axes[i] = axes;
                self.frame_constants[i] = constant;
            }
            ParameterOwner::Tool(i) => {
                let (axes, constant) = Self::tool_caches(&self.tools[i]);
                self.tool_axes[i] = axes;
                self.tool_constants[i] = constant;
            }
            ParameterOwner::Measurement => self.refresh_world(),
        }
        Ok(())
    }

    /// [`Self::world_from_base`] from the measurement-frame parameters, if they exist.
    fn refresh_world(&mut self) {
        if let Some(parameters) = &self.frame_parameters {
            self.world_from_base = parameters.effective();
        }
    }

    /// Folds joint offset `delta` of revolute frame `frame` into the constants after it
    /// ([`Self::with_offsets_absorbed`]).
    pub(crate) fn absorb_offset(&mut self, frame: usize, delta: f64) {
        if self.frames[frame].kind != FrameKind::Revolute {
            return;
        }
        for child in self.frames.iter_mut().filter(|f| f.parent == Some(frame)) {
            child.phi += delta;
        }
        for tool in self.tools.iter_mut().filter(|t| t.parent == Some(frame)) {
            tool.phi += delta;
        }
        let link = self.frames[frame].frame_from_link;
        self.frames[frame].frame_from_link = pose(Vec3::zeros(), rot_z(delta)) * link;
        if let Some(slot) = self.joint_errors.slots.get_mut(frame) {
            slot[0] = slot[0].map(|_| 0.0);
        }
        self.refresh();
    }

    /// The field holding parameter `kind` of `owner`.
    fn slot(&mut self, owner: ParameterOwner, kind: ParameterKind) -> &mut f64 {
        match owner {
            ParameterOwner::Frame(i) => {
                let f = &mut self.frames[i];
                match kind {
                    ParameterKind::Alpha => &mut f.alpha,
                    ParameterKind::Beta => &mut f.beta,
                    ParameterKind::X => &mut f.x,
                    ParameterKind::Y | ParameterKind::Gamma | ParameterKind::Z => &mut f.y,
                    kind => {
                        let slots = &mut self.joint_errors.slots;
                        if slots.len() <= i {
                            slots.resize(i + 1, [None; 4]);
                        }
                        slots[i][joint_error_slot(kind)].get_or_insert(0.0)
                    }
                }
            }
            ParameterOwner::Measurement => {
                let reference = self.world_from_base;
                let parameters =
                    self.frame_parameters
                        .get_or_insert(super::joint_errors::FrameParameters {
                            values: [0.0; 6],
                            reference,
                        });
                &mut parameters.values[frame_slot(kind)]
            }
            ParameterOwner::Tool(i) => {
                let t = &mut self.tools[i];
                match kind {
                    ParameterKind::Alpha => &mut t.alpha,
                    ParameterKind::Beta => &mut t.beta,
                    ParameterKind::Gamma => &mut t.gamma,
                    ParameterKind::X => &mut t.x,
                    ParameterKind::Y => &mut t.y,
                    ParameterKind::Z => &mut t.z,
                    _ => &mut t.gamma,
                }
            }
        }
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

/// The index of a joint-error kind in [`super::joint_errors::JOINT_ERROR_KINDS`].
fn joint_error_slot(kind: ParameterKind) -> usize {
    match kind {
        ParameterKind::Offset => 0,
        ParameterKind::Sine => 1,
        ParameterKind::Cosine => 2,
        _ => 3,
    }
}

/// The index of a measurement-frame parameter (α, β, γ, x, y, z).
fn frame_slot(kind: ParameterKind) -> usize {
    match kind {
        ParameterKind::Alpha => 0,
        ParameterKind::Beta => 1,
        ParameterKind::Gamma => 2,
        ParameterKind::X => 3,
        ParameterKind::Y => 4,
        _ => 5,
    }
}

/// Geometry of an MCPC frame at the all-joints-zero configuration, in the root frame.
#[derive(Clone, Copy)]
struct Placed {
    rotation: Rotation,
    origin: Vec3,
    /// Rotation about z of this frame relative to its reference frame ([`McpcFrame::twist`]).
    twist: f64,
}

const BASE: Placed = Placed {
    rotation: Rotation::new_unchecked(nalgebra::Quaternion::new(1.0, 0.0, 0.0, 0.0)),
    origin: Vec3::new(0.0, 0.0, 0.0),
    twist: 0.0,
};

/// α, β with `Rx(α)·Ry(β)·e_z = axis`. Only used where |β| ≤ 60°, so α is well defined; the
/// guard keeps an axis exactly along ±x from giving atan2(±0, −0) = ±π.
fn axis_angles(axis: &Vec3) -> (f64, f64) {
    let beta = axis.x.atan2(axis.y.hypot(axis.z));
    let alpha = if axis.y == 0.0 && axis.z == 0.0 {
        0.0
    } else {
        wrap_angle((-axis.y).atan2(axis.z))
    };
    (alpha, beta)
}

fn convert(tree: &KinematicTree, branches: &Branches) -> Result<McpcModel> {
    // Every joint at its own zero (mimic offsets are not applied: the model is in joint values).
    let mut root_from_link = vec![Pose::identity()];
    for joint in tree.joints() {
        root_from_link.push(root_from_link[joint.parent.0] * joint.parent_from_child(0.0));
    }

    let mut frames: Vec<McpcFrame> = Vec::new();
    let mut placed: Vec<Placed> = Vec::new();
    let frame_of =
        |frames: &[McpcFrame], joint: JointId| frames.iter().position(|f| f.joint == joint);
    // The nearest movable ancestor joint of a link that is already a frame.
    let parent_frame = |frames: &[McpcFrame], link: LinkId| -> Option<usize> {
        tree.path_from_root(link)
            .iter()
            .rev()
            .find_map(|&j| frame_of(frames, j))
    };

    for joint_id in frame_order(tree, branches) {
        let joint = tree.joint(joint_id);
        let kind = match joint.kind {
            JointKind::Revolute | JointKind::Continuous => FrameKind::Revolute,
            JointKind::Prismatic => FrameKind::Prismatic,
            JointKind::Fixed => continue,
        };
        let parent = parent_frame(&frames, joint.parent);
        let previous = parent.map_or(BASE, |p| placed[p]);
        let root_from_joint = root_from_link[joint.parent.0] * joint.parent_from_joint;
        let axis_root = root_from_joint.rotation * joint.axis.into_inner();

        let reference = previous.rotation * rot_z(-previous.twist);
        let (alpha_ref, beta_ref) = axis_angles(&(reference.inverse() * axis_root));
        let reparametrised = beta_ref.abs() > SINGULARITY_THRESHOLD;
        let (phi, alpha, beta, rotation, twist) = if !reparametrised {
            let rotation = reference * rot_x(alpha_ref) * rot_y(beta_ref);
            (-previous.twist, alpha_ref, beta_ref, rotation, 0.0)
        } else {
            let turned = reference * rot_z(FRAC_PI_2);
            let (alpha, beta) = axis_angles(&(turned.inverse() * axis_root));
            let rotation = turned * rot_x(alpha) * rot_y(beta);
            // Later rows are expressed relative to the frame whose x axis is the previous joint
            // axis (−z for β > 0, +z for β < 0) projected onto the plane normal to this axis: the
            // plain MCPC frame when the axis is exactly along the previous X (Table 1's β = 90°
            // rows), and well conditioned near there, where the plain α is not.
            let previous_axis = reference * Vec3::z();
            let towards = previous_axis * -beta_ref.signum();
            let reference_x = (towards - axis_root * towards.dot(&axis_root)).normalize();
            let actual_x = rotation * Vec3::x();
            let twist = reference_x
                .cross(&actual_x)
                .dot(&axis_root)
                .atan2(reference_x.dot(&actual_x));
            (-previous.twist + FRAC_PI_2, alpha, beta, rotation, twist)
        };
        let origin = match kind {
            FrameKind::Revolute => {
                let point = root_from_joint.translation.vector;
                point + axis_root * (previous.origin - point).dot(&axis_root)
            }
            FrameKind::Prismatic => previous.origin,
        };
        let offset = rotation.inverse() * (origin - previous.origin);
        let (x, y) = match kind {
            FrameKind::Revolute => (offset.x, offset.y),
            FrameKind::Prismatic => (0.0, 0.0),
        };
        let root_from_frame = pose(origin, rotation);
        frames.push(McpcFrame {
            joint: joint_id,
            kind,
            parent,
            actuation: joint.actuation,
            phi: wrap_angle(phi),
            alpha,
            beta,
            x,
            y,
            frame_from_link: root_from_frame.inverse() * root_from_link[joint.child.0],
            reparametrised,
            twist,
        });
        placed.push(Placed {
            rotation,
            origin,
            twist,
        });
    }

    let reference = (branches.reference != tree.root()).then(|| {
        let parent = parent_frame(&frames, branches.reference);
        let previous = parent.map_or(BASE, |p| placed[p]);
        super::ReferenceLink {
            link: branches.reference,
            parent,
            last_from_link: pose(previous.origin, previous.rotation).inverse()
                * root_from_link[branches.reference.0],
        }
    });
    let mut tools = Vec::new();
    for tool_link in branches.tools() {
        let parent = parent_frame(&frames, tool_link);
        let previous = parent.map_or(BASE, |p| placed[p]);
        let last_from_tool =
            pose(previous.origin, previous.rotation).inverse() * root_from_link[tool_link.0];
        tools.push(McpcTool::from_relative_pose(
            tool_link,
            parent,
            previous.twist,
            &last_from_tool,
        ));
    }
    let mut model = McpcModel::new(frames, tools)?;
    model.set_reference(reference)?;
    Ok(model)
}

/// The joints that get an MCPC frame, parents first: the branches' joints in branch order,
/// each preceded by those of its URDF ancestors that are on a branch too (a path up a leg from
/// a reference link lists a leg's joints against their URDF order).
fn frame_order(tree: &KinematicTree, branches: &Branches) -> Vec<JointId> {
    let wanted: Vec<JointId> = branches
        .all()
        .flat_map(|b| b.joints.iter().copied())
        .collect();
    let mut ordered: Vec<JointId> = Vec::with_capacity(wanted.len());
    for &joint in &wanted {
        for ancestor in tree.path_from_root(tree.joint(joint).child) {
            if wanted.contains(&ancestor) && !ordered.contains(&ancestor) {
                ordered.push(ancestor);
            }
        }
    }
    ordered
}
