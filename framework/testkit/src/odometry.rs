//! Conformance of odometry plugins: a known synthetic motion through a static scene is recovered, the
//! first scan is a keyframe with a finite sensor-frame cloud, and bad scans (empty, too few points, NaN,
//! a stamp going backwards) give an error without corrupting the estimator.

use skid_core::slots::Odometry;
use skid_core::{Pose, RawPoint, Scan};

use crate::pose_error;
use crate::scene::{Scene, planar_pose};

/// How close the recovered trajectory must be.
#[derive(Clone, Copy, Debug)]
pub struct OdometryExpectations {
    /// Largest final position error, in metres (the path is 20 m long).
    pub max_translation_error_m: f64,
    /// Largest final rotation error, in degrees (the path turns 40°).
    pub max_rotation_error_deg: f64,
}

impl Default for OdometryExpectations {
    fn default() -> Self {
        Self {
            max_translation_error_m: 0.3,
            max_rotation_error_deg: 1.0,
        }
    }
}

/// The ground-truth pose of synthetic scan `index`: 0.5 m forward and 1° left per scan, 1.8 m up.
pub fn synthetic_pose(index: u32) -> Pose {
    let yaw = f64::from(index).to_radians();
    // Integrate the arc so consecutive poses differ by 0.5 m along the current heading.
    let (mut x, mut y) = (0.0, 0.0);
    for step in 0..index {
        let heading = f64::from(step).to_radians();
        x += 0.5 * heading.cos();
        y += 0.5 * heading.sin();
    }
    planar_pose(x, y, 1.8, yaw)
}

/// Synthetic scan `index` of the static scene, with ground truth.
pub fn synthetic_scan(scene: &Scene, index: u32) -> Scan {
    let pose = synthetic_pose(index);
    Scan {
        sequence: index,
        stamp_nanos: u64::from(index) * 100_000_000,
        points: scene.sample_raw(&pose, 20_000, 60.0, 1000 + u64::from(index)),
        ground_truth_world_from_sensor: Some(pose),
        ..Scan::default()
    }
}

/// Runs the odometry contract on a fresh instance from `make`.
pub fn check_odometry(mut make: impl FnMut() -> Box<dyn Odometry>, expect: OdometryExpectations) {
    let scene = Scene::new(42, 80.0);
    let mut odometry = make();
    let scans = 41;
    let mut last = Pose::identity();
    for index in 0..scans {
        let update = odometry
            .register(&synthetic_scan(&scene, index))
            .expect("a good scan registers");
        if index == 0 {
            let keyframe = update.keyframe.as_ref().expect("the first scan is a keyframe");
            assert!(!keyframe.cloud.is_empty(), "the first keyframe has points");
            assert!(keyframe.cloud.points.iter().all(|p| p.is_finite()));
        }
        last = update.world_from_sensor;
    }
    let first_truth = synthetic_pose(0);
    let truth = first_truth.inverse() * synthetic_pose(scans - 1);
    let (translation_m, rotation_deg) = pose_error(&truth, &last);
    assert!(
        translation_m <= expect.max_translation_error_m && rotation_deg <= expect.max_rotation_error_deg,
        "final pose off by {translation_m:.3} m and {rotation_deg:.3}° (allowed {} m, {}°)",
        expect.max_translation_error_m,
        expect.max_rotation_error_deg
    );

    // Bad input on a fresh instance: errors, and the estimator still works afterwards.
    let mut odometry = make();
    odometry.register(&synthetic_scan(&scene, 0)).expect("first scan");
    let mut empty = synthetic_scan(&scene, 1);
    empty.points.clear();
    assert!(odometry.register(&empty).is_err(), "an empty scan is an error");
    let mut tiny = synthetic_scan(&scene, 1);
    tiny.points.truncate(5);
    assert!(
        odometry.register(&tiny).is_err(),
        "a scan with 5 points is an error"
    );
    let mut backwards = synthetic_scan(&scene, 1);
    backwards.stamp_nanos = 0;
    assert!(
        odometry.register(&backwards).is_err(),
        "a stamp that does not advance is an error"
    );
    let mut with_nan = synthetic_scan(&scene, 1);
    with_nan
        .points
        .push(RawPoint::new(f32::NAN, 0.0, 0.0, 0.0, 0.0, 0));
    with_nan
        .points
        .push(RawPoint::new(1.0, f32::INFINITY, 0.0, 0.0, 0.0, 0));
    let update = odometry
        .register(&with_nan)
        .expect("NaN points are dropped, the scan still registers");
    assert!(
        update
            .world_from_sensor
            .translation
            .vector
            .iter()
            .all(|v| v.is_finite())
    );
    let (translation_m, _) = pose_error(
        &(first_truth.inverse() * synthetic_pose(1)),
        &update.world_from_sensor,
    );
    assert!(
        translation_m < 0.2,
        "after rejected scans the estimate is intact (off by {translation_m:.3} m)"
    );
}
