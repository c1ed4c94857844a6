//! The observation seam: what one kind of measurement is to the calibration.
//!
//! A measurement kind (a tracked point, a tracked frame, later a camera's pixel, a contact) is
//! known to the rest of the calibration only through [`MeasurementKind`]: how many rows it
//! contributes and what each row measures ([`RowKind`], which picks its σ from [`Noise`]),
//! its residual `measured ⊖ predicted` from the robot's state at the measured configuration
//! ([`RobotState`]: the tools' poses and Jacobians in the measurement frame, the model, the
//! nuisance parameters), and the Jacobian of its prediction with respect to the parameters
//! (the robot's and its own nuisance parameters, in one flat index space: [`Nuisance`]). The
//! solver (`solver::linearise`), robust weighting (`robust::residuals`) and the residual
//! summaries consume only this trait.
//!
//! Each kind lives in a file of its own, implemented on the measured value that
//! [`Observation`] holds: `position.rs` (a point, 3 rows) and `pose.rs` (a frame, 6 rows; also
//! the three-target frame, which the reader turns into a pose). [`kind_of`] is the only
//! place that maps an observation to its kind. `docs/architecture.md`, "Adding a measurement
//! kind", says what a new kind touches.
//!
//! Sign convention (Gauss–Newton's): the residual is `r = measured ⊖ predicted` and
//! [`MeasurementKind::jacobian`] is `J = ∂predicted/∂θ` (so `∂r/∂θ ≈ −J`); the solver steps
//! by `Δθ = (JᵀWJ)⁻¹JᵀWr`.

mod contact;
mod pose;
mod position;

pub use contact::contact_violation;

use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, ToolJacobian};
use crate::math::{Pose, Vec3};
use crate::measurement::Observation;
use nalgebra::{DMatrix, DMatrixViewMut, Vector6};

/// What one row of a measurement measures: its unit, and which σ of [`Noise`] weighs it.
/// New kinds add their own row kinds (pixels, heights, tilts) here, with their σ in
/// [`Noise`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RowKind {
    /// A position coordinate (m), weighed by [`Noise::position`].
    Position,
    /// A rotation coordinate (rad, a component of the rotation vector), weighed by
    /// [`Noise::rotation`].
    Rotation,
    /// A contact's height above its plane (m; a flush face or a contact point), weighed by
    /// [`Noise::height`].
    Height,
    /// A contact face's tilt against its plane (rad, the sine of the angle about one of the
    /// plane's in-plane axes), weighed by [`Noise::tilt`].
    Tilt,
    /// A coordinate of the gap between two contact points that touch (m), weighed by
    /// [`Noise::gap`].
    Gap,
    /// The error of a distance between two contact points (m, a bar), weighed by
    /// [`Noise::length`].
    Length,
}

impl RowKind {
    /// Every row kind, in the order residual summaries list them.
    pub const ALL: [RowKind; 6] = [
        RowKind::Position,
        RowKind::Rotation,
        RowKind::Height,
        RowKind::Tilt,
        RowKind::Gap,
        RowKind::Length,
    ];

    /// `position`, `rotation`, `height`, `tilt`, `gap` or `length`.
    pub fn name(self) -> &'static str {
        match self {
            RowKind::Position => "position",
            RowKind::Rotation => "rotation",
            RowKind::Height => "height",
            RowKind::Tilt => "tilt",
            RowKind::Gap => "gap",
            RowKind::Length => "length",
        }
    }

    /// The unit of a row: `m` or `rad`.
    pub fn unit(self) -> &'static str {
        match self {
            RowKind::Rotation | RowKind::Tilt => "rad",
            _ => "m",
        }
    }
}

/// The noise model: the expected error σ of one row, per [`RowKind`] (SI units). A row's
/// weight in the least-squares problem is `1/σ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// σ of a position coordinate (m).
    pub position: f64,
    /// σ of a rotation coordinate (rad).
    pub rotation: f64,
    /// σ of a contact's height above its plane (m).
    pub height: f64,
    /// σ of a contact face's tilt against its plane (rad).
    pub tilt: f64,
    /// σ of a coordinate of the gap between two touching contact points (m).
    pub gap: f64,
    /// σ of a distance between two contact points (m).
    pub length: f64,
}

/// The contact σ's every command assumes unless told otherwise: height 1 mm, tilt 0.01 rad,
/// touch gap 1 mm, bar length 1 mm.
pub const DEFAULT_CONTACT_SIGMAS: [f64; 4] = [1e-3, 1e-2, 1e-3, 1e-3];

impl Default for Noise {
    /// The default tracker σ's (`DEFAULT_POSITION_SIGMA`, `DEFAULT_ROTATION_SIGMA`) and
    /// [`DEFAULT_CONTACT_SIGMAS`].
    fn default() -> Self {
        let [height, tilt, gap, length] = DEFAULT_CONTACT_SIGMAS;
        Self {
            position: super::DEFAULT_POSITION_SIGMA,
            rotation: super::DEFAULT_ROTATION_SIGMA,
            height,
            tilt,
            gap,
            length,
        }
    }
}

impl Noise {
    /// σ of a row of kind `kind`.
    pub fn sigma(&self, kind: RowKind) -> f64 {
        match kind {
            RowKind::Position => self.position,
            RowKind::Rotation => self.rotation,
            RowKind::Height => self.height,
            RowKind::Tilt => self.tilt,
            RowKind::Gap => self.gap,
            RowKind::Length => self.length,
        }
    }

    /// Whether every σ is a positive number.
    pub fn is_valid(&self) -> bool {
        RowKind::ALL.iter().all(|&kind| self.sigma(kind) > 0.0)
    }
}

/// Parameters outside the robot model that some measurement kinds need: camera intrinsics
/// and extrinsics, board poses, plane poses, a bar's length. They come in named blocks and are
/// numbered after the model's own parameters: flat index `model.parameter_count() + k` is the
/// `k`-th nuisance value (blocks in order). Tracked points and frames have none of their own:
/// their nuisance parameters — the measurement frame and the tool offsets — are part of the
/// MCPC parameter vector ([`crate::kinematics::ParameterOwner`]). Contacts have planes,
/// contact points and faces, bar lengths ([`crate::measurement::Contact`]); the solver steps
/// them with the model's parameters ([`crate::calibration::identify_with_nuisance`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Nuisance {
    /// The blocks, in flat-index order.
    pub blocks: Vec<NuisanceBlock>,
}

/// One block of nuisance parameters (e.g. one camera's intrinsics).
#[derive(Debug, Clone, PartialEq)]
pub struct NuisanceBlock {
    /// What the block is, for messages (e.g. `camera head intrinsics`).
    pub name: String,
    /// One name per value (e.g. `fx`), for messages and reports.
    pub parameter_names: Vec<String>,
    /// The values (SI units: m, rad; pixels for intrinsics).
    pub values: Vec<f64>,
}

impl Nuisance {
    /// No nuisance parameters (today's kinds).
    pub fn none() -> &'static Nuisance {
        static NONE: Nuisance = Nuisance { blocks: Vec::new() };
        &NONE
    }

    /// The number of nuisance values.
    pub fn len(&self) -> usize {
        self.blocks.iter().map(|b| b.values.len()).sum()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index of block `block`'s first value among the nuisance values (add the model's
    /// parameter count for the flat index).
    pub fn offset(&self, block: usize) -> usize {
        self.blocks[..block.min(self.blocks.len())]
            .iter()
            .map(|b| b.values.len())
            .sum()
    }

    /// All values, blocks in order.
    pub fn values(&self) -> Vec<f64> {
        self.blocks
            .iter()
            .flat_map(|b| b.values.iter().copied())
            .collect()
    }

    /// Replaces all values (blocks in order); an error when `values` has another length.
    pub fn set_values(&mut self, values: &[f64]) -> Result<()> {
        if values.len() != self.len() {
            return Err(Error::InvalidData {
                origin: "nuisance parameters".into(),
                message: format!("{} values given for {}", values.len(), self.len()),
            });
        }
        let mut rest = values;
        for block in &mut self.blocks {
            let (head, tail) = rest.split_at(block.values.len());
            block.values.copy_from_slice(head);
            rest = tail;
        }
        Ok(())
    }

    /// The name of nuisance value `k` (0-based among the nuisance values), e.g.
    /// `plane day1 height`; `None` past the end.
    pub fn value_name(&self, k: usize) -> Option<String> {
        let mut start = 0;
        for block in &self.blocks {
            if k < start + block.values.len() {
                let name = block
                    .parameter_names
                    .get(k - start)
                    .map_or("?", String::as_str);
                return Some(format!("{} {}", block.name, name));
            }
            start += block.values.len();
        }
        None
    }

    /// The block named `name`, if any.
    pub fn block(&self, name: &str) -> Option<usize> {
        self.blocks.iter().position(|b| b.name == name)
    }

    /// Block `block`'s values, or an error naming the missing block (a contact that names a
    /// block this nuisance does not have).
    pub fn block_values(&self, block: usize) -> Result<&[f64]> {
        self.blocks
            .get(block)
            .map(|b| b.values.as_slice())
            .ok_or_else(|| Error::InvalidData {
                origin: "nuisance parameters".into(),
                message: format!(
                    "block {block} does not exist ({} blocks)",
                    self.blocks.len()
                ),
            })
    }
}

/// The tools as the predictor evaluated them at one configuration: poses only (residuals), or
/// poses with their parameter Jacobians (linearisation).
#[derive(Debug, Clone, Copy)]
pub enum Tools<'a> {
    /// Poses of every tool in the measurement frame.
    Poses(&'a [Pose]),
    /// Poses and `6 × parameter_count` Jacobians of every tool.
    Jacobians(&'a [ToolJacobian]),
}

/// The robot at one measurement's configuration: what a kind predicts from. Built by the
/// consumer (the solver, the robust weighting) once per row, from the predictor's evaluation
/// of the configuration, which rows measured there share.
#[derive(Debug, Clone, Copy)]
pub struct RobotState<'a> {
    /// The model at the current parameters (its other frames and links: `model.link_poses`).
    pub model: &'a McpcModel,
    /// The configuration (one value per independent joint).
    pub q: &'a [f64],
    /// The tool the measurement names ([`crate::measurement::Measurement::tool`]).
    pub tool: usize,
    /// Every tool, as predicted (deflected under exact flexibility compensation).
    pub tools: Tools<'a>,
    /// The linear flexibility error `D_f` of this row's tool (eq. (26)), in
    /// [`crate::math::pose_error`] coordinates, when the plan compensates linearly: the
    /// residual is `measured ⊖ predicted − D_f`.
    pub offset: Option<&'a Vector6<f64>>,
    /// The nuisance parameters' current values.
    pub nuisance: &'a Nuisance,
}

impl RobotState<'_> {
    /// The pose of tool `tool` in the measurement frame.
    pub fn tool_pose(&self, tool: usize) -> Result<&Pose> {
        match self.tools {
            Tools::Poses(poses) => poses.get(tool),
            Tools::Jacobians(tools) => tools.get(tool).map(|t| &t.pose),
        }
        .ok_or_else(|| missing_tool(tool))
    }

    /// The `6 × parameter_count` Jacobian of tool `tool`'s pose (rows x, y, z (m), then
    /// rotation x, y, z (rad), in the measurement frame); an error when only poses were
    /// evaluated.
    pub fn tool_jacobian(&self, tool: usize) -> Result<&ToolJacobian> {
        match self.tools {
            Tools::Jacobians(tools) => tools.get(tool).ok_or_else(|| missing_tool(tool)),
            Tools::Poses(_) => Err(Error::InvalidData {
                origin: "identification".into(),
                message: "no Jacobian".into(),
            }),
        }
    }
}

fn missing_tool(tool: usize) -> Error {
    Error::InvalidData {
        origin: "identification".into(),
        message: format!("no prediction for tool {tool}"),
    }
}

/// One kind of measurement, as the calibration sees it. Implemented on the measured value
/// an [`Observation`] variant holds; one file per kind. `Sync`: rows are linearised in
/// parallel.
pub trait MeasurementKind: std::fmt::Debug + Sync {
    /// Short name: `position`, `pose`.
    fn name(&self) -> &'static str;

    /// What each row measures, in row order; its length is the row count.
    fn row_kinds(&self) -> &'static [RowKind];

    /// Rows this measurement contributes (equal to [`Observation::rows`]).
    fn rows(&self) -> usize {
        self.row_kinds().len()
    }

    /// Whether every measured value is a finite number.
    fn is_finite(&self) -> bool;

    /// The unweighted residual `measured ⊖ predicted − D_f` at `at` (SI units, one value per
    /// row) into `out` (`rows()` long).
    fn residual(&self, at: &RobotState<'_>, out: &mut [f64]) -> Result<()>;

    /// `∂predicted/∂θ` (unweighted) for the parameters `columns` (flat indices: the model's
    /// parameters, then the [`Nuisance`] values) into `out` (`rows() × columns.len()`). `at`
    /// carries the tools' Jacobians.
    fn jacobian(
        &self,
        at: &RobotState<'_>,
        columns: &[usize],
        out: &mut DMatrixViewMut<'_, f64>,
    ) -> Result<()>;

    /// `∂predicted/∂ξ` (`rows() × 6`) for a small motion `ξ = (δp, δω)` of tool `tool`'s
    /// predicted pose (m, rad; in the measurement frame, rotation about the tool's origin:
    /// [`crate::math::pose_error`] coordinates); zero when the kind does not see that tool.
    /// Consumers that move tools by parameters of their own (compliance scales, a session's
    /// frame) chain it with their `∂ξ/∂θ`.
    fn tool_motion_jacobian(&self, at: &RobotState<'_>, tool: usize) -> DMatrix<f64>;

    /// Where the measured tool's origin is in the measurement frame, when the kind measures
    /// it directly (closed-form starts, the unit check, column checks, errors in m); `None`
    /// for kinds that do not (a pixel, a contact).
    fn measured_point(&self) -> Option<Vec3>;

    /// The measured tool frame in the measurement frame, when the kind measures all of it.
    fn measured_frame(&self) -> Option<Pose> {
        None
    }

    /// The same observation expressed in another measurement frame, `new_from_old` being the
    /// old frame's pose in the new one (measurement sessions). Kinds measured in a frame of
    /// their own (a camera on the robot) return themselves.
    fn in_frame(&self, new_from_old: &Pose) -> Observation;

    /// The observation a perfect instrument would report at `at` (the prediction itself, same
    /// kind): simulation, planning and noise-free tests.
    fn noise_free(&self, at: &RobotState<'_>) -> Result<Observation>;
}

/// The kind of `observation`: the one place that maps an observation to its implementation.
pub fn kind_of(observation: &Observation) -> &dyn MeasurementKind {
    match observation {
        Observation::Position(point) => point as &dyn MeasurementKind,
        Observation::Pose(frame) => frame as &dyn MeasurementKind,
        Observation::Contact(contact) => contact.as_ref() as &dyn MeasurementKind,
    }
}

/// The residual of one measurement split by row kind: the sum of squares of its rows of each
/// kind (`None` for a kind it has no rows of), in [`RowKind::ALL`] order.
pub fn squares_by_row_kind(
    kind: &dyn MeasurementKind,
    residual: &[f64],
) -> [Option<f64>; RowKind::ALL.len()] {
    let row_kinds = kind.row_kinds();
    RowKind::ALL.map(|wanted| {
        let mut squares = None;
        for (_, value) in row_kinds
            .iter()
            .zip(residual)
            .filter(|(k, _)| **k == wanted)
        {
            *squares.get_or_insert(0.0) += value * value;
        }
        squares
    })
}

/// [`squares_by_row_kind`], square-rooted: the norm of each row kind's part of the residual.
pub fn norms_by_row_kind(
    kind: &dyn MeasurementKind,
    residual: &[f64],
) -> [Option<f64>; RowKind::ALL.len()] {
    squares_by_row_kind(kind, residual).map(|s| s.map(f64::sqrt))
}

/// `‖W·r‖` of one measurement's unweighted residual: the norm of each row kind's rows over its
/// σ, combined in quadrature (robust weighting).
pub fn standardized_norm(kind: &dyn MeasurementKind, residual: &[f64], noise: &Noise) -> f64 {
    norms_by_row_kind(kind, residual)
        .iter()
        .zip(RowKind::ALL)
        .map(|(norm, row_kind)| (norm.unwrap_or(0.0) / noise.sigma(row_kind)).powi(2))
        .sum::<f64>()
        .sqrt()
}
