//! treecal
pub mod error;
pub mod kinematics;
pub mod math;
pub mod tree;
pub mod urdf;
