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
        name: "abi",
        summary: "the C ABI's cost per registration call: built-in GICP vs the same code loaded as a cdylib (and the C++ example)",
        package: "skid-bench",
        binary: "skid-bench-abi",
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
    BenchProfile {
        name: "table1-descriptor-memory",
        summary: "paper Table I: total descriptor bytes shared over a long three-robot run, SOLiD vs Scan Context vs LiDAR-Iris",
        package: "skid-bench",
        binary: "skid-bench-table1-descriptor-memory",
    },
    BenchProfile {
        name: "fig-pr-curves",
        summary: "paper PR-curve figure: SOLiD, Scan Context, LiDAR-Iris per environment (planetary, cave, urban, narrow FOV)",
        package: "skid-bench",
        binary: "skid-bench-fig-pr-curves",
    },
    BenchProfile {
        name: "table2-registration",
        summary: "paper Table II: RTE/RRE/success of ICP, GICP, VGICP, KISS-Matcher (+GICP), RANSAC (+GICP) on simulated pairs",
        package: "skid-bench",
        binary: "skid-bench-table2-registration",
    },
    BenchProfile {
        name: "fig-yaw-sweep",
        summary: "paper figure: registration success rate vs yaw on the real HDL-32E pair",
        package: "skid-bench",
        binary: "skid-bench-fig-yaw-sweep",
    },
    BenchProfile {
        name: "table3-slam",
        summary: "paper Table III: ATE/ARE of robots α and β (α/β metric) per world, default vs DiSCo-like vs DCL-like, real two-robot runtime runs",
        package: "skid-bench",
        binary: "skid-bench-table3-slam",
    },
    BenchProfile {
        name: "aliasing",
        summary: "false and true inter-robot merges in worlds that alias (urban grid, identical blocks), judged where the robots met, ten seeds each, merge rules on vs off",
        package: "skid-bench",
        binary: "skid-bench-aliasing",
    },
    BenchProfile {
        name: "relocalise",
        summary: "a robot placing itself in a prior map: first fixes, false fixes and error from starts on and off the mapped routes, another LiDAR and season; cost beside full SLAM",
        package: "skid-bench",
        binary: "skid-bench-relocalise",
    },
    BenchProfile {
        name: "table4-latency",
        summary: "paper Table IV: descriptor and cloud message latency at 5-30 m over the loopback link model",
        package: "skid-bench",
        binary: "skid-bench-table4-latency",
    },
    BenchProfile {
        name: "scale",
        summary: "N = 2..16 robots of the default pipeline and a 20-minute mission: wall and CPU per stage, memory, bytes, loops, ATE; back-end/verifier cost per keyframe over time",
        package: "skid-bench",
        binary: "skid-bench-scale",
    },
    BenchProfile {
        name: "stages",
        summary: "issue #18's stage speeds beside their peers in one run: SOLiD extraction on KITTI scans, GICP end to end vs small_gicp, LM on sphere2500 vs GTSAM",
        package: "skid-bench",
        binary: "skid-bench-stages",
    },
    BenchProfile {
        name: "cosmo",
        summary: "COSMO-Bench's real 3-robot problems with labelled wrong loops through SKiD's verifier and back-end, batch and distributed-incremental, beside GTSAM 4.3 (LM, LM on inliers, GNC-TLS) in the same run",
        package: "skid-bench",
        binary: "skid-bench-cosmo",
    },
    BenchProfile {
        name: "zenoh-tls",
        summary: "the zenoh transport's mutual TLS against plain TCP: bytes on the wire of the default pipeline as three robot processes, one-way latency by message size",
        package: "skid-bench",
        binary: "skid-bench-zenoh-tls",
    },
];
