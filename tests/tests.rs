//! treecal's integration tests: one binary, files mirror the modules and commands.

mod common;

mod branches;
mod mcpc;
mod urdf_import;
