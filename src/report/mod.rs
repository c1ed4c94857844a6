//! Human- and machine-readable reports.

pub mod inspect;
pub mod plot;
pub mod simulate;

pub use inspect::{inspect, InspectReport};
