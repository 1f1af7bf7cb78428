//! Trajectory files in the two common evaluation formats.
//!
//! * **TUM** (TUM RGB-D benchmark, also used by evo): one pose per line, `stamp tx ty tz qx qy qz qw`,
//!   with the stamp in seconds and the pose of the sensor in the world frame (`world_from_sensor`).
//!   Lines starting with `#` are comments; blank lines are ignored. Quaternions are normalised on read;
//!   a zero quaternion is an error.
//! * **KITTI** (KITTI odometry ground truth `poses/NN.txt`): one pose per line, 12 numbers = the
//!   row-major 3x4 `[R | t]` of `world_from_sensor`, no timestamps (pair with `times.txt` through
//!   [`stamp_poses`]). KITTI prints 7 significant digits, so `R` is orthonormal to ~1e-7 only: the reader
//!   **re-orthonormalises** it to the nearest rotation (SVD polar factor, see
//!   [`crate::geometry::nearest_rotation`]) and refuses matrices further than
//!   [`crate::geometry::MAX_ROTATION_DEVIATION`] from any rotation.
//!
//! Both writers print the shortest decimal form that reads back to the same `f64`.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Isometry3;

use crate::error::{IoError, write_file};
use crate::geometry::{isometry_from_3x4, isometry_from_xyz_quat, isometry_to_3x4, isometry_to_xyz_quat};
use crate::text::{Tokens, numbered_lines, read_text};

/// A timestamped pose: the sensor frame expressed in the world frame at `stamp_s` seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StampedPose {
    /// Time in seconds (the file's own epoch).
    pub stamp_s: f64,
    /// Maps sensor-frame coordinates to world-frame coordinates.
    pub world_from_sensor: Isometry3<f64>,
}

/// True for lines a trajectory reader skips: blank ones and `#` comments.
fn is_blank_or_comment(line: &str) -> bool {
    let trimmed = line.trim_start();
    trimmed.is_empty() || trimmed.starts_with('#')
}

/// Reads a TUM trajectory (`stamp tx ty tz qx qy qz qw` per line).
pub fn read_tum(path: impl AsRef<Path>) -> Result<Vec<StampedPose>, IoError> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let mut poses = Vec::new();
    for (line, content) in numbered_lines(&text) {
        if is_blank_or_comment(content) {
            continue;
        }
        let mut tokens = Tokens::new(path, line, content);
        let stamp_s = tokens.next_f64("timestamp")?;
        let t = tokens.next_f64s::<3>("translation tx ty tz")?;
        let q = tokens.next_f64s::<4>("quaternion qx qy qz qw")?;
        let world_from_sensor = isometry_from_xyz_quat(t, q).map_err(|m| tokens.error(m))?;
        tokens.finish()?;
        poses.push(StampedPose {
            stamp_s,
            world_from_sensor,
        });
    }
    Ok(poses)
}

/// Writes a TUM trajectory (with a `# timestamp tx ty tz qx qy qz qw` header line).
pub fn write_tum(path: impl AsRef<Path>, poses: &[StampedPose]) -> Result<(), IoError> {
    let mut text = String::from("# timestamp tx ty tz qx qy qz qw\n");
    for pose in poses {
        let (t, q) = isometry_to_xyz_quat(&pose.world_from_sensor);
        let _ = writeln!(
            text,
            "{} {} {} {} {} {} {} {}",
            pose.stamp_s, t[0], t[1], t[2], q[0], q[1], q[2], q[3]
        );
    }
    write_file(path.as_ref(), text.as_bytes())
}

/// Reads a KITTI pose file (12 numbers per line, row-major 3x4 `[R | t]` of `world_from_sensor`),
/// re-orthonormalising each rotation.
pub fn read_kitti_poses(path: impl AsRef<Path>) -> Result<Vec<Isometry3<f64>>, IoError> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let mut poses = Vec::new();
    for (line, content) in numbered_lines(&text) {
        if is_blank_or_comment(content) {
            continue;
        }
        let mut tokens = Tokens::new(path, line, content);
        let values = tokens.next_f64s::<12>("3x4 pose matrix entry")?;
        tokens.finish()?;
        poses.push(isometry_from_3x4(&values).map_err(|m| IoError::at_line(path, line, m))?);
    }
    Ok(poses)
}

/// Writes a KITTI pose file (12 numbers per line).
pub fn write_kitti_poses(path: impl AsRef<Path>, poses: &[Isometry3<f64>]) -> Result<(), IoError> {
    let mut text = String::new();
    for pose in poses {
        let values = isometry_to_3x4(pose);
        let line: Vec<String> = values.iter().map(|v| format!("{v:e}")).collect();
        text.push_str(&line.join(" "));
        text.push('\n');
    }
    write_file(path.as_ref(), text.as_bytes())
}

/// Pairs KITTI poses with the timestamps of `times.txt`; the two must have the same length.
/// `times_path` is only used to name the file in the error.
pub fn stamp_poses(
    poses: &[Isometry3<f64>],
    times_s: &[f64],
    times_path: impl AsRef<Path>,
) -> Result<Vec<StampedPose>, IoError> {
    if poses.len() != times_s.len() {
        return Err(IoError::invalid(
            times_path.as_ref(),
            format!("{} timestamps for {} poses", times_s.len(), poses.len()),
        ));
    }
    Ok(times_s
        .iter()
        .zip(poses)
        .map(|(&stamp_s, &world_from_sensor)| StampedPose {
            stamp_s,
            world_from_sensor,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn tum_and_kitti_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let poses: Vec<StampedPose> = (0..5)
            .map(|i| StampedPose {
                stamp_s: 1_305_031_102.175_304 + 0.1 * f64::from(i),
                world_from_sensor: Isometry3::new(
                    Vector3::new(f64::from(i), 0.5, -1.25),
                    Vector3::new(0.1, -0.2, 0.3 * f64::from(i)),
                ),
            })
            .collect();
        let tum = dir.path().join("traj.tum");
        write_tum(&tum, &poses).unwrap();
        let back = read_tum(&tum).unwrap();
        assert_eq!(back.len(), poses.len());
        for (a, b) in back.iter().zip(&poses) {
            assert_eq!(a.stamp_s, b.stamp_s);
            assert_eq!(a.world_from_sensor.translation, b.world_from_sensor.translation);
            assert!(
                a.world_from_sensor
                    .rotation
                    .angle_to(&b.world_from_sensor.rotation)
                    < 1e-12
            );
        }
        let kitti = dir.path().join("poses.txt");
        let isos: Vec<_> = poses.iter().map(|p| p.world_from_sensor).collect();
        write_kitti_poses(&kitti, &isos).unwrap();
        let back = read_kitti_poses(&kitti).unwrap();
        for (a, b) in back.iter().zip(&isos) {
            assert!((a.to_homogeneous() - b.to_homogeneous()).norm() < 1e-14);
        }
        let times: Vec<f64> = poses.iter().map(|p| p.stamp_s).collect();
        assert_eq!(stamp_poses(&back, &times, "t").unwrap().len(), 5);
        assert!(stamp_poses(&back, &times[1..], "t").is_err());
    }
}
