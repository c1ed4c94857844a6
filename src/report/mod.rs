//! Human- and machine-readable reports.

pub(crate) mod arm;
pub(crate) mod artifact;
pub(crate) mod calibrate;
pub(crate) mod calibrate_markdown;
pub(crate) mod camera;
pub(crate) mod check;
pub(crate) mod compare;
mod contact_scores;
pub(crate) mod contacts;
pub(crate) mod html;
pub(crate) mod html_chart;
mod html_escape;
mod html_markdown;
pub(crate) mod html_page;
pub(crate) mod inspect;
pub(crate) mod outliers;
pub(crate) mod pairing;
pub(crate) mod plot;
pub(crate) mod sessions;
pub(crate) mod simulate;
pub(crate) mod stiffness;
pub(crate) mod strata;
pub(crate) mod verify;

pub use arm::{ArmReport, BeforeAfter, RowErrors};
pub use artifact::{ArtifactReport, ArtifactScore, UnobservableBase};
pub use calibrate::{
    calibration_summary, parameter_file, CalibrationContext, CalibrationSummary, REPORT_SCHEMA,
    REPORT_SCHEMA_VERSIONS,
};
pub use calibrate::{FrameValues, ParameterFile, StageOutcome};
pub use calibrate_markdown::{calibration_markdown, calibration_plots};
pub use camera::{
    camera_markdown, kinds_markdown, CameraCalibrationReport, CameraFitSummary, FittedIntrinsic,
    FittedPose, HeldOut, PixelResiduals, RobotParameter, TargetResiduals, TrackerRegistration,
};
pub use check::{CheckReport, StageCheck, CHECK_SCHEMA};
pub use compare::{
    CompareReport, Displacement, DisplacementRow, FrameChange, MovedParameter, ValidationFigures,
    COMPARE_SCHEMA,
};
pub use contact_scores::{written_contacts, ContactScores, Errors, Judged, Scored};
pub use contacts::{contact_report, contact_unobservable_markdown};
pub use html::escape;
pub use html::{calibration_html, HtmlReport, Scene, SceneConfiguration};
pub use html_chart::parameter_chart_svg;
pub use html_page::markdown_page;
pub use inspect::{inspect, InspectReport};
pub use inspect::{
    BranchEntry, BranchesReport, JointCounts, LimbEntry, McpcReport, McpcRow, TreeEntry,
    INSPECT_SCHEMA,
};
pub use outliers::{outlier_rows, OutlierRow, RobustSummary};
pub use outliers::{outliers_markdown, robust_summary};
pub use pairing::{pairing_markdown, PairingReport};
pub use plot::{
    arm_error_plots, arm_error_plots_by_id, error_plot_svg, line_plot_svg, Curve, ErrorPlot,
    LinePlot, Series,
};
pub use sessions::{sessions_markdown, sessions_summary, SessionsSummary};
pub use sessions::{FrameXyzRpy, SessionRow, ValidationSessionRow};
pub use simulate::simulation_markdown;
pub use simulate::{simulation_results, SimulationResults, RESULTS_SCHEMA};
pub use stiffness::{compliance_identifiability_markdown, stiffness_markdown, StiffnessSummary};
pub use strata::{StrataRow, StratumFigures, ValidationStrata, WorstRow};
pub use verify::{
    SetAside, VerifyContext, VerifyReport, VerifyRow, VerifySession, VerifyVerdict, VERIFY_SCHEMA,
};

/// The first few names, and how many more (for one line of a report).
pub(crate) fn first_few(names: &[String]) -> String {
    const SHOWN: usize = 5;
    let mut text = names
        .iter()
        .take(SHOWN)
        .map(String::as_str)
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > SHOWN {
        text.push_str(&format!(" and {} more", names.len() - SHOWN));
    }
    text
}
