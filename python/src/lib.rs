//! `treecal._treecal`: the Rust half of the Python package `treecal`.
//!
//! Thin: each function turns plain Python values (str, float lists, dicts) into a
//! `treecal::workflow` config, calls the one library function, and hands back plain values;
//! numpy and JSON decoding live in `python/treecal/__init__.py`. Every `treecal::Error`
//! becomes `treecal.TreecalError` with the message the CLI prints after `treecal: error:`.

#![forbid(unsafe_code)]

mod calibrate;
mod camera;
mod contacts;
mod fk;
mod measurements;
mod trust;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

pyo3::create_exception!(
    treecal,
    TreecalError,
    PyValueError,
    "An error of treecal: bad input (a file, row, joint or link named in the message) or a \
     calibration that cannot run. The message is the CLI's `treecal: error:` text."
);

/// The Python exception carrying `error`'s message, with the settings it names spelled as this
/// package's keyword arguments.
pub(crate) fn to_py(error: treecal::Error) -> PyErr {
    TreecalError::new_err(python_names(&error.to_string()))
}

/// The one table from the library's settings (snake_case, named in backticks in its messages)
/// to the keyword arguments that set them (of `calibrate`, `fk`, `Measurements` and
/// `Calibration.write`).
const KEYWORDS: &[(&str, &str)] = &[
    ("add_tool_links", "add_tool_links"),
    ("angle_unit", "angle_unit"),
    ("calibration", "calibration"),
    ("camera", "camera"),
    ("contact_setup", "contact_setup"),
    ("contacts", "contacts"),
    ("detections", "detections"),
    ("frame", "frame"),
    ("gravity_frame", "gravity_frame"),
    ("identify_stiffness", "identify_stiffness"),
    ("ignore_columns", "ignore_columns"),
    ("joint_length_unit", "joint_length_unit"),
    ("joints", "joints"),
    ("length_unit", "length_unit"),
    ("max_error", "max_error"),
    ("measurement_frame", "measurement_frame"),
    ("measurements", "measurements"),
    ("out", "out_dir"),
    ("pixel_sigma", "pixel_sigma"),
    ("plan", "plan"),
    ("plan_file", "plan"),
    ("position_sigma", "position_sigma"),
    ("reference_link", "reference_link"),
    ("registration", "registration"),
    ("robot", "robot"),
    ("robust", "robust"),
    ("rotation_sigma", "rotation_sigma"),
    ("seed", "seed"),
    ("stiffness", "stiffness"),
    ("stiffness_prior", "stiffness_prior"),
    ("strict", "strict"),
    ("tip", "tip"),
    ("tools", "tools"),
    ("validation", "validation"),
];

/// The keyword argument that sets `setting`, if the binding offers one.
fn keyword(setting: &str) -> Option<&'static str> {
    KEYWORDS
        .iter()
        .find(|(s, _)| *s == setting)
        .map(|(_, keyword)| *keyword)
}

/// `message` with each setting of [`KEYWORDS`] named in backticks, or as a CLI flag in the
/// messages that still name one (`--length-unit`), replaced by its keyword argument; others
/// are left as they are.
fn python_names(message: &str) -> String {
    let named = treecal::error::name_settings(message, |s| keyword(s).map(str::to_owned));
    let mut out = String::with_capacity(named.len());
    let mut rest = named.as_str();
    while let Some(start) = rest.find("--") {
        out.push_str(&rest[..start]);
        let after = &rest[start + 2..];
        let end = after
            .find(|c: char| !(c.is_ascii_lowercase() || c == '-'))
            .unwrap_or(after.len());
        let flag = after[..end].trim_end_matches('-');
        match keyword(&flag.replace('-', "_")) {
            Some(keyword) if !flag.is_empty() => {
                out.push_str(keyword);
                rest = &after[flag.len()..];
            }
            _ => {
                out.push_str("--");
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// A `TreecalError` with a message of the binding's own (bad argument values).
pub(crate) fn invalid(message: impl Into<String>) -> PyErr {
    TreecalError::new_err(message.into())
}

#[pymodule]
fn _treecal(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("TreecalError", m.py().get_type::<TreecalError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(fk::fk, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::calibrate, m)?)?;
    m.add_class::<calibrate::PyCalibration>()?;
    m.add_function(wrap_pyfunction!(camera::calibrate_camera, m)?)?;
    m.add_class::<camera::PyCameraCalibration>()?;
    m.add_function(wrap_pyfunction!(contacts::calibrate_contacts_files, m)?)?;
    m.add_class::<contacts::PyContactCalibration>()?;
    m.add_function(wrap_pyfunction!(trust::verify, m)?)?;
    m.add_function(wrap_pyfunction!(trust::compare, m)?)?;
    Ok(())
}
