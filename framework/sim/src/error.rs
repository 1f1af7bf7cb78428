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

    #[error("invalid simulator setting: {0}")]
    InvalidConfig(String),

    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },

    #[error("{}: PNG encoding failed: {message}", path.display())]
    Png { path: PathBuf, message: String },
}

impl SimError {
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
