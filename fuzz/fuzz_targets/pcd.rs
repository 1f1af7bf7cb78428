//! cargo-fuzz target `pcd`: arbitrary bytes through `skid_fuzz_harness::pcd`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::pcd(data));
