//! Contact setup YAML (issue 29, docs/file-formats.md): the reference link, each tool's link
//! with its nominal contact face (flush) and contact point (point, touch, distance), each
//! session's nominal plane as a pose in the reference link, the bar, which nuisance values are
//! fitted, and the σ of each equation kind. Lengths in m, angles in rad.

use super::yaml::parse_yaml;
use crate::error::{Error, Result};
use crate::limits::{cut, read_text, MAX_YAML_BYTES};
use crate::math::Pose;
use nalgebra::{Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

const HINT: &str = "; see the contact setup file in docs/file-formats.md";

/// A pose: `xyz` (m) and `rpy` (rad, fixed-axis roll-pitch-yaw as in a URDF origin).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PoseEntry {
    /// Translation (m).
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw (rad).
    #[serde(default)]
    pub rpy: [f64; 3],
}

impl PoseEntry {
    /// The pose.
    pub fn pose(&self) -> Pose {
        let [x, y, z] = self.xyz;
        let [r, p, w] = self.rpy;
        Pose::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(r, p, w),
        )
    }

    /// The entry of `pose`.
    pub fn of(pose: &Pose) -> Self {
        let (r, p, w) = pose.rotation.euler_angles();
        let t = pose.translation.vector;
        Self {
            xyz: [t.x, t.y, t.z],
            rpy: [r, p, w],
        }
    }
}

/// One tool: its link and its nominal contact geometry in the link's frame.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ToolSetup {
    /// The URDF link carrying the contact face or point.
    pub link: String,
    /// The nominal contact face (its z axis the face's outward normal): flush rows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub face: Option<PoseEntry>,
    /// The nominal contact point (m): point, touch and distance rows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<[f64; 3]>,
}

/// The bar of the distance rows.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BarSetup {
    /// Its nominal length (m).
    pub length: f64,
    /// Fit the length (an unknown bar) instead of holding it.
    #[serde(default)]
    pub free: bool,
}

/// Which nuisance values are fitted.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct FreeSetup {
    /// Each session's plane height and tilts (default true).
    pub plane: bool,
    /// Each face's two tilts (default true).
    pub face_tilt: bool,
    /// Each face's offset along its normal (default false: it aliases the plane height
    /// exactly; freed, the rank decision leaves the combination at its start).
    pub face_offset: bool,
    /// Each tool's contact point (default true).
    pub point: bool,
}

impl Default for FreeSetup {
    fn default() -> Self {
        Self {
            plane: true,
            face_tilt: true,
            face_offset: false,
            point: true,
        }
    }
}

/// The σ of each equation kind (m and rad).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SigmaSetup {
    /// Heights above a plane (m; default 1 mm).
    pub height: f64,
    /// Tilts against a plane (rad; default 0.01).
    pub tilt: f64,
    /// Touch gaps (m; default 1 mm).
    pub gap: f64,
    /// Bar lengths (m; default 1 mm).
    pub length: f64,
}

impl Default for SigmaSetup {
    fn default() -> Self {
        Self {
            height: 1e-3,
            tilt: 0.01,
            gap: 1e-3,
            length: 1e-3,
        }
    }
}

/// A contact setup file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSetup {
    /// The link fixed in the world while the contacts were made (a sole); `--reference-link`
    /// overrides it; neither: the URDF root.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_link: Option<String>,
    /// The tools by the name the CSV's `tool` column uses.
    pub tools: BTreeMap<String, ToolSetup>,
    /// Each session's nominal plane (its z axis the plane's normal) in the reference link.
    #[serde(default)]
    pub planes: BTreeMap<String, PoseEntry>,
    /// The bar of the distance rows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bar: Option<BarSetup>,
    /// Which nuisance values are fitted.
    #[serde(default)]
    pub free: FreeSetup,
    /// The σ of each equation kind.
    #[serde(default)]
    pub sigma: SigmaSetup,
}

/// Reads a contact setup file.
pub fn read_contact_setup(path: &Path) -> Result<ContactSetup> {
    let text = read_text(path, MAX_YAML_BYTES)?;
    parse_contact_setup(&text, &path.display().to_string())
}

/// Parses a contact setup (`origin` names it in messages) and checks its values.
pub fn parse_contact_setup(text: &str, origin: &str) -> Result<ContactSetup> {
    let setup: ContactSetup = parse_yaml(text, origin, HINT)?;
    let fail = |message: String| Error::InvalidData {
        origin: origin.to_owned(),
        message: format!("{message}{HINT}"),
    };
    if setup.tools.is_empty() {
        return Err(fail("'tools' names no tool".into()));
    }
    let finite = |values: &[f64]| values.iter().all(|v| v.is_finite() && v.abs() < 1e3);
    for (name, tool) in &setup.tools {
        let bad_face = tool
            .face
            .is_some_and(|f| !finite(&f.xyz) || !finite(&f.rpy));
        let bad_point = tool.point.is_some_and(|p| !finite(&p));
        if bad_face || bad_point {
            return Err(fail(format!(
                "tool '{}' has a value that is not a finite number below 1000 (m, rad)",
                cut(name)
            )));
        }
    }
    for (name, plane) in &setup.planes {
        if !finite(&plane.xyz) || !finite(&plane.rpy) {
            return Err(fail(format!(
                "plane '{}' has a value that is not a finite number below 1000 (m, rad)",
                cut(name)
            )));
        }
    }
    if let Some(bar) = setup.bar {
        if !(bar.length.is_finite() && bar.length > 0.0 && bar.length < 1e3) {
            return Err(fail(format!(
                "the bar's length {} is not a positive length in m",
                bar.length
            )));
        }
    }
    let s = setup.sigma;
    if ![s.height, s.tilt, s.gap, s.length]
        .iter()
        .all(|v| v.is_finite() && *v > 0.0)
    {
        return Err(fail(
            "every sigma must be a positive number (m, rad)".into(),
        ));
    }
    Ok(setup)
}

/// The setup as YAML text (what `simulate --observation flush` writes).
pub fn contact_setup_to_yaml(setup: &ContactSetup) -> Result<String> {
    serde_yaml::to_string(setup).map_err(|e| Error::InvalidData {
        origin: "contact setup".into(),
        message: e.to_string(),
    })
}
