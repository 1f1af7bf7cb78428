//! Shared plumbing of the benchmark binaries: command-line options, a profile's parameter file, timing
//! statistics, the report (JSON + Markdown) every profile writes into `target/bench/<profile>/`, and the
//! experiments several profiles share — the SKiD-SLAM paper's evaluation (Kim et al., "SKiD-SLAM"):
//! place recognition ([`place_recognition`]), registration ([`registration`]), descriptor memory
//! ([`memory`]), the two-robot SLAM comparison ([`slam`]) and message latency ([`latency`]); and bag decoding beside rosbags ([`bag_io`]).

pub mod bag_io;
pub mod latency;
pub mod memory;
pub mod place_recognition;
pub mod profile;
pub mod registration;
pub mod report;
pub mod slam;
pub mod stats;

pub use profile::{load_profile, run_profile};
pub use report::{BenchArgs, Report, append_markdown, markdown_table};
pub use stats::Timing;
