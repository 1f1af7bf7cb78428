//! The shape of a SKiD configuration file: run and deploy sections, and one table per plugin slot.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// The plugin name that leaves an optional slot empty (every slot but `source`).
pub const NONE_PLUGIN: &str = "none";

/// Most robots a fleet may have.
pub const MAX_ROBOTS: u32 = 16;

/// `[run]`: what to run and where to write it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunSection {
    /// Name of the run; outputs go to `<output_dir>/<name>/`.
    pub name: String,
    /// Number of robots in the fleet (1 to 16).
    pub robots: u32,
    /// Seed for every random choice, so lockstep runs are reproducible.
    pub seed: u64,
    /// Worker threads for the whole host; 0 means one per core.
    pub threads: usize,
    /// Folder under which each run writes its own folder.
    pub output_dir: PathBuf,
    /// Stop each robot after this many scans; 0 means run until the source ends.
    pub max_scans: u64,
}

impl Default for RunSection {
    fn default() -> Self {
        Self {
            name: "default".to_owned(),
            robots: 3,
            seed: 7,
            threads: 0,
            output_dir: PathBuf::from("runs"),
            max_scans: 0,
        }
    }
}

/// How the robots and their stages are laid out on threads and processes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DeployMode {
    /// One thread runs every robot step by step; bit-for-bit reproducible.
    #[default]
    Lockstep,
    /// One process per robot, stages on threads.
    Threads,
    /// Stage groups in separate processes connected by shared memory.
    Processes,
}

/// `[deploy]`: the process model.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DeploySection {
    pub mode: DeployMode,
}

/// A slot table as written: the selected plugin and the parameter tables of any plugins.
#[derive(Clone, Debug, Deserialize)]
pub(crate) struct RawSlot {
    pub plugin: String,
    #[serde(flatten)]
    pub tables: BTreeMap<String, toml::Value>,
}

/// The whole file as written, before plugin parameters are checked.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawConfig {
    #[serde(default)]
    pub run: RunSection,
    #[serde(default)]
    pub deploy: DeploySection,
    pub source: Option<RawSlot>,
    pub odometry: Option<RawSlot>,
    pub descriptor: Option<RawSlot>,
    pub coarse: Option<RawSlot>,
    pub fine: Option<RawSlot>,
    pub verifier: Option<RawSlot>,
    pub backend: Option<RawSlot>,
    pub transport: Option<RawSlot>,
}

impl RawConfig {
    /// The table of a slot, by slot.
    pub fn slot(&self, slot: skid_core::Slot) -> Option<&RawSlot> {
        use skid_core::Slot;
        match slot {
            Slot::Source => self.source.as_ref(),
            Slot::Odometry => self.odometry.as_ref(),
            Slot::Descriptor => self.descriptor.as_ref(),
            Slot::Coarse => self.coarse.as_ref(),
            Slot::Fine => self.fine.as_ref(),
            Slot::Verifier => self.verifier.as_ref(),
            Slot::Backend => self.backend.as_ref(),
            Slot::Transport => self.transport.as_ref(),
        }
    }
}
