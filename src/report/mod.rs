//! Human- and machine-readable reports.

pub mod check;
pub mod inspect;
pub mod plot;
pub mod simulate;

pub use check::{CheckReport, StageCheck};
pub use inspect::{inspect, InspectReport};
