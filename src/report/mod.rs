//! Human- and machine-readable reports.

pub mod artifact;
pub mod calibrate;
pub mod camera;
pub mod check;
pub mod compare;
pub mod contacts;
pub mod html;
pub mod html_chart;
mod html_escape;
pub mod html_page;
pub mod inspect;
pub mod outliers;
pub mod pairing;
pub mod plot;
pub mod sessions;
pub mod simulate;
pub mod stiffness;
pub mod strata;
pub mod verify;

pub use calibrate::{
    calibration_markdown, calibration_plots, calibration_summary, parameter_file, ArmReport,
    BeforeAfter, CalibrationContext, CalibrationSummary, RowErrors, REPORT_SCHEMA,
};
pub use check::{CheckReport, StageCheck, CHECK_SCHEMA};
pub use html::{calibration_html, HtmlReport, Scene, SceneConfiguration};
pub use inspect::{inspect, InspectReport};
pub use outliers::{outlier_rows, OutlierRow, RobustSummary};
pub use pairing::{pairing_markdown, PairingReport};
pub use sessions::{sessions_markdown, sessions_summary, SessionsSummary};
pub use simulate::{simulation_results, SimulationResults, RESULTS_SCHEMA};
pub use stiffness::{compliance_identifiability_markdown, stiffness_markdown, StiffnessSummary};
