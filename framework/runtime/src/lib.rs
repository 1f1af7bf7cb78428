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
mod clock;
mod delivery;
mod error;
mod fleet;
mod frontend;
mod graph;
mod host;
mod localisation;
mod lockstep;
mod loop_lines;
mod loop_truth;
mod map_clouds;
mod messages;
mod metrics;
mod observer;
mod outputs;
mod peer_faults;
mod prior;
mod process;
mod run_folder;
mod run_record;
mod session_out;
mod settings;
mod single;
mod stop;
mod summary;
mod warn_limit;

pub use artifacts::{frames_in_alpha, g2o_vertex_id, pose_graph};
pub use clock::{CLOUD_RETRY_PERIOD, HostClock};
pub use error::RuntimeError;
pub use fleet::Fleet;
pub use frontend::{FrontEnd, FrontEndError, FrontEndFeed, FrontEndOutput, OdometryOutcome, ThreadFeed};
pub use graph::HostGraph;
pub use host::{
    CloudServing, JoinedFrame, Localisation, LoopStanding, LoopStats, Placement, Plugins, RobotHost,
    ScanRecord, StandingLoop,
};
pub use localisation::LocalisationSummary;
pub use loop_lines::{LOOP_CLASSES, PlacedLoop, loop_class_of_namespace, own_frame_loops};
pub use loop_truth::{FALSE_MERGE_DEG, FALSE_MERGE_M, FalseLoop, LoopTruth};
pub use map_clouds::{MAP_VOXEL_M, merged_map};
pub use metrics::{AlignmentMetrics, PlacementRecord, RobotMetrics, RunMetrics, TrajectoryMetrics};
pub use observer::{HostObserver, Observers};
pub use outputs::{write_outputs, write_partial_outputs};
pub use prior::{PRIOR_ROBOT_BASE, is_prior_robot};
pub use process::{CRASH_AFTER_VAR, ProcessFeed, STAGE_EXE_VAR, exit_when_host_exits, run_front_end_stage};
pub use run_folder::abandon_run;
pub use single::{SingleRobot, SingleRobotError};
pub use stop::{request_stop, stop_requested};
pub use summary::{RobotSummary, RunSummary};
pub use warn_limit::WarnLimiter;
