#![no_main]
//! Fuzz target `registration`: see tests/common/fuzz.rs (shared with the replay test) and README.md.

#[path = "../../tests/common/fuzz.rs"]
#[allow(dead_code)]
mod entries;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entries::registration(data));
