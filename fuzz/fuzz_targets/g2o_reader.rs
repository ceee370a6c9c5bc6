//! Fuzz target: see `checks::g2o_reader`.
#![no_main]

#[path = "../checks.rs"]
#[allow(dead_code)]
mod checks;

libfuzzer_sys::fuzz_target!(|data: &[u8]| checks::g2o_reader(data));
