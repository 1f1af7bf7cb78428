//! cargo-fuzz target `g2o`: arbitrary bytes through `skid_fuzz_harness::g2o`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::g2o(data));
