//! `skid run` with `[deploy] robot = N`: one robot of the fleet in this process, in real time, talking
//! to the other robots' processes through the configured transport (`zenoh` on a real network), as in
//! the distributed setting of the SKiD-SLAM paper (Sec. III). Outputs go to
//! `<output_dir>/<name>-robot<N>/`.

use anyhow::Result;
use skid_config::ResolvedConfig;
use skid_core::{Registry, Slot};

/// Builds and runs robot `deploy.robot`, writes its outputs and prints its summary as JSON.
pub fn run_robot(
    registry: &Registry,
    config: ResolvedConfig,
    viewers: &super::viewers::Viewers,
) -> Result<()> {
    tracing::info!(
        run = %config.run.name,
        robot = ?config.deploy.robot,
        robots = config.run.robots,
        transport = %config.slot(Slot::Transport).plugin,
        playback_speed = config.deploy.playback_speed,
        "starting one robot of the fleet"
    );
    let mut robot = skid_runtime::SingleRobot::build(config, registry)?;
    let _viewers = viewers.attach(robot.fleet_mut())?;
    let started = std::time::Instant::now();
    let mut last_report = started;
    let outcome = robot.run(|scans| {
        // Several robots may share a terminal: a log line every few seconds rather than a bar.
        if last_report.elapsed().as_secs_f64() >= 2.0 {
            tracing::info!(scans, "running");
            last_report = std::time::Instant::now();
        }
    });
    let summary = match outcome {
        Ok(summary) => summary,
        Err(error) => {
            // What exists at the stop goes into the incomplete folder, as for a whole fleet.
            let reason = error.to_string();
            let partial = skid_runtime::RunSummary::interrupted(
                robot.fleet(),
                started.elapsed().as_secs_f64(),
                &reason,
            );
            tracing::info!(%reason, "the robot stopped early; writing what it has");
            if let Err(write_error) = skid_runtime::write_partial_outputs(robot.fleet(), &partial) {
                tracing::warn!(error = %write_error, "could not write the partial outputs");
            }
            let config = robot.fleet().config.clone();
            drop(robot);
            return Err(super::abandoned(&config, error));
        }
    };
    let (folder, metrics) = skid_runtime::write_outputs(robot.fleet(), &summary)?;
    tracing::info!(folder = %folder.display(), wall_s = summary.wall_s, "finished");
    println!("{}", serde_json::to_string(&summary)?);
    super::table::show(&super::table::run_table(&summary, &metrics, &folder));
    super::check_every_robot_registered(&summary)
}
