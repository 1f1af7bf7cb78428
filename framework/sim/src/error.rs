//! The simulator's error type.

use std::path::PathBuf;

/// What can go wrong when configuring or running the simulator.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("unknown world `{name}`; known worlds: {}", known.join(", "))]
    UnknownWorld { name: String, known: Vec<String> },

    #[error("unknown sensor `{name}`; known sensors: {}", known.join(", "))]
    UnknownSensor { name: String, known: Vec<String> },

    #[error("robot count {robots} is out of range: the simulator drives 1 to {max} robots")]
    RobotCount { robots: u32, max: u32 },

    #[error("robot index {index} is out of range for a fleet of {robots} robots")]
    RobotIndex { index: u32, robots: u32 },

    /// A setting out of its range, at `key` of the simulator's table (empty when no one key is at fault).
    #[error("invalid simulator setting: {message}")]
    InvalidConfig { key: &'static str, message: String },

    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },

    #[error("{}: PNG encoding failed: {message}", path.display())]
    Png { path: PathBuf, message: String },
}

impl SimError {
    /// A setting out of its range, at `key`.
    pub fn invalid(key: &'static str, message: impl Into<String>) -> Self {
        Self::InvalidConfig {
            key,
            message: message.into(),
        }
    }

    /// The key of the simulator's table the error is about, when it is about one.
    pub fn config_key(&self) -> Option<&'static str> {
        match self {
            Self::UnknownWorld { .. } => Some("world"),
            Self::UnknownSensor { .. } => Some("sensor"),
            Self::RobotCount { .. } => Some("robots"),
            Self::InvalidConfig { key, .. } if !key.is_empty() => Some(key),
            _ => None,
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

impl From<SimError> for skid_core::PluginError {
    fn from(error: SimError) -> Self {
        match error {
            SimError::Io { path, source } => skid_core::PluginError::io(path, source),
            other => skid_core::PluginError::InvalidInput(other.to_string()),
        }
    }
}
