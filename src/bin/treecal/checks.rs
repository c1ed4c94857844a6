//! Checks shared by the subcommands: the library's (`treecal::workflow::checks`).

pub use treecal::workflow::checks::{check_outputs, Output};
