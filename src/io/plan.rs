//! Calibration plan files (YAML): the stages of a custom plan.
//!
//! ```yaml
//! stages:
//!   - name: torso
//!     parameters: coupled      # coupled | arms | all
//!     measurements: torso      # rows whose `stage` column says this; omit for all rows
//!   - name: arms
//!     parameters: arms
//!     measurements: arms
//! ```

use super::yaml::parse_yaml;
use crate::calibration::Plan;
use crate::error::{Error, Result};
use crate::limits::{check_count, MAX_PLAN_STAGES};
use std::path::Path;

/// Parses a plan; `origin` names the file in messages.
///
/// Unknown keys are errors naming the closest valid one (a misspelt `measurements` would
/// otherwise make a stage use every row), and a plan has at most [`MAX_PLAN_STAGES`] stages.
pub fn parse_plan(text: &str, origin: &str) -> Result<Plan> {
    let plan: Plan = parse_yaml(
        text,
        origin,
        "; not a calibration plan: see docs/file-formats.md for the layout",
    )?;
    if plan.stages.is_empty() {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: "the plan has no stages".into(),
        });
    }
    check_count(plan.stages.len(), MAX_PLAN_STAGES, origin, "stages")?;
    Ok(plan)
}

/// Reads a plan file.
pub fn read_plan(path: &Path) -> Result<Plan> {
    let text = crate::limits::read_text(path, crate::limits::MAX_YAML_BYTES)?;
    parse_plan(&text, &path.display().to_string())
}
