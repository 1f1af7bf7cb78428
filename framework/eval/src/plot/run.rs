//! The plots of a multi-robot run: `trajectories.png` (every robot in one frame, one colour each, its
//! ground truth dashed in the same colour, loop closures as thin lines, a ring where each robot
//! started), `errors.png` (each robot's position error over time) and `map.png` (the merged map
//! coloured by robot, with the trajectories and loops over it).
//!
//! The common frame is robot 0's map frame, where the back-end placed the other robots. When robot 0
//! has a ground truth, that frame is aligned once (SE(3), on robot 0's poses) onto the ground truth's,
//! so a robot misplaced by a wrong inter-robot loop shows as misplaced instead of being hidden by an
//! alignment of its own; a robot never placed in robot 0's frame is aligned on its own and says so.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Point3, Similarity3};
use skid_core::Pose;

use super::{Chart, PALETTE, PlotOptions, PlotOutput, Series, SeriesStyle, draw_chart};
use crate::error::EvalError;
use crate::{AlignmentKind, align, ape};

/// Most map points drawn; the PLY keeps them all.
const MAP_PLOT_POINTS: usize = 300_000;

/// One robot's part of a run.
#[derive(Clone, Debug, Default)]
pub struct RobotTrack {
    pub name: String,
    /// The optimised trajectory in the robot's own map frame, `(stamp_nanos, pose)`.
    pub trajectory: Vec<(u64, Pose)>,
    /// Where the robot's map frame sits in robot 0's; `None` when the back-end never placed it.
    pub map_from_robot: Option<Pose>,
    /// The ground truth at the same stamps (any subset of them), in the world frame.
    pub ground_truth: Vec<(u64, Pose)>,
    /// The robot's map points in its own map frame.
    pub map_points: Vec<[f64; 3]>,
}

/// What became of a loop closure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoopClass {
    Accepted,
    Rejected,
    Undecided,
}

/// A loop closure between two keyframe positions in robot 0's map frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopLine {
    pub class: LoopClass,
    pub from_m: [f64; 3],
    pub to_m: [f64; 3],
}

/// Everything the run plots show.
#[derive(Clone, Debug, Default)]
pub struct RunPlotData {
    pub robots: Vec<RobotTrack>,
    pub loops: Vec<LoopLine>,
}

const LOOP_STYLES: [(LoopClass, &str, [u8; 3]); 3] = [
    (LoopClass::Accepted, "accepted loops", [0, 0, 0]),
    (LoopClass::Rejected, "rejected loops", [220, 0, 220]),
    (LoopClass::Undecided, "undecided loops", [160, 160, 160]),
];

fn color(index: usize) -> [u8; 3] {
    PALETTE[index % PALETTE.len()]
}

fn xy(pose: &Pose) -> (f64, f64) {
    (pose.translation.x, pose.translation.y)
}

/// The estimate and ground truth at the stamps both have.
fn associated(track: &RobotTrack) -> (Vec<Pose>, Vec<Pose>, Vec<u64>) {
    let truth: BTreeMap<u64, Pose> = track.ground_truth.iter().copied().collect();
    let mut out = (Vec::new(), Vec::new(), Vec::new());
    for (stamp, estimate) in &track.trajectory {
        if let Some(truth) = truth.get(stamp) {
            out.0.push(*truth);
            out.1.push(*estimate);
            out.2.push(*stamp);
        }
    }
    out
}

/// The ground-truth frame from robot 0's map frame, when robot 0 has enough ground truth.
fn world_from_map(data: &RunPlotData) -> Option<Similarity3<f64>> {
    let first = data.robots.first()?;
    let (truth, estimate, _) = associated(first);
    if truth.len() < 3 {
        return None;
    }
    Some(align(&truth, &estimate, AlignmentKind::Se3).ok()?.gt_from_est)
}

fn moved(frame: &Similarity3<f64>, point: [f64; 3]) -> (f64, f64) {
    let p = frame.transform_point(&Point3::from(point));
    (p.x, p.y)
}

/// Loop segments per class, moved by `frame`.
fn loop_series(loops: &[LoopLine], frame: &Similarity3<f64>) -> Vec<Series> {
    LOOP_STYLES
        .iter()
        .filter_map(|(class, name, rgb)| {
            let points: Vec<(f64, f64)> = loops
                .iter()
                .filter(|line| line.class == *class)
                .flat_map(|line| [moved(frame, line.from_m), moved(frame, line.to_m)])
                .collect();
            (!points.is_empty()).then(|| Series {
                name: Some((*name).to_owned()),
                points,
                color: Some(*rgb),
                style: SeriesStyle::Segments,
            })
        })
        .collect()
}

/// Each robot's estimate in `frame` (robot 0's map frame moved by it), with a ring at its start; a robot
/// never placed in robot 0's frame is aligned on its own ground truth when `unplaced_alone`, else left out.
fn estimates(data: &RunPlotData, frame: &Similarity3<f64>, unplaced_alone: bool) -> Vec<Series> {
    let mut series = Vec::new();
    for (index, track) in data.robots.iter().enumerate() {
        let (name, points): (String, Vec<(f64, f64)>) = match track.map_from_robot {
            Some(map_from_robot) => (
                track.name.clone(),
                track
                    .trajectory
                    .iter()
                    .map(|(_, pose)| moved(frame, (map_from_robot * pose).translation.vector.into()))
                    .collect(),
            ),
            None if !unplaced_alone => continue,
            None => {
                let (truth, estimate, _) = associated(track);
                let Ok(aligned) = align(&truth, &estimate, AlignmentKind::Se3) else {
                    continue;
                };
                let name = format!("{} (aligned alone: never placed)", track.name);
                (name, aligned.est_aligned.iter().map(xy).collect())
            }
        };
        if let Some(start) = points.first() {
            series.push(Series {
                name: None,
                points: vec![*start],
                color: Some(color(index)),
                style: SeriesStyle::Rings,
            });
        }
        series.push(Series {
            name: Some(name),
            points,
            color: Some(color(index)),
            style: SeriesStyle::Line,
        });
    }
    series
}

/// Writes `trajectories.png`, `errors.png` (when there is ground truth) and `map.png` (when there are
/// map points) into `folder`.
pub fn write_run_plots(
    folder: &Path,
    data: &RunPlotData,
    options: &PlotOptions,
) -> Result<Vec<PlotOutput>, EvalError> {
    let mut written = Vec::new();
    let world = world_from_map(data);
    let frame = world.unwrap_or_else(Similarity3::identity);
    let mut series: Vec<Series> = Vec::new();
    if world.is_some() {
        for (index, track) in data.robots.iter().enumerate() {
            if track.ground_truth.len() >= 2 {
                series.push(Series {
                    name: Some(format!("{} ground truth", track.name)),
                    points: track.ground_truth.iter().map(|(_, pose)| xy(pose)).collect(),
                    color: Some(color(index)),
                    style: SeriesStyle::DashedLine,
                });
            }
        }
    }
    series.extend(estimates(data, &frame, true));
    series.extend(loop_series(&data.loops, &frame));
    if series.iter().any(|s| !s.points.is_empty()) {
        let title = if world.is_some() {
            "trajectories and loops (robot 0's map aligned to the ground truth)"
        } else {
            "trajectories and loops in robot 0's map frame"
        };
        let chart = Chart {
            title: title.into(),
            x_label: "x (m)".into(),
            y_label: "y (m)".into(),
            series,
            equal_aspect: true,
            ..Chart::default()
        };
        written.push(draw_chart(&folder.join("trajectories.png"), &chart, options)?);
    }
    if let Some(errors) = error_chart(data) {
        written.push(draw_chart(&folder.join("errors.png"), &errors, options)?);
    }
    if let Some(map) = map_chart(data) {
        written.push(draw_chart(&folder.join("map.png"), &map, options)?);
    }
    Ok(written)
}

/// Each robot's position error over time after its own SE(3) alignment (the ATE of `metrics.json`).
fn error_chart(data: &RunPlotData) -> Option<Chart> {
    let mut series = Vec::new();
    for (index, track) in data.robots.iter().enumerate() {
        let (truth, estimate, stamps) = associated(track);
        let Ok(result) = ape(&truth, &estimate, AlignmentKind::Se3) else {
            continue;
        };
        let start = stamps.first().copied().unwrap_or(0);
        let points = stamps
            .iter()
            .zip(&result.translation_errors_m)
            .map(|(stamp, error)| (stamp.saturating_sub(start) as f64 * 1e-9, *error))
            .collect();
        let mut line = Series::line(track.name.clone(), points);
        line.color = Some(color(index));
        series.push(line);
    }
    (!series.is_empty()).then(|| Chart {
        title: "position error after each robot's SE(3) alignment".into(),
        x_label: "time since the robot's first scan (s)".into(),
        y_label: "error (m)".into(),
        series,
        ..Chart::default()
    })
}

/// The placed robots' map points in robot 0's map frame, one colour per robot, trajectories and loops over.
fn map_chart(data: &RunPlotData) -> Option<Chart> {
    let total: usize = data
        .robots
        .iter()
        .filter(|t| t.map_from_robot.is_some())
        .map(|t| t.map_points.len())
        .sum();
    if total == 0 {
        return None;
    }
    let stride = total.div_ceil(MAP_PLOT_POINTS).max(1);
    let mut series = Vec::new();
    for (index, track) in data.robots.iter().enumerate() {
        let Some(map_from_robot) = track.map_from_robot else {
            continue;
        };
        let frame = Similarity3::from_isometry(map_from_robot, 1.0);
        series.push(Series {
            name: None,
            points: track
                .map_points
                .iter()
                .step_by(stride)
                .map(|p| moved(&frame, *p))
                .collect(),
            color: Some(color(index)),
            style: SeriesStyle::Pixels,
        });
    }
    let identity = Similarity3::identity();
    for mut line in estimates(data, &identity, false) {
        // Darker than the robot's points, so the path reads over its own map.
        line.color = line.color.map(|[r, g, b]| [r / 2, g / 2, b / 2]);
        series.push(line);
    }
    series.extend(loop_series(&data.loops, &identity));
    Some(Chart {
        title: "merged map by robot (robot 0's map frame)".into(),
        x_label: "x (m)".into(),
        y_label: "y (m)".into(),
        series,
        equal_aspect: true,
        ..Chart::default()
    })
}
