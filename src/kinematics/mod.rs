//! Kinematic models built on the tree: the MCPC model and its forward kinematics.

mod flexibility;
mod forward;
mod jacobian;
mod joint_errors;
mod mcpc;
mod model_extras;
mod reference;
mod table;

pub use flexibility::{
    point_load_deflection, uniform_load_deflection, BeamCompliance, ComplianceBasis,
    ComplianceJacobian, ComplianceKind, ComplianceParameter, Deformations, JointDeformation,
    JointStiffness, LinkStiffness, Payload, Segment, SegmentDeformation, SegmentEnd,
    STANDARD_GRAVITY,
};
pub use joint_errors::JOINT_ERROR_KINDS;
pub use mcpc::{frame_transform, tool_transform};

pub(crate) use flexibility::names::Names;
pub(crate) use flexibility::{mass_problem, stiffness_problem};
pub use flexibility::{FlexibilityModel, Stiffness};
pub use forward::ForwardFrames;
pub use jacobian::{ChainFrames, ToolJacobian};
pub use joint_errors::JointErrorTerms;
pub use mcpc::{
    FrameKind, McpcFrame, McpcModel, McpcTool, ParameterKind, ParameterOwner, SINGULARITY_THRESHOLD,
};
pub use model_extras::{GravitySigns, ReferenceLink};
pub use table::{McpcTable, TableBranch, TableRow, TableTool};
