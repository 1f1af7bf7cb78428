//! The loopback transport: conformance on both clocks, the link model (bandwidth, latency, range, loss,
//! duplication, reordering), determinism by seed, link cuts, robots leaving and returning, registry use.

use std::time::Duration;

use skid_core::slots::{Destination, Transport};
use skid_core::{Params, PluginContext, Registry, RobotId};
use skid_transport_loopback::*;

const MS: u64 = 1_000_000;

fn sim_hub(link: LinkModel, seed: u64) -> LoopbackHub {
    let config = HubConfig {
        clock: ClockMode::Simulated,
        link,
        ..HubConfig::default()
    };
    LoopbackHub::new(config, seed).unwrap()
}

fn payloads(endpoint: &mut LoopbackEndpoint) -> Vec<(RobotId, Vec<u8>)> {
    endpoint
        .poll(Duration::ZERO)
        .unwrap()
        .into_iter()
        .map(|d| (d.from, d.payload))
        .collect()
}

#[test]
fn conformance_wall_clock_default_link() {
    let config = HubConfig {
        clock: ClockMode::Wall,
        ..HubConfig::default()
    };
    let hub = LoopbackHub::new(config, 1).unwrap();
    let mut a = hub.endpoint(RobotId(0)).unwrap();
    let mut b = hub.endpoint(RobotId(1)).unwrap();
    skid_testkit::transport::check_transport(&mut a, &mut b);
}

#[test]
fn conformance_simulated_ideal_link() {
    let hub = sim_hub(LinkModel::ideal(), 1);
    let mut a = hub.endpoint(RobotId(3)).unwrap();
    let mut b = hub.endpoint(RobotId(5)).unwrap();
    skid_testkit::transport::check_transport(&mut a, &mut b);
}

/// A hub on the default link without jitter, with radio queues split at `sparse_bytes`, after robot 0
/// sent robot 1 a 125 kB message and then a 125-byte one.
fn large_then_small(sparse_bytes: usize) -> (LoopbackHub, LoopbackEndpoint, LoopbackEndpoint) {
    let link = LinkModel {
        jitter_ms: 0.0,
        sparse_bytes,
        ..LinkModel::default()
    };
    let hub = sim_hub(link, 0);
    let mut a = hub.endpoint(RobotId(0)).unwrap();
    let b = hub.endpoint(RobotId(1)).unwrap();
    a.send(Destination::Robot(RobotId(1)), &vec![7u8; 125_000])
        .unwrap();
    a.send(Destination::Robot(RobotId(1)), &[1u8; 125]).unwrap();
    (hub, a, b)
}

#[test]
fn bandwidth_and_latency_set_the_arrival_time() {
    // 125 kB at 1 Mbit/s take 1 s of airtime, then 28 ms of latency; in one queue, the second waits for
    // the first.
    let (hub, _a, mut b) = large_then_small(0);
    hub.advance_to(1_027 * MS);
    assert!(payloads(&mut b).is_empty());
    hub.advance_to(1_028 * MS);
    let first = payloads(&mut b);
    assert_eq!(first.len(), 1);
    assert_eq!(first[0].1.len(), 125_000);
    hub.advance_to(1_029 * MS);
    assert_eq!(payloads(&mut b).len(), 1, "1 kbit more airtime = 1 ms");
    let stats = hub.stats();
    let link = stats.link(RobotId(0), RobotId(1)).unwrap();
    assert_eq!(link.delivered_messages, 2);
    assert!((link.latency_max_ms - 1029.0).abs() < 1e-6);
}

#[test]
fn a_small_message_overtakes_a_large_one_in_the_radio_queue() {
    // The 125-byte message (1 ms of airtime) goes before the 125 kB one on the air; a second 125 kB
    // message waits for the first and for the small one's airtime.
    let (hub, mut a, mut b) = large_then_small(LinkModel::default().sparse_bytes);
    a.send(Destination::Robot(RobotId(1)), &vec![8u8; 125_000])
        .unwrap();
    hub.advance_to(29 * MS);
    let first = payloads(&mut b);
    assert_eq!(first.len(), 1);
    assert_eq!(first[0].1.len(), 125);
    hub.advance_to(1_027 * MS);
    assert!(payloads(&mut b).is_empty());
    hub.advance_to(1_028 * MS);
    assert_eq!(payloads(&mut b).len(), 1);
    hub.advance_to(2_028 * MS);
    assert!(payloads(&mut b).is_empty());
    hub.advance_to(2_029 * MS);
    assert_eq!(payloads(&mut b).len(), 1);
}

/// Mean one-way latency of a 400-byte (SOLiD) and a 4.8 kB (Scan Context) message at `distance_m`.
fn latency_at(distance_m: f64, bytes: usize) -> f64 {
    let hub = sim_hub(
        LinkModel {
            loss: 0.0,
            range_curve: LinkModel::default()
                .range_curve
                .into_iter()
                .map(|p| RangePoint { extra_loss: 0.0, ..p })
                .collect(),
            ..LinkModel::default()
        },
        9,
    );
    let mut a = hub.endpoint(RobotId(0)).unwrap();
    let mut b = hub.endpoint(RobotId(1)).unwrap();
    hub.set_position(RobotId(0), [0.0, 0.0, 0.0]);
    hub.set_position(RobotId(1), [distance_m, 0.0, 0.0]);
    for i in 0..20u64 {
        hub.advance_to(i * 1_000 * MS);
        a.send(Destination::Robot(RobotId(1)), &vec![0u8; bytes]).unwrap();
    }
    hub.advance_to(100_000 * MS);
    assert_eq!(payloads(&mut b).len(), 20);
    hub.stats()
        .link(RobotId(0), RobotId(1))
        .unwrap()
        .mean_latency_ms()
        .unwrap()
}

#[test]
fn latency_grows_with_distance_and_size() {
    let small_near = latency_at(5.0, 400);
    let small_far = latency_at(30.0, 400);
    let large_near = latency_at(5.0, 4_800);
    let large_far = latency_at(30.0, 4_800);
    // A SOLiD descriptor stays in the paper's 30–60 ms band out to 30 m; larger messages suffer more.
    assert!((29.0..=35.0).contains(&small_near), "{small_near}");
    assert!(small_far < 90.0 && small_far > small_near, "{small_far}");
    assert!(large_far - large_near > 10.0 * (small_far - small_near - 20.0).max(1.0));
    assert!(large_near > small_near);
}

#[test]
fn max_range_drops_messages() {
    let hub = sim_hub(
        LinkModel {
            max_range_m: Some(50.0),
            ..LinkModel::ideal()
        },
        0,
    );
    let mut a = hub.endpoint(RobotId(0)).unwrap();
    let mut b = hub.endpoint(RobotId(1)).unwrap();
    hub.set_position(RobotId(0), [0.0, 0.0, 0.0]);
    hub.set_position(RobotId(1), [0.0, 60.0, 0.0]);
    a.send(Destination::AllPeers, b"far").unwrap();
    assert!(payloads(&mut b).is_empty());
    hub.set_position(RobotId(1), [0.0, 40.0, 0.0]);
    a.send(Destination::AllPeers, b"near").unwrap();
    assert_eq!(payloads(&mut b), vec![(RobotId(0), b"near".to_vec())]);
    assert_eq!(
        hub.stats()
            .link(RobotId(0), RobotId(1))
            .unwrap()
            .dropped_out_of_range,
        1
    );
}

/// Sends 2,000 numbered messages over a faulty link; returns the arrival order at the receiver.
fn faulty_run(seed: u64) -> Vec<u32> {
    let link = LinkModel {
        loss: 0.3,
        duplicate: 0.1,
        reorder: 0.2,
        reorder_delay_ms: 30.0,
        jitter_ms: 5.0,
        bandwidth_bps: f64::INFINITY,
        ..LinkModel::default()
    };
    let hub = sim_hub(link, seed);
    let mut a = hub.endpoint(RobotId(0)).unwrap();
    let mut b = hub.endpoint(RobotId(1)).unwrap();
    let mut arrivals = Vec::new();
    for i in 0..2_000u32 {
        hub.advance_to(u64::from(i) * 2 * MS);
        a.send(Destination::Robot(RobotId(1)), &i.to_le_bytes()).unwrap();
        for (_, payload) in payloads(&mut b) {
            arrivals.push(u32::from_le_bytes(payload.try_into().unwrap()));
        }
    }
    hub.advance_to(10_000 * MS);
    for (_, payload) in payloads(&mut b) {
        arrivals.push(u32::from_le_bytes(payload.try_into().unwrap()));
    }
    arrivals
}

#[test]
fn loss_duplication_and_reordering_follow_the_model_and_the_seed() {
    let arrivals = faulty_run(42);
    assert_eq!(arrivals, faulty_run(42), "same seed, same deliveries");
    assert_ne!(arrivals, faulty_run(43));
    let mut unique = arrivals.clone();
    unique.sort();
    unique.dedup();
    let delivered = unique.len() as f64 / 2_000.0;
    assert!(
        (0.65..0.75).contains(&delivered),
        "delivered fraction {delivered}"
    );
    let duplicates = arrivals.len() - unique.len();
    assert!((80..200).contains(&duplicates), "{duplicates} duplicates");
    let overtaken = arrivals.windows(2).filter(|w| w[1] < w[0]).count();
    assert!(overtaken > 100, "{overtaken} reordered");
}

#[test]
fn cut_links_lose_messages_in_flight_and_recover() {
    let hub = sim_hub(LinkModel::default(), 0);
    let mut a = hub.endpoint(RobotId(0)).unwrap();
    let mut b = hub.endpoint(RobotId(1)).unwrap();
    let mut c = hub.endpoint(RobotId(2)).unwrap();
    a.send(Destination::AllPeers, b"before").unwrap();
    hub.cut_link(RobotId(1), RobotId(0));
    hub.advance_to(100 * MS);
    assert!(payloads(&mut b).is_empty(), "in flight when cut");
    assert_eq!(payloads(&mut c).len(), 1, "the other link is unaffected");
    a.send(Destination::Robot(RobotId(1)), b"during").unwrap();
    hub.restore_link(RobotId(0), RobotId(1));
    hub.isolate(RobotId(2));
    a.send(Destination::AllPeers, b"after").unwrap();
    hub.advance_to(200 * MS);
    assert_eq!(payloads(&mut b), vec![(RobotId(0), b"after".to_vec())]);
    assert!(payloads(&mut c).is_empty());
    hub.rejoin(RobotId(2));
    a.send(Destination::Robot(RobotId(2)), b"back").unwrap();
    hub.advance_to(300 * MS);
    assert_eq!(payloads(&mut c).len(), 1);
}

#[test]
fn a_robot_leaves_and_returns() {
    let hub = sim_hub(LinkModel::ideal(), 0);
    let mut a = hub.endpoint(RobotId(0)).unwrap();
    let b = hub.endpoint(RobotId(1)).unwrap();
    assert!(hub.endpoint(RobotId(1)).is_err(), "attached twice");
    a.send(Destination::Robot(RobotId(1)), b"lost with the robot")
        .unwrap();
    drop(b);
    a.send(Destination::AllPeers, b"nobody").unwrap();
    hub.advance_to(1_000 * MS);
    let silent = a.peers();
    assert_eq!(silent.len(), 0, "{silent:?}");
    let mut b = hub.endpoint(RobotId(1)).unwrap();
    assert!(payloads(&mut b).is_empty(), "a new endpoint starts empty");
    a.send(Destination::Robot(RobotId(1)), b"welcome back").unwrap();
    assert_eq!(payloads(&mut b).len(), 1);
    b.send(Destination::AllPeers, b"hi").unwrap();
    assert_eq!(payloads(&mut a).len(), 1);
    hub.advance_to(3_000 * MS);
    let peers = a.peers();
    assert_eq!(peers.len(), 1);
    assert_eq!(peers[0].silent_for, Some(Duration::from_secs(2)));
}

#[test]
fn oversized_and_self_sends_are_errors() {
    let hub = LoopbackHub::new(
        HubConfig {
            max_message_bytes: 1_000,
            ..HubConfig::default()
        },
        0,
    )
    .unwrap();
    let mut a = hub.endpoint(RobotId(0)).unwrap();
    assert!(a.send(Destination::AllPeers, &[0; 1_001]).is_err());
    assert!(a.send(Destination::AllPeers, &[0; 1_000]).is_ok());
    assert!(a.send(Destination::Robot(RobotId(0)), b"me").is_err());
    assert!(a.send(Destination::Robot(RobotId(9)), b"nobody there").is_ok());
}

#[test]
fn injected_bytes_arrive_now_whatever_their_size() {
    let hub = sim_hub(LinkModel::default(), 3);
    let mut b = hub.endpoint(RobotId(1)).unwrap();
    hub.advance_to(7 * MS);
    let oversized = vec![0xA5; hub.config().max_message_bytes + 1];
    hub.inject(RobotId(0), RobotId(1), &oversized);
    hub.inject(RobotId(0), RobotId(1), b"garbage");
    // Nobody is attached as robot 5: the bytes go nowhere and nothing fails.
    hub.inject(RobotId(0), RobotId(5), b"lost");
    let got = payloads(&mut b);
    assert_eq!(got.len(), 2);
    assert_eq!(got[0], (RobotId(0), oversized));
    assert_eq!(got[1], (RobotId(0), b"garbage".to_vec()));
}

#[test]
fn registry_robots_share_a_named_hub() {
    let mut registry = Registry::new();
    register(&mut registry).unwrap();
    let params = Params::from_toml_str(
        "hub = \"registry-test\"\nclock = \"simulated\"\n[link]\nlatency_ms = 10.0\njitter_ms = 0.0",
    )
    .unwrap();
    let context = |robot| PluginContext {
        robot: RobotId(robot),
        fleet_size: 3,
        seed: 5 + u64::from(robot),
        ..PluginContext::default()
    };
    let mut robots: Vec<Box<dyn Transport>> = (0..3)
        .map(|r| {
            registry
                .transport
                .create("loopback", &params, &context(r))
                .unwrap()
        })
        .collect();
    let hub = LoopbackHub::find("registry-test").expect("the runtime finds the hub by name");
    assert_eq!(hub.config().link.latency_ms, 10.0);
    robots[2].send(Destination::AllPeers, b"to both").unwrap();
    // 10 ms latency plus 56 µs of airtime at 1 Mbit/s.
    hub.advance_to(10 * MS);
    assert!(robots[0].poll(Duration::ZERO).unwrap().is_empty());
    hub.advance_to(11 * MS);
    for robot in &mut robots[..2] {
        assert_eq!(robot.poll(Duration::ZERO).unwrap().len(), 1);
    }
    // Another link model under the same hub name is refused; an unknown key is refused.
    let other = Params::from_toml_str("hub = \"registry-test\"\n[link]\nlatency_ms = 11.0").unwrap();
    assert!(
        registry
            .transport
            .create("loopback", &other, &context(3))
            .is_err()
    );
    let typo = Params::from_toml_str("hub = \"x\"\nlatncy_ms = 1.0").unwrap();
    assert!(registry.transport.parse("loopback", &typo).is_err());
    drop(robots);
    drop(hub);
    assert!(
        LoopbackHub::find("registry-test").is_none(),
        "the hub ends with its robots"
    );
}
