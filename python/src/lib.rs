//! `treecal._treecal`: the Rust half of the Python package `treecal`.
//!
//! Thin: each function turns plain Python values (str, float lists, dicts) into a
//! `treecal::workflow` config, calls the one library function, and hands back plain values;
//! numpy and JSON decoding live in `python/treecal/__init__.py`. Every `treecal::Error`
//! becomes `treecal.TreecalError` with the message the CLI prints after `treecal: error:`.

#![forbid(unsafe_code)]

mod calibrate;
mod fk;
mod measurements;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

pyo3::create_exception!(
    treecal,
    TreecalError,
    PyValueError,
    "An error of treecal: bad input (a file, row, joint or link named in the message) or a \
     calibration that cannot run. The message is the CLI's `treecal: error:` text."
);

/// The Python exception carrying `error`'s message.
pub(crate) fn to_py(error: treecal::Error) -> PyErr {
    TreecalError::new_err(error.to_string())
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
    Ok(())
}
