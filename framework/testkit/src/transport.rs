//! Conformance of transports: a message reaches one named peer and all peers, unchanged, within a
//! second, and the receiver learns who sent it.

use std::time::{Duration, Instant};

use skid_core::slots::{Datagram, Destination, Transport};

fn receive(transport: &mut dyn Transport, within: Duration) -> Vec<Datagram> {
    let deadline = Instant::now() + within;
    let mut received = Vec::new();
    while received.is_empty() && Instant::now() < deadline {
        received.extend(transport.poll(Duration::from_millis(20)).expect("poll"));
    }
    received
}

/// Runs the transport contract on two connected endpoints.
pub fn check_transport(a: &mut dyn Transport, b: &mut dyn Transport) {
    let payload: Vec<u8> = (0..10_000u32).map(|i| (i % 251) as u8).collect();
    a.send(Destination::Robot(b.local_robot()), &payload)
        .expect("send to one peer");
    let received = receive(b, Duration::from_secs(1));
    assert_eq!(received.len(), 1, "one message arrives");
    assert_eq!(received[0].from, a.local_robot());
    assert_eq!(received[0].payload, payload);
    b.send(Destination::AllPeers, b"hello").expect("send to all");
    let received = receive(a, Duration::from_secs(1));
    assert_eq!(received.len(), 1);
    assert_eq!(received[0].payload, b"hello");
    assert!(
        b.peers().iter().any(|peer| peer.robot == a.local_robot()),
        "the receiver knows the sender"
    );
}
