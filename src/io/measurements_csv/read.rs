//! A measurement CSV read row by row.

// The parent's types, constants and imports.
use super::checks::{
    angles_look_like_radians, limit_warnings, number, position_only_note, quoted_list,
    OutsideLimits, Repeats,
};
use super::columns::{classify, Columns};
use super::*;

mod parts;

/// Reads a measurement CSV file as one text (any file the format allows; a plain file is read
/// line by line by [`super::read_measurements`]); see [`parse_measurements`].
pub(super) fn read_whole(
    path: &Path,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Result<MeasurementSet> {
    let text = crate::limits::read_text(path, crate::limits::MAX_CSV_BYTES)?;
    let origin = path.display().to_string();
    let (table, header) = parse_table(&text, &origin)?;
    // The text is not needed once parsed (at 10⁵ rows it is as large as the measurements).
    drop(text);
    measurements_from_table(
        &table,
        &header,
        Places::Lines,
        &origin,
        tree,
        model,
        options,
    )
}

/// Parses measurement CSV text; `origin` names it in messages (`origin:line:column`).
pub fn parse_measurements(
    text: &str,
    origin: &str,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Result<MeasurementSet> {
    let (table, header) = parse_table(text, origin)?;
    measurements_from_table(&table, &header, Places::Lines, origin, tree, model, options)
}

/// The table and the stated units of measurement CSV text.
fn parse_table(text: &str, origin: &str) -> Result<(CsvFields, StatedUnits)> {
    let table = parse_csv_fields(text, origin).map_err(without_header)?;
    Ok((table, parse_units_header(text, origin)?))
}

/// A CSV without a header row, told what a measurement file needs (other errors unchanged).
pub(super) fn without_header(e: Error) -> Error {
    match e {
        Error::InvalidData { origin, message }
            if message.starts_with("the file is empty")
                || message.starts_with(crate::io::joints_csv::NO_HEADER) =>
        {
            let what = message.split(';').next().unwrap_or_default();
            Error::InvalidData {
                origin,
                message: format!(
                    "{what}; it needs a header row (tool, joint names, observation columns) \
                     and one row per measurement"
                ),
            }
        }
        other => other,
    }
}

/// The measurements of `table` (a CSV as read, or arrays laid out as one) whose stated units
/// are `header`: the one validation shared by files and arrays.
pub(in crate::io) fn measurements_from_table(
    table: &CsvFields,
    header: &StatedUnits,
    places: Places,
    origin: &str,
    tree: &KinematicTree,
    model: &McpcModel,
    options: &MeasurementReadOptions,
) -> Result<MeasurementSet> {
    let place = HeaderPlace {
        places,
        origin,
        line: table.header_line,
    };
    let mut rows = SetBuilder::start(&table.headers, header, place, tree, model, options)?;
    if table.is_empty() {
        return Err(no_data_rows(origin));
    }
    rows.reserve(table.len());
    for row in table.rows() {
        rows.push(row)?;
    }
    rows.finish()
}

/// The error of a table with a header but no rows.
pub(super) fn no_data_rows(origin: &str) -> Error {
    Error::InvalidData {
        origin: origin.to_owned(),
        message: "the file has a header but no data rows; add one row per measurement".into(),
    }
}

/// Where the header of a table is and how its rows are named.
#[derive(Debug, Clone, Copy)]
pub(super) struct HeaderPlace<'a> {
    pub(super) places: Places,
    pub(super) origin: &'a str,
    /// The 1-based line of the header row.
    pub(super) line: usize,
}

/// A [`MeasurementSet`] built one row at a time (a file streamed line by line, or a table).
pub(super) struct SetBuilder<'a> {
    reader: RowReader<'a>,
    set: MeasurementSet,
    tally: Tally,
    /// A digest of every id merged from blocks read in parallel (`parts`).
    id_digests: Vec<u64>,
}

impl<'a> SetBuilder<'a> {
    /// Checks the header (`headers`, the stated units `header`) against the model.
    pub(super) fn start(
        headers: &[String],
        header: &StatedUnits,
        place: HeaderPlace<'a>,
        tree: &'a KinematicTree,
        model: &'a McpcModel,
        options: &'a MeasurementReadOptions,
    ) -> Result<Self> {
        let HeaderPlace {
            places,
            origin,
            line,
        } = place;
        let stated = StatedUnits {
            length: options.length_unit,
            angle: options.angle_unit,
            joint_length: options.joint_length_unit,
            rotation: None,
            line: None,
        };
        let units = resolve_units(&stated, header, origin)?;
        let columns = classify(headers, line, places, tree, model, options, origin)?;
        let (warnings, notes) =
            header_remarks(headers, line, &columns, places, origin, tree, options);
        let set = MeasurementSet {
            measurements: Vec::new(),
            ids: Vec::new(),
            lines: Vec::new(),
            observation: columns.observation,
            warnings,
            notes,
            units,
        };
        let tally = Tally {
            outside: Vec::new(),
            revolute_values: 0,
            first_line_of_id: Some(HashMap::new()),
            repeats: Repeats::new(columns.id),
            position_rows: Vec::new(),
        };
        let reader = RowReader {
            headers: headers.to_vec(),
            columns,
            places,
            origin,
            tree,
            options,
            units,
            tool_names: model
                .tools()
                .iter()
                .map(|t| tree.link(t.link).name.as_str())
                .collect(),
            tool_dofs: tool_dofs(tree, model),
        };
        Ok(Self {
            reader,
            set,
            tally,
            id_digests: Default::default(),
        })
    }

    /// Room for `rows` more rows.
    pub(super) fn reserve(&mut self, rows: usize) {
        self.set.measurements.reserve(rows);
        self.set.ids.reserve(rows);
        self.set.lines.reserve(rows);
    }

    /// Number of rows read so far.
    pub(super) fn len(&self) -> usize {
        self.set.lines.len()
    }

    /// Reads the next data row.
    pub(super) fn push(&mut self, row: CsvRow<'_>) -> Result<()> {
        let index = self.set.lines.len();
        let (id, measurement) = self.reader.read_row(index, row, &mut self.tally)?;
        self.set.measurements.push(measurement);
        self.set.ids.push(id);
        self.set.lines.push(row.line);
        self.tally.repeats.see(row);
        Ok(())
    }

    /// The set, with the warnings and notes about all its rows.
    pub(super) fn finish(self) -> Result<MeasurementSet> {
        let Self {
            reader,
            mut set,
            tally,
            ..
        } = self;
        let (origin, units) = (reader.origin, set.units);
        set.warnings.extend(limit_warnings(
            &tally.outside,
            tally.revolute_values,
            units.angle,
            origin,
        )?);
        angles_look_like_radians(&set, reader.tree, units.angle, origin)?;
        set.warnings
            .extend(tally.repeats.warning(origin, reader.places));
        if let Some(note) = position_only_note(&tally.position_rows, set.observation, origin) {
            set.notes.push(note);
        }
        Ok(set)
    }
}

/// The header's warnings (ignored columns the file does not have) and notes (columns skipped).
fn header_remarks(
    headers: &[String],
    header_line: usize,
    columns: &Columns,
    places: Places,
    origin: &str,
    tree: &KinematicTree,
    options: &MeasurementReadOptions,
) -> (Vec<String>, Vec<String>) {
    let mut warnings = Vec::new();
    for name in &options.ignore_columns {
        if !headers.contains(name) {
            warnings.push(format!(
                "{origin}: column '{name}' is to be ignored but the file has no such column"
            ));
        }
    }
    let mut notes = Vec::new();
    if !columns.skipped.is_empty() {
        let listed: Vec<&str> = columns.skipped.iter().map(|(_, s)| s.as_str()).collect();
        notes.push(format!(
            "{}: {} column(s) neither a joint of '{}' nor a measurement column, not read: {}; list them with `ignore_columns` to silence this note",
            places.header(origin, header_line, None),
            listed.len(),
            tree.name(),
            listed.join(", ")
        ));
    }
    (warnings, notes)
}

/// The independent joints each tool's pose depends on (mimic joints through their masters).
fn tool_dofs(tree: &KinematicTree, model: &McpcModel) -> Vec<Vec<usize>> {
    model
        .tools()
        .iter()
        .map(|t| {
            // The joints between the link fixed in the world and the tool.
            let reference = model.reference().map_or(tree.root(), |r| r.link);
            let mut dofs: Vec<usize> = tree
                .path_between(reference, t.link)
                .into_iter()
                .filter_map(|j| tree.joint(j).actuation.driver().map(|dof| dof.0))
                .collect();
            dofs.sort_unstable();
            dofs.dedup();
            dofs
        })
        .collect()
}

/// What every row is read against.
struct RowReader<'a> {
    headers: Vec<String>,
    columns: Columns,
    places: Places,
    origin: &'a str,
    tree: &'a KinematicTree,
    options: &'a MeasurementReadOptions,
    units: MeasurementUnits,
    tool_names: Vec<&'a str>,
    /// Per tool, the independent joints its pose depends on ([`tool_dofs`]).
    tool_dofs: Vec<Vec<usize>>,
}

/// What reading the rows gathers besides the measurements.
struct Tally {
    outside: Vec<OutsideLimits>,
    revolute_values: usize,
    /// The first line of every id; `None` while a block is read in parallel (the merge checks
    /// the ids across blocks).
    first_line_of_id: Option<HashMap<String, usize>>,
    repeats: Repeats,
    /// The ids of the pose layout's rows read as positions.
    position_rows: Vec<String>,
}

/// One data row: its file line, the id messages name it by, its fields.
struct Row<'r> {
    line: usize,
    id: String,
    fields: CsvRow<'r>,
}

impl RowReader<'_> {
    /// A place in `row`: the cell of column `name`.
    fn at(&self, row: &Row<'_>, name: &str) -> String {
        self.places.row(self.origin, row.line, &row.id, Some(name))
    }

    /// A place in `row`: the cell of column `column`.
    fn place(&self, row: &Row<'_>, column: usize) -> String {
        self.at(row, &self.headers[column])
    }

    fn invalid(&self, row: &Row<'_>, column: usize, message: String) -> Error {
        Error::InvalidData {
            origin: self.place(row, column),
            message,
        }
    }

    /// Row `index` (0-based) at file line `line`: its id and its measurement.
    fn read_row(
        &self,
        index: usize,
        fields: CsvRow<'_>,
        tally: &mut Tally,
    ) -> Result<(String, Measurement)> {
        let columns = &self.columns;
        let line = fields.line;
        let row = Row {
            line,
            id: match columns.id.map(|column| fields.field(column)) {
                Some(id) if !id.is_empty() => id.to_owned(),
                _ => line.to_string(),
            },
            fields,
        };
        let id = self.id(&row, index, tally)?;
        let text = |column: Option<usize>| {
            column
                .map(|column| fields.field(column))
                .filter(|s| !s.is_empty())
                .map(str::to_owned)
        };
        let (stage, session) = (text(columns.stage), text(columns.session));
        let payload = self.payload(&row)?;
        let (tool, tool_name) = self.tool(&row)?;
        let (q, given) = self.joint_values(&row, tally)?;
        self.check_tool_joints(&row, tool, tool_name, &given)?;
        let observation = self.observation(&row, tally)?;
        let measurement = Measurement {
            payload,
            tool,
            q,
            observation,
            stage,
            session,
        };
        Ok((id, measurement))
    }

    /// The row's id (its 1-based row number without an id column), unique in the file.
    fn id(&self, row: &Row<'_>, index: usize, tally: &mut Tally) -> Result<String> {
        let id = match self.columns.id {
            Some(column) if row.fields[column].is_empty() => {
                return Err(self.invalid(
                    row,
                    column,
                    "the id is empty; give every row an id, or remove the id column".into(),
                ))
            }
            Some(column) => row.fields[column].to_owned(),
            None => (index + 1).to_string(),
        };
        let seen = tally.first_line_of_id.as_mut();
        if let Some(first) = seen.and_then(|seen| seen.insert(id.clone(), row.line)) {
            return Err(self.invalid(
                row,
                self.columns.id.unwrap_or(0),
                format!(
                    "id '{id}' was already used on {}; ids must be unique",
                    self.places.earlier(first)
                ),
            ));
        }
        Ok(id)
    }

    /// The row's payload at every tool (kg), if it gives one.
    fn payload(&self, row: &Row<'_>) -> Result<Option<f64>> {
        match self.columns.payload {
            Some(column) if !row.fields[column].is_empty() => {
                let mass =
                    number(&row.fields[column], "kg").map_err(|m| self.invalid(row, column, m))?;
                if let Some(why) = magnitude_problem(mass, Quantity::Mass) {
                    return Err(self.invalid(
                        row,
                        column,
                        format!("the payload: {why}; give the mass at the tool in kg, or leave it empty for the stiffness file's"),
                    ));
                }
                Ok(Some(mass))
            }
            _ => Ok(None),
        }
    }

    /// The model tool the row measures (a tool link, or the marker link of a point on it),
    /// and the tool link's name as the row gives it.
    fn tool<'r>(&'r self, row: &Row<'r>) -> Result<(usize, &'r str)> {
        let columns = &self.columns;
        let tool_names = &self.tool_names;
        let tool_column = columns.tool.unwrap_or(0);
        let tool_name = match columns.tool {
            Some(column) => row.fields.field(column),
            None => self.options.tool.as_deref().unwrap_or(tool_names[0]),
        };
        let point = columns.point.map(|column| row.fields.field(column));
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
                self.invalid(
                    row,
                    column,
                    format!(
                        "{what} is not a tool of the model{}; the tools are {}",
                        did_you_mean(&measured, tool_names.iter().copied()),
                        quoted_list(tool_names)
                    ),
                )
            })?;
        Ok((tool, tool_name))
    }

    /// The row's configuration (SI) and which of its values the row gives; values outside
    /// their limits are errors under strict limits, else gathered in `tally`.
    fn joint_values(&self, row: &Row<'_>, tally: &mut Tally) -> Result<(Vec<f64>, Vec<bool>)> {
        let (tree, fields) = (self.tree, row.fields);
        let (angle, joint_length) = (self.units.angle, self.units.joint_length);
        let mut q = tree.zero_configuration();
        let mut given = vec![false; q.len()];
        for &(column, dof) in &self.columns.joints {
            if fields[column].is_empty() {
                continue;
            }
            let joint = tree.joint(tree.dofs()[dof]);
            let (scale, unit) = if joint.kind == JointKind::Prismatic {
                (joint_length.in_metres(), joint_length.symbol())
            } else {
                tally.revolute_values += 1;
                (angle.in_radians(), angle.symbol())
            };
            let value = number(&fields[column], unit).map_err(|m| self.invalid(row, column, m))?;
            let quantity = match joint.kind {
                JointKind::Prismatic => Quantity::Length,
                _ => Quantity::Angle,
            };
            q[dof] = limits::check(value * scale, quantity, || self.place(row, column))?;
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
                    if self.options.strict_limits {
                        return Err(self.invalid(
                            row,
                            column,
                            format!("{message}; correct the value, or accept it with a warning by not asking for strict limits"),
                        ));
                    }
                    tally.outside.push(OutsideLimits {
                        place: self.place(row, column),
                        message,
                        revolute: joint.kind != JointKind::Prismatic,
                        within_in_degrees: joint.kind != JointKind::Prismatic
                            && (limits.lower - TOLERANCE..=limits.upper + TOLERANCE)
                                .contains(&(value.to_radians())),
                    });
                }
            }
        }
        Ok((q, given))
    }

    /// Every joint that moves `tool` has a value in the row.
    fn check_tool_joints(
        &self,
        row: &Row<'_>,
        tool: usize,
        tool_name: &str,
        given: &[bool],
    ) -> Result<()> {
        let (tree, columns) = (self.tree, &self.columns);
        for &dof in &self.tool_dofs[tool] {
            if given[dof] {
                continue;
            }
            let name = &tree.joint(tree.dofs()[dof]).name;
            let column = columns.joints.iter().find(|(_, d)| *d == dof);
            return Err(Error::InvalidData {
                origin: self.at(row, name),
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
        Ok(())
    }

    /// What the row observes (SI).
    fn observation(&self, row: &Row<'_>, tally: &mut Tally) -> Result<Observation> {
        let (columns, fields) = (&self.columns, row.fields);
        let (length, rotation) = (self.units.length, self.units.rotation);
        // A pose layout's row without any orientation cell is a position (a session measured
        // with single markers, in the same file as the 6-DoF rows).
        let position_only = matches!(
            columns.observation,
            ObservationKind::Pose | ObservationKind::RollPitchYaw | ObservationKind::RotationMatrix
        ) && columns.observed[3..].iter().all(|&c| fields[c].is_empty());
        let (kind, observed) = if position_only {
            tally.position_rows.push(row.id.clone());
            (ObservationKind::Position, &columns.observed[..3])
        } else {
            (columns.observation, &columns.observed[..])
        };
        let mut values = Vec::with_capacity(observed.len());
        for &column in observed {
            let (scale, unit, quantity) = match column_quantity(&self.headers[column]) {
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
            let value = number(&fields[column], unit).map_err(|m| self.invalid(row, column, m))?;
            values.push(match quantity {
                Some(quantity) => {
                    limits::check(value * scale, quantity, || self.place(row, column))?
                }
                None => value,
            });
        }
        observation(kind, &values).map_err(|(columns, message)| Error::InvalidData {
            origin: self.at(row, columns),
            message,
        })
    }
}
