//! `skid replay FILE.jrl`: a recorded collaborative SLAM problem (JSON Robot Log, as COSMO-Bench ships
//! them) through the configured verifier and back-end plugins, the ones `skid run` builds (chosen and
//! tuned with `--set`), batch or distributed and incremental (see `skid-replay`). Prints each robot's
//! ATE, the loops kept and dropped against the file's labels and the time per update (`--json`: one JSON
//! line), and with `--out DIR` writes each robot's estimate and ground truth (TUM) and graph (g2o, vertex
//! ids the file's keys) for `skid eval`.

use std::path::Path;

use anyhow::{Context, Result};
use skid_core::{KeyframeId, Registry, Slot};
use skid_io::g2o::{Edge, PoseGraph};
use skid_io::trajectory::{StampedPose, write_tum};
use skid_replay::{ConfiguredPlugins, ReplayMode, ReplayOutcome, ReplayProblem, ReplayReport};

use super::table::{Table, show};
use crate::LayerArgs;

/// `skid replay FILE --mode batch|incremental [--out DIR] [--json]`.
pub fn replay(
    registry: &Registry,
    file: &Path,
    mode: &str,
    out: Option<&Path>,
    json: bool,
    layers: &LayerArgs,
) -> Result<()> {
    let mode = match mode {
        "batch" => ReplayMode::Batch,
        _ => ReplayMode::Incremental,
    };
    let config = skid_replay::load_config(super::sources(None, layers), mode, registry)?;
    let dataset = skid_io::jrl::read_jrl(file)?;
    let problem =
        ReplayProblem::from_dataset(&dataset).with_context(|| format!("replaying {}", file.display()))?;
    let factory = ConfiguredPlugins {
        registry,
        config: &config,
    };
    let budget = factory.budget();
    tracing::info!(
        file = %file.display(),
        robots = problem.robots.len(),
        keyframes = problem.keyframe_count(),
        loops = problem.labels.len(),
        verifier = %config.slot(Slot::Verifier).plugin,
        backend = %config.slot(Slot::Backend).plugin,
        "replaying"
    );
    let outcome = skid_replay::replay(&problem, mode, &factory, budget)
        .with_context(|| format!("replaying {}", file.display()))?;
    let report = ReplayReport::new(&problem, &outcome);
    if let Some(out) = out {
        write_outputs(out, &problem, &outcome)?;
    }
    if json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        show(&report_text(&report));
    }
    Ok(())
}

/// The report for people: a line on the run, a row per robot, a line per kind of loop.
fn report_text(report: &ReplayReport) -> String {
    let mut text = format!(
        "{} ({}): {:.2} s in the plugins; per update median {:.2} ms, p95 {:.2} ms, max {:.1} ms over {}\n",
        report.dataset,
        report.mode,
        report.total_s,
        report.updates.median_ms,
        report.updates.p95_ms,
        report.updates.max_ms,
        report.updates.updates
    );
    if report.mode == "incremental" {
        let slowest = &report.slowest_robot_updates;
        text.push_str(&format!(
            "  the slowest robot's share (its verifiers and back-end; the robots work at once): median {:.2} ms, p95 {:.2} ms, max {:.1} ms over {}\n",
            slowest.median_ms, slowest.p95_ms, slowest.max_ms, slowest.updates
        ));
    }
    let mut table = Table::new(&[
        "robot",
        "keyframes",
        "ATE m (unaligned)",
        "ATE m (aligned jointly)",
    ]);
    for robot in &report.robots {
        table.row(vec![
            robot.robot.to_string(),
            robot.keyframes.to_string(),
            format!("{:.3}", robot.ate_m),
            format!("{:.3}", robot.ate_aligned_m),
        ]);
    }
    text.push_str(&table.render());
    for (kind, counts) in [("intra-robot", &report.intra), ("inter-robot", &report.inter)] {
        text.push_str(&format!(
            "  {kind} loops: {} ({} labelled outliers); accepted {}, kept {}; labelled outliers kept {}, \
             true loops dropped {}, undecided {}\n",
            counts.loops,
            counts.labelled_outliers,
            counts.accepted,
            counts.kept,
            counts.outliers_kept,
            counts.inliers_dropped,
            counts.undecided
        ));
        if !counts.inliers_dropped_by.is_empty() {
            let by: Vec<String> = counts
                .inliers_dropped_by
                .iter()
                .map(|(place, count)| format!("{place} {count}"))
                .collect();
            text.push_str(&format!("    true loops dropped by: {}\n", by.join(", ")));
        }
    }
    text
}

/// The GTSAM key of a keyframe: the robot's letter in the top 8 bits.
fn key(problem: &ReplayProblem, id: KeyframeId) -> u64 {
    let letter = problem
        .robots
        .get(id.robot.0 as usize)
        .map_or('?', |robot| robot.letter);
    (u64::from(u32::from(letter)) << 56) | u64::from(id.index)
}

fn write_outputs(out: &Path, problem: &ReplayProblem, outcome: &ReplayOutcome) -> Result<()> {
    for (number, robot) in problem.robots.iter().enumerate() {
        let folder = out.join(format!("robot_{}", robot.letter));
        std::fs::create_dir_all(&folder).with_context(|| format!("creating {}", folder.display()))?;
        let stamped = |poses: &mut dyn Iterator<Item = (&u32, &skid_core::Pose)>| -> Vec<StampedPose> {
            poses
                .filter_map(|(index, pose)| {
                    let stamp = robot.stamps.get(index)?;
                    Some(StampedPose {
                        stamp_s: *stamp as f64 * 1e-9,
                        world_from_sensor: *pose,
                    })
                })
                .collect()
        };
        let estimate = &outcome.estimates[number];
        write_tum(folder.join("trajectory.tum"), &stamped(&mut estimate.iter()))?;
        let truth: Vec<(&u32, &skid_core::Pose)> = robot
            .ground_truth
            .iter()
            .filter(|(index, _)| estimate.contains_key(index))
            .collect();
        write_tum(folder.join("ground_truth.tum"), &stamped(&mut truth.into_iter()))?;
        let graph = outcome
            .graphs
            .get(number)
            .or_else(|| outcome.graphs.first())
            .context("the replay kept no graph")?;
        let mut g2o = PoseGraph::default();
        for (id, pose) in &graph.poses {
            g2o.vertices.insert(key(problem, *id), *pose);
        }
        let edges = graph
            .odometry
            .iter()
            .map(|m| (m.target, m.source, m.target_from_source, m.information))
            .chain(
                graph
                    .loops
                    .iter()
                    .map(|l| (l.target, l.source, l.target_from_source, l.information)),
            );
        for (target, source, from_from_to, information) in edges {
            g2o.edges.push(Edge {
                from: key(problem, target),
                to: key(problem, source),
                from_from_to,
                information,
            });
        }
        skid_io::g2o::write_g2o_3d(folder.join("pose_graph.g2o"), &g2o)?;
    }
    Ok(())
}
