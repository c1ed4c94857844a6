//! The measurement CSV (see `docs/file-formats.md`): one row per tool observation, with the
//! values of the joints that move the tool and the observation (a position, a pose, or three
//! targets A, B, C), in metres and radians or the units the options name.

use super::csv_fields::{CsvFields, CsvRow};
use super::joints_csv::parse_csv_fields;
pub use super::observations::ObservationKind;
use super::observations::{
    column_quantity, observation, ColumnQuantity, KINDS, LAYOUTS, OBSERVATION_COLUMNS,
};
use super::units::{
    parse_units_header, resolve_units, AngleUnit, LengthUnit, MeasurementUnits, StatedUnits,
};
use crate::error::{did_you_mean, Error, Result};
use crate::kinematics::McpcModel;
use crate::limits::{self, magnitude_problem, Quantity};
use crate::measurement::{targets_on, Measurement, Observation};
use crate::tree::{Actuation, JointKind, KinematicTree};
use std::collections::HashMap;
use std::path::Path;

mod names;
pub use names::{
    measured_targets, measured_tool_names, read_measured_targets, read_measured_tool_names,
};

mod write;
pub use write::{measurements_to_csv, measurements_to_csv_with, MeasurementWriteOptions};

mod blocks;
mod checks;
mod columns;
mod read;
mod stream;
pub(super) use read::measurements_from_table;
pub use read::parse_measurements;
pub use stream::read_measurements;

/// How to read a measurement CSV. A unit left `None` is taken from the file's units comment
/// (`# units: length=mm angle=deg`), else the default; a unit given here that contradicts the
/// comment is an error.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeasurementReadOptions {
    /// Unit of positions, targets (and prismatic joint values unless `joint_length_unit`
    /// says otherwise); default m.
    pub length_unit: Option<LengthUnit>,
    /// Unit of revolute and continuous joint values; default rad.
    pub angle_unit: Option<AngleUnit>,
    /// Unit of prismatic joint values; default `length_unit`.
    pub joint_length_unit: Option<LengthUnit>,
    /// Columns to skip (e.g. a tracker's timestamp) without a note; other columns that are
    /// neither a joint nor a measurement column are skipped with one note listing them.
    pub ignore_columns: Vec<String>,
    /// The tool link of rows without a `tool` column (the one tool named by `--tools`);
    /// without it such a file needs a model with a single tool.
    pub tool: Option<String>,
    /// A joint value outside its URDF limits is an error (otherwise a warning).
    pub strict_limits: bool,
}

/// The measurements of a CSV, with where each came from.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementSet {
    /// The measurements in file order (metres, radians).
    pub measurements: Vec<Measurement>,
    /// The `id` of each row, or its 1-based data row number as text when there is no `id` column.
    pub ids: Vec<String>,
    /// The 1-based file line of each row.
    pub lines: Vec<usize>,
    /// What the rows observe.
    pub observation: ObservationKind,
    /// Accepted oddities (joint values outside their limits, ignored columns not present),
    /// each naming its place.
    pub warnings: Vec<String>,
    /// What was read in a way worth saying (columns skipped), each naming its place.
    pub notes: Vec<String>,
    /// The units the numbers were read in.
    pub units: MeasurementUnits,
}

/// Columns of the row's identity (never joint names); the observation columns are
/// [`super::observations::OBSERVATION_COLUMNS`].
const IDENTITY: [&str; 4] = ["id", "stage", "tool", POINT_COLUMN];

/// The optional column naming a measured point on the row's tool link: the row observes the
/// marker link `<tool>_<point>` (docs/file-formats.md).
pub const POINT_COLUMN: &str = "point";

/// The link a row observes: the tool link, or the marker link of a point on it.
pub fn measured_link_name(tool: &str, point: Option<&str>) -> String {
    match point.filter(|p| !p.is_empty()) {
        Some(point) => format!("{tool}_{point}"),
        None => tool.to_owned(),
    }
}

/// The optional column of the payload at every tool (kg) a row was measured with.
pub const PAYLOAD_COLUMN: &str = "payload_kg";

/// The optional column naming the measurement session of a row: one measurement frame per
/// session (`calibration::sessions`).
pub const SESSION_COLUMN: &str = "session";

/// How messages name a row and a column: `origin:line:column` in a file, `origin, row ID,
/// column NAME` for in-memory arrays ([`super::MeasurementTable`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Places {
    /// Rows are file lines.
    Lines,
    /// Rows are named by their id (`records`' numbers are 1-based row numbers).
    RowIds,
}

impl Places {
    /// The header row, or one of its columns.
    fn header(self, origin: &str, header_line: usize, column: Option<&str>) -> String {
        match (self, column) {
            (Places::Lines, None) => format!("{origin}:{header_line}"),
            (Places::Lines, Some(name)) => format!("{origin}:{header_line}:{name}"),
            (Places::RowIds, None) => origin.to_owned(),
            (Places::RowIds, Some(name)) => format!("{origin}, column '{name}'"),
        }
    }

    /// Row `line` (whose id is `id`), or one of its columns.
    fn row(self, origin: &str, line: usize, id: &str, column: Option<&str>) -> String {
        match (self, column) {
            (Places::Lines, None) => format!("{origin}:{line}"),
            (Places::Lines, Some(name)) => format!("{origin}:{line}:{name}"),
            (Places::RowIds, None) => format!("{origin}, row {id}"),
            (Places::RowIds, Some(name)) => format!("{origin}, row {id}, column '{name}'"),
        }
    }

    /// What an earlier row is called: `line 4` or `row 4`.
    fn earlier(self, line: usize) -> String {
        match self {
            Places::Lines => format!("line {line}"),
            Places::RowIds => format!("row {line}"),
        }
    }
}
