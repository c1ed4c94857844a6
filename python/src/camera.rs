//! `treecal.calibrate(camera=…, detections=…)`: `treecal::workflow::calibrate_camera` with plain
//! Python arguments (the camera file, the detections as a CSV path or CSV text, optional tracker
//! rows).

use crate::calibrate::{frame_choice, parse_unit};
use crate::{invalid, to_py};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::PathBuf;
use treecal::workflow::RobotSource;
use treecal::workflow::{
    calibrate_camera_files, CameraCalibrateConfig, CameraCalibration, CameraTrackerInput,
    DetectionsSource,
};

/// The outcome of a camera calibration; `treecal.Calibration` wraps it.
#[pyclass(module = "treecal._treecal", name = "CameraCalibration", frozen)]
pub struct PyCameraCalibration {
    inner: CameraCalibration,
}

#[pymethods]
impl PyCameraCalibration {
    /// The verdict (status and reasons) as JSON.
    #[getter]
    fn verdict_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner.verdict).map_err(|e| invalid(e.to_string()))
    }

    /// The robot's parameter rows (name, nominal, calibrated, std_dev, determined) as JSON.
    #[getter]
    fn parameters_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner.report.robot_parameters)
            .map_err(|e| invalid(e.to_string()))
    }

    /// report.json's content.
    #[getter]
    fn report_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner.report).map_err(|e| invalid(e.to_string()))
    }

    /// report.md.
    #[getter]
    fn markdown(&self) -> &str {
        &self.inner.report_markdown
    }

    /// calibrated.urdf, or None.
    #[getter]
    fn urdf(&self) -> Option<&str> {
        self.inner.urdf.as_deref()
    }

    /// What the CLI prints on stderr: (level, text).
    #[getter]
    fn notes(&self) -> Vec<(String, String)> {
        self.inner
            .notes
            .iter()
            .map(|n| (n.level.as_str().to_owned(), n.text.clone()))
            .collect()
    }

    /// Every output file: (name, bytes).
    fn files<'py>(&self, py: Python<'py>) -> Vec<(String, Bound<'py, PyBytes>)> {
        self.inner
            .files
            .iter()
            .map(|(name, bytes)| (name.clone(), PyBytes::new(py, bytes)))
            .collect()
    }

    /// Writes every output file into `out` (like `treecal calibrate --camera … --out`).
    fn write(&self, py: Python<'_>, out: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write(&out)).map_err(to_py)
    }

    /// Writes calibrated.urdf to `path` (atomically).
    fn write_urdf(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let Some(urdf) = self.inner.urdf.clone() else {
            return Err(invalid(format!(
                "no calibrated URDF: the verdict is {}",
                self.inner.verdict.status
            )));
        };
        py.detach(|| treecal::io::write_atomically(&path, urdf.as_bytes()))
            .map_err(to_py)
    }
}

/// Tracker rows fitted with pixels or contacts: the measurement CSV `path` with its σ's (the
/// CLI's defaults when `None`) and its frame (`auto`, `fit`, `base` or a registration path).
pub(crate) fn tracker_input(
    path: PathBuf,
    position_sigma: Option<f64>,
    rotation_sigma: Option<f64>,
    measurement_frame: &str,
    length_unit: Option<treecal::io::LengthUnit>,
    ignore_columns: Vec<String>,
) -> CameraTrackerInput {
    CameraTrackerInput {
        measurements: path,
        position_sigma: position_sigma.unwrap_or(treecal::calibration::DEFAULT_POSITION_SIGMA),
        rotation_sigma: rotation_sigma.unwrap_or(treecal::calibration::DEFAULT_ROTATION_SIGMA),
        frame: frame_choice(measurement_frame),
        length_unit,
        ignore_columns,
    }
}

/// Runs `treecal::workflow::calibrate_camera_files`; arguments as
/// `treecal.calibrate` documents them (`detections`: a CSV path; `detections_csv`: CSV text).
#[pyfunction]
#[pyo3(signature = (*, robot, camera, detections, detections_csv, validation, measurements,
    pixel_sigma, position_sigma, rotation_sigma, measurement_frame, length_unit, angle_unit,
    joint_length_unit, tools, ignore_columns, add_tool_links))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate_camera(
    py: Python<'_>,
    robot: Option<PathBuf>,
    camera: PathBuf,
    detections: Option<PathBuf>,
    detections_csv: Option<String>,
    validation: Option<PathBuf>,
    measurements: Option<PathBuf>,
    pixel_sigma: f64,
    position_sigma: Option<f64>,
    rotation_sigma: Option<f64>,
    measurement_frame: String,
    length_unit: Option<String>,
    angle_unit: Option<String>,
    joint_length_unit: Option<String>,
    tools: Option<Vec<String>>,
    ignore_columns: Vec<String>,
    add_tool_links: bool,
) -> PyResult<PyCameraCalibration> {
    let detections = match (detections, detections_csv) {
        (Some(path), None) => DetectionsSource::File(path),
        (None, Some(text)) => DetectionsSource::Csv {
            text,
            origin: "detections".into(),
        },
        _ => {
            return Err(invalid(
                "give detections as a CSV path or as rows, not both",
            ))
        }
    };
    let length: Option<treecal::io::LengthUnit> = parse_unit(length_unit.as_deref())?;
    let joint_length: Option<treecal::io::LengthUnit> = parse_unit(joint_length_unit.as_deref())?;
    let tracker = measurements.map(|path| {
        tracker_input(
            path,
            position_sigma,
            rotation_sigma,
            &measurement_frame,
            length,
            ignore_columns,
        )
    });
    let config = CameraCalibrateConfig {
        robot: RobotSource::from_path(robot),
        tools,
        camera_file: camera,
        detections,
        validation,
        pixel_sigma,
        tracker,
        contacts: None,
        angle_unit: parse_unit(angle_unit.as_deref())?,
        length_unit: joint_length.or(length),
        add_tool_links,
    };
    let inner = py
        .detach(|| calibrate_camera_files(&config))
        .map_err(to_py)?;
    Ok(PyCameraCalibration { inner })
}
