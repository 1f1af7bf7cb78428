//! The run's derived artefacts: the merged map (every robot's keyframe clouds at their optimised poses,
//! in robot 0's frame, voxel-downsampled), each robot's pose graph as g2o, and the PNG plots (top-down
//! trajectories against ground truth; the map).

use std::path::{Path, PathBuf};

use skid_core::slots::{GraphView, LoopClosure};
use skid_core::{KeyframeId, Point, Pose};
use skid_eval::plot::PlotOptions;
use skid_eval::{AlignmentKind, ape, plot};
use skid_io::g2o::{Edge, PoseGraph, write_g2o_3d};

use crate::RuntimeError;
use crate::host::RobotHost;
use crate::metrics::{alpha_frames, associated};
use crate::settings::{information_from_covariance, loop_information};

/// Edge length of the merged map's voxels, metres.
pub const MAP_VOXEL_M: f32 = 0.5;

/// Most points drawn in the map plot; the PLY keeps them all.
const PLOT_POINTS: usize = 300_000;

/// g2o vertex id of a keyframe: the robot in the millions, so ids stay readable.
pub fn g2o_vertex_id(id: KeyframeId) -> u64 {
    u64::from(id.robot.0) * 1_000_000 + u64::from(id.index)
}

pub(crate) fn output_error(path: &Path, message: impl ToString) -> RuntimeError {
    RuntimeError::Output {
        path: path.to_owned(),
        message: message.to_string(),
    }
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

/// The merged, voxel-downsampled map in robot 0's frame, from the robots whose frame is known there.
pub fn merged_map(robots: &[RobotHost], frames: &[Option<Pose>]) -> Vec<Point> {
    let mut map: Vec<Point> = Vec::new();
    for (robot, frame) in robots.iter().zip(frames) {
        let Some(alpha_from_robot) = frame else { continue };
        for (&index, keyframe) in &robot.keyframes {
            let Some(pose) = robot.keyframe_pose(index) else {
                continue;
            };
            let alpha_from_sensor = alpha_from_robot * pose;
            let cloud = keyframe.cloud.view().transformed(&alpha_from_sensor);
            map.extend_from_slice(&cloud.points);
            // Downsample as the map grows so memory stays bounded by the explored volume.
            if map.len() > 4_000_000 {
                map = skid_geometry::voxel_downsample(&map, MAP_VOXEL_M);
            }
        }
    }
    skid_geometry::voxel_downsample(&map, MAP_VOXEL_M)
}

/// One robot's pose graph: every keyframe its back-end holds (its own and the peers' it was given), the
/// odometry edges between consecutive keyframes of each robot, and the accepted loops.
pub fn pose_graph(robot: &RobotHost) -> PoseGraph<Pose> {
    let mut graph = PoseGraph::default();
    let backend: Option<&dyn GraphView> = robot.plugins.backend.as_ref().map(|b| b.graph());
    let keyframes = match backend {
        Some(view) => view.keyframes(),
        None => robot
            .keyframes
            .keys()
            .map(|&index| KeyframeId {
                robot: robot.robot,
                index,
            })
            .collect(),
    };
    for &id in &keyframes {
        let pose = backend
            .and_then(|view| view.pose(id))
            .or_else(|| robot.chains.pose(id));
        if let Some(pose) = pose {
            graph.vertices.insert(g2o_vertex_id(id), pose);
        }
    }
    for pair in keyframes.windows(2) {
        let (target, source) = (pair[0], pair[1]);
        if target.robot != source.robot {
            continue;
        }
        if let Some(relative) = robot.chains.between(target, source) {
            graph.edges.push(Edge {
                from: g2o_vertex_id(target),
                to: g2o_vertex_id(source),
                from_from_to: relative.target_from_source,
                information: information_from_covariance(&relative.covariance),
            });
        }
    }
    // A loop received from a peer before that peer's odometry reached its keyframe has no vertex yet;
    // it is left out so the file stays a valid graph.
    let has_vertex = |id: KeyframeId| graph.vertices.contains_key(&g2o_vertex_id(id));
    let drawable: Vec<&LoopClosure> = robot
        .loops
        .values()
        .filter(|closure| has_vertex(closure.target) && has_vertex(closure.source))
        .collect();
    for closure in drawable {
        graph.edges.push(Edge {
            from: g2o_vertex_id(closure.target),
            to: g2o_vertex_id(closure.source),
            from_from_to: closure.target_from_source,
            information: loop_information(),
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
            .join(format!("robot{}", robot.robot.0))
            .join("pose_graph.g2o");
        write_g2o_3d(&path, &pose_graph(robot)).map_err(|e| output_error(&path, e))?;
        written.push(path);
    }
    Ok(written)
}

/// Writes `trajectories.png` (each robot after its own SE(3) alignment, over its ground truth) and
/// `map.png` (the merged map seen from above with the robots' trajectories in robot 0's frame).
pub fn write_plots(
    folder: &Path,
    robots: &[RobotHost],
    frames: &[Option<Pose>],
    map: &[Point],
) -> Result<(), RuntimeError> {
    let options = PlotOptions::default();
    let mut named: Vec<(String, Vec<Pose>)> = Vec::new();
    for robot in robots {
        let (truth, estimate) = associated(robot);
        if truth.len() < 3 {
            continue;
        }
        if let Ok(result) = ape(&truth, &estimate, AlignmentKind::Se3) {
            named.push((format!("robot {} ground truth", robot.robot.0), truth));
            named.push((format!("robot {} estimate", robot.robot.0), result.est_aligned));
        }
    }
    if !named.is_empty() {
        let path = folder.join("trajectories.png");
        let series: Vec<(&str, &[Pose])> = named.iter().map(|(n, p)| (n.as_str(), p.as_slice())).collect();
        plot::trajectory_plot(
            &path,
            "trajectories (each aligned to its ground truth)",
            &series,
            false,
            &options,
        )
        .map_err(|e| output_error(&path, e))?;
    }
    if map.is_empty() {
        return Ok(());
    }
    let stride = map.len().div_ceil(PLOT_POINTS).max(1);
    let points: Vec<[f64; 3]> = map
        .iter()
        .step_by(stride)
        .map(|p| [f64::from(p.x), f64::from(p.y), f64::from(p.z)])
        .collect();
    let in_alpha: Vec<(String, Vec<Pose>)> = robots
        .iter()
        .zip(frames)
        .filter_map(|(robot, frame)| {
            let frame = (*frame)?;
            let poses = robot
                .optimised_trajectory()
                .iter()
                .map(|(_, pose)| frame * pose)
                .collect();
            Some((format!("robot {}", robot.robot.0), poses))
        })
        .collect();
    let series: Vec<(&str, &[Pose])> = in_alpha.iter().map(|(n, p)| (n.as_str(), p.as_slice())).collect();
    let path = folder.join("map.png");
    plot::point_map(&path, "merged map (robot 0's frame)", &points, &series, &options)
        .map_err(|e| output_error(&path, e))?;
    Ok(())
}
