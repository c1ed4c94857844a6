//! Contacts CSV (issue 29, docs/file-formats.md): one row per contact — the whole joint state
//! at the moment a tool presses flush on a plane, touches a plane with its contact point,
//! touches another tool, or holds a bar — with the columns
//! `id, session, kind, tool, spot (optional), tool2 (touch/distance), <joints by URDF name>`.
//! Joint units from the `# units: angle=… joint_length=…` comment (default rad, m).

use super::bounded::read_text;
use super::joints_csv::{parse_csv, ColumnMapping};
use super::units::{parse_units_header, LengthUnit};
use crate::error::{closest, Error, Result};
use crate::limits::{cut, MAX_CSV_BYTES};
use crate::tree::KinematicTree;
use std::path::Path;

/// The kind of a contact row (the `kind` column).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactKind {
    /// The tool's contact face lies flush in the session's plane (3 equations).
    Flush,
    /// The tool's contact point lies in the session's plane (1 equation).
    Point,
    /// The tool's contact point touches `tool2`'s (3 equations).
    Touch,
    /// The tool's contact point is the bar's length from `tool2`'s (1 equation).
    Distance,
}

impl ContactKind {
    /// The names the `kind` column takes.
    pub const NAMES: [&'static str; 4] = ["flush", "point", "touch", "distance"];

    /// The kind named `name` (case-insensitive).
    pub fn parse(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "flush" => Some(Self::Flush),
            "point" => Some(Self::Point),
            "touch" => Some(Self::Touch),
            "distance" => Some(Self::Distance),
            _ => None,
        }
    }

    /// Its name in the CSV.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// Whether it involves a second tool (`tool2` required).
    pub fn is_pair(self) -> bool {
        matches!(self, Self::Touch | Self::Distance)
    }
}

/// One row of a contacts CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactRow {
    /// The 1-based line in the file.
    pub line: usize,
    /// The `id` column.
    pub id: String,
    /// The `session` column (one plane per session).
    pub session: String,
    /// The `kind` column.
    pub kind: ContactKind,
    /// The `tool` column: a tool name of the setup file.
    pub tool: String,
    /// The optional `spot` column (the table spot touched), empty as `None`.
    pub spot: Option<String>,
    /// The `tool2` column (touch, distance).
    pub tool2: Option<String>,
    /// The configuration (SI: rad, m), one value per independent joint of the tree.
    pub q: Vec<f64>,
}

/// A contacts file as read: its rows, and what the reader noticed (columns that are no joint,
/// chain joints without a column).
#[derive(Debug, Clone, Default)]
pub struct ContactTable {
    /// The rows in file order.
    pub rows: Vec<ContactRow>,
    /// Columns that are neither a contact column nor a joint of the robot (ignored).
    pub ignored_columns: Vec<String>,
    /// Independent joints of the robot without a column (their value is 0).
    pub missing_joints: Vec<String>,
}

/// The columns every contacts file has.
const REQUIRED: [&str; 4] = ["id", "session", "kind", "tool"];
/// The optional contact columns.
const OPTIONAL: [&str; 2] = ["spot", "tool2"];

/// Reads a contacts CSV file.
pub fn read_contacts(path: &Path, tree: &KinematicTree) -> Result<ContactTable> {
    let text = read_text(path, MAX_CSV_BYTES)?;
    parse_contacts(&text, &path.display().to_string(), tree)
}

/// Parses contacts CSV `text` (`origin` names it in messages).
pub fn parse_contacts(text: &str, origin: &str, tree: &KinematicTree) -> Result<ContactTable> {
    let units = parse_units_header(text, origin)?;
    let angle_scale = units.angle.map_or(1.0, |a| a.in_radians());
    let joint_length = units
        .joint_length
        .or(units.length)
        .unwrap_or(LengthUnit::Metre);
    let table = parse_csv(text, origin)?;
    let column = |name: &str| {
        table
            .headers
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))
    };
    let mut required = [0; 4];
    for (slot, name) in required.iter_mut().zip(REQUIRED) {
        *slot = column(name).ok_or_else(|| Error::InvalidData {
            origin: format!("{origin}:{}", table.header_line),
            message: format!(
                "the header has no '{name}' column; a contacts file has the columns id, \
                 session, kind, tool, spot (optional), tool2 (touch and distance rows) and one \
                 column per joint named as in the URDF (docs/file-formats.md)"
            ),
        })?;
    }
    let [id, session, kind, tool] = required;
    let [spot, tool2] = OPTIONAL.map(column);
    let mapping = ColumnMapping::new(&table.headers, tree);
    let contact_columns: Vec<usize> = required.iter().copied().chain(spot).chain(tool2).collect();
    let ignored_columns = mapping
        .unmatched
        .iter()
        .filter(|c| !contact_columns.contains(c))
        .map(|&c| table.headers[c].clone())
        .collect();
    let mut covered = vec![false; tree.dofs().len()];
    for &(_, dof) in &mapping.joints {
        covered[dof] = true;
    }
    let missing_joints = covered
        .iter()
        .enumerate()
        .filter(|(_, c)| !**c)
        .map(|(dof, _)| tree.joint(tree.dofs()[dof]).name.clone())
        .collect();
    let mut rows = Vec::with_capacity(table.records.len());
    for (line, fields) in &table.records {
        let place = |c: usize| format!("{origin}:{line}:{}", table.headers[c]);
        if fields.len() != table.headers.len() {
            return Err(Error::InvalidData {
                origin: format!("{origin}:{line}"),
                message: format!(
                    "{} fields for {} columns; every row has one field per header column",
                    fields.len(),
                    table.headers.len()
                ),
            });
        }
        let text_at = |c: usize| -> Result<String> {
            let value = fields[c].trim();
            if value.is_empty() {
                return Err(Error::InvalidData {
                    origin: place(c),
                    message: format!("the '{}' field is empty; give a value", table.headers[c]),
                });
            }
            Ok(value.to_owned())
        };
        let optional = |c: Option<usize>| {
            c.map(|c| fields[c].trim().to_owned())
                .filter(|v| !v.is_empty())
        };
        let kind_text = text_at(kind)?;
        let kind_value = ContactKind::parse(&kind_text).ok_or_else(|| Error::InvalidData {
            origin: place(kind),
            message: format!(
                "'{}' is not a contact kind; use one of {}{}",
                cut(&kind_text),
                ContactKind::NAMES.join(", "),
                closest(&kind_text, ContactKind::NAMES)
                    .map(|b| format!(" (closest: '{b}')"))
                    .unwrap_or_default()
            ),
        })?;
        let second = optional(tool2);
        if kind_value.is_pair() && second.is_none() {
            return Err(Error::InvalidData {
                origin: format!("{origin}:{line}"),
                message: format!(
                    "a {} row needs the other tool in a 'tool2' column",
                    kind_value.name()
                ),
            });
        }
        let mut q =
            mapping.configuration(tree, &table.headers, (*line, fields), angle_scale, origin)?;
        scale_prismatic(tree, &mut q, &mapping, joint_length);
        rows.push(ContactRow {
            line: *line,
            id: text_at(id)?,
            session: text_at(session)?,
            kind: kind_value,
            tool: text_at(tool)?,
            spot: optional(spot),
            tool2: if kind_value.is_pair() { second } else { None },
            q,
        });
    }
    if rows.is_empty() {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: "has no contact rows; give one row per contact below the header".into(),
        });
    }
    Ok(ContactTable {
        rows,
        ignored_columns,
        missing_joints,
    })
}

/// Prismatic joint values given in `unit` converted to metres.
fn scale_prismatic(tree: &KinematicTree, q: &mut [f64], mapping: &ColumnMapping, unit: LengthUnit) {
    for &(_, dof) in &mapping.joints {
        if tree.joint(tree.dofs()[dof]).kind == crate::tree::JointKind::Prismatic {
            q[dof] *= unit.in_metres();
        }
    }
}

/// Contacts CSV text for `rows` (`joints`: the independent joints' names in tree order), with
/// a units comment (rad, m): what `simulate --observation flush` writes as a lab would.
pub fn contacts_to_csv(rows: &[ContactRow], joints: &[String]) -> String {
    let mut text = String::from("# units: length=m angle=rad\n");
    let mut header = vec!["id", "session", "kind", "tool", "spot", "tool2"];
    header.extend(joints.iter().map(String::as_str));
    text.push_str(&header.join(","));
    text.push('\n');
    for row in rows {
        let mut fields = vec![
            row.id.clone(),
            row.session.clone(),
            row.kind.name().to_owned(),
            row.tool.clone(),
            row.spot.clone().unwrap_or_default(),
            row.tool2.clone().unwrap_or_default(),
        ];
        fields.extend(row.q.iter().map(|v| format!("{v:e}")));
        text.push_str(&fields.join(","));
        text.push('\n');
    }
    text
}
