//! Registration files (YAML, `treecal calibrate --measurement-frame FILE`): where the robot's
//! root link frame is in the measurement (tracker) frame, when a registration is known.
//!
//! ```yaml
//! # The robot base in the tracker frame.
//! units: {length: mm, angle: deg}
//! xyz: [2300.0, -150.0, 420.0]
//! rpy: [0.0, 0.0, 90.0]        # roll, pitch, yaw about the fixed x, y, z axes (as URDF)
//! ```

use super::units::{AngleUnit, LengthUnit};
use crate::error::{Error, Result};
use crate::math::Pose;
use nalgebra::{Translation3, UnitQuaternion};
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RegistrationFile {
    units: UnitsEntry,
    xyz: [f64; 3],
    rpy: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UnitsEntry {
    length: String,
    angle: String,
}

/// Parses a registration: `world_from_base`, the pose of the robot's root link frame in the
/// measurement frame (metres, radians); `origin` names the file in messages.
pub fn parse_registration(text: &str, origin: &str) -> Result<Pose> {
    let file: RegistrationFile = serde_yaml::from_str(text).map_err(|e| Error::InvalidData {
        origin: match e.location() {
            Some(l) => format!("{origin}:{}:{}", l.line(), l.column()),
            None => origin.to_owned(),
        },
        message: format!(
            "not a registration ({e}); give `units: {{length: mm, angle: deg}}`, `xyz: [x, y, z]` \
             and `rpy: [roll, pitch, yaw]`: the robot base in the tracker frame (see \
             docs/file-formats.md)"
        ),
    })?;
    let unit_error = |key: &str, e: Error| match e {
        Error::InvalidData { message, .. } => Error::InvalidData {
            origin: format!("{origin}: units.{key}"),
            message,
        },
        other => other,
    };
    let length: LengthUnit = file
        .units
        .length
        .parse()
        .map_err(|e| unit_error("length", e))?;
    let angle: AngleUnit = file
        .units
        .angle
        .parse()
        .map_err(|e| unit_error("angle", e))?;
    if file.xyz.iter().chain(&file.rpy).any(|v| !v.is_finite()) {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: "xyz and rpy must be finite numbers".into(),
        });
    }
    let [x, y, z] = file.xyz.map(|v| v * length.in_metres());
    let [roll, pitch, yaw] = file.rpy.map(|v| v * angle.in_radians());
    Ok(Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    ))
}

/// Reads a registration file; see [`parse_registration`].
pub fn read_registration(path: &Path) -> Result<Pose> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_registration(&text, &path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_units_and_urdf_rpy() {
        let pose = parse_registration(
            "units: {length: mm, angle: deg}\nxyz: [1000, -20, 5]\nrpy: [0, 0, 90]\n",
            "r.yaml",
        )
        .unwrap();
        assert!(
            (pose.translation.vector - nalgebra::Vector3::new(1.0, -0.02, 0.005)).norm() < 1e-12
        );
        // Yaw 90°: the base x axis points along the tracker's y.
        let x = pose.rotation * nalgebra::Vector3::x();
        assert!((x - nalgebra::Vector3::y()).norm() < 1e-12);
        let missing = parse_registration("xyz: [0, 0, 0]\nrpy: [0, 0, 0]\n", "r.yaml")
            .unwrap_err()
            .to_string();
        assert!(missing.contains("units"), "{missing}");
        let bad = parse_registration(
            "units: {length: cm, angle: rad}\nxyz: [0, 0, 0]\nrpy: [0, 0, 0]\n",
            "r.yaml",
        )
        .unwrap_err()
        .to_string();
        assert!(
            bad.contains("units.length") && bad.contains("use m or mm"),
            "{bad}"
        );
    }
}
