//! SKiD core: the vocabulary every crate shares and the contracts every plugin implements.
//!
//! - [`ids`]: robot, keyframe and loop identifiers.
//! - [`pose`]: SE(3) poses as nalgebra `Isometry3<f64>` and their wire conversions.
//! - [`cloud`]: the owned [`Cloud`], the borrowed zero-copy [`CloudView`], scans and keyframes.
//! - [`slots`]: one trait per plugin slot (source, odometry, descriptor + index, coarse and fine
//!   registration, verifier, back-end, transport) and the data they exchange.
//! - [`registry`]: the explicit [`Registry`] with a typed table per slot, and plugin parameters.

pub mod cloud;
pub mod error;
pub mod ids;
pub mod pose;
pub mod registry;
pub mod slot;
pub mod slots;

pub use cloud::{Cloud, CloudView, Keyframe, Scan};
pub use error::{PluginError, PluginResult};
pub use ids::{KeyframeId, LoopId, RobotId};
pub use pose::{Information, Pose};
pub use registry::{
    ParamError, Params, ParsedParams, PluginContext, PluginEntry, PluginInfo, PluginParams, Registry, Slot,
    SlotTable,
};
pub use skid_msgs as msgs;
pub use skid_msgs::{ImuSample, Point, RawPoint};
