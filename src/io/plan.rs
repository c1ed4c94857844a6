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

use crate::calibration::Plan;
use crate::error::{Error, Result};
use std::path::Path;

/// Parses a plan; `origin` names the file in messages.
pub fn parse_plan(text: &str, origin: &str) -> Result<Plan> {
    crate::limits::check_yaml_depth(text, origin)?;
    let plan: Plan = serde_yaml::from_str(text).map_err(|e| Error::InvalidData {
        origin: match e.location() {
            Some(l) => format!("{origin}:{}:{}", l.line(), l.column()),
            None => origin.to_owned(),
        },
        message: format!("not a calibration plan ({e}); see docs/file-formats.md for the layout"),
    })?;
    if plan.stages.is_empty() {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: "the plan has no stages".into(),
        });
    }
    Ok(plan)
}

/// Reads a plan file.
pub fn read_plan(path: &Path) -> Result<Plan> {
    let text = crate::limits::read_text(path, crate::limits::MAX_YAML_BYTES)?;
    parse_plan(&text, &path.display().to_string())
}
