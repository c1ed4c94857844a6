//! Simulation: random and planned configurations and the self-collision checks they must pass.

pub mod blunders;
pub mod camera;
pub mod camera_planning;
pub mod camera_setup;
pub mod camera_visibility;
pub mod collision;
pub mod contacts;
mod detmax;
pub mod experiment;
pub mod mesh;
pub mod monte_carlo;
pub mod noise;
pub mod planning;
pub mod pose_set;
pub mod sampling;
mod trial_report;
pub mod truth;
