//! The integration tests of `skid`, in one test binary: the dependency graph is linked once, not once
//! per file. Each module holds the tests of one subject; run one module with
//! `cargo test -p skid --test it <module>`.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test code fails loudly by design.

// The modules that need the network plugins run with the `zenoh` feature (`cargo xtask ci` turns it on).

mod all_slots_from_a_library;
mod bags;
mod cli;
mod cpp_plugin;
mod default_odometry;
mod executors;
#[cfg(feature = "zenoh")]
mod live_and_bag;
#[cfg(feature = "zenoh")]
mod live_ros2_output;
mod new_user;
mod pcm_sets;
mod prior_map;
mod rerun_recording;
mod run_folders;
mod run_record;
mod sim_bags;
#[cfg(feature = "zenoh")]
mod zenoh_robots;
