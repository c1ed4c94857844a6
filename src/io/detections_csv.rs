//! The detections CSV: pixels of board corners and markers seen by cameras, one row per
//! detected point, with the configuration the image was taken at:
//!
//! ```text
//! # units: angle=deg
//! id,camera,target,corner,u,v,torso_joint1,torso_joint2,left_joint1,…
//! img0001,head,left_board,0,312.41,240.07,0,10,…
//! ```
//!
//! `id` names the image: its rows must share one camera and one configuration; a row's
//! `target` and `corner` (the point's index on its target, OpenCV's order for a board) name
//! the point, `u` and `v` its pixel (always px). Joint columns as in the measurement CSV
//! (units by the `# units:` comment, radians by default; joints without a column are 0).
//! See `docs/file-formats.md`.

use super::csv_fields::CsvTable;
use super::joints_csv::{configurations, parse_csv};
use super::units::{parse_units_header, resolve_units, StatedUnits};
use crate::camera::{Rig, View};
use crate::error::{closest, Error, Result};
use crate::limits::cut;
use crate::tree::KinematicTree;
use nalgebra::Vector2;
use std::path::Path;

/// The columns every detections CSV has.
pub const DETECTION_COLUMNS: [&str; 6] = ["id", "camera", "target", "corner", "u", "v"];

/// Reads a detections CSV for `rig` on `tree`; `flags` are the units given on the command line.
pub fn read_detections(
    path: &Path,
    tree: &KinematicTree,
    rig: &Rig,
    flags: &StatedUnits,
) -> Result<Vec<View>> {
    let text = super::read_text(path, crate::limits::MAX_CSV_BYTES)?;
    parse_detections(&text, &path.display().to_string(), tree, rig, flags)
}

/// [`read_detections`] from text; `origin` names the file in messages.
pub fn parse_detections(
    text: &str,
    origin: &str,
    tree: &KinematicTree,
    rig: &Rig,
    flags: &StatedUnits,
) -> Result<Vec<View>> {
    let units = resolve_units(flags, &parse_units_header(text, origin)?, origin)?;
    let table = parse_csv(text, origin)?;
    let columns = required_columns(&table, origin)?;
    let (qs, _) = configurations(&table, tree, units.angle.in_radians(), origin)?;
    let mut views: Vec<View> = Vec::new();
    // Per view: the line of its first row (to name a disagreeing row's partner).
    let mut first_lines: Vec<usize> = Vec::new();
    for ((line, fields), q) in table.records.iter().zip(qs) {
        let field = |k: usize| fields.get(columns[k]).map_or("", String::as_str);
        let place = |k: usize| format!("{origin}:{line}:{}", DETECTION_COLUMNS[k]);
        let id = field(0);
        if id.is_empty() {
            return Err(invalid(place(0), "the image id is empty".into()));
        }
        let camera = find(
            field(1),
            rig.cameras.iter().map(|c| c.name.as_str()),
            "camera",
            place(1),
        )?;
        let target = find(
            field(2),
            rig.targets.iter().map(|t| t.name.as_str()),
            "target",
            place(2),
        )?;
        let count = rig.targets[target].shape.point_count();
        let corner: usize = field(3).parse().map_err(|_| {
            invalid(
                place(3),
                format!("'{}' is not a corner index (0, 1, …)", cut(field(3))),
            )
        })?;
        if corner >= count {
            return Err(invalid(
                place(3),
                format!(
                    "corner {corner} is not on target '{}', which has {count} points (0 to {})",
                    rig.targets[target].name,
                    count - 1
                ),
            ));
        }
        let pixel = |k: usize| -> Result<f64> {
            match field(k).parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(invalid(
                    place(k),
                    format!("'{}' is not a finite pixel coordinate", cut(field(k))),
                )),
            }
        };
        let point = (corner, Vector2::new(pixel(4)?, pixel(5)?));
        let image = &rig.cameras[camera].intrinsics;
        for (k, value, size) in [(4, point.1.x, image.width), (5, point.1.y, image.height)] {
            if !(-1.0..=size + 1.0).contains(&value) {
                return Err(invalid(
                    place(k),
                    format!(
                        "{value} px is outside camera '{}''s {} × {} image; check the image \
                         size in the camera file, the camera column, or that u and v are \
                         pixels (not normalised coordinates)",
                        rig.cameras[camera].name, image.width, image.height
                    ),
                ));
            }
        }
        let existing = views.iter().position(|v| v.id == id && v.target == target);
        let same_image = views.iter().position(|v| v.id == id);
        if let Some(other) = same_image {
            if views[other].camera != camera || views[other].q != q {
                return Err(invalid(
                    format!("{origin}:{line}"),
                    format!(
                        "image '{}' has a different camera or configuration here than on line \
                         {}; one image is one camera at one configuration",
                        cut(id),
                        first_lines[other]
                    ),
                ));
            }
        }
        match existing {
            Some(v) => {
                if views[v].points.iter().any(|(c, _)| *c == corner) {
                    return Err(invalid(
                        place(3),
                        format!(
                            "image '{}' has corner {corner} of '{}' twice",
                            cut(id),
                            rig.targets[target].name
                        ),
                    ));
                }
                views[v].points.push(point);
            }
            None => {
                views.push(View {
                    id: id.to_owned(),
                    q,
                    camera,
                    target,
                    points: vec![point],
                });
                first_lines.push(*line);
            }
        }
    }
    if views.is_empty() {
        return Err(invalid(origin.to_owned(), "no detections".into()));
    }
    Ok(views)
}

/// The column of each of [`DETECTION_COLUMNS`], or an error naming the missing one.
fn required_columns(table: &CsvTable, origin: &str) -> Result<[usize; 6]> {
    let mut columns = [0; 6];
    for (k, name) in DETECTION_COLUMNS.iter().enumerate() {
        columns[k] = table
            .headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| {
                invalid(
                    format!("{origin}:{}", table.header_line),
                    format!(
                        "no '{name}' column; a detections CSV has the columns {} and one per \
                         joint (docs/file-formats.md)",
                        DETECTION_COLUMNS.join(", ")
                    ),
                )
            })?;
    }
    Ok(columns)
}

/// The index of `name` among `names`, or an error naming the closest.
fn find<'a>(
    name: &str,
    names: impl Iterator<Item = &'a str> + Clone,
    what: &str,
    place: String,
) -> Result<usize> {
    if let Some(index) = names.clone().position(|n| n == name) {
        return Ok(index);
    }
    let all: Vec<&str> = names.clone().collect();
    let hint = match closest(name, names) {
        Some(best) => format!(
            "; the closest is '{best}' (the camera file has {})",
            all.join(", ")
        ),
        None => "; the camera file describes none".into(),
    };
    Err(invalid(
        place,
        format!("'{}' is not a {what} of the camera file{hint}", cut(name)),
    ))
}

fn invalid(origin: String, message: String) -> Error {
    Error::InvalidData { origin, message }
}

/// A detections CSV of `views` (cameras and targets of `rig` on `tree`), which
/// [`parse_detections`] reads back: one row per detected point, revolute joints in radians,
/// prismatic ones in metres, pixels at full precision.
pub fn detections_to_csv(tree: &KinematicTree, rig: &Rig, views: &[View]) -> String {
    let mut text = String::from("# units: length=m angle=rad\n");
    let mut header: Vec<String> = DETECTION_COLUMNS.iter().map(|c| c.to_string()).collect();
    header.extend(tree.dofs().iter().map(|j| tree.joint(*j).name.clone()));
    text.push_str(&header.join(","));
    text.push('\n');
    for view in views {
        let joints: Vec<String> = view.q.iter().map(|v| format!("{v:?}")).collect();
        let joints = joints.join(",");
        for (corner, pixel) in &view.points {
            text.push_str(&format!(
                "{},{},{},{corner},{:?},{:?},{joints}\n",
                view.id,
                rig.cameras[view.camera].name,
                rig.targets[view.target].name,
                pixel.x,
                pixel.y
            ));
        }
    }
    text
}
