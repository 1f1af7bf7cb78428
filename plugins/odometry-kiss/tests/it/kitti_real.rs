//! KISS-ICP odometry (Vizzo et al., RA-L 2023) on the 16 real KITTI 00 frames in the shared data, against
//! the LiDAR-frame ground truth (`poses_velodyne.txt`).
//!
//! The bound is loose on purpose: in these files the scans themselves show the car accelerating from
//! about 0.68 to 0.86 m per frame (a brute-force search over the forward offset between consecutive
//! scans agrees with the odometry to a few centimetres), while the ground truth says a steady 0.86 m,
//! so any scan-matching odometry ends about 1.2 m short of the ground truth here. A broken odometry
//! (no motion, or the wrong direction) is still far outside the bound.

use skid_core::slots::Odometry;
use skid_core::{PluginContext, RawPoint, Scan};
use skid_io::{CloudReadOptions, kitti, trajectory};
use skid_odometry_kiss::{KissIcpConfig, KissIcpOdometry, trajectory_errors};

#[test]
fn kitti_00_first_16_frames() {
    let folder = skid_io::data_dir().join("kitti_00_lidar_frames_0000_0015");
    let truth = trajectory::read_kitti_poses(folder.join("poses_velodyne.txt")).unwrap();
    let times_s = kitti::read_kitti_times(folder.join("times.txt")).unwrap();
    let mut odometry = KissIcpOdometry::new(
        KissIcpConfig::default(),
        &PluginContext {
            threads: 2,
            ..PluginContext::default()
        },
    )
    .unwrap();
    let mut estimate = Vec::new();
    let mut keyframes = 0;
    for (index, stamp_s) in times_s.iter().enumerate().take(16) {
        let cloud = kitti::read_kitti_bin(
            folder.join(format!("velodyne/{index:06}.bin")),
            CloudReadOptions::default(),
        )
        .unwrap();
        let scan = Scan {
            sequence: index as u32,
            stamp_nanos: (stamp_s * 1e9).round() as u64,
            points: cloud
                .points
                .iter()
                .map(|p| RawPoint::new(p.x, p.y, p.z, p.intensity, 0.0, RawPoint::UNKNOWN_RING))
                .collect(),
            ..Scan::default()
        };
        let update = odometry.register(&scan).unwrap();
        if let Some(keyframe) = &update.keyframe {
            keyframes += 1;
            assert!(keyframe.cloud.len() > 10_000 && keyframe.cloud.points.iter().all(|p| p.is_finite()));
        }
        estimate.push(update.world_from_sensor);
    }
    let errors = trajectory_errors(&estimate, &truth[..16]).unwrap();
    println!("{errors:?}, {keyframes} keyframes");
    let travelled_m = estimate[15].translation.vector.norm();
    assert!(
        (10.5..13.5).contains(&travelled_m),
        "the odometry travelled {travelled_m:.2} m (ground truth 12.9 m)"
    );
    assert!(
        errors.drift_percent < 15.0,
        "drift {:.2}% of the path",
        errors.drift_percent
    );
    assert!(errors.ate_rmse_m < 0.6, "ATE {:.3} m", errors.ate_rmse_m);
    assert!(
        errors.final_rotation_error_deg < 3.0,
        "final rotation off by {:.2}°",
        errors.final_rotation_error_deg
    );
    // Keyframes every 2 m over 12.9 m: the first scan and about five more.
    assert!((5..=8).contains(&keyframes), "{keyframes} keyframes");
}
