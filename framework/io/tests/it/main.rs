//! The integration tests of `skid-io`, in one test binary: the dependency graph is linked once, not once
//! per file. Each module holds the tests of one subject; run one module with
//! `cargo test -p skid-io --test it <module>`.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test code fails loudly by design.

mod formats;
mod jrl;
mod malformed;
mod real_clouds;
mod real_pose_graphs;
