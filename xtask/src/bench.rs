//! The benchmark profiles `cargo xtask bench <profile>` knows: each is a release binary that writes
//! JSON, a Markdown table (and plots where it has figures) into `target/bench/<profile>/`.

/// One benchmark profile.
pub struct BenchProfile {
    pub name: &'static str,
    pub summary: &'static str,
    /// The package and binary that implement it.
    pub package: &'static str,
    pub binary: &'static str,
}

/// Every profile, in the order the paper's evaluation uses them.
pub const PROFILES: &[BenchProfile] = &[BenchProfile {
    name: "io",
    summary: "read/write throughput of KITTI .bin, PCD, PLY and g2o on the shared data",
    package: "skid-bench",
    binary: "skid-bench-io",
}];
