//! Simulation: random and planned configurations and the self-collision checks they must pass.

mod blunders;
pub(crate) mod camera;
pub(crate) mod camera_contacts;
pub(crate) mod camera_planning;
pub(crate) mod camera_setup;
pub(crate) mod camera_visibility;
mod collision;
mod contact_collisions;
pub use contact_collisions::ContactCollisions;
mod contact_planning;
mod contact_tracker;
mod contact_trial;
pub(crate) mod contacts;
mod detmax;
mod experiment;
mod mesh;
mod monte_carlo;
mod noise;
mod planning;
mod pose_set;
mod sampling;
mod stance;
mod trial_report;
mod truth;

pub use blunders::inject_blunders;
pub use camera::{
    board_size, camera_trial_data, fit_options, held_out_views, run_camera_trial, CameraSetup,
    CameraSimulationOptions, CameraTrialData, CameraTrialReport, ObservationMode,
};
pub use camera_contacts::{camera_contact_scene, contact_noise, contact_unknowns};
pub use camera_planning::{plan_camera_poses, CameraPlanReport, CameraPlanningOptions};
pub use camera_setup::{camera_rig, camera_specs, CameraRigOptions};
pub use camera_visibility::{rigid_group, Hidden, Sight, VisibilityRules};
pub use collision::{CollisionCheck, CollisionChecker, CollisionOptions, MeshLoader};
pub use contact_planning::{choose_contacts, ContactChoiceReport};
pub use contact_tracker::{contact_tracker_frame, contact_tracker_rows, CONTACT_TRACKER_SIGMA};
pub use contacts::{
    collision_free_contact_configurations, contact_configurations, contact_free_parameters,
    contact_scene, held_out_residual, independent_columns, linear_columns, onto_contact,
    run_contact_trial, ContactChoice, ContactScene, ContactSimulation, ContactTrial, LINEAR_STD,
};
pub use experiment::{
    run_trial, trial_seed, ArmErrors, BlunderReport, ErrorStats, RunSummary, Setup,
    SimulationOptions, StageSummary, TrialReport, TruthJointError,
};
pub use mesh::MeshLookup;
pub use monte_carlo::{run_trials, summarise, ArmSummary, SimulationSummary, Spread};
pub use noise::{observe, NoiseModel, Targets};
pub use planning::{
    criterion_value, plan_poses, Criterion, PlanReport, PlannedPose, PlanningOptions, PlanningStage,
};
pub use pose_set::{staged_pose_set, StagedPoseSet};
pub use sampling::{sample_configurations, SamplingOptions};
pub use stance::{contact_limits, STANCE_ANGLE, STANCE_LENGTH};
pub use truth::{true_model, with_joint_errors, ErrorRanges, JointErrorRanges};
