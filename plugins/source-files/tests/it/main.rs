//! The integration tests of `skid-source-files`, in one test binary: the dependency graph is linked once, not once
//! per file. Each module holds the tests of one subject; run one module with
//! `cargo test -p skid-source-files --test it <module>`.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test code fails loudly by design.

mod bag_layouts;
mod bag_source;
#[path = "../../../../framework/bag/tests/it/generated/mod.rs"]
mod generated;
mod real_data;
mod sim_export;
