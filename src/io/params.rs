//! Calibrated MCPC parameter values (YAML), as `treecal export` reads them.
//!
//! ```yaml
//! parameters:
//!   - name: left_joint1 alpha      # McpcModel::parameter_name
//!     calibrated: 1.5712           # SI: rad for alpha/beta/gamma, m for x/y/z
//!   - name: left_tool z
//!     calibrated: 0.1451
//! ```
//!
//! The other keys the calibration writes (of the file: `robot`, `units`,
//! `measurement_frame`, `stiffness`; of an entry: `owner`, `kind`, `unit`, `nominal`,
//! `change`, `identifiable`) are read and ignored, so its `params.yaml` reads as is; any other
//! key is an error naming the closest valid one.
//! Unknown names are errors; parameters the file does not list keep their nominal value,
//! with a warning. See `docs/file-formats.md`.

use crate::error::{did_you_mean, Error, Result};
use crate::kinematics::McpcModel;
use crate::limits::{magnitude_problem, Quantity};
use crate::tree::KinematicTree;
use serde::de::IgnoredAny;
use std::collections::HashMap;
use std::path::Path;

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    parameters: Vec<Entry>,
    #[serde(default, rename = "robot")]
    _robot: Option<IgnoredAny>,
    #[serde(default, rename = "units")]
    _units: Option<IgnoredAny>,
    #[serde(default, rename = "measurement_frame")]
    _measurement_frame: Option<IgnoredAny>,
    #[serde(default, rename = "stiffness")]
    _stiffness: Option<IgnoredAny>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    name: String,
    calibrated: f64,
    /// The calibration's standard deviation (SI), as `params.yaml` gives it.
    #[serde(default)]
    std_dev: Option<f64>,
    #[serde(default, rename = "owner")]
    _owner: Option<IgnoredAny>,
    #[serde(default, rename = "kind")]
    _kind: Option<IgnoredAny>,
    #[serde(default, rename = "unit")]
    _unit: Option<IgnoredAny>,
    #[serde(default, rename = "nominal")]
    _nominal: Option<IgnoredAny>,
    #[serde(default, rename = "change")]
    _change: Option<IgnoredAny>,
    #[serde(default, rename = "identifiable")]
    _identifiable: Option<IgnoredAny>,
}

/// The parameter vector a parameter file gives, and what the user should know about it.
#[derive(Debug, Clone)]
pub struct ParameterValues {
    /// Every MCPC parameter (rad, m) in [`McpcModel::parameter_layout`] order.
    pub values: Vec<f64>,
    /// Parameters the file does not list (they keep their nominal value).
    pub warnings: Vec<String>,
    /// The standard deviation (rad, m) the file gives for each parameter (`std_dev`, as the
    /// calibration writes it), same order; `None` where not given or not a positive number.
    pub std_devs: Vec<Option<f64>>,
}

/// Reads a parameter file for `model` (the nominal model of `tree`).
pub fn read_parameters(
    path: &Path,
    tree: &KinematicTree,
    model: &McpcModel,
) -> Result<ParameterValues> {
    let text = crate::limits::read_text(path, crate::limits::MAX_YAML_BYTES)?;
    parse_parameters(&text, &path.display().to_string(), tree, model)
}

/// Parses a parameter file; `origin` names it in messages, with `:line:column` where known.
pub fn parse_parameters(
    text: &str,
    origin: &str,
    tree: &KinematicTree,
    model: &McpcModel,
) -> Result<ParameterValues> {
    let file: File = super::yaml::parse_yaml(
        text,
        origin,
        "; expected `parameters:` with a list of `name:` and `calibrated:` (SI units)",
    )?;
    // serde_yaml keeps no positions of values, so a bad name is found in the text again.
    let at = |name: &str| match text.find(name) {
        Some(offset) => {
            let before = &text[..offset];
            let line = before.matches('\n').count() + 1;
            let column = before.len() - before.rfind('\n').map_or(0, |n| n + 1) + 1;
            format!("{origin}:{line}:{column}")
        }
        None => origin.to_owned(),
    };
    let names: Vec<String> = (0..model.parameter_count())
        .map(|i| model.parameter_name(tree, i))
        .collect();
    let index: HashMap<&str, usize> = names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let mut values = model.parameters();
    let mut given = vec![false; values.len()];
    let mut std_devs = vec![None; values.len()];
    for (entry_index, entry) in file.parameters.iter().enumerate() {
        let name = entry.name.trim();
        let Some(&i) = index.get(name) else {
            return Err(Error::InvalidData {
                origin: at(name),
                message: format!(
                    "parameters[{entry_index}]: unknown parameter '{name}'{}; names are a joint or tool link and one of alpha, beta, gamma, x, y, z (see `treecal inspect`)",
                    did_you_mean(name, names.iter().map(String::as_str))
                ),
            });
        };
        if given[i] {
            return Err(Error::InvalidData {
                origin: origin.to_owned(),
                message: format!(
                    "parameters[{entry_index}]: '{name}' is given twice; keep one entry"
                ),
            });
        }
        let quantity = if model.parameter_layout()[i].1.is_angle() {
            Quantity::Angle
        } else {
            Quantity::Length
        };
        if let Some(problem) = magnitude_problem(entry.calibrated, quantity) {
            return Err(Error::InvalidData {
                origin: at(name),
                message: format!(
                    "parameters[{entry_index}]: '{name}' has calibrated value {problem}"
                ),
            });
        }
        given[i] = true;
        values[i] = entry.calibrated;
        std_devs[i] = entry.std_dev.filter(|s| s.is_finite() && *s >= 0.0);
    }
    let warnings = names
        .iter()
        .zip(&given)
        .zip(&values)
        .filter(|((_, given), _)| !**given)
        .map(|((name, _), value)| {
            format!(
                "{origin}: parameter '{name}' is not listed; it keeps its nominal value {value}"
            )
        })
        .collect();
    Ok(ParameterValues {
        values,
        warnings,
        std_devs,
    })
}
