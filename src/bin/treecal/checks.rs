//! Checks shared by the subcommands: the library's (`treecal::workflow::checks`).

pub use treecal::workflow::checks::{refuse_overwrite, refuse_overwrite_in};
