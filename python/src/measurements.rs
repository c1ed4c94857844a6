//! Measurements from Python: a CSV path or the plain-list payload of `treecal.Measurements`.

use crate::calibrate::parse_unit;
use crate::invalid;
use pyo3::prelude::*;
use std::path::PathBuf;
use treecal::io::{MeasurementTable, ObservationRows};
use treecal::workflow::MeasurementSource;

/// `treecal.Measurements._payload()`: plain lists, checked by the library.
#[derive(FromPyObject)]
#[pyo3(from_item_all)]
pub struct TablePayload {
    origin: String,
    ids: Option<Vec<String>>,
    tools: Vec<String>,
    joint_names: Vec<String>,
    joints: Vec<Vec<f64>>,
    kind: String,
    observations: Vec<Vec<f64>>,
    stages: Option<Vec<String>>,
    sessions: Option<Vec<String>>,
    points: Option<Vec<String>>,
    length_unit: Option<String>,
    angle_unit: Option<String>,
}

/// What `measurements=` / `validation=` hold once the Python layer has looked at them.
// Short-lived (one per call, converted at once), so the size difference does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(FromPyObject)]
pub enum SourceArg {
    /// A measurement CSV.
    Csv(PathBuf),
    /// Several measurement CSVs (each its own session).
    Files(Vec<PathBuf>),
    /// Arrays.
    Table(TablePayload),
}

/// The library's measurement source for `arg`.
pub fn measurement_source(arg: SourceArg) -> PyResult<MeasurementSource> {
    match arg {
        SourceArg::Csv(path) => Ok(MeasurementSource::Csv(path)),
        SourceArg::Files(paths) => Ok(MeasurementSource::from_paths(paths)),
        SourceArg::Table(payload) => Ok(MeasurementSource::Table(table(payload)?)),
    }
}

fn table(p: TablePayload) -> PyResult<MeasurementTable> {
    let observations = match p.kind.as_str() {
        "positions" => ObservationRows::Positions(fixed(&p.observations, &p.origin)?),
        "poses" => ObservationRows::Poses(fixed(&p.observations, &p.origin)?),
        "targets" => ObservationRows::ThreeTargets(fixed(&p.observations, &p.origin)?),
        other => {
            return Err(invalid(format!(
                "{}: unknown observation kind '{other}'",
                p.origin
            )))
        }
    };
    Ok(MeasurementTable {
        length_unit: parse_unit(p.length_unit.as_deref())?,
        angle_unit: parse_unit(p.angle_unit.as_deref())?,
        origin: p.origin,
        ids: p.ids,
        tools: p.tools,
        joint_names: p.joint_names,
        joints: p.joints,
        observations,
        stages: p.stages,
        sessions: p.sessions,
        points: p.points,
    })
}

/// Rows of exactly `N` values.
fn fixed<const N: usize>(rows: &[Vec<f64>], origin: &str) -> PyResult<Vec<[f64; N]>> {
    rows.iter()
        .enumerate()
        .map(|(i, row)| {
            <[f64; N]>::try_from(row.as_slice()).map_err(|_| {
                invalid(format!(
                    "{origin}: observation row {}: {} values, expected {N}",
                    i + 1,
                    row.len()
                ))
            })
        })
        .collect()
}
