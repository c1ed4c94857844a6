//! One library call per workflow (the CLI's commands, the Python package): a plain-data
//! `XxxConfig` (its `Default` holds the CLI's defaults) → `xxx(&config)` computes everything
//! and writes nothing → an outcome with its notes, reports and files, and `write(out)`.
//! See docs/workflows.md.

pub mod calibrate;
pub mod calibrate_artifact;
pub mod calibrate_camera;
mod calibrate_camera_judge;
pub mod calibrate_contacts;
pub mod calibrate_deploy;
mod calibrate_html;
mod calibrate_outputs;
mod calibrate_steps;
mod camera_contacts;
mod camera_tracker;
pub mod check;
pub mod check_camera;
pub mod checker;
pub mod checks;
pub mod compare;
pub mod contact_fit;
pub mod cross_validation;
pub mod export;
pub mod fk;
pub mod model;
pub mod model_choice;
pub mod note;
pub mod pair;
pub mod plan;
pub mod plan_camera;
pub mod postures;
pub mod progress;
pub mod provenance;
pub mod simulate;
mod simulate_camera;
mod simulate_contacts;
pub mod source;
pub mod verify;

pub use calibrate::{
    calibrate, CalibrateConfig, Calibration, GravityFrame, MeasurementFrameChoice, NoiseChoice,
    ParameterRow,
};
pub use export::{export, Export, ExportConfig};
pub use fk::{fk, fk_csv, fk_csv_stream, FkConfig, FkCsvConfig, FkStreamSummary, FkTable};
pub use model::{from_mcpc, inspect, to_mcpc, Inspection, McpcTableText, ModelConfig};
pub use note::{Note, NoteLevel};
pub use pair::{pair, PairConfig, Pairing};
pub use progress::{no_progress, Progress, ProgressFn};
pub use source::{LoadedRobot, MeasurementSource, PlanSource, RobotSource, StiffnessSource};
pub use verify::{verify, Verification, VerifyConfig, VerifyFrame};
