//! Link mass properties and shapes, as plain data (no file format in here).

use crate::math::{Mat3, Pose, Vec3};

/// A link's mass properties (URDF `<inertial>`).
#[derive(Debug, Clone, PartialEq)]
pub struct Inertial {
    /// Mass in kg.
    pub mass: f64,
    /// Pose of the inertia frame (centre of mass) in the link frame.
    pub link_from_inertia: Pose,
    /// Inertia tensor about the centre of mass in the inertia frame, kg·m².
    pub inertia: Mat3,
}

impl Inertial {
    /// Centre of mass in the link frame.
    pub fn center_of_mass(&self) -> Vec3 {
        self.link_from_inertia.translation.vector
    }
}

/// A primitive or mesh shape, in metres.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Box with full side lengths.
    Box {
        /// Side lengths along x, y, z.
        size: Vec3,
    },
    /// Cylinder along its z axis, centred on its origin.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Full length.
        length: f64,
    },
    /// Capsule along its z axis (a URDF extension some files use).
    Capsule {
        /// Radius.
        radius: f64,
        /// Length of the straight part.
        length: f64,
    },
    /// Sphere.
    Sphere {
        /// Radius.
        radius: f64,
    },
    /// A mesh file, never opened for kinematics.
    Mesh {
        /// The file name as written in the URDF (may be `package://...`).
        filename: String,
        /// Scale factors along x, y, z.
        scale: Vec3,
    },
}

/// The shapes of one link, each with its pose in the link frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinkGeometry {
    /// `<collision>` shapes.
    pub collisions: Vec<(Pose, Shape)>,
    /// `<visual>` shapes.
    pub visuals: Vec<(Pose, Shape)>,
}
