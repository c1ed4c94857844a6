//! The measurement CSV (see `docs/file-formats.md`): one row per tool observation, with the
//! values of the joints that move the tool and the observation (a position, a pose, or three
//! targets A, B, C), in metres and radians or the units the options name.

use super::joints_csv::{parse_csv, CsvTable};
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

/// Reads a measurement CSV file; see [`parse_measurements`].
pub fn read_measurements(
    path: &Path,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Result<MeasurementSet> {
    let text = crate::limits::read_text(path, crate::limits::MAX_CSV_BYTES)?;
    parse_measurements(&text, &path.display().to_string(), tree, model, options)
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

/// Where the columns of a measurement CSV go.
struct Columns {
    id: Option<usize>,
    stage: Option<usize>,
    /// `payload_kg`: the payload at every tool for this row (kg).
    payload: Option<usize>,
    /// `session`: the measurement session of this row.
    session: Option<usize>,
    tool: Option<usize>,
    point: Option<usize>,
    /// Columns skipped as neither joints nor measurement columns: name, and how to say it.
    skipped: Vec<(String, String)>,
    /// `(column, dof)` of independent joints.
    joints: Vec<(usize, usize)>,
    observation: ObservationKind,
    /// The observation columns in [`ObservationKind::columns`] order.
    observed: Vec<usize>,
}

/// Parses measurement CSV text; `origin` names it in messages (`origin:line:column`).
pub fn parse_measurements(
    text: &str,
    origin: &str,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Result<MeasurementSet> {
    let table = parse_csv(text, origin).map_err(|e| match e {
        Error::InvalidData { origin, message } if message.starts_with("the file is empty") => {
            Error::InvalidData {
                origin,
                message: "the file is empty; it needs a header row (tool, joint names, \
                          observation columns) and one row per measurement"
                    .into(),
            }
        }
        other => other,
    })?;
    let header = parse_units_header(text, origin)?;
    measurements_from_table(&table, &header, Places::Lines, origin, tree, model, options)
}

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

/// The measurements of `table` (a CSV as read, or arrays laid out as one) whose stated units
/// are `header`: the one validation shared by files and arrays.
pub(super) fn measurements_from_table(
    table: &CsvTable,
    header: &StatedUnits,
    places: Places,
    origin: &str,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Result<MeasurementSet> {
    let stated = StatedUnits {
        length: options.length_unit,
        angle: options.angle_unit,
        joint_length: options.joint_length_unit,
        rotation: None,
        line: None,
    };
    let units = resolve_units(&stated, header, origin)?;
    let mut warnings = Vec::new();
    let columns = classify(
        &table.headers,
        table.header_line,
        places,
        tree,
        model,
        options,
        origin,
    )?;
    for name in &options.ignore_columns {
        if !table.headers.contains(name) {
            warnings.push(format!(
                "{origin}: column '{name}' is to be ignored but the file has no such column"
            ));
        }
    }
    let mut notes = Vec::new();
    if !columns.skipped.is_empty() {
        let listed: Vec<&str> = columns.skipped.iter().map(|(_, s)| s.as_str()).collect();
        notes.push(format!(
            "{}: {} column(s) neither a joint of '{}' nor a measurement column, not read: {}; list them with --ignore-columns to silence this note",
            places.header(origin, table.header_line, None),
            listed.len(),
            tree.name(),
            listed.join(", ")
        ));
    }
    if table.records.is_empty() {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: "the file has a header but no data rows; add one row per measurement".into(),
        });
    }
    let tool_names: Vec<&str> = model
        .tools()
        .iter()
        .map(|t| tree.link(t.link).name.as_str())
        .collect();
    // The independent joints each tool's pose depends on (mimic joints through their masters).
    let tool_dofs: Vec<Vec<usize>> = model
        .tools()
        .iter()
        .map(|t| {
            // The joints between the link fixed in the world and the tool.
            let reference = model.reference().map_or(tree.root(), |r| r.link);
            let mut dofs: Vec<usize> = tree
                .path_between(reference, t.link)
                .into_iter()
                .filter_map(|j| match tree.joint(j).actuation {
                    Actuation::Independent(dof) | Actuation::Mimic { master: dof, .. } => {
                        Some(dof.0)
                    }
                    Actuation::None => None,
                })
                .collect();
            dofs.sort_unstable();
            dofs.dedup();
            dofs
        })
        .collect();
    let (length, angle, joint_length, rotation) = (
        units.length,
        units.angle,
        units.joint_length,
        units.rotation,
    );
    let mut outside = Vec::new();
    let mut revolute_values = 0;
    let mut set = MeasurementSet {
        measurements: Vec::with_capacity(table.records.len()),
        ids: Vec::with_capacity(table.records.len()),
        lines: Vec::with_capacity(table.records.len()),
        observation: columns.observation,
        warnings,
        notes,
        units,
    };
    let mut first_line_of_id: HashMap<String, usize> = HashMap::new();
    let mut repeats = Repeats::new(columns.id);
    let mut position_rows: Vec<String> = Vec::new();
    for (row, (line, fields)) in table.records.iter().enumerate() {
        let line = *line;
        let row_id = match columns.id.map(|column| fields[column].as_str()) {
            Some(id) if !id.is_empty() => id.to_owned(),
            _ => line.to_string(),
        };
        let at = |name: &str| places.row(origin, line, &row_id, Some(name));
        let place = |column: usize| at(&table.headers[column]);
        let invalid = |column: usize, message: String| Error::InvalidData {
            origin: place(column),
            message,
        };
        let id = match columns.id {
            Some(column) if fields[column].is_empty() => {
                return Err(invalid(
                    column,
                    "the id is empty; give every row an id, or remove the id column".into(),
                ))
            }
            Some(column) => fields[column].clone(),
            None => (row + 1).to_string(),
        };
        if let Some(first) = first_line_of_id.insert(id.clone(), line) {
            return Err(invalid(
                columns.id.unwrap_or(0),
                format!(
                    "id '{id}' was already used on {}; ids must be unique",
                    places.earlier(first)
                ),
            ));
        }
        let stage = columns
            .stage
            .map(|column| fields[column].clone())
            .filter(|s| !s.is_empty());
        let session = columns
            .session
            .map(|column| fields[column].clone())
            .filter(|s| !s.is_empty());
        let payload = match columns.payload {
            Some(column) if !fields[column].is_empty() => {
                let mass = number(&fields[column], "kg").map_err(|m| invalid(column, m))?;
                if let Some(why) = magnitude_problem(mass, Quantity::Mass) {
                    return Err(invalid(
                        column,
                        format!("the payload: {why}; give the mass at the tool in kg, or leave it empty for the stiffness file's"),
                    ));
                }
                Some(mass)
            }
            _ => None,
        };
        let tool_column = columns.tool.unwrap_or(0);
        let tool_name = match columns.tool {
            Some(column) => fields[column].as_str(),
            None => options.tool.as_deref().unwrap_or(tool_names[0]),
        };
        let point = columns.point.map(|column| fields[column].as_str());
        let measured = measured_link_name(tool_name, point);
        let tool = tool_names
            .iter()
            .position(|t| *t == measured)
            .ok_or_else(|| {
                let cut = crate::limits::cut;
                let what = match point.filter(|p| !p.is_empty()) {
                    Some(point) => format!(
                        "point '{}' on '{}' (link '{}')",
                        cut(point),
                        cut(tool_name),
                        cut(&measured)
                    ),
                    None => format!("'{}'", cut(tool_name)),
                };
                let column = match point.filter(|p| !p.is_empty()) {
                    Some(_) => columns.point.unwrap_or(tool_column),
                    None => tool_column,
                };
                invalid(
                    column,
                    format!(
                        "{what} is not a tool of the model{}; the tools are {}",
                        did_you_mean(&measured, tool_names.iter().copied()),
                        quoted_list(&tool_names)
                    ),
                )
            })?;
        let mut q = tree.zero_configuration();
        let mut given = vec![false; q.len()];
        for &(column, dof) in &columns.joints {
            if fields[column].is_empty() {
                continue;
            }
            let joint = tree.joint(tree.dofs()[dof]);
            let (scale, unit) = if joint.kind == JointKind::Prismatic {
                (joint_length.in_metres(), joint_length.symbol())
            } else {
                revolute_values += 1;
                (angle.in_radians(), angle.symbol())
            };
            let value = number(&fields[column], unit).map_err(|m| invalid(column, m))?;
            let quantity = match joint.kind {
                JointKind::Prismatic => Quantity::Length,
                _ => Quantity::Angle,
            };
            q[dof] = limits::check(value * scale, quantity, || place(column))?;
            given[dof] = true;
            if let Some(limits) = joint.limits.filter(|_| joint.kind != JointKind::Continuous) {
                const TOLERANCE: f64 = 1e-9;
                if q[dof] < limits.lower - TOLERANCE || q[dof] > limits.upper + TOLERANCE {
                    let message = format!(
                        "{value} {unit} is outside the limits of joint '{}' [{}, {}] {unit}",
                        joint.name,
                        limits.lower / scale,
                        limits.upper / scale
                    );
                    if options.strict_limits {
                        return Err(invalid(
                            column,
                            format!("{message}; correct the value, or accept it with a warning by not asking for strict limits"),
                        ));
                    }
                    outside.push(OutsideLimits {
                        place: place(column),
                        message,
                        revolute: joint.kind != JointKind::Prismatic,
                        within_in_degrees: joint.kind != JointKind::Prismatic
                            && (limits.lower - TOLERANCE..=limits.upper + TOLERANCE)
                                .contains(&(value.to_radians())),
                    });
                }
            }
        }
        for &dof in &tool_dofs[tool] {
            if given[dof] {
                continue;
            }
            let name = &tree.joint(tree.dofs()[dof]).name;
            let column = columns.joints.iter().find(|(_, d)| *d == dof);
            return Err(Error::InvalidData {
                origin: at(name),
                message: match column {
                    Some(_) => format!(
                        "the value is empty, but tool '{tool_name}' moves with joint '{name}'; give its value"
                    ),
                    None => format!(
                        "the file has no column '{name}', but tool '{tool_name}' moves with that joint; add the column{}",
                        did_you_mean(name, columns.skipped.iter().map(|(n, _)| n.as_str()))
                            .replace("; did you mean", " (or rename the file's column")
                            .replace("'?", "', which was not read)")
                    ),
                },
            });
        }
        // A pose layout's row without any orientation cell is a position (a session measured
        // with single markers, in the same file as the 6-DoF rows).
        let position_only = matches!(
            columns.observation,
            ObservationKind::Pose | ObservationKind::RollPitchYaw | ObservationKind::RotationMatrix
        ) && columns.observed[3..].iter().all(|&c| fields[c].is_empty());
        let (kind, observed) = if position_only {
            position_rows.push(row_id.clone());
            (ObservationKind::Position, &columns.observed[..3])
        } else {
            (columns.observation, &columns.observed[..])
        };
        let mut values = Vec::with_capacity(observed.len());
        for &column in observed {
            let (scale, unit, quantity) = match column_quantity(&table.headers[column]) {
                ColumnQuantity::Length => {
                    (length.in_metres(), length.symbol(), Some(Quantity::Length))
                }
                ColumnQuantity::Angle => (
                    rotation.in_radians(),
                    rotation.symbol(),
                    Some(Quantity::Angle),
                ),
                ColumnQuantity::Plain => (1.0, "", None),
            };
            let value = number(&fields[column], unit).map_err(|m| invalid(column, m))?;
            values.push(match quantity {
                Some(quantity) => limits::check(value * scale, quantity, || place(column))?,
                None => value,
            });
        }
        let observation =
            observation(kind, &values).map_err(|(columns, message)| Error::InvalidData {
                origin: at(columns),
                message,
            })?;
        set.measurements.push(Measurement {
            payload,
            tool,
            q,
            observation,
            stage,
            session,
        });
        set.ids.push(id);
        set.lines.push(line);
        repeats.see(fields, line);
    }
    set.warnings.extend(limit_warnings(
        &outside,
        revolute_values,
        units.angle,
        origin,
    )?);
    angles_look_like_radians(&set, tree, units.angle, origin)?;
    set.warnings.extend(repeats.warning(origin, places));
    if let Some(note) = position_only_note(&position_rows, columns.observation, origin) {
        set.notes.push(note);
    }
    Ok(set)
}

/// The note on the rows of a pose file read as positions (every orientation cell empty).
fn position_only_note(rows: &[String], kind: ObservationKind, origin: &str) -> Option<String> {
    let first = rows.first()?;
    let orientation = kind.columns()[3..].join(",");
    Some(format!(
        "{origin}: {} row(s) have empty {orientation} and are read as positions of the measured point (first: '{}'); the other rows are full poses",
        rows.len(),
        crate::limits::cut(first)
    ))
}

/// A joint value outside its URDF limits, as read.
struct OutsideLimits {
    place: String,
    message: String,
    revolute: bool,
    /// A revolute value read as radians that would be within the limits in degrees.
    within_in_degrees: bool,
}

/// At most this many values outside their limits are listed one by one.
const LISTED_OUTSIDE: usize = 5;

/// The warnings for values outside their limits: a few listed, the rest counted. When many
/// revolute values read as radians are outside their limits and nearly all of them would be
/// within in degrees, the file is in degrees: one error naming `--angle-unit` instead.
fn limit_warnings(
    outside: &[OutsideLimits],
    revolute_values: usize,
    angle: AngleUnit,
    origin: &str,
) -> Result<Vec<String>> {
    let revolute = outside.iter().filter(|o| o.revolute).count();
    let explained = outside.iter().filter(|o| o.within_in_degrees).count();
    // "Many": a tenth of the revolute values (and at least 3), nine in ten of them explained.
    if angle == AngleUnit::Radian
        && revolute >= 3
        && 10 * revolute >= revolute_values
        && 10 * explained >= 9 * revolute
    {
        let first = outside
            .iter()
            .find(|o| o.revolute)
            .map_or(String::new(), |o| {
                format!(" (first: {}: {})", o.place, o.message)
            });
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: format!(
                "{revolute} of {revolute_values} revolute joint values are outside their limits \
                when read as radians{first}, and {explained} of them are within the limits when \
                read as degrees: the joint values look like degrees; give --angle-unit deg (or \
                state `# units: angle=deg` in the file)"
            ),
        });
    }
    let mut warnings: Vec<String> = outside
        .iter()
        .take(LISTED_OUTSIDE)
        .map(|o| format!("{}: {}", o.place, o.message))
        .collect();
    if outside.len() > LISTED_OUTSIDE {
        warnings.push(format!(
            "{origin}: {} more joint values are outside their limits (the first {LISTED_OUTSIDE} are listed)",
            outside.len() - LISTED_OUTSIDE
        ));
    }
    Ok(warnings)
}

/// Joint values read in degrees that are all within ±2π while the joints could move far more:
/// radians read as degrees (every revolute joint would have moved less than 6.3°, too little
/// to calibrate anything). Only checked with at least 10 revolute values.
fn angles_look_like_radians(
    set: &MeasurementSet,
    tree: &KinematicTree,
    angle: AngleUnit,
    origin: &str,
) -> Result<()> {
    if angle != AngleUnit::Degree {
        return Ok(());
    }
    let revolute: Vec<usize> = tree
        .dofs()
        .iter()
        .enumerate()
        .filter(|(_, j)| tree.joint(**j).kind != JointKind::Prismatic)
        .map(|(dof, _)| dof)
        .collect();
    let values: Vec<f64> = set
        .measurements
        .iter()
        .flat_map(|m| revolute.iter().map(|&d| m.q[d]))
        .filter(|v| *v != 0.0)
        .collect();
    let largest_in_degrees = values
        .iter()
        .fold(0.0_f64, |a, v| a.max(v.abs().to_degrees()));
    if values.len() >= 10 && largest_in_degrees <= std::f64::consts::TAU {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: format!(
                "all {} non-zero revolute joint values are within ±{largest_in_degrees:.3} deg, \
                too small a motion to calibrate from: the joint values look like radians; \
                give --angle-unit rad (or state `# units: angle=rad` in the file)",
                values.len()
            ),
        });
    }
    Ok(())
}

/// Rows that repeat an earlier row in every column but the id: accepted (a repeated
/// measurement is legitimate), with one warning, since an accidentally duplicated row weighs
/// double in the fit.
struct Repeats {
    id: Option<usize>,
    first_line: HashMap<Vec<String>, usize>,
    /// `(line, line it repeats)` of every repeated row.
    found: Vec<(usize, usize)>,
}

impl Repeats {
    fn new(id: Option<usize>) -> Self {
        Self {
            id,
            first_line: HashMap::new(),
            found: Vec::new(),
        }
    }

    fn see(&mut self, fields: &[String], line: usize) {
        let mut key = fields.to_vec();
        if let Some(id) = self.id {
            key[id].clear();
        }
        if let Some(&first) = self.first_line.get(&key) {
            self.found.push((line, first));
        } else {
            self.first_line.insert(key, line);
        }
    }

    fn warning(&self, origin: &str, places: Places) -> Option<String> {
        let &(line, first) = self.found.first()?;
        let more = match self.found.len() {
            1 => String::new(),
            n => format!(" ({} repeated rows in all)", n),
        };
        Some(format!(
            "{}: the row repeats {} in every column but the id{more}; \
             a repeated row weighs double in the fit: remove it if it was copied by mistake",
            places.row(origin, line, &line.to_string(), None),
            places.earlier(first)
        ))
    }
}

/// A finite number, or what is wrong with the text.
fn number(text: &str, unit: &str) -> std::result::Result<f64, String> {
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" in {unit}")
    };
    if text.is_empty() {
        return Err(format!("the value is missing; give a number{unit}"));
    }
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(format!(
            "'{}' is not a finite number; give a number{unit}",
            crate::limits::cut(text)
        )),
        Err(_) => Err(format!(
            "'{}' is not a number; give a number{unit}",
            crate::limits::cut(text)
        )),
    }
}

fn quoted_list(names: &[&str]) -> String {
    names
        .iter()
        .map(|n| format!("'{n}'"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Sorts the header's columns into identity, joints and observation, or says which is wrong.
/// Columns that are neither (and not listed as ignored) are skipped, named in
/// [`Columns::skipped`].
fn classify(
    headers: &[String],
    header_line: usize,
    places: Places,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
    origin: &str,
) -> Result<Columns> {
    let mut id = None;
    let mut stage = None;
    let mut payload = None;
    let mut session = None;
    let mut tool = None;
    let mut point = None;
    let mut joints = Vec::new();
    let mut skipped = Vec::new();
    let mut observed: HashMap<&str, usize> = HashMap::new();
    for (column, name) in headers.iter().enumerate() {
        if options.ignore_columns.contains(name) {
            continue;
        }
        match name.as_str() {
            "id" => id = Some(column),
            "stage" => stage = Some(column),
            PAYLOAD_COLUMN => payload = Some(column),
            SESSION_COLUMN => session = Some(column),
            "tool" => tool = Some(column),
            POINT_COLUMN => point = Some(column),
            other if OBSERVATION_COLUMNS.contains(&other) => {
                observed.insert(other, column);
            }
            other => match tree.joint_id(other).map(|j| tree.joint(j).actuation) {
                Ok(Actuation::Independent(dof)) => joints.push((column, dof.0)),
                Ok(Actuation::Mimic { master, .. }) => skipped.push((
                    other.to_owned(),
                    format!(
                        "'{other}' (a mimic joint: its value follows '{}')",
                        tree.joint(tree.dofs()[master.0]).name
                    ),
                )),
                Ok(Actuation::None) => {
                    skipped.push((other.to_owned(), format!("'{other}' (a fixed joint)")))
                }
                Err(_) => {
                    let candidates = tree
                        .dofs()
                        .iter()
                        .map(|j| tree.joint(*j).name.as_str())
                        .chain(OBSERVATION_COLUMNS)
                        .chain(IDENTITY)
                        .chain([PAYLOAD_COLUMN, SESSION_COLUMN]);
                    let hint = did_you_mean(other, candidates);
                    skipped.push((
                        other.to_owned(),
                        format!("'{}'{hint}", crate::limits::cut(other)),
                    ));
                }
            },
        }
    }
    if tool.is_none() && options.tool.is_none() && model.tools().len() != 1 {
        let names: Vec<&str> = model
            .tools()
            .iter()
            .map(|t| tree.link(t.link).name.as_str())
            .collect();
        return Err(Error::InvalidData {
            origin: places.header(origin, header_line, None),
            message: format!(
                "the header has no 'tool' column; add one naming the measured tool link of each \
                 row (one of {}), or name the one measured tool with --tools",
                quoted_list(&names)
            ),
        });
    }
    let observation = KINDS
        .into_iter()
        .find(|kind| {
            kind.columns().len() == observed.len()
                && kind.columns().iter().all(|c| observed.contains_key(c))
        })
        .ok_or_else(|| {
            let mut present: Vec<(&str, usize)> =
                observed.iter().map(|(n, c)| (*n, *c)).collect();
            present.sort_by_key(|(_, c)| *c);
            let present: Vec<&str> = present.into_iter().map(|(n, _)| n).collect();
            Error::InvalidData {
                origin: places.header(origin, header_line, None),
                message: if present.is_empty() {
                    format!("the header has no observation columns; give {LAYOUTS}")
                } else {
                    format!(
                        "the observation columns {} are not a complete layout; give exactly {LAYOUTS}",
                        present.join(",")
                    )
                },
            }
        })?;
    let observed = observation.columns().iter().map(|c| observed[c]).collect();
    Ok(Columns {
        id,
        stage,
        payload,
        session,
        tool,
        point,
        skipped,
        joints,
        observation,
        observed,
    })
}
