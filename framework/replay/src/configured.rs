//! The plugins of a resolved configuration as a [`PluginFactory`]: each robot's verifier and back-end
//! built from the registry exactly as `skid run` builds them, and the configuration a replay mode needs
//! (batch mode solves one graph holding every robot, so the `pgo` back-end is not distributed).

use skid_config::{ConfigError, ConfigSources, ResolvedConfig, ResolvedSlot};
use skid_core::slots::{Backend, OptimizeBudget, Verifier};
use skid_core::{PluginContext, PluginError, PluginResult, Registry, RobotId, Slot};

use crate::run::{PluginFactory, ReplayMode};

/// Loads the configuration from `sources` for a replay in `mode`. Batch mode sets
/// `backend.pgo.distributed = false` before the user's own `--set`s, which still win.
pub fn load_config(
    mut sources: ConfigSources,
    mode: ReplayMode,
    registry: &Registry,
) -> Result<ResolvedConfig, ConfigError> {
    if mode == ReplayMode::Batch {
        sources.sets.insert(0, "backend.pgo.distributed=false".to_owned());
    }
    sources.load(registry)
}

/// Builds each robot's verifier and back-end from a resolved configuration.
pub struct ConfiguredPlugins<'a> {
    pub registry: &'a Registry,
    pub config: &'a ResolvedConfig,
}

impl ConfiguredPlugins<'_> {
    /// The optimisation budget of the configuration's loop section.
    pub fn budget(&self) -> OptimizeBudget {
        OptimizeBudget {
            max_iterations: self.config.loops.optimize_iterations,
            ..OptimizeBudget::default()
        }
    }

    fn context(&self, robot: RobotId) -> PluginContext {
        PluginContext {
            robot,
            fleet_size: self.config.run.robots,
            seed: self.config.run.seed,
            ..PluginContext::default()
        }
    }

    fn chosen(&self, slot: Slot) -> PluginResult<&ResolvedSlot> {
        let resolved = self.config.slot(slot);
        if resolved.is_none() {
            return Err(PluginError::InvalidInput(format!(
                "the replay needs a {slot} plugin; `{slot}.plugin = \"none\"` leaves it empty"
            )));
        }
        Ok(resolved)
    }
}

impl PluginFactory for ConfiguredPlugins<'_> {
    fn verifier(&self, robot: RobotId) -> PluginResult<Box<dyn Verifier>> {
        let resolved = self.chosen(Slot::Verifier)?;
        resolved.build(&self.registry.verifier, &self.context(robot))
    }

    fn backend(&self, robot: RobotId) -> PluginResult<Box<dyn Backend>> {
        let resolved = self.chosen(Slot::Backend)?;
        resolved.build(&self.registry.backend, &self.context(robot))
    }

    fn fleet_loops(&self) -> bool {
        self.config.loops.fleet_loops
    }
}
