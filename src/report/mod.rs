//! Human- and machine-readable reports.

pub mod inspect;

pub use inspect::{inspect, InspectReport};
