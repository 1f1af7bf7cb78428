//! The integration tests of `skid-transport-zenoh`, in one test binary: the dependency graph is linked once, not once
//! per file. Each module holds the tests of one subject; run one module with
//! `cargo test -p skid-transport-zenoh --test it <module>`.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // Test code fails loudly by design.

mod mutual_tls;
mod zenoh;
