//! Fuzz harnesses for every decoder that reads bytes from outside the process (issue #20, item 4): the
//! inter-robot protocol (envelope and message bodies), the point-cloud files (PCD, PLY, KITTI `.bin`),
//! the pose-graph files (g2o, TORO, JRL), the bag containers (ROS 1, MCAP) and the ROS messages inside them,
//! and saved sessions (their descriptor files and whole session folders).
//!
//! Each harness takes arbitrary bytes, runs the real reader on them and checks what a caller relies on:
//! no panic, no unbounded allocation (libFuzzer's `-malloc_limit_mb` catches that), and for inputs that
//! are accepted, the reader's own invariants (finite points where non-finite ones are dropped, counts
//! that add up, a message that re-encodes to itself). The `fuzz/` folder's cargo-fuzz targets call these
//! functions, and `tests/corpus_replay.rs` runs them over the committed corpus and the crashers kept as
//! regression cases, so CI exercises every decoder without a fuzzer.

// A harness reports a defect by panicking: that is what the fuzzer and the replay test catch.
#![allow(clippy::expect_used, clippy::unwrap_used, clippy::panic)]

mod bags;
mod clouds;
mod graphs;
mod protocol;
mod scratch;
pub mod seeds;
mod sessions;

pub use bags::{mcap_bag, ros_messages, ros1_bag};
pub use clouds::{kitti_bin, pcd, ply};
pub use graphs::{g2o, jrl, toro};
pub use protocol::protocol_message;
pub use sessions::{SESSION_FILE_SEPARATOR, SESSION_FILES, session_descriptors, session_folder};

/// A fuzz harness: arbitrary bytes in, a panic only on a real defect.
pub type Harness = fn(&[u8]);

/// Every harness by target name (the names of the cargo-fuzz targets and corpus folders).
pub const TARGETS: &[(&str, Harness)] = &[
    ("protocol_message", protocol_message),
    ("pcd", pcd),
    ("ply", ply),
    ("kitti_bin", kitti_bin),
    ("g2o", g2o),
    ("toro", toro),
    ("jrl", jrl),
    ("ros1_bag", ros1_bag),
    ("mcap_bag", mcap_bag),
    ("ros_messages", ros_messages),
    ("session_descriptors", session_descriptors),
    ("session_folder", session_folder),
];

/// The harness named `name`.
pub fn harness(name: &str) -> Option<Harness> {
    TARGETS
        .iter()
        .find(|(target, _)| *target == name)
        .map(|(_, run)| *run)
}
