//! `cargo xtask bench scale`: how SKiD's cost grows with the fleet (N = 2, 4, 8, 16 robots of the default
//! pipeline on shorter routes as N grows) and with the mission (long missions of 3 robots for 20 minutes
//! of robot time, the back-end and verifier time per keyframe read at minutes 1, 5, 10 and 20). Parameters in
//! `configs/bench/scale.toml`; the method is `skid_bench::scale`'s.

use anyhow::Context;
use skid_bench::scale::{ScaleSettings, run_fleet};
use skid_bench::scale_report::{fleet_markdown, fleet_row, long_markdown, minute_rows};

fn main() -> anyhow::Result<()> {
    skid_bench::run_profile("scale", |settings: &ScaleSettings, report, out| {
        let registry = skid_builtin::registry().context("registering the built-in plugins")?;
        let mut rows = Vec::new();
        for case in &settings.fleets {
            let mut sets = settings.sets.clone();
            sets.extend([
                format!("run.robots={}", case.robots),
                format!("run.max_scans={}", case.max_scans),
                format!("source.sim.route_length_m={}", case.route_length_m),
            ]);
            sets.extend(case.sets.iter().cloned());
            let run = run_fleet(&format!("fleet{}", case.robots), sets, &registry, out)?;
            let row = fleet_row(&run);
            eprintln!(
                "{} robots: {:.0} s wall, {:.1} CPU ms per robot-scan, {:.0} MB peak, {} inter-robot loops",
                row.robots, row.wall_s, row.cpu_ms_per_robot_scan, row.peak_rss_mb, row.inter_robot_loops
            );
            report.push(&row)?;
            rows.push(row);
        }
        let mut markdown = "# Scale\n".to_owned();
        if !rows.is_empty() {
            markdown.push_str(&format!(
                "\n## Fleet size\n\nThe default pipeline (`threads` executor) with N robots on the \
                 `explore_meet` mission, routes shortened as N grows.\n\n{}",
                fleet_markdown(&rows, out)?
            ));
        }
        for long in settings.long.iter().filter(|long| long.minutes > 0) {
            let mut sets = settings.sets.clone();
            sets.extend([
                format!("run.robots={}", long.robots),
                format!("run.max_scans={}", u64::from(long.minutes) * 600),
            ]);
            sets.extend(long.sets.iter().cloned());
            let run = run_fleet(&long.name, sets, &registry, out)?;
            let minutes = minute_rows(&run, long.minutes);
            for row in &minutes {
                let mut value = serde_json::to_value(row)?;
                if let Some(fields) = value.as_object_mut() {
                    fields.insert("mission".to_owned(), long.name.clone().into());
                }
                report.push(&value)?;
            }
            let fleet = fleet_row(&run);
            markdown.push_str(&format!(
                "\n## Long mission `{}`\n\n{} robots, {} minutes of robot time ({} keyframes, {:.0} s wall, {} inter-robot loops, ATE α {} m); back-end and verifier time per new keyframe over the minute before each checkpoint, with the work behind it: the loop candidates the verifiers judged and the loops the back-ends' graphs gained or lost.\n\n{}",
                long.name,
                long.robots,
                long.minutes,
                fleet.keyframes,
                fleet.wall_s,
                fleet.inter_robot_loops,
                fleet.ate_alpha_m.map_or_else(|| "–".to_owned(), |v| format!("{v:.3}")),
                long_markdown(&minutes, &long.checkpoints_min, &out.join(format!("long_{}_per_keyframe.png", long.name)))?
            ));
        }
        Ok(markdown)
    })
}
