//! Measurements given as arrays (from Python or any caller holding them in memory) rather than
//! as a CSV file: laid out as the CSV's table and read by the same validation, so that units,
//! limits, tool names and the length-scale and degree/radian diagnoses are the file's, with
//! messages naming the table's `origin`, the row id and the column instead of a file line.

use super::csv_fields::CsvFields;
use super::measurements_csv::{
    measurements_from_table, MeasurementReadOptions, MeasurementSet, ObservationKind, Places,
};
use super::units::{AngleUnit, LengthUnit, StatedUnits};
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::limits::{check_count, MAX_CSV_COLUMNS, MAX_CSV_ROWS};
use crate::tree::KinematicTree;

/// The observation of every row, one layout per table (as one CSV has one header).
#[derive(Debug, Clone, PartialEq)]
pub enum ObservationRows {
    /// `x, y, z`: one target's position per row.
    Positions(Vec<[f64; 3]>),
    /// `x, y, z, qw, qx, qy, qz`: a full pose per row (unit quaternion, w first).
    Poses(Vec<[f64; 7]>),
    /// `ax, ay, az, bx, by, bz, cx, cy, cz`: three targets A, B, C on the tool per row.
    ThreeTargets(Vec<[f64; 9]>),
}

impl ObservationRows {
    /// Number of rows.
    pub fn len(&self) -> usize {
        match self {
            ObservationRows::Positions(rows) => rows.len(),
            ObservationRows::Poses(rows) => rows.len(),
            ObservationRows::ThreeTargets(rows) => rows.len(),
        }
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The CSV layout these rows correspond to.
    pub fn kind(&self) -> ObservationKind {
        match self {
            ObservationRows::Positions(_) => ObservationKind::Position,
            ObservationRows::Poses(_) => ObservationKind::Pose,
            ObservationRows::ThreeTargets(_) => ObservationKind::ThreeTargets,
        }
    }

    /// The values of row `row`, in [`ObservationKind::columns`] order.
    fn row(&self, row: usize) -> &[f64] {
        match self {
            ObservationRows::Positions(rows) => &rows[row],
            ObservationRows::Poses(rows) => &rows[row],
            ObservationRows::ThreeTargets(rows) => &rows[row],
        }
    }
}

/// Measurements as arrays: the columns of a measurement CSV (docs/file-formats.md), one entry
/// per row. Values are in the table's units (or the read options'), as in a file.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementTable {
    /// Names the table in messages, e.g. `measurements (arrays)`.
    pub origin: String,
    /// The row ids; `None` numbers the rows `1`..`N`.
    pub ids: Option<Vec<String>>,
    /// The measured tool link of each row.
    pub tools: Vec<String>,
    /// The joints the values of `joints` belong to (the CSV's joint columns).
    pub joint_names: Vec<String>,
    /// Per row, one value per entry of `joint_names`; NaN means not given (an empty cell).
    pub joints: Vec<Vec<f64>>,
    /// What each row observes.
    pub observations: ObservationRows,
    /// `torso` (taken with the arms locked) or `arms` per row, for the staged plan.
    pub stages: Option<Vec<String>>,
    /// The measurement session of each row (the CSV's `session` column: one measurement
    /// frame per session).
    pub sessions: Option<Vec<String>>,
    /// The measured point of each row on its tool (the CSV's `point` column: several markers
    /// on one body).
    pub points: Option<Vec<String>>,
    /// Unit of positions, targets and prismatic joint values, like `# units: length=`.
    pub length_unit: Option<LengthUnit>,
    /// Unit of revolute joint values, like `# units: angle=`.
    pub angle_unit: Option<AngleUnit>,
}

impl MeasurementTable {
    /// The distinct tool links named by the rows, in order of first appearance (the measured
    /// tools, as [`super::measured_tool_names`] reads them from a CSV).
    pub fn tool_names(&self) -> Result<Vec<String>> {
        self.check_shape()?;
        let mut names: Vec<String> = Vec::new();
        for (row, name) in self.tools.iter().enumerate() {
            if name.trim().is_empty() {
                return Err(self.invalid(
                    Some(row),
                    "the tool is empty; name the measured tool link".into(),
                ));
            }
            if !names.iter().any(|n| n == name.trim()) {
                names.push(name.trim().to_owned());
            }
        }
        Ok(names)
    }

    /// The distinct `(tool, point)` pairs the rows name, in order of first appearance (as
    /// [`super::measured_targets`] reads them from a CSV); the point is `None` without
    /// `points` or for an empty label.
    pub fn targets(&self) -> Result<Vec<(Option<String>, Option<String>)>> {
        self.tool_names()?;
        let mut pairs = Vec::new();
        for (row, tool) in self.tools.iter().enumerate() {
            let point = self
                .points
                .as_ref()
                .map(|points| points[row].trim().to_owned())
                .filter(|p| !p.is_empty());
            let pair = (Some(tool.trim().to_owned()), point);
            if !pairs.contains(&pair) {
                pairs.push(pair);
            }
        }
        Ok(pairs)
    }

    /// The measurements of the table for the robot `tree` with model `model`, checked exactly
    /// as [`super::parse_measurements`] checks a CSV. [`MeasurementSet::lines`] holds 1-based
    /// row numbers.
    pub fn to_measurements(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        options: &MeasurementReadOptions,
    ) -> Result<MeasurementSet> {
        self.check_shape()?;
        self.check_units(options)?;
        let stated = StatedUnits {
            length: self.length_unit,
            angle: self.angle_unit,
            joint_length: None,
            rotation: None,
            line: None,
        };
        let table = self.as_csv_table()?;
        measurements_from_table(
            &table,
            &stated,
            Places::RowIds,
            &self.origin,
            tree,
            model,
            options,
        )
    }

    /// Where messages place tool `name`: the first row naming it, in the `tool` column.
    pub fn place_of_tool(&self, name: &str) -> String {
        match self.tools.iter().position(|t| t.trim() == name) {
            Some(row) => format!("{}, row {}, column 'tool'", self.origin, self.id(row)),
            None => self.origin.clone(),
        }
    }

    /// The units the table states agree with the ones the options give (the CSV's check
    /// names a units comment, which a table does not have).
    fn check_units(&self, options: &MeasurementReadOptions) -> Result<()> {
        let units = [
            (
                "length",
                options.length_unit.map(LengthUnit::symbol),
                self.length_unit.map(LengthUnit::symbol),
            ),
            (
                "angle",
                options.angle_unit.map(AngleUnit::symbol),
                self.angle_unit.map(AngleUnit::symbol),
            ),
        ];
        for (what, given, stated) in units {
            if let Some((given, stated)) = given.zip(stated).filter(|(g, s)| g != s) {
                return Err(self.invalid(
                    None,
                    format!(
                        "the {what} unit {given} given contradicts the table's {what} unit \
                         {stated}; give one of them"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The id of row `row` as messages name it.
    fn id(&self, row: usize) -> String {
        match &self.ids {
            Some(ids) if ids.get(row).is_some_and(|id| !id.is_empty()) => ids[row].clone(),
            _ => (row + 1).to_string(),
        }
    }

    fn invalid(&self, row: Option<usize>, message: String) -> Error {
        Error::InvalidData {
            origin: match row {
                Some(row) => format!("{}, row {}", self.origin, self.id(row)),
                None => self.origin.clone(),
            },
            message,
        }
    }

    /// Every array has one entry per row, every row one value per joint name, and the joint
    /// names are distinct and not the names of the identity or observation columns.
    fn check_shape(&self) -> Result<()> {
        let rows = self.tools.len();
        if rows == 0 {
            return Err(self.invalid(
                None,
                "the table has no rows; give one row per measurement".into(),
            ));
        }
        check_count(rows, MAX_CSV_ROWS, &self.origin, "rows")?;
        check_count(
            self.joint_names.len(),
            MAX_CSV_COLUMNS,
            &self.origin,
            "joint names",
        )?;
        let lengths = [
            ("joint value rows", Some(self.joints.len())),
            ("observations", Some(self.observations.len())),
            ("ids", self.ids.as_ref().map(Vec::len)),
            ("stages", self.stages.as_ref().map(Vec::len)),
            ("sessions", self.sessions.as_ref().map(Vec::len)),
            ("points", self.points.as_ref().map(Vec::len)),
        ];
        for (what, length) in lengths {
            if let Some(length) = length.filter(|&l| l != rows) {
                return Err(self.invalid(
                    None,
                    format!("{length} {what} for {rows} tools; give one per row"),
                ));
            }
        }
        for (row, values) in self.joints.iter().enumerate() {
            if values.len() != self.joint_names.len() {
                return Err(self.invalid(
                    Some(row),
                    format!(
                        "{} joint values for {} joint names; give one value per name (NaN for none)",
                        values.len(),
                        self.joint_names.len()
                    ),
                ));
            }
        }
        let identity = ["id", "stage", "tool", "session", "point"];
        let observed = [
            ObservationKind::Position,
            ObservationKind::Pose,
            ObservationKind::ThreeTargets,
        ]
        .map(ObservationKind::columns);
        for (index, name) in self.joint_names.iter().enumerate() {
            if identity.contains(&name.as_str()) || observed.iter().any(|c| c.contains(&&**name)) {
                return Err(self.invalid(
                    None,
                    format!("joint name '{name}' is the name of a measurement column, not a joint"),
                ));
            }
            if self.joint_names[..index]
                .iter()
                .any(|n| n.trim() == name.trim())
            {
                return Err(self.invalid(
                    None,
                    format!("joint name '{name}' is given twice; give each joint once"),
                ));
            }
        }
        Ok(())
    }

    /// The table laid out as a CSV as read: numbers written in full precision (`{}` prints
    /// the shortest text that reads back to the same `f64`), NaN as an empty cell.
    fn as_csv_table(&self) -> Result<CsvFields> {
        let text = |value: f64| {
            if value.is_nan() {
                String::new()
            } else {
                format!("{value}")
            }
        };
        let mut headers = Vec::new();
        headers.extend(self.ids.as_ref().map(|_| "id".to_owned()));
        headers.extend(self.stages.as_ref().map(|_| "stage".to_owned()));
        headers.push("tool".to_owned());
        headers.extend(self.sessions.as_ref().map(|_| "session".to_owned()));
        headers.extend(self.points.as_ref().map(|_| "point".to_owned()));
        headers.extend(self.joint_names.iter().map(|n| n.trim().to_owned()));
        headers.extend(
            self.observations
                .kind()
                .columns()
                .iter()
                .map(|c| c.to_string()),
        );
        let mut table = CsvFields::new(headers, 0);
        let mut fields: Vec<String> = Vec::with_capacity(table.headers.len());
        for row in 0..self.tools.len() {
            fields.clear();
            fields.extend(self.ids.as_ref().map(|ids| ids[row].trim().to_owned()));
            fields.extend(
                self.stages
                    .as_ref()
                    .map(|stages| stages[row].trim().to_owned()),
            );
            fields.push(self.tools[row].trim().to_owned());
            for labels in [&self.sessions, &self.points].into_iter().flatten() {
                fields.push(labels[row].trim().to_owned());
            }
            fields.extend(self.joints[row].iter().map(|&v| text(v)));
            fields.extend(self.observations.row(row).iter().map(|&v| text(v)));
            table.push_row(row + 1, fields.iter().map(String::as_str), &self.origin)?;
        }
        Ok(table)
    }
}
