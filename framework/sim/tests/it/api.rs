//! The simulator's public contract: configuration errors, determinism, route overlap patterns,
//! motion limits, IMU consistency, the `sim` plugin, KITTI export and PNG preview.

use crate::common;

use nalgebra::Vector3;
use skid_core::{Params, PluginContext, Registry, RobotId};
use skid_sim::{
    MAX_ROBOTS, Overlap, SimConfig, SimError, SimSource, World, WorldKind, export_fleet_kitti, export_kitti,
    plan_route, preview_fleet_png,
};

fn small(world: &str) -> SimConfig {
    SimConfig {
        world: world.to_owned(),
        sensor: "vlp16".to_owned(),
        robots: 6,
        frames: 3,
        ..SimConfig::default()
    }
}

#[test]
fn bad_settings_are_clear_errors() {
    let error = SimSource::new(
        &SimConfig {
            world: "moon".into(),
            ..SimConfig::default()
        },
        0,
        1,
    )
    .unwrap_err();
    assert!(matches!(error, SimError::UnknownWorld { .. }));
    assert!(
        error.to_string().contains("moon") && error.to_string().contains("planetary, cave, urban"),
        "{error}"
    );
    let error = SimSource::new(
        &SimConfig {
            sensor: "hdl-32".into(),
            ..SimConfig::default()
        },
        0,
        1,
    )
    .unwrap_err();
    assert!(
        error.to_string().contains("hdl-32") && error.to_string().contains("avia"),
        "{error}"
    );
    for robots in [0, MAX_ROBOTS + 1] {
        let error = SimSource::new(
            &SimConfig {
                robots,
                ..SimConfig::default()
            },
            0,
            1,
        )
        .unwrap_err();
        assert!(matches!(error, SimError::RobotCount { .. }), "{error}");
        assert!(error.to_string().contains("1 to 16"), "{error}");
    }
    let error = SimSource::new(
        &SimConfig {
            robots: 2,
            ..SimConfig::default()
        },
        2,
        1,
    )
    .unwrap_err();
    assert!(error.to_string().contains("robot index 2"), "{error}");
    let error = SimSource::new(
        &SimConfig {
            speed_mps: -1.0,
            ..SimConfig::default()
        },
        0,
        1,
    )
    .unwrap_err();
    assert!(error.to_string().contains("speed_mps"), "{error}");

    // An output folder below a regular file cannot be created.
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let error = export_fleet_kitti(blocker.join("out"), &small("urban"), 1).unwrap_err();
    assert!(
        matches!(error, SimError::Io { .. }) && error.to_string().contains("file/out"),
        "{error}"
    );
    let error = preview_fleet_png(blocker.join("preview.png"), &small("urban"), 32).unwrap_err();
    assert!(error.to_string().contains("preview.png"), "{error}");
}

#[test]
fn the_plugin_is_registered_and_checks_its_parameters() {
    let mut registry = Registry::new();
    skid_sim::register(&mut registry).unwrap();
    assert!(registry.source.get("sim").is_ok());
    let params = Params::from_toml_str("world = \"urban\"\nsensor = \"os1-32\"\nframes = 2").unwrap();
    let context = PluginContext {
        robot: RobotId(1),
        fleet_size: 2,
        threads: 2,
        ..PluginContext::default()
    };
    let mut source = registry.source.create("sim", &params, &context).unwrap();
    assert_eq!(source.remaining_hint(), Some(2));
    let scan = source.next_scan().unwrap().unwrap();
    assert_eq!(scan.robot, RobotId(1));
    assert!(scan.ground_truth_world_from_sensor.is_some() && !scan.points.is_empty());
    assert!(source.next_scan().unwrap().is_some() && source.next_scan().unwrap().is_none());

    let unknown = Params::from_toml_str("wrld = \"urban\"").unwrap();
    let error = registry
        .source
        .create("sim", &unknown, &context)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(error.contains("wrld"), "{error}");
    let bad_world = Params::from_toml_str("world = \"mars\"").unwrap();
    let error = registry
        .source
        .create("sim", &bad_world, &context)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(error.contains("mars"), "{error}");
}

#[test]
fn simulation_is_deterministic_and_seeded() {
    let config = SimConfig {
        world: "urban".into(),
        sensor: "avia".into(),
        robots: 1,
        frames: 2,
        ..SimConfig::default()
    };
    let a: Vec<_> = SimSource::new(&config, 0, 2).unwrap().collect();
    let b: Vec<_> = SimSource::new(&config, 0, 1).unwrap().collect();
    assert_eq!(a.len(), 2);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.points, y.points, "threads must not change the result");
        assert_eq!(x.imu, y.imu);
        assert_eq!(x.ground_truth_world_from_sensor, y.ground_truth_world_from_sensor);
    }
    let other = SimSource::new(&SimConfig { seed: 8, ..config }, 0, 1)
        .unwrap()
        .scan_at(1);
    assert_ne!(other.points, a[1].points);
}

#[test]
fn routes_overlap_in_the_ways_that_matter() {
    for kind in WorldKind::ALL {
        let world = common::world(kind);
        let routes: Vec<_> = (0..6).map(|robot| plan_route(&world, 7, robot, 600.0)).collect();
        let roles: Vec<&str> = routes.iter().map(|r| r.role.as_str()).collect();
        assert_eq!(roles, Overlap::FOR_ROBOT.map(Overlap::name).to_vec());
        let length = |line: &[[f64; 3]]| {
            line.windows(2)
                .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
                .sum::<f64>()
        };
        let near =
            |p: [f64; 3], line: &[[f64; 3]]| line.iter().any(|q| (p[0] - q[0]).hypot(p[1] - q[1]) < 3.0);
        let shared = |a: &[[f64; 3]], b: &[[f64; 3]]| {
            a.iter().filter(|p| near(**p, b)).count() as f64 / a.len() as f64
        };
        let leader = &routes[0].centre_line;
        assert!(
            length(leader) >= 550.0 && length(leader) < 1200.0,
            "{kind}: leader drives {} m",
            length(leader)
        );
        // Reverse: the same road, the other way round.
        let reverse = &routes[1].centre_line;
        assert!((reverse[0][0] - leader[leader.len() - 1][0]).abs() < 1e-9 && shared(reverse, leader) > 0.99);
        // Same direction: a later stretch of the leader's road, in the leader's direction.
        let same = &routes[2].centre_line;
        assert!(
            shared(same, leader) > 0.3,
            "{kind}: same-direction overlap {}",
            shared(same, leader)
        );
        // Partial: some shared road, mostly not.
        let partial = shared(&routes[3].centre_line, leader);
        assert!(
            partial > 0.05 && partial < 0.8,
            "{kind}: partial overlap {partial}"
        );
        // Crossing: meets the leader's road and also drives roads the leader never takes (in the
        // sparse cave network that can still be a good share of the route).
        let crossing = shared(&routes[4].centre_line, leader);
        assert!(
            crossing > 0.0 && crossing < 0.9,
            "{kind}: crossing overlap {crossing}"
        );
        // Far start: starts far from the leader's start, then joins its road.
        let far = &routes[5].centre_line;
        assert!((far[0][0] - leader[0][0]).hypot(far[0][1] - leader[0][1]) > 150.0);
        assert!(
            shared(far, leader) > 0.1,
            "{kind}: far-start overlap {}",
            shared(far, leader)
        );
    }
}

#[test]
fn ground_motion_is_plausible_and_ground_truth_is_exact() {
    for kind in WorldKind::ALL {
        let config = SimConfig {
            world: kind.name().into(),
            robots: 1,
            route_length_m: 300.0,
            speed_mps: 1.5,
            ..SimConfig::default()
        };
        let source = SimSource::new(&config, 0, 1).unwrap();
        let trajectory = source.trajectory();
        let world: &World = source.world();
        let mut t = trajectory.start_s();
        let (mut max_speed, mut max_tilt) = (0.0f64, 0.0f64);
        while t < trajectory.end_s() {
            let (velocity, _) = trajectory.velocity_acceleration_at(t);
            max_speed = max_speed.max(velocity.xy().norm());
            let pose = trajectory.pose_at(t);
            let up = pose.rotation * Vector3::z();
            max_tilt = max_tilt.max(up.angle(&Vector3::z()));
            let p = pose.translation.vector;
            let ground = world.ground_below(p.x, p.y, p.z, 5.0).unwrap_or(f64::NAN);
            assert!(
                (p.z - ground - 0.8).abs() < 0.35,
                "{kind}: sensor {} m above ground at t = {t}",
                p.z - ground
            );
            t += 0.5;
        }
        assert!(
            max_speed < 1.55 && max_speed > 1.0,
            "{kind}: top speed {max_speed}"
        );
        // The planetary terrain's metre-scale relief (RMS slope about 10°) tilts a rover by up to about
        // 26°, within what planetary rovers drive (Curiosity's rating is 30°); roads and tunnels less.
        let max_allowed = if kind == WorldKind::Planetary { 0.5 } else { 0.4 };
        assert!(
            max_tilt > 0.002 && max_tilt < max_allowed,
            "{kind}: tilt up to {max_tilt} rad"
        );
        let scan = source.scan_at(17);
        assert_eq!(scan.ground_truth_world_from_sensor, Some(trajectory.pose_at(1.7)));
    }
}

#[test]
fn imu_agrees_with_the_ground_truth() {
    let config = SimConfig {
        world: "planetary".into(),
        robots: 1,
        frames: 40,
        imu_noise: false,
        sensor: "avia".into(),
        ..SimConfig::default()
    };
    let mut source = SimSource::new(&config, 0, 2).unwrap();
    let trajectory = std::sync::Arc::clone(source.trajectory());
    let first = source.next().unwrap();
    assert_eq!(first.imu.len(), 1);
    // Standing still: the accelerometer reads gravity in the body frame.
    let rotation = trajectory.pose_at(0.0).rotation;
    let gravity = rotation.inverse() * Vector3::new(0.0, 0.0, 9.80665);
    assert!((Vector3::from(first.imu[0].accel_mps2) - gravity).norm() < 1e-6);
    let mut previous = first;
    for scan in source.by_ref() {
        assert_eq!(scan.imu.len(), 20, "200 Hz between 10 Hz scans");
        assert!(
            scan.imu
                .iter()
                .all(|s| s.stamp_nanos > previous.stamp_nanos && s.stamp_nanos <= scan.stamp_nanos)
        );
        // Integrating the gyroscope reproduces the true rotation between the scans.
        let mut rotation = trajectory.pose_at(previous.stamp_nanos as f64 * 1e-9).rotation;
        let mut t = previous.stamp_nanos;
        for sample in &scan.imu {
            let dt = (sample.stamp_nanos - t) as f64 * 1e-9;
            rotation *= nalgebra::UnitQuaternion::from_scaled_axis(Vector3::from(sample.gyro_radps) * dt);
            t = sample.stamp_nanos;
        }
        let truth = trajectory.pose_at(scan.stamp_nanos as f64 * 1e-9).rotation;
        assert!(
            rotation.angle_to(&truth) < 2e-4,
            "gyro integration off by {} rad",
            rotation.angle_to(&truth)
        );
        previous = scan;
    }
    // With noise on, samples differ from the ideal ones but stay close.
    let noisy = SimSource::new(
        &SimConfig {
            imu_noise: true,
            ..config
        },
        0,
        1,
    )
    .unwrap()
    .nth(5)
    .unwrap();
    let ideal = SimSource::new(
        &SimConfig {
            imu_noise: false,
            ..SimConfig {
                world: "planetary".into(),
                robots: 1,
                frames: 40,
                sensor: "avia".into(),
                ..SimConfig::default()
            }
        },
        0,
        1,
    )
    .unwrap()
    .nth(5)
    .unwrap();
    let difference = (Vector3::from(noisy.imu[0].accel_mps2) - Vector3::from(ideal.imu[0].accel_mps2)).norm();
    assert!(difference > 1e-4 && difference < 0.5, "{difference}");
}

#[test]
fn kitti_export_writes_a_readable_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let config = SimConfig {
        world: "cave".into(),
        sensor: "os1-32".into(),
        robots: 1,
        frames: 3,
        ..SimConfig::default()
    };
    let mut source = SimSource::new(&config, 0, 2).unwrap();
    let expected: Vec<_> = (0..3).map(|k| source.scan_at(k)).collect();
    let summary = export_kitti(dir.path(), &mut source).unwrap();
    assert_eq!(summary.scans, 3);
    let bin = std::fs::read(dir.path().join("velodyne/000001.bin")).unwrap();
    assert_eq!(bin.len(), expected[1].points.len() * 16);
    let x = f32::from_le_bytes([bin[0], bin[1], bin[2], bin[3]]);
    assert_eq!(x, expected[1].points[0].x);
    let poses = std::fs::read_to_string(dir.path().join("poses.txt")).unwrap();
    let lines: Vec<Vec<f64>> = poses
        .lines()
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(lines.len(), 3);
    assert!(lines.iter().all(|l| l.len() == 12));
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    assert!(
        lines[0].iter().zip(identity).all(|(a, b)| (a - b).abs() < 1e-12),
        "the first pose is the origin: {:?}",
        lines[0]
    );
    let relative = expected[0].ground_truth_world_from_sensor.unwrap().inverse()
        * expected[2].ground_truth_world_from_sensor.unwrap();
    assert!((lines[2][3] - relative.translation.x).abs() < 1e-6);
    let times = std::fs::read_to_string(dir.path().join("times.txt")).unwrap();
    let stamps: Vec<f64> = times.lines().map(|l| l.trim().parse().unwrap()).collect();
    assert_eq!(stamps, vec![0.0, 0.1, 0.2]);
    let calib = std::fs::read_to_string(dir.path().join("calib.txt")).unwrap();
    assert!(calib.lines().any(|l| l.starts_with("Tr: 1")));
    assert!(dir.path().join("world_from_first.txt").is_file() && dir.path().join("imu.txt").is_file());
}

#[test]
fn preview_is_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.png");
    preview_fleet_png(
        &path,
        &SimConfig {
            world: "urban".into(),
            robots: 4,
            ..SimConfig::default()
        },
        96,
    )
    .unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
}

#[test]
fn config_defaults_round_trip_and_refuse_unknown_keys() {
    let text = toml::to_string(&SimConfig::default()).unwrap();
    let back: SimConfig = toml::from_str(&text).unwrap();
    assert_eq!(back, SimConfig::default());
    assert!(toml::from_str::<SimConfig>("speed = 2.0").is_err());
    let partial: SimConfig = toml::from_str("world = \"cave\"\nprofile = \"aerial\"").unwrap();
    assert_eq!(partial.world, "cave");
    assert_eq!(partial.profile, skid_sim::Profile::Aerial);
}

#[test]
fn aerial_profile_flies_above_the_ground() {
    let config = SimConfig {
        world: "planetary".into(),
        robots: 1,
        route_length_m: 300.0,
        speed_mps: 3.0,
        profile: skid_sim::Profile::Aerial,
        frames: 1,
        ..SimConfig::default()
    };
    let source = SimSource::new(&config, 0, 1).unwrap();
    let p = source.trajectory().pose_at(20.0).translation.vector;
    let ground = source.world().terrain_height(p.x, p.y).unwrap_or(f64::NAN);
    assert!(
        p.z - ground > 6.0 && p.z - ground < 14.0,
        "{} m above ground",
        p.z - ground
    );
    assert!(!source.scan_at(100).points.is_empty());
}
