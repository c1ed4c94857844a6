//! Joint-state logs (`treecal pair --joints`): a CSV with a time column and one column per
//! joint, or a ROS 2 bag in MCAP holding `sensor_msgs/msg/JointState` (`joint_log_mcap`).

use super::joints_csv::parse_csv;
use super::units::{parse_units_header, resolve_units, AngleUnit, LengthUnit, StatedUnits};
use crate::error::{Error, Result};

/// Largest time stamp (s, either sign): a Unix time in seconds is about 2·10⁹.
pub const MAX_TIME: f64 = 1e11;

/// How to read a joint log.
#[derive(Debug, Clone, PartialEq)]
pub struct JointLogOptions {
    /// The CSV's time column (seconds).
    pub time_column: String,
    /// The MCAP topic to read [default: the one topic with JointState messages].
    pub topic: Option<String>,
    /// Unit of revolute joint values in a CSV [default: its `# units:` comment, else rad].
    pub angle_unit: Option<AngleUnit>,
    /// Unit of prismatic joint values in a CSV [default: its `# units:` comment, else m].
    pub joint_length_unit: Option<LengthUnit>,
}

impl Default for JointLogOptions {
    fn default() -> Self {
        Self {
            time_column: "time".into(),
            topic: None,
            angle_unit: None,
            joint_length_unit: None,
        }
    }
}

/// A joint log as read: values in the file's units, NaN where a sample has no value for a
/// joint.
#[derive(Debug, Clone, PartialEq)]
pub struct JointLog {
    /// How messages name the file.
    pub origin: String,
    /// Joint names, in the order first seen.
    pub names: Vec<String>,
    /// Sample times (s), non-decreasing.
    pub times: Vec<f64>,
    /// Per sample, one value per name.
    pub values: Vec<Vec<f64>>,
    /// Per sample, where it is in the file (`file:line` or `file: message n`).
    pub places: Vec<String>,
    /// Unit of revolute and continuous joint values.
    pub angle_unit: AngleUnit,
    /// Unit of prismatic joint values.
    pub joint_length_unit: LengthUnit,
}

pub use super::joint_log_read::read_joint_log;

/// Parses a joint-log CSV: a header with the time column and joint names, one sample per
/// row; an empty cell is a joint the sample does not give.
pub fn parse_joint_log_csv(
    text: &str,
    origin: &str,
    options: &JointLogOptions,
) -> Result<JointLog> {
    let stated = parse_units_header(text, origin)?;
    let header = StatedUnits {
        length: stated.joint_length.or(stated.length),
        angle: stated.angle,
        joint_length: None,
        rotation: None,
        line: stated.line,
    };
    let flags = StatedUnits {
        length: options.joint_length_unit,
        angle: options.angle_unit,
        ..StatedUnits::default()
    };
    let units = resolve_units(&flags, &header, origin)?;
    let table = parse_csv(text, origin)?;
    let time = table
        .headers
        .iter()
        .position(|h| *h == options.time_column)
        .ok_or_else(|| Error::InvalidData {
            origin: format!("{origin}:{}", table.header_line),
            message: format!(
                "no time column '{}' (columns: {}); name it with `joints_time_column`",
                options.time_column,
                table.headers.join(", ")
            ),
        })?;
    let names: Vec<String> = table
        .headers
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != time)
        .map(|(_, h)| h.clone())
        .collect();
    let mut log = JointLog {
        origin: origin.to_owned(),
        names,
        times: Vec::with_capacity(table.records.len()),
        values: Vec::with_capacity(table.records.len()),
        places: Vec::with_capacity(table.records.len()),
        angle_unit: units.angle,
        joint_length_unit: units.length,
    };
    for (line, fields) in &table.records {
        let place = |column: &str| format!("{origin}:{line}:{column}");
        let t = number(&fields[time], &place(&options.time_column))?
            .ok_or_else(|| invalid(place(&options.time_column), "the time is empty".into()))?;
        log.push_time(t, &place(&options.time_column))?;
        let mut values = Vec::with_capacity(log.names.len());
        for (i, field) in fields.iter().enumerate().filter(|(i, _)| *i != time) {
            values.push(number(field, &place(&table.headers[i]))?.unwrap_or(f64::NAN));
        }
        log.values.push(values);
        log.places.push(format!("{origin}:{line}"));
    }
    if log.times.is_empty() {
        return Err(invalid(
            origin.to_owned(),
            "no samples; the log needs data rows".into(),
        ));
    }
    Ok(log)
}

impl JointLog {
    /// Appends a sample time, refusing one out of range or earlier than the last.
    pub(crate) fn push_time(&mut self, t: f64, place: &str) -> Result<()> {
        if t.abs() > MAX_TIME {
            return Err(invalid(
                place.to_owned(),
                format!("time {t} s is beyond ±{MAX_TIME} s"),
            ));
        }
        if let Some(&last) = self.times.last() {
            if t < last {
                return Err(invalid(
                    place.to_owned(),
                    format!("time {t} s is earlier than the previous sample's {last} s; samples must be in time order"),
                ));
            }
        }
        self.times.push(t);
        Ok(())
    }
}

/// A cell as a finite number, `None` when empty; anything else is an error naming `place`.
pub(crate) fn number(field: &str, place: &str) -> Result<Option<f64>> {
    if field.is_empty() {
        return Ok(None);
    }
    match field.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(Some(v)),
        _ => Err(invalid(
            place.to_owned(),
            format!("'{field}' is not a finite number"),
        )),
    }
}

fn invalid(origin: String, message: String) -> Error {
    Error::InvalidData { origin, message }
}
