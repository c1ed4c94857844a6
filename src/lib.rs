#![doc = include_str!("../README.md")]

pub mod calibration;
pub mod camera;
mod digests;
pub mod error;
pub mod io;
pub mod kinematics;
pub mod limits;
pub mod math;
pub mod measurement;
pub mod pairing;
pub mod report;
mod serde_labels;
pub mod sim;
pub mod tree;
pub mod urdf;
pub mod workflow;

pub use error::{Error, Result};
pub use kinematics::{McpcModel, McpcTable};
pub use tree::{detect_branches, detect_branches_from, Branches, KinematicTree};
pub use urdf::{export_urdf, load_urdf, parse_urdf, urdf_from_mcpc_table};
