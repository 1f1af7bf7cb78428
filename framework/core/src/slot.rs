//! The plugin slots as a closed enum, with their config-file names.

use std::fmt;

use serde::{Deserialize, Serialize};

/// One stage of the pipeline that a plugin fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Slot {
    Source,
    Odometry,
    Descriptor,
    Coarse,
    Fine,
    Verifier,
    Backend,
    Transport,
}

impl Slot {
    /// Every slot, in pipeline order.
    pub const ALL: [Slot; 8] = [
        Slot::Source,
        Slot::Odometry,
        Slot::Descriptor,
        Slot::Coarse,
        Slot::Fine,
        Slot::Verifier,
        Slot::Backend,
        Slot::Transport,
    ];

    /// The table name of the slot in config files (`[descriptor]`, `[coarse]`, …).
    pub const fn key(self) -> &'static str {
        match self {
            Slot::Source => "source",
            Slot::Odometry => "odometry",
            Slot::Descriptor => "descriptor",
            Slot::Coarse => "coarse",
            Slot::Fine => "fine",
            Slot::Verifier => "verifier",
            Slot::Backend => "backend",
            Slot::Transport => "transport",
        }
    }

    /// The slot whose config key is `key`.
    pub fn from_key(key: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|slot| slot.key() == key)
    }
}

impl fmt::Display for Slot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.key())
    }
}
