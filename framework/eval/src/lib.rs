//! SKiD evaluation metrics, as the SKiD-SLAM paper defines them (Sec. "Evaluation Metrics"):
//!
//! - [`pr_curve`]: precision/recall of place recognition over the descriptor distance threshold, with
//!   max F1, recall at 100 % precision and average precision.
//! - [`registration_stats`]: RTE, RRE and success rate (2 m / 5° by default, RTE/RRE over the
//!   successful pairs only).
//! - [`umeyama`], [`ape`], [`rpe`]: ATE/ARE after SE(3)/Sim(3) Umeyama alignment and RPE with evo's
//!   definitions (Grupp, "evo: Python package for the evaluation of odometry and SLAM", 2017), which
//!   the paper used; [`associate_by_time`] / [`associate_by_index`] pair the poses first.
//! - [`alpha_beta`]: the paper's multi-robot alignment metric `T_β,APE = (T^GT_β)⁻¹ T^GT_α T^α_β`.
//! - [`meeting_frame_error`]: a merge's error where the robots met, free of the odometry's drift;
//!   [`meeting_with_fleet`]: the same where a robot met any robot already placed.
//! - [`alignment_conditioning`]: whether an SE(3) alignment's rotation is observable (not on a straight path).
//! - [`drift`]: KITTI-style segment drift (%, deg/100 m) and end-point drift.
//! - [`descriptor_memory`] and [`latency_vs_distance`]: the communication and memory figures.
//! - [`evaluate_files`]: the `skid eval --gt GT --est EST` evaluation of two TUM/KITTI files.
//! - [`plot`]: PNG line plots, top-down trajectory plots and point maps.

pub mod alpha_beta;
pub mod ape;
pub mod associate;
pub mod comms;
pub mod conditioning;
pub mod drift;
mod error;
pub mod geometry;
pub mod meeting;
pub mod plot;
pub mod pr;
pub mod registration;
pub mod report;
pub mod rpe;
pub mod stats;
pub mod trajectory;
pub mod umeyama;

pub use alpha_beta::{AlphaBetaInput, AlphaBetaResult, TransformError, alpha_beta, anchored_frame_error};
pub use ape::{Aligned, AlignmentSummary, ApeResult, align, ape, ape_of_aligned};
pub use associate::{Associated, DEFAULT_MAX_DIFF_S, TimeAssociation, associate_by_index, associate_by_time};
pub use comms::{
    DescriptorMemory, LatencyBin, LatencySample, descriptor_memory, descriptor_memory_of, latency_vs_distance,
};
pub use conditioning::{AlignmentConditioning, MIN_EIGENVALUE_RATIO, alignment_conditioning};
pub use drift::{DriftOptions, DriftResult, SegmentDrift, drift};
pub use error::EvalError;
pub use meeting::{MEETING_RADIUS_M, MeetingError, meeting_frame_error, meeting_with_fleet};
pub use pr::{PrCurve, PrPoint, ScoredCandidate, pr_curve};
pub use registration::{
    RegistrationError, RegistrationPair, RegistrationStats, RegistrationThresholds, registration_error,
    registration_stats,
};
pub use report::{AssociationMode, EvalOptions, EvalReport, evaluate, evaluate_files};
pub use rpe::{DeltaUnit, RpeOptions, RpeResult, rpe, rpe_pairs};
pub use stats::ErrorStats;
pub use trajectory::{Trajectory, TrajectoryFormat, detect_format, read_trajectory};
pub use umeyama::{AlignmentKind, align_trajectory, umeyama};
