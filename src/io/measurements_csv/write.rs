//! The measurement CSV written: the reader's columns and units, so that what is written reads back.

// The parent's types, constants and imports.
use super::*;

/// How to write a measurement CSV.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeasurementWriteOptions {
    /// Unit of positions, targets and prismatic joint values (default m).
    pub length_unit: LengthUnit,
    /// Unit of revolute and continuous joint values (default rad).
    pub angle_unit: AngleUnit,
    /// Write each pose as three targets `ax,…,cz` placed by
    /// [`crate::measurement::targets_on`] (as a tracker exports them) instead of `x,…,qz`.
    pub three_targets: bool,
}

/// Writes measurements as CSV in metres and radians:
/// `id,stage,tool,<joint names…>,x,y,z[,qw,qx,qy,qz]`.
/// Full poses and single positions cannot be mixed in one file.
pub fn measurements_to_csv(
    tree: &KinematicTree,
    model: &McpcModel,
    measurements: &[Measurement],
) -> Result<String> {
    measurements_to_csv_with(
        tree,
        model,
        measurements,
        &MeasurementWriteOptions::default(),
    )
}

/// Writes measurements as CSV in the units and layout `options` name; output in units other
/// than metres and radians starts with the units comment `# units: length=… angle=…`.
pub fn measurements_to_csv_with(
    tree: &KinematicTree,
    model: &McpcModel,
    measurements: &[Measurement],
    options: &MeasurementWriteOptions,
) -> Result<String> {
    let fail = |message: String| Error::InvalidData {
        origin: "measurement CSV".into(),
        message,
    };
    let poses = measurements
        .iter()
        .filter(|m| matches!(m.observation, Observation::Pose(_)))
        .count();
    if poses != 0 && poses != measurements.len() {
        return Err(fail(
            "full poses and single positions cannot be written to one file".into(),
        ));
    }
    if options.three_targets && poses != measurements.len() {
        return Err(fail(
            "three targets can only be written for full poses, not for positions".into(),
        ));
    }
    let kind = match (options.three_targets, poses > 0) {
        (true, _) => ObservationKind::ThreeTargets,
        (false, true) => ObservationKind::Pose,
        (false, false) => ObservationKind::Position,
    };
    let mut header: Vec<String> = vec!["id".into(), "stage".into(), "tool".into()];
    header.extend(tree.dofs().iter().map(|j| tree.joint(*j).name.clone()));
    header.extend(kind.columns().iter().map(|c| c.to_string()));
    // The payload column only when some row states its payload.
    let payloads = measurements.iter().any(|m| m.payload.is_some());
    if payloads {
        header.push(PAYLOAD_COLUMN.into());
    }
    // The session column only when some row names its session.
    let sessions = measurements.iter().any(|m| m.session.is_some());
    if sessions {
        header.push(SESSION_COLUMN.into());
    }
    let length = options.length_unit.in_metres();
    let joint_scales: Vec<f64> = tree
        .dofs()
        .iter()
        .map(|j| match tree.joint(*j).kind {
            JointKind::Prismatic => length,
            _ => options.angle_unit.in_radians(),
        })
        .collect();
    let text = |v: f64| format!("{v}");
    let mut rows = vec![header];
    for (index, m) in measurements.iter().enumerate() {
        let tool = model
            .tools()
            .get(m.tool)
            .map(|t| tree.link(t.link).name.clone())
            .ok_or_else(|| {
                fail(format!(
                    "measurement {index} names tool {} of {}",
                    m.tool,
                    model.tools().len()
                ))
            })?;
        if m.q.len() != joint_scales.len() {
            return Err(fail(format!(
                "measurement {index} has {} joint values but the robot has {} independent joints",
                m.q.len(),
                joint_scales.len()
            )));
        }
        let mut row = vec![
            (index + 1).to_string(),
            m.stage.clone().unwrap_or_default(),
            tool,
        ];
        row.extend(m.q.iter().zip(&joint_scales).map(|(v, s)| text(v / s)));
        match &m.observation {
            Observation::Pose(p) if options.three_targets => {
                for target in targets_on(p) {
                    row.extend(target.iter().map(|v| text(v / length)));
                }
            }
            Observation::Pose(p) => {
                let t = p.translation.vector / length;
                let q = p.rotation.quaternion();
                row.extend([t.x, t.y, t.z, q.w, q.i, q.j, q.k].map(text));
            }
            Observation::Position(p) => row.extend((p / length).iter().map(|v| text(*v))),
            // Contacts have no tracker columns: they are written to a contacts CSV.
            Observation::Contact(_) => {}
        }
        if payloads {
            row.push(m.payload.map(text).unwrap_or_default());
        }
        if sessions {
            row.push(m.session.clone().unwrap_or_default());
        }
        rows.push(row);
    }
    let body = super::super::csv_text(&rows, "measurement CSV")?;
    if options.length_unit == LengthUnit::Metre && options.angle_unit == AngleUnit::Radian {
        Ok(body)
    } else {
        let units = MeasurementUnits {
            length: options.length_unit,
            angle: options.angle_unit,
            joint_length: options.length_unit,
            rotation: options.angle_unit,
        };
        Ok(format!("{}\n{body}", StatedUnits::line_for(&units)))
    }
}
