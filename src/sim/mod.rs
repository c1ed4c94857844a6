//! Simulation: random configurations and the self-collision checks they must pass.

pub mod collision;
pub mod experiment;
pub mod monte_carlo;
pub mod noise;
pub mod pose_set;
pub mod sampling;
pub mod truth;
