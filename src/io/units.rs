//! Units of lengths and angles in data files; everything inside treecal is metres and radians.

use crate::error::{Error, Result};
use std::str::FromStr;

/// The unit of lengths (positions, prismatic joint values) in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LengthUnit {
    /// Metres (`m`).
    #[default]
    Metre,
    /// Millimetres (`mm`).
    Millimetre,
}

impl LengthUnit {
    /// Metres per unit: multiply a file value by this to get metres.
    pub fn in_metres(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Millimetre => 1e-3,
        }
    }

    /// The symbol used on the command line and in messages (`m`, `mm`).
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Millimetre => "mm",
        }
    }
}

impl FromStr for LengthUnit {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        match text.trim() {
            "m" => Ok(LengthUnit::Metre),
            "mm" => Ok(LengthUnit::Millimetre),
            other => Err(Error::InvalidData {
                origin: "--length-unit".into(),
                message: format!("'{other}' is not a length unit; use m or mm"),
            }),
        }
    }
}

/// The unit of angles (revolute and continuous joint values) in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AngleUnit {
    /// Radians (`rad`).
    #[default]
    Radian,
    /// Degrees (`deg`).
    Degree,
}

impl AngleUnit {
    /// Radians per unit: multiply a file value by this to get radians.
    pub fn in_radians(self) -> f64 {
        match self {
            AngleUnit::Radian => 1.0,
            AngleUnit::Degree => std::f64::consts::PI / 180.0,
        }
    }

    /// The symbol used on the command line and in messages (`rad`, `deg`).
    pub fn symbol(self) -> &'static str {
        match self {
            AngleUnit::Radian => "rad",
            AngleUnit::Degree => "deg",
        }
    }
}

impl FromStr for AngleUnit {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        match text.trim() {
            "rad" => Ok(AngleUnit::Radian),
            "deg" => Ok(AngleUnit::Degree),
            other => Err(Error::InvalidData {
                origin: "--angle-unit".into(),
                message: format!("'{other}' is not an angle unit; use rad or deg"),
            }),
        }
    }
}
