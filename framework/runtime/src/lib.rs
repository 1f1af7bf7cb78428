//! The robot host: instantiates each robot's plugins from a resolved configuration and runs the fleet.
//!
//! What runs today is the front end in lockstep (every robot's source and odometry, one scan at a time
//! in turn, bit-for-bit reproducible); the place-recognition, registration, verification and back-end
//! stages are constructed (so a configuration naming them is checked end to end) and are wired in as
//! their plugins land. Outputs go to `<output_dir>/<run name>/`.

mod fleet;
mod outputs;

pub use fleet::{Fleet, RobotHost, RobotSummary, RunSummary};
pub use outputs::write_outputs;

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
    /// An output could not be written.
    #[error("writing {}: {message}", path.display())]
    Output {
        path: std::path::PathBuf,
        message: String,
    },
}
