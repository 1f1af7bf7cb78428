//! cargo-fuzz target `ply`: arbitrary bytes through `skid_fuzz_harness::ply`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::ply(data));
