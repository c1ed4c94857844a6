//! `treecal.fk`: `treecal::workflow::fk` with plain Python arguments.

use crate::calibrate::parse_unit;
use crate::to_py;
use pyo3::prelude::*;
use std::path::PathBuf;
use treecal::workflow::{FkConfig, RobotSource};

/// `root_from_tip` of `tip` for each row of `joints` (columns named by `joint_names`), as
/// row-major 4×4 matrices flattened to 16 values.
#[pyfunction]
#[pyo3(signature = (robot, tip, joint_names, joints, angle_unit = "rad", first_row = 0))]
pub fn fk(
    py: Python<'_>,
    robot: Option<PathBuf>,
    tip: String,
    joint_names: Vec<String>,
    joints: Vec<Vec<f64>>,
    angle_unit: &str,
    first_row: usize,
) -> PyResult<Vec<Vec<f64>>> {
    let config = FkConfig {
        robot: RobotSource::from_path(robot),
        tip,
        joint_names,
        joints,
        angle_unit: parse_unit(Some(angle_unit))?.unwrap_or_default(),
        first_row,
    };
    let poses = py
        .detach(|| treecal::workflow::fk(&config))
        .map_err(to_py)?;
    Ok(poses
        .iter()
        .map(|pose| {
            let m = pose.to_homogeneous();
            (0..4)
                .flat_map(|i| (0..4).map(move |j| m[(i, j)]))
                .collect()
        })
        .collect())
}
