//! cargo-fuzz target `toro`: arbitrary bytes through `skid_fuzz_harness::toro`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::toro(data));
