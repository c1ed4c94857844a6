//! treecal's integration tests: one binary, files mirror the modules and commands.

mod common;

mod branches;
mod calibrate;
mod cli;
mod collision;
mod corpus;
mod export;
mod flexibility;
mod frame;
mod from_mcpc;
mod hardening;
mod identifiability;
mod identification;
mod jacobian;
mod mcpc;
mod measurements_csv;
mod oracle;
mod pair;
mod pair_files;
mod pair_logs;
mod payloads;
mod planning;
mod plot;
mod readme;
mod real_robots;
mod recalibration;
mod report_json;
mod robust;
mod simulate;
mod stiffness;
mod urdf_import;
mod urdf_tolerant;
mod verdict;
mod workflow;
mod workflow_sim;
