//! `cargo xtask bench fig-yaw-sweep`: the SKiD-SLAM paper's "success rate vs yaw" figure — on the real
//! HDL-32E pair, the target yawed through a full turn and moved a fixed distance; success (< 2 m, < 5°)
//! of KISS-Matcher (Lim et al., ICRA 2025) and RANSAC, each alone and + GICP, and of GICP from the
//! identity. Parameters in `configs/bench/fig-yaw-sweep.toml`; writes `success_vs_yaw.png`.

use skid_bench::registration::sweep::{SweepSettings, yaw_sweep};
use skid_bench::registration::{Methods, REGISTRATION_NOTE};

fn main() -> anyhow::Result<()> {
    skid_bench::run_profile("fig-yaw-sweep", |settings: &SweepSettings, report, out| {
        let mut methods = Methods::new(settings.threads)?;
        let sweep = yaw_sweep(&mut methods, settings, report, out)?;
        Ok(format!(
            "{}\n## Over the whole sweep\n\n{}\n\n{REGISTRATION_NOTE}\n",
            sweep.markdown.replacen("\n## ", "# fig-yaw-sweep\n\n## ", 1),
            report.markdown().lines().skip(2).collect::<Vec<_>>().join("\n"),
        ))
    })
}
