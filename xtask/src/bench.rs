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
pub const PROFILES: &[BenchProfile] = &[
    BenchProfile {
        name: "sim",
        summary: "simulator: world generation, scans per second and ms per scan for every sensor in every world",
        package: "skid-sim",
        binary: "sim-bench",
    },
    BenchProfile {
        name: "io",
        summary: "read/write throughput of KITTI .bin, PCD, PLY and g2o on the shared data",
        package: "skid-bench",
        binary: "skid-bench-io",
    },
    BenchProfile {
        name: "registration-fine",
        summary: "fine registration (GICP, VGICP, ICP, plane ICP) on the real scan pair vs small_gicp: ms, iterations, pose",
        package: "skid-bench",
        binary: "skid-bench-registration-fine",
    },
    BenchProfile {
        name: "pgo",
        summary: "pose-graph optimisation vs GTSAM and SE-Sync optima; PCM/GNC with wrong loops; multi-robot PCM sets",
        package: "skid-bench",
        binary: "skid-bench-pgo",
    },
    BenchProfile {
        name: "place-recognition",
        summary: "PR curves, max F1, recall at 100% precision, bytes, extraction/query time of SOLiD, Scan Context, LiDAR-Iris on simulated multi-robot runs",
        package: "skid-bench",
        binary: "skid-bench-place-recognition",
    },
    BenchProfile {
        name: "registration-coarse",
        summary: "global registration: KISS-Matcher and RANSAC success vs yaw on the real pair (PNG), and the simulated registration table",
        package: "skid-bench",
        binary: "skid-bench-registration-coarse",
    },
    BenchProfile {
        name: "ipc",
        summary: "one-way latency of 2 MB / 256 KB / 2 KB keyframes between two processes over skid-ipc (iceoryx2, event wake-up)",
        package: "skid-bench",
        binary: "skid-bench-ipc",
    },
    BenchProfile {
        name: "odometry",
        summary: "kiss_icp odometry: ms per frame, fps, peak memory, ATE and drift on the real KITTI 00 frames and 500-scan simulated HDL-64E sequences",
        package: "skid-bench",
        binary: "skid-bench-odometry",
    },
];
