//! `cargo xtask bench table4-latency`: the SKiD-SLAM paper's Table IV — descriptor (and keyframe cloud)
//! message latency at 5–30 m between two robots, for Scan Context, LiDAR-Iris and SOLiD, over the
//! loopback transport's link model. Parameters in `configs/bench/table4-latency.toml`; the method is
//! `skid_bench::latency`'s.

use skid_bench::latency::{LatencySettings, latency_markdown, latency_rows};

fn main() -> anyhow::Result<()> {
    skid_bench::run_profile("table4-latency", |settings: &LatencySettings, report, _| {
        let rows = latency_rows(settings)?;
        for row in &rows {
            report.push(row)?;
        }
        Ok(latency_markdown(settings, &rows))
    })
}
