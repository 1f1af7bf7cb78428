//! `cargo xtask bench table1-descriptor-memory`: the SKiD-SLAM paper's Table I — total bytes of the
//! global descriptors robots β and γ share with α over a long three-robot run, SOLiD (Kim et al., RA-L
//! 2024) vs Scan Context (Kim & Kim, IROS 2018) vs LiDAR-Iris (Wang et al., IROS 2020). Parameters in
//! `configs/bench/table1-descriptor-memory.toml`; the method is `skid_bench::memory`'s.

use skid_bench::memory::{MemorySettings, descriptor_memory_rows, memory_markdown};

fn main() -> anyhow::Result<()> {
    skid_bench::run_profile(
        "table1-descriptor-memory",
        |settings: &MemorySettings, report, _| {
            let rows = descriptor_memory_rows(settings)?;
            for row in &rows {
                report.push(row)?;
            }
            Ok(memory_markdown(settings, &rows))
        },
    )
}
