//! cargo-fuzz target `ros1_bag`: arbitrary bytes through `skid_fuzz_harness::ros1_bag`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::ros1_bag(data));
