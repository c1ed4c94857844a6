//! treecal's integration tests: one binary, files mirror the modules and commands.

mod common;

mod branches;
mod cli;
mod collision;
mod flexibility;
mod from_mcpc;
mod identification;
mod jacobian;
mod mcpc;
mod oracle;
mod planning;
mod plot;
mod simulate;
mod urdf_import;
