//! Checks shared by the subcommands: the library's (`treecal::workflow::checks`).

pub use treecal::workflow::{check_outputs, Output};
