//! Reading and writing data files (YAML, CSV): the only users of serde_yaml and csv.

pub mod joints_csv;
pub mod mcpc_table;
pub mod measurements_csv;
pub mod stiffness;
pub mod write;

pub use joints_csv::{append_poses, configurations, parse_csv, ColumnMapping, CsvTable};
pub use mcpc_table::{mcpc_table_to_yaml, parse_mcpc_table, read_mcpc_table};
pub use measurements_csv::measurements_to_csv;
pub use stiffness::{parse_stiffness, read_stiffness};
pub use write::write_atomically;

use crate::error::{Error, Result};

/// Serialises a report as YAML.
pub fn to_yaml<T: serde::Serialize>(value: &T) -> Result<String> {
    serde_yaml::to_string(value).map_err(|e| Error::InvalidData {
        origin: "YAML output".into(),
        message: e.to_string(),
    })
}

/// Serialises a report as pretty-printed JSON with a final newline.
pub fn to_json<T: serde::Serialize>(value: &T) -> Result<String> {
    serde_json::to_string_pretty(value)
        .map(|s| s + "\n")
        .map_err(|e| Error::InvalidData {
            origin: "JSON output".into(),
            message: e.to_string(),
        })
}
