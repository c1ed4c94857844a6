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
            other => Err(Error::setting(
                "length_unit",
                format!(
                    "'{}' is not a length unit; use m or mm",
                    crate::limits::cut(other)
                ),
            )),
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
            other => Err(Error::setting(
                "angle_unit",
                format!(
                    "'{}' is not an angle unit; use rad or deg",
                    crate::limits::cut(other)
                ),
            )),
        }
    }
}

/// The units of a measurement CSV's numbers after flags, header and defaults are combined.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MeasurementUnits {
    /// Positions and targets.
    pub length: LengthUnit,
    /// Revolute and continuous joint values.
    pub angle: AngleUnit,
    /// Prismatic joint values (a controller may log metres while the tracker writes mm).
    pub joint_length: LengthUnit,
    /// Measured roll, pitch and yaw (a tracker may write degrees while the controller logs
    /// radians); default: the angle unit.
    pub rotation: AngleUnit,
}

/// The units a measurement CSV states in its comment lines before the header, each `None`
/// when not stated. Two forms are read: `# units: length=mm angle=deg joint_length=m
/// rotation=deg` (the
/// documented one; keys in any order, each optional) and `# lengths in mm, angles in deg`
/// (what treecal wrote before).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StatedUnits {
    /// `length=`.
    pub length: Option<LengthUnit>,
    /// `angle=`.
    pub angle: Option<AngleUnit>,
    /// `joint_length=`.
    pub joint_length: Option<LengthUnit>,
    /// `rotation=` (of measured roll, pitch, yaw).
    pub rotation: Option<AngleUnit>,
    /// The 1-based line of the units comment, if any.
    pub line: Option<usize>,
}

impl StatedUnits {
    /// The documented comment line for `units` (without a newline): `# units: length=mm
    /// angle=deg`, with `joint_length=` only when it differs from `length`.
    pub fn line_for(units: &MeasurementUnits) -> String {
        let mut line = format!(
            "# units: length={} angle={}",
            units.length.symbol(),
            units.angle.symbol()
        );
        if units.joint_length != units.length {
            line.push_str(&format!(" joint_length={}", units.joint_length.symbol()));
        }
        if units.rotation != units.angle {
            line.push_str(&format!(" rotation={}", units.rotation.symbol()));
        }
        line
    }
}

/// The lines of `text` broken at `\r\n`, `\n` or a lone `\r` (old Mac files; `str::lines`
/// keeps a lone `\r` inside the line).
fn lines_any_break(text: &str) -> impl Iterator<Item = &str> {
    let mut rest = Some(text);
    std::iter::from_fn(move || {
        let current = rest?;
        match current.find(['\r', '\n']) {
            Some(at) => {
                let skip = if current[at..].starts_with("\r\n") {
                    2
                } else {
                    1
                };
                rest = Some(&current[at + skip..]);
                Some(&current[..at])
            }
            None => {
                rest = None;
                Some(current)
            }
        }
    })
}

/// Reads the units comment of CSV `text` (see [`StatedUnits`]): only `#` lines before the
/// first other non-blank line are looked at. A malformed units comment is an error naming
/// its line.
pub fn parse_units_header(text: &str, origin: &str) -> Result<StatedUnits> {
    let mut header = StatedUnits::default();
    for (index, raw) in lines_any_break(text).enumerate() {
        // A byte-order mark (spreadsheet programs write one) must not hide the comment.
        let line = raw.trim_start_matches('\u{feff}').trim();
        if line.is_empty() {
            continue;
        }
        let Some(comment) = line.strip_prefix('#') else {
            break;
        };
        let number = index + 1;
        let fail = |message: String| Error::InvalidData {
            origin: format!("{origin}:{number}"),
            message,
        };
        let comment = comment.trim();
        let states_units = comment.starts_with("units:") || old_form(comment).is_some();
        if let (true, Some(first)) = (states_units, header.line) {
            return Err(fail(format!(
                "a second units comment (the first is on line {first}); keep one, so that \
                 the file states its units once"
            )));
        }
        if let Some(rest) = comment.strip_prefix("units:") {
            for item in rest.split_whitespace() {
                let (key, value) = item.split_once('=').ok_or_else(|| {
                    fail(format!(
                        "'{}' in the units comment is not key=value; write e.g. \
                         `# units: length=mm angle=deg`",
                        crate::limits::cut(item)
                    ))
                })?;
                let bad = |e: Error| match e {
                    Error::InvalidData { message, .. } | Error::InvalidSetting { message, .. } => {
                        fail(format!("{key}: {message}"))
                    }
                    other => other,
                };
                match key {
                    "length" => header.length = Some(value.parse().map_err(bad)?),
                    "angle" => header.angle = Some(value.parse().map_err(bad)?),
                    "joint_length" => header.joint_length = Some(value.parse().map_err(bad)?),
                    "rotation" => header.rotation = Some(value.parse().map_err(bad)?),
                    other => {
                        return Err(fail(format!(
                            "unknown key '{}' in the units comment; the keys are length, \
                             angle, joint_length and rotation",
                            crate::limits::cut(other)
                        )))
                    }
                }
            }
            header.line = Some(number);
        } else if let Some((length, angle)) = old_form(comment) {
            header.length = Some(length);
            header.angle = Some(angle);
            header.line = Some(number);
        }
    }
    Ok(header)
}

/// `lengths in mm, angles in deg`, as treecal wrote it before the `units:` form.
fn old_form(comment: &str) -> Option<(LengthUnit, AngleUnit)> {
    let (length, angle) = comment.split_once(',')?;
    let length = length.trim().strip_prefix("lengths in ")?.parse().ok()?;
    let angle = angle.trim().strip_prefix("angles in ")?.parse().ok()?;
    Some((length, angle))
}

/// Combines the units the user gave (`flags`, e.g. `--length-unit`), the file's `header` and
/// the defaults (m, rad; prismatic joints as lengths). A flag that contradicts the header is
/// an error: one of the two is wrong and guessing which would silently scale the data.
pub fn resolve_units(
    flags: &StatedUnits,
    header: &StatedUnits,
    origin: &str,
) -> Result<MeasurementUnits> {
    let place = match header.line {
        Some(line) => format!("{origin}:{line}"),
        None => origin.to_owned(),
    };
    fn pick<T: PartialEq + Copy>(
        flag: Option<T>,
        stated: Option<T>,
        symbol: fn(T) -> &'static str,
        names: (&str, &str),
        place: &str,
    ) -> Result<Option<T>> {
        match (flag, stated) {
            (Some(f), Some(s)) if f != s => Err(Error::InvalidData {
                origin: place.to_owned(),
                message: format!(
                    "{} {} contradicts the file's units comment ({}={}); remove the setting or \
                     correct the comment",
                    names.0,
                    symbol(f),
                    names.1,
                    symbol(s)
                ),
            }),
            (Some(f), _) => Ok(Some(f)),
            (None, s) => Ok(s),
        }
    }
    let length = pick(
        flags.length,
        header.length,
        LengthUnit::symbol,
        ("`length_unit`", "length"),
        &place,
    )?
    .unwrap_or_default();
    let angle = pick(
        flags.angle,
        header.angle,
        AngleUnit::symbol,
        ("`angle_unit`", "angle"),
        &place,
    )?
    .unwrap_or_default();
    let joint_length = pick(
        flags.joint_length,
        header.joint_length,
        LengthUnit::symbol,
        ("`joint_length_unit`", "joint_length"),
        &place,
    )?
    .unwrap_or(length);
    let rotation = pick(
        flags.rotation,
        header.rotation,
        AngleUnit::symbol,
        ("the rotation unit", "rotation"),
        &place,
    )?
    .unwrap_or(angle);
    Ok(MeasurementUnits {
        length,
        angle,
        joint_length,
        rotation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_header_forms_are_read_and_conflicts_named() {
        let new = parse_units_header("# units: angle=deg length=mm\nid,x\n", "f.csv").unwrap();
        assert_eq!(new.length, Some(LengthUnit::Millimetre));
        assert_eq!(new.angle, Some(AngleUnit::Degree));
        assert_eq!(new.joint_length, None);
        assert_eq!(new.line, Some(1));
        let old = parse_units_header("\n# made today\n# lengths in mm, angles in deg\nid\n", "f")
            .unwrap();
        assert_eq!(old.length, Some(LengthUnit::Millimetre));
        assert_eq!(old.line, Some(3));
        // After the header row a comment is data, not a units statement.
        let late = parse_units_header("id\n# units: length=mm\n", "f").unwrap();
        assert_eq!(late, StatedUnits::default());
        let bad = parse_units_header("# units: length=cm\n", "f").unwrap_err();
        assert!(bad.to_string().contains("f:1"), "{bad}");
        let unknown = parse_units_header("# units: size=mm\n", "f").unwrap_err();
        assert!(
            unknown.to_string().contains("unknown key 'size'"),
            "{unknown}"
        );

        let units = resolve_units(&StatedUnits::default(), &new, "f").unwrap();
        assert_eq!(units.joint_length, LengthUnit::Millimetre);
        let flags = StatedUnits {
            joint_length: Some(LengthUnit::Metre),
            ..StatedUnits::default()
        };
        assert_eq!(
            resolve_units(&flags, &new, "f").unwrap().joint_length,
            LengthUnit::Metre
        );
        let conflict = StatedUnits {
            length: Some(LengthUnit::Metre),
            ..StatedUnits::default()
        };
        let error = resolve_units(&conflict, &new, "f").unwrap_err().to_string();
        assert!(
            error.contains("`length_unit` m contradicts") && error.contains("f:1"),
            "{error}"
        );
        assert_eq!(
            resolve_units(&StatedUnits::default(), &StatedUnits::default(), "f").unwrap(),
            MeasurementUnits::default()
        );
        assert_eq!(
            StatedUnits::line_for(&units),
            "# units: length=mm angle=deg"
        );
    }
}
