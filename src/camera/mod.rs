//! Calibration with cameras: a camera on a link of the robot (a head, a torso, a wrist) or
//! fixed in the world looks at boards and markers on other links (or in the world), and the
//! pixels it records calibrate the tree. See `docs/camera.md`.
//!
//! - `model`: the pinhole camera with Brown–Conrady distortion, its projection and the
//!   projection's analytic Jacobians.
//! - `target`: boards (a grid of corners) and single markers.
//! - `rig`: cameras and targets mounted on the MCPC model as extra tool frames, so that their
//!   poses and pose Jacobians come from the robot's own kinematics.
//! - `observation`: one image of one target, its predicted pixels and their Jacobians.
//! - `unknown`: what a camera fit solves for (robot and rig parameters, intrinsics, contact
//!   nuisance values), below both the rig that lists them and the fit.
//! - `check`: what a camera data set determines, before fitting, said in words.
//! - `fit` and [`calibrate_camera`]: the joint fit of the robot, the rig's poses and the
//!   intrinsics from pixels, mixed with tracker rows and contacts (`ContactRows`) if there
//!   are any.

pub(crate) mod check;
mod contact_rows;
pub(crate) mod fit;
pub(crate) mod model;
pub(crate) mod observation;
pub(crate) mod rig;
mod solve;
pub(crate) mod target;
mod unknown;

pub use check::explain;
pub use check::{
    camera_identifiability, explain as explain_identifiability, CameraIdentifiability,
};
pub use contact_rows::ContactRows;
pub use fit::kind_scales;
pub use fit::{CameraFitOptions, CameraFitReport, CameraProblem, KindScale, RejectedPoint};
pub use model::MIN_DEPTH;
pub use model::{Intrinsics, Projection, Rejection, INTRINSIC_COUNT, INTRINSIC_NAMES};
pub use observation::{linearise_view, predict_pixels, View, ViewPrediction};
pub use rig::{CameraSpec, Mount, Rig, RigCamera, RigTarget, TargetSpec};
pub use solve::calibrate_camera;
pub use target::TargetShape;
pub use unknown::Unknown;
