//! The `lio` filter on simulated sequences with the simulator's noisy 200 Hz IMU: the start-up slide
//! of the default planetary world (smooth terrain leaves LiDAR-only registration unconstrained along the
//! ground) is gone, gravity and the gyroscope bias converge, a second without LiDAR is bridged by the
//! IMU, and a broken IMU stream (NaN samples, stamps going backwards, a 2 s gap) is survived.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test helpers fail loudly by design.

use nalgebra::Vector3;
use skid_core::slots::{Odometry, Source};
use skid_core::{PluginContext, Pose, Scan};
use skid_odometry_lio::{LioConfig, LioOdometry};
use skid_sim::{SimConfig, SimSource};

fn scans(world: &str, robot: u32, count: u32) -> Vec<Scan> {
    let config = SimConfig {
        world: world.to_owned(),
        frames: count,
        ..SimConfig::default()
    };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut source = SimSource::new(&config, robot, threads).unwrap();
    let mut scans = Vec::new();
    while let Some(scan) = source.next_scan().unwrap() {
        scans.push(scan);
    }
    scans
}

fn path_length(poses: &[Pose]) -> f64 {
    poses
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum()
}

/// Runs a fresh filter over `scans`; refused scans are skipped as the runtime skips them.
fn run(scans: &[Scan]) -> (LioOdometry, Vec<Pose>, Vec<Pose>) {
    let context = PluginContext {
        threads: 2,
        ..PluginContext::default()
    };
    let mut odometry = LioOdometry::new(LioConfig::default(), &context).unwrap();
    let (mut estimate, mut truth) = (Vec::new(), Vec::new());
    for scan in scans {
        if let Ok(update) = odometry.register(scan) {
            estimate.push(update.world_from_sensor);
            truth.push(scan.ground_truth_world_from_sensor.unwrap());
        }
    }
    (odometry, estimate, truth)
}

/// Final position error after aligning the first poses, in metres.
fn final_error_m(estimate: &[Pose], truth: &[Pose]) -> f64 {
    let align = truth[0] * estimate[0].inverse();
    let last = estimate.len() - 1;
    ((align * estimate[last]).translation.vector - truth[last].translation.vector).norm()
}

#[test]
fn the_planetary_start_up_slide_is_gone_and_the_states_converge() {
    // Robot 1 of the default run, which LiDAR-only odometry saw slide 22.8 m in these 100 scans.
    let scans = scans("planetary", 1, 100);
    let (odometry, estimate, truth) = run(&scans);
    assert_eq!(estimate.len(), scans.len());
    let (estimated, true_length) = (path_length(&estimate), path_length(&truth));
    assert!(
        (estimated - true_length).abs() <= 0.02 * true_length.max(1.0),
        "path {estimated:.2} m against {true_length:.2} m"
    );
    assert!(
        final_error_m(&estimate, &truth) < 0.5,
        "final error {:.3} m",
        final_error_m(&estimate, &truth)
    );
    assert!(odometry.initialised());
    // Gravity: its magnitude within 0.05 m/s² of 9.80665 (the accelerometer's turn-on bias is 0.03 m/s²
    // per axis, which the static initialisation cannot tell from gravity) and its direction, in the
    // world frame (the first sensor frame), within 1° of the truth's.
    let state = odometry.state();
    let gravity_world_truth = truth[0].rotation.inverse() * Vector3::new(0.0, 0.0, -9.80665);
    let angle_deg = state.gravity.angle(&gravity_world_truth).to_degrees();
    assert!(
        (state.gravity.norm() - 9.80665).abs() < 0.05,
        "{:?}",
        state.gravity
    );
    assert!(angle_deg < 1.0, "gravity off by {angle_deg:.3}°");
    // The gyroscope bias: the simulator draws 0.002 rad/s per axis at turn-on; within 5e-4 rad/s.
    assert!(state.gyro_bias.norm() < 0.01, "{:?}", state.gyro_bias);
}

#[test]
fn a_second_without_lidar_is_bridged_by_the_imu() {
    let mut scans = scans("cave", 0, 90);
    // Scans 40..50 lose their points (the LiDAR drops out for 1 s); their IMU samples still arrive.
    for scan in &mut scans[40..50] {
        scan.points.clear();
    }
    let (odometry, estimate, truth) = run(&scans);
    assert_eq!(estimate.len(), scans.len() - 10, "the empty scans are refused");
    let error = final_error_m(&estimate, &truth);
    let length = path_length(&truth);
    assert!(
        error < 0.02 * length + 0.1,
        "final error {error:.3} m over {length:.1} m"
    );
    assert_eq!(odometry.counters().unconstrained_scans, 0);
}

#[test]
fn a_broken_imu_stream_is_survived_with_warnings() {
    let mut scans = scans("urban", 0, 80);
    // NaN samples, a pair of samples out of order, and a 2 s stretch without any sample.
    scans[20].imu[3].accel_mps2[0] = f64::NAN;
    scans[21].imu[5].gyro_radps[2] = f64::INFINITY;
    scans[25].imu.swap(2, 7);
    for scan in &mut scans[40..60] {
        scan.imu.clear();
    }
    let (odometry, estimate, truth) = run(&scans);
    assert_eq!(estimate.len(), scans.len());
    assert!(
        estimate
            .iter()
            .all(|p| p.translation.vector.iter().all(|v| v.is_finite()))
    );
    let counters = odometry.counters();
    assert!(counters.bad_imu_samples >= 2, "{counters:?}");
    assert!(counters.imu_gaps >= 1, "{counters:?}");
    let error = final_error_m(&estimate, &truth);
    assert!(
        error < 0.03 * path_length(&truth) + 0.2,
        "final error {error:.3} m"
    );
}
