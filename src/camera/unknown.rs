//! The unknowns of a camera fit: the robot's and the rig's pose parameters, the cameras'
//! intrinsics and the contacts' nuisance values. A file of its own so that the rig (which
//! lists them) and the fit (which solves for them) both depend on it, not on each other.

/// One unknown of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unknown {
    /// A parameter of the augmented model (flat index): the robot's, or a camera's or
    /// target's pose ([`Rig::extra`](crate::camera::Rig::extra)).
    Parameter(usize),
    /// Intrinsic `index` ([`INTRINSIC_NAMES`](crate::camera::INTRINSIC_NAMES)) of camera
    /// `camera`.
    Intrinsic {
        /// The camera.
        camera: usize,
        /// Which intrinsic.
        index: usize,
    },
    /// Nuisance value `k` of the contacts
    /// ([`ContactRows::nuisance`](crate::camera::ContactRows::nuisance), 0-based among its
    /// values): a plane's height or tilt, a contact point's coordinate, a bar's length.
    Nuisance(usize),
}
