//! Transport slot: moves opaque, already-encoded protocol messages between robots.
//!
//! The protocol (envelopes, size limits, message kinds) lives in the runtime; a transport only moves
//! bytes, is polled (no hidden threads) and never blocks past the deadline it is given. A transport that
//! simulates the network in process (the `loopback` link model) also offers a [`SimulatedNetwork`], which
//! the runtime drives with the scans' clock and the robots' true positions, whatever the plugin's name.

use std::any::Any;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use crate::{PluginResult, RobotId};

/// Where a message goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Destination {
    Robot(RobotId),
    AllPeers,
}

/// A message received from a peer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Datagram {
    pub from: RobotId,
    pub payload: Vec<u8>,
}

/// What the transport knows about a peer.
#[derive(Clone, Debug, PartialEq)]
pub struct PeerInfo {
    pub robot: RobotId,
    /// Time since anything was last heard from the peer, if ever.
    pub silent_for: Option<Duration>,
}

/// Moves bytes between robots.
pub trait Transport: Send {
    /// The robot this transport endpoint belongs to.
    fn local_robot(&self) -> RobotId;

    /// Queues a message; an unreachable peer is not an error (links come and go), an oversized message is.
    fn send(&mut self, destination: Destination, payload: &[u8]) -> PluginResult<()>;

    /// Returns the messages that arrived, waiting at most `timeout` for the first one.
    fn poll(&mut self, timeout: Duration) -> PluginResult<Vec<Datagram>>;

    /// The peers currently known.
    fn peers(&self) -> Vec<PeerInfo>;

    /// Messages the transport refused before they reached the protocol, by class (an unauthorised
    /// sender, a full receive budget, …); written to `summary.json`. Empty for a transport that refuses
    /// nothing.
    fn refusals(&self) -> BTreeMap<String, u64> {
        BTreeMap::new()
    }

    /// The in-process network this endpoint is part of, when the transport simulates one; `None` for a
    /// real network.
    fn simulated_network(&self) -> Option<Arc<dyn SimulatedNetwork>> {
        None
    }
}

/// A network simulated in process, shared by the endpoints of one run: its clock follows the scans'
/// stamps (in a lockstep run) and its link model may depend on where the robots are.
pub trait SimulatedNetwork: Send + Sync {
    /// The network's clock in nanoseconds.
    fn now_nanos(&self) -> u64;

    /// Moves the clock forward to `nanos` (never back).
    fn advance_to(&self, nanos: u64);

    /// Where `robot` is, metres in any frame common to the robots, for range-dependent links.
    fn set_position(&self, robot: RobotId, position_m: [f64; 3]);

    /// What the network did with the messages so far, summed over its links.
    fn totals(&self) -> NetworkTotals;

    /// The concrete network, for tests and tools that know it (fault injection, link statistics).
    fn as_any(&self) -> &dyn Any;
}

/// What a simulated network did with the messages, summed over its directed links: a broadcast to
/// fifteen peers counts fifteen times.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct NetworkTotals {
    pub sent_messages: u64,
    pub delivered_messages: u64,
    /// Lost on the air (the link model's loss at the robots' distance).
    pub lost: u64,
    /// Dropped because the sender's radio queue already held more than the longest wait.
    pub queue_full: u64,
    /// Dropped beyond the link's range, on a cut link or to a robot not attached.
    pub unreachable: u64,
    /// Mean one-way latency of the delivered messages (queueing, airtime and latency), milliseconds.
    pub mean_latency_ms: f64,
}
