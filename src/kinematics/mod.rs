//! Kinematic models built on the tree: the MCPC model and its forward kinematics.

mod forward;
mod jacobian;
pub mod mcpc;
pub mod table;

pub use jacobian::ToolJacobian;
pub use mcpc::{
    FrameKind, McpcFrame, McpcModel, McpcTool, ParameterKind, ParameterOwner, SINGULARITY_THRESHOLD,
};
pub use table::{McpcTable, TableBranch, TableRow, TableTool};
