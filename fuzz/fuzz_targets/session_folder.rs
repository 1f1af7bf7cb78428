//! cargo-fuzz target `session_folder`: arbitrary bytes through `skid_fuzz_harness::session_folder`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::session_folder(data));
