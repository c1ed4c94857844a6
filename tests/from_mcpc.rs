//! Tests: from_mcpc.
