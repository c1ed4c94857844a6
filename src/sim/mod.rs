//! Simulation: random and planned configurations and the self-collision checks they must pass.

mod blunders;
pub mod camera;
pub mod camera_contacts;
pub mod camera_planning;
pub mod camera_setup;
pub mod camera_visibility;
mod collision;
mod contact_trial;
pub mod contacts;
mod detmax;
mod experiment;
mod mesh;
mod monte_carlo;
mod noise;
mod planning;
mod pose_set;
mod sampling;
mod trial_report;
mod truth;

pub use blunders::inject_blunders;
pub use collision::{CollisionCheck, CollisionChecker, CollisionOptions, MeshLoader};
pub use experiment::{
    run_trial, trial_seed, ArmErrors, BlunderReport, ErrorStats, RunSummary, Setup,
    SimulationOptions, TrialReport, TruthJointError,
};
pub use mesh::MeshLookup;
pub use monte_carlo::{run_trials, summarise, ArmSummary, SimulationSummary, Spread};
pub use noise::{observe, NoiseModel, Targets};
pub use planning::{
    criterion_value, plan_poses, Criterion, PlanReport, PlannedPose, PlanningOptions, PlanningStage,
};
pub use pose_set::{staged_pose_set, StagedPoseSet};
pub use sampling::{sample_configurations, SamplingOptions};
pub use truth::{true_model, with_joint_errors, ErrorRanges, JointErrorRanges};
