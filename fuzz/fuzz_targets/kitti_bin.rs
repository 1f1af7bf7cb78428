//! cargo-fuzz target `kitti_bin`: arbitrary bytes through `skid_fuzz_harness::kitti_bin`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| skid_fuzz_harness::kitti_bin(data));
