//! One library call per workflow (the CLI's commands, the Python package): a plain-data
//! `XxxConfig` (its `Default` holds the CLI's defaults) → `xxx(&config)` computes everything
//! and writes nothing → an outcome with its notes, reports and files, and `write(out)`.
//! See docs/workflows.md.

mod artifact_joint_errors;
mod artifact_scoring;
pub(crate) mod calibrate;
pub(crate) mod calibrate_artifact;
pub(crate) mod calibrate_camera;
mod calibrate_camera_judge;
mod calibrate_config;
pub(crate) mod calibrate_contacts;
pub(crate) mod calibrate_deploy;
mod calibrate_html;
mod calibrate_identify;
mod calibrate_outputs;
mod calibrate_products;
mod calibrate_steps;
mod camera_contacts;
pub use camera_contacts::CameraContactsInput;
mod camera_tracker;
pub(crate) mod check;
pub(crate) mod check_camera;
mod check_contacts;
pub(crate) mod checker;
pub(crate) mod checks;
pub(crate) mod compare;
pub(crate) mod compare_gauge;
pub(crate) mod contact_cv;
pub(crate) mod contact_fit;
mod contact_model;
mod contact_scale;
mod contact_tracker;
pub(crate) mod cross_validation;
pub(crate) mod export;
pub(crate) mod fk;
mod measurement_files;
pub(crate) mod model;
pub(crate) mod model_choice;
pub(crate) mod note;
pub(crate) mod pair;
pub(crate) mod plan;
pub(crate) mod plan_camera;
mod plan_contacts;
pub(crate) mod postures;
pub(crate) mod progress;
pub(crate) mod provenance;
mod report_json;
pub(crate) mod simulate;
mod simulate_camera;
mod simulate_config;
mod simulate_contacts;
pub(crate) mod source;
pub(crate) mod spelling;
pub(crate) mod verify;

pub use artifact_joint_errors::JOINT_ERRORS_FILE;
pub use calibrate::{
    calibrate, calibrate_for_writing, CalibrateConfig, Calibration, GravityFrame,
    MeasurementFrameChoice, NoiseChoice, ParameterRow,
};
pub use calibrate::{is_output_file, OUTPUT_FILES};
pub use calibrate_artifact::{registration_text, COMPENSATED_URDF, REGISTRATION_FILE};
pub use calibrate_camera::{
    calibrate_camera_files, CameraCalibrateConfig, CameraCalibration, CameraTrackerInput,
    DetectionsSource, CALIBRATED_CAMERAS, PIXEL_SIGMA_FAILED, PIXEL_SIGMA_WARNING,
};
pub use calibrate_contacts::{
    calibrate_contacts, contact_options, contact_problem, ContactCalibrateConfig,
    ContactCalibration, CONTACT_OUTPUTS,
};
pub use calibrate_deploy::{DEPLOY_FILES, HTML_FILE, OFFSETS_FILE, OVERLAY_FILE};
pub use check::{check, stage_analysis, Check, CheckConfig};
pub use check_camera::{check_camera, CameraCheck, CameraCheckConfig};
pub use check_contacts::{check_contacts, ContactCheck, ContactCheckConfig};
pub use checker::{collision_checker, collision_statement};
pub use checks::{check_outputs, count, sigmas, unused_stage_rows, Output};
pub use compare::{compare, CompareConfig, Comparison, COMPARE_FILES};
pub use contact_cv::{
    candidate_problem, choose_contact_model, cross_validate_contacts, fit_candidate, ContactCv,
    ContactCvInput, ContactCvRow, ContactFolds, ContactModelChoice, ContactModelSpec,
    CONTACT_ADAPTIVE_SIGMA, CONTACT_CANDIDATES, CONTACT_RULE,
};
pub use contact_fit::{contact_violations, fit_contacts, plane_start, ContactFit, ContactProblem};
pub use cross_validation::{
    candidates, cross_validate, joint_steps, lines as cross_validation_lines, markdown, paired,
    CrossValidation, CrossValidationInput, CvRow, Paired, DEFAULT_FOLDS, MAX_STEPS, REPEATS, RULE,
    SIGNIFICANT_T,
};
pub use export::export_notes;
pub use export::{export, Export, ExportConfig};
pub use fk::{fk, fk_csv, fk_csv_stream, FkConfig, FkCsvConfig, FkStreamSummary, FkTable};
pub use model::{from_mcpc, inspect, to_mcpc, Inspection, McpcTableText, ModelConfig};
pub use model_choice::{
    fit_noise, frame_joints, glob_match, grouped_folds, position_errors, posture_groups, prepare,
    run_model, run_model_with_noise, shows_model_error, ModelChoice, ModelLevel, ModelSpec,
    NoiseEstimate, ParameterPatterns, PreparedModel, POSTURE_TOLERANCE,
};
pub use note::{Note, NoteLevel};
pub use pair::report_path;
pub use pair::{pair, PairConfig, Pairing};
pub use plan::{
    check_output, plan, plan_with_progress, PlanConfig, PlanStage, PlannedSet, PosePlan,
};
pub use plan_camera::{check_camera_plan_output, plan_camera, CameraPlanConfig, CameraPosePlan};
pub use plan_contacts::{
    check_contact_plan_output, plan_contacts, ContactPlanConfig, ContactPosePlan,
};
pub use postures::{
    chains_of, record, RecordedJoint, RecordedPosture, RecordedPostures, RecordedTool, POSTURES_KEY,
};
pub use progress::{no_progress, Progress, ProgressFn};
pub use provenance::{settings_text, Started, PROVENANCE_FILE};
pub use simulate::{
    check_outputs as check_simulate_outputs, simulate, simulate_with_progress, MeasurementFormat,
    ObservationChoice, PosesFrom, SimulateConfig, Simulation,
};
pub use source::{
    add_measured_points, branches, measured_branches, reference_link, MeasuredPoints,
    BUILT_IN_ROBONAUT, BUILT_IN_ROBONAUT_ORIGIN, BUILT_IN_STIFFNESS, BUILT_IN_STIFFNESS_ORIGIN,
};
pub use source::{LoadedRobot, MeasurementSource, PlanSource, RobotSource, StiffnessSource};
pub use spelling::{spell_reports, Spelling};
pub use verify::VERIFY_FILES;
pub use verify::{verify, Verification, VerifyConfig, VerifyFrame};
