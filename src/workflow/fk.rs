//! `fk`: forward kinematics of one link, from joint values in memory or in a joint CSV. Both
//! convert values with [`crate::io::joint_value`] and compute [`KinematicTree::link_pose`],
//! so the CLI and the Python package agree to the last bit.

use super::note::Note;
use super::source::RobotSource;
use crate::error::{Error, Result};
use crate::io::{
    append_poses, configurations, joint_value, open_csv_records, parse_csv, pose_fields, AngleUnit,
    ColumnMapping, POSE_COLUMNS,
};
use crate::math::Pose;
use crate::tree::{Actuation, KinematicTree, LinkId};
use std::io::Write;
use std::path::PathBuf;

/// Joint values in memory.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FkConfig {
    /// The robot.
    pub robot: RobotSource,
    /// The link whose pose is computed.
    pub tip: String,
    /// The independent joints the columns of `joints` belong to; the tree's other joints are 0.
    pub joint_names: Vec<String>,
    /// One configuration per row, one value per joint name.
    pub joints: Vec<Vec<f64>>,
    /// Unit of revolute and continuous values (prismatic values are metres).
    pub angle_unit: AngleUnit,
    /// The 0-based index of `joints`' first row in the caller's table (messages name rows
    /// from it): a caller that passes a long table in chunks keeps the rows' numbers.
    pub first_row: usize,
}

/// `root_from_tip` of every configuration. An unknown or repeated joint name, a mimic or fixed
/// joint, a row of the wrong length or a non-finite value is an error naming it.
pub fn fk(config: &FkConfig) -> Result<Vec<Pose>> {
    let robot = config.robot.load()?;
    let tree = robot.tree();
    let tip = tree.link_id(config.tip.trim())?;
    let dofs = config
        .joint_names
        .iter()
        .map(|name| independent_dof(tree, name))
        .collect::<Result<Vec<_>>>()?;
    // A joint named twice would take the later column's value without a word.
    for (index, &dof) in dofs.iter().enumerate() {
        if let Some(first) = dofs[..index].iter().position(|&d| d == dof) {
            return Err(Error::InvalidData {
                origin: "joint_names".into(),
                message: format!(
                    "joint '{}' is named twice (columns {} and {}); name each joint once",
                    config.joint_names[index].trim(),
                    first + 1,
                    index + 1
                ),
            });
        }
    }
    let scale = config.angle_unit.in_radians();
    let mut rows = Vec::with_capacity(config.joints.len());
    for (row, values) in config.joints.iter().enumerate() {
        if values.len() != dofs.len() {
            return Err(Error::InvalidData {
                origin: format!("joints, row {}", config.first_row + row + 1),
                message: format!(
                    "{} values for {} joint names; give one value per name",
                    values.len(),
                    dofs.len()
                ),
            });
        }
        let mut q = tree.zero_configuration();
        for ((&dof, &value), name) in dofs.iter().zip(values).zip(&config.joint_names) {
            q[dof] = joint_value(tree, dof, value, scale, || {
                format!("joints, row {}, joint '{name}'", config.first_row + row + 1)
            })?;
        }
        rows.push(q);
    }
    poses(tree, tip, &rows)
}

/// The configuration index of the independent joint `name`.
fn independent_dof(tree: &KinematicTree, name: &str) -> Result<usize> {
    let joint = tree.joint(tree.joint_id(name.trim())?);
    match joint.actuation {
        Actuation::Independent(dof) => Ok(dof.0),
        Actuation::Mimic { master, .. } => Err(Error::InvalidData {
            origin: format!("joint '{name}'"),
            message: format!(
                "a mimic joint that follows '{}'; give the value of '{}' instead",
                tree.joint(tree.dofs()[master.0]).name,
                tree.joint(tree.dofs()[master.0]).name
            ),
        }),
        Actuation::None => Err(Error::InvalidData {
            origin: format!("joint '{name}'"),
            message: "a fixed joint has no value; leave it out".into(),
        }),
    }
}

/// The core of both paths: `root_from_tip` at every configuration (SI values).
fn poses(tree: &KinematicTree, tip: LinkId, configurations: &[Vec<f64>]) -> Result<Vec<Pose>> {
    configurations
        .iter()
        .map(|q| tree.link_pose(tip, q))
        .collect()
}

/// A joint CSV (the CLI's `fk`): a header naming joints, one configuration per row; columns
/// that match no joint are passed through (with a note), joints without a column are 0.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FkCsvConfig {
    /// The robot.
    pub robot: RobotSource,
    /// The link whose pose is computed.
    pub tip: String,
    /// The joint CSV.
    pub joints: PathBuf,
    /// Unit of revolute and continuous values in the CSV (prismatic values are metres).
    pub angle_unit: AngleUnit,
}

/// The poses of a joint CSV and the CSV with them appended.
#[derive(Debug, Clone, PartialEq)]
pub struct FkTable {
    /// `root_from_tip` per row.
    pub poses: Vec<Pose>,
    /// Every input row with `x,y,z,r11,…,r33` appended (metres, full precision).
    pub csv: String,
    /// Loader warnings and the columns not used, in order.
    pub notes: Vec<Note>,
}

/// Reads the CSV, computes the poses and appends them to its rows.
pub fn fk_csv(config: &FkCsvConfig) -> Result<FkTable> {
    let robot = config.robot.load()?;
    let mut notes = robot.notes();
    let tree = robot.tree();
    let tip = tree.link_id(&config.tip)?;
    let origin = config.joints.display().to_string();
    let text = crate::limits::read_text(&config.joints, crate::limits::MAX_CSV_BYTES)?;
    let table = parse_csv(&text, &origin)?;
    let (rows, mapping) = configurations(&table, tree, config.angle_unit.in_radians(), &origin)?;
    notes.extend(mapping_notes(&mapping, &table.headers, tree, &origin));
    let poses = poses(tree, tip, &rows)?;
    let csv = append_poses(&table, &poses)?;
    Ok(FkTable { poses, csv, notes })
}

/// The notes on a joint CSV's columns: those matching no joint (passed through) and those
/// naming an implied joint (not used).
fn mapping_notes(
    mapping: &ColumnMapping,
    headers: &[String],
    tree: &KinematicTree,
    origin: &str,
) -> Vec<Note> {
    let mut notes = Vec::new();
    for column in &mapping.unmatched {
        notes.push(Note::info(format!(
            "column '{}' of {origin} matches no joint of '{}'; passed through unchanged",
            headers[*column],
            tree.name()
        )));
    }
    for (_, reason) in &mapping.implied {
        notes.push(Note::info(format!(
            "{origin}: {reason}; the column is not used"
        )));
    }
    notes
}

/// What [`fk_csv_stream`] did: the rows written and the notes of [`FkTable::notes`].
#[derive(Debug, Clone, PartialEq)]
pub struct FkStreamSummary {
    /// Data rows written.
    pub rows: usize,
    /// Loader warnings and the columns not used, in order.
    pub notes: Vec<Note>,
}

/// [`fk_csv`] in memory bounded by one row: writes to `output` the same bytes as
/// [`FkTable::csv`]. The file is read twice: first every row is checked (so an error writes
/// nothing), then each row is written with its pose as it is computed.
pub fn fk_csv_stream(config: &FkCsvConfig, output: &mut dyn Write) -> Result<FkStreamSummary> {
    let robot = config.robot.load()?;
    let tree = robot.tree();
    let tip = tree.link_id(&config.tip)?;
    let origin = config.joints.display().to_string();
    let scale = config.angle_unit.in_radians();
    // First pass: every row checked, nothing written.
    let mut records = open_csv_records(&config.joints)?;
    let headers = records.headers().to_vec();
    let mapping = ColumnMapping::new(&headers, tree);
    let mut rows = 0;
    while let Some((line, fields)) = records.next_record()? {
        let q = mapping.configuration(tree, &headers, (line, &fields), scale, &origin)?;
        tree.link_pose(tip, &q)?;
        rows += 1;
    }
    // Second pass: each row written as it is computed.
    let mut records = open_csv_records(&config.joints)?;
    let mut writer = csv::Writer::from_writer(output);
    writer
        .write_record(headers.iter().map(String::as_str).chain(POSE_COLUMNS))
        .map_err(output_error)?;
    while let Some((line, fields)) = records.next_record()? {
        let q = mapping.configuration(tree, &headers, (line, &fields), scale, &origin)?;
        let pose = tree.link_pose(tip, &q)?;
        writer
            .write_record(fields.iter().cloned().chain(pose_fields(&pose)))
            .map_err(output_error)?;
    }
    writer.flush().map_err(|source| Error::Io {
        path: "output".into(),
        source,
    })?;
    let mut notes = robot.notes();
    notes.extend(mapping_notes(&mapping, &headers, tree, &origin));
    Ok(FkStreamSummary { rows, notes })
}

/// A failed write of the output: an I/O error stays one (a closed pipe is recognisable).
fn output_error(error: csv::Error) -> Error {
    let message = error.to_string();
    match error.into_kind() {
        csv::ErrorKind::Io(source) => Error::Io {
            path: "output".into(),
            source,
        },
        _ => Error::InvalidData {
            origin: "output".into(),
            message,
        },
    }
}
