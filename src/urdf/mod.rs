//! URDF in and out: the only module that uses urdf-rs or reads XML.
//!
//! - [`import`]: URDF text → [`KinematicTree`](crate::tree::KinematicTree), with every
//!   check a real robot file needs (names, roots, cycles, NaN, unsupported joints).
//! - [`from_mcpc`]: an MCPC table (paper Table 1 layout) → a new URDF document.
//! - [`export`]: a calibrated MCPC model → the original URDF with corrected joint origins,
//!   edited in place; [`export_overlay`]: the same edits as a joint-origin overlay.

mod bounds;
pub mod export;
pub mod export_options;
pub mod export_overlay;
pub mod from_mcpc;
pub mod import;
mod tolerant;
mod xml;

pub use export::{export_urdf, export_urdf_with, ExportReport, JointChange};
pub use export_options::{AddedReason, AddedToolLink, DroppedOffset, ExportOptions};
pub use export_overlay::{apply_overlay, JointOverlay, OverlayJoint};
pub use from_mcpc::urdf_from_mcpc_table;

pub use import::{load_urdf, parse_urdf, UrdfImport};
