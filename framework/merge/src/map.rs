//! The joined session's map: every placed keyframe's cloud moved into the joined map frame and thinned
//! at the run's map voxel, for `map.ply` beside the session.

use std::path::Path;

use skid_core::Point;
use skid_session::{Session, SessionError};

/// Points gathered before an intermediate thinning, so memory stays bounded by the mapped volume.
const THIN_ABOVE_POINTS: usize = 4_000_000;

/// The map of `session` (read from `dir`), thinned at `voxel_m`.
pub fn session_map(dir: &Path, session: &Session, voxel_m: f32) -> Result<Vec<Point>, SessionError> {
    let mut map: Vec<Point> = Vec::new();
    for robot in &session.robots {
        for keyframe in &robot.keyframes {
            let Some(pose) = robot.session_from_sensor(keyframe) else {
                continue;
            };
            let points = skid_session::read_keyframe_cloud(dir, robot, keyframe)?;
            let cloud = skid_core::Cloud::new(points);
            map.extend(cloud.view().transformed(&pose).points);
            if map.len() > THIN_ABOVE_POINTS {
                map = skid_geometry::voxel_downsample(&map, voxel_m);
            }
        }
    }
    Ok(skid_geometry::voxel_downsample(&map, voxel_m))
}
