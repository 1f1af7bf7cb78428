//! SKiD's replay of recorded collaborative SLAM problems: a JSON Robot Log dataset (COSMO-Bench, McGann,
//! Potokar & Kaess, 2025: real multi-robot LiDAR problems with labelled wrong loops) run through the
//! verifier and back-end plugins that `skid run` uses, in one graph (batch) or one graph per robot
//! receiving its measurements in stamp order (distributed, incremental), and judged against the file's
//! ground truth and labels.
//!
//! | module | what |
//! |---|---|
//! | [`problem`] | the dataset as events of keyframes, odometry, priors and labelled loops |
//! | [`run`] | the two modes, driving plugin instances from a [`PluginFactory`] |
//! | [`report`] | ATE (unaligned and jointly aligned), loops kept and dropped by label, time per update |
//! | `frames` | what a replayed verifier sees: chains, back-end poses, frames through third robots |
//! | [`configured`] | the plugins and budget of a resolved configuration, as `skid run` builds them |

pub mod configured;
mod frames;
pub mod problem;
pub mod report;
pub mod run;

pub use configured::{ConfiguredPlugins, load_config};
pub use problem::{LoopLabel, ReplayProblem};
pub use report::{LoopCounts, ReplayReport, RobotReport, UpdateTimes};
pub use run::{LoopFate, PluginFactory, ReplayMode, ReplayOutcome, RobotGraph, replay};

use skid_core::{PluginError, RobotId};

/// What stops a replay.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The dataset holds something the replay cannot map onto SKiD's plugins.
    #[error("{0}")]
    Unsupported(String),
    /// A plugin refused or failed.
    #[error("robot {robot}: {source}")]
    Plugin {
        robot: RobotId,
        #[source]
        source: PluginError,
    },
}
