//! SKiD in-process transport with a link model: bandwidth, latency, loss, reordering, range-dependent
//! degradation (design guide §6), so that the distributed pipeline of the SKiD-SLAM paper, and its
//! latency-versus-distance experiment (Sec. IV-E), can run for N robots in one process, reproducibly.
//!
//! - [`LoopbackHub`]: shared by the robots of a run; applies the [`LinkModel`]; owns the clock
//!   ([`ClockMode::Simulated`] for lockstep: time moves only with [`LoopbackHub::advance_to`]);
//!   positions, link cuts and isolation; per-link [`HubStats`].
//! - [`LoopbackEndpoint`]: one robot's [`Transport`].
//! - [`register`]: the `loopback` plugin. Robots built from the registry find their hub by the `hub`
//!   name in the config within their run's scope (`PluginContext::run_scope`; a process-wide table of
//!   live hubs); the runtime drives the hub through each endpoint's `Transport::simulated_network` to
//!   advance the simulated clock and set robot positions.

mod endpoint;
mod hub;
mod link;
mod radio;
mod stats;

use serde::{Deserialize, Serialize};
use skid_core::slots::Transport;
use skid_core::{PluginContext, PluginEntry, PluginError, Registry};

pub use endpoint::LoopbackEndpoint;
pub use hub::{ClockMode, HubConfig, LoopbackHub};
pub use link::{LinkModel, LinkQuality, RangePoint};
pub use stats::{HubStats, LinkStats};

/// Parameters of the `loopback` transport (`[transport.loopback]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct LoopbackConfig {
    /// Name of the process-wide hub the robots share; robots with the same name hear each other.
    pub hub: String,
    /// Seed of the link model's randomness; `None` takes the seed of the robot that creates the hub
    /// (robot 0 in a lockstep run, so the run stays reproducible).
    pub seed: Option<u64>,
    /// `simulated` (lockstep: the runtime advances time) or `wall` (threads).
    pub clock: ClockMode,
    /// Largest message a robot may send, in bytes.
    pub max_message_bytes: usize,
    pub link: LinkModel,
}

impl Default for LoopbackConfig {
    fn default() -> Self {
        let hub = HubConfig::default();
        Self {
            hub: "default".into(),
            seed: None,
            clock: hub.clock,
            max_message_bytes: hub.max_message_bytes,
            link: hub.link,
        }
    }
}

impl LoopbackConfig {
    /// The part of the config that every robot sharing the hub must agree on.
    pub fn hub_config(&self) -> HubConfig {
        HubConfig {
            clock: self.clock,
            max_message_bytes: self.max_message_bytes,
            link: self.link.clone(),
        }
    }
}

/// Registers `loopback` in the transport slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        "loopback",
        "In-process transport for N robots with a link model (bandwidth, latency, loss, reordering, range)",
        |config: LoopbackConfig, context: &PluginContext| {
            // Robots of one run share the hub; another run in the process gets its own.
            let name = match &context.run_scope {
                Some(scope) => format!("{}/{scope}", config.hub),
                None => config.hub.clone(),
            };
            let hub = LoopbackHub::named(&name, config.hub_config(), config.seed.unwrap_or(context.seed))?;
            Ok(Box::new(hub.endpoint(context.robot)?) as Box<dyn Transport>)
        },
    )?;
    registry.transport.register(entry)
}

impl skid_core::PluginParams for LoopbackConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        use skid_core::registry::check::count_within;
        if self.hub.trim().is_empty() {
            return Err(skid_core::ParamError::at("hub", "the hub name is empty"));
        }
        count_within("max_message_bytes", self.max_message_bytes, 1024, 1 << 30)?;
        self.link.validate().map_err(|error| error.in_table("link"))
    }
}
