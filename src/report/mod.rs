//! Human- and machine-readable reports.

pub mod inspect;
pub mod plot;

pub use inspect::{inspect, InspectReport};
