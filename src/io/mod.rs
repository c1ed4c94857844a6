//! Reading and writing data files (YAML, CSV, MCAP): the only users of serde_yaml, csv and
//! mcap.

mod bounded;
pub(crate) mod camera_yaml;
mod collada;
pub(crate) mod contacts_csv;
pub(crate) mod contacts_yaml;
mod csv_fields;
mod csv_scan;
pub(crate) mod detections_csv;
mod direct_write;
mod joint_errors;
mod joint_log;
mod joint_log_mcap;
mod joint_log_read;
mod joints_csv;
mod joints_stream;
mod json_rows;
mod mcpc_table;
mod measurement_table;
mod measurements_csv;
mod mesh_files;
mod observations;
mod output_lock;
mod overlay;
mod paired_csv;
mod params;
mod plan;
mod poses_csv;
mod provenance;
mod registration;
mod ros_joint_state;
mod stiffness;
mod stiffness_write;
mod tracker_log;
mod units;
mod write;
mod yaml;

pub use joint_log::MAX_TIME;
pub use joint_log_mcap::{is_mcap, read_joint_log_mcap, JOINT_STATE_SCHEMA, MAX_MCAP_RECORD_BYTES};
pub use measurements_csv::{PAYLOAD_COLUMN, POINT_COLUMN, SESSION_COLUMN};
pub use observations::ROTATION_MATRIX_TOLERANCE;
pub use output_lock::{lock_output, recover, swap_in};
pub use poses_csv::STAGES;
pub use provenance::{
    commit_description, input_file, output_files, recorded_outputs, sha256_hex, utc_iso8601,
    InputFile, OutputFile, Program, ProvenanceRecord, RunFacts, GIT_COMMIT, GIT_DIRTY,
    PROVENANCE_FILE,
};
pub use ros_joint_state::{decode_joint_state, JointStateMessage};
pub use tracker_log::TRACKER_KEYS;

pub use bounded::{read_bytes, read_text};
pub use camera_yaml::{camera_file_yaml, parse_camera_file, read_camera_file, CameraFileContents};
pub use contacts_csv::{
    contacts_to_csv, parse_contacts, read_contacts, ContactKind, ContactRow, ContactTable,
};
pub use contacts_yaml::{
    contact_setup_to_yaml, parse_contact_setup, read_contact_setup, BarSetup, ContactSetup,
    FreeSetup, PoseEntry, SigmaSetup, ToolSetup,
};
pub use csv_fields::CsvTable;
pub use detections_csv::{detections_to_csv, parse_detections, read_detections, DETECTION_COLUMNS};
pub use joint_errors::{parse_joint_errors, JointErrorEntry};
pub use joint_log::{parse_joint_log_csv, read_joint_log, JointLog, JointLogOptions};
pub use joints_csv::{
    append_poses, configurations, joint_value, parse_csv, pose_fields, ColumnMapping, POSE_COLUMNS,
};
pub use joints_stream::{open_csv_records, CsvRecords};
pub use json_rows::{json_at_depth, to_json_rows, write_json_rows, Verbatim};
pub use mcpc_table::{mcpc_table_to_yaml, parse_mcpc_table, read_mcpc_table};
pub use measurement_table::{MeasurementTable, ObservationRows};
pub use measurements_csv::{
    measured_link_name, measured_targets, measured_tool_names, measurements_to_csv,
    measurements_to_csv_with, parse_measurements, read_measured_targets, read_measured_tool_names,
    read_measurements, MeasurementReadOptions, MeasurementSet, MeasurementWriteOptions,
    ObservationKind,
};
pub use mesh_files::{
    mesh_file_loader, mesh_vertices, package_dirs, read_mesh_vertices, resolve_mesh,
};
pub use output_lock::OutputLock;
pub use overlay::{
    joint_offsets_to_yaml, overlay_to_yaml, parse_overlay, JointOffset, OFFSETS_FORMAT,
    OVERLAY_FORMAT,
};
pub use paired_csv::{paired_measurements_to_csv, PairedRow};
pub use params::{
    parse_parameters, read_parameter_file_robot, read_parameters, ParameterFileRobot,
    ParameterValues,
};
pub use plan::{parse_plan, read_plan};
pub use poses_csv::{planned_poses_to_csv, pose_rows, PoseSet};
pub use registration::{parse_registration, read_registration};
pub use stiffness::{parse_stiffness, read_stiffness};
pub use stiffness_write::stiffness_to_yaml;
pub use tracker_log::{
    parse_tracker_log, read_tracker_log, TrackerColumns, TrackerLog, TrackerLogOptions,
};
pub use units::{
    parse_units_header, resolve_units, AngleUnit, LengthUnit, MeasurementUnits, StatedUnits,
};
pub use write::{
    check_output_dir, check_output_file, check_output_folder, replace_folder,
    replace_folder_streamed, write_atomically, write_atomically_with, StreamedFile,
};

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

/// Rows (header first) as CSV text; `origin` names the output in messages.
pub(crate) fn csv_text(rows: &[Vec<String>], origin: &str) -> Result<String> {
    let fail = |message: String| Error::InvalidData {
        origin: origin.to_owned(),
        message,
    };
    let mut writer = csv::Writer::from_writer(Vec::new());
    for row in rows {
        writer.write_record(row).map_err(|e| fail(e.to_string()))?;
    }
    let bytes = writer.into_inner().map_err(|e| fail(e.to_string()))?;
    String::from_utf8(bytes).map_err(|e| fail(e.to_string()))
}
