//! cargo-fuzz target `ros_messages`: arbitrary bytes through `skid_fuzz_harness::ros_messages`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::ros_messages(data));
