//! The robot host and the fleet runner.
//!
//! Each robot's [`RobotHost`] owns its plugin instances and joins them the way SKiD-SLAM does (Sec. III
//! of the paper): odometry turns scans into keyframes; each keyframe is described, shared with peers as
//! a small descriptor, and queried against the robot's own and its peers' descriptors; candidates are
//! registered (coarse, then fine — a peer's cloud is fetched only for its candidates), verified
//! (truncated MSE + PCM) and added to the robot's pose graph, which also holds the peer keyframes its
//! inter-robot loops touch, joined by the peers' odometry chains. [`Fleet`] runs the robots in lockstep
//! and delivers their messages through the configured transport; outputs go to
//! `<output_dir>/<run name>/`.

mod artifacts;
mod catchup;
mod fleet;
mod frontend;
mod graph;
mod host;
mod loop_lines;
mod loops;
mod metrics;
mod observer;
mod outputs;
mod peers;
mod process;
mod run_folder;
mod run_record;
mod settings;
mod single;
mod stop;
mod summary;
mod warn_limit;

pub use artifacts::{MAP_VOXEL_M, frames_in_alpha, g2o_vertex_id, merged_map, pose_graph};
pub use fleet::Fleet;
pub use frontend::{FrontEnd, FrontEndError, FrontEndFeed, FrontEndOutput, OdometryOutcome, ThreadFeed};
pub use graph::HostGraph;
pub use host::{LoopStats, Plugins, RobotHost, ScanRecord};
pub use loop_lines::{LOOP_CLASSES, PlacedLoop, loop_class_of_namespace, own_frame_loops};
pub use metrics::{AlignmentMetrics, RobotMetrics, RunMetrics, TrajectoryMetrics};
pub use observer::{HostObserver, Observers};
pub use outputs::write_outputs;
pub use process::{CRASH_AFTER_VAR, ProcessFeed, STAGE_EXE_VAR, exit_when_host_exits, run_front_end_stage};
pub use run_folder::abandon_run;
pub use single::{SingleRobot, SingleRobotError};
pub use stop::{request_stop, stop_requested};
pub use summary::{RobotSummary, RunSummary};
pub use warn_limit::WarnLimiter;

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
    /// An output could not be written.
    #[error("writing {}: {message}", path.display())]
    Output {
        path: std::path::PathBuf,
        message: String,
    },
}
