//! Joint-value CSV files (`treecal fk`): a header naming joints, one configuration per row.

use super::csv_fields::{CsvFields, CsvTable};
use crate::error::{Error, Result};
use crate::limits::{
    self, check_count, check_text_size, Quantity, MAX_CSV_BYTES, MAX_CSV_COLUMNS, MAX_CSV_ROWS,
};
use crate::math::Pose;
use crate::tree::{Actuation, JointKind, KinematicTree};

/// Parses CSV text: `#` comment lines and blank lines skipped, fields trimmed. Line breaks
/// may be `\n`, `\r\n` or a lone `\r`; rows and columns are limited to
/// [`MAX_CSV_ROWS`] and [`MAX_CSV_COLUMNS`]. Linear in the size of the text.
pub fn parse_csv(text: &str, origin: &str) -> Result<CsvTable> {
    parse_csv_fields(text, origin).map(CsvFields::into_table)
}

/// [`parse_csv`] into the compact [`CsvFields`] (one text buffer, no `String` per field).
pub fn parse_csv_fields(text: &str, origin: &str) -> Result<CsvFields> {
    check_text_size(text, MAX_CSV_BYTES, origin)?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    super::csv_scan::check_csv_shape(text, origin)?;
    // csv-core ends `#` comments (and fields) at `\n` only: a file with lone `\r` line
    // breaks would be one comment or one row. Those breaks become `\n` (lines keep their
    // numbers: a lone `\r` counts as a line break below too).
    let normalised;
    let text = if has_lone_carriage_return(text) {
        normalised = text.replace("\r\n", "\n").replace('\r', "\n");
        normalised.as_str()
    } else {
        text
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.as_bytes());
    let mut lines = LineCounter::new(text);
    let mut table: Option<CsvFields> = None;
    let mut record = csv::StringRecord::new();
    loop {
        let more = reader
            .read_record(&mut record)
            .map_err(|e| Error::InvalidData {
                origin: match e.position() {
                    Some(p) => format!("{origin}:{}", lines.line_at(p.byte())),
                    None => origin.to_owned(),
                },
                message: format!("not readable as CSV: {e}"),
            })?;
        if !more {
            break;
        }
        let line = record.position().map_or(0, |p| lines.line_at(p.byte()));
        if record.len() > MAX_CSV_COLUMNS {
            check_count(
                record.len(),
                MAX_CSV_COLUMNS,
                &format!("{origin}:{line}"),
                "columns",
            )?;
        }
        if record.iter().all(str::is_empty) {
            continue;
        }
        match &mut table {
            None => {
                let headers: Vec<String> = record.iter().map(str::to_owned).collect();
                // Before any data row: its field count would be the only message.
                check_separator(&headers, &format!("{origin}:{line}"))?;
                table = Some(CsvFields::new(headers, line))
            }
            Some(table) => {
                if table.len() == MAX_CSV_ROWS {
                    check_count(
                        MAX_CSV_ROWS + 1,
                        MAX_CSV_ROWS,
                        &format!("{origin}:{line}"),
                        "data rows",
                    )?;
                }
                table.push_row(line, &record, origin)?;
            }
        }
    }
    let table = table.ok_or_else(|| Error::InvalidData {
        origin: origin.to_owned(),
        message: if text.trim().is_empty() {
            "the file is empty; it needs a header row naming joints".into()
        } else {
            format!("{NO_HEADER}; it needs a header row naming joints")
        },
    })?;
    check_header(&table.headers, &format!("{origin}:{}", table.header_line))?;
    Ok(table)
}

/// The start of the message for a file with only comment and blank lines.
pub(crate) const NO_HEADER: &str = "the file has no header row, only comment (`#`) and blank lines";

/// Whether `text` has a `\r` that is not followed by `\n`.
fn has_lone_carriage_return(text: &str) -> bool {
    let bytes = text.as_bytes();
    bytes
        .iter()
        .enumerate()
        .any(|(i, &b)| b == b'\r' && bytes.get(i + 1) != Some(&b'\n'))
}

/// The 1-based line of records at increasing byte offsets, counted incrementally (so reading
/// a whole file is linear in its size).
///
/// The csv crate takes a record's position before skipping what precedes it (blank lines,
/// `#` comment lines, the `\n` of a `\r\n`), so its `line()` is too small after any of those.
/// This skips the same bytes csv-core does at the start of a record, then counts line breaks
/// from the previous record on.
struct LineCounter<'a> {
    bytes: &'a [u8],
    /// Where counting stopped, and the 1-based line there.
    offset: usize,
    line: usize,
}

impl<'a> LineCounter<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            bytes: text.as_bytes(),
            offset: 0,
            line: 1,
        }
    }

    /// The line on which the record at reader byte offset `byte` starts.
    fn line_at(&mut self, byte: u64) -> usize {
        let bytes = self.bytes;
        let mut start = usize::try_from(byte).map_or(bytes.len(), |b| b.min(bytes.len()));
        loop {
            match bytes.get(start) {
                Some(b'\r' | b'\n') => start += 1,
                Some(b'#') => {
                    start = bytes[start..]
                        .iter()
                        .position(|&b| b == b'\n')
                        .map_or(bytes.len(), |i| start + i + 1)
                }
                _ => break,
            }
        }
        if start < self.offset {
            // Offsets only grow while reading; start again rather than count wrongly.
            self.offset = 0;
            self.line = 1;
        }
        // A line break is `\n`, or a `\r` not followed by `\n`.
        self.line += bytes[self.offset..start]
            .iter()
            .enumerate()
            .filter(|&(i, &b)| {
                b == b'\n' || (b == b'\r' && bytes.get(self.offset + i + 1) != Some(&b'\n'))
            })
            .count();
        self.offset = start;
        self.line
    }
}

/// How the columns of a joint CSV map onto a robot.
#[derive(Debug, Clone, Default)]
pub struct ColumnMapping {
    /// `(column, configuration index)` of independent joints.
    pub joints: Vec<(usize, usize)>,
    /// Columns naming a fixed or mimic joint: read but not used (the value is implied).
    pub implied: Vec<(usize, String)>,
    /// Columns matching no joint: passed through.
    pub unmatched: Vec<usize>,
}

/// Reads configurations from a joint CSV. Joints without a column are 0; `angle_scale`
/// converts angle columns to radians (1 for rad, π/180 for deg).
pub fn configurations(
    table: &CsvTable,
    tree: &KinematicTree,
    angle_scale: f64,
    origin: &str,
) -> Result<(Vec<Vec<f64>>, ColumnMapping)> {
    let mapping = ColumnMapping::new(&table.headers, tree);
    let mut configurations = Vec::with_capacity(table.records.len());
    for (line, fields) in &table.records {
        configurations.push(mapping.configuration(
            tree,
            &table.headers,
            (*line, fields),
            angle_scale,
            origin,
        )?);
    }
    Ok((configurations, mapping))
}

impl ColumnMapping {
    /// Which columns of `headers` are joints of `tree`, implied joints, or neither.
    pub fn new(headers: &[String], tree: &KinematicTree) -> Self {
        let mut mapping = ColumnMapping::default();
        for (column, name) in headers.iter().enumerate() {
            match tree.joint_id(name) {
                Ok(joint) => match tree.joint(joint).actuation {
                    Actuation::Independent(dof) => mapping.joints.push((column, dof.0)),
                    Actuation::Mimic { .. } => mapping.implied.push((
                        column,
                        format!("'{name}' is a mimic joint; its value follows its master"),
                    )),
                    Actuation::None => mapping
                        .implied
                        .push((column, format!("'{name}' is a fixed joint"))),
                },
                Err(_) => mapping.unmatched.push(column),
            }
        }
        mapping
    }

    /// The configuration (SI) of one row `(line, fields)`; a value that is not a finite
    /// number or beyond its magnitude limit is an error naming `origin:line:column`.
    pub fn configuration(
        &self,
        tree: &KinematicTree,
        headers: &[String],
        (line, fields): (usize, &[String]),
        angle_scale: f64,
        origin: &str,
    ) -> Result<Vec<f64>> {
        let mut q = tree.zero_configuration();
        for &(column, dof) in &self.joints {
            let text = &fields[column];
            let place = || format!("{origin}:{line}:{}", headers[column]);
            let value: f64 = text.parse().map_err(|_| Error::InvalidData {
                origin: place(),
                message: format!("'{}' is not a number", limits::cut(text)),
            })?;
            if !value.is_finite() {
                return Err(Error::InvalidData {
                    origin: place(),
                    message: format!("'{}' is not a finite number", limits::cut(text)),
                });
            }
            q[dof] = joint_value(tree, dof, value, angle_scale, place)?;
        }
        Ok(q)
    }
}

/// The value of independent joint `dof` in SI: a revolute or continuous value times
/// `angle_scale`, a prismatic value as given (metres), checked against the magnitude limits
/// (an error at `place`). The one conversion of `fk` from a CSV and from arrays.
pub fn joint_value(
    tree: &KinematicTree,
    dof: usize,
    value: f64,
    angle_scale: f64,
    place: impl FnOnce() -> String,
) -> Result<f64> {
    if tree.joint(tree.dofs()[dof]).kind == JointKind::Prismatic {
        limits::check(value, Quantity::Length, place)
    } else {
        limits::check(value * angle_scale, Quantity::Angle, place)
    }
}

/// The table with `x,y,z,r11,…,r33` of each row's pose appended (metres, full precision).
pub fn append_poses(table: &CsvTable, poses: &[Pose]) -> Result<String> {
    let mut header = table.headers.clone();
    header.extend(POSE_COLUMNS.map(String::from));
    let mut rows = vec![header];
    for ((_, fields), pose) in table.records.iter().zip(poses) {
        let mut row = fields.clone();
        row.extend(pose_fields(pose));
        rows.push(row);
    }
    super::csv_text(&rows, "output")
}

/// The columns [`append_poses`] appends.
pub const POSE_COLUMNS: [&str; 12] = [
    "x", "y", "z", "r11", "r12", "r13", "r21", "r22", "r23", "r31", "r32", "r33",
];

/// A pose as the [`POSE_COLUMNS`] fields: the translation (m), then the rotation matrix row by
/// row, at full precision.
pub fn pose_fields(pose: &Pose) -> impl Iterator<Item = String> {
    let t = pose.translation.vector;
    let r = pose.rotation.to_rotation_matrix();
    [t.x, t.y, t.z]
        .into_iter()
        .chain((0..3).flat_map(move |i| (0..3).map(move |j| r[(i, j)])))
        .map(|v| format!("{v}"))
}

/// A header naming a column twice is an error at `place` (`file:line`).
/// The header's checks: another separator than commas, then a column named twice.
pub(super) fn check_header(headers: &[String], place: &str) -> Result<()> {
    check_separator(headers, place)?;
    check_unique_columns(headers, place)
}

/// Fails when the header is one column holding semicolons or tabs: a spreadsheet's export
/// with another separator, which would else show later as a missing column or a field count.
fn check_separator(headers: &[String], place: &str) -> Result<()> {
    let [only] = headers else {
        return Ok(());
    };
    let (separator, why) = if only.contains(';') {
        (
            "semicolons",
            " (a spreadsheet's export where the decimal mark is a comma)",
        )
    } else if only.contains('\t') {
        ("tabs", "")
    } else {
        return Ok(());
    };
    Err(Error::InvalidData {
        origin: place.to_owned(),
        message: format!(
            "the header row is separated by {separator}, not commas{why}: treecal reads \
             comma-separated values with `.` as the decimal mark; save the sheet as \
             \"CSV (comma delimited)\" with `.` decimals"
        ),
    })
}

pub(super) fn check_unique_columns(headers: &[String], place: &str) -> Result<()> {
    let mut seen = std::collections::HashSet::with_capacity(headers.len());
    for name in headers {
        if !seen.insert(name.as_str()) {
            return Err(Error::InvalidData {
                origin: place.to_owned(),
                message: format!("column '{name}' appears twice in the header"),
            });
        }
    }
    Ok(())
}
