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
//! The transport is polled: received messages are queued (bounded in bytes) by zenoh's own threads and
//! handed out by `poll`. Zenoh's runtime threads are the one exception to "no hidden threads"; it is a
//! network stack, and its pools are small.

mod config;
mod transport;

use skid_core::slots::Transport;
use skid_core::{PluginContext, PluginEntry, PluginError, Registry};

pub use config::{Congestion, ZenohConfig};
pub use transport::ZenohTransport;

/// Registers `zenoh` in the transport slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        "zenoh",
        "Zenoh peer-to-peer transport over TCP with explicit endpoints (real networks, one host per robot)",
        |config: ZenohConfig, context: &PluginContext| {
            Ok(Box::new(ZenohTransport::open(context.robot, config)?) as Box<dyn Transport>)
        },
    )?;
    registry.transport.register(entry)
}
