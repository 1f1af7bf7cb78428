//! The integration tests of `skid-sim`, in one test binary: the dependency graph is linked once, not once
//! per file. Each module holds the tests of one subject; run one module with
//! `cargo test -p skid-sim --test it <module>`.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test code fails loudly by design.

mod api;
mod blocks;
mod bodies;
mod common;
mod geometry;
mod missions;
mod planetary_relief;
