//! Reading and writing data files (YAML, CSV): the only users of serde_yaml and csv.

pub mod joints_csv;
pub mod mcpc_table;
pub mod write;

pub use joints_csv::{append_poses, configurations, parse_csv, ColumnMapping, CsvTable};
pub use mcpc_table::{parse_mcpc_table, read_mcpc_table};
pub use write::write_atomically;
