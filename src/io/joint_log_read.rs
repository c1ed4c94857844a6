//! A joint log read from a file of either format: MCAP (by its magic bytes) or CSV.

use super::bounded::read_text;
use super::joint_log::{parse_joint_log_csv, JointLog, JointLogOptions};
use crate::error::Result;
use crate::limits::MAX_CSV_BYTES;
use std::path::Path;

/// Reads a joint log: an MCAP file (by its magic bytes) or a CSV.
pub fn read_joint_log(path: &Path, options: &JointLogOptions) -> Result<JointLog> {
    if super::joint_log_mcap::is_mcap(path)? {
        return super::joint_log_mcap::read_joint_log_mcap(path, options.topic.as_deref());
    }
    let text = read_text(path, MAX_CSV_BYTES)?;
    parse_joint_log_csv(&text, &path.display().to_string(), options)
}
