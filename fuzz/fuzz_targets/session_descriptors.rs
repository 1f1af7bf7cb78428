//! cargo-fuzz target `session_descriptors`: arbitrary bytes through `skid_fuzz_harness::session_descriptors`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::session_descriptors(data));
