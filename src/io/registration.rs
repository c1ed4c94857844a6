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
use super::yaml::parse_yaml;
use crate::error::{Error, Result};
use crate::limits::{magnitude_problem, Quantity};
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
/// measurement frame (metres, radians); `origin` names the file in messages. The size and
/// depth are limited and unknown keys are errors (`src/io/yaml.rs`); `xyz` must be within
/// [`crate::limits::MAX_LENGTH`] and `rpy` within [`crate::limits::MAX_ANGLE`], checked here
/// with the file and line.
pub fn parse_registration(text: &str, origin: &str) -> Result<Pose> {
    let file: RegistrationFile = parse_yaml(
        text,
        origin,
        "; give `units: {length: mm, angle: deg}`, `xyz: [x, y, z]` and `rpy: [roll, pitch, \
         yaw]`: the robot base in the tracker frame (see docs/file-formats.md)",
    )?;
    let unit_error = |key: &str, e: Error| match e {
        Error::InvalidData { message, .. } | Error::InvalidSetting { message, .. } => {
            Error::InvalidData {
                origin: format!("{origin}: units.{key}"),
                message,
            }
        }
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
    let xyz = checked(
        text,
        origin,
        "xyz",
        file.xyz,
        length.in_metres(),
        Quantity::Length,
    )?;
    let rpy = checked(
        text,
        origin,
        "rpy",
        file.rpy,
        angle.in_radians(),
        Quantity::Angle,
    )?;
    Ok(Pose::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    ))
}

/// `values` times `scale` (to SI), each a sane `quantity`, else an error at the line of `key`.
fn checked(
    text: &str,
    origin: &str,
    key: &str,
    values: [f64; 3],
    scale: f64,
    quantity: Quantity,
) -> Result<[f64; 3]> {
    for (index, value) in values.iter().enumerate() {
        if let Some(problem) = magnitude_problem(value * scale, quantity) {
            let line = text
                .lines()
                .position(|l| l.trim_start().starts_with(&format!("{key}:")))
                .map_or(String::new(), |n| format!(":{}", n + 1));
            return Err(Error::InvalidData {
                origin: format!("{origin}{line}"),
                message: format!("{key}[{index}] (in SI units): {problem}"),
            });
        }
    }
    Ok(values.map(|v| v * scale))
}

/// Reads a registration file (through the bounded reader, at most
/// [`crate::limits::MAX_YAML_BYTES`]); see [`parse_registration`].
pub fn read_registration(path: &Path) -> Result<Pose> {
    let text = super::bounded::read_text(path, crate::limits::MAX_YAML_BYTES)?;
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
        let far = parse_registration(
            "units: {length: mm, angle: deg}\nxyz: [1e300, 0, 0]\nrpy: [0, 0, 0]\n",
            "r.yaml",
        )
        .unwrap_err()
        .to_string();
        assert!(
            far.starts_with("r.yaml:2: xyz[0] (in SI units): 1e297 is beyond the limit"),
            "{far}"
        );
        let typo = parse_registration(
            "units: {length: mm, angle: deg}\nxyz: [0, 0, 0]\nrpyy: [0, 0, 0]\n",
            "r.yaml",
        )
        .unwrap_err()
        .to_string();
        assert!(typo.contains("the closest valid key is 'rpy'"), "{typo}");
    }
}
