//! The explicit plugin registry: a typed table per slot, filled by `register_all` functions (built-ins)
//! and by the dynamic loader (cdylib plugins), and queried by name when a config is instantiated.

pub mod check;
pub mod docs;
mod params;
mod parsed;
mod table;

pub use check::PluginParams;
pub use docs::{ParamDocs, param_docs};
pub use params::Params;
pub use parsed::ParsedParams;

pub use crate::error::ParamError;
pub use crate::slot::Slot;
pub use table::{PluginEntry, PluginInfo, SlotTable};

use std::path::PathBuf;

use crate::slots::{
    Backend, CoarseRegistration, Descriptor, FineRegistration, Odometry, Source, Transport, Verifier,
};
use crate::{PluginError, RobotId};

/// What every plugin constructor is told about where it runs.
#[derive(Clone, Debug)]
pub struct PluginContext {
    /// The robot this plugin instance serves.
    pub robot: RobotId,
    /// Number of robots in the fleet.
    pub fleet_size: u32,
    /// Threads the plugin may use (rayon pools are sized from it); at least 1.
    pub threads: usize,
    /// Seed for anything random, so lockstep runs are reproducible.
    pub seed: u64,
    /// Folder for the run's outputs, when the plugin writes any.
    pub output_dir: Option<PathBuf>,
    /// Whether this robot's source delivers IMU samples with its scans ([`Source::provides_imu`]); the
    /// host sets it once the source is built, before the other plugins.
    pub source_provides_imu: bool,
    /// A name unique to this run within the process, set by the runtime: a plugin that keeps state shared
    /// by the robots of one run in the process (the `loopback` transport's hub) keys it by this, so two
    /// runs in one process (tests, benchmarks) never meet. `None` outside a run.
    pub run_scope: Option<String>,
}

impl PluginContext {
    /// This context for the plugins built after `source`: the same, knowing whether it provides IMU
    /// samples.
    pub fn after_source(self, source: &dyn Source) -> Self {
        Self {
            source_provides_imu: source.provides_imu(),
            ..self
        }
    }
}

impl Default for PluginContext {
    fn default() -> Self {
        Self {
            robot: RobotId(0),
            fleet_size: 1,
            threads: 1,
            seed: 0,
            output_dir: None,
            source_provides_imu: false,
            run_scope: None,
        }
    }
}

/// Every plugin the host knows, one typed table per slot.
pub struct Registry {
    pub source: SlotTable<dyn Source>,
    pub odometry: SlotTable<dyn Odometry>,
    pub descriptor: SlotTable<dyn Descriptor>,
    pub coarse: SlotTable<dyn CoarseRegistration>,
    pub fine: SlotTable<dyn FineRegistration>,
    pub verifier: SlotTable<dyn Verifier>,
    pub backend: SlotTable<dyn Backend>,
    pub transport: SlotTable<dyn Transport>,
    /// Plugins this build leaves out (a cargo feature off), with how to build them in, so a
    /// configuration that selects one is told why it is missing rather than that it does not exist.
    left_out: Vec<(Slot, String, String)>,
}

impl Default for Registry {
    fn default() -> Self {
        Self::new()
    }
}

impl Registry {
    /// An empty registry.
    pub fn new() -> Self {
        Self {
            source: SlotTable::new(Slot::Source),
            odometry: SlotTable::new(Slot::Odometry),
            descriptor: SlotTable::new(Slot::Descriptor),
            coarse: SlotTable::new(Slot::Coarse),
            fine: SlotTable::new(Slot::Fine),
            verifier: SlotTable::new(Slot::Verifier),
            backend: SlotTable::new(Slot::Backend),
            transport: SlotTable::new(Slot::Transport),
            left_out: Vec::new(),
        }
    }

    /// Notes that plugin `name` of `slot` exists but is not built into this binary; `how_to_build` says
    /// how to get it (for example the cargo feature to turn on).
    pub fn note_left_out(&mut self, slot: Slot, name: &str, how_to_build: &str) {
        self.left_out
            .push((slot, name.to_owned(), how_to_build.to_owned()));
    }

    /// How to build plugin `name` of `slot` in, when this build left it out.
    pub fn left_out(&self, slot: Slot, name: &str) -> Option<&str> {
        self.left_out
            .iter()
            .find(|(s, n, _)| *s == slot && n == name)
            .map(|(_, _, how)| how.as_str())
    }

    /// The names registered for a slot, sorted.
    pub fn names(&self, slot: Slot) -> Vec<String> {
        self.infos(slot).into_iter().map(|info| info.name).collect()
    }

    /// Name, summary and default parameters of every plugin of a slot, sorted by name.
    pub fn infos(&self, slot: Slot) -> Vec<PluginInfo> {
        match slot {
            Slot::Source => self.source.infos(),
            Slot::Odometry => self.odometry.infos(),
            Slot::Descriptor => self.descriptor.infos(),
            Slot::Coarse => self.coarse.infos(),
            Slot::Fine => self.fine.infos(),
            Slot::Verifier => self.verifier.infos(),
            Slot::Backend => self.backend.infos(),
            Slot::Transport => self.transport.infos(),
        }
    }

    /// Every plugin of every slot, in slot order.
    pub fn catalogue(&self) -> Vec<PluginInfo> {
        Slot::ALL.iter().flat_map(|&slot| self.infos(slot)).collect()
    }

    /// Parses and checks `params` for the named plugin, without building it.
    pub fn parse(&self, slot: Slot, name: &str, params: &Params) -> Result<ParsedParams, PluginError> {
        match slot {
            Slot::Source => self.source.parse(name, params),
            Slot::Odometry => self.odometry.parse(name, params),
            Slot::Descriptor => self.descriptor.parse(name, params),
            Slot::Coarse => self.coarse.parse(name, params),
            Slot::Fine => self.fine.parse(name, params),
            Slot::Verifier => self.verifier.parse(name, params),
            Slot::Backend => self.backend.parse(name, params),
            Slot::Transport => self.transport.parse(name, params),
        }
    }

    /// Checks `params` against the named plugin's parameter type without building it.
    pub fn validate(&self, slot: Slot, name: &str, params: &Params) -> Result<(), PluginError> {
        self.parse(slot, name, params).map(drop)
    }
}
