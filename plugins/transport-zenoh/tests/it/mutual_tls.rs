//! The zenoh transport with mutual TLS and the fleet's access control on 127.0.0.1 (issue #20): two
//! robots with certificates from `write_fleet_certificates` pass the transport conformance suite; a peer
//! whose certificate another CA signed never gets a link; a fleet certificate that publishes under
//! another robot's id has every such message dropped on arrival and counted; a peer that floods fills
//! only its own receive budget.

use skid_testkit::net::free_tcp_ports;
use std::path::Path;
use std::time::{Duration, Instant};

use skid_core::RobotId;
use skid_core::slots::{Destination, Transport};
use skid_transport_zenoh::*;

const FLEET_SIZE: u32 = 3;

fn endpoint(port: u16) -> String {
    format!("tls/127.0.0.1:{port}")
}

/// Robot `robot`'s TLS configuration from `fleet`, listening on `listen` and connecting to `connect`.
fn config(fleet: &FleetFiles, robot: u32, listen: u16, connect: &[u16], prefix: &str) -> ZenohConfig {
    ZenohConfig {
        listen: vec![endpoint(listen)],
        connect: connect.iter().map(|&p| endpoint(p)).collect(),
        key_prefix: prefix.into(),
        tls: fleet.tls_for(robot).unwrap(),
        ..ZenohConfig::default()
    }
}

/// Polls `transport` for `period` and returns the senders of what arrived, with the payloads.
fn collect(transport: &mut ZenohTransport, period: Duration) -> Vec<(RobotId, Vec<u8>)> {
    let deadline = Instant::now() + period;
    let mut got = Vec::new();
    while Instant::now() < deadline {
        for datagram in transport.poll(Duration::from_millis(50)).unwrap() {
            got.push((datagram.from, datagram.payload));
        }
    }
    got
}

fn certificates(folder: &Path) -> FleetFiles {
    write_fleet_certificates(folder, FLEET_SIZE, 1).unwrap()
}

#[test]
fn the_default_is_mutual_tls_and_plain_tcp_must_be_asked_for() {
    let plain_endpoint = ZenohConfig {
        listen: vec!["tcp/127.0.0.1:7447".into()],
        ..ZenohConfig::default()
    };
    let error = plain_endpoint.validate().unwrap_err().to_string();
    assert!(error.contains("plain_tcp"), "{error}");
    let no_files = ZenohConfig::default().validate().unwrap_err().to_string();
    assert!(no_files.contains("tls.ca_certificate"), "{no_files}");
    let folder = tempfile::tempdir().unwrap();
    let fleet = certificates(folder.path());
    let mut missing = config(&fleet, 0, 1, &[], "skid");
    missing.tls.private_key = folder.path().join("nowhere.key");
    let error = missing.validate().unwrap_err().to_string();
    assert!(
        error.contains("tls.private_key") && error.contains("nowhere.key"),
        "{error}"
    );
}

#[test]
fn fleet_robots_talk_and_intruders_are_refused_and_counted() {
    let folder = tempfile::tempdir().unwrap();
    let fleet = certificates(&folder.path().join("fleet"));
    let foreign = certificates(&folder.path().join("foreign"));
    let prefix = format!("skid-tls-test-{}", std::process::id());
    let (port_a, port_b) = {
        let [a, b] = free_tcp_ports::<2>();
        (a, b)
    };
    let mut a =
        ZenohTransport::open(RobotId(0), config(&fleet, 0, port_a, &[], &prefix), FLEET_SIZE).unwrap();
    let mut b = ZenohTransport::open(
        RobotId(1),
        config(&fleet, 1, port_b, &[port_a], &prefix),
        FLEET_SIZE,
    )
    .unwrap();
    assert!(a.wait_for_peers(&[RobotId(1)], Duration::from_secs(10)).unwrap());
    assert!(b.wait_for_peers(&[RobotId(0)], Duration::from_secs(10)).unwrap());
    skid_testkit::transport::check_transport(&mut a, &mut b);

    // A robot certificate signed by another CA: the TLS handshake fails, so it is never a peer.
    let mut stranger = ZenohTransport::open(
        RobotId(2),
        config(&foreign, 2, free_tcp_ports::<1>()[0], &[port_a], &prefix),
        FLEET_SIZE,
    )
    .unwrap();
    // Robot 2's genuine certificate, used to publish as robot 1: the access control drops it.
    let mut impostor = ZenohTransport::open(
        RobotId(1),
        config(&fleet, 2, free_tcp_ports::<1>()[0], &[port_a], &prefix),
        FLEET_SIZE,
    )
    .unwrap();
    std::thread::sleep(Duration::from_secs(2));
    for _ in 0..20 {
        stranger.send(Destination::AllPeers, b"stranger").unwrap();
        impostor.send(Destination::AllPeers, b"impostor").unwrap();
        impostor
            .send(Destination::Robot(RobotId(0)), b"impostor")
            .unwrap();
    }
    b.send(Destination::Robot(RobotId(0)), b"genuine").unwrap();
    let got = collect(&mut a, Duration::from_secs(2));
    assert!(
        got.iter().all(|(_, payload)| payload == b"genuine"),
        "an intruder got through"
    );
    assert_eq!(got.len(), 1, "robot 1's own message arrives");
    assert!(
        !a.peers().iter().any(|peer| peer.robot == RobotId(2)),
        "no peer announces itself as robot 2"
    );
    assert!(
        stranger.alive_peers().is_empty(),
        "the stranger sees no fleet robot"
    );
    let refusals = a.refusals();
    let denied = refusals.get("access_denied robot-2").copied().unwrap_or(0);
    assert!(
        denied >= 40,
        "the impostor's 40 messages are counted: {refusals:?}"
    );
}

#[test]
fn a_flooding_peer_fills_only_its_own_budget() {
    let folder = tempfile::tempdir().unwrap();
    let fleet = certificates(folder.path());
    let prefix = format!("skid-flood-test-{}", std::process::id());
    let ports = free_tcp_ports::<3>();
    let mut receiver_config = config(&fleet, 0, ports[0], &[], &prefix);
    receiver_config.max_message_bytes = 64 << 10;
    receiver_config.max_queued_bytes = 1 << 20;
    let mut receiver = ZenohTransport::open(RobotId(0), receiver_config, FLEET_SIZE).unwrap();
    let mut honest = ZenohTransport::open(
        RobotId(1),
        config(&fleet, 1, ports[1], &[ports[0]], &prefix),
        FLEET_SIZE,
    )
    .unwrap();
    let mut flood_config = config(&fleet, 2, ports[2], &[ports[0]], &prefix);
    flood_config.congestion = Congestion::Block;
    let mut flooder = ZenohTransport::open(RobotId(2), flood_config, FLEET_SIZE).unwrap();
    assert!(
        honest
            .wait_for_peers(&[RobotId(0)], Duration::from_secs(10))
            .unwrap()
    );
    assert!(
        flooder
            .wait_for_peers(&[RobotId(0)], Duration::from_secs(10))
            .unwrap()
    );
    // 4 MB from the flooder while the receiver does not poll, four times its budget.
    for _ in 0..64 {
        flooder
            .send(Destination::Robot(RobotId(0)), &[7; 60 << 10])
            .unwrap();
    }
    for index in 0..5u8 {
        honest
            .send(Destination::Robot(RobotId(0)), &[index; 100])
            .unwrap();
    }
    std::thread::sleep(Duration::from_secs(2));
    let got = collect(&mut receiver, Duration::from_secs(1));
    let from_honest = got.iter().filter(|(from, _)| *from == RobotId(1)).count();
    let from_flooder = got.iter().filter(|(from, _)| *from == RobotId(2)).count();
    assert_eq!(from_honest, 5, "the honest robot's messages all arrive");
    assert!(
        from_flooder < 64 && from_flooder > 0,
        "{from_flooder} flood messages kept"
    );
    let refusals = receiver.refusals();
    assert_eq!(
        refusals.get("queue_full").copied(),
        Some(64 - from_flooder as u64),
        "{refusals:?}"
    );
}
