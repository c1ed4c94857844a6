//! The stiffness data of a robot: gravity, payloads, joint and link stiffness (SI units).
//!
//! Pure data: no file format (see `src/io/stiffness.rs`) and no robot in here. Names are
//! resolved against a robot when a [`super::FlexibilityModel`] is built.

use crate::error::{Error, Result};
use crate::math::Vec3;

/// Standard gravity, m/s².
pub const STANDARD_GRAVITY: f64 = 9.81;

/// Stiffness of one joint against deflection of its moved frame (paper eq. (18)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointStiffness {
    /// Against rotation about the two axes normal to the joint axis, N·m/rad.
    pub bending: f64,
    /// Against rotation about the joint axis, N·m/rad.
    pub torsion: f64,
}

impl Default for JointStiffness {
    /// 5000 N·m/rad for both, the paper's section 5.2 value.
    fn default() -> Self {
        Self {
            bending: 5000.0,
            torsion: 5000.0,
        }
    }
}

/// Rigidities of a link modelled as a uniform straight beam (paper eq. (21)).
///
/// The beam frame has x along the segment; which body axes y and z are is described in
/// `docs/flexibility.md` (z is normally the proximal joint's axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkStiffness {
    /// Axial rigidity EA, N.
    pub axial: f64,
    /// Bending rigidity EI_y about the beam's y axis (deflection along z), N·m².
    pub bending_y: f64,
    /// Bending rigidity EI_z about the beam's z axis (deflection along y), N·m².
    pub bending_z: f64,
    /// Torsional rigidity G·I_p about the beam's x axis, N·m².
    pub torsion: f64,
}

impl LinkStiffness {
    /// A round tube of outer diameter `outer_diameter` and wall `wall` (m), Young's modulus
    /// `youngs_modulus` and shear modulus `shear_modulus` (Pa).
    pub fn tube(outer_diameter: f64, wall: f64, youngs_modulus: f64, shear_modulus: f64) -> Self {
        let outer = outer_diameter / 2.0;
        let inner = (outer - wall).max(0.0);
        let area = std::f64::consts::PI * (outer.powi(2) - inner.powi(2));
        let second_moment = std::f64::consts::PI / 4.0 * (outer.powi(4) - inner.powi(4));
        Self {
            axial: youngs_modulus * area,
            bending_y: youngs_modulus * second_moment,
            bending_z: youngs_modulus * second_moment,
            torsion: shear_modulus * 2.0 * second_moment,
        }
    }
}

impl Default for LinkStiffness {
    /// A Schunk-class aluminium tube: Ø70 mm, 3 mm wall, E = 70 GPa, G = 26 GPa
    /// (EA ≈ 4.42e7 N, EI ≈ 2.49e4 N·m², GI_p ≈ 1.85e4 N·m²).
    fn default() -> Self {
        Self::tube(0.070, 0.003, 70e9, 26e9)
    }
}

/// A mass carried at a tool link.
#[derive(Debug, Clone, PartialEq)]
pub struct Payload {
    /// The tool link's name.
    pub link: String,
    /// Mass, kg.
    pub mass: f64,
    /// Centre of mass in the tool link frame, m.
    pub center_of_mass: Vec3,
}

/// Everything the flexibility model needs besides the robot: loads and stiffness, SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct Stiffness {
    /// Gravitational acceleration in the root link frame, m/s².
    pub gravity: Vec3,
    /// Whether the links' own weights (URDF `<inertial>` masses) load the structure.
    pub self_weight: bool,
    /// Masses carried at tool links (several at one tool add up).
    pub payloads: Vec<Payload>,
    /// Stiffness of every calibrated joint not in `joint_overrides`.
    pub joint_default: JointStiffness,
    /// Per-joint stiffness, by joint name.
    pub joint_overrides: Vec<(String, JointStiffness)>,
    /// Rigidities of every link segment not in `link_overrides`.
    pub link_default: LinkStiffness,
    /// Per-link rigidities, by the name of a URDF link of the body or of the joint that moves it.
    pub link_overrides: Vec<(String, LinkStiffness)>,
}

impl Default for Stiffness {
    /// Gravity −9.81 m/s² along the root's z, self-weight on, no payload, the default joint
    /// and link stiffness.
    fn default() -> Self {
        Self {
            gravity: Vec3::new(0.0, 0.0, -STANDARD_GRAVITY),
            self_weight: true,
            payloads: Vec::new(),
            joint_default: JointStiffness::default(),
            joint_overrides: Vec::new(),
            link_default: LinkStiffness::default(),
            link_overrides: Vec::new(),
        }
    }
}

impl Stiffness {
    /// Checks every number: gravity finite, masses finite and ≥ 0, stiffness > 0 (`+∞` means
    /// rigid). Names are checked against a robot by [`super::FlexibilityModel::new`].
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| Error::InvalidData {
            origin: "stiffness".into(),
            message,
        };
        if !self.gravity.iter().all(|g| g.is_finite()) {
            return Err(bad(format!(
                "gravity ({}, {}, {}) m/s² is not finite",
                self.gravity.x, self.gravity.y, self.gravity.z
            )));
        }
        for payload in &self.payloads {
            if let Some(message) = mass_problem(payload.mass) {
                return Err(bad(format!(
                    "payload at '{}': mass {message}",
                    payload.link
                )));
            }
            if !payload.center_of_mass.iter().all(|c| c.is_finite()) {
                return Err(bad(format!(
                    "payload at '{}': centre of mass is not finite",
                    payload.link
                )));
            }
        }
        let joints = std::iter::once(("default", &self.joint_default))
            .chain(self.joint_overrides.iter().map(|(n, s)| (n.as_str(), s)));
        for (name, joint) in joints {
            for (what, value) in [("bending", joint.bending), ("torsion", joint.torsion)] {
                if let Some(message) = stiffness_problem(value) {
                    return Err(bad(format!("joint {name}: {what} stiffness {message}")));
                }
            }
        }
        let links = std::iter::once(("default", &self.link_default))
            .chain(self.link_overrides.iter().map(|(n, s)| (n.as_str(), s)));
        for (name, link) in links {
            let values = [
                ("EA", link.axial),
                ("EI_y", link.bending_y),
                ("EI_z", link.bending_z),
                ("GI_p", link.torsion),
            ];
            for (what, value) in values {
                if let Some(message) = stiffness_problem(value) {
                    return Err(bad(format!("link {name}: {what} {message}")));
                }
            }
        }
        Ok(())
    }
}

/// What is wrong with a stiffness value, if anything: it must be > 0; `+∞` (rigid) is allowed.
pub(crate) fn stiffness_problem(value: f64) -> Option<String> {
    if value.is_nan() || value <= 0.0 {
        Some(format!(
            "is {}; must be positive (use .inf for rigid)",
            crate::limits::shown(value)
        ))
    } else {
        None
    }
}

/// What is wrong with a mass, if anything: it must be finite and ≥ 0.
pub(crate) fn mass_problem(value: f64) -> Option<String> {
    if !value.is_finite() || value < 0.0 {
        Some(format!(
            "is {}; must be a finite number ≥ 0 (kg)",
            crate::limits::shown(value)
        ))
    } else {
        None
    }
}
