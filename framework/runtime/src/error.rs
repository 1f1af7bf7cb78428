//! What can stop a run, and the error for an output that could not be written.

use std::path::Path;

/// What can stop a run.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    /// A plugin could not be built or failed while running.
    #[error("{robot}: {slot} plugin `{plugin}`: {source}")]
    Plugin {
        robot: skid_core::RobotId,
        slot: skid_core::Slot,
        plugin: String,
        #[source]
        source: skid_core::PluginError,
    },
    /// A stop was requested (by `signal`, as the binary reported it) before the run ended; the run's
    /// folder stays `<name>.incomplete/`.
    #[error("stopped by signal {signal} before the end")]
    Interrupted { signal: i32 },
    /// The prior map (`[prior] path`) cannot be used.
    #[error("prior.path = {}: {message}", path.display())]
    Prior {
        path: std::path::PathBuf,
        message: String,
    },
    /// An output could not be written.
    #[error("writing {}: {message}", path.display())]
    Output {
        path: std::path::PathBuf,
        message: String,
    },
}

/// The error for an output at `path` that could not be written.
pub(crate) fn output_error(path: &Path, message: impl ToString) -> RuntimeError {
    RuntimeError::Output {
        path: path.to_owned(),
        message: message.to_string(),
    }
}
