//! Tests of the peer-visibility check on ray-cast scenes: flat ground 0.8 m under the sensor, a wall
//! 30 m ahead, and the peer's rover (1.0 × 0.8 × 0.5 m, as the simulator renders it) standing where it
//! was or not at all, seen by a 64-beam spinning LiDAR and thinned to the keyframes' 0.25 m voxels.

use super::*;
use skid_core::Information;
use skid_core::slots::RelativePose;
use skid_geometry::voxel_downsample;
use skid_testkit::scene::planar_pose;

use crate::test_scene::{Block, closure, hit};

/// Two robots driving straight along their own x axes at 2 m/s, a keyframe every 0.5 s (1 m); robot
/// 1's clock stamps `offset_s` later than robot 0's.
struct TwoRobots {
    offset_s: f64,
}

impl GraphView for TwoRobots {
    fn pose(&self, _: KeyframeId) -> Option<Pose> {
        None
    }

    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        (target.robot == source.robot).then(|| RelativePose {
            target_from_source: Pose::from_parts(
                nalgebra::Translation3::new(f64::from(source.index) - f64::from(target.index), 0.0, 0.0),
                nalgebra::UnitQuaternion::identity(),
            ),
            covariance: Information::identity() * 1e-4,
        })
    }

    fn keyframes(&self) -> Vec<KeyframeId> {
        Vec::new()
    }

    fn loops(&self) -> Vec<LoopClosure> {
        Vec::new()
    }

    fn keyframe_stamp_nanos(&self, id: KeyframeId) -> Option<u64> {
        let offset_s = if id.robot.0 == 1 { self.offset_s } else { 0.0 };
        (id.index <= 20).then(|| ((f64::from(id.index) * 0.5 + offset_s) * 1e9) as u64)
    }
}

/// A sweep of 64 beams from −16.6° to +16.6° and 1024 columns, from a sensor 0.8 m above flat ground
/// with a wall 30 m ahead, with a rover whose sensor is at `peer` (in this sensor's frame) if any.
fn scan(peer: Option<Pose>) -> Vec<Point> {
    let rover = Block {
        min: Vector3::new(-0.5, -0.4, -0.65),
        max: Vector3::new(0.5, 0.4, -0.15),
    };
    let mut points = Vec::new();
    for row in 0..64 {
        let elevation = (-16.6 + 33.2 * f64::from(row) / 63.0_f64).to_radians();
        for column in 0..1024 {
            let azimuth = (f64::from(column) * 360.0 / 1024.0).to_radians();
            let direction = Vector3::new(
                elevation.cos() * azimuth.cos(),
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
            );
            let ground = (direction.z < 0.0).then(|| -0.8 / direction.z);
            let wall = (direction.x > 0.0).then(|| 30.0 / direction.x);
            let body = peer.and_then(|peer| {
                let inverse = peer.inverse();
                let origin = inverse * Point3::origin();
                hit(&rover, &origin.coords, &(inverse.rotation * direction))
            });
            let nearest = [ground, wall, body]
                .into_iter()
                .flatten()
                .fold(f64::INFINITY, f64::min);
            if nearest < 100.0 {
                let p = direction * nearest;
                points.push(Point::new(p.x as f32, p.y as f32, p.z as f32));
            }
        }
    }
    voxel_downsample(&points, 0.25)
}

#[test]
fn robots_side_by_side_that_see_each_other_pass() {
    let check = PeerSeenConfig::default();
    let source_in_target = planar_pose(3.0, 0.0, 0.0, f64::to_radians(90.0));
    let loop_ = closure(KeyframeId::new(0, 4), KeyframeId::new(1, 4), source_in_target);
    let (target, source) = (
        scan(Some(source_in_target)),
        scan(Some(source_in_target.inverse())),
    );
    let graph = TwoRobots { offset_s: 0.0 };
    assert_eq!(check.refusal(&loop_, (&target, &source), &graph), None);
    // Every ray towards the core ends on the body around it (few do: the body's near face is a handful
    // of 0.25 m voxels at this range).
    let count = check.count(&target, &source_in_target);
    assert!(count.blocked >= 1 && count.through == 0, "{count:?}");
}

#[test]
fn robots_side_by_side_that_do_not_see_each_other_are_refused() {
    let check = PeerSeenConfig::default();
    let source_in_target = planar_pose(2.5, 0.0, 0.0, f64::to_radians(90.0));
    let loop_ = closure(KeyframeId::new(0, 4), KeyframeId::new(1, 4), source_in_target);
    let (target, source) = (scan(None), scan(None));
    let graph = TwoRobots { offset_s: 0.0 };
    let reason = check
        .refusal(&loop_, (&target, &source), &graph)
        .expect("an empty place where the peer should stand refutes the loop");
    assert!(reason.starts_with("peer unseen"), "{reason}");
    // Recorded far apart in time, the same loop says nothing about where the peer was.
    let later = TwoRobots { offset_s: 20.0 };
    assert_eq!(check.refusal(&loop_, (&target, &source), &later), None);
    // Nor does an intra-robot loop, or a check turned off.
    let own = closure(KeyframeId::new(0, 4), KeyframeId::new(0, 9), source_in_target);
    assert_eq!(check.refusal(&own, (&target, &source), &graph), None);
    let off = PeerSeenConfig {
        enabled: false,
        ..PeerSeenConfig::default()
    };
    assert_eq!(off.refusal(&loop_, (&target, &source), &graph), None);
}

#[test]
fn the_peer_is_looked_for_where_its_odometry_has_it_at_the_seers_stamp() {
    let check = PeerSeenConfig::default();
    // Robot 1's keyframe 6 (1 s after robot 0's keyframe 4) is 5 m ahead, facing along x: at robot 0's
    // stamp it was two keyframes (2 m) earlier, 3 m ahead.
    let loop_ = closure(
        KeyframeId::new(0, 4),
        KeyframeId::new(1, 6),
        Pose::translation(5.0, 0.0, 0.0),
    );
    let graph = TwoRobots { offset_s: 0.0 };
    let seen_at_stamp = scan(Some(Pose::translation(3.0, 0.0, 0.0)));
    let seen_later = scan(Some(Pose::translation(5.0, 0.0, 0.0)));
    let peer_view = scan(None);
    assert_eq!(check.refusal(&loop_, (&seen_at_stamp, &[]), &graph), None);
    let reason = check.refusal(&loop_, (&seen_later, &peer_view), &graph);
    assert!(reason.is_some_and(|reason| reason.starts_with("peer unseen")));
}

#[test]
fn a_peer_beyond_the_range_or_behind_a_wall_is_not_judged() {
    let check = PeerSeenConfig::default();
    let graph = TwoRobots { offset_s: 0.0 };
    let far = closure(
        KeyframeId::new(0, 4),
        KeyframeId::new(1, 4),
        Pose::translation(40.0, 0.0, 0.0),
    );
    assert_eq!(check.refusal(&far, (&scan(None), &scan(None)), &graph), None);
    // A rover 35 m away behind the wall at 30 m: every ray towards it is blocked.
    let count = check.count(&scan(None), &Pose::translation(29.0, 0.0, 0.0));
    assert_eq!(count.through, 0, "{count:?}");
}

#[test]
fn a_peer_whose_body_the_rays_end_on_is_sighted() {
    let check = PeerSeenConfig::default();
    let graph = TwoRobots { offset_s: 0.0 };
    for distance_m in [3.0, 8.0, 15.0] {
        let source_in_target = planar_pose(distance_m, 1.0, 0.0, f64::to_radians(30.0));
        let loop_ = closure(KeyframeId::new(0, 4), KeyframeId::new(1, 4), source_in_target);
        let clouds = (
            scan(Some(source_in_target)),
            scan(Some(source_in_target.inverse())),
        );
        assert_eq!(
            check.judge(&loop_, (&clouds.0, &clouds.1), &graph, true),
            Sighting::Seen,
            "{distance_m} m"
        );
        // Where neither scan shows the other robot, the loop is refuted.
        let nobody = scan(None);
        let empty = check.judge(&loop_, (&nobody, &nobody), &graph, true);
        assert!(matches!(empty, Sighting::Unseen(_)), "{distance_m} m: {empty:?}");
    }
    // Beyond the range nothing is judged, even with the body in the scan.
    let far_pose = Pose::translation(40.0, 0.0, 0.0);
    let far = closure(KeyframeId::new(0, 4), KeyframeId::new(1, 4), far_pose);
    let clouds = (scan(Some(far_pose)), scan(Some(far_pose.inverse())));
    assert_eq!(
        check.judge(&far, (&clouds.0, &clouds.1), &graph, true),
        Sighting::Unjudged
    );
}

#[test]
fn out_of_range_parameters_name_their_key() {
    let cases = [
        (
            PeerSeenConfig {
                within_s: 0.0,
                ..PeerSeenConfig::default()
            },
            "within_s",
        ),
        (
            PeerSeenConfig {
                core_half_extents_m: [0.1, -0.1, 0.1],
                ..PeerSeenConfig::default()
            },
            "core_half_extents_m",
        ),
        (
            PeerSeenConfig {
                max_range_m: 1.0,
                ..PeerSeenConfig::default()
            },
            "max_range_m",
        ),
        (
            PeerSeenConfig {
                max_through_fraction: 1.5,
                ..PeerSeenConfig::default()
            },
            "max_through_fraction",
        ),
        (
            PeerSeenConfig {
                min_rays: 0,
                ..PeerSeenConfig::default()
            },
            "min_rays",
        ),
        (
            PeerSeenConfig {
                sighting_half_extents_m: [0.4, 0.0, 0.1],
                ..PeerSeenConfig::default()
            },
            "sighting_half_extents_m",
        ),
        (
            PeerSeenConfig {
                max_sighted_through_fraction: -0.1,
                ..PeerSeenConfig::default()
            },
            "max_sighted_through_fraction",
        ),
    ];
    for (config, key) in cases {
        let error = config.validate().expect_err(key);
        assert!(error.to_string().contains(key), "{error}");
    }
    assert!(PeerSeenConfig::default().validate().is_ok());
}
