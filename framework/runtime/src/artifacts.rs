//! The run's derived artefacts: the merged map (every robot's keyframe clouds at their optimised poses,
//! in robot 0's frame, voxel-downsampled), each robot's pose graph as g2o, and the PNG plots (every
//! robot's trajectory and the loops against ground truth, errors over time, the map by robot).

use std::path::{Path, PathBuf};

use skid_core::slots::LoopClosure;
use skid_core::{KeyframeId, Pose};
use skid_eval::plot;
use skid_eval::plot::{LoopLine, PlotOptions, RobotTrack, RunPlotData};
use skid_io::g2o::{Edge, PoseGraph, write_g2o_3d};

use crate::error::{RuntimeError, output_error};
use crate::host::RobotHost;
use crate::map_clouds::RobotClouds;
use crate::metrics::alpha_frames;
use crate::settings::information_from_covariance;

/// g2o vertex id of a keyframe: the robot in the millions, so ids stay readable.
pub fn g2o_vertex_id(id: KeyframeId) -> u64 {
    u64::from(id.robot.0) * 1_000_000 + u64::from(id.index)
}

/// Where each robot's map frame sits in robot 0's; `None` for robots robot 0 never closed a loop with.
pub fn frames_in_alpha(robots: &[RobotHost]) -> Vec<Option<Pose>> {
    map_frames(&alpha_frames(robots))
}

/// The map frames of [`alpha_frames`]' fits.
pub(crate) fn map_frames(fits: &[Result<(Pose, usize), String>]) -> Vec<Option<Pose>> {
    fits.iter()
        .map(|fit| fit.as_ref().ok().map(|(frame, _)| *frame))
        .collect()
}

/// One robot's pose graph: every keyframe its back-end holds (its own and the peers' it was given), the
/// odometry edges between consecutive keyframes of each robot, and the accepted loops.
pub fn pose_graph(robot: &RobotHost) -> PoseGraph<Pose> {
    let mut graph = PoseGraph::default();
    let backend = robot.backend_graph();
    let keyframes = match backend {
        Some(view) => view.keyframes(),
        None => robot
            .keyframes()
            .keys()
            .map(|&index| KeyframeId {
                robot: robot.robot(),
                index,
            })
            .collect(),
    };
    for &id in &keyframes {
        let pose = backend
            .and_then(|view| view.pose(id))
            .or_else(|| robot.chains().pose(id));
        if let Some(pose) = pose {
            graph.vertices.insert(g2o_vertex_id(id), pose);
        }
    }
    for pair in keyframes.windows(2) {
        let (target, source) = (pair[0], pair[1]);
        if target.robot != source.robot {
            continue;
        }
        if let Some(relative) = robot.chains().between(target, source) {
            graph.edges.push(Edge {
                from: g2o_vertex_id(target),
                to: g2o_vertex_id(source),
                from_from_to: relative.target_from_source,
                information: information_from_covariance(&relative.covariance),
            });
        }
    }
    // A loop received from a peer before that peer's odometry reached its keyframe has no vertex yet;
    // it is left out so the file stays a valid graph. The fleet's loops in the back-end (between other
    // robots, `loops.fleet_loops`) are edges of the graph too.
    let has_vertex = |id: KeyframeId| graph.vertices.contains_key(&g2o_vertex_id(id));
    let fleet_loops = robot.fleet_loops_in_graph();
    let drawable: Vec<&LoopClosure> = robot
        .accepted_loops()
        .values()
        .chain(&fleet_loops)
        .filter(|closure| has_vertex(closure.target) && has_vertex(closure.source))
        .collect();
    for closure in drawable {
        graph.edges.push(Edge {
            from: g2o_vertex_id(closure.target),
            to: g2o_vertex_id(closure.source),
            from_from_to: closure.target_from_source,
            information: closure.information,
        });
    }
    if let Some(&first) = keyframes.first() {
        graph.fixed.push(g2o_vertex_id(first));
    }
    graph
}

/// Writes each robot's pose graph to `<robot folder>/pose_graph.g2o`.
pub fn write_pose_graphs(folder: &Path, robots: &[RobotHost]) -> Result<Vec<PathBuf>, RuntimeError> {
    let mut written = Vec::new();
    for robot in robots {
        let path = folder
            .join(format!("robot{}", robot.robot().0))
            .join("pose_graph.g2o");
        write_g2o_3d(&path, &pose_graph(robot)).map_err(|e| output_error(&path, e))?;
        written.push(path);
    }
    Ok(written)
}

/// Everything the run plots show, from the robots' final state: trajectories in each robot's map frame,
/// where robot 0's frame holds each, ground truth, each robot's keyframe clouds (voxel-downsampled) and
/// the loops placed in robot 0's frame.
pub(crate) fn run_plot_data(
    robots: &[RobotHost],
    clouds: &[RobotClouds],
    frames: &[Option<Pose>],
) -> RunPlotData {
    let tracks = robots
        .iter()
        .zip(clouds)
        .zip(frames)
        .map(|((robot, clouds), frame)| {
            let map_points = clouds
                .map
                .iter()
                .map(|p| [f64::from(p.x), f64::from(p.y), f64::from(p.z)])
                .collect();
            RobotTrack {
                name: format!("robot {}", robot.robot().0),
                trajectory: robot.optimised_trajectory(),
                map_from_robot: *frame,
                ground_truth: robot
                    .scans()
                    .iter()
                    .filter_map(|scan| Some((scan.stamp_nanos, scan.ground_truth?)))
                    .collect(),
                map_points,
            }
        })
        .collect();
    let loops = crate::loop_lines::placed_loops(robots, frames)
        .into_iter()
        .map(|line| LoopLine {
            class: crate::loop_lines::LOOP_CLASSES[line.class].2,
            from_m: line.target_m,
            to_m: line.source_m,
        })
        .collect();
    RunPlotData {
        robots: tracks,
        loops,
    }
}

/// Writes `trajectories.png`, `errors.png` and `map.png` (see [`skid_eval::plot::write_run_plots`]).
pub(crate) fn write_plots(
    folder: &Path,
    robots: &[RobotHost],
    clouds: &[RobotClouds],
    frames: &[Option<Pose>],
) -> Result<(), RuntimeError> {
    let data = run_plot_data(robots, clouds, frames);
    plot::write_run_plots(folder, &data, &PlotOptions::default()).map_err(|e| output_error(folder, e))?;
    Ok(())
}
