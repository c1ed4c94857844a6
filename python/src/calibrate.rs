//! `treecal.calibrate`: `treecal::workflow::calibrate` with plain Python arguments.

use crate::measurements::{measurement_source, SourceArg};
use crate::{invalid, to_py};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::{Path, PathBuf};
use treecal::calibration::RobustLoss;
use treecal::workflow::{
    CalibrateConfig, Calibration, GravityFrame, MeasurementFrameChoice, ModelChoice, ModelLevel,
    ParameterPatterns, PlanSource, RobotSource, StiffnessSource,
};

/// The outcome of a calibration; `treecal.Calibration` wraps it.
#[pyclass(module = "treecal._treecal", name = "Calibration", frozen)]
pub struct PyCalibration {
    inner: Calibration,
}

#[pymethods]
impl PyCalibration {
    /// The verdict (status and reasons) as JSON.
    #[getter]
    fn verdict_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner.verdict).map_err(|e| invalid(e.to_string()))
    }

    /// The parameter rows as JSON.
    #[getter]
    fn parameters_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner.parameters).map_err(|e| invalid(e.to_string()))
    }

    /// report.json's content.
    #[getter]
    fn report_json(&self) -> PyResult<String> {
        let bytes = self
            .inner
            .files
            .iter()
            .find(|(name, _)| name == "report.json")
            .map_or(&[][..], |(_, bytes)| bytes.as_slice());
        String::from_utf8(bytes.to_vec()).map_err(|e| invalid(e.to_string()))
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

    /// Writes every output file into `out` (like `treecal calibrate --out`); refuses a folder
    /// holding an input.
    fn write(&self, py: Python<'_>, out: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write(&out)).map_err(to_py)
    }

    /// Writes calibrated.urdf to `path` (atomically); refuses an input's path.
    fn write_urdf(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write_urdf(&path)).map_err(to_py)
    }
}

/// Runs `treecal::workflow::calibrate`; arguments as `treecal.calibrate` documents them.
#[pyfunction]
#[pyo3(signature = (*, robot, measurements, validation, length_unit, angle_unit,
    joint_length_unit, stiffness, tools, reference_link, plan, seed, robust, identify_stiffness, stiffness_prior,
    measurement_frame, gravity_frame, position_sigma, rotation_sigma, ignore_columns, strict,
    add_tool_links, model, prior, prior_scale, cv, freeze, free))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate(
    py: Python<'_>,
    robot: Option<PathBuf>,
    measurements: SourceArg,
    validation: Option<SourceArg>,
    length_unit: Option<String>,
    angle_unit: Option<String>,
    joint_length_unit: Option<String>,
    stiffness: Option<PathBuf>,
    tools: Option<Vec<String>>,
    reference_link: Option<String>,
    plan: Option<String>,
    seed: u64,
    robust: &str,
    identify_stiffness: bool,
    stiffness_prior: Option<f64>,
    measurement_frame: String,
    gravity_frame: &str,
    position_sigma: Option<f64>,
    rotation_sigma: Option<f64>,
    ignore_columns: Vec<String>,
    strict: bool,
    add_tool_links: bool,
    model: &str,
    prior: bool,
    prior_scale: f64,
    cv: Option<usize>,
    freeze: Vec<String>,
    free: Vec<String>,
) -> PyResult<PyCalibration> {
    let defaults = CalibrateConfig::default();
    let config = CalibrateConfig {
        robot: RobotSource::from_path(robot),
        measurements: measurement_source(measurements)?,
        validation: validation.map(measurement_source).transpose()?,
        stiffness: stiffness.map(StiffnessSource::File),
        tools,
        reference_link,
        plan: plan_source(plan.as_deref()),
        length_unit: parse_unit(length_unit.as_deref())?,
        angle_unit: parse_unit(angle_unit.as_deref())?,
        joint_length_unit: parse_unit(joint_length_unit.as_deref())?,
        ignore_columns,
        strict,
        measurement_frame: frame_choice(&measurement_frame),
        position_sigma: position_sigma.unwrap_or(defaults.position_sigma),
        rotation_sigma: rotation_sigma.unwrap_or(defaults.rotation_sigma),
        seed,
        robust: robust_loss(robust)?,
        identify_stiffness,
        stiffness_prior: stiffness_prior.unwrap_or(defaults.stiffness_prior),
        gravity_frame: gravity(gravity_frame)?,
        add_tool_links,
        model: model_choice(model)?,
        prior,
        prior_scale,
        cv,
        patterns: ParameterPatterns { freeze, free },
        ..defaults
    };
    let inner = py
        .detach(|| treecal::workflow::calibrate(&config))
        .map_err(to_py)?;
    Ok(PyCalibration { inner })
}

/// `model` as the CLI's `--model` takes it: "adaptive", "offsets", "geometry" or "auto".
pub(crate) fn model_choice(text: &str) -> PyResult<ModelChoice> {
    match text {
        "adaptive" => Ok(ModelChoice::Adaptive),
        "offsets" => Ok(ModelChoice::Level(ModelLevel::Offsets)),
        "geometry" => Ok(ModelChoice::Level(ModelLevel::Geometry)),
        "auto" => Ok(ModelChoice::Auto),
        other => Err(invalid(format!(
            "model '{other}' is not a model; give adaptive, offsets, geometry or auto"
        ))),
    }
}

/// A unit given as text ("m", "mm", "rad", "deg"), parsed by the library's own parser.
pub(crate) fn parse_unit<T>(text: Option<&str>) -> PyResult<Option<T>>
where
    T: std::str::FromStr<Err = treecal::Error>,
{
    text.map(str::parse).transpose().map_err(to_py)
}

fn plan_source(plan: Option<&str>) -> PlanSource {
    match plan {
        None | Some("auto") => PlanSource::Auto,
        Some("staged") => PlanSource::Staged,
        Some("simultaneous") => PlanSource::Simultaneous,
        Some(path) => PlanSource::File(Path::new(path).to_path_buf()),
    }
}

pub(crate) fn frame_choice(text: &str) -> MeasurementFrameChoice {
    match text {
        "auto" => MeasurementFrameChoice::Auto,
        "fit" => MeasurementFrameChoice::Fit,
        "base" => MeasurementFrameChoice::Base,
        path => MeasurementFrameChoice::File(PathBuf::from(path)),
    }
}

fn robust_loss(text: &str) -> PyResult<RobustLoss> {
    match text {
        "huber" => Ok(RobustLoss::Huber),
        "cauchy" => Ok(RobustLoss::Cauchy),
        "off" => Ok(RobustLoss::Off),
        other => Err(invalid(format!(
            "robust '{other}': use 'huber', 'cauchy' or 'off'"
        ))),
    }
}

fn gravity(text: &str) -> PyResult<GravityFrame> {
    match text {
        "measurement" => Ok(GravityFrame::Measurement),
        "base" => Ok(GravityFrame::Base),
        other => Err(invalid(format!(
            "gravity_frame '{other}': use 'measurement' or 'base'"
        ))),
    }
}
