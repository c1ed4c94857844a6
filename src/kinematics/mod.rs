//! Kinematic models built on the tree: the MCPC model and its forward kinematics.

pub mod flexibility;
mod forward;
mod jacobian;
pub mod joint_errors;
pub mod mcpc;
mod model_extras;
mod reference;
pub mod table;

pub use flexibility::{FlexibilityModel, Stiffness};
pub use forward::ForwardFrames;
pub use jacobian::{ChainFrames, ToolJacobian};
pub use joint_errors::JointErrorTerms;
pub use mcpc::{
    FrameKind, McpcFrame, McpcModel, McpcTool, ParameterKind, ParameterOwner, SINGULARITY_THRESHOLD,
};
pub use model_extras::{GravitySigns, ReferenceLink};
pub use table::{McpcTable, TableBranch, TableRow, TableTool};
