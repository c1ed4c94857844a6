//! URDF in and out: the only module that uses urdf-rs or reads XML.
//!
//! - [`load_urdf`], [`parse_urdf`]: URDF text → [`KinematicTree`](crate::tree::KinematicTree),
//!   with every check a real robot file needs (names, roots, cycles, NaN, unsupported joints).
//! - [`urdf_from_mcpc_table`]: an MCPC table (paper Table 1 layout) → a new URDF document.
//! - [`export_urdf`]: a calibrated MCPC model → the original URDF with corrected joint origins,
//!   edited in place; [`apply_overlay`]: the same edits as a joint-origin overlay.

mod bounds;
mod export;
mod export_options;
mod export_overlay;
mod from_mcpc;
mod import;
mod tolerant;
mod xml;

pub use export::UNCHANGED_TOLERANCE;
pub use export_options::{DROPPED_OFFSET_SIGMAS, ON_AXIS_TOLERANCE};

pub use export::{export_urdf, export_urdf_with, ExportReport, JointChange};
pub use export_options::{AddedReason, AddedToolLink, DroppedOffset, ExportOptions};
pub use export_overlay::{apply_overlay, JointOverlay, OverlayJoint};
pub use from_mcpc::urdf_from_mcpc_table;

pub use import::{load_urdf, parse_urdf, UrdfImport};
