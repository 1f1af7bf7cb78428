//! `skid plot RUN_DIR`: draws a run's plots again from its record (`run.mcap`), read with SKiD's own bag
//! reader: each robot's optimised path and ground truth, where `/tf_static` places its map frame in
//! robot 0's, its keyframe clouds, and the loop lines of `/loops`.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result, bail};
use skid_bag::msgs::markers::decode_marker_array;
use skid_bag::msgs::motion::{StampedPose, decode_path, decode_tf_message};
use skid_bag::msgs::point_cloud2::{CloudLayout, PointCloud2, raw_points};
use skid_bag::{Bag, MessageReader, WireReader};
use skid_core::Pose;
use skid_eval::plot::{LoopLine, PlotOptions, RobotTrack, RunPlotData, write_run_plots};

/// A recorded pose, refused when it is not finite or its quaternion has no direction.
fn pose_of(stamped: &StampedPose, path: &Path, topic: &str) -> Result<Pose> {
    skid_core::pose::pose_from_wire(&stamped.wire()).with_context(|| {
        format!(
            "{}: a pose on {topic} is not finite or has a zero quaternion",
            path.display()
        )
    })
}

/// The robot index of a `/robot<i>/…` topic or a `robot<i>/map` frame.
fn robot_index(name: &str) -> Option<usize> {
    let rest = name.trim_start_matches('/').strip_prefix("robot")?;
    rest.split('/').next()?.parse().ok()
}

/// The plot data a run record holds.
fn read_record(path: &Path) -> Result<RunPlotData> {
    let mut bag = Bag::open(path)?;
    let mut robots: BTreeMap<usize, RobotTrack> = BTreeMap::new();
    let mut loops = Vec::new();
    while let Some(message) = bag.next_message()? {
        let topic = message.connection.topic.as_str();
        let mut reader = WireReader::new(&message.data, message.connection.encoding)?;
        let context = || format!("{}: the message on {topic}", path.display());
        if topic == "/loops" {
            for marker in decode_marker_array(&mut reader).with_context(context)? {
                // Markers of other namespaces (another tool's) are not loops.
                let Some(class) = skid_runtime::loop_class_of_namespace(&marker.namespace) else {
                    continue;
                };
                for pair in marker.points.chunks_exact(2) {
                    loops.push(LoopLine {
                        class,
                        from_m: pair[0],
                        to_m: pair[1],
                    });
                }
            }
            continue;
        }
        if topic == "/tf_static" {
            for transform in decode_tf_message(&mut reader).with_context(context)? {
                if let Some(index) = robot_index(&transform.child_frame_id) {
                    robots.entry(index).or_default().map_from_robot = Some(pose_of(&transform, path, topic)?);
                }
            }
            continue;
        }
        let Some(index) = robot_index(topic) else {
            continue;
        };
        let track = robots.entry(index).or_default();
        track.name = format!("robot {index}");
        if topic.ends_with("/path") || topic.ends_with("/ground_truth") {
            let poses = decode_path(&mut reader)
                .with_context(context)?
                .iter()
                .map(|pose| Ok((pose.stamp_nanos, pose_of(pose, path, topic)?)))
                .collect::<Result<Vec<(u64, Pose)>>>()?;
            if topic.ends_with("/path") {
                track.trajectory = poses;
            } else {
                track.ground_truth = poses;
            }
        } else if topic.ends_with("/keyframes") {
            let cloud = PointCloud2::decode(&mut reader).with_context(context)?;
            let layout = CloudLayout::detect(&cloud.fields).with_context(context)?;
            let points = raw_points(&cloud, &layout).points;
            track.map_points.extend(
                points
                    .iter()
                    .map(|p| [f64::from(p.x), f64::from(p.y), f64::from(p.z)]),
            );
        }
    }
    if robots.is_empty() {
        bail!("{} holds no robot's topics (/robot<i>/path …)", path.display());
    }
    // The run thins each robot's map once before it draws map.png; so does this, or the plot drawn
    // again would be denser than the run's own.
    for track in robots.values_mut() {
        track.map_points = thinned(&track.map_points);
    }
    Ok(RunPlotData {
        robots: robots.into_values().collect(),
        loops,
    })
}

/// `points` thinned at the run's map voxel size ([`skid_runtime::MAP_VOXEL_M`]).
fn thinned(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let points: Vec<skid_core::Point> = points
        .iter()
        .map(|&[x, y, z]| skid_core::Point::new(x as f32, y as f32, z as f32))
        .collect();
    skid_geometry::voxel_downsample(&points, skid_runtime::MAP_VOXEL_M)
        .iter()
        .map(|p| [f64::from(p.x), f64::from(p.y), f64::from(p.z)])
        .collect()
}

pub fn plot(run_dir: &Path) -> Result<()> {
    let record = run_dir.join("run.mcap");
    if !record.is_file() {
        bail!(
            "{} has no run.mcap (runs write it unless output.record = false)",
            run_dir.display()
        );
    }
    let data = read_record(&record)?;
    for written in write_run_plots(run_dir, &data, &PlotOptions::default())? {
        println!("{}", written.path.display());
    }
    Ok(())
}
