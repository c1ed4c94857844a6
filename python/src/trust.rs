//! `treecal.verify` and `treecal.compare`: `treecal::workflow::verify` and
//! `treecal::workflow::compare` with plain Python arguments.

use crate::calibrate::parse_unit;
use crate::measurements::{measurement_source, SourceArg};
use crate::{invalid, to_py};
use pyo3::prelude::*;
use std::path::PathBuf;
use treecal::workflow::CompareConfig;
use treecal::workflow::{GravityFrame, StiffnessSource, VerifyConfig, VerifyFrame};

/// Runs `treecal::workflow::verify`; writes the files into `out_dir` when given. Returns
/// `(report.json text, report.md, passed)`.
#[pyfunction]
#[pyo3(signature = (*, measurements, calibration, robot, registration, stiffness, frame,
    max_error, tools, length_unit, angle_unit, joint_length_unit, gravity_frame, out_dir))]
#[allow(clippy::too_many_arguments)]
pub fn verify(
    py: Python<'_>,
    measurements: SourceArg,
    calibration: Option<PathBuf>,
    robot: Option<PathBuf>,
    registration: Option<PathBuf>,
    stiffness: Option<PathBuf>,
    frame: &str,
    max_error: Option<f64>,
    tools: Option<Vec<String>>,
    length_unit: Option<String>,
    angle_unit: Option<String>,
    joint_length_unit: Option<String>,
    gravity_frame: &str,
    out_dir: Option<PathBuf>,
) -> PyResult<(String, String, bool)> {
    let config = VerifyConfig {
        calibration,
        robot,
        registration,
        stiffness: stiffness.map(StiffnessSource::File),
        measurements: measurement_source(measurements)?,
        tools,
        length_unit: parse_unit(length_unit.as_deref())?,
        angle_unit: parse_unit(angle_unit.as_deref())?,
        joint_length_unit: parse_unit(joint_length_unit.as_deref())?,
        frame: match frame {
            "fit" => VerifyFrame::Fit,
            "registration" => VerifyFrame::Registration,
            "base" => VerifyFrame::Base,
            other => {
                return Err(invalid(format!(
                    "frame '{other}': use 'fit', 'registration' or 'base'"
                )))
            }
        },
        gravity_frame: match gravity_frame {
            "measurement" => GravityFrame::Measurement,
            "base" => GravityFrame::Base,
            other => {
                return Err(invalid(format!(
                    "gravity_frame '{other}': use 'measurement' or 'base'"
                )))
            }
        },
        max_error_mm: max_error,
        ..VerifyConfig::default()
    };
    let verification = py
        .detach(|| {
            let verification = treecal::workflow::verify(&config)?;
            if let Some(out) = &out_dir {
                verification.write(out)?;
            }
            Ok::<_, treecal::Error>(verification)
        })
        .map_err(to_py)?;
    let json = serde_json::to_string(&verification.report).map_err(|e| invalid(e.to_string()))?;
    Ok((json, verification.markdown.clone(), verification.passed()))
}

/// Runs `treecal::workflow::compare`; writes the files into `out_dir` when given.
/// Returns `(report.json text, report.md)`.
#[pyfunction]
#[pyo3(signature = (a, b, *, k, out_dir))]
pub fn compare(
    py: Python<'_>,
    a: PathBuf,
    b: PathBuf,
    k: f64,
    out_dir: Option<PathBuf>,
) -> PyResult<(String, String)> {
    let config = CompareConfig { a, b, k };
    let comparison = py
        .detach(|| {
            let comparison = treecal::workflow::compare(&config)?;
            if let Some(out) = &out_dir {
                comparison.write(out)?;
            }
            Ok::<_, treecal::Error>(comparison)
        })
        .map_err(to_py)?;
    let json = serde_json::to_string(&comparison.report).map_err(|e| invalid(e.to_string()))?;
    Ok((json, comparison.markdown.clone()))
}
