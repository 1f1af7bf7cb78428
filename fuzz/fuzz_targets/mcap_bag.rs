//! cargo-fuzz target `mcap_bag`: arbitrary bytes through `skid_fuzz_harness::mcap_bag`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::mcap_bag(data));
