//! cargo-fuzz target `protocol_message`: arbitrary bytes through `skid_fuzz_harness::protocol_message`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::protocol_message(data));
