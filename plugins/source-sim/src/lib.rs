//! The `sim` source plugin: a robot of a simulated fleet (see `skid-sim` for the worlds, sensors, routes
//! and noise models). Its parameters are [`SimConfig`] under `[source.sim]`; the robot index comes from
//! the plugin context, so every robot host of a fleet uses the same table.

use skid_core::{PluginError, Registry};

pub use skid_sim::{SimConfig, SimSource};

/// Adds the `sim` source to `registry`.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    skid_sim::register(registry)
}
