//! The error every plugin method returns, and the error of a parameter table that does not fit its plugin.

use std::path::PathBuf;

use crate::slot::Slot;

/// Result alias for plugin methods.
pub type PluginResult<T> = Result<T, PluginError>;

/// What can go wrong inside or around a plugin. Every variant carries enough context to act on.
#[derive(Debug, thiserror::Error)]
pub enum PluginError {
    /// The data handed to the plugin cannot be processed (empty or tiny cloud, NaN points, …).
    #[error("invalid input: {0}")]
    InvalidInput(String),

    /// The plugin's parameters do not parse.
    #[error("invalid parameters: {0}")]
    Params(#[from] ParamError),

    /// No plugin of that name is registered for the slot.
    #[error("unknown {slot} plugin `{name}`; known {slot} plugins: {}", known.join(", "))]
    UnknownPlugin {
        slot: Slot,
        name: String,
        known: Vec<String>,
    },

    /// A plugin of that name is already registered for the slot.
    #[error("a {slot} plugin named `{name}` is already registered")]
    DuplicatePlugin { slot: Slot, name: String },

    /// A file the plugin needs could not be read or written.
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },

    /// A dynamically loaded plugin panicked; the panic was caught at the C boundary.
    #[error("plugin `{plugin}` panicked: {message}")]
    Panicked { plugin: String, message: String },

    /// A peer or the network misbehaved.
    #[error("transport: {0}")]
    Transport(String),

    /// The plugin failed for a reason of its own.
    #[error("{plugin}: {message}")]
    Failed { plugin: String, message: String },
}

impl PluginError {
    /// A plugin-specific failure.
    pub fn failed(plugin: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Failed {
            plugin: plugin.into(),
            message: message.into(),
        }
    }

    /// A file error with its path.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
}

/// A parameter table that does not fit the plugin's config type.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}", self.describe())]
pub struct ParamError {
    /// Dotted path of the offending key, relative to the plugin's table (empty for the table itself).
    pub path: String,
    /// What serde said: the unknown field and the expected ones, or the type that was expected.
    pub message: String,
}

impl ParamError {
    fn describe(&self) -> String {
        if self.path.is_empty() {
            self.message.clone()
        } else {
            format!("key `{}`: {}", self.path, self.message)
        }
    }
}
