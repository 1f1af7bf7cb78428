//! SKiD Zenoh transport for real networks (design guide §6): robots that outgrow one machine each run
//! their own host, and zenoh carries the inter-robot messages of the SKiD-SLAM pipeline between them.
//!
//! Zenoh runs in peer mode with explicit endpoints (`listen`, `connect`), multicast and gossip scouting
//! off, so only the configured TCP links are opened; the sync API (`.wait()`) is used throughout. Zenoh
//! reconnects to the `connect` endpoints by itself when a peer drops and comes back.
//!
//! Keys under `key_prefix` (default `skid`):
//! - `skid/msg/<to>/<from>`: a message for robot `<to>` (or `all`) from robot `<from>`; the sender is read
//!   from the key, so payloads stay the protocol's bytes untouched.
//! - `skid/alive/<robot>`: a liveliness token per robot; peers appear and disappear with it.
//!
//! Security (issue #20): by default the links are TLS with mutual authentication against the fleet's CA,
//! and zenoh's access control binds each robot's certificate (`robot-<id>`) to its own keys
//! ([`access`]); plain TCP must be asked for (`security = "plain_tcp"`) and warns. Refusals by the
//! access control are counted from zenoh's statistics ([`refusals`]); `skid fleet certs` writes a test
//! fleet's certificates ([`certs`]). Each peer has its own receive budget, so one that floods loses
//! only its own messages.
//!
//! The transport is polled: received messages are queued (bounded in bytes) by zenoh's own threads and
//! handed out by `poll`. Zenoh's runtime threads are the one exception to "no hidden threads"; it is a
//! network stack, and its pools are small.

pub mod access;
pub mod certs;
mod config;
pub mod peer;
pub mod refusals;
mod transport;

use skid_core::slots::Transport;
use skid_core::{PluginContext, PluginEntry, PluginError, Registry};

pub use certs::{FleetFiles, RobotFiles, write_fleet_certificates};
pub use config::{Congestion, Security, TlsFiles, ZenohConfig};
pub use transport::ZenohTransport;

/// Registers `zenoh` in the transport slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        "zenoh",
        "Zenoh peer-to-peer transport with explicit endpoints, mutual TLS and per-robot access control \
         (real networks, one host per robot)",
        |config: ZenohConfig, context: &PluginContext| {
            Ok(
                Box::new(ZenohTransport::open(context.robot, config, context.fleet_size)?)
                    as Box<dyn Transport>,
            )
        },
    )?;
    registry.transport.register(entry)
}
