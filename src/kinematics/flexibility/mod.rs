//! The flexibility error model (paper section 3): how far gravity bends the robot's joints and
//! links, and what that does to the tools.
//!
//! - [`stiffness`]: the data (gravity, payloads, joint and link stiffness), SI units.
//! - `names`: which body each URDF link belongs to; what names in the data mean.
//! - `model`: [`FlexibilityModel::new`] builds bodies, segments and point masses once.
//! - `loads`: the static force balance from the tips inward and the deformations `d_f`
//!   (eq. (18)–(19), (21)) at one configuration: [`FlexibilityModel::deformations`].
//! - [`beam`]: the Euler–Bernoulli cantilever formulas (eq. (21), corrected).
//! - [`compliance`]: compliance scale factors as parameters, and the exact derivatives of the
//!   deflected tool poses with respect to them (stiffness identification).
//! - `apply`: the linear map `D_f = J_f·d_f` (eq. (20)–(24)),
//!   [`FlexibilityModel::tool_deflections`], and the deflected forward kinematics,
//!   [`FlexibilityModel::deflected_tool_poses`].
//! - `derivative`: how the deflected tool poses change with the MCPC parameters,
//!   [`FlexibilityModel::deflected_pose_derivatives`]; `load_change`: the loads' and
//!   deformations' change with one parameter in closed form.
//!
//! The model, its sign conventions and the comparison with the paper: `docs/flexibility.md`.

mod apply;
mod beam;
mod compliance;
mod derivative;
mod load_change;
mod loads;
mod model;
pub(crate) mod names;
mod stiffness;

pub use beam::{point_load_deflection, uniform_load_deflection, BeamCompliance};
pub use compliance::{ComplianceBasis, ComplianceJacobian, ComplianceKind, ComplianceParameter};
pub use loads::{Deformations, JointDeformation, SegmentDeformation};
pub use model::{FlexibilityModel, Segment, SegmentEnd};
pub(crate) use stiffness::{mass_problem, stiffness_problem};
pub use stiffness::{JointStiffness, LinkStiffness, Payload, Stiffness, STANDARD_GRAVITY};
