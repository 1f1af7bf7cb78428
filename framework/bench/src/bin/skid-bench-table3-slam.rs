//! `cargo xtask bench table3-slam`: the SKiD-SLAM paper's Table III — ATE/ARE of robot α (Umeyama) and
//! of the robots β (the α/β alignment metric) per simulated world for the default pipeline against the
//! DiSCo-like and DCL-like profiles, each a real `skid_runtime::Fleet` run on a mission. Parameters in
//! `configs/bench/table3-slam.toml`; the method is `skid_bench::slam`'s. Run outputs (trajectories,
//! graphs, metrics, effective configs) go to `runs/` under the output folder.

use anyhow::Context;
use skid_bench::slam::{SlamSettings, run_one, slam_markdown};

fn main() -> anyhow::Result<()> {
    skid_bench::run_profile("table3-slam", |settings: &SlamSettings, report, out| {
        let registry = skid_builtin::registry().context("registering the built-in plugins")?;
        let mut rows = Vec::new();
        for world in &settings.worlds {
            for pipeline in &settings.pipelines {
                for row in run_one(settings, world, pipeline, &registry, out)? {
                    eprintln!(
                        "{world} {} (β = robot {}): ATE α {:?} m, ATE β {:?} m, {} inter-robot loops, {:.0} s",
                        pipeline.name,
                        row.beta_robot,
                        row.ate_alpha_m,
                        row.ate_beta_m,
                        row.inter_robot_loops,
                        row.run_wall_s
                    );
                    report.push(&row)?;
                    rows.push(row);
                }
            }
        }
        Ok(slam_markdown(settings, &rows))
    })
}
