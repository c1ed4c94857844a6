//! Tracker / motion-capture logs (`treecal pair --tracker`): a CSV with a time column and a
//! target's position `x,y,z`, optionally a rigid body's orientation `qw,qx,qy,qz`. Other
//! column names (a vendor's export) are mapped with [`TrackerColumns`].

use super::bounded::read_text;
use super::csv_fields::CsvTable;
use super::joint_log::{number, MAX_TIME};
use super::joints_csv::parse_csv;
use super::units::{parse_units_header, resolve_units, LengthUnit, StatedUnits};
use crate::error::{Error, Result};
use crate::limits::{self, Quantity, MAX_CSV_BYTES};
use crate::math::{Rotation, Vec3};
use nalgebra::Quaternion;
use std::path::Path;
use std::str::FromStr;

/// The keys of [`TrackerColumns`], in the order written.
pub const TRACKER_KEYS: [&str; 8] = ["time", "x", "y", "z", "qw", "qx", "qy", "qz"];

/// The tracker CSV's column for each quantity (default: the key itself, e.g. `x`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TrackerColumns {
    /// Column names for `time, x, y, z, qw, qx, qy, qz`.
    pub names: [String; 8],
}

impl Default for TrackerColumns {
    fn default() -> Self {
        Self {
            names: TRACKER_KEYS.map(String::from),
        }
    }
}

/// `key=column,key=column`: e.g. `time=Time,x=TX,y=TY,z=TZ`; keys not given keep their default.
impl FromStr for TrackerColumns {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        let mut columns = Self::default();
        for item in text.split(',').map(str::trim).filter(|i| !i.is_empty()) {
            let fail = |message: String| Error::setting("tracker_columns", message);
            let (key, column) = item
                .split_once('=')
                .ok_or_else(|| fail(format!("'{item}' is not key=column, e.g. x=TX")))?;
            let index = TRACKER_KEYS
                .iter()
                .position(|k| *k == key.trim())
                .ok_or_else(|| {
                    fail(format!(
                        "unknown key '{}'; use {}",
                        key.trim(),
                        TRACKER_KEYS.join(", ")
                    ))
                })?;
            columns.names[index] = column.trim().to_owned();
        }
        Ok(columns)
    }
}

/// How to read a tracker log.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackerLogOptions {
    /// Which columns hold what.
    pub columns: TrackerColumns,
    /// Frames per second when the time column counts frames [default: it is in seconds].
    pub rate: Option<f64>,
    /// Unit of positions [default: the file's `# units: length=…` comment, else m].
    pub length_unit: Option<LengthUnit>,
}

/// A tracker log as read, in metres and seconds.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerLog {
    /// How messages name the file.
    pub origin: String,
    /// Sample times (s), non-decreasing.
    pub times: Vec<f64>,
    /// Target positions (m).
    pub positions: Vec<Vec3>,
    /// Rigid-body orientations, when the file has quaternion columns.
    pub orientations: Option<Vec<Rotation>>,
    /// Lines of rows left out because a position or quaternion cell was empty or NaN (the
    /// target was not seen).
    pub dropped: Vec<usize>,
    /// The unit positions were given in.
    pub length_unit: LengthUnit,
}

/// Reads a tracker CSV.
pub fn read_tracker_log(path: &Path, options: &TrackerLogOptions) -> Result<TrackerLog> {
    let text = read_text(path, MAX_CSV_BYTES)?;
    parse_tracker_log(&text, &path.display().to_string(), options)
}

/// Parses a tracker CSV (see [`read_tracker_log`]).
pub fn parse_tracker_log(
    text: &str,
    origin: &str,
    options: &TrackerLogOptions,
) -> Result<TrackerLog> {
    let length_unit = length_unit(text, origin, options)?;
    let table = parse_csv(text, origin)?;
    let fail = |place: String, message: String| Error::InvalidData {
        origin: place,
        message,
    };
    let (used, pose) = used_columns(&table, origin, options)?;
    let rate = match options.rate {
        Some(r) if !(r.is_finite() && r > 0.0) => {
            return Err(Error::setting(
                "tracker_rate",
                format!("{r} is not a positive frame rate"),
            ))
        }
        Some(r) => r,
        None => 1.0,
    };
    let scale = length_unit.in_metres();
    let mut log = TrackerLog {
        origin: origin.to_owned(),
        times: Vec::new(),
        positions: Vec::new(),
        orientations: pose.then(Vec::new),
        dropped: Vec::new(),
        length_unit,
    };
    for (line, fields) in &table.records {
        let place = |i: usize| format!("{origin}:{line}:{}", table.headers[i]);
        let mut values = Vec::with_capacity(used.len());
        for &i in &used {
            let text = fields[i].as_str();
            values.push(if text.eq_ignore_ascii_case("nan") {
                None
            } else {
                number(text, &place(i))?
            });
        }
        let Some(t) = values[0] else {
            return Err(fail(place(used[0]), "the time is empty".into()));
        };
        let t = t / rate;
        if t.abs() > MAX_TIME || log.times.last().is_some_and(|&last| t < last) {
            return Err(fail(place(used[0]), format!("time {t} s is out of order or beyond ±{MAX_TIME} s; samples must be in time order")));
        }
        if values.iter().any(Option::is_none) {
            log.dropped.push(*line);
            continue;
        }
        let v: Vec<f64> = values.into_iter().flatten().collect();
        let position = Vec3::new(v[1], v[2], v[3]) * scale;
        for (k, value) in position.iter().enumerate() {
            limits::check(*value, Quantity::Length, || place(used[k + 1]))?;
        }
        if let Some(orientations) = &mut log.orientations {
            orientations.push(unit_quaternion(
                Quaternion::new(v[4], v[5], v[6], v[7]),
                &format!("{origin}:{line}"),
            )?);
        }
        log.times.push(t);
        log.positions.push(position);
    }
    if log.times.len() < 2 {
        return Err(fail(
            origin.to_owned(),
            format!(
                "{} samples with a seen target; a tracker log needs many",
                log.times.len()
            ),
        ));
    }
    Ok(log)
}

/// The length unit of a tracker CSV: the options', else its units comment's, else metres.
fn length_unit(text: &str, origin: &str, options: &TrackerLogOptions) -> Result<LengthUnit> {
    let stated = parse_units_header(text, origin)?;
    let flags = StatedUnits {
        length: options.length_unit,
        ..StatedUnits::default()
    };
    let header = StatedUnits {
        length: stated.length,
        ..StatedUnits::default()
    };
    Ok(resolve_units(
        &flags,
        &StatedUnits {
            line: stated.line,
            ..header
        },
        origin,
    )?
    .length)
}

/// The columns of time, x, y, z (and the quaternion's w, x, y, z when the log has poses), and
/// whether it has poses.
fn used_columns(
    table: &CsvTable,
    origin: &str,
    options: &TrackerLogOptions,
) -> Result<(Vec<usize>, bool)> {
    let names = &options.columns.names;
    let find = |key: usize| table.headers.iter().position(|h| *h == names[key]);
    let missing = |keys: &[usize]| {
        keys.iter()
            .filter(|&&k| find(k).is_none())
            .map(|&k| format!("'{}' ({})", names[k], TRACKER_KEYS[k]))
            .collect::<Vec<_>>()
    };
    let required = missing(&[0, 1, 2, 3]);
    let quaternion = missing(&[4, 5, 6, 7]);
    let header_place = format!("{origin}:{}", table.header_line);
    let fail = |place: String, message: String| Error::InvalidData {
        origin: place,
        message,
    };
    if !required.is_empty() {
        return Err(fail(header_place, format!(
            "no column {} (columns: {}); rename the columns or map them with `tracker_columns`, e.g. time=Time,x=TX,y=TY,z=TZ",
            required.join(", "),
            table.headers.join(", ")
        )));
    }
    if !quaternion.is_empty() && quaternion.len() < 4 {
        return Err(fail(
            header_place,
            format!(
                "a pose needs all four quaternion columns; missing {}",
                quaternion.join(", ")
            ),
        ));
    }
    let pose = quaternion.is_empty();
    Ok((
        (0..if pose { 8 } else { 4 }).filter_map(find).collect(),
        pose,
    ))
}

/// A quaternion within 1 % of unit length, normalised; a wrong column order usually is not.
fn unit_quaternion(q: Quaternion<f64>, place: &str) -> Result<Rotation> {
    let norm = q.norm();
    if (norm - 1.0).abs() > 1e-2 {
        return Err(Error::InvalidData {
            origin: place.to_owned(),
            message: format!(
                "the quaternion has norm {norm:.4}, not 1; check which columns are qw, qx, qy, qz"
            ),
        });
    }
    Ok(Rotation::new_normalize(q))
}
