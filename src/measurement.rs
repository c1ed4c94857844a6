//! Measured configurations and what was observed there (data only), and the three-target
//! tool frame of the paper's section 5.3.1.

use crate::math::{Pose, Vec3};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};

/// What a measuring instrument reports for one tool at one configuration, in the
/// measurement frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Observation {
    /// A full tool pose (e.g. the three-target frame of the paper's section 5.3.1).
    Pose(Pose),
    /// The position of one target fixed on the tool (a single laser-tracker reflector).
    Position(Vec3),
    /// A contact: the tool's face flush with a plane, its contact point on a plane, touching
    /// another tool's contact point, or a known or fitted distance from it. No instrument
    /// reading: the contact itself is the measurement (its measured value is zero). Boxed: a
    /// contact is twice a pose's size, and every row of a million-row file would pay for it.
    Contact(Box<Contact>),
}

impl Observation {
    /// Rows this observation contributes to the identification problem (6, 3, or a
    /// contact's 3 or 1).
    pub fn rows(&self) -> usize {
        match self {
            Observation::Pose(_) => 6,
            Observation::Position(_) => 3,
            Observation::Contact(contact) => contact.rows(),
        }
    }

    /// The contact, when this observation is one.
    pub fn contact(&self) -> Option<&Contact> {
        match self {
            Observation::Contact(contact) => Some(contact),
            _ => None,
        }
    }

    /// The contact, mutable, when this observation is one.
    pub fn contact_mut(&mut self) -> Option<&mut Contact> {
        match self {
            Observation::Contact(contact) => Some(contact),
            _ => None,
        }
    }
}

/// A plane a contact lies in: a nuisance block of three values (its height `h` (m) along its
/// normal and two tilts `a`, `b` (rad) about its nominal frame's x and y axes), about a
/// nominal frame. The plane is `{x : n·(x − o) = h}` with `n` the z axis of
/// `nominal·Rx(a)·Ry(b)` and `o` the nominal origin (all in the measurement frame: the
/// reference link's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPlane {
    /// The nuisance block holding `[h, a, b]`.
    pub block: usize,
    /// The nominal plane frame (its z axis the nominal normal).
    pub nominal: Pose,
}

/// A contact face on a tool: a nuisance block of three values (its offset `d` (m) along its
/// normal and two tilts `a`, `b` (rad) about its nominal frame's x and y axes) about a
/// nominal frame in the tool frame. The face's normal is the z axis `m` of
/// `nominal·Rx(a)·Ry(b)`, its point `f = o + d·m` (tool frame); its in-plane position and
/// yaw carry nothing for a flush contact and are not parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactFace {
    /// The nuisance block holding `[d, a, b]`.
    pub block: usize,
    /// The nominal face frame in the tool frame.
    pub nominal: Pose,
}

/// One contact (the measured tool is [`Measurement::tool`]); contact points are nuisance
/// blocks of three values (x, y, z (m) in their tool's frame), a bar's length a block of one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Contact {
    /// The tool's face lies flush in a plane: 3 equations (height, 2 tilts).
    Flush {
        /// The plane.
        plane: ContactPlane,
        /// The tool's contact face.
        face: ContactFace,
    },
    /// The tool's contact point lies in a plane: 1 equation (height).
    Point {
        /// The plane.
        plane: ContactPlane,
        /// The nuisance block of the tool's contact point.
        point: usize,
    },
    /// The tool's contact point coincides with another tool's: 3 equations (gap x, y, z).
    Touch {
        /// The nuisance block of the tool's contact point.
        point: usize,
        /// The other tool.
        tool2: usize,
        /// The nuisance block of the other tool's contact point.
        point2: usize,
    },
    /// The tool's contact point lies a bar's length from another tool's: 1 equation.
    Distance {
        /// The nuisance block of the tool's contact point.
        point: usize,
        /// The other tool.
        tool2: usize,
        /// The nuisance block of the other tool's contact point.
        point2: usize,
        /// The nuisance block of the bar's length (one value, fixed when known).
        length: usize,
    },
}

impl Contact {
    /// Equations this contact contributes: 3 (flush, touch) or 1 (point, distance).
    pub fn rows(&self) -> usize {
        match self {
            Contact::Flush { .. } | Contact::Touch { .. } => 3,
            Contact::Point { .. } | Contact::Distance { .. } => 1,
        }
    }

    /// `flush`, `point`, `touch` or `distance`.
    pub fn name(&self) -> &'static str {
        match self {
            Contact::Flush { .. } => "flush",
            Contact::Point { .. } => "point",
            Contact::Touch { .. } => "touch",
            Contact::Distance { .. } => "distance",
        }
    }

    /// The other tool of a touch or a distance.
    pub fn second_tool(&self) -> Option<usize> {
        match self {
            Contact::Touch { tool2, .. } | Contact::Distance { tool2, .. } => Some(*tool2),
            _ => None,
        }
    }
}

/// One measurement: a configuration, the tool observed, and the observation.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Index of the tool in [`crate::McpcModel::tools`].
    pub tool: usize,
    /// The configuration (one value per independent joint of the tree).
    pub q: Vec<f64>,
    /// What was measured.
    pub observation: Observation,
    /// The calibration stage the measurement was taken for (e.g. `torso` for configurations
    /// with the arms locked), if labelled.
    pub stage: Option<String>,
    /// The payload (kg) the robot carried at every tool when this row was measured (the
    /// measurement CSV's `payload_kg` column); `None`: the stiffness file's payloads.
    pub payload: Option<f64>,
    /// The measurement session (the CSV's `session` column): rows of one session share one
    /// measurement frame, each session has its own (`calibration::sessions`); `None`: the
    /// unnamed session.
    pub session: Option<String>,
}

/// Spacing of the targets A→B and A→C that [`targets_on`] places on a tool (m).
pub const TARGET_SPACING: f64 = 0.1;

/// Targets closer than this cannot define a frame: [`targets_problem`] (m).
pub const MIN_TARGET_SEPARATION: f64 = 1e-3;

/// The angle between AB and AC (or its supplement) below which [`targets_problem`] calls
/// three targets collinear (rad): 0.5°.
pub const MIN_TARGET_ANGLE: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// Three targets on a tool frame: A at the origin, B along x, C along y, [`TARGET_SPACING`]
/// apart; [`frame_from_targets`] turns them back into the same frame.
pub fn targets_on(tool: &Pose) -> [Vec3; 3] {
    let a = tool.translation.vector;
    [
        a,
        a + tool.rotation * Vec3::x() * TARGET_SPACING,
        a + tool.rotation * Vec3::y() * TARGET_SPACING,
    ]
}

/// The frame built from three targets as in the paper's section 5.3.1: origin A, X along AB,
/// Z along AB × AC, Y completing a right-handed frame. `None` for exactly coincident or
/// collinear targets; [`targets_problem`] applies a measurement-sized tolerance.
pub fn frame_from_targets(a: &Vec3, b: &Vec3, c: &Vec3) -> Option<Pose> {
    let x = (b - a).try_normalize(1e-12)?;
    let z = (b - a).cross(&(c - a)).try_normalize(1e-12)?;
    let y = z.cross(&x);
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Some(Pose::from_parts(
        (*a).into(),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

/// Why three targets (m) define no reliable frame, or `None` when they do: two of them closer
/// than [`MIN_TARGET_SEPARATION`] (coincident), or AB and AC within [`MIN_TARGET_ANGLE`] of
/// parallel (collinear).
pub fn targets_problem(a: &Vec3, b: &Vec3, c: &Vec3) -> Option<String> {
    if !a
        .iter()
        .chain(b.iter())
        .chain(c.iter())
        .all(|v| v.is_finite())
    {
        return Some("a target coordinate is not a finite number".into());
    }
    let pairs = [("A", "B", a, b), ("A", "C", a, c), ("B", "C", b, c)];
    for (first, second, p, q) in pairs {
        let distance = (q - p).norm();
        // Written so that NaN (from an overflow) fails the test too.
        if distance.is_nan() || distance < MIN_TARGET_SEPARATION {
            return Some(format!(
                "targets {first} and {second} are {:.3} mm apart (coincident; at least {} mm needed)",
                distance * 1e3,
                MIN_TARGET_SEPARATION * 1e3
            ));
        }
    }
    let (ab, ac) = (b - a, c - a);
    let sine = ab.cross(&ac).norm() / (ab.norm() * ac.norm());
    if sine.is_nan() || sine < MIN_TARGET_ANGLE.sin() {
        return Some(format!(
            "targets A, B, C are collinear (AB and AC are {:.3}° from parallel; at least {}° needed)",
            sine.clamp(0.0, 1.0).asin().to_degrees(),
            MIN_TARGET_ANGLE.to_degrees()
        ));
    }
    None
}
