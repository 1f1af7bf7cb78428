//! `cargo xtask bench relocalise`: a robot placing itself in a prior map, from starts on and off the
//! mapped routes, with another sensor and another season; and sessions of other days and of far places
//! merged with the map. Parameters in `configs/bench/relocalise.toml`;
//! the method is `skid_bench::relocalise`'s. Run outputs go to `runs/` under the output folder.

use anyhow::Context;
use skid_bench::relocalise::{
    RelocaliseSettings, fleet_markdown, map_world, mission_markdown, relocalise_markdown, run_fleet_trials,
    run_mission_comparison, run_trials,
};
use skid_bench::session_merge::{merge_markdown, run_merges};

fn main() -> anyhow::Result<()> {
    skid_bench::run_profile("relocalise", |settings: &RelocaliseSettings, report, out| {
        let registry = skid_builtin::registry().context("registering the built-in plugins")?;
        let session = map_world(settings, &registry, out)?;
        let rows = run_trials(settings, &session, &registry, out, |row| {
            eprintln!(
                "trial {} from junction {} ({}): localised {} after {:?} m / {:?} s, error {:?} m {:?}°{}, {:.1} ms/scan (SLAM alone {:?}), {:.0} s",
                row.trial,
                row.start_junction,
                row.kind,
                row.localised,
                row.first_fix_distance_m,
                row.first_fix_s,
                row.error_m,
                row.error_deg,
                if row.false_fix { " FALSE FIX" } else { "" },
                row.loop_ms_per_scan,
                row.slam_loop_ms_per_scan,
                row.run_wall_s
            );
            report.push(row)
        })?;
        let fleet = run_fleet_trials(settings, &session, &registry, out, |row| {
            eprintln!(
                "fleet trial {} robot {} ({}): localised {} via {:?}, error {:?} m {:?}°{}",
                row.trial,
                row.robot,
                row.kind,
                row.localised,
                row.via_robot,
                row.error_m,
                row.error_deg,
                if row.false_fix { " FALSE FIX" } else { "" }
            );
            report.push(row)
        })?;
        let mission = if settings.mission_comparison {
            run_mission_comparison(settings, &session, &registry, out)?
        } else {
            Vec::new()
        };
        for row in &mission {
            eprintln!(
                "mission, {}: {:.1} ms/robot-scan, {} of {} localised, {} false fixes, worst {:?}, {:.0} s",
                row.mode,
                row.loop_ms_per_scan,
                row.localised,
                row.robots,
                row.false_fixes,
                row.worst_error,
                row.wall_s
            );
            report.push(row)?;
        }
        let merges = run_merges(settings, &session, &registry, out, |row| {
            eprintln!(
                "merge {} ({}): placed {}, {} of {} robots localised, {} loops, error {:?} m {:?}°{}, {:.1} s",
                row.session,
                row.kind,
                row.placed,
                row.robots_localised,
                row.robots,
                row.loops,
                row.error_m,
                row.error_deg,
                if row.false_merge { " FALSE MERGE" } else { "" },
                row.merge_s
            );
            report.push(row)
        })?;
        Ok(format!(
            "{}\n{}\n{}\n{}",
            relocalise_markdown(settings, &rows),
            fleet_markdown(&fleet),
            mission_markdown(&mission),
            merge_markdown(&merges)
        ))
    })
}
