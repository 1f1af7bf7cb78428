//! cargo-fuzz target `jrl`: arbitrary bytes through `skid_fuzz_harness::jrl`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::jrl(data));
