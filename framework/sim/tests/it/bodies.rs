//! The fleet's robots see each other: a robot's sweep holds points on a peer's body where the peer's
//! trajectory has it, and none there when bodies are off.

use skid_sim::{BodyShape, Mission, NoiseModel, SimConfig, SimSource};

/// Two robots driving one route in opposite directions, passing each other in their own lanes.
fn passing(robot_bodies: bool) -> SimConfig {
    SimConfig {
        world: "planetary".to_owned(),
        sensor: "os1-64".to_owned(),
        robots: 2,
        mission: Mission::Reverse,
        route_length_m: 120.0,
        noise: NoiseModel::Ideal,
        robot_bodies,
        ..SimConfig::default()
    }
}

/// Points of `scan` (robot 0's) inside robot 1's body, grown by 5 cm.
fn points_on_peer(own: &SimSource, peer: &SimSource, sequence: u32) -> usize {
    let scan = own.scan_at(sequence);
    let shape = BodyShape::of(skid_sim::Profile::Ground, 0.8);
    scan.points
        .iter()
        .filter(|p| {
            let t_s = scan.stamp_nanos as f64 * 1e-9 + f64::from(p.time_offset_s);
            let world = own.trajectory().pose_at(t_s)
                * nalgebra::Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
            let in_body = peer.trajectory().pose_at(t_s).inverse() * world;
            (0..3).all(|axis| {
                let offset = in_body[axis] - f64::from(shape.centre_m[axis]);
                offset.abs() <= f64::from(shape.half_extents_m[axis]) + 0.05
            })
        })
        .count()
}

#[test]
fn a_robot_sees_a_peer_a_few_metres_away_and_only_with_bodies_on() {
    let with = passing(true);
    let (own, peer) = (
        SimSource::new(&with, 0, 2).unwrap(),
        SimSource::new(&with, 1, 2).unwrap(),
    );
    // The first scan at which the robots, driving towards each other, are 3 to 8 m apart.
    let sequence = (0..own.scan_count().min(peer.scan_count()))
        .find(|&k| {
            let t_s = SimSource::stamp_nanos(k) as f64 * 1e-9;
            let apart_m = (own.trajectory().pose_at(t_s).translation.vector
                - peer.trajectory().pose_at(t_s).translation.vector)
                .norm();
            (3.0..8.0).contains(&apart_m)
        })
        .expect("the robots meet within their routes");
    let seen = points_on_peer(&own, &peer, sequence);
    assert!(
        seen >= 50,
        "robot 0 sees {seen} points of robot 1 at scan {sequence}"
    );
    let without = passing(false);
    let (own, peer) = (
        SimSource::new(&without, 0, 2).unwrap(),
        SimSource::new(&without, 1, 2).unwrap(),
    );
    assert_eq!(points_on_peer(&own, &peer, sequence), 0);
}
