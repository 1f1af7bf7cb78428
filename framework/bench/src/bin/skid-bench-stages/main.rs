//! `cargo xtask bench stages`: the stage speeds of issue #18's table, each measured beside its peer in
//! the same run (the Python packages `small-gicp` and `gtsam` of the benchmark venv, through
//! `skid_bench::python_peers`), with rounds of SKiD and the peer alternated so both meet the shared machine
//! in the same states: SOLiD extraction on real KITTI scans ([`solid`]), GICP end to end on the real
//! HDL-32E pair ([`gicp`]) and Levenberg-Marquardt on sphere2500 ([`lm`]). The KISS-Matcher yaw sweep,
//! robust PGO with wrong loops and the default run have their own profiles (`registration-coarse`,
//! `pgo`, the README's default run). `SKID_BENCH_STAGES=solid,gicp,lm` picks sections.

mod gicp;
mod lm;
mod solid;

use anyhow::Result;
use clap::Parser;
use serde::Serialize;
use skid_bench::{BenchArgs, Report};

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    common: BenchArgs,
    /// Timed repetitions per round (three rounds per stage).
    #[arg(long, default_value_t = 10)]
    repeats: usize,
}

/// One stage against its peer.
#[derive(Serialize)]
pub struct Row {
    stage: String,
    input: String,
    skid: String,
    peer: String,
    /// SKiD's time over the peer's.
    ratio: Option<f64>,
    goal: String,
    detail: String,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let wanted = std::env::var("SKID_BENCH_STAGES").unwrap_or_else(|_| "solid,gicp,lm".into());
    let wants = |name: &str| wanted.split(',').any(|w| w.trim() == name);
    let python = skid_bench::python_peers::python();
    let repeats = args.repeats.max(1);
    let mut report = Report::new("stages");
    if wants("solid") {
        report.push(&solid::row(repeats * 3)?)?;
    }
    if wants("gicp") {
        report.push(&gicp::row(python.as_deref(), repeats)?)?;
    }
    if wants("lm") {
        for row in lm::rows(python.as_deref(), repeats.div_ceil(3))? {
            report.push(&row)?;
        }
    }
    report.write(&args.common.out)
}
