//! `cargo xtask bench aliasing`: false and true inter-robot merges in worlds that alias, over several
//! seeds, with the merge rules on and off. Parameters in `configs/bench/aliasing.toml`; the method is
//! `skid_bench::aliasing`'s. Run outputs go to `runs/` under the output folder.

use anyhow::Context;
use skid_bench::aliasing::{AliasingSettings, aliasing_markdown, run_one};

fn main() -> anyhow::Result<()> {
    skid_bench::run_profile("aliasing", |settings: &AliasingSettings, report, out| {
        let registry = skid_builtin::registry().context("registering the built-in plugins")?;
        let mut rows = Vec::new();
        for world in &settings.worlds {
            for &seed in &settings.seeds {
                for variant in &settings.variants {
                    for row in run_one(settings, world, seed, variant, &registry, out)? {
                        eprintln!(
                            "{world} seed {seed} {} (β = robot {}): {} ({:?} m, {:?}° by {}; T_β,APE {:?} m, {:?}°), first placed at {:?} s, standing from {:?} s, {} loops ({} false in the graphs), {:.0} s",
                            variant.name,
                            row.beta_robot,
                            row.outcome,
                            row.frame_error_m,
                            row.frame_error_deg,
                            row.judged_by,
                            row.t_beta_ape_m,
                            row.t_beta_ape_deg,
                            row.joined_after_s,
                            row.placed_since_s,
                            row.inter_robot_loops,
                            row.false_loops_in_graphs,
                            row.run_wall_s
                        );
                        report.push(&row)?;
                        rows.push(row);
                    }
                }
            }
        }
        Ok(aliasing_markdown(settings, &rows))
    })
}
