//! The measurement CSV `treecal pair` writes: one row per kept plateau, in the units of the
//! logs it came from, read back by `read_measurements` (docs/file-formats.md, section 4).

use super::units::{MeasurementUnits, StatedUnits};
use crate::error::Result;
use crate::math::{Rotation, Vec3};

/// One paired measurement, SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct PairedRow {
    /// The row's `id`.
    pub id: String,
    /// The tool link.
    pub tool: String,
    /// One value per joint column (rad, m); NaN is written as an empty cell.
    pub joints: Vec<f64>,
    /// The target's mean position (m).
    pub position: Vec3,
    /// The rigid body's mean orientation, when the tracker gave poses.
    pub orientation: Option<Rotation>,
}

/// The CSV text: the units comment, `comments` (each written as a `#` line), the header
/// `id,tool,<joints>,x,y,z[,qw,qx,qy,qz]` and the rows at full precision. `prismatic[i]` says
/// whether joint column `i` is in the joint-length unit rather than the angle unit.
pub fn paired_measurements_to_csv(
    joint_names: &[String],
    prismatic: &[bool],
    rows: &[PairedRow],
    units: &MeasurementUnits,
    comments: &[String],
) -> Result<String> {
    let pose = rows.first().is_some_and(|r| r.orientation.is_some());
    let mut header = vec!["id".to_string(), "tool".to_string()];
    header.extend(joint_names.iter().cloned());
    let observed: &[&str] = if pose {
        &["x", "y", "z", "qw", "qx", "qy", "qz"]
    } else {
        &["x", "y", "z"]
    };
    header.extend(observed.iter().map(|c| c.to_string()));
    let length = units.length.in_metres();
    let scales: Vec<f64> = prismatic
        .iter()
        .map(|&p| {
            if p {
                units.joint_length.in_metres()
            } else {
                units.angle.in_radians()
            }
        })
        .collect();
    let text = |v: f64| {
        if v.is_nan() {
            String::new()
        } else {
            format!("{v}")
        }
    };
    let mut table = vec![header];
    for row in rows {
        let mut fields = vec![row.id.clone(), row.tool.clone()];
        fields.extend(row.joints.iter().zip(&scales).map(|(v, s)| text(v / s)));
        fields.extend((row.position / length).iter().map(|v| text(*v)));
        if let (true, Some(r)) = (pose, row.orientation) {
            let q = r.quaternion();
            fields.extend([q.w, q.i, q.j, q.k].map(text));
        }
        table.push(fields);
    }
    let body = super::csv_text(&table, "paired measurement CSV")?;
    let mut out = StatedUnits::line_for(units);
    out.push('\n');
    for comment in comments {
        for line in comment.lines() {
            out.push_str(&format!("# {line}\n"));
        }
    }
    out.push_str(&body);
    Ok(out)
}
