//! `cargo xtask bench registration-coarse`: global registration as the SKiD-SLAM paper evaluates it
//! (Kim et al., "SKiD-SLAM"; KISS-Matcher, Lim et al., ICRA 2025).
//!
//! 1. Yaw sweep on the real HDL-32E pair (`skid_bench::registration::sweep`): KISS-Matcher, RANSAC (each
//!    alone and + GICP) and GICP from the identity; `success_vs_yaw.png` is the paper's figure.
//! 2. Simulated pairs from the planetary, cave and urban worlds (`skid_bench::registration::sim`): RTE,
//!    RRE and success rate of ICP, plane ICP, GICP, VGICP, KISS-Matcher, KISS-Matcher + GICP and
//!    RANSAC + GICP — shaped like the paper's registration table.

use anyhow::Result;
use clap::Parser;
use skid_bench::registration::sim::{SimTableSettings, sim_table};
use skid_bench::registration::sweep::{SweepSettings, yaw_sweep};
use skid_bench::registration::{Methods, REGISTRATION_NOTE};
use skid_bench::{BenchArgs, Report, append_markdown};

#[derive(Parser, Debug)]
struct Args {
    #[command(flatten)]
    bench: BenchArgs,
    /// Threads every plugin may use.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Simulated pairs per world and pair kind.
    #[arg(long, default_value_t = 4)]
    sim_pairs: usize,
    /// Offset directions per yaw in the real-pair sweep.
    #[arg(long, default_value_t = 4)]
    directions: usize,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let out = &args.bench.out;
    let mut methods = Methods::new(args.threads)?;
    let mut report = Report::new("registration-coarse");
    let sweep = SweepSettings {
        threads: args.threads,
        directions: args.directions,
        ..SweepSettings::default()
    };
    let sweep = yaw_sweep(&mut methods, &sweep, &mut report, out)?;
    let table = SimTableSettings {
        threads: args.threads,
        pairs_per_kind: args.sim_pairs,
        ..SimTableSettings::default()
    };
    sim_table(&mut methods, &table, &mut report)?;
    report.write(out)?;
    append_markdown(
        out,
        &format!(
            "{}\n{REGISTRATION_NOTE} Fine methods in the simulated rows start from the truth off by up to 1.5 m and 20° of yaw.\n",
            sweep.markdown
        ),
    )?;
    Ok(())
}
