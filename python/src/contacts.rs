//! `treecal.calibrate(contacts=…, contact_setup=…)`: `treecal::workflow::calibrate_contacts` with
//! plain Python arguments (the contacts CSV, the setup YAML, optional held-out contacts and
//! tracker rows).

use crate::{invalid, to_py};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::PathBuf;
use treecal::workflow::{
    calibrate_contacts, ContactCalibrateConfig, ContactCalibration, RobotSource,
};

/// Why `calibrate --contacts` writes no URDF (the CLI's words).
const NOT_BETTER: &str = "the calibrated robot does not predict the held-out contacts better than the registered nominal robot";

/// The outcome of a calibration from contacts; `treecal.Calibration` wraps it.
#[pyclass(module = "treecal._treecal", name = "ContactCalibration", frozen)]
pub struct PyContactCalibration {
    inner: ContactCalibration,
}

#[pymethods]
impl PyContactCalibration {
    /// The verdict as JSON: ok when the calibrated robot predicts the held-out contacts better
    /// than the registered nominal robot (calibrated.urdf written), else failed with the reason.
    #[getter]
    fn verdict_json(&self) -> String {
        let reasons = if self.inner.usable() {
            serde_json::json!([])
        } else {
            match &self.inner.refused {
                Some(reason) => {
                    serde_json::json!([{"status": "failed", "code": "contacts-scale", "message": reason}])
                }
                None => {
                    serde_json::json!([{"status": "failed", "code": "contacts-not-better", "message": NOT_BETTER}])
                }
            }
        };
        let status = if self.inner.usable() { "ok" } else { "failed" };
        serde_json::json!({"status": status, "reasons": reasons}).to_string()
    }

    /// The robot's parameters (name, value) as JSON.
    #[getter]
    fn parameters_json(&self) -> String {
        self.inner.report_json["parameters"].to_string()
    }

    /// report.json's content.
    #[getter]
    fn report_json(&self) -> String {
        self.inner.report_json.to_string()
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
        let mut files = vec![
            ("report.md".to_owned(), self.inner.report_markdown.clone()),
            ("report.json".to_owned(), self.inner.report_json.to_string()),
        ];
        if let Some(urdf) = &self.inner.urdf {
            files.push(("calibrated.urdf".to_owned(), urdf.clone()));
        }
        files
            .into_iter()
            .map(|(name, text)| (name, PyBytes::new(py, text.as_bytes())))
            .collect()
    }

    /// Writes every output file into `out` (like `treecal calibrate --contacts … --out`).
    fn write(&self, py: Python<'_>, out: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write(&out)).map_err(to_py)
    }

    /// Writes calibrated.urdf to `path` (atomically).
    fn write_urdf(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let Some(urdf) = self.inner.urdf.clone() else {
            return Err(invalid(format!("no calibrated URDF: {NOT_BETTER}")));
        };
        py.detach(|| treecal::io::write_atomically(&path, urdf.as_bytes()))
            .map_err(to_py)
    }
}

/// Runs `treecal::workflow::calibrate_contacts`; arguments as `treecal.calibrate` documents
/// them.
#[pyfunction]
#[pyo3(signature = (*, robot, contacts, contact_setup, validation, reference_link, measurements,
    position_sigma, rotation_sigma, measurement_frame, length_unit, ignore_columns, model, prior,
    prior_scale, cv, seed, freeze, free, tools=None))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate_contacts_files(
    py: Python<'_>,
    robot: Option<PathBuf>,
    contacts: PathBuf,
    contact_setup: PathBuf,
    validation: Option<PathBuf>,
    reference_link: Option<String>,
    measurements: Option<PathBuf>,
    position_sigma: Option<f64>,
    rotation_sigma: Option<f64>,
    measurement_frame: String,
    length_unit: Option<String>,
    ignore_columns: Vec<String>,
    model: &str,
    prior: bool,
    prior_scale: f64,
    cv: Option<usize>,
    seed: u64,
    freeze: Vec<String>,
    free: Vec<String>,
    tools: Option<Vec<String>>,
) -> PyResult<PyContactCalibration> {
    let length_unit: Option<treecal::io::LengthUnit> =
        crate::calibrate::parse_unit(length_unit.as_deref())?;
    let tracker = measurements.map(|path| {
        crate::camera::tracker_input(
            path,
            position_sigma,
            rotation_sigma,
            &measurement_frame,
            length_unit,
            ignore_columns,
        )
    });
    let config = ContactCalibrateConfig {
        robot: RobotSource::from_path(robot),
        contacts,
        setup: contact_setup,
        validation,
        reference_link,
        tools,
        tracker,
        model: crate::calibrate::model_choice(model)?,
        prior: prior.then_some(prior_scale),
        cv,
        seed,
        patterns: treecal::workflow::ParameterPatterns { freeze, free },
        ..ContactCalibrateConfig::default()
    };
    let inner = py.detach(|| calibrate_contacts(&config)).map_err(to_py)?;
    Ok(PyContactCalibration { inner })
}
