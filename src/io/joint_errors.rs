//! joint_errors.yaml (written by `treecal calibrate` when the model has harmonic or backlash
//! terms, docs/file-formats.md): the joint-angle errors a URDF cannot carry, to be added to the
//! commanded joint angles.
//!
//! ```yaml
//! units: {angle: rad}
//! joints:
//!   arm_6_joint: {sine: 0.001, cosine: -0.0004, backlash: 0.0007}
//! ```

use super::yaml::parse_yaml;
use crate::error::{Error, Result};
use crate::limits::MAX_ANGLE;
use serde::Deserialize;
use std::collections::BTreeMap;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JointErrorsFile {
    units: UnitsEntry,
    #[serde(default)]
    joints: BTreeMap<String, JointErrorEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UnitsEntry {
    angle: String,
}

/// One joint's terms (rad): `θ = q + sine·sin q + cosine·cos q + backlash·sign τ`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointErrorEntry {
    /// The first harmonic's sine coefficient.
    #[serde(default)]
    pub sine: f64,
    /// The first harmonic's cosine coefficient.
    #[serde(default)]
    pub cosine: f64,
    /// Half the dead band, signed by the gravity torque.
    #[serde(default)]
    pub backlash: f64,
}

/// Parses joint_errors.yaml: per joint name, its terms in radians; `origin` names the file in
/// messages.
pub fn parse_joint_errors(text: &str, origin: &str) -> Result<BTreeMap<String, JointErrorEntry>> {
    let file: JointErrorsFile = parse_yaml(
        text,
        origin,
        "; give `units: {angle: rad}` and `joints:` with `<joint>: {sine: …, cosine: …, backlash: …}` (see docs/file-formats.md)",
    )?;
    let scale = match file.units.angle.as_str() {
        "rad" => 1.0,
        "deg" => std::f64::consts::PI / 180.0,
        other => {
            return Err(Error::InvalidData {
                origin: format!("{origin}: units.angle"),
                message: format!("unknown angle unit '{other}': give rad or deg"),
            })
        }
    };
    let mut joints = file.joints;
    for (name, entry) in joints.iter_mut() {
        for value in [&mut entry.sine, &mut entry.cosine, &mut entry.backlash] {
            if !value.is_finite() || value.abs() * scale > MAX_ANGLE {
                return Err(Error::InvalidData {
                    origin: format!("{origin}: joints.{name}"),
                    message: format!(
                        "a joint-angle error of {value} {} is not finite or beyond {MAX_ANGLE:e} rad: check the file", file.units.angle
                    ),
                });
            }
            *value *= scale;
        }
    }
    Ok(joints)
}
