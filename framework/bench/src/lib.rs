//! Shared plumbing of the benchmark binaries: command-line options, a profile's parameter file, timing
//! statistics, the report (JSON + Markdown) every profile writes into `target/bench/<profile>/`, and the
//! experiments several profiles share — the SKiD-SLAM paper's evaluation (Kim et al., "SKiD-SLAM"):
//! place recognition ([`place_recognition`]), registration ([`registration`]), descriptor memory
//! ([`memory`]), the two-robot SLAM comparison ([`slam`]) and message latency ([`latency`]); and bag decoding beside rosbags ([`bag_io`]).

/// The allocator of every benchmark binary, the same as the `skid` command's. Scans come and go as buffers of megabytes: glibc's allocator
/// hands each one back to the kernel when it is freed and page-faults to get it again for the next
/// scan, while mimalloc keeps the pages for reuse (bag decoding runs 25-45% faster with it; see
/// `cargo xtask bench io`).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

pub mod aliasing;
pub mod bag_io;
pub mod files;
pub mod latency;
pub mod memory;
pub mod place_recognition;
pub mod profile;
pub mod python_peers;
pub mod registration;
pub mod relocalise;
pub mod report;
pub mod scale;
pub mod scale_report;
pub mod session_merge;
pub mod slam;
pub mod stats;
pub mod usage;
pub mod wire_security;

pub use profile::{load_profile, run_profile};
pub use report::{BenchArgs, Report, append_markdown, markdown_table};
pub use stats::Timing;
