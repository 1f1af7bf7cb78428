//! Reads the real point clouds and trajectories of the shared data directory and checks them against
//! the numbers stated in each folder's PROVENANCE.md; round-trips them through every cloud writer.
//!
//! Data sets (all read-only, located through `SKID_DATA_DIR`, default `<workspace>/../shared/data`):
//! * `kitti_00_lidar_frames_0000_0015`: KITTI odometry sequence 00, Velodyne HDL-64E frames 0-15 with
//!   ground truth, calibration and timestamps (Geiger, Lenz, Urtasun, "Are we ready for autonomous
//!   driving? The KITTI vision benchmark suite", CVPR 2012; CC BY-NC-SA 3.0), scans via MULLS /
//!   patchwork++.
//! * `kitti_odometry_ground_truth`: KITTI odometry ground-truth poses and times of sequences 00-10.
//! * `lidar_scan_pair_fast_gicp`: two HDL-32E scans from `koide3/fast_gicp` (BSD-3-Clause) `data/`.
//!
//! A missing data directory makes these tests fail with a message naming `SKID_DATA_DIR`.

// Test helpers outside #[test] functions unwrap too: a failure there is a test failure.

use std::path::PathBuf;

use nalgebra::Isometry3;
use skid_io::kitti::{read_kitti_bin, read_kitti_calib, read_kitti_times, write_kitti_bin};
use skid_io::pcd::{PcdData, PcdFieldKind, PcdWriteOptions, read_pcd, write_pcd};
use skid_io::ply::{PlyFormat, read_ply, write_ply};
use skid_io::trajectory::{read_kitti_poses, read_tum, stamp_poses, write_kitti_poses, write_tum};
use skid_io::{CloudReadOptions, NonFinitePolicy, data_path};

/// A path in the data directory; fails the test (naming SKID_DATA_DIR) when it is absent.
fn data(relative: &str) -> PathBuf {
    data_path(relative).unwrap_or_else(|e| panic!("{e}"))
}

const KITTI: &str = "kitti_00_lidar_frames_0000_0015";

/// Point counts of frames 0..15 from the PROVENANCE.md.
const KITTI_COUNTS: [usize; 16] = [
    124668, 124605, 124478, 124167, 123969, 123924, 123373, 122765, 122123, 121357, 121018, 120945, 120503,
    120295, 120406, 121023,
];

#[test]
fn kitti_scans_match_provenance_and_round_trip() {
    let strict = CloudReadOptions {
        non_finite: NonFinitePolicy::Error,
        drop_zero: false,
    };
    let dir = tempfile::tempdir().unwrap();
    let (mut min_range, mut max_range) = (f32::MAX, 0.0_f32);
    for (frame, expected) in KITTI_COUNTS.iter().enumerate() {
        let path = data(&format!("{KITTI}/velodyne/{frame:06}.bin"));
        let cloud = read_kitti_bin(&path, strict).unwrap();
        assert_eq!(cloud.points.len(), *expected, "frame {frame}");
        assert_eq!(cloud.report.points_in_file, *expected);
        for p in &cloud.points {
            assert!((0.0..=0.99).contains(&p.intensity), "reflectance {}", p.intensity);
            // Reflectance lies on KITTI's 0.01 grid.
            assert!((p.intensity * 100.0 - (p.intensity * 100.0).round()).abs() < 1e-3);
            min_range = min_range.min(p.range_m());
            max_range = max_range.max(p.range_m());
        }
        if frame == 0 {
            // Bit-exact round trip through every writer.
            let bin = dir.path().join("f.bin");
            write_kitti_bin(&bin, &cloud.points).unwrap();
            assert_eq!(std::fs::read(&bin).unwrap(), std::fs::read(&path).unwrap());
            for data_kind in [PcdData::Ascii, PcdData::Binary, PcdData::BinaryCompressed] {
                let pcd = dir.path().join("f.pcd");
                write_pcd(&pcd, &cloud.points, &PcdWriteOptions::new(data_kind)).unwrap();
                assert_eq!(
                    read_pcd(&pcd, strict).unwrap().points,
                    cloud.points,
                    "{data_kind:?}"
                );
            }
            for format in [
                PlyFormat::Ascii,
                PlyFormat::BinaryLittleEndian,
                PlyFormat::BinaryBigEndian,
            ] {
                let ply = dir.path().join("f.ply");
                write_ply(&ply, &cloud.points, format).unwrap();
                assert_eq!(read_ply(&ply, strict).unwrap().points, cloud.points, "{format:?}");
            }
        }
    }
    // PROVENANCE: range 1.3 m .. 80.4 m.
    assert!(
        (1.2..1.4).contains(&min_range) && (80.3..80.5).contains(&max_range),
        "{min_range} {max_range}"
    );
}

#[test]
fn kitti_calib_times_and_poses_agree() {
    let calib = read_kitti_calib(data(&format!("{KITTI}/calib.txt"))).unwrap();
    assert_eq!(calib.projections.len(), 4);
    assert!((calib.projections["P0"][(0, 0)] - 718.856).abs() < 1e-9);
    let tr = calib.cam0_from_velodyne;
    assert!((tr.translation.vector.z - -0.2921968648686).abs() < 1e-12);
    assert!((tr.translation.vector.x - -0.01198459927713).abs() < 1e-12);

    let times = read_kitti_times(data(&format!("{KITTI}/times.txt"))).unwrap();
    assert_eq!(times.len(), 16);
    assert_eq!((times[0], times[1]), (0.0, 1.037359e-01));

    let cam = read_kitti_poses(data(&format!("{KITTI}/poses.txt"))).unwrap();
    let velo = read_kitti_poses(data(&format!("{KITTI}/poses_velodyne.txt"))).unwrap();
    assert_eq!((cam.len(), velo.len()), (16, 16));
    // KITTI prints 7 digits: the stored rotations are slightly off orthonormal and are re-orthonormalised.
    let text = std::fs::read_to_string(data(&format!("{KITTI}/poses.txt"))).unwrap();
    let mut worst = 0.0_f64;
    for (line, pose) in text.lines().zip(&cam) {
        let v: Vec<f64> = line.split_whitespace().map(|t| t.parse().unwrap()).collect();
        let stored = nalgebra::Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
        let (_, deviation) = skid_io::geometry::nearest_rotation(&stored).unwrap();
        worst = worst.max(deviation);
        let read = pose.rotation.to_rotation_matrix();
        assert!((read.matrix() - stored).abs().max() < 1e-6);
        assert!(
            (read.matrix().transpose() * read.matrix() - nalgebra::Matrix3::identity())
                .abs()
                .max()
                < 1e-15
        );
    }
    assert!(
        worst > 1e-8 && worst < 1e-5,
        "largest deviation from a rotation {worst}"
    );
    // PROVENANCE: T_velo_i = Tr^-1 * T_cam_i * Tr.
    for (c, v) in cam.iter().zip(&velo) {
        let derived: Isometry3<f64> = tr.inverse() * c * tr;
        assert!((derived.to_homogeneous() - v.to_homogeneous()).abs().max() < 1e-5);
    }
    // 12.90 m travelled, ~0.86 m per frame, straight street.
    let travelled: f64 = velo
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum();
    assert!((travelled - 12.90).abs() < 0.01, "{travelled}");
    // Round trip through the TUM and KITTI writers.
    let stamped = stamp_poses(&velo, &times, "times.txt").unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_tum(dir.path().join("v.tum"), &stamped).unwrap();
    let back = read_tum(dir.path().join("v.tum")).unwrap();
    for (a, b) in back.iter().zip(&stamped) {
        assert_eq!(a.stamp_s, b.stamp_s);
        assert!(
            (a.world_from_sensor.to_homogeneous() - b.world_from_sensor.to_homogeneous())
                .abs()
                .max()
                < 1e-14
        );
    }
    write_kitti_poses(dir.path().join("v.txt"), &velo).unwrap();
    let back = read_kitti_poses(dir.path().join("v.txt")).unwrap();
    for (a, b) in back.iter().zip(&velo) {
        assert!((a.to_homogeneous() - b.to_homogeneous()).abs().max() < 1e-14);
    }
}

#[test]
fn kitti_ground_truth_sequences_have_the_stated_frame_counts() {
    // Frames per sequence 00..10 and path lengths (m) from the PROVENANCE.md.
    let frames = [4541, 1101, 4661, 801, 271, 2761, 1101, 1101, 4071, 1591, 1201];
    let lengths = [
        3724.0, 2453.0, 5067.0, 561.0, 394.0, 2206.0, 1233.0, 695.0, 3223.0, 1705.0, 920.0,
    ];
    for (sequence, (&n, &length)) in frames.iter().zip(&lengths).enumerate() {
        let poses = read_kitti_poses(data(&format!(
            "kitti_odometry_ground_truth/poses/{sequence:02}.txt"
        )))
        .unwrap();
        let times = read_kitti_times(data(&format!(
            "kitti_odometry_ground_truth/times/{sequence:02}.txt"
        )))
        .unwrap();
        assert_eq!((poses.len(), times.len()), (n, n), "sequence {sequence:02}");
        let travelled: f64 = poses
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum();
        assert!(
            (travelled - length).abs() < 1.0,
            "sequence {sequence:02}: {travelled} m"
        );
        for pose in &poses {
            let r = pose.rotation.to_rotation_matrix();
            assert!((r.matrix().transpose() * r.matrix() - nalgebra::Matrix3::identity()).norm() < 1e-12);
        }
    }
}

#[test]
fn fast_gicp_pcd_pair_matches_provenance() {
    // PROVENANCE: PCD v0.7, DATA binary, fields x y z intensity (F4); points / zero points per file.
    let mut max_intensity = 0.0_f32;
    for (name, points, zeros) in [("251370668.pcd", 69088, 5032), ("251371071.pcd", 69792, 5107)] {
        let path = data(&format!("lidar_scan_pair_fast_gicp/{name}"));
        let all = read_pcd(&path, CloudReadOptions::KEEP_ALL).unwrap();
        assert_eq!(all.header.data, PcdData::Binary);
        let names: Vec<&str> = all.header.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["x", "y", "z", "intensity"]);
        assert!(
            all.header
                .fields
                .iter()
                .all(|f| f.kind == PcdFieldKind::Float && f.size == 4)
        );
        assert_eq!(
            (all.points.len(), all.report.zero, all.report.non_finite),
            (points, zeros, 0)
        );
        max_intensity = all
            .points
            .iter()
            .map(|p| p.intensity)
            .fold(max_intensity, f32::max);
        assert!(all.points.iter().all(|p| p.intensity.fract() == 0.0));

        let valid = read_pcd(&path, CloudReadOptions::VALID_ONLY).unwrap();
        assert_eq!(valid.points.len(), points - zeros);
        assert_eq!(valid.report.dropped_zero, zeros);

        let dir = tempfile::tempdir().unwrap();
        for data_kind in [PcdData::Ascii, PcdData::Binary, PcdData::BinaryCompressed] {
            let out = dir.path().join("out.pcd");
            write_pcd(&out, &all.points, &PcdWriteOptions::new(data_kind)).unwrap();
            let back = read_pcd(&out, CloudReadOptions::KEEP_ALL).unwrap();
            assert_eq!(back.points, all.points, "{data_kind:?}");
            assert_eq!(back.report, all.report);
        }
    }
    // PROVENANCE: intensity 0-215 (integers stored as float) over the pair.
    assert_eq!(max_intensity, 215.0);
}
