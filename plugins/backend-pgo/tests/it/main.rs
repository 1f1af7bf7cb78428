//! The integration tests of `skid-backend-pgo`, in one test binary: the dependency graph is linked once, not once
//! per file. Each module holds the tests of one subject; run one module with
//! `cargo test -p skid-backend-pgo --test it <module>`.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test code fails loudly by design.

mod backend_plugin;
mod g2o_graphs;
