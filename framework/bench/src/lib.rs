//! Shared plumbing of the benchmark binaries: command-line options, timing statistics, and the report
//! (JSON + Markdown table) every profile writes into `target/bench/<profile>/`.

pub mod report;
pub mod stats;

pub use report::{BenchArgs, Report};
pub use stats::Timing;
