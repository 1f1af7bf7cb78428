//! The integration tests of `skid-eval`, in one test binary: the dependency graph is linked once, not once
//! per file. Each module holds the tests of one subject; run one module with
//! `cargo test -p skid-eval --test it <module>`.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test code fails loudly by design.

mod files_and_plots;
mod metrics;
