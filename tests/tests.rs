//! treecal's integration tests: one binary, files mirror the modules and commands.

mod common;

mod branches;
mod calibrate;
mod cli;
mod collision;
mod export;
mod flexibility;
mod from_mcpc;
mod identifiability;
mod identification;
mod jacobian;
mod mcpc;
mod measurements_csv;
mod oracle;
mod planning;
mod plot;
mod recalibration;
mod simulate;
mod stiffness;
mod urdf_import;
