//! Human- and machine-readable reports.

pub mod calibrate;
pub mod check;
pub mod inspect;
pub mod outliers;
pub mod plot;
pub mod simulate;
pub mod stiffness;

pub use calibrate::{
    calibration_markdown, calibration_plots, calibration_summary, parameter_file,
    CalibrationContext, CalibrationSummary,
};
pub use check::{CheckReport, StageCheck};
pub use inspect::{inspect, InspectReport};
pub use outliers::{outlier_rows, OutlierRow, RobustSummary};
pub use stiffness::{compliance_identifiability_markdown, stiffness_markdown, StiffnessSummary};
